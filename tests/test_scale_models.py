"""The scaling benchmark's inputs: midpoint subdivision keeps the surface and the seams."""

import numpy as np

from bench.core.mesh import Mesh, face_areas
from bench.catalog.scale import subdivide


def test_one_triangle_becomes_four_at_its_midpoints():
    tri = Mesh(np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]), np.array([[0, 1, 2]]))
    out = subdivide(tri)
    assert out.n_faces == 4 and out.n_vertices == 6
    assert sorted(map(tuple, out.positions[3:])) == [(0, 1, 0), (1, 0, 0), (1, 1, 0)]
    assert np.allclose(face_areas(out.positions, out.faces), 0.5)
    assert np.all(np.cross(*(out.positions[out.faces[:, 1:]] -
                             out.positions[out.faces[:, :1]]).transpose(1, 0, 2))[:, 2] > 0)


def test_a_shared_edge_gets_one_midpoint_and_a_seam_two():
    quad = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]),
                np.array([[0, 1, 2], [0, 2, 3]]))
    out = subdivide(quad)
    assert out.n_faces == 8 and out.n_vertices == 4 + 5
    assert out.welded.n_vertices == 9
    # the same square with a UV seam along the diagonal: two render vertices per end
    seam = Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0],
                          [0, 1, 0]]), np.array([[0, 1, 2], [3, 4, 5]]),
                uv=np.array([[0, 0], [1, 0], [1, 1], [0, 0.5], [1, 0.5], [0, 1]]))
    out = subdivide(seam)
    assert out.n_vertices == 6 + 6 and out.welded.n_vertices == 9
    assert np.isclose(face_areas(out.positions, out.faces).sum(), 1.0)
    edges = [(0, 1), (0, 2), (1, 2), (3, 4), (3, 5), (4, 5)]  # in np.unique's order
    assert np.allclose(out.uv[6:], [(seam.uv[i] + seam.uv[j]) / 2 for i, j in edges])
