"""Tests for the protocol cameras (metrics.views, Lindstrom & Turk 2000 §3.2/§5.1)."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from metrics.views import (
    Camera,
    _circumball,
    _farthest_squared,
    _first_outside,
    bounding_sphere,
    cameras_for,
    dodecahedron_directions,
    protocol_cameras,
    rhombicuboctahedron_directions,
    silhouette_cameras,
)

GOLDEN = (1.0 + np.sqrt(5.0)) / 2.0
SETS = {
    "rhombicuboctahedron": (rhombicuboctahedron_directions, 24),
    "dodecahedron": (dodecahedron_directions, 20),
}


def _min_angle(d):
    cos = np.clip(d @ d.T, -1.0, 1.0)
    np.fill_diagonal(cos, -1.0)
    return float(np.arccos(cos.max()))


def _ndc(camera, points, aspect=1.0):
    homogeneous = np.c_[points, np.ones(len(points))]
    clip = homogeneous @ (camera.projection_matrix(aspect) @ camera.view_matrix()).T
    return clip[:, :3] / clip[:, 3:4]


@pytest.fixture(scope="module")
def bunny():
    from bench.catalog import BUNNY

    return BUNNY.load()


# -- viewpoint sets ---------------------------------------------------------------------

@pytest.mark.parametrize("name", SETS)
def test_count_unit_length_and_distinct(name):
    make, count = SETS[name]
    d = make()
    assert d.shape == (count, 3) and d.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-15)
    assert len(np.unique(d.round(12), axis=0)) == count


@pytest.mark.parametrize("name", SETS)
def test_closed_under_negation(name):
    d = SETS[name][0]()
    for v in d:
        assert np.min(np.linalg.norm(d + v, axis=1)) < 1e-12


@pytest.mark.parametrize("name", SETS)
def test_order_is_deterministic_and_sorted(name):
    a, b = SETS[name][0](), SETS[name][0]()
    assert np.array_equal(a, b)
    assert np.array_equal(np.lexsort((a[:, 2], a[:, 1], a[:, 0])), np.arange(len(a)))


def test_rhombicuboctahedron_neighbour_angle():
    # Edge length 2 (e.g. (1,1,1+√2) to (-1,1,1+√2) and to (1,1+√2,1)), circumradius
    # R = |(1,1,1+√2)| = √(5+2√2); the central angle over an edge is 2·asin(1/R).
    radius = np.sqrt(5.0 + 2.0 * np.sqrt(2.0))
    expected = 2.0 * np.arcsin(2.0 / (2.0 * radius))
    assert _min_angle(rhombicuboctahedron_directions()) == pytest.approx(expected, abs=1e-9)


def test_dodecahedron_neighbour_angle():
    # Circumradius √3 (|(1,1,1)|) and edge length 2/φ, e.g. (1,1,1) to (0,1/φ,φ).
    expected = 2.0 * np.arcsin((2.0 / GOLDEN) / (2.0 * np.sqrt(3.0)))
    assert _min_angle(dodecahedron_directions()) == pytest.approx(expected, abs=1e-9)


def test_every_direction_has_the_expected_number_of_neighbours():
    # Each rhombicuboctahedron vertex has 4 edges, each dodecahedron vertex 3.
    for make, degree in ((rhombicuboctahedron_directions, 4), (dodecahedron_directions, 3)):
        d = make()
        cos = d @ d.T
        np.fill_diagonal(cos, -1.0)
        nearest = cos.max(axis=1, keepdims=True)
        assert np.all(np.sum(np.abs(cos - nearest) < 1e-12, axis=1) == degree)


# -- minimum bounding sphere --------------------------------------------------------------

def test_bounding_sphere_of_cube_corners():
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
    center, radius = bounding_sphere(corners)
    np.testing.assert_allclose(center, 0.0, atol=1e-12)
    assert radius == pytest.approx(np.sqrt(3.0), abs=1e-12)


def _brute_force_sphere(points):
    """Oracle: the smallest ball through 2, 3 or 4 of the points enclosing them all."""
    best = (None, np.inf)
    for k in (2, 3, 4):
        for subset in itertools.combinations(points, k):
            center, _ = _circumball(list(subset))
            radius = np.sqrt(np.max(np.sum((points - center) ** 2, axis=1)))
            if radius < best[1]:
                best = (center, radius)
    return best


@pytest.mark.parametrize("seed", range(8))
def test_bounding_sphere_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(int(rng.integers(2, 11)), 3)) * rng.uniform(0.1, 10.0, 3)
    center, radius = bounding_sphere(points)
    expected_center, expected_radius = _brute_force_sphere(points)
    assert radius == pytest.approx(expected_radius, rel=1e-12)
    np.testing.assert_allclose(center, expected_center, atol=1e-9 * expected_radius)


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 40), st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 2]))
def test_welzl_kernels_are_numpys_sums(n, seed, ties):
    # Welzl's scan: the first point whose squared distance, summed as NumPy sums
    # ``(q - c) ** 2`` along its rows, exceeds the limit. Limits exactly at a point's
    # distance (ties) and between them; the recursion's verdicts are NumPy's to the bit,
    # and so is the circumball's radius (the farthest of its points).
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3, 3)
    center = q[rng.integers(n)] + rng.normal(size=3) * rng.uniform(0, 2)
    squared = np.sum((q - center) ** 2, axis=1)
    start, end = sorted(int(x) for x in rng.integers(0, n + 1, 2))
    limit = (float(rng.choice(squared)) if ties else
             float(np.quantile(squared, rng.uniform()))) * (1.0 if ties < 2 else 1 - 1e-16)
    for lim in (limit, -np.inf, np.inf):
        outside = np.flatnonzero(squared[start:end] > lim)
        expected = start + int(outside[0]) if outside.size else -1
        assert _first_outside(q, start, end, center, lim) == expected
    assert _farthest_squared(q, center) == max(float(np.sum((s - center) ** 2)) for s in q)


def test_bounding_sphere_encloses_and_is_deterministic(bunny):
    center, radius = bounding_sphere(bunny.positions)
    distance = np.linalg.norm(bunny.positions - center, axis=1)
    assert distance.max() <= radius
    assert distance.max() == pytest.approx(radius, rel=1e-15)
    again = bounding_sphere(bunny.positions)
    assert np.array_equal(again[0], center) and again[1] == radius


def test_bounding_sphere_edge_cases():
    center, radius = bounding_sphere([[1.0, 2.0, 3.0]])
    assert np.array_equal(center, [1.0, 2.0, 3.0]) and radius == 0.0
    center, radius = bounding_sphere([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    np.testing.assert_allclose(center, [1.0, 0.0, 0.0])
    assert radius == pytest.approx(1.0)


@pytest.mark.parametrize("bad, match", [
    (np.zeros((0, 3)), "empty"),
    (np.zeros((4, 2)), "shape"),
    ([[0.0, np.nan, 0.0]], "NaN"),
])
def test_bounding_sphere_rejects_bad_input(bad, match):
    with pytest.raises(ValueError, match=match):
        bounding_sphere(bad)


# -- cameras --------------------------------------------------------------------------------

def test_protocol_and_silhouette_camera_counts(bunny):
    assert len(protocol_cameras(bunny)) == 24
    assert len(silhouette_cameras(bunny)) == 20


def _assert_inside_frustum(cameras, points):
    for camera in cameras:
        ndc = _ndc(camera, points)
        assert np.all(np.abs(ndc) <= 1.0 + 1e-9), f"a point leaves the frustum of {camera}"


def test_random_cloud_projects_inside_every_frustum():
    points = np.random.default_rng(7).normal(size=(2000, 3)) * [3.0, 1.0, 0.5] + [5, -2, 1]
    for directions in (rhombicuboctahedron_directions(), dodecahedron_directions()):
        _assert_inside_frustum(cameras_for(points, directions), points)


def test_bunny_projects_inside_every_frustum(bunny):
    _assert_inside_frustum(protocol_cameras(bunny) + silhouette_cameras(bunny),
                           bunny.positions)


def test_bounding_sphere_just_fits_the_frame():
    # A point of the sphere on the cone tangent to it projects onto the frame's top edge.
    points = np.random.default_rng(3).normal(size=(500, 3))
    center, radius = bounding_sphere(points)
    camera = cameras_for(points, [[1.0, 0.0, 0.0]])[0]
    # Tangent point above the centre: at angle 30° from the axis, distance √3 r.
    axis, up = camera.direction, camera.up
    tangent = camera.eye + np.sqrt(3.0) * radius * (np.cos(np.pi / 6) * axis
                                                    + np.sin(np.pi / 6) * up)
    assert np.linalg.norm(tangent - center) == pytest.approx(radius)
    assert _ndc(camera, tangent[None])[0, 1] == pytest.approx(1.0, abs=1e-12)


def test_camera_geometry(bunny):
    center, radius = bounding_sphere(bunny.positions)
    for camera, d in zip(protocol_cameras(bunny), rhombicuboctahedron_directions()):
        np.testing.assert_allclose(camera.eye, center + 2.0 * radius * d, atol=1e-15)
        assert np.array_equal(camera.target, center)
        assert camera.fov_y_deg == 60.0
        assert camera.near == pytest.approx(0.99 * radius)
        assert camera.far == pytest.approx(3.01 * radius)
        view = camera.view_matrix()
        np.testing.assert_allclose(view @ np.r_[camera.eye, 1.0], [0, 0, 0, 1], atol=1e-15)
        target = view @ np.r_[camera.target, 1.0]
        np.testing.assert_allclose(target[:2], 0.0, atol=1e-15)
        assert target[2] == pytest.approx(-2.0 * radius)
        np.testing.assert_allclose(view[:3, :3] @ view[:3, :3].T, np.eye(3), atol=1e-14)
        assert np.linalg.det(view[:3, :3]) == pytest.approx(1.0)
        assert abs(np.dot(camera.up, camera.direction)) < 1e-14
        assert np.linalg.norm(camera.up) == pytest.approx(1.0)
        np.testing.assert_allclose(view[1, :3], camera.up, atol=1e-14)
        np.testing.assert_allclose(camera.pose() @ view, np.eye(4), atol=1e-14)


def test_up_vector_is_world_z_projected_and_y_at_the_poles():
    points = np.random.default_rng(0).normal(size=(50, 3))
    cams = cameras_for(points, [[1.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, -2.0]])
    np.testing.assert_allclose(cams[0].up, [-1 / np.sqrt(2), 0, 1 / np.sqrt(2)], atol=1e-15)
    np.testing.assert_allclose(cams[1].up, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(cams[2].up, [0.0, 1.0, 0.0])


def test_projection_matrix_is_opengl_perspective():
    camera = Camera(eye=[0, 0, 0], target=[0, 0, -1], up=[0, 1, 0], near=1.0, far=3.0)
    proj = camera.projection_matrix()
    for z, depth in ((-1.0, -1.0), (-3.0, 1.0)):
        clip = proj @ [0.0, 0.0, z, 1.0]
        assert clip[2] / clip[3] == pytest.approx(depth)
    edge = proj @ [0.0, np.tan(np.radians(30.0)) * 2.0, -2.0, 1.0]
    assert edge[1] / edge[3] == pytest.approx(1.0)
    assert camera.projection_matrix(2.0)[0, 0] == pytest.approx(proj[0, 0] / 2.0)


def test_camera_and_cameras_for_reject_bad_input():
    with pytest.raises(ValueError, match="near < far"):
        Camera(eye=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0], near=2.0, far=1.0)
    with pytest.raises(ValueError, match="radius 0"):
        cameras_for(np.ones((3, 3)), dodecahedron_directions())
    with pytest.raises(ValueError, match="non-zero"):
        cameras_for(np.eye(3), [[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"\(k, 3\)"):
        cameras_for(np.eye(3), [1.0, 0.0, 0.0])


def test_evaluation_cameras_name_the_view_sets(bunny):
    from metrics.views import REPRESENTATIVE_VIEW, VIEW_SET_SIZES, VIEW_SETS, evaluation_cameras

    every = protocol_cameras(bunny)
    default = evaluation_cameras(bunny)  # the 24 views
    assert len(default) == 24
    for a, b in zip(default, every):
        np.testing.assert_array_equal(a.eye, b.eye)
    one = evaluation_cameras(bunny, "representative")
    assert len(one) == 1 and one[0] is not None
    np.testing.assert_array_equal(one[0].eye, every[REPRESENTATIVE_VIEW].eye)
    np.testing.assert_array_equal(one[0].up, every[REPRESENTATIVE_VIEW].up)
    assert {v: len(evaluation_cameras(bunny, v)) for v in VIEW_SETS} == VIEW_SET_SIZES
    with pytest.raises(ValueError, match="views must be one of"):
        evaluation_cameras(bunny, "front")
