"""The cache of meshes read from files (bench.io.cache): a read from it gives the mesh
the file gives, with the same warnings; any change to a file the mesh came from, or to
one it named and did not find, reads the file again; a damaged entry or an unwritable
folder is no error."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from PIL import Image

from bench.core.errors import InputError, MeshWarning
from bench.io import cache, meshio
from bench.io.meshio import input_files, load_mesh
from conftest import write

SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
FACES = "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"


@pytest.fixture
def cached(tmp_path, monkeypatch):
    """The cache on, in a folder of its own; the reads that did not come from it. Files
    count as settled once written (the racy-file rule has its own test)."""
    monkeypatch.setenv("BENCH_MESH_CACHE", "1")
    monkeypatch.setenv("BENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "RACY_SECONDS", 0.0)
    (tmp_path / "cache").mkdir()  # the cache's entries do not change tmp_path itself
    reads = []
    read = meshio._read_mesh

    def counted(*args):
        reads.append(args[0])
        return read(*args)

    monkeypatch.setattr(meshio, "_read_mesh", counted)
    return reads


def new_process():
    """Forget what this process remembers of files read (as a new process would)."""
    cache._NAMED.clear()
    meshio._LAST_OBJ_SCAN[:] = [None, None]


def textured(folder, rgb=(200, 10, 10)):
    pixels = np.full((2, 4, 3), rgb, np.uint8)
    Image.fromarray(pixels).save(folder / "t.png")
    write(folder / "m.mtl", "newmtl m\nmap_Kd t.png\n")
    return write(folder / "sq.obj", "mtllib m.mtl\n" + SQUARE + "usemtl m\n" + FACES)


def same_mesh(a, b):
    for attr in ("positions", "faces", "uv", "normals", "colors", "texture"):
        x, y = getattr(a, attr), getattr(b, attr)
        assert (x is None) == (y is None), attr
        if x is not None:
            assert x.dtype == y.dtype and x.flags.c_contiguous == y.flags.c_contiguous, attr
            np.testing.assert_array_equal(x, y, err_msg=attr)
    assert (a.name, a.metadata) == (b.name, b.metadata)


def test_a_second_read_comes_from_the_cache_and_equals_the_file(tmp_path, cached,
                                                                monkeypatch):
    obj = textured(tmp_path)
    first = load_mesh(obj)
    second = load_mesh(obj)
    assert len(cached) == 1
    same_mesh(second, first)
    from_entry = input_files(obj)
    monkeypatch.setenv("BENCH_MESH_CACHE", "0")  # the oracle: the file read afresh
    same_mesh(second, load_mesh(obj))
    new_process()
    assert from_entry == input_files(obj) == [(obj, "mesh"), (tmp_path / "m.mtl", "material"),
                                              (tmp_path / "t.png", "texture")]


def test_a_changed_texture_reads_the_file_again(tmp_path, cached):
    obj = textured(tmp_path)
    load_mesh(obj)
    Image.fromarray(np.full((2, 4, 3), (0, 0, 255), np.uint8)).save(tmp_path / "t.png")
    mesh = load_mesh(obj)
    assert len(cached) == 2
    assert tuple(mesh.texture[0, 0][:3]) == (0, 0, 255)


def test_a_material_file_that_appears_reads_the_file_again(tmp_path, cached):
    obj = write(tmp_path / "sq.obj", "mtllib m.mtl\n" + SQUARE + "usemtl m\n" + FACES)
    with pytest.warns(MeshWarning, match="m.mtl"):
        assert load_mesh(obj).texture is None
    Image.fromarray(np.full((2, 4, 3), 7, np.uint8)).save(tmp_path / "t.png")
    write(tmp_path / "m.mtl", "newmtl m\nmap_Kd t.png\n")  # the OBJ itself unchanged
    assert load_mesh(obj).texture is not None
    new_process()
    assert load_mesh(obj).texture is not None  # from the entry that read stored
    assert len(cached) == 2


def test_a_read_from_the_cache_gives_the_same_warnings(tmp_path, cached):
    obj = write(tmp_path / "quad.obj", SQUARE + "f 1/1 2/2 3/3 4/4\n")
    messages = []
    for _ in range(2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            load_mesh(obj)
        messages.append([(str(w.message), w.filename, w.lineno) for w in caught
                         if w.category is MeshWarning])
    assert len(cached) == 1
    assert messages[0] and messages[0] == messages[1]
    with pytest.raises(MeshWarning), warnings.catch_warnings():
        warnings.simplefilter("error")  # the filters in force decide, as for a read
        load_mesh(obj)
    with warnings.catch_warnings(record=True) as caught:  # a module's filter applies
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=MeshWarning, module="bench.io.meshio")
        load_mesh(obj)
    assert not [w for w in caught if w.category is MeshWarning]


def test_warnings_before_an_error_are_given(tmp_path, cached):
    obj = write(tmp_path / "bad.obj", SQUARE.replace("vt 1 1", "vt 1e30 1")
                + "f 1/1 2/2 3/3 4/4\n")
    with pytest.warns(MeshWarning, match="triangulated"), pytest.raises(InputError):
        load_mesh(obj)


def test_names_textures_and_images_beside_an_obj_without_materials_count(tmp_path, cached):
    obj = write(tmp_path / "sq.obj", SQUARE + FACES)
    assert load_mesh(obj).name == "sq"
    assert load_mesh(obj, "other").name == "other"
    Image.fromarray(np.full((2, 2, 3), 9, np.uint8)).save(tmp_path / "u.png")
    for _ in range(2):  # read again (a new image beside it), then from the cache
        with pytest.warns(MeshWarning, match="u.png beside it looks like its texture"):
            assert load_mesh(obj).texture is None
    assert load_mesh(obj, texture_file=tmp_path / "u.png").texture is not None
    assert len(cached) == 4


def test_a_file_modified_just_before_its_reading_is_not_cached(tmp_path, cached,
                                                               monkeypatch):
    monkeypatch.setattr(cache, "RACY_SECONDS", 2.0)
    obj = textured(tmp_path)
    load_mesh(obj)
    load_mesh(obj)
    assert len(cached) == 2 and not list((tmp_path / "cache").rglob("*.pickle"))


def test_a_damaged_entry_or_an_unwritable_folder_is_no_error(tmp_path, cached, monkeypatch):
    obj = textured(tmp_path)
    load_mesh(obj)
    (entry,) = (tmp_path / "cache" / "meshes").glob("*.pickle")
    entry.write_bytes(b"not a pickle")
    same_mesh(load_mesh(obj), load_mesh(obj))
    assert len(cached) == 2
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder would be")
    monkeypatch.setenv("BENCH_CACHE", str(blocked))
    load_mesh(obj)
    load_mesh(obj)
    assert len(cached) == 4


def test_off_writes_nothing(tmp_path, cached, monkeypatch):
    monkeypatch.setenv("BENCH_MESH_CACHE", "0")
    obj = textured(tmp_path)
    load_mesh(obj)
    load_mesh(obj)
    assert len(cached) == 2 and not (tmp_path / "cache" / "meshes").exists()


def test_the_least_recently_used_entries_go_over_the_budget(tmp_path, cached, monkeypatch):
    files = [write(tmp_path / f"m{i}.obj", SQUARE + FACES) for i in range(3)]
    load_mesh(files[0])
    (first,) = (tmp_path / "cache" / "meshes").glob("*.pickle")
    monkeypatch.setattr(cache, "BUDGET_BYTES", 2 * first.stat().st_size + 1)
    os.utime(first, ns=(1, 1))  # long unused
    load_mesh(files[1])
    load_mesh(files[2])
    entries = sorted((tmp_path / "cache" / "meshes").glob("*.pickle"))
    assert len(entries) == 2 and first not in entries
