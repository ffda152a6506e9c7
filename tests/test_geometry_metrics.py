"""Metro-style distances against a brute-force point-to-triangle oracle.

The oracle is Ericson's closest point on a triangle (Real-Time Collision Detection,
2005, §5.1.5) in pure NumPy, evaluated against every triangle.
"""

import numpy as np
import pytest

from bench.core.mesh import Mesh
from metrics import geometry
from metrics.geometry import distance_to_surface, hausdorff, sample_surface

# MeshLab measures in single precision: distances agree to ~1e-7 of the scene size.
FLOAT32_TOL = 1e-6


# -- the oracle ------------------------------------------------------------------------------

def closest_point_on_triangles(p, a, b, c):
    """Closest points of triangles (a, b, c) to points p; all arrays broadcast to
    (..., 3). Ericson's Voronoi-region walk, every region computed and the first that
    applies selected."""
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c
    dot = lambda u, v: np.sum(u * v, axis=-1)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        on_ab = a + (d1 / (d1 - d3))[..., None] * ab
        on_ac = a + (d2 / (d2 - d6))[..., None] * ac
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        on_bc = b + t_bc[..., None] * (c - b)
        denom = va + vb + vc
        inside = a + (vb / denom)[..., None] * ab + (vc / denom)[..., None] * ac
    regions = [
        (d1 <= 0) & (d2 <= 0),                            # vertex a
        (d3 >= 0) & (d4 <= d3),                           # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),                # edge ab
        (d6 >= 0) & (d5 <= d6),                           # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),                # edge ac
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),  # edge bc
    ]
    choices = [a, b, on_ab, c, on_ac, on_bc]
    shape = np.broadcast_shapes(p.shape, a.shape)
    out = np.broadcast_to(inside, shape).copy()
    for region, choice in reversed(list(zip(regions, choices))):  # first region wins
        out = np.where(region[..., None], np.broadcast_to(choice, shape), out)
    return out


def brute_force_distance(points, mesh):
    """Distance from each point (p, 3) to the mesh, checking every triangle."""
    tri = mesh.positions[mesh.faces]
    best = np.full(len(points), np.inf)
    for chunk in np.array_split(np.arange(len(points)), max(1, len(points) // 2000)):
        p = points[chunk, None, :]
        q = closest_point_on_triangles(p, tri[None, :, 0], tri[None, :, 1], tri[None, :, 2])
        best[chunk] = np.linalg.norm(q - p, axis=2).min(axis=1)
    return best


def test_oracle_closest_point_regions():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = {(-1, -1, 2): a, (2, -0.5, 0): b, (-0.5, 3, 1): c, (0.5, -1, 0): (0.5, 0, 0),
             (-2, 0.25, 0): (0, 0.25, 0), (1, 1, 0): (0.5, 0.5, 0),
             (0.2, 0.3, -4): (0.2, 0.3, 0)}
    for p, expected in cases.items():
        got = closest_point_on_triangles(np.array(p, float), a, b, c)
        np.testing.assert_allclose(got, expected, atol=1e-12)


# -- meshes --------------------------------------------------------------------------------

def square(z=0.0):
    """The unit square in the plane at height z::

        3-----2
        |   / |
        | /   |
        0-----1
    """
    return Mesh(np.array([[0, 0, z], [1, 0, z], [1, 1, z], [0, 1, z]], float),
                np.array([[0, 1, 2], [0, 2, 3]]))


def tetrahedron(scale=1.0, offset=(0.0, 0.0, 0.0)):
    corners = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    return Mesh(corners * scale + offset, np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]))


# -- exact values ----------------------------------------------------------------------------

def test_parallel_offset_squares_are_exactly_the_offset_apart():
    h = hausdorff(square(0.0), square(0.1), samples=500)
    expected = 0.1 / np.sqrt(2)  # the original's diagonal is √2
    for key in ("forward_mean", "forward_rms", "forward_max", "backward_mean",
                "backward_rms", "backward_max", "symmetric_max", "hausdorff_mean"):
        assert h[key] == pytest.approx(expected, rel=FLOAT32_TOL), key


def test_identical_meshes_are_zero_apart():
    h = hausdorff(tetrahedron(), tetrahedron(), samples=1000)
    assert all(v == pytest.approx(0.0, abs=FLOAT32_TOL) for v in h.values())


def test_directions_differ_when_one_surface_covers_more():
    # A unit square against its lower-left quarter: every point of the quarter lies on
    # the square (backward 0), but the square's far corner is √(0.5² + 0.5²) from the
    # quarter (forward max = 0.5·√2 / √2 = 0.5 of the diagonal).
    quarter = square().replace(positions=square().positions * [0.5, 0.5, 1])
    h = hausdorff(square(), quarter, samples=2000)
    assert h["backward_max"] == pytest.approx(0.0, abs=FLOAT32_TOL)
    assert h["forward_max"] == pytest.approx(0.5, rel=FLOAT32_TOL)
    assert h["symmetric_max"] == h["forward_max"]
    assert h["hausdorff_mean"] == pytest.approx(0.5 * h["forward_mean"], rel=1e-9)


# -- against the brute-force oracle ----------------------------------------------------------

def test_distances_match_brute_force_on_the_same_samples():
    original, displaced = tetrahedron(), tetrahedron(1.3, (0.2, -0.1, 0.3))
    for source, target in ((original, displaced), (displaced, original)):
        points = sample_surface(source, samples=3000, seed=4)
        got = distance_to_surface(points, target)
        expected = brute_force_distance(points, target)
        np.testing.assert_allclose(got, expected, atol=FLOAT32_TOL * target.diagonal)


def test_distances_of_points_off_the_surface_match_brute_force():
    points = np.random.default_rng(5).uniform(-3, 3, size=(2000, 3))
    mesh = tetrahedron()
    np.testing.assert_allclose(distance_to_surface(points, mesh),
                               brute_force_distance(points, mesh), atol=FLOAT32_TOL * 10)


def test_hausdorff_matches_brute_force_on_an_independent_dense_sampling():
    original, displaced = tetrahedron(), tetrahedron(1.3, (0.2, -0.1, 0.3))
    h = hausdorff(original, displaced, samples=20_000)
    diag = original.diagonal
    for side, source, target in (("forward", original, displaced),
                                 ("backward", displaced, original)):
        points = sample_surface(source, samples=40_000, seed=99)  # other points
        d = brute_force_distance(points, target) / diag
        # Means of 40k points agree to well under 1 %; the maxima here sit at vertices,
        # which both samplings contain, so they agree to single precision.
        assert h[f"{side}_mean"] == pytest.approx(d.mean(), rel=0.01)
        assert h[f"{side}_rms"] == pytest.approx(np.sqrt(np.mean(d ** 2)), rel=0.01)
        assert h[f"{side}_max"] == pytest.approx(d.max(), rel=FLOAT32_TOL)


# -- sampling ----------------------------------------------------------------------------------

def test_samples_are_vertices_then_edges_then_faces_and_lie_on_the_surface():
    mesh = tetrahedron()
    points = sample_surface(mesh, samples=500, seed=1)
    assert points.shape == (4 + 2 * 500, 3)
    np.testing.assert_array_equal(points[:4], mesh.welded.positions)
    assert np.allclose(brute_force_distance(points, mesh), 0, atol=1e-12)
    # Edge samples lie on the six edges: on the line through two corners.
    edge_points = points[4:504]
    a, b = mesh.positions[mesh.welded.edges[:, 0]], mesh.positions[mesh.welded.edges[:, 1]]
    ab = b - a
    t = np.clip(np.einsum("pej,ej->pe", edge_points[:, None] - a, ab)
                / np.einsum("ej,ej->e", ab, ab), 0, 1)
    off_line = np.linalg.norm(edge_points[:, None] - (a + t[..., None] * ab), axis=2).min(axis=1)
    assert np.allclose(off_line, 0, atol=1e-12)


def test_edge_samples_are_spread_by_length():
    # A thin 4×1 rectangle: the two long edges get 4/(4+4+1+1+√17) of the samples each.
    rect = Mesh(np.array([[0, 0, 0], [4, 0, 0], [4, 1, 0], [0, 1, 0]], float),
                np.array([[0, 1, 2], [0, 2, 3]]))
    edges = sample_surface(rect, samples=10_000)[4:10_004]
    on_bottom = np.isclose(edges[:, 1], 0).sum()
    assert on_bottom / 10_000 == pytest.approx(4 / (10 + np.sqrt(17)), abs=1e-3)


def test_face_samples_are_uniform_over_the_area():
    points = sample_surface(square(), samples=40_000, seed=2)[4 + 40_000:]
    # Each quarter of the square holds a quarter of the points (binomial sd ≈ 0.002).
    counts = np.histogram2d(points[:, 0], points[:, 1], bins=2, range=[[0, 1], [0, 1]])[0]
    np.testing.assert_allclose(counts / len(points), 0.25, atol=0.01)


def test_a_flat_mesh_of_zero_area_gets_no_face_samples():
    line = Mesh(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0]], float), np.array([[0, 1, 2]]))
    assert sample_surface(line, samples=10).shape == (3 + 10, 3)


# -- determinism -------------------------------------------------------------------------------

def test_hausdorff_is_deterministic_even_after_other_pymeshlab_calls():
    import pymeshlab

    original, displaced = tetrahedron(), tetrahedron(1.3, (0.2, -0.1, 0.3))
    first = hausdorff(original, displaced, samples=5000)
    # pymeshlab remembers parameters as defaults and advances its sampling generator;
    # neither may leak into the next measurement.
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(original.positions, original.faces))
    ms.add_mesh(pymeshlab.Mesh(displaced.positions, displaced.faces))
    ms.get_hausdorff_distance(sampledmesh=1, targetmesh=0, samplevert=False,
                              sampleface=True, samplenum=77,
                              maxdist=pymeshlab.PercentageValue(1.0))
    assert hausdorff(original, displaced, samples=5000) == first


def test_another_seed_gives_close_but_different_numbers():
    original, displaced = tetrahedron(), tetrahedron(1.3, (0.2, -0.1, 0.3))
    a = hausdorff(original, displaced, samples=5000, seed=0)
    b = hausdorff(original, displaced, samples=5000, seed=7)
    assert a["forward_mean"] != b["forward_mean"]
    assert a["forward_mean"] == pytest.approx(b["forward_mean"], rel=0.02)


def test_far_apart_meshes_lose_no_samples():
    # Farther apart than the original's own diagonal: a maxdist of 100 % of that
    # diagonal would drop every sample.
    h = hausdorff(square(), square(5.0), samples=100)
    assert h["forward_max"] == pytest.approx(5 / np.sqrt(2), rel=FLOAT32_TOL)


# -- errors and metrics ------------------------------------------------------------------------

def test_errors():
    empty = Mesh(np.zeros((3, 3)), np.zeros((0, 3), int))
    point = Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="no faces"):
        hausdorff(empty, square())
    with pytest.raises(ValueError, match="no faces"):
        hausdorff(square(), empty)
    with pytest.raises(ValueError, match="zero diagonal"):
        hausdorff(point, square())
    with pytest.raises(ValueError, match="positive integer"):
        hausdorff(square(), square(), samples=0)
    with pytest.raises(ValueError, match="positive integer"):
        sample_surface(square(), samples=2.5)
    with pytest.raises(ValueError, match=r"shape \(p, 3\)"):
        distance_to_surface(np.zeros((4, 2)), square())
    with pytest.raises(ValueError, match="NaN"):
        distance_to_surface(np.full((1, 3), np.nan), square())
    with pytest.raises(ValueError, match="bench.core.mesh.Mesh"):
        hausdorff(square().positions, square())


def test_metrics_share_one_computation_through_ctx():
    ctx = {"hausdorff_samples": 1000}
    mean = geometry.HAUSDORFF_MEAN.compute(square(), square(0.1), ctx)
    assert mean == pytest.approx(0.1 / np.sqrt(2), rel=FLOAT32_TOL)
    ctx["hausdorff"]["symmetric_max"] = 123.0  # the cached result is what max reads
    assert geometry.HAUSDORFF_MAX.compute(square(), square(0.1), ctx) == 123.0
    assert geometry.HAUSDORFF_MAX.unit == "fraction of bbox diagonal"
    assert geometry.HAUSDORFF_MEAN.higher_is_better is False


@pytest.mark.slow
def test_bunny_agrees_with_meshlabs_own_sampling():
    import pymeshlab

    from bench.catalog import BUNNY
    from bench.core.method import run_method
    from methods.baselines import QSlim

    bunny = BUNNY.load()
    coarse = run_method(QSlim(), bunny, 1332).mesh
    h = hausdorff(bunny, coarse)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(bunny.positions, bunny.faces))
    ms.add_mesh(pymeshlab.Mesh(coarse.positions, coarse.faces))
    own = ms.get_hausdorff_distance(sampledmesh=0, targetmesh=1, savesample=False,
                                    samplevert=True, sampleedge=True, samplefauxedge=False,
                                    sampleface=True, samplenum=200_000,
                                    maxdist=pymeshlab.PercentageValue(100.0))
    assert h["forward_mean"] == pytest.approx(own["mean"] / bunny.diagonal, rel=0.02)
    assert h["forward_rms"] == pytest.approx(own["RMS"] / bunny.diagonal, rel=0.02)
    assert h["forward_max"] == pytest.approx(own["max"] / bunny.diagonal, rel=0.1)


def test_metric_sample_count_comes_from_ctx_or_the_protocol():
    from types import SimpleNamespace

    ctx = {"protocol": SimpleNamespace(hausdorff_samples=300)}
    geometry.HAUSDORFF_MEAN.compute(tetrahedron(), tetrahedron(1.3), ctx)
    assert ctx["hausdorff"] == hausdorff(tetrahedron(), tetrahedron(1.3), samples=300)
