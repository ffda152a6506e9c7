"""The evaluation protocol in one place (Lindstrom & Turk 2000, §3.2 and §5.1).

:func:`evaluate` measures a simplified mesh against its original:

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
   (:func:`model_metrics`: the share of faces on the exterior, §5.2).

Bump :data:`PROTOCOL_VERSION` whenever any of this changes a number; results of
different protocol versions are never compared.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from bench.mesh import Mesh

__all__ = ["PROTOCOL_VERSION", "Protocol", "Evaluation", "evaluate", "model_metrics",
           "original_images", "cache_dir"]

PROTOCOL_VERSION = "1"


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

    def as_dict(self) -> dict:
        return asdict(self)

    def image_key(self, mesh: Mesh) -> str:
        """Cache key of a mesh's protocol images under these settings."""
        return (f"{mesh.content_hash[:16]}-p{self.version}-{self.shading}"
                f"{'-spec' if self.specular else ''}-{self.resolution}-msaa{self.msaa}")


@dataclass
class Evaluation:
    """What :func:`evaluate` returns."""

    metrics: dict
    per_view: dict = field(default_factory=dict)
    silhouette_histogram: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    images: np.ndarray | None = None


def cache_dir() -> Path:
    """Where the originals' images are cached: ``$BENCH_CACHE`` or ``~/.cache/bench``."""
    root = os.environ.get("BENCH_CACHE") or Path.home() / ".cache" / "bench"
    return Path(root)


def render_views(mesh: Mesh, original: Mesh, protocol: Protocol) -> np.ndarray:
    """The 24 protocol images of ``mesh`` with cameras fitted to ``original``.

    Returns
    -------
    ndarray of shape (24, R, R, 3) uint8
    """
    from metrics.render import get_renderer
    from metrics.views import protocol_cameras

    renderer = get_renderer(protocol.resolution, protocol.resolution, protocol.msaa)
    return renderer.render(mesh, protocol_cameras(original), shading=protocol.shading,
                           specular=protocol.specular)


def render_per_view(meshes: list[Mesh], original: Mesh, protocol: Protocol) -> np.ndarray:
    """The protocol images of a view-dependent result: view i shows ``meshes[i]``.

    Returns
    -------
    ndarray of shape (24, R, R, 3) uint8
    """
    from metrics.render import get_renderer
    from metrics.views import protocol_cameras

    cameras = protocol_cameras(original)
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
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npy")
    np.save(tmp, images)
    os.replace(tmp, path)
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


def evaluate(original: Mesh, simplified: Mesh, protocol: Protocol = Protocol(),
             reference_images: np.ndarray | None = None,
             view_meshes: list[Mesh] | None = None) -> Evaluation:
    """Measure ``simplified`` against ``original`` under ``protocol``.

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
    """
    from metrics import geometry, image, silhouette, topology
    from metrics.views import silhouette_cameras

    seconds = {}
    t = time.perf_counter()
    ref = reference_images if reference_images is not None else original_images(original, protocol)
    seconds["original_images"] = time.perf_counter() - t

    t = time.perf_counter()
    imgs = (render_views(simplified, original, protocol) if view_meshes is None
            else render_per_view(view_meshes, original, protocol))
    seconds["render"] = time.perf_counter() - t

    t = time.perf_counter()
    d, d_views = image.d_rms(ref, imgs)
    s, s_views = image.ssim_mean(ref, imgs)
    seconds["d_rms_ssim"] = time.perf_counter() - t

    flip_views = None if protocol.flip_views == "subset" else "all"
    f, f_views, seconds["flip"] = image.flip_mean(ref, imgs, views=flip_views)

    t = time.perf_counter()
    h = geometry.hausdorff(original, simplified, samples=protocol.hausdorff_samples)
    seconds["hausdorff"] = time.perf_counter() - t

    t = time.perf_counter()
    eyes = np.array([c.eye for c in silhouette_cameras(original)])
    hist, mean = silhouette.silhouette_histogram(simplified, eyes)
    seconds["silhouette"] = time.perf_counter() - t

    metrics = {"d_rms": d, "ssim": s, "flip": f, **h, "hausdorff_max": h["symmetric_max"],
               "silhouette_mean": mean}
    metrics.update(topology.counts(original, simplified))
    metrics.update(model_metrics(original, simplified))
    return Evaluation(metrics=metrics,
                      per_view={"d_rms": d_views.tolist(), "ssim": s_views.tolist(),
                                "flip": f_views.tolist()},
                      silhouette_histogram=list(map(float, hist)), seconds=seconds, images=imgs)
