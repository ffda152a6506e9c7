"""Multi-material assets (bench.io.atlas, the loaders and writers of bench.io.meshio).

The asset under test is the two-material sphere of ``bench.catalog.materials``: bricks
(256 x 256) on the northern hemisphere, waves (128 x 256) on the southern, generated
here. The OBJ and the GLB the tests read are written by the tests themselves (text for
the OBJ, trimesh for the GLB), not by the suite's writers, so loading is checked
against files made independently. The expectations are the file's own: which faces use
which material (a face of the north has its centroid at z > 0), the texture images
pixel for pixel, the UVs of each material in its own space.
"""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import warnings

import numpy as np
import pytest
from PIL import Image

from bench.catalog.materials import make_two_materials, two_material_parts
from bench.core.errors import InputError, MeshWarning
from bench.core.method import run_method
from bench.core.registry import registry
from bench.io.atlas import (
    GUTTER,
    Part,
    face_materials,
    material_image,
    materials_of,
    mixed_faces,
    pack_materials,
    split_materials,
    wedge_tiles,
)
from bench.io.meshio import load_mesh, save_lods, save_mesh

NAMES = ["bricks", "waves"]


def originals():
    """{material name: (positions, faces, uv, image)} of the generated halves."""
    return {p.material: (p.positions, p.faces, p.uv, p.image) for p in two_material_parts()}


def write_obj(folder, parts=None, normals=False):
    """An OBJ as an exporter writes one: every part's own ``v``/``vt`` lines, one
    ``usemtl`` group per material, an MTL naming each texture, the PNGs."""
    parts = parts or two_material_parts()
    lines, mtl, base = ["mtllib asset.mtl"], [], 0
    for part in parts:
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in part.positions.tolist()]
        lines += [f"vt {u!r} {v!r}" for u, v in part.uv.tolist()]
        lines.append(f"usemtl {part.material}")
        lines += ["f " + " ".join(f"{i}/{i}" for i in (face + base + 1).tolist())
                  for face in part.faces]
        base += len(part.positions)
        mtl += [f"newmtl {part.material}",
                "Kd {:.6g} {:.6g} {:.6g}".format(*(c / 255 for c in part.color[:3]))]
        if part.image is not None:
            Image.fromarray(part.image).save(folder / f"{part.material}.png")
            mtl.append(f"map_Kd {part.material}.png")
    (folder / "asset.obj").write_text("\n".join(lines) + "\n")
    (folder / "asset.mtl").write_text("\n".join(mtl) + "\n")
    return folder / "asset.obj"


def write_glb(path):
    """A GLB with one mesh and node per material, as trimesh exports a scene."""
    import trimesh

    scene = trimesh.Scene()
    for part in two_material_parts():
        tm = trimesh.Trimesh(part.positions, part.faces, process=False)
        material = trimesh.visual.material.PBRMaterial(
            name=part.material, baseColorTexture=Image.fromarray(part.image))
        tm.visual = trimesh.visual.TextureVisuals(uv=part.uv, material=material)
        scene.add_geometry(tm, geom_name=part.material, node_name=part.material)
    path.write_bytes(scene.export(file_type="glb"))
    return path


def glb_json(path) -> dict:
    data = path.read_bytes()
    length = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + length])


def hemisphere_of(mesh) -> np.ndarray:
    """0 for faces whose centroid is north of the equator, 1 south: the generated
    asset's material of each face."""
    return (mesh.positions[mesh.faces].mean(axis=1)[:, 2] < 0).astype(int)


def _sorted(rows: np.ndarray) -> np.ndarray:
    rows = np.round(rows, 6)  # glTF stores float32: sort on what survives it
    return rows[np.lexsort(rows.T[::-1])]


def own_space(mesh):
    """{material: sorted rows (x, y, z, u, v)} of each material's render vertices with
    the UVs mapped back out of the atlas (vertex order is the loader's business)."""
    return {part.material["name"]: _sorted(np.column_stack([mesh.positions[part.vertices],
                                                             part.uv]))
            for part in split_materials(mesh)}


def original_space():
    out = {}
    for name, (positions, faces, uv, _) in originals().items():
        used = np.unique(faces)
        out[name] = _sorted(np.column_stack([positions[used], uv[used]]))
    return out


def assert_is_the_asset(mesh):
    """``mesh`` holds the two-material sphere with every material kept: UVs back in
    each material's own space agree with the file's to 1e-6 (glTF's float32)."""
    materials = materials_of(mesh)
    assert [m["name"] for m in materials] == NAMES
    of_face = face_materials(mesh)
    assert np.bincount(of_face).tolist() == [1984, 1984]
    assert np.array_equal(of_face, hemisphere_of(mesh))
    assert not mixed_faces(mesh).any()
    for material in materials:
        assert np.array_equal(material_image(mesh, material), originals()[material["name"]][3])
    mine, theirs = own_space(mesh), original_space()
    for name in NAMES:
        assert mine[name].shape == theirs[name].shape
        assert np.allclose(mine[name], theirs[name], atol=1.5e-6, rtol=0)


@pytest.fixture(scope="module")
def asset_obj(tmp_path_factory):
    return write_obj(tmp_path_factory.mktemp("obj"))


@pytest.fixture(scope="module")
def loaded(asset_obj):
    return load_mesh(asset_obj)


# -- the atlas --------------------------------------------------------------------------------

def test_atlas_layout_and_gutter():
    mesh = make_two_materials()
    h, w = mesh.texture.shape[:2]
    rects = [m["rect"] for m in materials_of(mesh)]
    assert [r[2:] for r in rects] == [[256, 256], [128, 256]]
    for (x, y, rw, rh), material in zip(rects, materials_of(mesh)):
        assert x % GUTTER == 0 and y % GUTTER == 0  # mip blocks of 8 stay in one tile
        u0, v0, u1, v1 = material["tile"]
        assert (u0, u1) == (x / w, (x + rw) / w)
        assert (v0, v1) == ((h - y - rh) / h, (h - y) / h)  # UV origin bottom-left
        tile = mesh.texture[y - GUTTER:y + rh + GUTTER, x - GUTTER:x + rw + GUTTER]
        inner = tile[GUTTER:-GUTTER, GUTTER:-GUTTER]
        # the gutter repeats the edge texels: rows above/below, columns left/right
        assert (tile[:GUTTER, GUTTER:-GUTTER] == inner[:1]).all()
        assert (tile[-GUTTER:, GUTTER:-GUTTER] == inner[-1:]).all()
        assert (tile[:, :GUTTER] == tile[:, GUTTER:GUTTER + 1]).all()
        assert (tile[:, -GUTTER:] == tile[:, -GUTTER - 1:-GUTTER]).all()
    (ax, ay, aw, ah), (bx, by, bw, bh) = rects
    apart = ax + aw + 2 * GUTTER <= bx or bx + bw + 2 * GUTTER <= ax or \
        ay + ah + 2 * GUTTER <= by or by + bh + 2 * GUTTER <= ay
    assert apart  # tiles and their gutters do not overlap


def test_catalog_model_is_what_loading_the_file_gives(loaded):
    made = make_two_materials()
    assert_is_the_asset(made)
    assert np.array_equal(made.texture, loaded.texture)
    assert materials_of(made)[0]["tile"] == materials_of(loaded)[0]["tile"]
    summary = made.summary()
    # the equator: 64 welded vertices shared by the halves, a seam between materials
    assert summary["welded_vertices"] == 2 * (16 * 64 + 1) - 64
    assert summary["boundary_edges"] == 0


# -- loading ----------------------------------------------------------------------------------

def test_obj_with_two_usemtl_groups_loads_as_one_mesh(loaded, asset_obj):
    assert loaded.n_faces == 2 * 1984
    assert_is_the_asset(loaded)
    assert materials_of(loaded)[0]["texture"] == {
        "source": str(asset_obj.parent / "bricks.png"), "size": [256, 256]}
    # materials meet along a seam: the equator's welded edges are seams, not boundaries
    assert loaded.summary()["boundary_edges"] == 0


def test_glb_with_two_primitives_loads_as_one_mesh(tmp_path):
    mesh = load_mesh(write_glb(tmp_path / "asset.glb"))
    assert mesh.n_faces == 2 * 1984
    assert_is_the_asset(mesh)


def test_colour_only_material_becomes_a_solid_tile(tmp_path):
    bricks, waves = two_material_parts()
    waves = Part("paint", waves.positions, waves.faces, uv=waves.uv, color=(40, 200, 90, 255))
    mesh = load_mesh(write_obj(tmp_path, [bricks, waves]))
    paint = materials_of(mesh)[1]
    assert paint["texture"] is None and paint["color"] == [40, 200, 90, 255]
    x, y, w, h = paint["rect"]
    assert (mesh.texture[y - GUTTER:y + h + GUTTER, x - GUTTER:x + w + GUTTER]
            == (40, 200, 90)).all()
    of_face = face_materials(mesh)
    assert np.array_equal(of_face, hemisphere_of(mesh))
    u0, v0, u1, v1 = paint["tile"]
    corners = mesh.uv[mesh.faces[of_face == 1]].reshape(-1, 2)
    assert np.allclose(corners, [(u0 + u1) / 2, (v0 + v1) / 2])  # one colour, one UV
    out = tmp_path / "out" / "paint.obj"
    out.parent.mkdir()
    save_mesh(mesh, out)
    mtl = (out.parent / "paint.mtl").read_text()
    assert "newmtl paint\nKd 0.156863 0.784314 0.352941\n" in mtl
    assert mtl.count("map_Kd") == 1  # the bricks' only
    again = load_mesh(out)
    assert materials_of(again)[1]["color"] == [40, 200, 90, 255]
    assert np.array_equal(face_materials(again), hemisphere_of(again))


def test_missing_texture_of_one_material_warns_and_uses_its_colour(tmp_path):
    path = write_obj(tmp_path)
    (tmp_path / "waves.png").unlink()
    with pytest.warns(MeshWarning, match=r"material 'waves': texture image not found "
                      r"\(.*waves.png\); using its colour"):
        mesh = load_mesh(path)
    assert materials_of(mesh)[1]["texture"] is None
    assert np.array_equal(face_materials(mesh), hemisphere_of(mesh))


def test_repeating_texture_is_replicated_in_its_tile():
    """UVs spanning [-1, 1] x [0, 2] repeat the texture 2 x 2 times: the tile holds four
    copies and every UV samples the texel the repeating texture would."""
    image = np.random.default_rng(5).integers(0, 256, (16, 24, 3), dtype=np.uint8)
    rng = np.random.default_rng(6)
    uv = np.column_stack([rng.uniform(-1, 1, 30), rng.uniform(0, 2, 30)])
    positions = rng.standard_normal((30, 3))
    faces = np.arange(30).reshape(10, 3)
    other = Part("plain", positions + 5, faces, uv=rng.uniform(0, 1, (30, 2)), image=image[:8])
    mesh = pack_materials([Part("tiled", positions, faces, uv=uv, image=image), other],
                          source="test", name="repeat")
    tiled = materials_of(mesh)[0]
    assert tiled["repeat"] == [2, 2] and tiled["offset"] == [-1.0, 0.0]
    assert np.array_equal(material_image(mesh, tiled), image)

    def texel(img, u, v):  # nearest texel, repeating, origin bottom-left
        h, w = img.shape[:2]
        return img[np.floor((1 - v % 1) * h).astype(int) % h, np.floor(u % 1 * w).astype(int)]

    of_vertex = mesh.uv[:30]
    assert np.array_equal(texel(mesh.texture, of_vertex[:, 0], of_vertex[:, 1]),
                          texel(image, uv[:, 0], uv[:, 1]))
    back = split_materials(mesh)[0]
    assert np.allclose(back.uv, uv[back.vertices], atol=1e-12)


def test_repeat_too_large_for_an_atlas_is_refused_naming_the_material():
    image = np.zeros((1024, 1024, 3), np.uint8)
    uv = np.array([[0, 0], [12.5, 0], [0, 1]], float)
    part = Part("floor tiles", np.eye(3), np.array([[0, 1, 2]]), uv=uv, image=image)
    with pytest.raises(InputError, match="material 'floor tiles' repeats its 1024 x 1024 "
                       "texture 13 x 1 times"):
        pack_materials([part, Part("x", np.eye(3) + 1, np.array([[0, 1, 2]]))],
                       source="scene.obj", name="scene")


def test_single_material_obj_is_loaded_as_before(tmp_path):
    """One usemtl group: no atlas, the texture as the file has it."""
    bricks = two_material_parts()[0]
    mesh = load_mesh(write_obj(tmp_path, [bricks]))
    assert "atlas" not in mesh.metadata
    assert np.array_equal(mesh.texture, bricks.image)
    assert materials_of(mesh) is None and face_materials(mesh) is None


# -- writing ----------------------------------------------------------------------------------

def test_obj_round_trip_keeps_materials_textures_and_uvs(loaded, tmp_path):
    out = tmp_path / "copy.obj"
    written = save_mesh(loaded, out)
    assert sorted(p.name for p in written) == ["copy.mtl", "copy.obj", "copy_bricks.png",
                                               "copy_waves.png"]
    text = out.read_text()
    assert [line for line in text.splitlines() if line.startswith("usemtl")] == [
        "usemtl bricks", "usemtl waves"]
    for name in NAMES:  # each material's own texture, pixel for pixel
        assert np.array_equal(np.asarray(Image.open(tmp_path / f"copy_{name}.png")),
                              originals()[name][3])
    assert "map_Kd copy_bricks.png" in (tmp_path / "copy.mtl").read_text()
    again = load_mesh(out)
    assert_is_the_asset(again)
    assert again.summary() == loaded.summary()


def test_glb_round_trip_one_mesh_with_a_primitive_per_material(loaded, tmp_path):
    out = tmp_path / "copy.glb"
    save_mesh(loaded, out)
    doc = glb_json(out)
    assert [m["name"] for m in doc["meshes"]] == ["copy"]
    primitives = doc["meshes"][0]["primitives"]
    assert [doc["materials"][p["material"]]["name"] for p in primitives] == NAMES
    assert len(doc["images"]) == 2 and len(doc["nodes"]) == 1
    again = load_mesh(out)
    assert_is_the_asset(again)
    assert again.summary() == loaded.summary()


def test_lod_chain_of_a_multi_material_mesh(loaded, tmp_path):
    lower = run_method(registry("method").load("quadric")(), loaded, 1000).mesh
    out = tmp_path / "lods.glb"
    save_lods([("LOD0", loaded), ("LOD1", lower)], out)
    doc = glb_json(out)
    assert [m["name"] for m in doc["meshes"]] == ["LOD0", "LOD1"]
    assert all(len(m["primitives"]) == 2 for m in doc["meshes"])
    assert len(doc["materials"]) == 2 and len(doc["images"]) == 2  # shared by the levels
    files = save_lods([("LOD0", loaded), ("LOD1", lower)], tmp_path / "lods.obj")
    again = load_mesh(files["LOD1"][0])
    assert np.array_equal(face_materials(again), hemisphere_of(again))


def test_mixed_faces_are_written_with_a_warning(loaded, tmp_path):
    uv = loaded.uv.copy()
    face = loaded.faces[0]
    uv[face[0]] = materials_of(loaded)[1]["tile"][:2]  # one corner into the other tile
    broken = loaded.replace(uv=uv)
    assert mixed_faces(broken).sum() >= 1
    with pytest.warns(MeshWarning, match="faces have UV corners in two materials' tiles"):
        save_mesh(broken, tmp_path / "mixed.obj")


# -- methods keep materials apart --------------------------------------------------------------

@pytest.fixture(scope="module")
def two_materials():
    return make_two_materials()


@pytest.mark.parametrize("method", ["quadric", "memoryless", "canny-texture", "qslim-texture"])
def test_no_collapse_mixes_two_materials(two_materials, method):
    """At 10 % no face of the result has UV corners in two tiles.

    On the suite's engine, besides, every UV stays inside its material's tile (the
    engine clamps merged wedges' UVs there: without it quadric left 2 faces sampling
    the other texture) and every face keeps the material of its hemisphere (the seam
    rule keeps the equator's vertices on the equator). MeshLab's qslim-texture keeps
    the materials' UVs apart too but moves seam vertices off the seam: one face of the
    bricks reaches z = -0.1, so its hemisphere is not checked."""
    target = round(0.1 * two_materials.n_faces)
    result = run_method(registry("method").load(method)(), two_materials, target).mesh
    assert abs(result.n_faces - target) <= 2
    assert materials_of(result) is not None
    assert int(mixed_faces(result).sum()) == 0
    if method != "qslim-texture":
        tiles = wedge_tiles(result)[np.unique(result.faces)]
        uv = result.uv[np.unique(result.faces)]
        assert ((uv >= tiles[:, :2]) & (uv <= tiles[:, 2:])).all()
        assert np.array_equal(face_materials(result), hemisphere_of(result))


def test_simplified_result_round_trips_with_its_materials(two_materials, tmp_path):
    result = run_method(registry("method").load("quadric")(), two_materials,
                        round(0.25 * two_materials.n_faces)).mesh
    expected = face_materials(result)
    assert np.array_equal(expected, hemisphere_of(result))
    for name in ("lod.obj", "lod.glb"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            save_mesh(result, tmp_path / name)
        again = load_mesh(tmp_path / name)
        assert again.n_faces == result.n_faces
        assert np.bincount(face_materials(again)).tolist() == np.bincount(expected).tolist()
        assert np.array_equal(face_materials(again), hemisphere_of(again))
        for material in materials_of(again):
            assert np.array_equal(material_image(again, material),
                                  originals()[material["name"]][3])


# -- rendering --------------------------------------------------------------------------------

def test_each_half_renders_with_its_own_texture(loaded):
    """Seen from above the north pole, the loaded mesh looks like the northern half alone
    with the bricks texture as a single-material mesh; from below, like the southern
    half with the waves.

    Without mipmaps and multisampling the atlas samples exactly the file's texels, except
    along each half's wrap-around seam, where the file's repeating texture blends its
    first and last columns and the atlas repeats its edge texel (measured: 0 and 0.2 % of
    the covered pixels). With the protocol's mipmaps and 4x MSAA, llvmpipe's centroid
    interpolation is less exact for UVs far from 0 and mip levels above 3 straddle the
    tiles, so the images differ by fractions of a level on average (measured 0.1 and 0.7).
    """
    import dataclasses

    from bench.core.mesh import Mesh
    from metrics.render import BACKGROUND, DEFAULT_CONSTANTS, get_renderer
    from metrics.views import Camera

    renderer = get_renderer(256, 256, 4)
    exact = dataclasses.replace(DEFAULT_CONSTANTS, mipmaps=False)
    for name, z in (("bricks", 3.0), ("waves", -3.0)):
        positions, faces, uv, image = originals()[name]
        alone = Mesh(positions, faces, uv=uv, texture=image)
        camera = Camera(eye=[0.0, 0.0, z], target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0],
                        near=1.0, far=5.0)
        for constants, msaa, worst, mean in ((exact, False, 0.005, 0.1),
                                             (DEFAULT_CONSTANTS, None, 0.2, 1.0)):
            both = renderer.render(loaded, [camera], constants=constants, msaa=msaa)[0]
            reference = renderer.render(alone, [camera], constants=constants, msaa=msaa)[0]
            covered = (reference != BACKGROUND).any(-1)
            assert covered.mean() > 0.2
            diff = np.abs(both.astype(int) - reference)[covered]
            assert np.mean(diff.max(axis=-1) > 2) < worst, (name, constants.mipmaps)
            assert diff.mean() < mean, (name, constants.mipmaps)
        hue = both[covered].mean(axis=0)
        assert (hue[0] > 2 * hue[2]) if name == "bricks" else (hue[2] > 2 * hue[0])


# -- the command line -------------------------------------------------------------------------

def test_bench_simplify_writes_the_materials_back(asset_obj, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    out = tmp_path / "lod.obj"
    proc = subprocess.run([sys.executable, "-m", "bench", "simplify", str(asset_obj), str(out),
                           "--method", "quadric", "--ratio", "0.25"],
                          check=False, capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lod.mtl", "lod.obj", "lod_bricks.png",
                                                          "lod_waves.png"]
    mesh = load_mesh(out)
    assert abs(mesh.n_faces - 992) <= 2
    assert [m["name"] for m in materials_of(mesh)] == NAMES
    assert np.array_equal(face_materials(mesh), hemisphere_of(mesh))
