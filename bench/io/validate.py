"""Checks and cleaning for mesh data from outside the suite.

Every failure is an :class:`~bench.core.errors.InputError` whose one-line message starts
with the source (usually a file name) and says what is wrong and what to do; every
repair is a :class:`~bench.core.errors.MeshWarning` that says what was changed.

=========================  ===============================================
problem                    outcome
=========================  ===============================================
no faces                   error (a point cloud cannot be simplified)
NaN / inf positions        error
NaN / inf / huge UVs       error (in a file; NaN UVs given as arrays: dropped, warning)
face index out of range    error (also a vt or vn index, with the OBJ line)
truncated PLY              error
non-triangle faces         triangulated by the loader (concave: ear clipping), warning
faces of 1 or 2 corners    left out by the loader, warning with count
degenerate faces           dropped, warning with count (judged scale-free)
missing texture image      warning, mesh loaded untextured (UVs kept)
unreadable texture image   the same (empty, corrupt, a directory), with the reason
non-manifold edges         allowed, warning with count
several materials          one texture atlas (:mod:`bench.io.atlas`)
a material's texture gone  warning, that material uses its colour
repeat too large to pack   error naming the material
=========================  ===============================================
"""

from __future__ import annotations

import sys
import warnings
from contextlib import contextmanager

import numpy as np

from bench.core.errors import InputError, MeshWarning
from bench.core.mesh import Mesh

__all__ = ["UV_LIMIT", "build_mesh", "check_uv", "recorded_warnings", "warn", "warn_again"]

#: The largest texture coordinate accepted (in texture periods): beyond, a UV is taken
#: for corrupt data; no texture repeats that often, and a 32-bit float (as GPUs and
#: glTF store UVs) has no fraction left there.
UV_LIMIT = 1e6


def warn(message: str) -> None:
    """Issue a :class:`MeshWarning` (shown by the CLI as one ``bench: warning:`` line),
    attributed to the caller of the function that calls this; noted as well inside
    :func:`recorded_warnings`."""
    warnings.warn(message, MeshWarning, stacklevel=3)
    if _RECORDERS:
        frame = sys._getframe(2)
        _RECORDERS[-1].append((message, frame.f_code.co_filename, frame.f_lineno,
                               frame.f_globals.get("__name__", "")))


#: The lists :func:`recorded_warnings` is filling, innermost last.
_RECORDERS: list[list] = []


@contextmanager
def recorded_warnings():
    """The :class:`MeshWarning` s issued inside, each as (message, filename, line,
    module), in a list; they are issued as usual too (:func:`warn_again` issues one
    again, as from the same place)."""
    got: list = []
    _RECORDERS.append(got)
    try:
        yield got
    finally:
        _RECORDERS.pop()


def warn_again(message: str, filename: str, lineno: int, module: str) -> None:
    """Issue a warning recorded by :func:`recorded_warnings` as :func:`warn` issued it:
    from the same place, so a filter on its module applies and the default filter shows
    it once per place."""
    owner = sys.modules.get(module)
    registry = None if owner is None else vars(owner).setdefault("__warningregistry__", {})
    warnings.warn_explicit(message, MeshWarning, filename, lineno, module=module,
                           registry=registry)


def check_uv(uv: np.ndarray, source: str, *, finite_checked: bool = False) -> None:
    """InputError for texture coordinates that are not finite or beyond
    :data:`UV_LIMIT`; with ``finite_checked``, only the second."""
    uv = np.asarray(uv, dtype=np.float64)
    bad = ~(np.abs(uv) <= UV_LIMIT).all(axis=1)
    if finite_checked:
        bad &= np.isfinite(uv).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        u, v = uv[first]
        raise InputError(f"{source}: {int(bad.sum())} texture coordinates are not finite or "
                         f"beyond {UV_LIMIT:g} in magnitude (first: ({u:g}, {v:g}) at vertex "
                         f"{first}); the data is corrupt")


def build_mesh(positions, faces, *, source: str, uv=None, normals=None, colors=None,
               texture=None, name: str | None = None, metadata: dict | None = None) -> Mesh:
    """Validate raw arrays and return a clean :class:`Mesh`.

    Parameters
    ----------
    positions : array_like of shape (n, 3)
    faces : array_like of shape (m, 3) of int
    source : str
        What to name in messages (a file path or a model name).
    uv, normals, colors, texture, name, metadata
        As in :class:`Mesh`. Attribute arrays with the wrong number of rows are
        dropped with a warning rather than failing the load.

    Returns
    -------
    Mesh
        With degenerate faces removed and unused vertices kept (indices unchanged).

    Raises
    ------
    InputError
        No faces, non-finite positions, indices out of range, malformed arrays.
    """
    positions, faces = _checked_arrays(positions, faces, source)
    attrs = _attributes(source, len(positions), uv=uv, normals=normals, colors=colors)
    mesh = Mesh(positions, faces, texture=texture, name=name or source,
                metadata=dict(metadata or {}), **attrs)
    mesh = _drop_degenerate(mesh, source)
    nm = int(mesh.welded.non_manifold.sum())
    if nm:
        warn(f"{source}: {nm} non-manifold edges (more than two faces); allowed, but some "
             "methods treat them as locked")
    return mesh


def _checked_arrays(positions, faces, source: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions as float64 and faces as int32, or an InputError naming what is wrong:
    a shape, no faces, integer indices, non-finite coordinates, indices out of range."""
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        raise InputError(f"{source}: positions must be an (n, 3) array, "
                         f"got shape {positions.shape}")
    faces = np.asarray(faces)
    if faces.size == 0:
        raise InputError(f"{source}: the mesh has no faces (a point cloud or line set "
                         "cannot be simplified); export it with its triangles")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{source}: faces must be an (m, 3) array of triangles, "
                         f"got shape {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{source}: face indices must be integers, got {faces.dtype}")

    bad = ~np.isfinite(positions).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise InputError(f"{source}: {int(bad.sum())} vertices have NaN or infinite coordinates "
                         f"(first: vertex {first}); fix or remove them before simplifying")

    n = len(positions)
    out = (faces < 0) | (faces >= n)
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        idx = int(faces[f][out[f]][0])
        raise InputError(f"{source}: face {f} refers to vertex {idx} but the mesh has {n} "
                         f"vertices ({int(out.any(axis=1).sum())} faces out of range); "
                         "the file is corrupt or truncated")
    faces = faces.astype(np.int32)
    return positions, faces


def _attributes(source: str, n: int, **given) -> dict:
    """The per-vertex attributes (``uv``, ``normals``, ``colors``) given and usable: one
    of the wrong shape or with non-finite values is left out with a warning."""
    attrs = {}
    for attr, width in (("uv", 2), ("normals", 3), ("colors", 4)):
        value = given[attr]
        if value is None:
            continue
        value = np.asarray(value)
        if value.ndim != 2 or value.shape != (n, width):
            warn(f"{source}: ignoring {attr} of shape {value.shape} (expected ({n}, {width}))")
            continue
        if not np.isfinite(value.astype(np.float64)).all():
            warn(f"{source}: ignoring {attr}: they contain NaN or infinite values")
            continue
        if attr == "uv":
            check_uv(value, source, finite_checked=True)
        attrs[attr] = value
    return attrs


def _drop_degenerate(mesh: Mesh, source: str) -> Mesh:
    """Drop faces with a repeated (welded) corner or exactly zero area."""
    w = mesh.welded.faces
    repeated = (w[:, 0] == w[:, 1]) | (w[:, 1] == w[:, 2]) | (w[:, 2] == w[:, 0])
    flat = ~mesh.face_normals.any(axis=1)  # zero cross product: collinear corners
    bad = repeated | flat
    if not bad.any():
        return mesh
    if bad.all():
        raise InputError(f"{source}: all {len(bad)} faces are degenerate (zero area); "
                         "nothing to simplify")
    warn(f"{source}: dropped {int(bad.sum())} degenerate faces (repeated corner or zero area)")
    return mesh.replace(faces=mesh.faces[~bad])
