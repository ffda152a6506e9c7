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

import numpy as np

from bench.core.metric import Metric, Value
from metrics.shading import LUMA_WEIGHTS, luminance  # re-exported: callers of the metrics use them

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

    Uses :func:`skimage.metrics.structural_similarity` with the paper's settings: an
    11×11 Gaussian window of sigma 1.5, population covariances, data range 255, and
    K1 = 0.01, K2 = 0.03. SSIM of each view is the mean of its SSIM map away from a
    5-pixel border.

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
    from skimage.metrics import structural_similarity

    a, b = _check_pair(original_images, simplified_images)
    if min(a.shape[1:3]) < _SSIM_MIN_SIZE:
        raise ValueError(f"SSIM needs images of at least {_SSIM_MIN_SIZE}×{_SSIM_MIN_SIZE} "
                         f"pixels (its Gaussian window), got {a.shape[1]}×{a.shape[2]}; "
                         "render larger views")
    per_view = np.array([structural_similarity(luminance(a[v]), luminance(b[v]),
                                               **_SSIM_SETTINGS) for v in range(len(a))])
    return float(per_view.mean()), per_view


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
    for k, view in enumerate(indices):
        # LDR inputs are float images in 0..1, taken as sRGB-encoded.
        reference = a[view].astype(np.float32) / 255.0
        test = b[view].astype(np.float32) / 255.0
        _, mean_error, _ = flip_evaluator.evaluate(
            reference, test, "LDR", inputsRGB=True, applyMagma=False,
            computeMeanError=True, parameters={"ppd": FLIP_PPD})
        per_view[k] = mean_error
    seconds = time.perf_counter() - start
    return float(per_view.mean()), per_view, seconds


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
              _compute_ssim, requires={"skimage": "scikit-image>=0.22"}, needs={"images"})
FLIP = Metric("flip", "", False,
              "FLIP perceptual difference, mean over the FLIP_VIEWS subset of views",
              _compute_flip, requires={"flip_evaluator": "flip-evaluator>=1.2"},
              needs={"images"})
