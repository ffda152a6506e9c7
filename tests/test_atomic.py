"""bench.io.atomic.write_atomic, the package's one way of writing a file: a reader sees the
old file or the new one, a new file gets the umask's mode, a replaced file keeps its own,
and a failed write leaves the old file and no temporary file behind."""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

from bench.io.atomic import write_atomic

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def umask():
    """Set a umask for the test and restore the old one after it."""
    old = os.umask(0o022)
    os.umask(old)
    yield os.umask
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600),
                                        (0o002, 0o664)])
def test_a_new_file_gets_the_umask_mode(tmp_path, umask, mask, mode):
    umask(mask)
    path = write_atomic(tmp_path / "new.txt", "x")
    assert path == tmp_path / "new.txt"
    assert path.stat().st_mode & 0o777 == mode


def test_a_replaced_file_keeps_its_mode_and_gets_the_new_data(tmp_path, umask):
    umask(0o022)
    path = tmp_path / "old.bin"
    path.write_bytes(b"old")
    os.chmod(path, 0o604)
    write_atomic(path, b"new \x00 bytes")
    assert path.read_bytes() == b"new \x00 bytes"
    assert path.stat().st_mode & 0o777 == 0o604


def test_text_is_written_as_utf8(tmp_path):
    path = write_atomic(tmp_path / "t.txt", "d\u00e9j\u00e0 \u2713")
    assert path.read_bytes() == "d\u00e9j\u00e0 \u2713".encode()


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "kept.txt"
    path.write_text("old")
    with pytest.raises(TypeError):
        write_atomic(path, 12345)  # neither text nor bytes: fails after the temporary exists
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.txt"]


def test_an_unwritable_folder_is_an_oserror(tmp_path):
    with pytest.raises(OSError):
        write_atomic(tmp_path / "no such folder" / "f.txt", "x")
    assert list(tmp_path.iterdir()) == []


def test_no_other_module_renames_files_into_place():
    """One writer: nothing in the package but bench/io/atomic.py calls os.replace or
    os.rename (a second hand-made writer is how the two drifted apart before)."""
    callers = []
    for package in ("bench", "methods", "metrics"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path == ROOT / "bench" / "io" / "atomic.py":
                continue
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if (isinstance(node, ast.Attribute) and node.attr in ("replace", "rename")
                        and isinstance(node.value, ast.Name) and node.value.id == "os"):
                    callers.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert callers == []
