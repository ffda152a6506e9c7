"""Silhouette counts and histograms on hand-built meshes with worked-out answers."""

import itertools

import numpy as np
import pytest

from bench.core.mesh import Mesh
from metrics import silhouette
from metrics.silhouette import silhouette_counts, silhouette_histogram


def cube():
    """The cube [-1, 1]³: 8 corners, 12 triangles, 18 welded edges (12 sides of the
    squares and one diagonal in each of the 6 squares). Corner i has coordinates
    ((i >> 2) & 1, (i >> 1) & 1, i & 1) mapped 0 -> -1, 1 -> +1::

          3-------7
         /|      /|        z
        1-------5 |        |  y
        | 2-----|-6        | /
        |/      |/         |/
        0-------4          +---- x
    """
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    quads = [(4, 6, 7, 5), (0, 1, 3, 2),   # +x, -x
             (2, 3, 7, 6), (0, 4, 5, 1),   # +y, -y
             (1, 5, 7, 3), (0, 2, 6, 4)]   # +z, -z   (counter-clockwise from outside)
    faces = [tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))]
    return Mesh(corners, np.array(faces))


def edge_set(mesh, counts):
    """The silhouette edges as a set of frozensets of corner coordinates."""
    w = mesh.welded
    return {frozenset(map(tuple, w.positions[e].astype(int))) for e in w.edges[counts > 0]}


def square_edges(axis, sign):
    """The 4 sides of the cube's face whose ``axis`` coordinate is ``sign``."""
    corners = [c for c in itertools.product((-1, 1), repeat=3) if c[axis] == sign]
    return {frozenset((a, b)) for a, b in itertools.combinations(corners, 2)
            if sum(x != y for x, y in zip(a, b)) == 1}


def test_cube_is_well_formed():
    mesh = cube()
    assert len(mesh.welded.edges) == 18 and np.all(mesh.welded.edge_face_count == 2)
    normals = mesh.face_normals
    centres = mesh.positions[mesh.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", normals, centres) > 0)  # outward


def test_cube_from_the_x_axis_shows_the_outline_of_the_x_face():
    mesh = cube()
    counts = silhouette_counts(mesh, [[10, 0, 0]])
    assert counts.sum() == 4
    assert edge_set(mesh, counts) == square_edges(0, 1)  # not the +x face's diagonal


def test_cube_from_a_corner_shows_a_hexagon():
    mesh = cube()
    counts = silhouette_counts(mesh, [[10, 10, 10]])
    # Front faces +x, +y, +z; the silhouette is where they meet a back face: the sides
    # of the three squares minus the three sides they share (meeting at (1, 1, 1)).
    fronts = square_edges(0, 1) | square_edges(1, 1) | square_edges(2, 1)
    shared = {e for e in fronts if (1, 1, 1) in e}
    assert counts.sum() == 6
    assert edge_set(mesh, counts) == fronts - shared


def test_facing_is_judged_from_the_camera_position_not_its_direction():
    # From (3, 3, 0.5) the +z face (plane z = 1) is seen from below, so it is back-facing,
    # although the direction (3, 3, 0.5) has a positive z: only +x and +y face the eye.
    mesh = cube()
    counts = silhouette_counts(mesh, [[3, 3, 0.5]])
    fronts = square_edges(0, 1) | square_edges(1, 1)
    shared = square_edges(0, 1) & square_edges(1, 1)
    assert edge_set(mesh, counts) == fronts - shared and counts.sum() == 6


def test_cube_histogram_over_axis_and_corner_views():
    # 6 axis views and 8 corner views. A side of a square, between faces F and G, is a
    # silhouette from the 2 axis views of F and G and from the 4 corners that face
    # exactly one of them: 6 views. A diagonal lies inside one plane: never.
    axes = [s * np.eye(3)[k] * 10 for k in range(3) for s in (1, -1)]
    corners = [np.array(c) * 10.0 for c in itertools.product((-1, 1), repeat=3)]
    hist, mean = silhouette_histogram(cube(), np.array(axes + corners))
    expected = np.zeros(15)
    expected[0], expected[6] = 6 / 18, 12 / 18
    np.testing.assert_allclose(hist, expected, atol=1e-15)
    assert mean == pytest.approx(4.0)


def tetrahedron():
    """Regular tetrahedron a, b, c, d; the face opposite corner v has outward normal -v."""
    corners = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    return Mesh(corners, np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]))


def test_tetrahedron_from_a_corner_shows_the_opposite_triangle():
    mesh = tetrahedron()
    counts = silhouette_counts(mesh, [[10, 10, 10]])
    # The three faces at a = (1, 1, 1) face the eye, the one opposite it does not.
    expected = {frozenset(p) for p in itertools.combinations(
        [(1, -1, -1), (-1, 1, -1), (-1, -1, 1)], 2)}
    assert edge_set(mesh, counts) == expected


def test_tetrahedron_from_an_edge_midpoint_shows_four_edges():
    mesh = tetrahedron()
    # (10, 0, 0) lies beyond the midpoint (1, 0, 0) of edge ab. The two faces at ab face
    # the eye, the two at the opposite edge cd do not; the other four edges separate them.
    counts = silhouette_counts(mesh, [[10, 0, 0]])
    a, b, c, d = (1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)
    assert edge_set(mesh, counts) == {frozenset(e) for e in [(a, c), (a, d), (b, c), (b, d)]}


def test_single_triangle_outline_shows_only_from_the_front():
    tri = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]))
    np.testing.assert_array_equal(silhouette_counts(tri, [[0.2, 0.2, 5]]), [1, 1, 1])
    np.testing.assert_array_equal(silhouette_counts(tri, [[0.2, 0.2, -5]]), [0, 0, 0])
    np.testing.assert_array_equal(silhouette_counts(tri, [[9, 9, 0]]), [0, 0, 0])  # edge-on
    hist, mean = silhouette_histogram(tri, [[0.2, 0.2, 5], [0.2, 0.2, -5], [1, 1, 1]])
    np.testing.assert_allclose(hist, [0, 0, 1, 0])
    assert mean == 2.0


def test_non_manifold_edge_is_a_silhouette_when_its_faces_disagree():
    # Three fins on the z-axis edge 0-1 (out of the page), toward +x, +y and between::
    #
    #     3     4
    #     |   /             fin 0-2-1 has normal -y, fin 0-3-1 +x, fin 0-4-1 (1, -1, 0)
    #     | /
    #    0,1 ------ 2
    fins = Mesh(np.array([[0, 0, 0], [0, 0, 1], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float),
                np.array([[0, 2, 1], [0, 3, 1], [0, 4, 1]]))
    w = fins.welded
    spine = int(np.flatnonzero(w.edge_face_count == 3)[0])
    assert silhouette_counts(fins, [[5, 5, 0.5]])[spine] == 1    # -y back, +x front
    assert silhouette_counts(fins, [[5, -5, 0.5]])[spine] == 0   # all three front
    assert silhouette_counts(fins, [[-5, 5, 0.5]])[spine] == 0   # all three back
    assert silhouette_counts(fins, [[0, 0, 5]])[spine] == 0      # all edge-on: back


def test_histogram_sums_to_one_and_counts_follow_welded_edges():
    rng = np.random.default_rng(0)
    mesh = cube()
    eyes = rng.normal(size=(20, 3)) * 5
    hist, mean = silhouette_histogram(mesh, eyes)
    counts = silhouette_counts(mesh, eyes)
    assert hist.shape == (21,) and hist.sum() == pytest.approx(1.0)
    assert counts.shape == (18,)
    assert mean == pytest.approx(counts.mean())


def test_counts_match_a_per_edge_loop():
    # A slow, obviously-correct version on a random closed-ish surface with boundary.
    rng = np.random.default_rng(1)
    theta, phi = np.meshgrid(np.linspace(0, np.pi, 7), np.linspace(0, 2 * np.pi, 9)[:-1])
    pts = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                    np.cos(theta)], -1).reshape(-1, 3) * (1 + 0.1 * rng.random((56, 1)))
    idx = np.arange(56).reshape(8, 7)
    faces = []
    for i in range(7):      # leave one longitude gap open, so there is a boundary
        for j in range(6):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            faces += [(a, b, c), (a, c, d)]
    mesh = Mesh(pts, np.array(faces))
    eyes = rng.normal(size=(12, 3)) * 4
    w = mesh.welded
    expected = np.zeros(len(w.edges), int)
    for e, (u, v) in enumerate(w.edges):
        incident = [f for f in w.faces if {u, v} <= set(f.tolist())]
        for eye in eyes:
            front = []
            for f in incident:
                p = w.positions[f]
                n = np.cross(p[1] - p[0], p[2] - p[0])
                front.append(np.dot(n, eye - p[0]) > 0)
            expected[e] += (front[0] if len(front) == 1 else 0 < sum(front) < len(front))
    np.testing.assert_array_equal(silhouette_counts(mesh, eyes), expected)


@pytest.mark.parametrize("eyes, match", [
    (np.zeros((0, 3)), r"shape \(V, 3\)"),
    (np.zeros(3), r"shape \(V, 3\)"),
    (np.zeros((2, 2)), r"shape \(V, 3\)"),
    (np.array([[np.nan, 0, 0]]), "NaN"),
])
def test_bad_eyes_are_rejected(eyes, match):
    with pytest.raises(ValueError, match=match):
        silhouette_histogram(cube(), eyes)


def test_mesh_without_faces_is_rejected():
    with pytest.raises(ValueError, match="no faces"):
        silhouette_histogram(Mesh(np.zeros((3, 3)), np.zeros((0, 3), int)), [[0, 0, 1]])


def test_metric_reads_eyes_from_ctx():
    eyes = np.array([[10.0, 0, 0]])
    value = silhouette.SILHOUETTE_MEAN.compute(cube(), cube(), {"silhouette_eyes": eyes})
    assert value == pytest.approx(4 / 18)
    assert silhouette.SILHOUETTE_MEAN.unit == "views"
    assert silhouette.SILHOUETTE_MEAN.higher_is_better is None


def test_metric_defaults_to_the_dodecahedron_cameras_of_the_original():
    from metrics.views import silhouette_cameras

    eyes = np.array([c.eye for c in silhouette_cameras(cube())])
    assert len(eyes) == 20
    assert silhouette.SILHOUETTE_MEAN.compute(cube(), cube(), {}) == \
        silhouette_histogram(cube(), eyes).mean
