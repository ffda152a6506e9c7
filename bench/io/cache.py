"""Meshes read from files, kept on disk: reading an unchanged file again costs one
unpickling, not a parse, a validation and (for most formats) trimesh's import.

An entry is found by what was asked for: the path as given and as an absolute path, the
mesh's name, the texture file given with it, and a fingerprint of the code that reads
files (the sources of :mod:`bench.io` and :mod:`bench.core.mesh`, and the files of the
installed trimesh, numpy and Pillow: their ``__init__.py``'s path, size and time). It
holds the mesh, the :class:`~bench.core.errors.MeshWarning` s its reading gave (given
again at every read from the cache, as from the same place), and the identity (device,
inode, size, modification and change times) of every file the mesh was read from or
looked for: the file, an OBJ's material files and the images they name, a glTF's
buffers and images, the texture given with it, those it names that were missing, and
the file's folder when one was missing (trimesh then looks for the bare name there) or
an image beside it can decide a warning. An entry is used only while all of them are
unchanged. A file modified less than :data:`RACY_SECONDS` before its reading began is
not cached (a file system with coarse times could hide a second change, as git's racy
files).

The cache never turns a read into an error: a damaged or unreadable entry, an entry of
another version, a folder that cannot be written or anything else going wrong in it
means the file is read as if there were no cache. Where: ``$BENCH_CACHE/meshes``
(``~/.cache/bench/meshes`` by default, beside the originals' images);
``BENCH_MESH_CACHE=0`` turns it off. Entries over :data:`BUDGET_BYTES` in all are
removed, the least recently used first.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import time
from collections.abc import Callable
from pathlib import Path

from bench.core.mesh import Mesh
from bench.io.atomic import write_atomic
from bench.io.validate import recorded_warnings, warn_again

__all__ = ["BUDGET_BYTES", "RACY_SECONDS", "cache_dir", "cached_read", "file_identity",
           "named_files"]

#: The most the mesh entries may take on disk together.
BUDGET_BYTES = 2 * 1024**3
#: A file modified this recently before its reading began is not cached.
RACY_SECONDS = 2.0
#: Bumped when an entry's layout changes.
_LAYOUT = 3
_FINGERPRINT: list = []
#: path -> the (path, kind, identity) files of the entry last read for it (named_files)
_NAMED: dict = {}


def cache_dir() -> Path:
    """The suite's cache folder: ``$BENCH_CACHE``, or ``~/.cache/bench``."""
    root = os.environ.get("BENCH_CACHE") or Path.home() / ".cache" / "bench"
    return Path(root)


def cached_read(path: Path, name: str | None, texture_file, read: Callable[[], Mesh],
                sources: Callable[[], list]) -> Mesh:
    """``read()``'s mesh, from the cache when its entry is still valid, else read and
    stored. ``sources()``, called after a read, gives ``(path, kind)`` for each file
    the mesh was read from or looked for (see the module docstring)."""
    if os.environ.get("BENCH_MESH_CACHE", "1") == "0":
        return read()
    try:
        entry = _entry_path(path, name, texture_file)
        found = _lookup(entry)
    except Exception:  # noqa: BLE001 - the cache never fails a read
        entry = found = None
    if found is not None:
        mesh, messages, files = found
        _NAMED[str(path)] = files
        for message in messages:
            warn_again(*message)
        return mesh
    began = time.time_ns()
    with recorded_warnings() as messages:  # given as they come, and noted
        mesh = read()
    if entry is not None:
        try:
            given = [(Path(texture_file), "given")] if texture_file else []
            files = [(str(f), kind, file_identity(f)) for f, kind in [*sources(), *given]]
            if not _racy(files, began):
                _store(entry, {"layout": _LAYOUT, "files": files}, (mesh, messages))
        except Exception:  # noqa: BLE001, S110 - no cache, no harm
            pass
    return mesh


def named_files(path: Path) -> list | None:
    """The ``(path, kind)`` files of the entry this process last read ``path`` from (see
    :func:`cached_read`), if they are all as they were; else None."""
    files = _NAMED.get(str(path))
    if files is None or any(file_identity(Path(f)) != identity for f, _, identity in files):
        return None
    return [(Path(f), kind) for f, kind, _ in files if kind != "given"]


def file_identity(path: Path):
    """(device, inode, size, modification and change times in ns) of ``path``, None
    when it does not exist (or cannot be examined)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def _racy(files: list, began: int) -> bool:
    """Whether a file was modified less than RACY_SECONDS before ``began`` (or after
    it)."""
    limit = began - int(RACY_SECONDS * 1e9)
    return any(identity is not None and identity[3] >= limit for _, _, identity in files)


def _fingerprint() -> str:
    """The code that reads files, as a digest, computed once per process: the sources of
    this package and of the mesh, and the installed trimesh, numpy and Pillow (each as
    its ``__init__.py``'s path, size and modification time: a reinstall changes them)."""
    if not _FINGERPRINT:
        import importlib.util

        digest = hashlib.blake2b(digest_size=16)
        here = Path(__file__).resolve().parent
        for source in sorted(here.glob("*.py")) + [here.parent / "core" / "mesh.py"]:
            digest.update(source.name.encode() + b"\0" + source.read_bytes())
        for package in ("trimesh", "numpy", "PIL"):
            spec = importlib.util.find_spec(package)
            origin = None if spec is None else spec.origin
            digest.update(repr((package, origin, origin and file_identity(Path(origin))))
                          .encode())
        _FINGERPRINT.append(digest.hexdigest())
    return _FINGERPRINT[0]


def _entry_path(path: Path, name, texture_file) -> Path:
    asked = repr((_LAYOUT, str(path), os.path.abspath(path), name,
                  None if texture_file is None else
                  (str(texture_file), os.path.abspath(texture_file)), _fingerprint()))
    key = hashlib.blake2b(asked.encode(), digest_size=16).hexdigest()
    return cache_dir() / "meshes" / f"{key}.pickle"


def _lookup(entry: Path):
    """``(mesh, warnings, files)`` of a valid entry, else None. An entry is two pickles:
    its header (layout and files), checked before the mesh is read, then the mesh and
    its warnings."""
    try:
        with open(entry, "rb") as f:
            header = pickle.load(f)
            if header["layout"] != _LAYOUT or any(
                    file_identity(Path(name)) != identity for name, _, identity in header["files"]):
                return None
            mesh, messages = pickle.load(f)
    except Exception:  # noqa: BLE001 - missing or damaged: read the file
        return None
    try:
        os.utime(entry)  # recently used
    except OSError:
        pass
    return mesh, messages, header["files"]


def _store(entry: Path, header: dict, payload: tuple) -> None:
    entry.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(entry, pickle.dumps(header, protocol=pickle.HIGHEST_PROTOCOL)
                 + pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL))
    _prune(entry.parent)


def _prune(folder: Path) -> None:
    """Remove the least recently used entries while they take over the budget."""
    entries = []
    for item in folder.glob("*.pickle"):
        try:
            st = item.stat()
        except OSError:
            continue
        entries.append((st.st_mtime_ns, st.st_size, item))
    total = sum(size for _, size, _ in entries)
    for _, size, item in sorted(entries):
        if total <= BUDGET_BYTES:
            break
        item.unlink(missing_ok=True)
        total -= size
