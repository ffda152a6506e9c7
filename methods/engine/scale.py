"""Meshes at a workable scale.

The engine and the view-based methods square lengths (quadrics, normals, bounding
spheres, camera frames), which overflows for coordinates near 1e300 and underflows
near 1e-150. A mesh whose largest coordinate lies outside [2^-LIMIT, 2^LIMIT] is
therefore simplified as a copy scaled by a power of two to coordinates below 1, and the
result is scaled back by the same power. Both scalings are exact in binary floating
point, and a mesh inside the range is left as it is, so its results do not change.
"""

from __future__ import annotations

import functools

import numpy as np

from bench.core.mesh import Mesh

#: Coordinates up to 2^LIMIT in magnitude (and down to 2^-LIMIT) are used as they are.
LIMIT = 60


def workable_exponent(positions: np.ndarray) -> int:
    """0 when ``positions`` are inside the workable range (or all zero), else the power
    of two ``e`` such that ``positions / 2^e`` has its largest magnitude in [0.5, 1)."""
    top = float(np.abs(positions).max()) if positions.size else 0.0
    if top == 0.0 or 2.0 ** -LIMIT <= top <= 2.0 ** LIMIT:
        return 0
    return int(np.frexp(top)[1])


def scaled(mesh: Mesh, exponent: int) -> Mesh:
    """``mesh`` with its positions multiplied by 2^exponent (exactly)."""
    if exponent == 0:
        return mesh
    return mesh.replace(positions=np.ldexp(mesh.positions, exponent))


def at_workable_scale(simplify):
    """Decorate a method's ``simplify(self, mesh, target_faces, ctx)`` so that it runs on
    :func:`scaled` ``mesh`` when the mesh is outside the workable range, and its result's
    mesh is scaled back (the view-based methods make their cameras from the mesh, so
    they scale before :func:`methods.engine.simplify.simplify_mesh` would)."""
    @functools.wraps(simplify)
    def wrapper(self, mesh: Mesh, target_faces: int, ctx=None):
        exponent = workable_exponent(mesh.positions)
        if not exponent:
            return simplify(self, mesh, target_faces, ctx)
        result = simplify(self, scaled(mesh, -exponent), target_faces, ctx)
        result.mesh = scaled(result.mesh, exponent)
        return result
    return wrapper
