"""Loading the files users have: texture and material file names with spaces, and
texture options, in an MTL."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from bench.io.meshio import _map_file, input_files, load_mesh
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
