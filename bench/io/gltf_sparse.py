"""glTF sparse accessors, applied before trimesh reads the file.

A glTF accessor may carry a ``sparse`` part: ``count`` element indices and as many
values that replace the elements of its base data (its ``bufferView``, or zeros when it
has none). Exporters use it for a morph target's few moved vertices and for a vertex
edit stored over a shared base mesh. trimesh 4 and 5 read the base data only, so the
edit would be lost without a word; here the accessor is made dense (base data with the
values put in) in a buffer of its own, and the file is handed to trimesh as glTF JSON
with the sparse parts gone. A file without sparse accessors is left alone. Anything the
sparse part points at that is not there (an index beyond the accessor, a view beyond
its buffer, a buffer file that is not a regular file) is an :class:`InputError`.

Reference: the glTF 2.0 specification, section 3.6.2.3 "Sparse Accessors".
"""

from __future__ import annotations

import base64
import json
import os
import stat
import struct
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from bench.core.errors import InputError

__all__ = ["dense_gltf"]

#: glTF componentType -> little-endian NumPy dtype (section 3.6.2.2)
_COMPONENTS = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
#: glTF accessor type -> components per element
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_GLB_MAGIC, _JSON_CHUNK, _BIN_CHUNK = b"glTF", 0x4E4F534A, 0x004E4942


def dense_gltf(path: Path) -> str | None:
    """The glTF (``.gltf``) or GLB (``.glb``) file ``path`` as glTF JSON with every sparse
    accessor made dense, or None when it has none (or is not glTF JSON: left to
    trimesh, whose error names the problem)."""
    data = Path(path).read_bytes()
    tree, binary = _split_glb(data) if data[:4] == _GLB_MAGIC else (_json(data), None)
    if not isinstance(tree, dict):
        return None
    accessors = tree.get("accessors")
    if not isinstance(accessors, list) or not any(
            isinstance(a, dict) and "sparse" in a for a in accessors):
        return None
    buffers = _Buffers(tree, binary, Path(path))
    try:
        for i, accessor in enumerate(accessors):
            if isinstance(accessor, dict) and "sparse" in accessor:
                _make_dense(tree, buffers, i, accessor)
    except InputError:
        raise
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(f"{path}: accessor {i}: malformed sparse accessor "
                         f"({type(exc).__name__}: {exc}); the file is corrupt") from None
    if binary is not None:  # the GLB's own buffer, as glTF JSON holds it
        tree["buffers"][0]["uri"] = _data_uri(binary)
    return json.dumps(tree)


def _json(data: bytes):
    try:
        return json.loads(data)
    except (ValueError, RecursionError):
        return None


def _split_glb(data: bytes) -> tuple:
    """(JSON tree, BIN chunk or None) of a GLB file; (None, None) when malformed."""
    at, tree, binary = 12, None, None
    while at + 8 <= len(data):
        length, kind = struct.unpack_from("<II", data, at)
        chunk = data[at + 8:at + 8 + length]
        if kind == _JSON_CHUNK and tree is None:
            tree = _json(chunk)
        elif kind == _BIN_CHUNK and binary is None:
            binary = chunk
        at += 8 + length + (-length % 4)
    return tree, binary


def _data_uri(blob: bytes) -> str:
    return "data:application/octet-stream;base64," + base64.b64encode(blob).decode("ascii")


class _Buffers:
    """The bytes of a glTF's buffers, read on first use: a data URI, a file beside the
    glTF (a regular file only: a named pipe would block the read), or a GLB's BIN chunk."""

    def __init__(self, tree: dict, binary: bytes | None, path: Path):
        self.tree, self.binary, self.path, self.cache = tree, binary, path, {}

    def __getitem__(self, index: int) -> bytes:
        if index not in self.cache:
            self.cache[index] = self._read(index)
        return self.cache[index]

    def _read(self, index: int) -> bytes:
        uri = self.tree["buffers"][index].get("uri")
        if uri is None:
            if index != 0 or self.binary is None:
                raise InputError(f"{self.path}: buffer {index} has no data; the file is "
                                 "corrupt")
            return self.binary
        if uri.startswith("data:"):
            return base64.b64decode(uri.split(",", 1)[1])
        where = self.path.parent / unquote(uri)
        try:
            if not stat.S_ISREG(os.stat(where).st_mode):
                raise InputError(f"{self.path}: buffer {uri!r} is not a regular file; give "
                                 "the glTF's .bin file")
            return where.read_bytes()
        except OSError as exc:
            raise InputError(f"{self.path}: buffer {uri!r} cannot be read "
                             f"({exc.strerror or exc})") from None


def _elements(tree: dict, buffers: _Buffers, view_index: int, offset: int, count: int,
              dtype: np.dtype, width: int, what: str, path: Path) -> np.ndarray:
    """``count`` elements of ``width`` components of ``dtype`` from a buffer view."""
    view = tree["bufferViews"][view_index]
    data = buffers[view["buffer"]]
    size = dtype.itemsize * width
    stride = view.get("byteStride") or size
    start = view.get("byteOffset", 0) + offset
    end = start + stride * (count - 1) + size if count else start
    if end > view.get("byteOffset", 0) + view["byteLength"] or end > len(data):
        raise InputError(f"{path}: {what} reaches beyond its buffer view; the file is "
                         "corrupt or truncated")
    return np.ndarray((count, width), dtype, buffer=data, offset=start,
                      strides=(stride, dtype.itemsize)).copy()


def _make_dense(tree: dict, buffers: _Buffers, index: int, accessor: dict) -> None:
    """Replace accessor ``index``'s sparse part by a dense copy of its data in a buffer
    of its own (appended to ``tree``)."""
    path = buffers.path
    dtype = np.dtype(_COMPONENTS[accessor["componentType"]])
    width, count = _WIDTHS[accessor["type"]], int(accessor["count"])
    if "bufferView" in accessor:
        values = _elements(tree, buffers, accessor["bufferView"], accessor.get("byteOffset", 0),
                           count, dtype, width, f"accessor {index}", path)
    else:  # no base data: zeros (section 3.6.2.3)
        values = np.zeros((count, width), dtype)
    sparse = accessor.pop("sparse")
    n = int(sparse["count"])
    where, new = sparse["indices"], sparse["values"]
    ids = _elements(tree, buffers, where["bufferView"], where.get("byteOffset", 0), n,
                    np.dtype(_COMPONENTS[where["componentType"]]), 1,
                    f"accessor {index}'s sparse indices", path)[:, 0].astype(np.int64)
    if n and (ids.min() < 0 or ids.max() >= count):
        raise InputError(f"{path}: accessor {index}: sparse index {int(ids.max())} is out of "
                         f"range (the accessor has {count} elements); the file is corrupt")
    values[ids] = _elements(tree, buffers, new["bufferView"], new.get("byteOffset", 0), n,
                            dtype, width, f"accessor {index}'s sparse values", path)
    blob = values.astype(dtype).tobytes()
    tree["buffers"].append({"byteLength": len(blob), "uri": _data_uri(blob)})
    tree["bufferViews"].append({"buffer": len(tree["buffers"]) - 1, "byteOffset": 0,
                                "byteLength": len(blob)})
    accessor["bufferView"] = len(tree["bufferViews"]) - 1
    accessor["byteOffset"] = 0
