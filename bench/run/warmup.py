"""Compilation is not method time: run a method once on a tiny mesh before timing it.

The engine's kernels are numba functions cached on disk. The first call in a fresh
install compiles them (minutes on two cores); every later process loads them from the
cache (about a second), and pymeshlab and the renderers have first-call costs of their
own. A run's timings should hold none of that, so each worker warms a method up on
:func:`tiny_meshes` before its first job of that method and records the time as
``compile_seconds``, apart from ``wall_seconds``. ``bench warmup`` (run by
``scripts/setup.sh``) fills numba's cache once, so the first real run starts warm.
"""

from __future__ import annotations

import time
import warnings
from functools import cache

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["tiny_meshes", "warm_up", "WARM"]

#: The methods (by name and parameters) this process has warmed up.
WARM: set = set()


@cache
def tiny_meshes() -> tuple[Mesh, Mesh]:
    """An untextured and a textured UV sphere of 112 faces (the textured one with a seam
    and a 16² texture), enough to reach every kernel of every method once."""
    from bench.catalog.torus import make_torus

    lat, lon = 8, 8
    theta = np.linspace(0, np.pi, lat + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, lon, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    positions = np.vstack([[0, 0, 1], ring, [0, 0, -1]])
    n, last = len(ring), len(ring) + 1
    faces = [[0, 1 + j, 1 + (j + 1) % lon] for j in range(lon)]
    for i in range(lat - 2):
        for j in range(lon):
            a, b = 1 + i * lon + j, 1 + i * lon + (j + 1) % lon
            faces += [[a, a + lon, b], [b, a + lon, b + lon]]
    faces += [[last, 1 + n - lon + (j + 1) % lon, 1 + n - lon + j] for j in range(lon)]
    plain = Mesh(positions, np.asarray(faces, np.int32), name="warmup")
    textured = make_torus(8, 7, texture_size=16).replace(name="warmup-textured")
    return plain, textured


def warm_up(method_cls, params=None, ctx=None) -> float:
    """Run ``method_cls(params)`` on both tiny meshes once per process and return the
    seconds it took (0 when this process already warmed it up, or when the method says
    it ``warms_up`` not). Failures are ignored: a method that cannot run on a tiny mesh
    fails, or not, on the real one."""
    from bench.core.method import run_method

    key = (method_cls.name, repr(params))
    if key in WARM or not getattr(method_cls, "warms_up", True):
        return 0.0
    start = time.perf_counter()
    for mesh in tiny_meshes():
        if getattr(method_cls, "needs_uv", False) and mesh.uv is None:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                run_method(method_cls(params), mesh, mesh.n_faces // 2,
                           {k: v for k, v in (ctx or {}).items() if k != "cache_dir"})
            except Exception:  # noqa: BLE001 - best effort, see the docstring
                pass
    WARM.add(key)
    return time.perf_counter() - start
