"""Image metrics over the protocol views: d_RMS (Lindstrom & Turk 2000), SSIM and FLIP.

All three compare two stacks of views of the same cameras, the original's and the
simplified mesh's, as uint8 RGB arrays of shape (V, H, W, 3):

- :func:`d_rms`, equation 2 of Lindstrom & Turk 2000: the RMS luminance difference with
  all views treated as one image mosaic;
- :func:`ssim_mean`, the structural similarity of Wang et al. 2004 on luminance, mean
  over views;
- :func:`flip_mean`, NVIDIA's FLIP perceptual difference (the ``flip-evaluator``
  package), by default on the six views of :data:`FLIP_VIEWS` because it costs far more
  than the other two.

The :class:`~bench.core.metric.Metric` constants at the bottom need ``"images"``: they are
called as ``compute(original, simplified, ctx)`` with ``ctx`` a dict holding

- ``"original_images"``, ``"simplified_images"``: ndarray of shape (24, H, W, 3) uint8,
  the protocol views, which :func:`metrics.protocol.evaluate` renders once for all
  metrics (this module renders nothing; a ``ctx`` without them is a ValueError);
- optionally ``"protocol"``, whose ``flip_views`` ("subset" or "all") FLIP follows, and
  ``"flip_views"``, a ``views`` argument for :func:`flip_mean` overriding the protocol.

Each returns a :class:`~bench.core.metric.Value`: the scalar with its per-view values.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numba
import numpy as np
from numba import njit

from bench.core.metric import Metric, Value
from bench.core.numba_cache import lock_cache_writes
from metrics.shading import LUMA_WEIGHTS, luminance  # re-exported: callers of the metrics use them

lock_cache_writes()  # several processes compile at once (bench.core.numba_cache)

__all__ = ["luminance", "d_rms", "ssim_mean", "flip_mean", "FLIP_VIEWS", "FLIP_PPD",
           "LUMA_WEIGHTS", "D_RMS", "SSIM", "FLIP"]

#: Pixels per degree of visual angle assumed by FLIP: its default, a 0.7 m viewing
#: distance from a 0.7 m wide 3840-pixel monitor. Passed explicitly so an upgrade of
#: ``flip-evaluator`` that changed the default would not silently change the numbers.
FLIP_PPD = 67.0

# The Wang et al. 2004 SSIM settings (skimage's documented recipe to match the paper):
# an 11-tap Gaussian window of sigma 1.5, population covariances, a 0..255 data range.
_SSIM_SETTINGS = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                      data_range=255)
_SSIM_MIN_SIZE = 11  # the Gaussian window's width; smaller images have no valid window
_SSIM_RADIUS = 5  # the window's half-width: skimage's int(3.5 * sigma + 0.5)

#: How far FLIP's filters reach at FLIP_PPD, in pixels: its colour filter's radius
#: ceil(3 · sqrt(0.04 / (2π²)) · ppd) = 10 (the widest of the three channels' Gaussians)
#: and its edge and point filters' ceil(3 · 0.5 · 0.082 · ppd) = 9.
_FLIP_REACH = 10


# -- where two views differ --------------------------------------------------------------
# Both metrics are local: a pixel's value depends only on the pixels within a fixed reach
# of it, and is exactly "no difference" (SSIM 1, FLIP 0) where the two views agree over
# all of that neighbourhood. So each view is evaluated on the box around its differing
# pixels grown by twice the reach (the values inside the box grown by one reach are then
# computed from exactly the pixels a whole-image evaluation uses), the rest is filled with
# the exact "no difference", and the mean is taken over the whole view as before. The
# numbers are the whole-image ones, bit for bit (tests/test_image_metrics.py compares
# them); the protocol's views of a mesh cover about half of each image.

def _differing_box(a: np.ndarray, b: np.ndarray, grow: int):
    """(rows, cols) slices of the box holding every pixel where views ``a`` and ``b``
    (H, W, 3) differ, grown by ``grow`` pixels and clipped to the image; None if the two
    are identical."""
    h, w = a.shape[:2]
    differ = (a != b).reshape(h, -1)  # a row of all channels: reductions run 20x faster
    rows = np.flatnonzero(differ.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(differ.any(axis=0).reshape(w, -1).any(axis=1))
    return (slice(max(0, rows[0] - grow), min(h, rows[-1] + 1 + grow)),
            slice(max(0, cols[0] - grow), min(w, cols[-1] + 1 + grow)))


# -- the view subset for FLIP ------------------------------------------------------------

def _protocol_directions() -> np.ndarray:
    """The 24 unit directions of the protocol cameras, shape (24, 3), in view order."""
    from metrics.views import rhombicuboctahedron_directions

    return rhombicuboctahedron_directions()


def _flip_views() -> tuple[int, ...]:
    # Three antipodal pairs, one per axis: ±(a, 1, -1), ±(-1, a, 1), ±(1, -1, a) with
    # a = 1 + √2. Each is one of the four views nearest its axis, and the cyclic sign
    # pattern makes any two of the six nearly orthogonal (|cos| = 1/(a² + 2) ≈ 0.13),
    # so the subset covers the sphere evenly. Matched by direction, so the indices
    # follow whatever order the protocol lists its views in.
    a = 1.0 + np.sqrt(2.0)
    wanted = np.array([[a, 1, -1], [-1, a, 1], [1, -1, a]])
    wanted = np.concatenate([wanted, -wanted])
    wanted /= np.linalg.norm(wanted, axis=1, keepdims=True)
    return tuple(int(i) for i in np.argmax(wanted @ _protocol_directions().T, axis=1))


#: Indices into the 24 protocol views on which :func:`flip_mean` runs by default: the
#: views in the directions ±(a, 1, -1), ±(-1, a, 1), ±(1, -1, a), a = 1 + √2 — one
#: near each of ±x, ±y, ±z, forming three antipodal, nearly orthogonal pairs.
FLIP_VIEWS: tuple[int, ...] = _flip_views()


# -- validation --------------------------------------------------------------------------

def _check_pair(original_images, simplified_images) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.asarray(original_images), np.asarray(simplified_images)
    for what, x in (("original_images", a), ("simplified_images", b)):
        if x.ndim != 4 or x.shape[-1] != 3:
            raise ValueError(f"{what} must have shape (V, H, W, 3) (views of RGB pixels), "
                             f"got {x.shape}; drop an alpha channel with images[..., :3]")
        if x.dtype != np.uint8:
            raise ValueError(f"{what} must be uint8 (0..255), got {x.dtype}; convert "
                             "float images in 0..1 with (255 * x).round().astype(np.uint8)")
        if x.shape[0] == 0 or x.shape[1] == 0 or x.shape[2] == 0:
            raise ValueError(f"{what} is empty, shape {x.shape}; render at least one view")
    if a.shape != b.shape:
        raise ValueError(f"original_images {a.shape} and simplified_images {b.shape} "
                         "differ in shape; render both with the same cameras and size")
    return a, b


# -- the metrics -------------------------------------------------------------------------

def d_rms(original_images: np.ndarray, simplified_images: np.ndarray
          ) -> tuple[float, np.ndarray]:
    """RMS luminance difference over all pixels of all views (L&T 2000, equation 2).

    Parameters
    ----------
    original_images, simplified_images : ndarray of shape (V, H, W, 3) uint8
        The same V views of the two meshes.

    Returns
    -------
    d : float
        sqrt( 1/(V·H·W) · Σ_h Σ_i Σ_j (y⁰_hij − y¹_hij)² ), the views treated as one
        mosaic image (equation 2), in luminance units 0..255.
    per_view : ndarray of shape (V,) float64
        Each view's own RMS difference (equation 1). ``d`` is the root of the mean of
        their squares, since every view has the same number of pixels.

    References
    ----------
    .. [1] Lindstrom, P. & Turk, G. Image-driven simplification. ACM TOG 19(3), 2000,
       equations 1 and 2.
    """
    a, b = _check_pair(original_images, simplified_images)
    mean_square = np.empty(len(a))
    for view in range(len(a)):  # one view at a time keeps memory at one float image
        diff = luminance(a[view]) - luminance(b[view])
        mean_square[view] = np.mean(diff * diff)
    return float(np.sqrt(mean_square.mean())), np.sqrt(mean_square)


def ssim_mean(original_images: np.ndarray, simplified_images: np.ndarray
              ) -> tuple[float, np.ndarray]:
    """Mean structural similarity of the views' luminance (Wang et al. 2004).

    The paper's settings, as :func:`skimage.metrics.structural_similarity` has them
    (``gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=255``):
    an 11×11 Gaussian window of sigma 1.5, population covariances, data range 255, and
    K1 = 0.01, K2 = 0.03. SSIM of each view is the mean of its SSIM map away from a
    5-pixel border. The numbers are skimage's bit for bit; the map is computed here,
    and only on the box where the views differ (it is exactly 1 elsewhere).

    Parameters
    ----------
    original_images, simplified_images : ndarray of shape (V, H, W, 3) uint8
        The same V views of the two meshes; H and W at least 11.

    Returns
    -------
    ssim : float
        Mean over views; 1 for identical images, lower is worse.
    per_view : ndarray of shape (V,) float64

    References
    ----------
    .. [1] Wang, Z., Bovik, A. C., Sheikh, H. R. & Simoncelli, E. P. Image quality
       assessment: from error visibility to structural similarity. IEEE TIP 13(4),
       2004, equation 13.
    """
    a, b = _check_pair(original_images, simplified_images)
    if min(a.shape[1:3]) < _SSIM_MIN_SIZE:
        raise ValueError(f"SSIM needs images of at least {_SSIM_MIN_SIZE}×{_SSIM_MIN_SIZE} "
                         f"pixels (its Gaussian window), got {a.shape[1]}×{a.shape[2]}; "
                         "render larger views")
    per_view = np.array([_ssim_view(a[v], b[v]) for v in range(len(a))])
    return float(per_view.mean()), per_view


def _ssim_view(a: np.ndarray, b: np.ndarray) -> float:
    """The mean SSIM of one view pair, from :func:`_ssim_map` on the box where they
    differ; the rest of the map is exactly 1."""
    r = _SSIM_RADIUS
    box = _differing_box(a, b, 2 * r)
    if box is None:
        return 1.0
    # The map covers the box less r on each side, where the window has the box's own
    # pixels; where the box meets the image's edge, the window reads the image mirrored
    # about it (scipy's "reflect", numpy's "symmetric") and the map reaches the edge.
    edges = [(s.start == 0, s.stop == n) for s, n in zip(box, a.shape[:2])]
    pads = [(r * lo, r * hi) for lo, hi in edges]
    x = np.pad(luminance(a[box]), pads, mode="symmetric")
    y = np.pad(luminance(b[box]), pads, mode="symmetric")
    s_map = np.ones(a.shape[:2])
    s_map[tuple(slice(s.start + r * (not lo), s.stop - r * (not hi))
                for s, (lo, hi) in zip(box, edges))] = \
        _ssim_map(x, y, _SSIM_WEIGHTS, _SSIM_C1, _SSIM_C2)
    return float(s_map[r:-r, r:-r].mean(dtype=np.float64))  # the border has no window


def _gaussian_weights(sigma: float, radius: int) -> np.ndarray:
    """scipy.ndimage's Gaussian taps (its ``_gaussian_kernel1d`` of order 0)."""
    x = np.arange(-radius, radius + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x ** 2)
    return phi / phi.sum()


_SSIM_WEIGHTS = _gaussian_weights(_SSIM_SETTINGS["sigma"], _SSIM_RADIUS)
_SSIM_C1 = (0.01 * _SSIM_SETTINGS["data_range"]) ** 2  # (K1 L)², K1 = 0.01
_SSIM_C2 = (0.03 * _SSIM_SETTINGS["data_range"]) ** 2  # (K2 L)², K2 = 0.03


@njit(cache=True)
def _ssim_map(x, y, w, c1, c2):  # pragma: no cover - compiled
    """The SSIM map of two luminance images padded by the window's radius r on every
    side, shape (H - 2r, W - 2r): skimage's ``structural_similarity`` with Gaussian
    weights ``w`` and population covariances, with the same arithmetic in the same
    order, so the values are skimage's bit for bit (tests/test_image_metrics.py checks).

    The five local moments are filtered separably in scipy.ndimage's order, down the
    columns (axis 0) and then along the rows, each tap pair summed first as its
    symmetric ``correlate1d`` does: x₀·w₀, then (x₋ₖ + xₖ)·wₖ for k = r … 1. One output
    row at a time, so the workspace is two rows of the five moments."""
    r = (len(w) - 1) // 2
    rows, cols = x.shape[0] - 2 * r, x.shape[1] - 2 * r
    out = np.empty((rows, cols))
    v = np.empty((5, x.shape[1]))   # the moments filtered down the columns, one row
    f = np.empty((5, cols))         # and then along it
    for i in range(rows):
        c = i + r
        for j in range(x.shape[1]):
            a, b = x[c, j], y[c, j]
            v[0, j], v[1, j], v[2, j] = a * w[r], b * w[r], (a * a) * w[r]
            v[3, j], v[4, j] = (b * b) * w[r], (a * b) * w[r]
        for k in range(-r, 0):
            wk = w[r + k]
            for j in range(x.shape[1]):
                a0, a1, b0, b1 = x[c + k, j], x[c - k, j], y[c + k, j], y[c - k, j]
                v[0, j] += (a0 + a1) * wk
                v[1, j] += (b0 + b1) * wk
                v[2, j] += (a0 * a0 + a1 * a1) * wk
                v[3, j] += (b0 * b0 + b1 * b1) * wk
                v[4, j] += (a0 * b0 + a1 * b1) * wk
        for n in range(5):
            for j in range(cols):
                f[n, j] = v[n, j + r] * w[r]
            for k in range(-r, 0):
                wk = w[r + k]
                for j in range(cols):
                    f[n, j] += (v[n, j + r + k] + v[n, j + r - k]) * wk
        for j in range(cols):
            ux, uy = f[0, j], f[1, j]
            vx, vy, vxy = f[2, j] - ux * ux, f[3, j] - uy * uy, f[4, j] - ux * uy
            a1, a2 = 2 * ux * uy + c1, 2 * vxy + c2
            b1, b2 = ux * ux + uy * uy + c1, vx + vy + c2
            out[i, j] = (a1 * a2) / (b1 * b2)
    return out


def flip_mean(original_images: np.ndarray, simplified_images: np.ndarray,
              views: str | Sequence[int] | None = None) -> tuple[float, np.ndarray, float]:
    """Mean FLIP error over views (the ``flip-evaluator`` package, LDR mode).

    Each view is compared as an sRGB low-dynamic-range image at :data:`FLIP_PPD` pixels
    per degree; a view's error is the mean of its FLIP error map (0 identical, 1 the
    largest perceived difference).

    Parameters
    ----------
    original_images, simplified_images : ndarray of shape (V, H, W, 3) uint8
        The same V views of the two meshes (the reference and the test images).
    views : None, "all" or sequence of int
        Which views to evaluate: None for :data:`FLIP_VIEWS` (needs the V = 24 protocol
        views), "all" for every view, or explicit view indices.

    Returns
    -------
    flip : float
        Mean over the evaluated views; lower is better.
    per_view : ndarray of shape (k,) float64
        Error of each evaluated view, in the order of ``views``.
    seconds : float
        Wall time spent in FLIP.

    References
    ----------
    .. [1] Andersson, P., Nilsson, J., Akenine-Möller, T., Oskarsson, M., Åström, K. &
       Fairchild, M. D. FLIP: A Difference Evaluator for Alternating Images. Proc. ACM
       Comput. Graph. Interact. Tech. 3(2), 2020.
    """
    a, b = _check_pair(original_images, simplified_images)
    indices = _resolve_views(views, len(a))
    try:
        import flip_evaluator
    except ImportError as exc:
        raise ImportError("FLIP needs the flip-evaluator package: "
                          "pip install 'flip-evaluator>=1.2'") from exc

    start = time.perf_counter()
    per_view = np.empty(len(indices))
    with _flip_threads():
        for k, view in enumerate(indices):
            per_view[k] = _flip_view(a[view], b[view], flip_evaluator)
    seconds = time.perf_counter() - start
    return float(per_view.mean()), per_view, seconds


def _flip_threads():
    """FLIP's OpenMP threads limited to the threads numba's parallel kernels have in this
    process: a job process of ``bench run --jobs 2`` has one, so its FLIP runs on one
    too. Left to itself, OpenMP starts a thread per core in every job process, and with
    two jobs on two cores its threads spin waiting at each of FLIP's barriers on the
    core the other job needs: FLIP took twice as long. The error map, and so the value,
    does not depend on the number of threads."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=numba.get_num_threads(), user_api="openmp")


def _flip_view(a: np.ndarray, b: np.ndarray, flip_evaluator) -> float:
    """FLIP's mean error over one view pair, evaluated on the box where they differ.

    The library's mean is a float32 sum of its error map in row order divided by the
    pixel count; the map is 0 outside the box, so summing the box's rows in order gives
    the same float32 sum."""
    box = _differing_box(a, b, 2 * _FLIP_REACH)
    if box is None:
        return 0.0
    # LDR inputs are float images in 0..1, taken as sRGB-encoded.
    reference = np.ascontiguousarray(a[box], dtype=np.float32) / 255.0
    test = np.ascontiguousarray(b[box], dtype=np.float32) / 255.0
    error_map, _, _ = flip_evaluator.evaluate(
        reference, test, "LDR", inputsRGB=True, applyMagma=False,
        computeMeanError=False, parameters={"ppd": FLIP_PPD})
    total = np.cumsum(np.asarray(error_map, dtype=np.float32).ravel(), dtype=np.float32)[-1]
    return float(total / np.float32(a.shape[0] * a.shape[1]))


def _resolve_views(views, n_views: int) -> list[int]:
    if views is None:
        if n_views != len(_protocol_directions()):
            raise ValueError(f"the default FLIP views index the {len(_protocol_directions())} "
                             f"protocol views, but {n_views} were given; pass views='all' "
                             "or a list of view indices")
        return list(FLIP_VIEWS)
    if isinstance(views, str):
        if views != "all":
            raise ValueError(f"views must be None, 'all' or a sequence of view indices, "
                             f"got {views!r}")
        return list(range(n_views))
    indices = [int(v) for v in views]
    if not indices:
        raise ValueError("views is empty; pass None, 'all' or at least one view index")
    bad = [v for v in indices if not 0 <= v < n_views]
    if bad:
        raise ValueError(f"view indices {bad} are out of range for {n_views} views; "
                         f"use indices 0..{n_views - 1}")
    return indices


# -- registered metrics ------------------------------------------------------------------

def _images(ctx) -> tuple[np.ndarray, np.ndarray]:
    """The two meshes' protocol images from ``ctx`` (see the module docstring). This
    module only compares images; rendering them is the protocol's job."""
    missing = [k for k in ("original_images", "simplified_images") if k not in (ctx or {})]
    if missing:
        raise ValueError(f"ctx has no {' and no '.join(missing)}; image metrics compare the "
                         "protocol images, which metrics.protocol.evaluate renders (or pass "
                         "them in ctx yourself)")
    return ctx["original_images"], ctx["simplified_images"]


def _compute_d_rms(original, simplified, ctx=None) -> Value:
    return Value(*d_rms(*_images(ctx)))


def _compute_ssim(original, simplified, ctx=None) -> Value:
    return Value(*ssim_mean(*_images(ctx)))


def _compute_flip(original, simplified, ctx=None) -> Value:
    ctx = {} if ctx is None else ctx
    views = ctx.get("flip_views")
    protocol = ctx.get("protocol")
    if views is None and (getattr(protocol, "flip_views", "subset") == "all"
                          or getattr(protocol, "views", "rhombicuboctahedron")
                          != "rhombicuboctahedron"):
        views = "all"  # the subset indexes the 24 views; another view set: all its views
    value, per_view, _ = flip_mean(*_images(ctx), views=views)
    return Value(value, per_view)


D_RMS = Metric("d_rms", "luminance (0-255)", False,
               "RMS luminance difference over the 24 protocol views (L&T 2000, eq. 2)",
               _compute_d_rms, needs={"images"})
SSIM = Metric("ssim", "", True,
              "structural similarity of luminance, mean over the 24 views (Wang et al. 2004)",
              _compute_ssim, needs={"images"})
FLIP = Metric("flip", "", False,
              "FLIP perceptual difference, mean over the FLIP_VIEWS subset of views",
              _compute_flip, requires={"flip_evaluator": "flip-evaluator>=1.2"},
              needs={"images"})
