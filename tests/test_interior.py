"""The ``interior`` model (L&T 2000 §5.2) and the ``exterior_share`` metric.

Topology is checked with an independent edge count (a Counter over vertex pairs and a
union-find over boundary edges), not with bench.core.mesh's welding; the metric is checked on
hand-made triangles whose centroids are placed by hand.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest

from bench.catalog import INTERIOR, resolve_model
from bench.catalog.interior import (
    EXTERIOR_RADIUS,
    INNER_AMPLITUDE,
    INNER_RADIUS,
    OPENINGS,
    bump_height,
    geodesic_sphere,
    make_interior,
)
from bench.core.mesh import Mesh
from metrics.interior import EXTERIOR_SHARE, exterior_share, exterior_sphere
from metrics.protocol import model_metrics

SHELL_FACES = 4543  # of the shell's 5,120 geodesic faces; see test_openings_remove_their_area
INNER_FACES = 20 * 48 * 48


@pytest.fixture(scope="module")
def interior():
    return INTERIOR.load()


def edge_counts(faces: np.ndarray) -> Counter:
    counts = Counter()
    for a, b, c in faces.tolist():
        for u, v in ((a, b), (b, c), (c, a)):
            counts[(min(u, v), max(u, v))] += 1
    return counts


def boundary_loops(faces: np.ndarray) -> list[set]:
    """Vertex sets of the connected components formed by edges used by one face."""
    boundary = [e for e, n in edge_counts(faces).items() if n == 1]
    parent = {}

    def find(x):
        parent.setdefault(x, x)
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for u, v in boundary:
        parent[find(u)] = find(v)
    loops = {}
    for u, v in boundary:
        loops.setdefault(find(u), set()).update((u, v))
    return list(loops.values())


# -- the model ------------------------------------------------------------------------------

def test_sizes_and_registration(interior):
    assert interior.name == "interior" and interior.metadata["model"] == "interior"
    assert interior.n_faces == SHELL_FACES + INNER_FACES == 50623
    assert interior.metadata["shell_faces"] == SHELL_FACES
    assert interior.metadata["inner_faces"] == INNER_FACES
    assert interior.uv is None and interior.texture is None
    assert resolve_model("interior").content_hash == interior.content_hash


def test_is_deterministic(interior):
    again = make_interior()
    np.testing.assert_array_equal(again.positions, interior.positions)
    np.testing.assert_array_equal(again.faces, interior.faces)


def test_openings_are_the_only_boundary(interior):
    faces = interior.faces
    counts = edge_counts(faces)
    assert max(counts.values()) == 2  # manifold: no edge has three faces
    loops = boundary_loops(faces)
    assert len(loops) == len(OPENINGS) == 4
    # each loop is a simple cycle (every rim vertex on exactly two boundary edges) ...
    degree = Counter(v for e, n in counts.items() if n == 1 for v in e)
    assert set(degree.values()) == {2}
    # ... lies on the unit sphere at its opening's angular radius from the opening's axis
    for loop in loops:
        p = interior.positions[sorted(loop)]
        np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-12)
        angles = []
        for az, el, radius in OPENINGS:
            az, el = math.radians(az), math.radians(el)
            axis = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az),
                             math.sin(el)])
            angles.append((np.degrees(np.arccos(np.clip(p @ axis, -1, 1))), radius))
        matches = [radius for a, radius in angles if np.allclose(a, radius, atol=1e-9)]
        assert len(matches) == 1


def test_euler_characteristic(interior):
    # A sphere with four holes (chi = 2 - 4) plus a closed sphere (chi = 2): V - E + F = 0.
    used = np.unique(interior.faces)
    assert len(used) == interior.n_vertices  # no unreferenced vertex
    assert interior.n_vertices - len(edge_counts(interior.faces)) + interior.n_faces == 0


def test_every_face_is_wound_outward(interior):
    p = interior.positions[interior.faces]
    normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    centroids = p.mean(axis=1)
    assert (np.einsum("ij,ij->i", normals, centroids) > 0).all()


def test_classification_counts_are_exact(interior):
    centroids = interior.positions[interior.faces].mean(axis=1)
    radius = np.linalg.norm(centroids, axis=1)
    exterior = radius > EXTERIOR_RADIUS
    assert exterior.sum() == SHELL_FACES
    assert (~exterior).sum() == INNER_FACES
    assert exterior[:SHELL_FACES].all() and not exterior[SHELL_FACES:].any()  # built in order
    # with a margin on both sides, so simplified meshes classify the same way
    assert radius[SHELL_FACES:].max() < INNER_RADIUS * (1 + INNER_AMPLITUDE) < EXTERIOR_RADIUS
    assert radius[:SHELL_FACES].min() > 0.99
    assert exterior_share(interior, interior) == pytest.approx(SHELL_FACES / 50623, abs=0)


def test_inner_object_is_far_denser_than_the_shell(interior):
    p = interior.positions[interior.faces]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    assert np.median(area[:SHELL_FACES]) > 20 * np.median(area[SHELL_FACES:])


def test_geodesic_sphere_is_closed_and_welded():
    positions, faces = geodesic_sphere(5)
    assert len(faces) == 20 * 25 and len(positions) == 10 * 25 + 2
    assert set(edge_counts(faces).values()) == {2}
    np.testing.assert_allclose(np.linalg.norm(positions, axis=1), 1.0)
    assert len(np.unique(positions, axis=0)) == len(positions)


def test_bump_height_is_bounded():
    directions, _ = geodesic_sphere(30)
    h = bump_height(directions)
    assert h.min() >= -1 and h.max() <= 1
    assert h.max() - h.min() > 1  # bumps and dents, not a sphere


def test_openings_remove_their_area():
    # Independent of the construction: the four caps' share of the sphere's area,
    # (1 - cos r) / 2 each, applied to the 5,120 faces of roughly equal area.
    kept = 5120 * (1 - sum((1 - math.cos(math.radians(o[2]))) / 2 for o in OPENINGS))
    assert abs(SHELL_FACES - kept) < 0.01 * 5120


def test_frequency_below_two_is_refused():
    with pytest.raises(ValueError, match="at least 2"):
        make_interior(shell_frequency=1)


# -- the metric ---------------------------------------------------------------------------

def _triangle_around(centre, size=0.01):
    """A small triangle whose centroid is exactly ``centre`` (corners at centre + d_k,
    with the d_k summing to zero)."""
    offsets = size * np.array([[1.0, 0.0, 0.0], [-0.5, 0.5, 0.0], [-0.5, -0.5, 0.0]])
    return np.asarray(centre, dtype=float) + offsets


def _mesh(centroids, metadata=None):
    positions = np.concatenate([_triangle_around(c) for c in centroids])
    faces = np.arange(len(positions), dtype=np.int32).reshape(-1, 3)
    return Mesh(positions, faces, metadata=metadata or {})


def _oracle(centroids, centre, radius):
    return sum(math.dist(c, centre) > radius for c in centroids) / len(centroids)


def test_exterior_share_matches_a_hand_count():
    centre, radius = [1.0, 2.0, 3.0], 2.0
    original = _mesh([[1, 2, 3]], {"exterior_sphere": {"centre": centre, "radius": radius}})
    centroids = [[1, 2, 6], [1, 2, 3.5], [4, 2, 3], [1, -0.5, 3], [2, 3, 4]]
    # distances: 3 (out), 0.5 (in), 3 (out), 2.5 (out), sqrt(3) = 1.73 (in)
    share = exterior_share(original, _mesh(centroids))
    assert share == pytest.approx(3 / 5)
    assert share == pytest.approx(_oracle(centroids, centre, radius))


def test_a_centroid_on_the_sphere_is_interior():
    original = _mesh([[0, 0, 0]], {"exterior_sphere": {"centre": [0, 0, 0], "radius": 1.0}})
    assert exterior_share(original, _mesh([[0, 0, 1.0], [0, 0, 1.5]])) == 0.5


def test_classification_comes_from_the_original():
    # The simplified mesh's own metadata is ignored: methods need not carry it through.
    plain = _mesh([[0, 0, 0]])
    classified = _mesh([[0, 0, 5]], {"exterior_sphere": {"centre": [0, 0, 0], "radius": 1}})
    assert math.isnan(exterior_share(plain, classified))
    assert exterior_share(classified, plain) == 0.0
    assert exterior_share(classified, classified) == 1.0


def test_undefined_share_is_nan_and_left_out_of_records():
    plain = _mesh([[0, 0, 0]])
    assert math.isnan(EXTERIOR_SHARE.compute(plain, plain, None))
    assert model_metrics(plain, plain) == {}
    classified = _mesh([[0, 0, 2]], {"exterior_sphere": {"centre": [0, 0, 0], "radius": 1}})
    assert model_metrics(classified, plain) == {"exterior_share": 0.0}
    empty = Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int32))
    assert math.isnan(exterior_share(classified, empty))


@pytest.mark.parametrize("spec", [{"centre": [0, 0], "radius": 1}, {"radius": 1},
                                  {"centre": [0, 0, 0], "radius": -1},
                                  {"centre": [0, 0, math.inf], "radius": 1}])
def test_malformed_classification_is_a_clear_error(spec):
    with pytest.raises(ValueError, match="exterior_sphere"):
        exterior_sphere(_mesh([[0, 0, 0]], {"exterior_sphere": spec}))


def test_metric_is_registered_with_a_direction():
    from bench.core.registry import registry

    metric = registry("metric").load("exterior_share")
    assert metric is EXTERIOR_SHARE and metric.higher_is_better is True
