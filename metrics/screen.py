"""Screen-size evaluation: from which on-screen size an LOD is indistinguishable.

Engines switch levels of detail by screen size, so the question a simplified mesh must
answer is not only "how different is it at 512²" but "from which size on can it replace
the original unseen". This module measures that under the protocol's cameras:

* **sizes**: the 24 protocol views are rendered at S × S pixels, S in
  :data:`DEFAULT_SCREEN_SIZES` (512, 256, 128, 64, 32) unless configured
  (``Protocol.screen_sizes``, ``bench run --screen-sizes``). The cameras are the
  protocol's, so the ORIGINAL's bounding sphere spans exactly S pixels at size S;
* **the original** is supersampled until converged: rendered at
  (:data:`SUPERSAMPLING` · S)² with the renderer's 4× MSAA and box-filtered down to S²
  (:func:`supersampled_images`; cached on disk like the protocol's original images).
  Converged means: at 4× and at 8× it differs by far less than the threshold
  (``tests/test_screen.py``; bunny at 128 px: FLIP 0.0021 against τ = 0.01);
* **the LOD** is rendered as an engine draws it at that size: S² with the protocol's
  4× MSAA, nothing more. At S = 512 these are the protocol's own images;
* per size: FLIP (mean over the protocol's FLIP views, :func:`metrics.image.flip_mean`)
  and d_RMS (all 24 views, :func:`metrics.image.d_rms`) of the LOD against the
  converged original, and the same of the original itself drawn as the engine draws it
  (4× MSAA at S², :func:`original_floor`): the **floor**, what anti-aliasing alone
  costs at that size. The lists are the job's **curve** (the record's ``screen`` part).

From the curve:

* ``switch_px`` (:func:`switch_size`): the largest S at which the LOD's FLIP exceeds the
  floor by at most τ (:data:`SWITCH_FLIP`), interpolated linearly in log S between the
  measured size that passes and the next larger one that fails. When the largest size
  passes, the value is that size with the bound ``">="`` (indistinguishable at every
  size measured: at least that); when no size passes, the smallest size with the bound
  ``"<"``. A bound is never replaced by an extrapolated value. ``switch_px_rms``
  likewise with d_RMS and :data:`SWITCH_RMS`;
* the **predicted** switch sizes an engine's rule would give: the size at which the
  largest deviation projects to one pixel, ``S = 2 r / d`` (``r`` the original's
  bounding-sphere radius, ``d`` a distance in model units): from the symmetric Hausdorff
  max (:func:`predicted_size`) and, for methods that report one (meshoptimizer), from
  the library's own error in model units.

Why above the floor, and why τ = 0.01 (docs/screen.md has the measurements): the
engine's own 4× MSAA of the ORIGINAL differs from its converged image by FLIP 0.004
(512 px) to 0.015 (32 px) on the bunny, and by 0.027 to 0.065 on the textured torus
(minified texture lines and text); an absolute threshold would call the original itself
distinguishable from itself on such models. So an LOD is indistinguishable where it adds
at most τ to what drawing the original costs. FLIP's authors recommend its mean as the
single number to report and publish no just-noticeable value for it; τ = 0.01 is the
low end of the mean-FLIP thresholds used to call two renderings the same (0.01-0.1),
and about the floor itself at 64-128 px on untextured models: an LOD may add no more
than anti-aliasing already does. :data:`FLIP_ABLATION` records the switch sizes at
0.005 and 0.02 too. ``switch_px_rms`` uses 2 luminance levels above the d_RMS floor
(the floor is 1.2 at 512 px to 4.0 at 32 px on the bunny).
"""

from __future__ import annotations

import io
import math
import time
from pathlib import Path

import numpy as np

from bench.core.mesh import Mesh
from bench.core.metric import Metric

__all__ = [
    "DEFAULT_SCREEN_SIZES",
    "FLIP_ABLATION",
    "MAX_SCREEN_SIZE",
    "SUPERSAMPLING",
    "SWITCH_FLIP",
    "SWITCH_PX",
    "SWITCH_PX_RMS",
    "SWITCH_RMS",
    "check_screen_sizes",
    "describe_switch",
    "parse_screen_sizes",
    "predicted_size",
    "screen_curve",
    "screen_part_problem",
    "supersampled_images",
    "switch_size",
]

#: The sizes S (pixels spanned by the original's bounding sphere) measured by default.
DEFAULT_SCREEN_SIZES = (512, 256, 128, 64, 32)
#: The largest size accepted (the supersampled original is rendered at 4× that).
MAX_SCREEN_SIZE = 4096
#: Supersampling factor of the original per axis (on top of the renderer's 4× MSAA).
SUPERSAMPLING = 4
#: τ: an LOD is indistinguishable at a size where its mean FLIP exceeds the original's
#: own floor there (:func:`original_floor`) by at most this.
SWITCH_FLIP = 0.01
#: The d_RMS threshold of ``switch_px_rms``: luminance levels (0..255) above the floor.
SWITCH_RMS = 2.0
#: The τ values of the ablation recorded with every curve (the record's ``screen``).
FLIP_ABLATION = (0.005, 0.01, 0.02)
#: Bounds: the value is a lower bound (indistinguishable at every size measured) or an
#: upper bound (distinguishable at every size measured).
AT_LEAST, BELOW = ">=", "<"


# -- the sizes --------------------------------------------------------------------------

def check_screen_sizes(sizes) -> tuple[int, ...]:
    """The sizes as a tuple of distinct whole numbers, largest first; ValueError (one
    line) for an empty list, a size below 1 or above :data:`MAX_SCREEN_SIZE`."""
    values = list(sizes)
    if not values:
        raise ValueError("screen sizes: give at least one size in pixels, e.g. 512,128,32")
    for s in values:
        if isinstance(s, bool) or not isinstance(s, (int, np.integer)):
            raise ValueError(f"screen size {s!r} is not a whole number of pixels")
        if not 1 <= s <= MAX_SCREEN_SIZE:
            raise ValueError(f"screen size {s} is out of range: give sizes from 1 to "
                             f"{MAX_SCREEN_SIZE} pixels")
    return tuple(sorted({int(s) for s in values}, reverse=True))


def parse_screen_sizes(text: str) -> tuple[int, ...]:
    """``"512,128,32"`` (or ``"default"``) -> sizes; ValueError (one line) if malformed."""
    if text.strip().lower() in ("default", "on", ""):
        return DEFAULT_SCREEN_SIZES
    sizes = []
    for item in text.split(","):
        item = item.strip()
        try:
            sizes.append(int(item))
        except ValueError:
            raise ValueError(f"screen size {item!r} is not a whole number of pixels; give "
                             "sizes such as 512,256,128,64,32") from None
    return check_screen_sizes(sizes)


# -- images -----------------------------------------------------------------------------

def _cache_file(cache: Path | None, name: str) -> Path | None:
    """Where a cached image set of the original lies (``cache/originals/name``; the
    protocol passes its :func:`metrics.protocol.cache_dir`), None without a cache."""
    return None if cache is None else Path(cache) / "originals" / name


def supersampled_images(original: Mesh, protocol, size: int,
                        factor: int = SUPERSAMPLING, cache: Path | None = None) -> np.ndarray:
    """The original's protocol views at ``size``² pixels, converged: rendered at
    (``factor`` · ``size``)² with 4× MSAA, then each ``factor`` × ``factor`` block
    averaged (and rounded to 8 bits). Cached on disk by content hash.

    Returns
    -------
    ndarray of shape (V, size, size, 3) uint8
    """
    from dataclasses import replace

    from metrics.render import get_renderer

    key = replace(protocol, resolution=size).image_key(original)
    path = _cache_file(cache, f"{key}-ss{factor}.npy")
    if path is not None and path.exists():
        try:
            return np.load(path)
        except (OSError, ValueError):
            pass  # a damaged cache file is rendered again
    big = size * factor
    renderer = get_renderer(big, big, 4)
    cameras = protocol.cameras(original)
    images = np.empty((len(cameras), size, size, 3), np.uint8)
    for i, camera in enumerate(cameras):  # one view at a time: memory of one big image
        view = renderer.render(original, [camera], shading=protocol.shading,
                               specular=protocol.specular)[0]
        block = view.reshape(size, factor, size, factor, 3).astype(np.float64)
        images[i] = np.rint(block.mean(axis=(1, 3))).astype(np.uint8)
    if path is not None:
        from bench.io.atomic import write_atomic

        buffer = io.BytesIO()
        np.save(buffer, images)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, buffer.getvalue())
    return images


def engine_images(mesh: Mesh, original: Mesh, protocol, size: int,
                  view_meshes: list[Mesh] | None = None) -> np.ndarray:
    """``mesh`` at ``size``² as an engine draws it: the protocol's cameras and 4× MSAA
    (a view-dependent result: view i shows ``view_meshes[i]``)."""
    from metrics.render import get_renderer

    renderer = get_renderer(size, size, 4)
    cameras = protocol.cameras(original)
    if view_meshes is None:
        return renderer.render(mesh, cameras, shading=protocol.shading,
                               specular=protocol.specular)
    return np.concatenate([renderer.render(m, [c], shading=protocol.shading,
                                           specular=protocol.specular)
                           for m, c in zip(view_meshes, cameras, strict=True)])


# -- the curve --------------------------------------------------------------------------

def original_floor(original: Mesh, protocol, size: int, reference: np.ndarray | None = None,
                   cache: Path | None = None) -> tuple[float, float]:
    """(FLIP, d_RMS) of the ORIGINAL drawn as an engine draws it (4× MSAA at ``size``²)
    against its converged image: what anti-aliasing alone costs at that size, the floor
    an LOD's error is measured above. Cached on disk beside the converged images."""
    import json
    from dataclasses import replace

    from metrics.image import d_rms, flip_mean

    key = replace(protocol, resolution=size).image_key(original)
    views = _flip_views(protocol)
    path = _cache_file(cache, f"{key}-ss{SUPERSAMPLING}-floor-{views or 'subset'}.json")
    try:
        values = json.loads(path.read_text())
        return float(values["flip"]), float(values["d_rms"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        pass  # not cached (or no cache)
    if reference is None:
        reference = supersampled_images(original, protocol, size, cache=cache)
    drawn = engine_images(original, original, protocol, size)
    values = {"flip": flip_mean(reference, drawn, views=views)[0],
              "d_rms": d_rms(reference, drawn)[0]}
    if path is not None:
        from bench.io.atomic import write_atomic

        path.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(path, json.dumps(values))
    return values["flip"], values["d_rms"]


def _flip_views(protocol):
    """FLIP's views at every size: the protocol's subset of the 24 views, or all."""
    return None if (protocol.flip_views == "subset"
                    and protocol.views == "rhombicuboctahedron") else "all"


def screen_curve(original: Mesh, simplified: Mesh, protocol, sizes=None,
                 protocol_images: np.ndarray | None = None,
                 view_meshes: list[Mesh] | None = None, cache: Path | None = None) -> dict:
    """FLIP and d_RMS of ``simplified`` against the converged ``original`` at each size,
    and the same of the original itself drawn as the engine draws it (the floor).

    Parameters
    ----------
    sizes : sequence of int, optional
        Default ``protocol.screen_sizes`` or :data:`DEFAULT_SCREEN_SIZES`.
    protocol_images : ndarray, optional
        ``simplified``'s protocol images; reused at the size equal to the protocol's
        resolution (they are the engine's image there) instead of rendering again.
    view_meshes : list of Mesh, optional
        A view-dependent result's per-view meshes (view i shows ``view_meshes[i]``).
    cache : Path, optional
        Folder of the original's cached images (the protocol passes its
        ``cache_dir()``); None renders them afresh.

    Returns
    -------
    dict
        ``sizes`` (largest first), ``flip``, ``d_rms`` (one value per size),
        ``original_flip``, ``original_d_rms`` (the floor at each size),
        ``flip_views`` (which views FLIP ran on: "subset" or "all"),
        ``supersampling``, ``seconds`` (rendering and comparing the LOD) and
        ``original_seconds`` (the original's converged images and floor, where not
        cached).
    """
    from metrics.image import d_rms, flip_mean

    sizes = check_screen_sizes(sizes or getattr(protocol, "screen_sizes", ())
                               or DEFAULT_SCREEN_SIZES)
    views = _flip_views(protocol)
    flips, rms, floor_flip, floor_rms = [], [], [], []
    seconds = original_seconds = 0.0
    for size in sizes:
        t = time.perf_counter()
        reference = supersampled_images(original, protocol, size, cache=cache)
        floor = original_floor(original, protocol, size, reference, cache=cache)
        floor_flip.append(floor[0])
        floor_rms.append(floor[1])
        original_seconds += time.perf_counter() - t
        t = time.perf_counter()
        if protocol_images is not None and size == protocol.resolution:
            images = protocol_images
        else:
            images = engine_images(simplified, original, protocol, size, view_meshes)
        flips.append(flip_mean(reference, images, views=views)[0])
        rms.append(d_rms(reference, images)[0])
        seconds += time.perf_counter() - t
    return {"sizes": list(sizes), "flip": flips, "d_rms": rms,
            "original_flip": floor_flip, "original_d_rms": floor_rms,
            "flip_views": "subset" if views is None else "all",
            "supersampling": SUPERSAMPLING, "seconds": seconds,
            "original_seconds": original_seconds}


def switch_size(sizes, values, threshold: float) -> tuple[float, str | None]:
    """The largest size at which ``values`` ≤ ``threshold``, interpolated in log S.

    Parameters
    ----------
    sizes : sequence of int
        Measured sizes (any order, distinct, positive).
    values : sequence of float
        The error at each size.
    threshold : float

    Returns
    -------
    value : float
    bound : None, ">=" or "<"
        None: ``value`` lies between two measured sizes (or is one); ``">="``: the
        largest size passes, the switch size is at least ``value`` (that size);
        ``"<"``: no size passes, it is below ``value`` (the smallest size).

    Between the largest passing size S_a (error e_a ≤ τ) and the next larger measured
    size S_b (error e_b > τ), the error is taken as linear in log S, so
    ``log S = log S_a + (τ − e_a) / (e_b − e_a) · (log S_b − log S_a)``.
    """
    pairs = sorted(zip((float(s) for s in sizes), (float(v) for v in values)), reverse=True)
    if not pairs:
        raise ValueError("switch_size needs at least one measured size")
    if any(math.isnan(v) for _, v in pairs):
        raise ValueError("switch_size: an error value is NaN")
    passing = [i for i, (_, v) in enumerate(pairs) if v <= threshold]
    if not passing:
        return pairs[-1][0], BELOW
    first = passing[0]
    if first == 0:
        return pairs[0][0], AT_LEAST
    (s_b, e_b), (s_a, e_a) = pairs[first - 1], pairs[first]
    t = (threshold - e_a) / (e_b - e_a)  # e_b > τ ≥ e_a, so 0 ≤ t < 1
    value = math.exp(math.log(s_a) + t * (math.log(s_b) - math.log(s_a)))
    return float(min(max(value, s_a), s_b)), None  # rounding never leaves [S_a, S_b]


def predicted_size(distance: float, radius: float) -> float | None:
    """The size S (pixels spanned by the bounding sphere of radius ``radius``) at which
    ``distance`` (model units) projects to one pixel: ``2 · radius / distance``; None
    when the distance is not finite or not above 1e-9 · radius (no deviation beyond
    rounding: never visible)."""
    if distance is None or not (math.isfinite(distance) and distance > radius * 1e-9):
        return None  # no deviation above rounding: never visible
    return 2.0 * radius / distance


def describe_switch(value: float, bound: str | None) -> dict:
    """A switch size as the record holds it: ``{"value", "bound"}``."""
    return {"value": float(value), "bound": bound}


def summarise(curve: dict, original: Mesh, hausdorff_max: float | None,
              flip_threshold: float = SWITCH_FLIP, rms_threshold: float = SWITCH_RMS) -> dict:
    """The record's ``screen`` part: the curve, the switch sizes (with bounds), the
    τ ablation and the Hausdorff prediction (``hausdorff_max`` a fraction of the
    original's bounding-box diagonal, as the protocol records it)."""
    from metrics.views import bounding_sphere

    sizes = curve["sizes"]
    flip = excess(curve["flip"], curve["original_flip"])
    rms = excess(curve["d_rms"], curve["original_d_rms"])
    radius = float(bounding_sphere(original.positions)[1])
    lo, hi = original.positions.min(axis=0), original.positions.max(axis=0)
    diagonal = float(np.linalg.norm(hi - lo))
    part = dict(curve)
    part.update(
        flip_threshold=flip_threshold, rms_threshold=rms_threshold, radius=radius,
        switch_px=describe_switch(*switch_size(sizes, flip, flip_threshold)),
        switch_px_rms=describe_switch(*switch_size(sizes, rms, rms_threshold)),
        ablation={f"{tau:g}": describe_switch(*switch_size(sizes, flip, tau))
                  for tau in FLIP_ABLATION},
        predicted={"hausdorff": predicted_size(
            None if hausdorff_max is None else hausdorff_max * diagonal, radius)})
    return part


def excess(values, floor) -> list[float]:
    """An LOD's error above the original's own floor at each size."""
    return [float(v) - float(f) for v, f in zip(values, floor, strict=True)]


def add_library_prediction(part: dict, stats: dict) -> None:
    """Add the prediction from a method's own error in model units
    (``stats["library_error_absolute"]``, meshoptimizer's rows) to a ``screen`` part."""
    error = stats.get("library_error_absolute")
    if error is not None:
        part.setdefault("predicted", {})["library"] = predicted_size(float(error),
                                                                     part["radius"])


def screen_part_problem(part) -> str | None:
    """Why a record's ``screen`` part is malformed (one line), or None."""
    if not isinstance(part, dict):
        return "must be an object"
    sizes = part.get("sizes")
    if not (isinstance(sizes, list) and sizes and all(
            isinstance(s, int) and not isinstance(s, bool) and s > 0 for s in sizes)):
        return "has 'sizes' that is not a list of positive whole numbers"
    for name in ("flip", "d_rms"):
        series = part.get(name)
        if not (isinstance(series, list) and len(series) == len(sizes) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in series)):
            return f"has {name!r} that is not one number per size"
    for name in ("switch_px", "switch_px_rms"):
        entry = part.get(name)
        if not (isinstance(entry, dict) and isinstance(entry.get("value"), (int, float))
                and entry.get("bound") in (None, AT_LEAST, BELOW)):
            return f"has {name!r} that is not {{value, bound}}"
    return None


def csv_columns(part: dict | None) -> dict:
    """The results.csv columns of a record's ``screen`` part (empty cells without one):
    the bounds of ``switch_px`` and ``switch_px_rms`` (``>=``, ``<`` or empty) and the
    predicted switch sizes."""
    part = part or {}
    predicted = part.get("predicted") or {}
    return {"switch_px_bound": (part.get("switch_px") or {}).get("bound"),
            "switch_px_rms_bound": (part.get("switch_px_rms") or {}).get("bound"),
            "switch_px_hausdorff": predicted.get("hausdorff"),
            "switch_px_library": predicted.get("library")}


#: The columns :func:`csv_columns` adds to results.csv when some record has a curve.
CSV_COLUMNS = ("switch_px_bound", "switch_px_rms_bound", "switch_px_hausdorff",
               "switch_px_library")


# -- LOD chains: halving levels and engine units --------------------------------------

#: The fewest faces a halving chain goes down to (unless the input's 1/256 is more).
HALVING_FLOOR = 100
#: Screen height (pixels) the engine units are stated at.
ENGINE_SCREEN_HEIGHT = 1080


def halving_faces(n_faces: int, floor: int | None = None) -> list[int]:
    """50 %, 25 %, ... of ``n_faces``, rounded, while at least ``floor`` faces (default
    the larger of :data:`HALVING_FLOOR` and ``n_faces / 256``), as engines build their
    chains; ValueError (one line) when not even the first level reaches the floor."""
    floor = max(HALVING_FLOOR, math.ceil(n_faces / 256)) if floor is None else int(floor)
    if floor < 1:
        raise ValueError(f"the halving floor must be at least 1 face, got {floor}")
    levels, k = [], 1
    while round(n_faces / 2 ** k) >= floor:
        levels.append(round(n_faces / 2 ** k))
        k += 1
    if not levels:
        raise ValueError(f"halving {n_faces} faces reaches the floor of {floor} faces at "
                         "once; give a lower floor")
    return levels


def engine_units(switch: dict, original: Mesh,
                 screen_height: int = ENGINE_SCREEN_HEIGHT) -> dict:
    """A switch size (``{"value", "bound"}``, pixels spanned by the bounding sphere) in
    engine units on a screen ``screen_height`` pixels high:

    * Unreal's ScreenSize: the bounding sphere's projected diameter over the screen's
      height (ComputeBoundsScreenSize), so S / H;
    * Unity's LODGroup screen-relative transition height: the group's size (taken as the
      largest side of the mesh's bounding box, what Unity computes from the renderers'
      bounds) projected, over the screen's height: S · L / (2 r) / H.

    The bound (``>=``, ``<`` or None) carries over: a switch of at least S pixels is a
    ScreenSize of at least S / H.
    """
    from metrics.views import bounding_sphere

    radius = float(bounding_sphere(original.positions)[1])
    side = float((original.positions.max(axis=0) - original.positions.min(axis=0)).max())
    value = float(switch["value"])
    return {"screen_height": screen_height, "bound": switch.get("bound"),
            "unreal_screen_size": value / screen_height,
            "unity_relative_height": value * side / (2.0 * radius) / screen_height}


def describe_bound(switch: dict) -> str:
    """``">= 512"``, ``"< 32"`` or ``"181"``: a switch size as people read it."""
    bound = switch.get("bound")
    return f"{bound} {switch['value']:.0f}" if bound else f"{switch['value']:.0f}"


def switch_entry(part: dict, original: Mesh, stats: dict | None = None) -> dict:
    """The ``switch`` entry of a level in an LOD chain's sidecar: ``switch_px`` and
    ``switch_px_rms`` with their bounds and in engine units, the predictions and the
    curve."""
    part = dict(part)
    add_library_prediction(part, stats or {})
    return {"switch_px": {**part["switch_px"], **engine_units(part["switch_px"], original)},
            "switch_px_rms": {**part["switch_px_rms"],
                              **engine_units(part["switch_px_rms"], original)},
            "flip_threshold": part["flip_threshold"], "rms_threshold": part["rms_threshold"],
            "predicted_px": part.get("predicted", {}),
            "curve": {k: part[k] for k in ("sizes", "flip", "d_rms", "original_flip",
                                           "original_d_rms")}}


# -- registered metrics -----------------------------------------------------------------

def _switch(name: str):
    def compute(original, simplified, ctx=None):
        part = (ctx or {}).get("screen")
        return None if part is None else part[name]["value"]
    return compute


SWITCH_PX = Metric(
    "switch_px", "px", True,
    "largest size (pixels spanned by the bounding sphere) at which the LOD's mean FLIP "
    "against the converged original is at most 0.01 above the original's own; "
    "results.csv's switch_px_bound says when it is a bound (needs --screen-sizes)",
    _switch("switch_px"), needs={"screen"})
SWITCH_PX_RMS = Metric(
    "switch_px_rms", "px", True,
    "the same with d_RMS at most 2 luminance levels above the original's own (needs "
    "--screen-sizes)",
    _switch("switch_px_rms"), needs={"screen"})
