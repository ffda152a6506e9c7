"""Tests of methods.engine.terms.canny: Canny texture borders, UV-segment traversal, edge penalties.

The traversal kernel is checked against two slow pure-Python oracles: an exact one that
cuts the segment at every pixel edge it crosses and takes the pixel of each piece's
midpoint, and a dense one that samples 10 001 points along the segment.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.core.mesh import Mesh
from methods.engine.terms import canny
from methods.engine.terms.canny import (
    border_image_with_edges,
    edge_penalties,
    segment_crosses_border,
    segment_pixels,
    segments_cross_border,
    texture_borders,
)

CORNER_TOLERANCE = 1e-9


# -- textures and meshes drawn by hand -----------------------------------------------------

def half_black_texture(size: int = 8) -> np.ndarray:
    """(size, size, 3) uint8: left half black, right half white."""
    texture = np.zeros((size, size, 3), np.uint8)
    texture[:, size // 2:] = 255
    return texture


#: The unit square in the plane z = 0, two faces, UVs inset into [0.3, 0.7]^2 on the
#: half-black texture (8x8: pixel columns 0-3 black, 4-7 white). Vertices are numbered
#: in sorted position order, so welded and render indices agree::
#:
#:     v=0.7  1-------3        welded edges    faces (0,2,3), (0,3,1), area 1/2 each
#:            |     / |        (0,1) left      u*8 runs from 2.4 to 5.6: pixel columns 2-5,
#:            |   /   |        (0,2) bottom    v*8 from 2.4 to 5.6: rows 2-5 from the top.
#:            | /     |        (0,3) diagonal  The step is between columns 3 and 4, where
#:     v=0.3  0-------2        (1,3) top       the border is; the left edge stays in
#:          u=0.3   u=0.7      (2,3) right     column 2 and the right edge in column 5.
#:
#: Crossing: bottom, diagonal, top. Penalties (Eq. 2): area of incident faces over the
#: total area 1: bottom 1/2, diagonal 1/2 + 1/2 = 1, top 1/2, left and right 0.
SQUARE_POSITIONS = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]], np.float64)
SQUARE_FACES = np.array([[0, 2, 3], [0, 3, 1]], np.int32)
SQUARE_UV = np.array([[0.3, 0.3], [0.3, 0.7], [0.7, 0.3], [0.7, 0.7]])
SQUARE_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 3], [2, 3]])
SQUARE_CROSSING = np.array([False, True, True, True, False])
SQUARE_PENALTY = np.array([0.0, 0.5, 1.0, 0.5, 0.0])


def square_mesh(scale: float = 1.0, texture=True) -> Mesh:
    return Mesh(SQUARE_POSITIONS * scale, SQUARE_FACES, uv=SQUARE_UV,
                texture=half_black_texture() if texture else None)


#: Two faces sharing the diagonal, which is a UV seam: each face has its own chart in a
#: 10x10 texture (pixel column c covers u in [c/10, (c+1)/10))::
#:
#:     positions            left chart (face 0,2,1)      right chart (face 3,4,5)
#:     0-----1 3            0 (.05,.95)  1 (.45,.95)                  3 (.95,.95)
#:     |    /  /|            |        /                             /  |
#:     |  /  /  |            |     /                             /     |
#:     2 4-----5            2 (.05,.05)                  4 (.55,.05)---5 (.95,.05)
#:
#: Welded vertices (positions sorted): (0,0)->0, (0,1)->1, (1,0)->2, (1,1)->3; welded
#: edges (0,1) left, (0,2) bottom, (0,3) diagonal (the seam), (1,3) top, (2,3) right.
#: The diagonal spans columns 0-4 in the left chart and columns 5-9 in the right one.
SEAM_POSITIONS = np.array([[0, 1, 0], [1, 1, 0], [0, 0, 0],
                           [1, 1, 0], [0, 0, 0], [1, 0, 0]], np.float64)
SEAM_FACES = np.array([[0, 2, 1], [3, 4, 5]], np.int32)
SEAM_UV = np.array([[0.05, 0.95], [0.45, 0.95], [0.05, 0.05],
                    [0.95, 0.95], [0.55, 0.05], [0.95, 0.05]])
SEAM_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 3], [2, 3]])


def column_borders(column: int, size: int = 10) -> np.ndarray:
    borders = np.zeros((size, size), bool)
    borders[:, column] = True
    return borders


# -- slow oracles --------------------------------------------------------------------------

def pixel_of(x: float, y: float, h: int, w: int) -> tuple[int, int]:
    """Pixel (row, col) containing the point (x, y) = (u w, (1 - v) h), y down."""
    return math.floor(y) % h, math.floor(x) % w


def to_texels(uv0, uv1, h, w):
    return uv0[0] * w, (1 - uv0[1]) * h, uv1[0] * w, (1 - uv1[1]) * h


def exact_pieces(uv0, uv1, h, w) -> list[tuple[tuple[int, int], float]]:
    """The segment cut at every pixel edge: (pixel, parameter length) of each piece."""
    x0, y0, x1, y1 = to_texels(uv0, uv1, h, w)
    cuts = {0.0, 1.0}
    for a0, a1 in ((x0, x1), (y0, y1)):
        if a1 != a0:
            lo, hi = sorted((a0, a1))
            cuts.update((k - a0) / (a1 - a0) for k in range(math.ceil(lo), math.floor(hi) + 1))
    cuts = sorted(t for t in cuts if 0.0 <= t <= 1.0)
    pieces = []
    for ta, tb in zip(cuts[:-1], cuts[1:]):
        if tb - ta > 1e-12:
            t = 0.5 * (ta + tb)
            pieces.append((pixel_of(x0 + t * (x1 - x0), y0 + t * (y1 - y0), h, w), tb - ta))
    if not pieces:  # a point
        pieces.append((pixel_of(x0, y0, h, w), 0.0))
    return pieces


def exact_pixels(uv0, uv1, h, w) -> set:
    return {pixel for pixel, _ in exact_pieces(uv0, uv1, h, w)}


def sampled_pixels(uv0, uv1, h, w, samples: int = 10_001) -> set:
    x0, y0, x1, y1 = to_texels(uv0, uv1, h, w)
    t = np.linspace(0.0, 1.0, samples)
    rows = np.floor(y0 + t * (y1 - y0)).astype(int) % h
    cols = np.floor(x0 + t * (x1 - x0)).astype(int) % w
    return set(zip(rows.tolist(), cols.tolist()))


def near_corner_pixels(uv0, uv1, h, w, tolerance=CORNER_TOLERANCE) -> set:
    """The four pixels around every pixel corner within ``tolerance`` of the segment."""
    x0, y0, x1, y1 = to_texels(uv0, uv1, h, w)
    p0, d = np.array([x0, y0]), np.array([x1 - x0, y1 - y0])
    near = set()
    for cx in range(math.floor(min(x0, x1)), math.ceil(max(x0, x1)) + 1):
        for cy in range(math.floor(min(y0, y1)), math.ceil(max(y0, y1)) + 1):
            c = np.array([cx, cy], float)
            t = np.clip((c - p0) @ d / max(d @ d, 1e-300), 0.0, 1.0)
            if np.linalg.norm(p0 + t * d - c) < tolerance:
                near.update(pixel_of(cx + ox, cy + oy, h, w)
                            for ox in (-0.5, 0.5) for oy in (-0.5, 0.5))
    return near


def reference_crossing(uv0, uv1, borders) -> np.ndarray:
    """Slow segments_cross_border: any border pixel among the exact oracle's pixels."""
    h, w = borders.shape
    return np.array([any(borders[p] for p in exact_pixels(a, b, h, w))
                     for a, b in zip(uv0, uv1)], bool)


def dda_set(uv0, uv1, h, w) -> set:
    return set(map(tuple, segment_pixels(uv0, uv1, (h, w)).tolist()))


def random_segments(rng, k, lo=0.0, hi=1.0):
    return rng.uniform(lo, hi, (k, 2)), rng.uniform(lo, hi, (k, 2))


# -- texture_borders -----------------------------------------------------------------------

def test_step_edge_gives_borders_along_the_step():
    # 8x8, columns 0-3 black, 4-7 white. The gradient peaks on columns 3 and 4 (equal by
    # symmetry; non-maximum suppression keeps ties), and the outer ring is never a border:
    #     ........
    #     ...##...   (either or both of columns 3 and 4 in rows 1-6)
    #     ...##...
    borders = texture_borders(half_black_texture())
    assert borders.shape == (8, 8) and borders.dtype == bool
    assert not borders[:, [0, 1, 2, 5, 6, 7]].any()
    assert not borders[[0, 7]].any()
    assert borders[1:7, 3:5].any(axis=1).all()


def test_horizontal_step_edge():
    texture = np.zeros((12, 12, 3), np.uint8)
    texture[6:] = 200
    rows = np.nonzero(texture_borders(texture).any(axis=1))[0]
    assert set(rows.tolist()) <= {5, 6} and len(rows) > 0


def test_constant_texture_has_no_borders():
    for value in (0, 37, 255):
        texture = np.full((16, 16, 4), value, np.uint8)
        assert not texture_borders(texture).any()
        assert not texture_borders(texture, sigma=0.0, low=0.0, high=0.0).any()


def test_thresholds_are_invariant_to_contrast():
    rng = np.random.default_rng(3)
    blocks = rng.integers(0, 101, (6, 6, 3)).astype(np.uint8)
    texture = np.kron(blocks, np.ones((5, 5, 1), np.uint8))  # 30x30 of flat blocks
    noise = rng.integers(0, 20, texture.shape).astype(np.uint8)
    for image in (texture, texture + noise):
        borders = texture_borders(image)
        assert borders.any()
        np.testing.assert_array_equal(texture_borders(2 * image), borders)


def test_alpha_is_ignored():
    texture = half_black_texture(10)
    alpha = np.random.default_rng(0).integers(0, 256, (10, 10, 1)).astype(np.uint8)
    np.testing.assert_array_equal(texture_borders(np.concatenate([texture, alpha], 2)),
                                  texture_borders(texture))


def test_gradient_magnitude_is_the_one_canny_thresholds():
    # Same operations as skimage.feature.canny's own preprocessing, bit for bit.
    _canny = pytest.importorskip("skimage.feature._canny")
    if not hasattr(_canny, "_preprocess"):
        pytest.skip("scikit-image's private _preprocess changed")
    from scipy import ndimage as ndi

    gray = np.random.default_rng(1).uniform(0, 255, (20, 17))
    smoothed, _ = _canny._preprocess(gray, None, 0.75, "nearest", 0.0)
    i, j = ndi.sobel(smoothed, axis=0), ndi.sobel(smoothed, axis=1)
    np.testing.assert_array_equal(canny._gradient_magnitude(gray, 0.75), np.sqrt(i * i + j * j))


def _canny_at_relative_thresholds(texture, sigma, low, high):
    """The oracle: ``skimage.feature.canny`` itself, its thresholds taken relative to
    the maximum of the magnitude recomputed here from the smoothed image's Sobels."""
    from scipy import ndimage as ndi
    from skimage.feature import canny as skimage_canny

    gray = canny._texture_luminance(texture)
    smoothed = ndi.gaussian_filter(gray, sigma, mode="nearest", truncate=4.0)
    i, j = ndi.sobel(smoothed, axis=0), ndi.sobel(smoothed, axis=1)
    top = float(np.sqrt(i * i + j * j).max())
    if top < 1e-9:
        return np.zeros(gray.shape, bool)
    return skimage_canny(gray, sigma=sigma, low_threshold=low * top,
                         high_threshold=high * top, mode="nearest")


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 30), st.integers(1, 30), st.integers(1, 4), st.integers(0, 2**32 - 1),
       st.sampled_from([0.0, 0.75, 2.0]), st.floats(0, 1), st.floats(0, 1))
def test_texture_borders_are_canny_at_the_relative_thresholds(h, w, block, seed, sigma, a, b):
    # The gradients are computed once and passed to scikit-image's own suppression;
    # the result is canny's, bit for bit, over noise and flat blocks (long ridges, so
    # hysteresis has groups to keep and to drop), with and without that shortcut.
    rng = np.random.default_rng(seed)
    texture = np.kron(rng.integers(0, 256, (h, w, 3)),
                      np.ones((block, block, 1))).astype(np.uint8)
    low, high = min(a, b), max(a, b)
    expected = _canny_at_relative_thresholds(texture, sigma, low, high)
    borders = texture_borders(texture, sigma, low, high)
    assert borders.dtype == bool
    np.testing.assert_array_equal(borders, expected)
    shortcut = canny._skimage_suppression
    try:
        canny._skimage_suppression = lambda: None  # a release without the private step
        np.testing.assert_array_equal(texture_borders(texture, sigma, low, high), expected)
    finally:
        canny._skimage_suppression = shortcut


def test_hysteresis_keeps_the_groups_that_reach_the_high_threshold():
    ridges = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                       [0.0, 0.5, 0.0, 0.0, 0.5, 0.0],
                       [0.0, 0.0, 0.9, 0.0, 0.0, 0.5],
                       [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    # (1, 1) touches (2, 2) diagonally and is kept with it; (1, 4) and (2, 5) reach 0.5 only
    expected = np.zeros(ridges.shape, bool)
    expected[1, 1] = expected[2, 2] = True
    np.testing.assert_array_equal(canny._hysteresis(ridges, 0.8), expected)
    np.testing.assert_array_equal(canny._hysteresis(ridges, 0.5), ridges > 0)
    assert not canny._hysteresis(np.zeros((3, 3)), 0.5).any()


def test_high_threshold_is_relative_to_the_maximum_magnitude():
    # A strong step (0 -> 200, columns 4|5) and a weak one (200 -> 250, columns 9|10).
    # The weak border survives a high threshold just below its magnitude over the
    # maximum and disappears just above: the threshold is on the scale of our maximum.
    texture = np.zeros((12, 15, 3), np.uint8)
    texture[:, 5:] = 200
    texture[:, 10:] = 250
    magnitude = canny._gradient_magnitude(canny._texture_luminance(texture), 0.75)
    weak = np.zeros(magnitude.shape, bool)
    weak[:, 8:12] = True
    borders = texture_borders(texture, low=0.1, high=0.1)
    assert (borders & weak).any() and (borders & ~weak).any()
    relative = magnitude[borders & weak].max() / magnitude.max()
    assert 0.1 < relative < 0.5
    below = texture_borders(texture, low=0.1, high=relative * (1 - 1e-9))
    above = texture_borders(texture, low=0.1, high=relative * (1 + 1e-9))
    assert (below & weak).any() and not (above & weak).any()
    np.testing.assert_array_equal(above & ~weak, borders & ~weak)


def test_texture_borders_validation():
    texture = half_black_texture()
    with pytest.raises(ValueError, match="0 <= low <= high <= 1"):
        texture_borders(texture, low=0.7, high=0.6)
    with pytest.raises(ValueError, match="0 <= low <= high <= 1"):
        texture_borders(texture, low=0.5, high=1.5)
    with pytest.raises(ValueError, match="sigma must be >= 0"):
        texture_borders(texture, sigma=-1)
    with pytest.raises(ValueError, match="sigma must be finite"):
        texture_borders(texture, sigma=float("nan"))
    with pytest.raises(ValueError, match="low must be a number"):
        texture_borders(texture, low="0.5")
    with pytest.raises(ValueError, match=r"shape \(h, w, 3\) or \(h, w, 4\)"):
        texture_borders(texture[..., 0])
    with pytest.raises(ValueError, match="must be uint8"):
        texture_borders(texture / 255.0)
    with pytest.raises(ValueError, match="texture is empty"):
        texture_borders(np.zeros((0, 4, 3), np.uint8))


# -- the traversal ---------------------------------------------------------------------------

def test_traversal_matches_the_exact_oracle():
    rng = np.random.default_rng(7)
    for h, w, lo, hi in ((9, 13, 0.0, 1.0), (6, 5, -1.5, 2.5), (1, 4, -0.5, 1.5)):
        for a, b in zip(*random_segments(rng, 150, lo, hi)):
            dda, exact = dda_set(a, b, h, w), exact_pixels(a, b, h, w)
            assert exact <= dda
            assert dda - exact <= near_corner_pixels(a, b, h, w)


def test_traversal_matches_dense_sampling():
    rng = np.random.default_rng(11)
    h, w = 12, 10
    step = 1.0 / 10_000
    for a, b in zip(*random_segments(rng, 60, -0.5, 1.5)):
        dda, sampled = dda_set(a, b, h, w), sampled_pixels(a, b, h, w)
        assert sampled <= dda
        # Pixels the samples missed hold only a piece shorter than the sample spacing.
        chord = {}
        for pixel, length in exact_pieces(a, b, h, w):
            chord[pixel] = max(chord.get(pixel, 0.0), length)
        missed = dda - sampled
        assert all(chord.get(p, 0.0) < step for p in missed - near_corner_pixels(a, b, h, w))


def test_traversal_is_ordered_and_4_or_8_connected():
    rng = np.random.default_rng(5)
    for a, b in zip(*random_segments(rng, 50, 0.0, 1.0)):
        pixels = segment_pixels(a, b, (16, 16))
        assert tuple(pixels[0]) == pixel_of(a[0] * 16, (1 - a[1]) * 16, 16, 16)
        assert tuple(pixels[-1]) == pixel_of(b[0] * 16, (1 - b[1]) * 16, 16, 16)
        assert (np.abs(np.diff(pixels, axis=0)).max(axis=1) == 1).all()


def test_traversal_through_exact_corners_steps_diagonally():
    # The diagonal of an 8x8 texture passes through pixel corners only:
    #     .......#
    #     ......#.
    #     ...
    #     #.......
    pixels = segment_pixels((0.0, 0.0), (1.0, 1.0), (8, 8))
    np.testing.assert_array_equal(pixels, [[7 - i, i] for i in range(8)])
    np.testing.assert_array_equal(segment_pixels((1.0, 1.0), (0.0, 0.0), (8, 8)),
                                  pixels[::-1])


def test_endpoints_on_pixel_edges_take_the_pixel_the_segment_is_in():
    # u*8 from 2 to 5 at v = 0.55 (row 3): columns 2, 3, 4, not column 5; reversed the same.
    forward = segment_pixels((0.25, 0.55), (0.625, 0.55), (8, 8))
    np.testing.assert_array_equal(forward, [[3, 2], [3, 3], [3, 4]])
    np.testing.assert_array_equal(segment_pixels((0.625, 0.55), (0.25, 0.55), (8, 8)),
                                  forward[::-1])


def test_degenerate_segment_is_its_pixel():
    np.testing.assert_array_equal(segment_pixels((0.35, 0.35), (0.35, 0.35), (10, 10)), [[6, 3]])


def test_uvs_wrap():
    # Across u = 1: columns 7 then 0 of row 3; and an integer shift of both endpoints
    # visits the same pixels.
    np.testing.assert_array_equal(segment_pixels((0.95, 0.55), (1.05, 0.55), (8, 8)),
                                  [[3, 7], [3, 0]])
    np.testing.assert_array_equal(segment_pixels((-0.05, -0.45), (0.05, -0.45), (8, 8)),
                                  [[3, 7], [3, 0]])
    rng = np.random.default_rng(2)
    a, b = random_segments(rng, 30)
    shift = np.array([3.0, -2.0])
    for p, q in zip(a, b):
        assert dda_set(p, q, 7, 9) == dda_set(p + shift, q + shift, 7, 9)


def test_crossing_kernel_matches_the_slow_reference():
    rng = np.random.default_rng(13)
    borders = rng.random((9, 12)) < 0.04
    uv0, uv1 = random_segments(rng, 400, -1.0, 2.0)
    hits = segments_cross_border(uv0, uv1, borders)
    np.testing.assert_array_equal(hits, reference_crossing(uv0, uv1, borders))
    assert 0 < hits.sum() < len(hits)
    assert segment_crosses_border(uv0[0], uv1[0], borders) == hits[0]
    assert segments_cross_border(np.zeros((0, 2)), np.zeros((0, 2)), borders).shape == (0,)


def test_segment_validation():
    borders = np.zeros((4, 4), bool)
    with pytest.raises(ValueError, match="same shape"):
        segments_cross_border(np.zeros((3, 2)), np.zeros((2, 2)), borders)
    with pytest.raises(ValueError, match=r"uv0 must have shape \(k, 2\)"):
        segments_cross_border(np.zeros(2), np.zeros(2), borders)
    with pytest.raises(ValueError, match="NaN or infinite"):
        segments_cross_border(np.full((1, 2), np.nan), np.zeros((1, 2)), borders)
    with pytest.raises(ValueError, match="must be a bool array"):
        segments_cross_border(np.zeros((1, 2)), np.zeros((1, 2)), borders.astype(np.uint8))
    with pytest.raises(ValueError, match="non-empty"):
        segments_cross_border(np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((0, 3), bool))
    with pytest.raises(ValueError, match="one \\(u, v\\) pair"):
        segment_crosses_border(np.zeros((2, 2)), np.zeros(2), borders)
    with pytest.raises(ValueError, match="must be finite"):
        segment_pixels((0, np.inf), (0, 0), (4, 4))
    with pytest.raises(ValueError, match="shape must be positive"):
        segment_pixels((0, 0), (1, 1), (0, 4))


# -- edge_penalties ----------------------------------------------------------------------

def test_square_penalties():
    edges, penalty, crossing = edge_penalties(square_mesh())
    np.testing.assert_array_equal(edges, SQUARE_EDGES)
    np.testing.assert_array_equal(crossing, SQUARE_CROSSING)
    np.testing.assert_allclose(penalty, SQUARE_PENALTY, rtol=1e-12)


def test_penalties_are_scale_invariant():
    _, reference, crossing = edge_penalties(square_mesh())
    for scale in (1e-3, 1000.0):
        _, penalty, scaled_crossing = edge_penalties(square_mesh(scale))
        np.testing.assert_array_equal(scaled_crossing, crossing)
        np.testing.assert_allclose(penalty, reference, rtol=1e-12)


@pytest.mark.parametrize("column, expected", [
    (8, [False, True, True, False, False]),   # right chart only: bottom and the seam
    (2, [False, False, True, True, False]),   # left chart only: top and the seam
    (0, [True, False, True, True, False]),    # left chart's column 0: left, seam, top
])
def test_seam_edge_crosses_if_either_chart_does(column, expected):
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV)
    edges, penalty, crossing = edge_penalties(mesh, column_borders(column))
    np.testing.assert_array_equal(edges, SEAM_EDGES)
    assert mesh.welded.seam.tolist() == [False, False, True, False, False]
    np.testing.assert_array_equal(crossing, expected)
    # Each face has area 1/2 of a total of 1; the seam has both faces.
    areas = np.array([0.5, 0.5, 1.0, 0.5, 0.5])
    np.testing.assert_allclose(penalty, np.where(expected, areas, 0.0), rtol=1e-12)


def test_crossing_matches_a_per_face_loop():
    # Reference: for every face and each of its edges, test that face's UV segment.
    rng = np.random.default_rng(17)
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=rng.uniform(-0.5, 1.5, (6, 2)))
    borders = rng.random((7, 5)) < 0.2
    edges, _, crossing = edge_penalties(mesh, borders)
    welded = mesh.welded
    expected = np.zeros(len(edges), bool)
    for face, welded_face in zip(mesh.faces, welded.faces):
        for i, j in ((0, 1), (1, 2), (2, 0)):
            key = sorted((welded_face[i], welded_face[j]))
            row = np.nonzero((edges == key).all(axis=1))[0][0]
            expected[row] |= reference_crossing([mesh.uv[face[i]]], [mesh.uv[face[j]]],
                                                borders)[0]
    np.testing.assert_array_equal(crossing, expected)


def test_untextured_meshes_have_no_penalties():
    for mesh in (square_mesh(texture=False),
                 Mesh(SQUARE_POSITIONS, SQUARE_FACES, texture=half_black_texture())):
        edges, penalty, crossing = edge_penalties(mesh)
        assert len(edges) == 5
        assert not crossing.any() and not penalty.any() and penalty.dtype == np.float64
    # Without UVs even explicit borders cannot be crossed.
    mesh = Mesh(SQUARE_POSITIONS, SQUARE_FACES)
    assert not edge_penalties(mesh, column_borders(3, 8))[2].any()
    # Explicit borders stand in for a missing texture.
    np.testing.assert_array_equal(
        edge_penalties(square_mesh(texture=False), texture_borders(half_black_texture()))[2],
        SQUARE_CROSSING)


def test_canny_parameters_are_passed_on():
    mesh = square_mesh()
    params = {"sigma": 1.5, "low": 0.2, "high": 0.3}
    by_params = edge_penalties(mesh, **params)
    by_borders = edge_penalties(mesh, texture_borders(mesh.texture, **params))
    for a, b in zip(by_params, by_borders):
        np.testing.assert_array_equal(a, b)
    _, _, crossing = edge_penalties(mesh, low=0.9, high=0.95)
    np.testing.assert_array_equal(crossing, SQUARE_CROSSING)


def test_edge_penalties_validation():
    mesh = square_mesh()
    with pytest.raises(ValueError, match=r"unknown Canny parameter\(s\) \['threshold'\]"):
        edge_penalties(mesh, threshold=0.5)
    with pytest.raises(ValueError, match="either borders or Canny parameters"):
        edge_penalties(mesh, column_borders(3, 8), sigma=1.0)
    with pytest.raises(ValueError, match="0 <= low <= high <= 1"):
        edge_penalties(square_mesh(texture=False), low=0.9)
    with pytest.raises(ValueError, match="NaN or infinite"):
        edge_penalties(Mesh(SQUARE_POSITIONS, SQUARE_FACES, uv=np.full((4, 2), np.nan),
                            texture=half_black_texture()))


# -- border_image_with_edges ---------------------------------------------------------------

RED, GRAY, WHITE = (255, 0, 0), (80, 80, 80), (255, 255, 255)


def colour_mask(image, colour):
    return (image == np.array(colour, np.uint8)).all(axis=2)


def test_border_image_draws_penalised_edges_red():
    mesh = square_mesh()
    borders = texture_borders(mesh.texture)
    _, _, crossing = edge_penalties(mesh)
    image = border_image_with_edges(mesh, borders, crossing, scale=4)
    assert image.shape == (32, 32, 3) and image.dtype == np.uint8
    assert colour_mask(image, RED).any() and colour_mask(image, GRAY).any()
    assert colour_mask(image, WHITE).any()
    # The left edge (u = 0.3, gray) runs down upscaled column 0.3 * 32 - 0.5 ~ 9.
    assert colour_mask(image, GRAY)[12:20, 9].all()
    none = border_image_with_edges(mesh, borders, np.zeros(5, bool))
    assert not colour_mask(none, RED).any()
    every = border_image_with_edges(mesh, borders, np.ones(5, bool))
    assert not colour_mask(every, GRAY).any()
    # Without UVs: the border image alone.
    plain = border_image_with_edges(Mesh(SQUARE_POSITIONS, SQUARE_FACES), borders,
                                    np.zeros(5, bool))
    np.testing.assert_array_equal(colour_mask(plain, WHITE), borders)


def test_border_image_validation():
    mesh = square_mesh()
    borders = texture_borders(mesh.texture)
    with pytest.raises(ValueError, match=r"shape \(5,\), one per welded edge"):
        border_image_with_edges(mesh, borders, np.zeros(4, bool))
    with pytest.raises(ValueError, match="positive integer"):
        border_image_with_edges(mesh, borders, np.zeros(5, bool), scale=0)
