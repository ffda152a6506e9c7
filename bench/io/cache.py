"""Meshes read from files, kept on disk: reading an unchanged file again costs one
unpickling, not a parse, a validation and (for most formats) trimesh's import.

An entry is found by what was asked for: the path as given and as an absolute path, the
mesh's name, the texture file given with it, and a fingerprint of the code that reads
files (the sources of :mod:`bench.io` and :mod:`bench.core.mesh`, and the installed
versions of trimesh, numpy and Pillow). It holds the mesh, the
:class:`~bench.core.errors.MeshWarning` s its reading gave (given again at every read
from the cache, so no warning is lost), and the identity (inode, size, modification and
change times) of every file the mesh was read from: the file, an OBJ's material files and
the images they name, a glTF's buffers and images, the texture given with it, and the
files it names that were missing (a file that appears changes the mesh too). An entry is
used only while all of them are unchanged.

The cache never turns a read into an error: a damaged or unreadable entry, an entry of
another version, or a folder that cannot be written means the file is read as if there
were no cache. Where: ``$BENCH_CACHE/meshes`` (``~/.cache/bench/meshes`` by default,
beside the originals' images); ``BENCH_MESH_CACHE=0`` turns it off. Entries over
:data:`BUDGET_BYTES` in all are removed, the least recently used first.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import warnings
from collections.abc import Callable
from pathlib import Path

from bench.core.errors import MeshWarning
from bench.core.mesh import Mesh
from bench.io.atomic import write_atomic

__all__ = ["BUDGET_BYTES", "cache_dir", "cached_read", "named_files"]

#: The most the mesh entries may take on disk together.
BUDGET_BYTES = 2 * 1024**3
#: Bumped when an entry's layout changes.
_LAYOUT = 2
_FINGERPRINT: list = []
#: path -> the (path, kind) files of the entry last read for it (see named_files)
_NAMED: dict = {}


def cache_dir() -> Path:
    """The suite's cache folder: ``$BENCH_CACHE``, or ``~/.cache/bench``."""
    root = os.environ.get("BENCH_CACHE") or Path.home() / ".cache" / "bench"
    return Path(root)


def cached_read(path: Path, name: str | None, texture_file, read: Callable[[], Mesh],
                named_files: Callable[[], list]) -> Mesh:
    """``read()``'s mesh, from the cache when its entry is still valid, else read and
    stored. ``named_files()``, called after a read, gives ``(path, kind)`` for each file
    the mesh was read from or looked for (see the module docstring)."""
    if os.environ.get("BENCH_MESH_CACHE", "1") == "0":
        return read()
    entry = _entry_path(path, name, texture_file)
    found = _lookup(entry)
    if found is not None:
        mesh, messages, files = found
        for message, filename, lineno in messages:
            warnings.warn_explicit(message, MeshWarning, filename, lineno)
        _NAMED[str(path)] = files
        return mesh
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = read()
    messages = []
    for w in caught:  # given again as they came, whatever the filters say
        if issubclass(w.category, MeshWarning):
            messages.append((str(w.message), w.filename, w.lineno))
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    files = [*named_files(), *([(Path(texture_file), "given")] if texture_file else [])]
    _store(entry, {"layout": _LAYOUT, "mesh": mesh, "warnings": messages,
                   "files": [(str(f), kind, _identity(f)) for f, kind in files]})
    return mesh


def named_files(path: Path) -> list | None:
    """The ``(path, kind)`` files of the entry this process last read ``path`` from (see
    ``cached_read``), if they are all as they were; else None."""
    files = _NAMED.get(str(path))
    if files is None or any(_identity(Path(f)) != identity for f, _, identity in files):
        return None
    return [(Path(f), kind) for f, kind, _ in files if kind != "given"]


def _identity(path: Path):
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


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
            digest.update(repr((package, origin, origin and _identity(Path(origin))[2:4]))
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
    """``(mesh, warnings, files)`` of a valid entry, else None."""
    try:
        with open(entry, "rb") as f:
            data = pickle.load(f)
        if data["layout"] != _LAYOUT:
            return None
        if any(_identity(Path(name)) != identity for name, _, identity in data["files"]):
            return None
        mesh, messages, files = data["mesh"], data["warnings"], data["files"]
    except Exception:  # noqa: BLE001 - missing or damaged: read the file
        return None
    try:
        os.utime(entry)  # recently used
    except OSError:
        pass
    return mesh, messages, files


def _store(entry: Path, data: dict) -> None:
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(entry, pickle.dumps(data, protocol=pickle.HIGHEST_PROTOCOL))
        _prune(entry.parent)
    except OSError:
        pass  # no cache, no harm


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
