"""The evaluation protocol in one place (Lindstrom & Turk 2000, §3.2 and §5.1).

:func:`evaluate` measures a simplified mesh against its original with every metric
registered under ``bench.metrics`` (built-in and third-party alike: :mod:`bench.core.metric`).
It computes the shared inputs once — the images, the Metro distances, the silhouette
histogram, the counts — and hands each metric those it declares in ``needs``. The
built-in metrics make up the protocol:

1. images: the 24 small-rhombicuboctahedron views of the ORIGINAL's bounding sphere at
   512² with 4× MSAA, 50 % gray background, headlight, ``flat`` or ``gouraud`` shading
   (textured when the mesh is) — the original's images come from a disk cache;
2. image metrics: d_RMS on luminance (equation 2) with per-view values, SSIM (mean over
   views) and FLIP (on :data:`metrics.image.FLIP_VIEWS` by default, timed separately);
3. geometry: Metro-style Hausdorff distances both ways, fractions of the original's
   bounding-box diagonal;
4. silhouettes: the share of edges that are silhouettes in exactly i of the 20
   dodecahedron views, and its mean ⟨x⟩ (Figure 7);
5. topology: faces, render and welded vertices, boundary edges, seam cracks;
6. model-specific metrics where the original's metadata defines them
   (``exterior_share``, §5.2; :func:`model_metrics`).

Two settings vary the images for comparisons made the way another paper makes them
(defaults: the 24 views at 512², the protocol above): ``resolution`` and ``views``, a
named view set of :data:`metrics.views.VIEW_SETS` (``representative``: one view, as
Williams et al. 2003 compare in §6 and Figure 4). Both are recorded with every result
and, when not at their defaults, in the job's key and its evaluation label
(:func:`bench.records.results.shading_label`), so results under different settings are
never matched with each other; FLIP's view subset belongs to the 24 views, so any other
view set runs FLIP on every one of its views.

Rendering lives here (:func:`render_views`, :func:`original_images`); the metric modules
only compare what they are given, so none of them imports this one.

Bump :data:`PROTOCOL_VERSION` whenever any of this changes a number; results of
different protocol versions are never compared.
"""

from __future__ import annotations

import io
import math
import numbers
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from bench.core.mesh import Mesh
from bench.io.atomic import write_atomic
from bench.io.cache import cache_dir

__all__ = ["PROTOCOL_VERSION", "Protocol", "Evaluation", "evaluate", "registered_metrics",
           "model_metrics", "original_images", "render_views", "render_per_view", "cache_dir"]

#: 2: ``seam_cracks`` counts the result's boundary where the original had none, by the
#: ends of each boundary edge (1 took the feature nearest its midpoint, which counted
#: chords of simplified holes passing near a seam); every other number is unchanged.
PROTOCOL_VERSION = "2"


@dataclass(frozen=True)
class Protocol:
    """Settings of one evaluation; part of every result record."""

    shading: Literal["flat", "gouraud"] = "flat"
    specular: bool = False
    resolution: int = 512
    msaa: int = 4
    hausdorff_samples: int = 200_000
    flip_views: Literal["subset", "all"] = "subset"
    version: str = PROTOCOL_VERSION
    #: the named view set of :data:`metrics.views.VIEW_SETS` the images are taken from
    views: Literal["rhombicuboctahedron", "representative"] = "rhombicuboctahedron"
    #: sizes of the screen-size evaluation (:mod:`metrics.screen`), largest first; empty:
    #: none (and left out of :meth:`as_dict`, so records without it are unchanged)
    screen_sizes: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        from metrics.views import VIEW_SETS

        if self.views not in VIEW_SETS:
            raise ValueError(f"views must be one of {', '.join(VIEW_SETS)}, got {self.views!r}")
        if isinstance(self.resolution, bool) or not isinstance(self.resolution, int) \
                or self.resolution < 1:
            raise ValueError(f"resolution must be a positive number of pixels, "
                             f"got {self.resolution!r}")
        if self.screen_sizes:
            from metrics.screen import check_screen_sizes

            object.__setattr__(self, "screen_sizes", check_screen_sizes(self.screen_sizes))
        else:
            object.__setattr__(self, "screen_sizes", ())

    def as_dict(self) -> dict:
        settings = asdict(self)
        if not self.screen_sizes:
            del settings["screen_sizes"]
        else:
            settings["screen_sizes"] = list(self.screen_sizes)
        return settings

    def cameras(self, original: Mesh) -> list:
        """The evaluation cameras of ``original`` under these settings."""
        from metrics.views import evaluation_cameras

        return evaluation_cameras(original, self.views)

    def image_key(self, mesh: Mesh) -> str:
        """Cache key of a mesh's protocol images under these settings (the view set
        shows only when it is not the default, so the default's keys never change)."""
        views = "" if self.views == "rhombicuboctahedron" else f"-{self.views}"
        return (f"{mesh.content_hash[:16]}-p{self.version}-{self.shading}"
                f"{'-spec' if self.specular else ''}-{self.resolution}-msaa{self.msaa}{views}")


@dataclass
class Evaluation:
    """What :func:`evaluate` returns."""

    metrics: dict
    per_view: dict = field(default_factory=dict)
    silhouette_histogram: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    images: np.ndarray | None = None
    #: metric name -> why it has no value (it raised, or is unavailable)
    errors: dict = field(default_factory=dict)
    #: the screen-size evaluation (:func:`metrics.screen.summarise`), None when off
    screen: dict | None = None


def render_views(mesh: Mesh, original: Mesh, protocol: Protocol) -> np.ndarray:
    """The protocol images of ``mesh`` with cameras fitted to ``original`` (the 24
    views by default; ``protocol.views`` names the set).

    Returns
    -------
    ndarray of shape (V, R, R, 3) uint8
    """
    from metrics.render import get_renderer

    renderer = get_renderer(protocol.resolution, protocol.resolution, protocol.msaa)
    return renderer.render(mesh, protocol.cameras(original), shading=protocol.shading,
                           specular=protocol.specular)


def render_per_view(meshes: list[Mesh], original: Mesh, protocol: Protocol) -> np.ndarray:
    """The protocol images of a view-dependent result: view i shows ``meshes[i]``.

    Returns
    -------
    ndarray of shape (V, R, R, 3) uint8
    """
    from metrics.render import get_renderer

    cameras = protocol.cameras(original)
    if len(meshes) != len(cameras):
        raise ValueError(f"a view-dependent result needs one mesh per protocol view "
                         f"({len(cameras)}), got {len(meshes)}")
    renderer = get_renderer(protocol.resolution, protocol.resolution, protocol.msaa)
    return np.concatenate([renderer.render(m, [c], shading=protocol.shading,
                                           specular=protocol.specular)
                           for m, c in zip(meshes, cameras)])


def original_images(original: Mesh, protocol: Protocol, cache: Path | None = None) -> np.ndarray:
    """The original's protocol images, rendered once and cached on disk."""
    folder = (cache or cache_dir()) / "originals"
    path = folder / f"{protocol.image_key(original)}.npy"
    if path.exists():
        try:
            return np.load(path)
        except (OSError, ValueError):
            pass  # a damaged cache file is re-rendered
    images = render_views(original, original, protocol)
    folder.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    np.save(buffer, images)
    write_atomic(path, buffer.getvalue())
    return images


def model_metrics(original: Mesh, simplified: Mesh) -> dict:
    """Metrics that only some models define (their metadata says how), keyed by name.

    A metric undefined for ``original`` is left out rather than recorded as NaN, so
    records, results.csv and the report show it only where it means something. Today:
    ``exterior_share`` (:mod:`metrics.interior`).
    """
    from metrics import interior

    share = interior.exterior_share(original, simplified)
    return {} if np.isnan(share) else {"exterior_share": share}


def registered_metrics() -> tuple[list[tuple[str, object]], dict[str, str]]:
    """The available registered metrics as (name, Metric) in name order, and the
    unavailable ones as name -> why (with the fix)."""
    from bench.core.registry import registry

    usable, problems = [], {}
    for entry in registry("metric"):
        if entry.available:
            usable.append((entry.name, entry.load()))
        else:
            problems[entry.name] = f"unavailable: {entry.problem}"
    return usable, problems


#: Shared inputs the record itself carries (sheet images and per-view values, the Metro
#: distances both ways, the silhouette histogram): computed whatever the metrics need.
_RECORDED_INPUTS = frozenset({"images", "hausdorff", "silhouette"})


def _shared_inputs(needs: set, original: Mesh, simplified: Mesh, protocol: Protocol,
                   reference_images, view_meshes, seconds: dict) -> dict:
    """``ctx`` with each input of ``needs`` (keys of :data:`bench.core.metric.NEEDS`) computed
    once, and its time in ``seconds``."""
    from metrics import geometry, silhouette, topology
    from metrics.views import silhouette_cameras

    ctx = {"protocol": protocol}
    if "images" in needs:
        t = time.perf_counter()
        ref = reference_images if reference_images is not None else \
            original_images(original, protocol)
        seconds["original_images"] = time.perf_counter() - t
        t = time.perf_counter()
        imgs = (render_views(simplified, original, protocol) if view_meshes is None
                else render_per_view(view_meshes, original, protocol))
        seconds["render"] = time.perf_counter() - t
        ctx["original_images"], ctx["simplified_images"] = _read_only(ref), _read_only(imgs)
    if "view_meshes" in needs:
        ctx["view_meshes"] = view_meshes
    if "hausdorff" in needs:
        t = time.perf_counter()
        ctx["hausdorff"] = geometry.hausdorff(original, simplified,
                                              samples=protocol.hausdorff_samples)
        seconds["hausdorff"] = time.perf_counter() - t
    if "silhouette" in needs:
        t = time.perf_counter()
        eyes = np.array([c.eye for c in silhouette_cameras(original)])
        ctx["silhouette"] = silhouette.silhouette_histogram(simplified, eyes)
        seconds["silhouette"] = time.perf_counter() - t
    if "screen" in needs and protocol.screen_sizes:
        from metrics.screen import screen_curve, summarise

        t = time.perf_counter()
        curve = screen_curve(original, simplified, protocol,
                             protocol_images=ctx.get("simplified_images"),
                             view_meshes=view_meshes, cache=cache_dir())
        ctx["screen"] = summarise(curve, original, ctx["hausdorff"]["symmetric_max"])
        seconds["screen"] = time.perf_counter() - t
    if "topology" in needs:
        t = time.perf_counter()
        ctx["topology"] = topology.counts(original, simplified)
        seconds["topology"] = time.perf_counter() - t
    if "parts" in needs:
        from metrics.parts import parts_lost

        t = time.perf_counter()
        ctx["parts"] = parts_lost(original, simplified)
        seconds["parts"] = time.perf_counter() - t
    return ctx


def _read_only(images: np.ndarray) -> np.ndarray:
    """A read-only view: one metric cannot change the images the next one sees."""
    view = images.view()
    view.flags.writeable = False
    return view


def _recorded(value) -> tuple[float | int | None, tuple | None]:
    """A metric's return value as (scalar for the record, per-view values or None);
    None and NaN mean undefined (left out). Raises TypeError for a non-number."""
    if value is None:
        return None, None
    per_view = getattr(value, "per_view", None) or None
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return int(value), per_view
    if not isinstance(value, numbers.Real):
        raise TypeError(f"returned {type(value).__name__} {value!r}, not a number")
    scalar = float(value)
    return (None if math.isnan(scalar) else scalar), per_view


def _computed(metrics, original: Mesh, simplified: Mesh, ctx: dict, seconds: dict,
              errors: dict) -> tuple[dict, dict]:
    """Each metric's value (after the Metro figures of ``ctx["hausdorff"]``) and per-view
    values; a metric that raises gets ``errors[name]`` instead, and its time goes to
    ``seconds`` either way."""
    values, per_view = dict(ctx["hausdorff"]), {}
    for name, metric in metrics:
        t = time.perf_counter()
        try:
            value, views = _recorded(metric.compute(original, simplified, ctx))
        except Exception as exc:  # one broken metric must not lose the job's other figures
            errors[name] = f"{type(exc).__name__}: {exc}"
            values.pop(name, None)
            continue
        finally:
            seconds[f"metric:{name}"] = time.perf_counter() - t
        if value is not None:
            values[name] = value
        if views is not None:
            per_view[name] = list(views)
    return values, per_view


def evaluate(original: Mesh, simplified: Mesh, protocol: Protocol = Protocol(),
             reference_images: np.ndarray | None = None,
             view_meshes: list[Mesh] | None = None, metrics=None) -> Evaluation:
    """Measure ``simplified`` against ``original`` under ``protocol`` with every
    registered metric.

    The flow: (1) gather the metrics (the available entries of the ``bench.metrics``
    registry, built-in and third-party alike; an unavailable one is an error of that
    metric); (2) compute once each shared input that a metric needs
    (:data:`bench.core.metric.NEEDS`) or the record carries — render the 24 views, sample
    the Hausdorff distances, count silhouettes and topology; (3) call each metric's
    ``compute(original, simplified, ctx)`` with those inputs in ``ctx``; its value goes
    to ``metrics[name]`` and, for a :class:`~bench.core.metric.Value`, its per-view values to
    ``per_view[name]``.

    A metric that raises, returns something that is not a number or is unavailable
    (a missing backend) does not fail the evaluation: its value is missing and
    ``errors[name]`` says why; ``bench check`` marks it ``newly failing`` where the
    baseline has a value. A metric returning None or NaN is undefined for this model and
    left out, with no error. A shared input that fails (the renderer, Metro) fails the
    whole evaluation, as it is the protocol itself.

    Parameters
    ----------
    original, simplified : Mesh
    protocol : Protocol
    reference_images : ndarray of shape (24, R, R, 3) uint8, optional
        The original's images, if already at hand (else from :func:`original_images`).
    view_meshes : list of 24 Mesh, optional
        A view-dependent method's per-view results: view i is imaged with
        ``view_meshes[i]``; geometry, silhouettes and topology still use ``simplified``
        (the method's view-independent result).
    metrics : iterable of (str, Metric), optional
        The metrics to compute instead of the registered ones.

    Returns
    -------
    Evaluation
        ``metrics`` also holds the Metro figures of :func:`metrics.geometry.hausdorff`
        (``forward_mean`` ... ``symmetric_max``), which are not registered metrics.
    """
    errors = {}
    if metrics is None:
        metrics, errors = registered_metrics()
    metrics = list(metrics)

    seconds = {}
    needs = set(_RECORDED_INPUTS)
    for _, metric in metrics:
        needs |= set(getattr(metric, "needs", ()))
    ctx = _shared_inputs(needs, original, simplified, protocol, reference_images,
                         view_meshes, seconds)

    values, per_view = _computed(metrics, original, simplified, ctx, seconds, errors)
    return Evaluation(metrics=values, per_view=per_view,
                      silhouette_histogram=list(map(float, ctx["silhouette"].histogram)),
                      seconds=seconds, images=ctx["simplified_images"], errors=errors,
                      screen=ctx.get("screen"))
