"""A Multi-Triangulation and its node bounds, built once per (model, parameters).

Building the MT (the engine's whole collapse sequence) and its bounds costs far more
than a cut, and neither depends on the budget or on the ``error`` variant, so a run
that asks ``perceptual-mt`` for several budgets and errors of one model builds them
once: in memory for the jobs a worker runs back to back, and on disk (one ``.npz``
per key in the run's cache directory) for the other workers and for ``--resume``.

The key is the model's content hash, the MT's parameters and the method's version: a
change that alters the MT or its bounds bumps the version, which makes a new key. The
run's directory is the cache's home, so a fresh run always builds afresh.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import os
import time
from pathlib import Path

import numpy as np

from bench.core.mesh import Mesh
from bench.io.atomic import write_atomic
from bench.io.jsonable import json_default
from methods.mt.bounds import NodeBounds, preprocess
from methods.mt.dag import MultiTriangulation, build_mt

__all__ = ["mt_and_bounds"]

#: The last (key, MT, bounds) a process built or loaded: consecutive jobs of one model.
_LAST: list = []


def mt_and_bounds(mesh: Mesh, texture_weight: float, version: str,
                  cache_dir: str | os.PathLike | None = None):
    """``(mt, bounds, source, seconds)`` for ``mesh``: ``source`` says where they came
    from (``"built"``, ``"memory"`` or ``"disk"``); ``seconds`` is the time to build
    the MT (0 when it was not built here)."""
    key = hashlib.sha256(json.dumps([mesh.content_hash, float(texture_weight), version])
                         .encode()).hexdigest()[:20]
    if _LAST and _LAST[0] == key:
        return _LAST[1], _LAST[2], "memory", 0.0
    path = Path(cache_dir) / f"mt-{key}.npz" if cache_dir else None
    found = _load(path, mesh) if path is not None and path.exists() else None
    if found is not None:
        mt, bounds = found
        source, seconds = "disk", 0.0
    else:
        t = time.perf_counter()
        mt = build_mt(mesh, texture_weight=texture_weight)
        seconds = time.perf_counter() - t
        bounds = preprocess(mt)
        source = "built"
        if path is not None:
            _save(path, mt, bounds)
    _LAST[:] = [key, mt, bounds]
    return mt, bounds, source, seconds


def _save(path: Path, mt: MultiTriangulation, bounds: NodeBounds) -> None:
    """Write both as one ``.npz``: arrays as arrays, the rest as JSON; the texture is
    the mesh's and is not stored. Written by :func:`bench.io.atomic.write_atomic`, so a
    reader in another worker never sees half a file."""
    arrays, meta = {}, {}
    for prefix, obj in (("mt", mt), ("bounds", bounds)):
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if f.name == "texture":
                continue
            if isinstance(value, np.ndarray):
                arrays[f"{prefix}.{f.name}"] = value
            else:
                meta[f"{prefix}.{f.name}"] = value
    path.parent.mkdir(parents=True, exist_ok=True)
    buffer = io.BytesIO()
    np.savez(buffer, __meta__=np.array(json.dumps(meta, default=json_default)), **arrays)
    write_atomic(path, buffer.getvalue())


def _load(path: Path, mesh: Mesh):
    """The (mt, bounds) stored at ``path``, or None when it cannot be read (it is
    then rebuilt and overwritten)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["__meta__"]))
            values = {**meta, **{k: data[k] for k in data.files if k != "__meta__"}}
    except (OSError, ValueError, KeyError):
        return None
    parts = {}
    for prefix, cls in (("mt", MultiTriangulation), ("bounds", NodeBounds)):
        kwargs = {f.name: values[f"{prefix}.{f.name}"] for f in dataclasses.fields(cls)
                  if f"{prefix}.{f.name}" in values}
        parts[prefix] = cls(**kwargs)
    mt = parts["mt"]
    mt.texture = mesh.texture if mt.uv is not None else None
    return mt, parts["bounds"]

