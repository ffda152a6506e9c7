"""Mesh, its welded topology, and the geometric helpers, on meshes counted by hand."""

from __future__ import annotations

import numpy as np
import pytest

from bench.core.mesh import Mesh, face_areas, face_normals
from conftest import SEAM_FACES, SEAM_POSITIONS, SEAM_UV, TET_FACES, TET_POSITIONS


def edge_set(edges) -> set[tuple[int, int]]:
    return {tuple(int(v) for v in e) for e in edges}


# -- welded topology ----------------------------------------------------------------------

class TestSeamQuad:
    """Two triangles with a UV seam along their shared diagonal (see conftest)::

        0-----1 3      welded vertices are the distinct positions sorted
        |    /  /|     lexicographically: w0=(0,0,0) w1=(0,1,0) w2=(1,0,0) w3=(1,1,0)
        |  /  /  |     render -> welded: 0->w1 1->w3 2->w0 3->w3 4->w0 5->w2
        2 4-----5      welded faces (w1,w0,w3) and (w3,w0,w2)

    Welded edges: w0w1, w0w2, w0w3 (the diagonal, 2 faces), w1w3, w2w3.
    The diagonal is a seam (the right face uses copies 3, 4); the other four are
    boundary edges of the square.
    """

    @pytest.fixture
    def mesh(self):
        return Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV)

    def test_counts(self, mesh):
        assert mesh.n_vertices == 6
        assert mesh.n_faces == 2
        assert mesh.welded.n_vertices == 4

    def test_vertex_map_and_welded_faces(self, mesh):
        w = mesh.welded
        np.testing.assert_array_equal(w.vertex_of, [1, 3, 0, 3, 0, 2])
        np.testing.assert_array_equal(w.positions, [[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0]])
        np.testing.assert_array_equal(w.faces, [[1, 0, 3], [3, 0, 2]])
        assert w.vertex_of.dtype == np.int32 and w.faces.dtype == np.int32

    def test_edges(self, mesh):
        w = mesh.welded
        np.testing.assert_array_equal(w.edges, [[0, 1], [0, 2], [0, 3], [1, 3], [2, 3]])
        np.testing.assert_array_equal(w.edge_face_count, [1, 1, 2, 1, 1])

    def test_exactly_one_seam_and_it_is_not_a_boundary(self, mesh):
        np.testing.assert_array_equal(mesh.welded.seam, [False, False, True, False, False])
        np.testing.assert_array_equal(mesh.seam_edges, [[0, 3]])
        assert len(mesh.boundary_edges) == 4
        assert (0, 3) not in edge_set(mesh.boundary_edges)
        assert not mesh.welded.non_manifold.any()

    def test_summary(self, mesh):
        assert mesh.summary() == {
            "faces": 2, "render_vertices": 6, "welded_vertices": 4, "boundary_edges": 4,
            "seam_edges": 1, "non_manifold_edges": 0, "uv": True, "texture": False}

    def test_shared_render_vertices_make_no_seam(self):
        #   0-----1      the same square with both faces using render vertices 1 and 2
        #   |    /|
        #   |  /  |      faces (0,2,1) and (1,2,3)
        #   2-----3
        mesh = Mesh([[0, 1, 0], [1, 1, 0], [0, 0, 0], [1, 0, 0]], [[0, 2, 1], [1, 2, 3]])
        w = mesh.welded
        assert w.n_vertices == 4
        assert len(w.edges) == 5
        assert w.seam.sum() == 0
        assert w.boundary.sum() == 4


def test_single_triangle_has_three_boundary_edges():
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    w = mesh.welded
    np.testing.assert_array_equal(w.edges, [[0, 1], [0, 2], [1, 2]])
    np.testing.assert_array_equal(w.edge_face_count, [1, 1, 1])
    assert w.boundary.sum() == 3
    assert w.seam.sum() == 0
    assert w.non_manifold.sum() == 0


def test_closed_tetrahedron():
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    w = mesh.welded
    assert w.n_vertices == 4
    assert len(w.edges) == 6
    np.testing.assert_array_equal(w.edge_face_count, [2] * 6)
    assert w.boundary.sum() == 0
    assert w.seam.sum() == 0
    assert w.non_manifold.sum() == 0
    assert w.n_vertices - len(w.edges) + mesh.n_faces == 2  # Euler: a sphere


def test_closed_tetrahedron_with_a_seamed_face():
    # Face (0,2,1) is stored with copies 4 (of 0) and 5 (of 1): render (4,2,5). Its three
    # edges are each shared with a face using the originals, so all three are seams,
    # and the mesh stays closed.
    positions = np.vstack([TET_POSITIONS, TET_POSITIONS[[0, 1]]])
    faces = np.array([[4, 2, 5], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = Mesh(positions, faces)
    w = mesh.welded
    # welded order: w0=(0,0,0) w1=(0,0,1) w2=(0,1,0) w3=(1,0,0)
    np.testing.assert_array_equal(w.vertex_of, [0, 3, 2, 1, 0, 3])
    assert mesh.n_vertices == 6 and w.n_vertices == 4
    assert len(w.edges) == 6
    assert w.boundary.sum() == 0
    # the seamed face's edges: (0,0,0)-(1,0,0), (0,0,0)-(0,1,0), (0,1,0)-(1,0,0)
    assert edge_set(mesh.seam_edges) == {(0, 3), (0, 2), (2, 3)}


def test_non_manifold_book():
    # Three pages on the spine (0,0,0)-(1,0,0):
    #
    #            4 (0,0,1)
    #            |
    #   2 (0,1,0)+--- spine 0-1 along x
    #            |
    #            3 (0,-1,0)
    #
    # faces (0,1,2), (1,0,3), (0,1,4). Welded order: w0=(0,-1,0) w1=(0,0,0)
    # w2=(0,0,1) w3=(0,1,0) w4=(1,0,0); the spine is w1-w4.
    positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]
    mesh = Mesh(positions, [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    w = mesh.welded
    np.testing.assert_array_equal(
        w.edges, [[0, 1], [0, 4], [1, 2], [1, 3], [1, 4], [2, 4], [3, 4]])
    np.testing.assert_array_equal(w.edge_face_count, [1, 1, 1, 1, 3, 1, 1])
    assert w.non_manifold.sum() == 1
    np.testing.assert_array_equal(w.edges[w.non_manifold], [[1, 4]])
    assert w.boundary.sum() == 6
    assert w.seam.sum() == 0  # seams are defined on two-face edges only


def test_signed_zeros_weld():
    # "-0" and "0" in a file are the same point; the right triangle's corner 3 is a
    # copy of corner 0 written as -0.0, so the shared edge 0-1 is a seam, not a crack.
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-0.0, 0, 0], [0, -1, 0]],
                [[0, 1, 2], [3, 4, 1]])
    assert mesh.welded.n_vertices == 4
    assert mesh.welded.seam.sum() == 1
    assert mesh.welded.boundary.sum() == 4


def test_no_faces_gives_empty_topology():
    mesh = Mesh(TET_POSITIONS, np.zeros((0, 3)))
    w = mesh.welded
    assert mesh.n_faces == 0 and w.n_vertices == 4
    assert w.edges.shape == (0, 2)
    assert len(w.seam) == 0


def test_replace_recomputes_welded_topology():
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    assert mesh.welded.boundary.sum() == 0
    open_mesh = mesh.replace(faces=TET_FACES[:3])
    assert open_mesh.welded.boundary.sum() == 3
    assert mesh.welded.boundary.sum() == 0  # the original is untouched


# -- geometry -----------------------------------------------------------------------------

def test_face_areas_and_normals_of_a_right_triangle():
    #   (0,4,0)
    #     |\
    #     |  \        legs 3 and 4: area 6, counter-clockwise seen from +z
    #     |____\
    #   (0,0,0) (3,0,0)
    positions = np.array([[0, 0, 0], [3, 0, 0], [0, 4, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 1]])
    np.testing.assert_allclose(face_areas(positions, faces), [6.0, 6.0])
    np.testing.assert_allclose(face_normals(positions, faces), [[0, 0, 1], [0, 0, -1]])
    mesh = Mesh(positions, faces[:1])
    np.testing.assert_allclose(mesh.face_normals, [[0, 0, 1]])


def test_face_normals_of_degenerate_triangle_are_zero():
    positions = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 3, 4]])
    np.testing.assert_array_equal(face_normals(positions, faces)[0], [0, 0, 0])
    np.testing.assert_allclose(face_normals(positions, faces)[1], [1, 0, 0])
    np.testing.assert_allclose(face_areas(positions, faces), [0.0, 2.0])


def test_vertex_normals_of_flat_square():
    #   3-----2
    #   |   / |   faces (0,1,2), (0,2,3), counter-clockwise seen from +z
    #   | /   |
    #   0-----1
    mesh = Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(mesh.vertex_normals, np.tile([0.0, 0.0, 1.0], (4, 1)))


def test_vertex_normals_are_shared_across_a_seam():
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV)
    np.testing.assert_allclose(mesh.vertex_normals, np.tile([0.0, 0.0, 1.0], (6, 1)))


def test_vertex_normals_are_area_weighted_over_the_welded_vertex():
    # At the tetrahedron's corner (0,0,0) meet three faces of area 1/2 with normals
    # -x, -y, -z: the area-weighted average is -(1,1,1)/sqrt(3).
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    np.testing.assert_allclose(mesh.vertex_normals[0], -np.ones(3) / np.sqrt(3))
    np.testing.assert_allclose(np.linalg.norm(mesh.vertex_normals, axis=1), 1.0)


def test_file_normals_are_used_as_given():
    normals = np.tile([1.0, 0.0, 0.0], (4, 1))
    mesh = Mesh(TET_POSITIONS, TET_FACES, normals=normals)
    np.testing.assert_array_equal(mesh.vertex_normals, normals)


def test_bounding_box_and_diagonal():
    mesh = Mesh([[0, 0, 0], [3, 0, 0], [0, 4, 0]], [[0, 1, 2]])
    lo, hi = mesh.bounding_box()
    np.testing.assert_array_equal(lo, [0, 0, 0])
    np.testing.assert_array_equal(hi, [3, 4, 0])
    assert mesh.diagonal == pytest.approx(5.0)


# -- construction -------------------------------------------------------------------------

def test_dtypes_are_normalised():
    mesh = Mesh(np.array(TET_POSITIONS, dtype=np.float32), TET_FACES.astype(np.int64),
                uv=np.zeros((4, 2), np.float32), colors=np.full((4, 4), 255.0),
                texture=np.zeros((2, 2, 3), np.int64))
    assert mesh.positions.dtype == np.float64
    assert mesh.faces.dtype == np.int32
    assert mesh.uv.dtype == np.float64
    assert mesh.colors.dtype == np.uint8
    assert mesh.texture.dtype == np.uint8
    assert mesh.has_texture


def test_repr_lists_attributes():
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV, name="quad")
    assert repr(mesh) == "Mesh('quad', 2 faces, 6 vertices, uv)"


@pytest.mark.parametrize("kwargs, match", [
    ({"positions": np.zeros((4, 2))}, r"positions must have shape \(n, 3\)"),
    ({"positions": np.zeros(12)}, r"positions must have shape \(n, 3\)"),
    ({"faces": np.zeros((1, 4), int)}, r"faces must have shape \(n, 3\)"),
    ({"faces": np.zeros((2, 2, 3), int)}, r"faces must have shape \(n, 3\)"),
    ({"uv": np.zeros((3, 2))}, r"uv has 3 rows for 4 vertices"),
    ({"uv": np.zeros((4, 3))}, r"uv must have shape \(n, 2\)"),
    ({"normals": np.zeros((5, 3))}, r"normals has 5 rows for 4 vertices"),
    ({"colors": np.zeros((4, 3))}, r"colors must have shape \(n, 4\)"),
    ({"texture": np.zeros((4, 4))}, r"texture must be \(h, w, 3\|4\) uint8"),
    ({"texture": np.zeros((4, 4, 2))}, r"texture must be \(h, w, 3\|4\) uint8"),
    ({"positions": [["a", "b", "c"]] * 4}, r"could not convert"),
])
def test_bad_shapes_and_dtypes_raise_value_error(kwargs, match):
    args = {"positions": TET_POSITIONS, "faces": TET_FACES} | kwargs
    with pytest.raises(ValueError, match=match):
        Mesh(**args)


# -- a mesh from kept faces (bench.core.mesh.compact, Mesh.keep_faces) -------------------------
def test_compact_renumbers_onto_the_used_vertices_in_order():
    from bench.core.mesh import compact

    used, faces = compact(np.array([[4, 2, 7], [7, 2, 9]]))
    assert used.tolist() == [2, 4, 7, 9]
    assert faces.tolist() == [[1, 0, 2], [2, 0, 3]]
    assert faces.dtype == np.int32
    empty_used, empty_faces = compact(np.zeros((0, 3), np.int64))
    assert empty_used.shape == (0,) and empty_faces.shape == (0, 3)


def test_compact_names_an_index_outside_the_vertices():
    from bench.core.mesh import compact

    with pytest.raises(ValueError, match="face index 5 is outside the mesh's 5 vertices"):
        compact(np.array([[0, 1, 5]]), 5)


def test_keep_faces_carries_every_attribute_of_the_used_vertices():
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [9, 9, 9]], float)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    colors = np.arange(20, dtype=np.uint8).reshape(5, 4)
    texture = np.zeros((2, 2, 3), np.uint8)
    mesh = Mesh(positions, [[0, 1, 2], [0, 2, 3], [1, 4, 2]], uv=uv, colors=colors,
                texture=texture, name="quad", metadata={"k": 1})
    kept = mesh.keep_faces(mesh.faces[[1]])
    assert kept.faces.tolist() == [[0, 1, 2]]
    assert kept.positions.tolist() == [[0, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert kept.uv.tolist() == [[0, 0], [1, 1], [0, 1]]
    assert kept.colors.tolist() == colors[[0, 2, 3]].tolist()
    assert kept.texture is texture and kept.name == "quad" and kept.metadata == {"k": 1}
    assert kept.normals is None


def test_keep_faces_matches_the_hand_written_compaction_it_replaces():
    # the mask-and-cumsum form methods/baselines.py and methods/meshopt.py used
    rng = np.random.default_rng(7)
    faces = rng.integers(0, 50, size=(40, 3))
    mask = np.zeros(50, bool)
    mask[faces.reshape(-1)] = True
    remap = np.cumsum(mask) - 1
    mesh = Mesh(rng.normal(size=(50, 3)), rng.integers(0, 50, size=(60, 3)))
    kept = mesh.keep_faces(faces)
    assert np.array_equal(kept.positions, mesh.positions[mask])
    assert np.array_equal(kept.faces, remap[faces].astype(np.int32))
