"""Input validation (errors and repair warnings) and save/load round trips."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from bench.core.errors import InputError, MeshWarning
from bench.core.mesh import Mesh
from bench.io.meshio import check_output_path, load_mesh, save_mesh
from bench.io.validate import build_mesh
from conftest import SEAM_FACES, SEAM_POSITIONS, SEAM_UV, TET_FACES, TET_POSITIONS, write

TRIANGLE_V = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def ply_ascii(vertices, faces) -> str:
    head = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
            "property float x", "property float y", "property float z",
            f"element face {len(faces)}", "property list uchar int vertex_indices",
            "end_header"]
    body = [" ".join(map(str, v)) for v in vertices]
    body += [" ".join(map(str, [len(f), *f])) for f in faces]
    return "\n".join(head + body) + "\n"


PLY_SQUARE_AND_TRIANGLE = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]]


# == load errors =============================================================================

def test_missing_file(tmp_path):
    path = tmp_path / "nope.obj"
    with pytest.raises(InputError, match=r"nope\.obj: no such file$"):
        load_mesh(path)


def test_directory(tmp_path):
    (tmp_path / "folder.obj").mkdir()
    with pytest.raises(InputError, match=r"folder\.obj: is a directory, not a mesh file"):
        load_mesh(tmp_path / "folder.obj")


def test_unknown_extension(tmp_path):
    path = write(tmp_path / "cloud.xyz", "1 2 3\n")
    with pytest.raises(InputError, match=r"cloud\.xyz: unknown mesh format '\.xyz'; "
                                         r"supported: \.obj, \.ply"):
        load_mesh(path)


def test_no_extension(tmp_path):
    path = write(tmp_path / "mesh", TRIANGLE_V + "f 1 2 3\n")
    with pytest.raises(InputError, match=r"unknown mesh format '\(none\)'"):
        load_mesh(path)


def test_obj_without_faces(tmp_path):
    path = write(tmp_path / "points.obj", TRIANGLE_V)
    with pytest.raises(InputError, match=r"points\.obj: the mesh has no faces"):
        load_mesh(path)


def test_empty_obj(tmp_path):
    path = write(tmp_path / "empty.obj", "")
    with pytest.raises(InputError, match=r"the mesh has no faces"):
        load_mesh(path)


def test_nan_position(tmp_path):
    path = write(tmp_path / "nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(InputError, match=r"nan\.obj: 1 vertices have NaN or infinite "
                                         r"coordinates \(first: vertex 0\)"):
        load_mesh(path)


@pytest.mark.parametrize("face, match", [
    ("f 1 2 4", r"line 4: face index 4 is out of range \(the file has 3 vertices\)"),
    ("f 1 2 9", r"line 4: face index 9 is out of range \(the file has 3 vertices\)"),
    ("f -1 -2 -4", r"line 4: face index -4 is out of range \(3 vertices defined before it\)"),
    ("f 0 1 2", r"line 4: face index 0 is out of range"),
    ("f 1/1 2/2 4/3", r"line 4: face index 4 is out of range"),
])
def test_obj_face_index_out_of_range(tmp_path, face, match):
    path = write(tmp_path / "bad.obj", TRIANGLE_V + face + "\n")
    with pytest.raises(InputError, match=match) as info:
        load_mesh(path)
    assert str(info.value).startswith(str(path))
    assert "corrupt or truncated" in str(info.value)


def test_obj_negative_index_counts_only_vertices_defined_before_the_face(tmp_path):
    # Relative index -3 on line 3 reaches before the first vertex, although the file
    # has three vertices in total.
    path = write(tmp_path / "rel.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n")
    with pytest.raises(InputError, match=r"line 3: face index -3 is out of range "
                                         r"\(2 vertices defined before it\)"):
        load_mesh(path)


def test_obj_negative_indices_in_range_are_fine(tmp_path):
    mesh = load_mesh(write(tmp_path / "rel.obj", TRIANGLE_V + "f -3 -2 -1\n"))
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])


def test_obj_bad_face_token(tmp_path):
    path = write(tmp_path / "tok.obj", TRIANGLE_V + "f a b c\n")
    with pytest.raises(InputError, match=r"line 4: bad face index 'a'"):
        load_mesh(path)


def test_ply_face_index_out_of_range(tmp_path):
    path = write(tmp_path / "bad.ply", ply_ascii(PLY_SQUARE_AND_TRIANGLE, [[0, 1, 2], [1, 7, 2]]))
    with pytest.raises(InputError, match=r"bad\.ply: face 1 refers to vertex 7 but the mesh "
                                         r"has 5 vertices \(1 faces out of range\)"):
        load_mesh(path)


def test_unparsable_ply(tmp_path):
    path = write(tmp_path / "junk.ply", "garbage\n")
    with pytest.raises(InputError, match=r"junk\.ply: could not read as PLY"):
        load_mesh(path)


def test_all_degenerate(tmp_path):
    path = write(tmp_path / "line.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n")
    with pytest.raises(InputError, match=r"line\.obj: all 2 faces are degenerate"):
        load_mesh(path)


# == load warnings ===========================================================================

def test_obj_quad_is_triangulated(tmp_path):
    path = write(tmp_path / "quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    with pytest.raises(MeshWarning):  # unexpected MeshWarnings fail tests (pyproject)
        load_mesh(path)
    with pytest.warns(MeshWarning, match=r"quad\.obj: triangulated 1 faces with more than "
                                         r"3 corners"):
        mesh = load_mesh(path)
    assert mesh.n_faces == 2
    assert mesh.welded.boundary.sum() == 4


def test_obj_pentagon_and_quad_are_triangulated(tmp_path):
    #  pentagon 1..5 (3 triangles) and a separate quad 6..9 (2 triangles)
    text = """
        v 0 0 0
        v 1 0 0
        v 1.5 1 0
        v 0.5 2 0
        v -0.5 1 0
        v 5 0 0
        v 6 0 0
        v 6 1 0
        v 5 1 0
        f 1 2 3 4 5
        f 6 7 8 9
    """
    with pytest.warns(MeshWarning, match=r"triangulated 2 faces with more than 3 corners"):
        mesh = load_mesh(write(tmp_path / "poly.obj", text))
    assert mesh.n_faces == 5
    np.testing.assert_allclose(mesh.face_normals, np.tile([0, 0, 1.0], (5, 1)))


def test_ply_polygon_is_triangulated(tmp_path):
    path = write(tmp_path / "poly.ply", ply_ascii(PLY_SQUARE_AND_TRIANGLE, [[0, 1, 2, 3], [1, 4, 2]]))
    with pytest.warns(MeshWarning, match=r"poly\.ply: triangulated polygon faces "
                                         r"\(2 faces in the file became 3 triangles\)"):
        mesh = load_mesh(path)
    assert mesh.n_faces == 3


def test_degenerate_faces_are_dropped_with_count(tmp_path):
    #  face 1: the real triangle; face 2: collinear (0,0,0),(1,0,0),(2,0,0);
    #  face 3: repeated corner
    text = TRIANGLE_V + "v 2 0 0\nf 1 2 3\nf 1 2 4\nf 1 1 3\n"
    with pytest.warns(MeshWarning, match=r"dropped 2 degenerate faces"):
        mesh = load_mesh(write(tmp_path / "degen.obj", text))
    assert mesh.n_faces == 1
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])


def test_missing_texture_image(tmp_path):
    write(tmp_path / "m.mtl", "newmtl mat\nmap_Kd missing.png\n")
    text = """
        mtllib m.mtl
        usemtl mat
        v 0 0 0
        v 1 0 0
        v 0 1 0
        vt 0 0
        vt 1 0
        vt 0 1
        f 1/1 2/2 3/3
    """
    with pytest.warns(MeshWarning, match=r"texture image not found \(missing\.png\); "
                                         r"loading untextured \(UVs kept\)"):
        mesh = load_mesh(write(tmp_path / "tex.obj", text))
    assert mesh.texture is None
    assert not mesh.has_texture
    assert mesh.uv is not None
    # each corner keeps its own UV: the UV of a vertex equals its (x, y)
    np.testing.assert_allclose(mesh.uv, mesh.positions[:, :2])


# trimesh substitutes a 2x2 placeholder image for textured meshes without a material;
# the loader must not take it for the asset's texture.


def test_missing_material_file(tmp_path):
    text = "mtllib gone.mtl\nusemtl mat\n" + TRIANGLE_V + "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = load_mesh(write(tmp_path / "tex.obj", text))
    assert mesh.uv is not None
    assert mesh.texture is None
    assert [str(w.message).split(": ", 1)[1] for w in caught] == [
        "texture image not found (gone.mtl (material file)); loading untextured (UVs kept)"]


def test_obj_with_uvs_and_no_material_is_untextured(tmp_path):
    text = TRIANGLE_V + "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"
    mesh = load_mesh(write(tmp_path / "uv.obj", text))
    assert mesh.uv is not None
    assert mesh.texture is None


def test_non_manifold_edges_are_reported(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"
    with pytest.warns(MeshWarning, match=r"book\.obj: 1 non-manifold edges \(more than two "
                                         r"faces\); allowed"):
        mesh = load_mesh(write(tmp_path / "book.obj", text))
    assert mesh.n_faces == 3


# == build_mesh on arrays ====================================================================

TRI = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)


@pytest.mark.parametrize("positions, faces, match", [
    (np.zeros((3, 2)), [[0, 1, 2]], r"src: positions must be an \(n, 3\) array, got shape \(3, 2\)"),
    (TRI, np.zeros((0, 3), int), r"src: the mesh has no faces"),
    (TRI, [], r"src: the mesh has no faces"),
    (TRI, [[0, 1, 2, 0]], r"src: faces must be an \(m, 3\) array of triangles, got shape \(1, 4\)"),
    (TRI, [0, 1, 2], r"faces must be an \(m, 3\) array of triangles, got shape \(3,\)"),
    (TRI, [[0.0, 1.0, 2.0]], r"src: face indices must be integers, got float64"),
    ([[0, 0, 0], [np.inf, 0, 0], [0, np.nan, 0]], [[0, 1, 2]],
     r"src: 2 vertices have NaN or infinite coordinates \(first: vertex 1\)"),
    (TRI, [[0, 1, 2], [0, 1, 3]],
     r"src: face 1 refers to vertex 3 but the mesh has 3 vertices \(1 faces out of range\)"),
    (TRI, [[0, 1, -1]], r"src: face 0 refers to vertex -1 but the mesh has 3 vertices"),
    (TRI, [[0, 1, 1], [2, 2, 2]], r"src: all 2 faces are degenerate"),
])
def test_build_mesh_errors(positions, faces, match):
    with pytest.raises(InputError, match=match) as info:
        build_mesh(positions, faces, source="src")
    assert isinstance(info.value, ValueError)


def test_build_mesh_clean_input_passes_without_warnings():
    mesh = build_mesh(TET_POSITIONS, TET_FACES, source="tet", uv=np.zeros((4, 2)))
    assert mesh.name == "tet"
    assert mesh.n_faces == 4 and mesh.faces.dtype == np.int32
    assert mesh.uv is not None


def test_build_mesh_drops_degenerate_face_across_a_seam():
    # Face 2 uses render vertices 1 and 3, which are copies of one position: a repeated
    # welded corner, so it is dropped although its render indices are all distinct.
    positions = np.vstack([TRI, TRI[1:2]])
    with pytest.warns(MeshWarning, match=r"dropped 1 degenerate faces"):
        mesh = build_mesh(positions, [[0, 1, 2], [0, 1, 3]], source="s")
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2]])
    assert mesh.n_vertices == 4  # unused vertices are kept, indices unchanged


@pytest.mark.parametrize("kwargs, match", [
    ({"uv": np.zeros((2, 2))}, r"s: ignoring uv of shape \(2, 2\) \(expected \(3, 2\)\)"),
    ({"normals": np.zeros((3, 2))}, r"ignoring normals of shape \(3, 2\) \(expected \(3, 3\)\)"),
    ({"uv": [[0, 0], [np.nan, 0], [0, 1]]}, r"s: ignoring uv: they contain NaN or infinite"),
])
def test_build_mesh_drops_bad_attributes_with_warning(kwargs, match):
    with pytest.warns(MeshWarning, match=match):
        mesh = build_mesh(TRI, [[0, 1, 2]], source="s", **kwargs)
    assert mesh.uv is None and mesh.normals is None


def test_build_mesh_reports_non_manifold_edges():
    positions = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]
    with pytest.warns(MeshWarning, match=r"book: 1 non-manifold edges"):
        build_mesh(positions, [[0, 1, 2], [1, 0, 3], [0, 1, 4]], source="book")


# == round trips =============================================================================

SEAM_OBJ = """
    mtllib {stem}.mtl
    usemtl mat
    v 0 1 0
    v 1 1 0
    v 0 0 0
    v 1 0 0
    vt 0 1
    vt 0.5 1
    vt 0 0
    vt 0.6 1
    vt 0.6 0
    vt 1 0
    f 1/1 3/3 2/2
    f 2/4 3/5 4/6
"""
#  The seam quad of conftest as a file: 4 positions, 6 texture coordinates. The faces
#  use different UVs for the shared diagonal, so the loader makes 6 render vertices.
#  Expected corners (position, uv) of each face, in winding order:
SEAM_CORNERS = [
    [((0, 1, 0), (0, 1)), ((0, 0, 0), (0, 0)), ((1, 1, 0), (0.5, 1))],
    [((1, 1, 0), (0.6, 1)), ((0, 0, 0), (0.6, 0)), ((1, 0, 0), (1, 0))],
]


def texture_image(seed: int, h: int = 4, w: int = 6) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 3), dtype=np.uint8)


@pytest.fixture
def seam_obj(tmp_path):
    """An OBJ + MTL + PNG of the seam quad; returns (path, texture pixels)."""
    src = tmp_path / "src"
    src.mkdir()
    tex = texture_image(0)
    Image.fromarray(tex).save(src / "seam.png")
    write(src / "seam.mtl", "newmtl mat\nmap_Kd seam.png\n")
    return write(src / "seam.obj", SEAM_OBJ.format(stem="seam")), tex


def corners(mesh: Mesh) -> list:
    """Per face, its (position, uv) corners rotated to start at the smallest one."""
    out = []
    for face in mesh.faces:
        c = [(tuple(mesh.positions[v].tolist()), tuple(np.round(mesh.uv[v], 6).tolist()))
             for v in face]
        k = c.index(min(c))
        out.append(c[k:] + c[:k])
    return out


def rotated(face):
    k = face.index(min(face))
    return [tuple((tuple(map(float, p)), tuple(map(float, t)))) for p, t in face[k:] + face[:k]]


def test_seam_obj_loads_as_render_vertices(seam_obj):
    path, tex = seam_obj
    mesh = load_mesh(path)
    assert mesh.name == "seam"
    assert mesh.n_vertices == 6 and mesh.welded.n_vertices == 4
    assert mesh.welded.seam.sum() == 1 and mesh.welded.boundary.sum() == 4
    assert corners(mesh) == [rotated(f) for f in SEAM_CORNERS]
    np.testing.assert_array_equal(mesh.texture, tex)


def test_obj_round_trip_keeps_seams_uvs_and_texture(seam_obj, tmp_path):
    path, tex = seam_obj
    mesh = load_mesh(path)
    out = tmp_path / "out"
    out.mkdir()
    written = save_mesh(mesh, out / "result.obj")
    assert sorted(p.name for p in written) == ["result.mtl", "result.obj", "result.png"]
    assert sorted(p.name for p in out.iterdir()) == ["result.mtl", "result.obj", "result.png"]

    back = load_mesh(out / "result.obj")
    assert back.n_vertices == mesh.n_vertices == 6
    assert back.welded.n_vertices == 4
    assert back.welded.seam.sum() == 1
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(back.positions, mesh.positions)
    np.testing.assert_allclose(back.uv, mesh.uv)
    np.testing.assert_array_equal(back.texture, tex)


def test_obj_round_trip_of_an_in_memory_mesh(tmp_path):
    tex = texture_image(1, 8, 5)
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV, texture=tex)
    save_mesh(mesh, tmp_path / "mem.obj")
    back = load_mesh(tmp_path / "mem.obj")
    assert back.n_vertices == 6 and back.welded.n_vertices == 4
    assert corners(back) == corners(mesh)
    np.testing.assert_array_equal(back.texture, tex)


def test_two_stems_in_one_folder_do_not_clobber(seam_obj, tmp_path):
    path, tex_a = seam_obj
    a = load_mesh(path)
    tex_b = texture_image(2)
    b = a.replace(texture=tex_b)
    save_mesh(a, tmp_path / "a.obj")
    save_mesh(b, tmp_path / "b.obj")
    names = {p.name for p in tmp_path.iterdir() if p.is_file()}
    assert names == {"a.obj", "a.mtl", "a.png", "b.obj", "b.mtl", "b.png"}
    np.testing.assert_array_equal(load_mesh(tmp_path / "a.obj").texture, tex_a)
    np.testing.assert_array_equal(load_mesh(tmp_path / "b.obj").texture, tex_b)
    assert not np.array_equal(tex_a, tex_b)


def test_obj_with_uvs_but_no_texture_round_trips_without_image(tmp_path):
    mesh = Mesh(SEAM_POSITIONS, SEAM_FACES, uv=SEAM_UV)
    written = save_mesh(mesh, tmp_path / "plain.obj")
    assert sorted(p.name for p in written) == ["plain.mtl", "plain.obj"]
    back = load_mesh(tmp_path / "plain.obj")
    assert back.texture is None
    assert corners(back) == corners(mesh)


@pytest.mark.parametrize("ext", [".ply", ".off", ".glb"])
def test_round_trip_positions_and_faces(tmp_path, ext):
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    assert [p.name for p in save_mesh(mesh, tmp_path / f"tet{ext}")] == [f"tet{ext}"]
    back = load_mesh(tmp_path / f"tet{ext}")
    np.testing.assert_array_equal(back.positions, mesh.positions)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    assert back.welded.boundary.sum() == 0


def test_glb_round_trip_keeps_uvs_and_texture(seam_obj, tmp_path):
    path, tex = seam_obj
    mesh = load_mesh(path)
    save_mesh(mesh, tmp_path / "seam.glb")
    back = load_mesh(tmp_path / "seam.glb")
    np.testing.assert_array_equal(back.positions, mesh.positions)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_allclose(back.uv, mesh.uv, atol=1e-6)  # GLB stores float32
    np.testing.assert_array_equal(back.texture, tex)
    assert back.welded.seam.sum() == 1


def test_ply_round_trip_keeps_uvs(seam_obj, tmp_path):
    path, _ = seam_obj
    mesh = load_mesh(path)
    save_mesh(mesh, tmp_path / "seam.ply")
    back = load_mesh(tmp_path / "seam.ply")
    np.testing.assert_array_equal(back.positions, mesh.positions)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_allclose(back.uv, mesh.uv, atol=1e-6)


def test_ply_round_trip_has_no_texture(seam_obj, tmp_path):
    path, _ = seam_obj
    save_mesh(load_mesh(path), tmp_path / "seam.ply")
    assert load_mesh(tmp_path / "seam.ply").texture is None


def test_gltf_round_trip(tmp_path):
    mesh = Mesh(TET_POSITIONS, TET_FACES)
    save_mesh(mesh, tmp_path / "tet.gltf")
    back = load_mesh(tmp_path / "tet.gltf")
    np.testing.assert_array_equal(back.faces, mesh.faces)


def test_bunny_textured_obj_round_trip(bunny_textured, tmp_path):
    mesh = bunny_textured
    save_mesh(mesh, tmp_path / "bunny.obj")
    back = load_mesh(tmp_path / "bunny.obj")
    assert back.n_faces == mesh.n_faces
    assert back.n_vertices == mesh.n_vertices
    assert back.welded.n_vertices == mesh.welded.n_vertices
    assert back.welded.seam.sum() == mesh.welded.seam.sum() > 0
    assert back.welded.boundary.sum() == mesh.welded.boundary.sum()
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_allclose(back.positions, mesh.positions, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back.uv, mesh.uv, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(back.texture, mesh.texture)


# == output paths ============================================================================

def test_check_output_path(tmp_path):
    assert check_output_path(tmp_path / "x.OBJ") == tmp_path / "x.OBJ"
    with pytest.raises(InputError, match=r"unknown mesh format '\.xyz'"):
        check_output_path(tmp_path / "x.xyz")
    with pytest.raises(InputError, match=r"folder .*missing does not exist; create it first"):
        check_output_path(tmp_path / "missing" / "x.obj")


def test_output_path_that_is_a_directory(tmp_path):
    (tmp_path / "out.obj").mkdir()
    with pytest.raises(InputError):
        save_mesh(Mesh(TET_POSITIONS, TET_FACES), tmp_path / "out.obj")
