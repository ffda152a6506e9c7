"""Texture borders and the edge penalty of González, Castelló & Chover (2007).

The paper (§3, Figure 3) extends the collapse cost of any edge-collapse simplifier: edges
whose image in the texture crosses a border of the texture are collapsed later. The
pipeline, as :func:`edge_penalties` runs it::

    borders = texture_borders(mesh.texture)                # EdgeDetection(Texture)
    crossing = segments_cross_border(uv0, uv1, borders)    # "e collides with a border of M"
    penalty = area(faces of e) / area(mesh) if crossing    # Eqs. 1-2, computeTextureError

and a simplifier adds ``penalty`` to its own cost ``c_e`` (Eq. 2: ``c_F = c_e + ...``).
:func:`border_image_with_edges` draws the border image and the edges it penalised.

Conventions
-----------
*Texture space.* UV has its origin at the bottom-left of the texture, the texture's row 0
is its top row. Pixel ``(row, col)`` of a ``(h, w)`` texture has its centre at
``x = col, y = row`` where ``x = u * w - 0.5`` and ``y = (1 - v) * h - 0.5``, i.e. it
covers ``u * w`` in ``[col, col + 1)`` and ``v * h`` in ``[h - 1 - row, h - row)``. UVs
outside ``[0, 1]`` wrap (repeat addressing), so ``u = 1`` lands in column 0, as it does
when a GPU samples with ``GL_REPEAT`` and nearest filtering.

*Thresholds.* ``low`` and ``high`` are fractions of the maximum gradient magnitude of the
image, as in MATLAB's ``edge(I, 'canny', [low high], sigma)``, which the paper used.
See :func:`texture_borders`.

References
----------
.. [1] González, C., Castelló, P. & Chover, M. A texture-based metric extension for
   simplification methods. GRAPP 2007, §3 and Figure 3.
.. [2] Canny, J. A computational approach to edge detection. IEEE TPAMI 8(6), 1986.
.. [3] Amanatides, J. & Woo, A. A fast voxel traversal algorithm for ray tracing.
   Eurographics 1987.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage as ndi
from numba import njit

from bench.core.mesh import Mesh, face_areas
from methods.engine.topology import _edge_faces, _faces_area
from methods.engine.wedges import corner_wedges
from metrics.shading import luminance

__all__ = [
    "DEFAULT_HIGH",
    "DEFAULT_LOW",
    "DEFAULT_SIGMA",
    "border_image_with_edges",
    "edge_penalties",
    "segment_crosses_border",
    "segment_pixels",
    "segments_cross_border",
    "texture_borders",
]

#: The paper's detector parameters (captions of its Figures 6, 9, 12 and 15).
DEFAULT_SIGMA = 0.75
DEFAULT_LOW = 0.5
DEFAULT_HIGH = 0.6

#: Boundary handling of the Gaussian smoothing. "nearest" repeats the outermost pixels
#: (MATLAB's ``edge`` does the same); "wrap" would invent a gradient between opposite
#: sides of the texture, and "constant" one against black, and either could become the
#: maximum that the relative thresholds are measured against.
_SMOOTHING_MODE = "nearest"
#: The Gaussian kernel is cut at this many sigmas: scikit-image's default, restated so
#: that our magnitude is computed exactly like the one ``skimage.feature.canny``
#: thresholds.
_GAUSSIAN_TRUNCATE = 4.0
#: Below this maximum gradient magnitude (luminance on 0..255) the texture is flat: the
#: magnitude is rounding noise, which relative thresholds would otherwise turn into
#: borders. A one-level step of the blue channel (the smallest weight) gives about
#: 0.35 / sigma, so no real variation is lost.
_FLAT_GRADIENT = 1e-9

_CANNY_PARAMS = ("sigma", "low", "high")

#: Colours of :func:`border_image_with_edges`.
_BORDER_RGB = (255, 255, 255)
_PENALISED_RGB = (255, 0, 0)
_OTHER_RGB = (80, 80, 80)


# -- public API ----------------------------------------------------------------------------

def texture_borders(texture: np.ndarray, sigma: float = DEFAULT_SIGMA,
                    low: float = DEFAULT_LOW, high: float = DEFAULT_HIGH) -> np.ndarray:
    """Canny borders of a texture's luminance (the paper's ``EdgeDetection(Texture)``).

    Parameters
    ----------
    texture : ndarray of shape (h, w, 3) or (h, w, 4) uint8
        The texture, row 0 at the top. An alpha channel is ignored.
    sigma : float
        Standard deviation of the Gaussian smoothing, in pixels (``>= 0``).
    low, high : float
        Hysteresis thresholds as fractions of the image's maximum gradient magnitude,
        ``0 <= low <= high <= 1``.

    Returns
    -------
    ndarray of shape (h, w) bool
        True on border pixels. The outermost ring of pixels is never a border
        (``skimage.feature.canny`` cannot tell what lies beyond the image), and a texture
        of constant luminance has no borders.

    Notes
    -----
    ``skimage.feature.canny`` takes absolute thresholds (or quantiles, which are not the
    same thing); MATLAB's ``edge``, which the paper used, divides the gradient magnitude
    by its maximum first. This function computes that maximum on exactly the magnitude
    canny thresholds -- luminance on 0..255 as float64 (canny does not rescale float
    input), smoothed by ``scipy.ndimage.gaussian_filter`` with the same sigma, boundary
    mode and truncation, then ``sqrt(i**2 + j**2)`` of ``scipy.ndimage.sobel`` along
    both axes, in canny's order of operations -- and thresholds at ``low * max`` and
    ``high * max``. The gradients are computed once and handed to scikit-image's own
    non-maximum suppression; where that private function is missing (another release),
    ``skimage.feature.canny`` runs on the same thresholds and computes them again. The
    borders are therefore invariant to the texture's contrast. Canny's smoothing and
    derivative filters differ from MATLAB's (a Gaussian then Sobel rather than
    derivative-of-Gaussian kernels), so borders match the paper's in spirit, not pixel
    for pixel. scikit-image passes the low threshold through a 32-bit float, so it is
    exact to about 1e-7 relative.
    """
    _check_canny_params(sigma, low, high)
    gray = _texture_luminance(texture)
    isobel, jsobel, magnitude = _gradients(gray, sigma)
    max_magnitude = float(magnitude.max())
    if max_magnitude < _FLAT_GRADIENT:
        return np.zeros(gray.shape, bool)
    suppress = _skimage_suppression()
    if suppress is None:
        from skimage.feature import canny

        return canny(gray, sigma=sigma, low_threshold=low * max_magnitude,
                     high_threshold=high * max_magnitude, mode=_SMOOTHING_MODE)
    inside = np.zeros(gray.shape, bool)  # the outer ring is never a border
    inside[1:-1, 1:-1] = True
    ridges = suppress(isobel, jsobel, magnitude, inside, low * max_magnitude)
    return _hysteresis(ridges, high * max_magnitude)


def segment_pixels(uv0, uv1, shape: tuple[int, int]) -> np.ndarray:
    """The pixels a UV segment passes through, in order from ``uv0`` to ``uv1``.

    Parameters
    ----------
    uv0, uv1 : array_like of shape (2,) float
        Endpoints in UV (origin bottom-left; values outside [0, 1] wrap).
    shape : (int, int)
        ``(h, w)`` of the texture.

    Returns
    -------
    ndarray of shape (p, 2) int64
        ``(row, col)`` of each pixel visited, row 0 at the top. A pixel appears once per
        visit (a segment longer than the texture can return to a pixel).

    Notes
    -----
    The walk is Amanatides & Woo's grid traversal: from the endpoint's pixel it moves to
    whichever neighbour the segment enters first, so it visits exactly the pixels whose
    interior the segment passes through, both endpoint pixels included. Where an
    endpoint lies on a pixel edge, its pixel is the one on the segment's side. Where the
    segment passes exactly through a pixel corner, the walk steps diagonally (the two
    pixels that only touch the corner are not visited). A segment lying on a pixel edge
    is assigned to the pixels on its +u / +v side.
    """
    h, w = _check_shape(shape)
    p0, p1 = _check_uv_pair(uv0, uv1)
    x0, y0, x1, y1 = p0[0] * w, p0[1] * h, p1[0] * w, p1[1] * h
    n = _cell_count(x0, x1) + _cell_count(y0, y1) - 1
    out = np.empty((n, 2), np.int64)
    count, _ = _walk(x0, y0, x1, y1, np.zeros((h, w), np.bool_), out)
    return out[:count]


def segment_crosses_border(uv0, uv1, borders: np.ndarray) -> bool:
    """Whether one UV segment passes through a border pixel.

    Parameters
    ----------
    uv0, uv1 : array_like of shape (2,) float
        Endpoints in UV (origin bottom-left; values outside [0, 1] wrap).
    borders : ndarray of shape (h, w) bool
        Border pixels, row 0 at the top (as from :func:`texture_borders`).

    Returns
    -------
    bool

    See Also
    --------
    segments_cross_border : the same for many segments; segment_pixels : the walk.
    """
    p0, p1 = _check_uv_pair(uv0, uv1)
    return bool(segments_cross_border(p0[None], p1[None], borders)[0])


def segments_cross_border(uv0: np.ndarray, uv1: np.ndarray,
                          borders: np.ndarray) -> np.ndarray:
    """Whether each UV segment passes through a border pixel.

    Parameters
    ----------
    uv0, uv1 : ndarray of shape (k, 2) float
        Segment endpoints in UV (origin bottom-left; values outside [0, 1] wrap).
    borders : ndarray of shape (h, w) bool
        Border pixels, row 0 at the top.

    Returns
    -------
    ndarray of shape (k,) bool

    Notes
    -----
    Walks the pixels of :func:`segment_pixels` and stops at the first border pixel; the
    cost of a segment is proportional to its length in pixels.
    """
    borders = _check_borders(borders)
    uv0 = _check_uv_array(uv0, "uv0")
    uv1 = _check_uv_array(uv1, "uv1")
    if uv0.shape != uv1.shape:
        raise ValueError(f"uv0 and uv1 must have the same shape, got {uv0.shape} and "
                         f"{uv1.shape}; pass one row per segment in each")
    return _segments_cross_border(uv0, uv1, borders)


def edge_penalties(mesh: Mesh, borders: np.ndarray | None = None,
                   **canny_params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's texture penalty of every welded edge (Eqs. 1-2, Figure 3).

    Parameters
    ----------
    mesh : Mesh
    borders : ndarray of shape (h, w) bool, optional
        Border pixels, row 0 at the top. By default they are detected in
        ``mesh.texture`` with :func:`texture_borders`.
    **canny_params
        ``sigma``, ``low``, ``high`` for :func:`texture_borders` (not with ``borders``).

    Returns
    -------
    edges : ndarray of shape (e, 2) int32
        ``mesh.welded.edges``.
    penalty : ndarray of shape (e,) float64
        For a crossing edge, the area of its incident faces over the area of the mesh
        (the term added to the collapse cost in Eq. 2); 0 for the others.
    crossing : ndarray of shape (e,) bool
        Whether the edge crosses a border (the paper's set E).

    Notes
    -----
    A seam edge has different UVs in each incident face. It is tested in every face's
    own UV chart and crosses if any of its images crosses a border: the texture is
    distorted wherever any side of the edge covers a border.

    Areas are computed on positions scaled so the bounding-box diagonal is 1. The ratio
    of Eq. 2 does not depend on scale; the scaling keeps the areas themselves on the same
    footing as the other cost terms of the suite, which are computed on normalised
    geometry, and keeps huge or tiny models away from overflow and underflow.

    A mesh without UVs, or without a texture when ``borders`` is not given, has no
    penalties (all zero, nothing crossing); so has a mesh of zero total area.
    """
    borders = _checked_inputs(borders, canny_params)
    welded = mesh.welded
    n_edges = len(welded.edges)
    penalty = np.zeros(n_edges)
    crossing = np.zeros(n_edges, bool)
    if mesh.uv is None or (borders is None and mesh.texture is None) or n_edges == 0:
        return welded.edges, penalty, crossing
    if not np.isfinite(mesh.uv).all():
        raise ValueError(f"{mesh.name}: mesh.uv has NaN or infinite values; load the mesh "
                         "through bench.io.validate.build_mesh or fix its UVs")
    if borders is None:
        borders = texture_borders(mesh.texture, **canny_params)

    render, edge_of, face_of = _half_edges(mesh)
    crossing = _crossing_edges(mesh.uv, render, edge_of, n_edges, borders)
    incident, total = _incident_areas(mesh, edge_of, face_of, n_edges)
    if total > 0:
        penalty[crossing] = incident[crossing] / total  # Eq. 2's added term
    return welded.edges, penalty, crossing


def _checked_inputs(borders: np.ndarray | None, canny_params: dict) -> np.ndarray | None:
    """:func:`edge_penalties`' ``borders`` (checked, or None) and Canny parameters,
    each problem a one-line error."""
    unknown = sorted(set(canny_params) - set(_CANNY_PARAMS))
    if unknown:
        raise ValueError(f"unknown Canny parameter(s) {unknown}; the parameters are "
                         f"{list(_CANNY_PARAMS)}")
    if borders is not None and canny_params:
        raise ValueError("pass either borders or Canny parameters, not both: the "
                         "parameters only apply when borders are detected in the texture")
    if canny_params:
        p = {"sigma": DEFAULT_SIGMA, "low": DEFAULT_LOW, "high": DEFAULT_HIGH}
        _check_canny_params(**(p | canny_params))
    return None if borders is None else _check_borders(borders)


def border_image_with_edges(mesh: Mesh, borders: np.ndarray, crossing: np.ndarray,
                            *, scale: int = 1) -> np.ndarray:
    """The border image with the mesh's UV edges drawn on it.

    Parameters
    ----------
    mesh : Mesh
    borders : ndarray of shape (h, w) bool
        Border pixels, row 0 at the top.
    crossing : ndarray of shape (e,) bool
        Per welded edge (``mesh.welded.edges``), as returned by :func:`edge_penalties`.
    scale : int
        Magnification (nearest-neighbour) of the border image, so thin lines stay
        legible on small textures.

    Returns
    -------
    ndarray of shape (h * scale, w * scale, 3) uint8
        Borders white on black, the UV segments of penalised edges red and of the other
        edges dark gray. Gray lines are drawn under the borders, red lines over them.

    Notes
    -----
    Every side of a seam edge is drawn in its own chart. A segment is drawn in the
    texture tile of its first endpoint and its neighbours on the +u and +v side, which
    shows every segment shorter than the texture; longer ones are clipped.
    """
    from PIL import Image, ImageDraw

    borders = _check_borders(borders)
    crossing = np.asarray(crossing)
    n_edges = len(mesh.welded.edges)
    if crossing.dtype != bool or crossing.shape != (n_edges,):
        raise ValueError(f"crossing must be a bool array of shape ({n_edges},), one per "
                         f"welded edge, got {crossing.dtype} {crossing.shape}; pass the "
                         "third result of edge_penalties(mesh)")
    if int(scale) != scale or scale < 1:
        raise ValueError(f"scale must be a positive integer, got {scale!r}")
    scale = int(scale)

    h, w = borders.shape
    white = np.kron(borders, np.ones((scale, scale), bool))
    rgb = np.zeros(white.shape + (3,), np.uint8)
    if mesh.uv is None or n_edges == 0:
        rgb[white] = _BORDER_RGB
        return rgb

    render, edge_of, _ = _half_edges(mesh)
    segments = _draw_coordinates(mesh.uv[render[:, 0]], mesh.uv[render[:, 1]], h * scale,
                                 w * scale)
    hit = crossing[edge_of]
    image = Image.fromarray(rgb)
    _draw_segments(ImageDraw.Draw(image), segments[~hit], _OTHER_RGB, h * scale, w * scale)
    rgb = np.array(image)
    rgb[white] = _BORDER_RGB
    image = Image.fromarray(rgb)
    _draw_segments(ImageDraw.Draw(image), segments[hit], _PENALISED_RGB, h * scale,
                   w * scale)
    return np.array(image)


# -- stages of edge_penalties ---------------------------------------------------------------

def _half_edges(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every face's three edges: render endpoints (3m, 2), welded edge (3m,), face (3m,)."""
    welded = mesh.welded
    corners = np.array([[0, 1], [1, 2], [2, 0]])
    render = mesh.faces[:, corners].reshape(-1, 2)
    key = np.sort(welded.faces[:, corners].reshape(-1, 2), axis=1).astype(np.int64)
    # Rows of welded.edges are sorted and unique, so an integer code finds them.
    n = max(welded.n_vertices, 1)
    codes = welded.edges[:, 0].astype(np.int64) * n + welded.edges[:, 1]
    edge_of = np.searchsorted(codes, key[:, 0] * n + key[:, 1])
    face_of = np.repeat(np.arange(mesh.n_faces), 3)
    return render, edge_of, face_of


def _crossing_edges(uv, render, edge_of, n_edges, borders) -> np.ndarray:
    """Per welded edge: does any face's UV image of it cross a border?"""
    # Faces that share render vertices along an edge share its UV segment: walk each
    # distinct (unordered) render segment once.
    pair = np.sort(render, axis=1).astype(np.int64)
    n = len(uv)
    segment, segment_of = np.unique(pair[:, 0] * n + pair[:, 1], return_inverse=True)
    hit = _segments_cross_border(uv[segment // n], uv[segment % n], borders)
    # "If e collides with a border of M then Insert(e, E)" (Figure 3), for any side of e.
    return np.bincount(edge_of, weights=hit[segment_of.reshape(-1)],
                       minlength=n_edges) > 0


def _incident_areas(mesh, edge_of, face_of, n_edges) -> tuple[np.ndarray, float]:
    """Per welded edge, the area of its faces; and the mesh's total area A_T (Eq. 1)."""
    diagonal = mesh.diagonal
    positions = mesh.positions / diagonal if diagonal > 0 else mesh.positions
    areas = face_areas(positions, mesh.faces)
    incident = np.bincount(edge_of, weights=areas[face_of], minlength=n_edges)
    return incident, float(areas.sum())  # Eq. 1: A_T = sum of a_i


# -- the traversal kernels ---------------------------------------------------------------

@njit(cache=True)
def _end_cells(a0, a1):
    """First and last cell (integer interval ``[c, c + 1)``) of the segment a0 -> a1 on
    one axis. An endpoint exactly on a cell edge belongs to the cell the segment lies in."""
    c0 = math.floor(a0)
    c1 = math.floor(a1)
    if a1 < a0 and c0 == a0:
        c0 -= 1
    if a1 > a0 and c1 == a1:
        c1 -= 1
    return c0, c1


@njit(cache=True)
def _walk(x0, y0, x1, y1, borders, out):
    """Amanatides-Woo traversal of the segment (x0, y0) -> (x1, y1) in texel units
    (x = u w, y = v h, y up). Records (row, col) of each pixel into ``out`` (p, 2) int64
    when it has rows, else stops at the first border pixel. Returns (pixels, hit)."""
    h, w = borders.shape
    cx, ex = _end_cells(x0, x1)
    cy, ey = _end_cells(y0, y1)
    dx = x1 - x0
    dy = y1 - y0
    sx = 1 if ex >= cx else -1
    sy = 1 if ey >= cy else -1
    nx = abs(ex - cx)
    ny = abs(ey - cy)
    record = out.shape[0] > 0
    count = 0
    hit = False
    while True:
        row = h - 1 - cy % h  # Python modulo: wraps negative cells too
        col = cx % w
        if record:
            out[count, 0] = row
            out[count, 1] = col
        count += 1
        if borders[row, col]:
            hit = True
            if not record:
                return count, hit
        if nx == 0 and ny == 0:
            return count, hit
        # Parameter t in [0, 1] at which the segment leaves the current cell across a
        # vertical (tx) or horizontal (ty) pixel edge; computed from the endpoint each
        # time, so an exact corner crossing gives tx == ty and one diagonal step.
        tx = math.inf
        ty = math.inf
        if nx > 0:
            tx = ((cx + 1 if sx > 0 else cx) - x0) / dx
        if ny > 0:
            ty = ((cy + 1 if sy > 0 else cy) - y0) / dy
        if tx <= ty:
            cx += sx
            nx -= 1
        if ty <= tx:
            cy += sy
            ny -= 1


@njit(cache=True)
def _segments_cross_border(uv0, uv1, borders):
    """(k, 2) float64, (k, 2) float64, (h, w) bool -> (k,) bool."""
    h, w = borders.shape
    out = np.zeros(uv0.shape[0], np.bool_)
    no_record = np.empty((0, 2), np.int64)
    for i in range(uv0.shape[0]):
        _, hit = _walk(uv0[i, 0] * w, uv0[i, 1] * h, uv1[i, 0] * w, uv1[i, 1] * h,
                       borders, no_record)
        out[i] = hit
    return out


def _cell_count(a0: float, a1: float) -> int:
    """Number of cells the segment a0 -> a1 spans on one axis (as :func:`_end_cells`)."""
    c0, c1 = _end_cells(a0, a1)
    return abs(int(c1) - int(c0)) + 1


# -- drawing -----------------------------------------------------------------------------

def _draw_coordinates(uv0, uv1, h, w) -> np.ndarray:
    """(k, 4) pixel-centre coordinates (x0, y0, x1, y1) of UV segments, shifted so the
    first endpoint lies in the unit tile."""
    shift = np.floor(uv0)
    a = uv0 - shift
    b = uv1 - shift
    to_x = lambda u: u * w - 0.5  # noqa: E731
    to_y = lambda v: (1.0 - v) * h - 0.5  # noqa: E731
    return np.column_stack([to_x(a[:, 0]), to_y(a[:, 1]), to_x(b[:, 0]), to_y(b[:, 1])])


def _draw_segments(draw, segments: np.ndarray, colour, height: int, width: int) -> None:
    """Draw each segment in its tile and the tiles to its +u and +v side."""
    for du, dv in ((0, 0), (-width, 0), (0, height), (-width, height)):
        for x0, y0, x1, y1 in segments:
            draw.line([(x0 + du, y0 + dv), (x1 + du, y1 + dv)], fill=colour)


# -- validation -----------------------------------------------------------------------------

def _check_canny_params(sigma, low, high) -> None:
    for name, value in (("sigma", sigma), ("low", low), ("high", high)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating,
                                                             np.integer)):
            raise ValueError(f"{name} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value!r}")
    if sigma < 0:
        raise ValueError(f"sigma must be >= 0 (pixels of Gaussian smoothing), got {sigma}")
    if not 0 <= low <= high <= 1:
        raise ValueError(f"thresholds are fractions of the maximum gradient magnitude and "
                         f"need 0 <= low <= high <= 1, got low={low}, high={high}")


def _texture_luminance(texture) -> np.ndarray:
    texture = np.asarray(texture)
    if texture.ndim != 3 or texture.shape[2] not in (3, 4):
        raise ValueError(f"texture must have shape (h, w, 3) or (h, w, 4), got "
                         f"{texture.shape}; stack a gray image as np.dstack([g, g, g])")
    if texture.dtype != np.uint8:
        raise ValueError(f"texture must be uint8, got {texture.dtype}; convert float "
                         "images in 0..1 with (255 * x).round().astype(np.uint8)")
    if texture.shape[0] == 0 or texture.shape[1] == 0:
        raise ValueError(f"texture is empty, shape {texture.shape}")
    return luminance(texture[..., :3])


def _gradients(gray: np.ndarray, sigma: float):
    """The Sobel derivatives along rows and columns and the gradient magnitude that
    ``skimage.feature.canny`` computes, each (h, w) float64.

    Same operations in the same order as canny (no mask, mode "nearest"): Gaussian
    smoothing, Sobel along both axes, sqrt(i^2 + j^2), so the values are bit-identical.
    """
    smoothed = ndi.gaussian_filter(gray, sigma, mode=_SMOOTHING_MODE, cval=0.0,
                                   truncate=_GAUSSIAN_TRUNCATE)
    jsobel = ndi.sobel(smoothed, axis=1)
    isobel = ndi.sobel(smoothed, axis=0)
    magnitude = isobel * isobel
    magnitude += jsobel * jsobel
    return isobel, jsobel, np.sqrt(magnitude)


def _gradient_magnitude(gray: np.ndarray, sigma: float) -> np.ndarray:
    """The gradient magnitude ``skimage.feature.canny`` thresholds, (h, w) float64."""
    return _gradients(gray, sigma)[2]


def _skimage_suppression():
    """scikit-image's non-maximum suppression, the step of ``skimage.feature.canny``
    after the gradients (``(isobel, jsobel, magnitude, mask, low) -> magnitude`` at the
    ridges at or above ``low``, 0 elsewhere); None where a release does not have it."""
    try:
        from skimage.feature._canny_cy import _nonmaximum_suppression_bilinear
    except ImportError:
        return None
    return _nonmaximum_suppression_bilinear


def _hysteresis(ridges: np.ndarray, high: float) -> np.ndarray:
    """The ridge pixels (``ridges > 0``) in 8-connected groups that reach ``high``."""
    candidates = ridges > 0
    groups, count = ndi.label(candidates, np.ones((3, 3), bool))
    if count == 0:
        return candidates
    strong = np.zeros(count + 1, bool)
    strong[groups[candidates & (ridges >= high)]] = True
    return strong[groups]


def _check_borders(borders) -> np.ndarray:
    borders = np.asarray(borders)
    if borders.ndim != 2 or borders.shape[0] == 0 or borders.shape[1] == 0:
        raise ValueError(f"borders must be a non-empty (h, w) array, got shape "
                         f"{borders.shape}")
    if borders.dtype != bool:
        raise ValueError(f"borders must be a bool array, got {borders.dtype}; pass e.g. "
                         "borders > 0 or texture_borders(texture)")
    return np.ascontiguousarray(borders)


def _check_shape(shape) -> tuple[int, int]:
    try:
        h, w = (int(s) for s in shape)
    except (TypeError, ValueError):
        raise ValueError(f"shape must be (h, w), got {shape!r}") from None
    if h < 1 or w < 1:
        raise ValueError(f"shape must be positive, got {shape!r}")
    return h, w


def _check_uv_pair(uv0, uv1) -> tuple[np.ndarray, np.ndarray]:
    p0 = np.asarray(uv0, dtype=np.float64)
    p1 = np.asarray(uv1, dtype=np.float64)
    if p0.shape != (2,) or p1.shape != (2,):
        raise ValueError(f"uv0 and uv1 must each be one (u, v) pair, got shapes {p0.shape}"
                         f" and {p1.shape}; use segments_cross_border for many")
    if not (np.isfinite(p0).all() and np.isfinite(p1).all()):
        raise ValueError("uv0 and uv1 must be finite")
    return p0, p1


def _check_uv_array(uv, name: str) -> np.ndarray:
    uv = np.ascontiguousarray(uv, dtype=np.float64)
    if uv.ndim != 2 or uv.shape[1] != 2:
        raise ValueError(f"{name} must have shape (k, 2), got {uv.shape}")
    if not np.isfinite(uv).all():
        raise ValueError(f"{name} has NaN or infinite values; drop those segments first")
    return uv


@njit(cache=True)
def _canny_penalty(a, b, surface, borders, per_area, efaces, no_record):
    """González et al. 2007, equations 1-2: (area of the edge's faces) × ``per_area``
    when the edge's UV segment, in any of its faces' charts, crosses a texture border
    (``borders``); 0 otherwise. ``per_area`` is 1 / the original's total area (equation
    2's ratio) or that ratio in the base cost's units (``Terms.canny_per_area``).
    ``surface`` is the mesh's (P, F, FW, uv, falive, vhead, cnext)."""
    P, F, FW, uv, falive, vhead, cnext = surface
    k = _edge_faces(a, b, F, vhead, cnext, falive, efaces)
    h, w = borders.shape
    for i in range(min(k, efaces.shape[0])):
        wa, wb = corner_wedges(F, FW, efaces[i], a, b)
        _, hit = _walk(uv[wa, 0] * w, uv[wa, 1] * h, uv[wb, 0] * w, uv[wb, 1] * h,
                       borders, no_record)
        if hit:
            return _faces_area(k, efaces, P, F) * per_area
    return 0.0
