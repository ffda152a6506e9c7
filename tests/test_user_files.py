"""Loading and writing the files users have: texture and material file names with
spaces, and texture options, in an MTL; an OBJ with UVs and no ``mtllib`` (a warning,
and ``MODEL::texture=IMAGE``); the material a written mesh gets; a written mesh reading
back as it renders."""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from test_cli import assert_one_line_error, bench

from bench.catalog import parse_model_spec, resolve_model
from bench.core.errors import InputError, MeshWarning, UnknownNameError
from bench.core.mesh import Mesh
from bench.io.meshio import _map_file, input_files, load_mesh, save_lods, save_mesh
from conftest import write

WILD = Path(__file__).resolve().parents[2] / "shared" / "assets" / "wild"

#: A unit square as two triangles with UVs covering [0, 1]^2.
SQUARE_UV = """\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
"""


def image(path: Path, rgb, size=(4, 2)) -> np.ndarray:
    """Write a solid ``size`` (w, h) image of colour ``rgb`` with one odd texel, so a
    flipped or resampled image would not compare equal; its pixels."""
    pixels = np.empty((size[1], size[0], 3), np.uint8)
    pixels[:] = rgb
    pixels[0, 0] = (1, 2, 3)
    Image.fromarray(pixels).save(path)
    return pixels


def no_warnings(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*args, **kwargs)


# == texture names with spaces, and options, in an MTL ======================================

@pytest.mark.parametrize("statement", [
    "map_Kd my tex.png",
    "map_Kd   my tex.png  ",
    "map_Kd -s 1 1 1 -clamp on my tex.png",
    "map_Kd -o 0.5 -bm 0.2 my tex.png",
    "map_Kd -mm 0 1 -s 2 2 my tex.png",
    "map_Kd -blendu off -blendv off -imfchan l -texres 512 -t 0 0 0 my tex.png",
])
def test_a_texture_name_with_a_space_loads(tmp_path, statement):
    """MTL: the file name is the rest of the line after the options."""
    pixels = image(tmp_path / "my tex.png", (200, 10, 10))
    write(tmp_path / "a.mtl", f"newmtl m\nKd 1 1 1\n{statement}\n")
    write(tmp_path / "sq.obj", "mtllib a.mtl\n" + SQUARE_UV + "usemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    mesh = no_warnings(load_mesh, tmp_path / "sq.obj")
    np.testing.assert_array_equal(mesh.texture, pixels)
    assert (tmp_path / "my tex.png", "texture") in input_files(tmp_path / "sq.obj")


def test_a_material_file_name_with_a_space(tmp_path):
    """``mtllib`` naming one file with a space in its name (as the OBJ writer writes for
    an output named so)."""
    pixels = image(tmp_path / "t.png", (1, 100, 1))
    write(tmp_path / "my materials.mtl", "newmtl m\nmap_Kd t.png\n")
    write(tmp_path / "sq.obj", "mtllib my materials.mtl\n" + SQUARE_UV + "usemtl m\nf 1/1 2/2 3/3\n")
    np.testing.assert_array_equal(no_warnings(load_mesh, tmp_path / "sq.obj").texture, pixels)
    assert (tmp_path / "my materials.mtl", "material") in input_files(tmp_path / "sq.obj")


def test_several_materials_with_spaces_and_options(tmp_path):
    red = image(tmp_path / "red tex.png", (200, 10, 10))
    green = image(tmp_path / "green tex.png", (10, 200, 10))
    write(tmp_path / "b.mtl", "newmtl r\nmap_Kd -o 0.5 red tex.png\n"
                              "newmtl g\nmap_Kd -bm 1 -clamp on green tex.png\n")
    write(tmp_path / "two.obj", "mtllib b.mtl\n" + SQUARE_UV
          + "usemtl r\nf 1/1 2/2 3/3\nusemtl g\nf 1/1 3/3 4/4\n")
    mesh = no_warnings(load_mesh, tmp_path / "two.obj")
    table = mesh.metadata["atlas"]["materials"]
    assert [m["name"] for m in table] == ["r", "g"]
    assert [m["texture"]["source"] for m in table] == [str(tmp_path / "red tex.png"),
                                                       str(tmp_path / "green tex.png")]
    for material, pixels in zip(table, (red, green)):
        x, y, w, h = material["rect"]
        np.testing.assert_array_equal(mesh.texture[y:y + h, x:x + w], pixels)


@pytest.mark.parametrize(("line", "name"), [
    ("map_Kd tex.png", "tex.png"),
    ("map_Kd fuze uv.jpg", "fuze uv.jpg"),
    ("map_Ka -s 1 2 a b c.png", "a b c.png"),
    ("bump -bm 0.3 normal map.png", "normal map.png"),
    ("map_Kd -o 1 -s 2 file.png", "file.png"),   # -o with one value, then -s
    ("map_Kd -s 1 2 3 4.png", "4.png"),          # a file name that starts with a digit
    ("map_Kd -clamp on", ""),                     # options and no file
    ("map_Kd", ""),
])
def test_map_file_names(line, name):
    assert _map_file(line) == name


OPTIONS = st.sampled_from([("-s", 3), ("-o", 1), ("-t", 2), ("-bm", 1), ("-clamp", 1),
                           ("-mm", 2), ("-blendu", 1), ("-texres", 1), ("-imfchan", 1)])
WORD = st.text(st.characters(min_codepoint=33, max_codepoint=126), min_size=1, max_size=8)


@settings(max_examples=200, deadline=None)
@given(options=st.lists(OPTIONS, max_size=4), words=st.lists(WORD, min_size=1, max_size=3),
       gap=st.sampled_from([" ", "  ", "\t"]))
def test_map_file_is_the_rest_of_the_line_after_the_options(options, words, gap):
    """Any options with their values, then any file name of words (not starting with an
    option's name or a number): the file name, its inner spacing kept."""
    first = words[0]
    if first.lower() in ("-s", "-o", "-t", "-bm", "-clamp", "-mm", "-blendu", "-blendv",
                         "-boost", "-cc", "-imfchan", "-texres", "-type"):
        return
    try:
        float(first)
        return
    except ValueError:
        pass
    parts = ["map_Kd"]
    for option, values in options:
        parts.append(option)
        parts += ["0.5"] * values if option not in ("-clamp", "-blendu", "-imfchan") \
            else ["on"]
    name = gap.join(words)
    assert _map_file(" ".join(parts) + " " + name + "  ") == name


@pytest.mark.skipif(not (WILD / "fuze").is_dir(), reason=f"{WILD / 'fuze'} is absent")
def test_fuze_loads_with_its_texture():
    """The real asset: ``map_Kd fuze uv.jpg``."""
    mesh = no_warnings(load_mesh, WILD / "fuze" / "fuze.obj")
    with Image.open(WILD / "fuze" / "fuze uv.jpg") as picture:
        expected = np.asarray(picture.convert("RGB"))
    np.testing.assert_array_equal(mesh.texture, expected)


# == an OBJ with UVs and no mtllib ==========================================================

def test_uvs_and_no_mtllib_warn_of_the_image_with_the_same_stem(tmp_path):
    write(tmp_path / "sq.obj", SQUARE_UV + "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    image(tmp_path / "sq.png", (9, 9, 9))
    image(tmp_path / "other.png", (9, 9, 9))
    with pytest.warns(MeshWarning) as caught:
        mesh = load_mesh(tmp_path / "sq.obj")
    assert mesh.texture is None and mesh.uv is not None
    (message,) = [str(w.message) for w in caught]
    assert message == (
        f"{tmp_path / 'sq.obj'}: has texture coordinates but no material file (no mtllib "
        "line), so it loads untextured; sq.png beside it looks like its texture: give it as "
        f"{tmp_path / 'sq.obj'}::texture={tmp_path / 'sq.png'} (bench simplify: --texture "
        f"{tmp_path / 'sq.png'})")


def test_uvs_and_no_mtllib_warn_of_the_only_image(tmp_path):
    write(tmp_path / "sq.obj", SQUARE_UV + "f 1/1 2/2 3/3\n")
    image(tmp_path / "paint.JPG", (9, 9, 9))
    with pytest.warns(MeshWarning, match=r"paint\.JPG beside it looks like its texture"):
        load_mesh(tmp_path / "sq.obj")


@pytest.mark.parametrize("images", [[], ["a.png", "b.png"]])
def test_no_warning_without_a_likely_texture(tmp_path, images):
    write(tmp_path / "sq.obj", SQUARE_UV + "f 1/1 2/2 3/3\n")
    for name in images:
        image(tmp_path / name, (9, 9, 9))
    assert no_warnings(load_mesh, tmp_path / "sq.obj").texture is None


def test_no_warning_without_uvs(tmp_path):
    write(tmp_path / "sq.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    image(tmp_path / "sq.png", (9, 9, 9))
    assert no_warnings(load_mesh, tmp_path / "sq.obj").uv is None


@pytest.mark.skipif(not (WILD / "spot").is_dir(), reason=f"{WILD / 'spot'} is absent")
def test_spot_warns_and_loads_with_the_texture_given():
    obj, png = WILD / "spot" / "spot_triangulated.obj", WILD / "spot" / "spot_texture.png"
    with pytest.warns(MeshWarning, match=r"spot_texture\.png beside it looks like its texture"):
        assert load_mesh(obj).texture is None
    mesh = no_warnings(resolve_model, f"{obj}::texture={png}")
    with Image.open(png) as picture:
        np.testing.assert_array_equal(mesh.texture, np.asarray(picture.convert("RGB")))
    assert mesh.n_faces == 5856


# == MODEL::texture=IMAGE ===================================================================

@pytest.fixture
def square(tmp_path, monkeypatch):
    """sq.obj with UVs and no mtllib, and t.png (not named like it) in a sub-folder; the
    working directory is tmp_path."""
    monkeypatch.chdir(tmp_path)
    write(tmp_path / "sq.obj", SQUARE_UV + "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    (tmp_path / "img").mkdir()
    return image(tmp_path / "img" / "t.png", (30, 60, 90))


def test_a_model_spec_gives_the_texture(square):
    mesh = no_warnings(resolve_model, "sq.obj::texture=img/t.png")
    np.testing.assert_array_equal(mesh.texture, square)
    assert mesh.metadata["texture"] == "img/t.png"
    assert mesh.name == "sq"
    plain = no_warnings(resolve_model, "sq.obj")
    np.testing.assert_array_equal(mesh.positions, plain.positions)
    np.testing.assert_array_equal(mesh.uv, plain.uv)
    assert mesh.content_hash != plain.content_hash


def test_a_registered_model_takes_a_texture(square):
    torus = resolve_model("torus")
    mesh = resolve_model("torus::texture=img/t.png")
    np.testing.assert_array_equal(mesh.texture, square)
    np.testing.assert_array_equal(mesh.uv, torus.uv)
    assert torus.texture.shape != square.shape  # the cached built-in is untouched


@pytest.mark.parametrize(("spec", "message"), [
    ("sq.obj::", r"^model 'sq\.obj::': options are written MODEL::texture=IMAGE"),
    ("sq.obj::texture", r"options are written MODEL::texture=IMAGE"),
    ("sq.obj::texture=", r"options are written MODEL::texture=IMAGE"),
    ("::texture=img/t.png", r"options are written MODEL::texture=IMAGE"),
    ("sq.obj::colour=red", (r"^model 'sq\.obj::colour=red': unknown option 'colour'; the one "
                           r"option is texture \(MODEL::texture=IMAGE\)$")),
    ("sq.obj::texture=img/t.png::texture=img/t.png", r"texture given twice$"),
    ("sq.obj::texture=t.png", (r"^t\.png: no such texture image \(the texture given for "
                              r"sq\.obj\)$")),
    ("sq.obj::texture=img", r"^img: is a directory, not an image"),
    ("sq.obj::texture=sq.obj", r"^sq\.obj: texture image cannot be read as an image"),
    ("nope.obj::texture=img/t.png", r"^nope\.obj: no such file$"),
    ("bunnny::texture=img/t.png", r"^unknown model 'bunnny'"),
    ("two-materials::texture=img/t.png", (r"^two-materials: has 2 materials, each with its own "
                                         r"texture")),
])
def test_bad_model_specs(square, spec, message):
    with pytest.raises((InputError, UnknownNameError), match=message):
        resolve_model(spec)


def test_a_texture_for_a_mesh_without_uvs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write(tmp_path / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    image(tmp_path / "t.png", (1, 1, 1))
    with pytest.raises(InputError, match=r"^tri\.obj: has no texture coordinates, so the "
                                         r"texture t\.png cannot be applied"):
        resolve_model("tri.obj::texture=t.png")


def test_a_relative_texture_beside_the_mesh_is_hinted(tmp_path, monkeypatch):
    (tmp_path / "far").mkdir()
    write(tmp_path / "far" / "sq.obj", SQUARE_UV + "f 1/1 2/2 3/3\n")
    image(tmp_path / "far" / "t.png", (1, 1, 1))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=r"relative paths are from the current folder: did "
                                         r"you mean far/t\.png\?$"):
        resolve_model("far/sq.obj::texture=t.png")


def test_parse_model_spec():
    assert parse_model_spec("a.obj") == ("a.obj", {})
    assert parse_model_spec("dir/a b.obj::texture=my t.png") == ("dir/a b.obj",
                                                                 {"texture": "my t.png"})


@pytest.fixture
def grid_obj(tmp_path):
    """A 6 x 6 grid of quads (72 triangles) with UVs and no mtllib, and grid.png."""
    n = 7
    xs, ys = np.meshgrid(np.arange(n), np.arange(n))
    lines = [f"v {x} {y} 0" for x, y in zip(xs.ravel(), ys.ravel())]
    lines += [f"vt {x / (n - 1)} {y / (n - 1)}" for x, y in zip(xs.ravel(), ys.ravel())]
    for y in range(n - 1):
        for x in range(n - 1):
            a, b, c, d = (y * n + x + 1, y * n + x + 2, (y + 1) * n + x + 2, (y + 1) * n + x + 1)
            lines += [f"f {a}/{a} {b}/{b} {c}/{c}", f"f {a}/{a} {c}/{c} {d}/{d}"]
    write(tmp_path / "grid.obj", "\n".join(lines) + "\n")
    return tmp_path / "grid.obj", image(tmp_path / "grid.png", (40, 80, 120), size=(8, 8))


def test_simplify_with_texture_writes_it(tmp_path, grid_obj):
    obj, pixels = grid_obj
    out = tmp_path / "out" / "g.obj"
    out.parent.mkdir()
    proc = bench("simplify", obj, out, "-m", "qslim", "-f", "36", "--texture",
                 tmp_path / "grid.png")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    written = load_mesh(out)
    np.testing.assert_array_equal(written.texture, pixels)
    assert written.n_faces < 72


def test_simplify_warns_without_texture_and_refuses_two(tmp_path, grid_obj):
    obj, _ = grid_obj
    proc = bench("simplify", obj, tmp_path / "g.glb", "-m", "qslim", "-f", "36")
    assert proc.returncode == 0
    assert proc.stderr.startswith(f"bench: warning: {obj}: has texture coordinates but no "
                                  "material file"), proc.stderr
    png = tmp_path / "grid.png"
    assert_one_line_error(bench("simplify", f"{obj}::texture={png}", tmp_path / "g.glb", "-m",
                                "qslim", "-f", "36", "--texture", png), "give it once")
    assert_one_line_error(bench("simplify", f"{obj}::texture=nope.png", tmp_path / "g.glb",
                                "-m", "qslim", "-f", "36"),
                          "nope.png: no such texture image")


def test_simplify_never_writes_over_a_given_texture(tmp_path, grid_obj):
    obj, pixels = grid_obj
    proc = bench("simplify", obj, tmp_path / "grid.obj", "-m", "qslim", "-f", "36",
                 "--texture", tmp_path / "grid.png", "--force")
    assert_one_line_error(proc, "is the input's texture")
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "grid.png")), pixels)


@pytest.mark.slow
def test_run_names_the_model_as_given(tmp_path, grid_obj):
    obj, _ = grid_obj
    spec = f"{obj}::texture={tmp_path / 'grid.png'}"
    proc = bench("run", "--models", spec, "--methods", "qslim", "--faces", "36", "--out",
                 tmp_path / "run", "--jobs", "1", "--no-report", timeout=600)
    assert proc.returncode == 0, proc.stderr
    (record,) = [json.loads(p.read_text()) for p in (tmp_path / "run" / "records").glob("*.json")]
    assert record["job"]["model"] == spec and record["status"] == "ok"
    textured = load_mesh(obj, texture_file=tmp_path / "grid.png")
    assert record["model"]["hash"] == textured.content_hash


# == the material a written mesh gets =======================================================

def glb_json(path: Path) -> dict:
    """The JSON chunk of a binary glTF file (read here, not through trimesh)."""
    data = path.read_bytes()
    assert data[:4] == b"glTF"
    length, kind = struct.unpack("<II", data[12:20])
    assert kind == 0x4E4F534A  # "JSON"
    return json.loads(data[20:20 + length])


def mtl_lines(path: Path) -> list[str]:
    return [line.strip() for line in path.read_text().splitlines() if line.strip()]


def textured_square(roughness=None) -> Mesh:
    positions = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=np.float64)
    texture = np.zeros((2, 2, 3), np.uint8)
    texture[0, 0] = 255
    metadata = {} if roughness is None else {"material": {"roughness": roughness}}
    return Mesh(positions, [[0, 1, 2], [0, 2, 3]], uv=positions[:, :2], texture=texture,
                metadata=metadata)


@pytest.mark.parametrize("roughness", [None, 0.25])
def test_a_textured_glb_is_white_not_metallic_with_its_roughness(tmp_path, roughness):
    save_mesh(textured_square(roughness), tmp_path / "s.glb")
    (material,) = glb_json(tmp_path / "s.glb")["materials"]
    pbr = material["pbrMetallicRoughness"]
    assert pbr["baseColorFactor"] == [1.0, 1.0, 1.0, 1.0]
    assert pbr["metallicFactor"] == 0.0  # glTF reads a missing factor as 1: fully metallic
    assert pbr["roughnessFactor"] == (1.0 if roughness is None else 0.25)
    assert "baseColorTexture" in pbr
    assert load_mesh(tmp_path / "s.glb").metadata["material"] == {
        "roughness": 1.0 if roughness is None else 0.25}


@pytest.mark.parametrize(("roughness", "ns"), [(None, "0"), (0.25, "562.5")])
def test_a_textured_mtl_is_white_not_metallic_with_its_roughness(tmp_path, roughness, ns):
    save_mesh(textured_square(roughness), tmp_path / "s.obj")
    lines = mtl_lines(tmp_path / "s.mtl")
    for expected in ("Kd 1.00000000 1.00000000 1.00000000", "Ks 0.00000000 0.00000000 0.00000000",
                     "map_Kd s.png", f"Pr {1 if roughness is None else roughness:g}", "Pm 0"):
        assert expected in lines
    assert float(next(x for x in lines if x.startswith("Ns ")).split()[1]) == float(ns)
    back = load_mesh(tmp_path / "s.obj")
    assert back.metadata["material"] == {"roughness": 1.0 if roughness is None else roughness}


@pytest.mark.parametrize(("mtl", "roughness"), [
    ("Ns 0", 1.0), ("Ns 1000", 0.0), ("Ns 250", 0.5), ("Ns 250\nPr 0.125", 0.125),
    ("Ns 5000", 0.0), ("", None)])
def test_the_input_roughness_is_read(tmp_path, mtl, roughness):
    image(tmp_path / "t.png", (5, 5, 5))
    write(tmp_path / "a.mtl", f"newmtl m\nKd 1 1 1\n{mtl}\nmap_Kd t.png\n")
    write(tmp_path / "sq.obj", "mtllib a.mtl\n" + SQUARE_UV + "usemtl m\nf 1/1 2/2 3/3\n")
    mesh = no_warnings(load_mesh, tmp_path / "sq.obj")
    assert mesh.metadata.get("material") == (None if roughness is None
                                             else {"roughness": roughness})


def test_simplify_writes_the_input_roughness(tmp_path, grid_obj):
    obj, _ = grid_obj
    write(obj.parent / "grid.mtl", "newmtl m\nNs 90\nPr 0.375\nmap_Kd grid.png\n")
    obj.write_text("mtllib grid.mtl\nusemtl m\n" + obj.read_text())
    proc = bench("simplify", obj, tmp_path / "g.glb", "-m", "qslim", "-f", "36")
    assert proc.returncode == 0, proc.stderr
    (material,) = glb_json(tmp_path / "g.glb")["materials"]
    assert material["pbrMetallicRoughness"]["roughnessFactor"] == 0.375
    assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0


def test_lod_chains_and_several_materials_are_not_metallic(tmp_path):
    mesh = textured_square()
    save_lods([("LOD0", mesh), ("LOD1", mesh.replace(faces=mesh.faces[:1]))],
              tmp_path / "c.glb")
    (material,) = glb_json(tmp_path / "c.glb")["materials"]
    assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0
    assert material["pbrMetallicRoughness"]["baseColorFactor"] == [1.0, 1.0, 1.0, 1.0]
    save_mesh(resolve_model("two-materials"), tmp_path / "two.glb")
    materials = glb_json(tmp_path / "two.glb")["materials"]
    assert len(materials) == 2
    for material in materials:
        assert material["pbrMetallicRoughness"]["metallicFactor"] == 0.0
        assert material["pbrMetallicRoughness"]["roughnessFactor"] == 1.0


def test_a_textured_material_without_kd_is_written_white(tmp_path):
    """An MTL material with a texture and no Kd: recorded white, not trimesh's 0.4 grey
    default, so the OBJ written back says Kd 1 1 1."""
    image(tmp_path / "r.png", (200, 0, 0))
    image(tmp_path / "g.png", (0, 200, 0))
    write(tmp_path / "b.mtl", "newmtl r\nmap_Kd r.png\nnewmtl g\nKd 0.5 0.5 0.5\nmap_Kd g.png\n")
    write(tmp_path / "two.obj", "mtllib b.mtl\n" + SQUARE_UV
          + "usemtl r\nf 1/1 2/2 3/3\nusemtl g\nf 1/1 3/3 4/4\n")
    mesh = no_warnings(load_mesh, tmp_path / "two.obj")
    assert [m["color"] for m in mesh.metadata["atlas"]["materials"]] == [
        [255, 255, 255, 255], [128, 128, 128, 255]]
    (tmp_path / "out").mkdir()
    save_mesh(mesh, tmp_path / "out" / "two.obj")
    lines = mtl_lines(tmp_path / "out" / "two.mtl")
    assert lines[:2] == ["newmtl r", "Kd 1 1 1"]


# == round trip under the protocol ==========================================================

@pytest.mark.slow
@pytest.mark.parametrize("model", [
    "bunny-textured", "two-materials",
    pytest.param(str(WILD / "fuze" / "fuze.obj"), id="fuze", marks=pytest.mark.skipif(
        not (WILD / "fuze").is_dir(), reason=f"{WILD / 'fuze'} is absent"))])
@pytest.mark.parametrize("ext", [".obj", ".glb"])
@pytest.mark.parametrize("stem", ["rt", "my lod"])
def test_an_unchanged_mesh_written_and_read_back_renders_the_same(tmp_path, model, ext, stem):
    """The protocol's 24 views of the mesh and of the file written and read back (with a
    space in the file's name, its material file and textures have one too)."""
    from metrics.image import d_rms
    from metrics.protocol import Protocol, render_views

    mesh = resolve_model(model)
    save_mesh(mesh, tmp_path / f"{stem}{ext}")
    back = no_warnings(load_mesh, tmp_path / f"{stem}{ext}")
    assert back.n_faces == mesh.n_faces and back.texture is not None
    protocol = Protocol()
    d, _ = d_rms(render_views(mesh, mesh, protocol), render_views(back, mesh, protocol))
    assert d < 0.5
