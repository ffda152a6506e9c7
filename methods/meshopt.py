"""meshoptimizer baselines: the simplifier game engines ship (Kapoulkine's meshoptimizer).

Three variants, each the library unchanged on the mesh's render-vertex index buffer, as
an engine calls it:

- ``meshopt``: ``simplify``. Quadric edge collapse (Garland & Heckbert 1997) that keeps
  the attribute seams it infers from split vertices (render vertices with equal
  positions), so seams stay closed; it may stop above the target when only seam or
  border collapses are left.
- ``meshopt-attributes``: ``simplify_with_attributes``, the same collapse with Hoppe's
  1999 attribute quadrics over texture coordinates and normals.
- ``meshopt-sloppy``: ``simplify_sloppy``, vertex clustering on a grid (after Lindstrom
  2000) that ignores topology and seams; the fast fallback engines use for the lowest
  LODs. With no error bound it never exceeds the target and often lands below it.

The library returns an index buffer into the original vertices; the result keeps the
surviving vertices (UVs, normals, colours and the texture carried along) and drops
unused ones. The error the library reports is recorded in the statistics: by default
relative to the mesh's extent (``meshopt_simplifyScale``), in model units with
``error_absolute``; both forms are recorded.

Python binding notes (meshoptimizer 0.2.30a0, an alpha built from an unmerged pull
request; the version is pinned and the behaviour below is tested):

- ``index_count`` defaults to ``len(indices)``, so the index buffer must be flat.
- ``simplify_with_attributes`` declares no ctypes argument types for its C function, so
  a Python float for ``target_error`` raises ``ctypes.ArgumentError`` and Python ints
  would be passed as C ``int`` where it expects ``size_t``: every scalar is passed
  already C-typed (see :func:`_c_scalars`).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from importlib.metadata import version
from typing import ClassVar

import numpy as np

from bench.errors import MethodError, ParamError
from bench.mesh import Mesh
from bench.method import Method, SimplifyResult, bounded, target_tolerance

__all__ = ["Meshopt", "MeshoptAttributes", "MeshoptSloppy", "simplify_index_buffer",
           "uv_density_weight"]

REQUIREMENT = "meshoptimizer==0.2.30a0"

#: An error bound that never stops a collapse: the largest float32. With it a stop
#: above the target is the library's topology rules (seams, borders), not its error bound.
UNBOUNDED_ERROR = float(np.finfo(np.float32).max)

#: Why simplify_sloppy lands below a target: it searches grid sizes (whole cells per
#: axis) and keeps the finest grid it found whose clustering stays under the target;
#: the face count jumps between neighbouring grid sizes.
SLOPPY_BELOW = ("simplify_sloppy keeps the finest grid it found whose clustering stays under "
                "the target, and face counts jump between grid sizes")


@dataclass
class MeshoptParams:
    """Parameters of ``meshoptimizer.simplify`` (options as booleans).

    By default the face target alone stops the simplifier, as the suite compares
    methods at equal budgets: the library gets an error bound no collapse reaches
    (``UNBOUNDED_ERROR``). With ``bound_error`` it gets ``target_error`` instead,
    relative to the mesh's extent (in model units with ``error_absolute``), as engines
    call it (the README's example uses 0.01) and accept a LOD that stops short.
    """

    bound_error: bool = False
    target_error: float = bounded(0.01, ge=0)  #: used only with bound_error
    lock_border: bool = False  #: SIMPLIFY_LOCK_BORDER: never move border vertices
    prune: bool = False  #: SIMPLIFY_PRUNE: remove isolated components (needs bound_error)
    error_absolute: bool = False  #: SIMPLIFY_ERROR_ABSOLUTE: errors in model units


@dataclass
class MeshoptAttributesParams(MeshoptParams):
    """``MeshoptParams`` plus the attribute weights of ``simplify_with_attributes``.

    normal_weight: the library's README (v0.22 on) uses 0.5 in its example and calls
    "around 1.0" appropriate for normalised attributes, since a change of 1/weight in
    an attribute over a distance d costs about as much as moving d. uv_weight_scale
    multiplies the UV weight the README (v1.0) recommends computing from the UV
    density, 1 / sqrt(mean |UV area| of a triangle) (:func:`uv_density_weight`; it
    calls 10-100 usual); 0 leaves UVs out of the metric. The error bound then covers
    positions and attributes together. (The C library in 0.2.30a0 is of the v0.22-0.23
    era: it has SIMPLIFY_PRUNE but not meshopt_simplifyPrune.)
    """

    normal_weight: float = bounded(0.5, ge=0)
    uv_weight_scale: float = bounded(1.0, ge=0)


@dataclass
class MeshoptSloppyParams:
    """Parameters of ``meshoptimizer.simplify_sloppy`` (it takes no options); the error
    bound as in :class:`MeshoptParams`, always relative to the mesh's extent."""

    bound_error: bool = False
    target_error: float = bounded(0.01, ge=0)  #: used only with bound_error


class Meshopt(Method):
    """meshoptimizer's ``simplify`` on the render-vertex index buffer.

    Split vertices with equal positions tell the library where the seams are; it keeps
    them closed (what an engine gets with no extra work) and may stop above the target
    when the remaining collapses would break a seam.
    """

    name = "meshopt"
    version = "1"
    summary = "meshoptimizer's quadric edge collapse on render vertices, seams kept"
    reference = ("A. Kapoulkine, meshoptimizer (software), meshopt_simplify; after Garland & "
                 "Heckbert, Surface simplification using quadric error metrics, SIGGRAPH 1997")
    requires: ClassVar[dict[str, str]] = {"meshoptimizer": REQUIREMENT}
    Params = MeshoptParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        import meshoptimizer

        p = _checked(self.params)

        def call(destination, indices, positions, target_index_count, target_error, error):
            return meshoptimizer.simplify(
                destination, indices, positions, index_count=len(indices),
                vertex_count=len(positions), vertex_positions_stride=positions.strides[0],
                target_index_count=target_index_count, target_error=target_error,
                options=_options(p), result_error=error)

        return simplify_index_buffer(mesh, target_faces, call, _error_bound(p),
                                     absolute=p.error_absolute)


class MeshoptAttributes(Method):
    """meshoptimizer's ``simplify_with_attributes`` with UV and normal quadrics.

    Attributes per render vertex: (u, v) weighted by the UV density rule of the
    library's README, and the vertex normal (the file's, else area-weighted over the
    welded vertex) weighted by ``normal_weight``. Seams are inferred as in ``meshopt``.
    """

    name = "meshopt-attributes"
    version = "1"
    summary = "meshoptimizer's edge collapse with UV and normal attribute quadrics"
    reference = ("A. Kapoulkine, meshoptimizer (software), meshopt_simplifyWithAttributes; "
                 "after Hoppe, New quadric metric for simplifying meshes with appearance "
                 "attributes, IEEE Visualization 1999")
    requires: ClassVar[dict[str, str]] = {"meshoptimizer": REQUIREMENT}
    Params = MeshoptAttributesParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        import meshoptimizer

        p = _checked(self.params)
        attributes, weights, weight_stats = _attributes(mesh, p)

        def call(destination, indices, positions, target_index_count, target_error, error):
            return meshoptimizer.simplify_with_attributes(
                destination, indices, positions, attributes, weights, vertex_lock=None,
                result_error=error, **_c_scalars(
                    index_count=len(indices), vertex_count=len(positions),
                    vertex_positions_stride=positions.strides[0],
                    vertex_attributes_stride=attributes.strides[0],
                    attribute_count=len(weights), target_index_count=target_index_count,
                    target_error=target_error, options=_options(p)))

        result = simplify_index_buffer(mesh, target_faces, call, _error_bound(p),
                                       absolute=p.error_absolute)
        result.stats.update(weight_stats)
        return result


class MeshoptSloppy(Method):
    """meshoptimizer's ``simplify_sloppy``: grid vertex clustering, topology ignored.

    Seams and borders are not kept (cracks and merged sheets are expected). With no
    error bound the result never exceeds the target; the grid search often stops below
    it. (With a bound the grid has at least 1/target_error cells per axis.)
    """

    name = "meshopt-sloppy"
    version = "1"
    summary = "meshoptimizer's sloppy grid clustering (fast, ignores seams and topology)"
    reference = ("A. Kapoulkine, meshoptimizer (software), meshopt_simplifySloppy; after "
                 "Lindstrom, Out-of-core simplification of large polygonal models, "
                 "SIGGRAPH 2000")
    requires: ClassVar[dict[str, str]] = {"meshoptimizer": REQUIREMENT}
    Params = MeshoptSloppyParams

    def simplify(self, mesh: Mesh, target_faces: int, ctx=None) -> SimplifyResult:
        import meshoptimizer

        def call(destination, indices, positions, target_index_count, target_error, error):
            return meshoptimizer.simplify_sloppy(
                destination, indices, positions, index_count=len(indices),
                vertex_count=len(positions), vertex_positions_stride=positions.strides[0],
                target_index_count=target_index_count, target_error=target_error,
                result_error=error)

        return simplify_index_buffer(mesh, target_faces, call, _error_bound(self.params),
                                     absolute=False, below=SLOPPY_BELOW)


def simplify_index_buffer(mesh: Mesh, target_faces: int, call, target_error: float,
                          absolute: bool, below: str = "") -> SimplifyResult:
    """The pipeline shared by the variants: index buffer in, compacted mesh out.

    Parameters
    ----------
    mesh : Mesh
    target_faces : int
    call : callable
        ``call(destination, indices, positions, target_index_count, target_error,
        error) -> index count``, one meshoptimizer simplifier with its options bound;
        ``error`` is a (1,) float32 array that receives the library's result error.
    target_error : float
        The library's error bound (``UNBOUNDED_ERROR`` for none).
    absolute : bool
        Whether ``target_error`` and the library's result error are in model units
        (``SIMPLIFY_ERROR_ABSOLUTE``) rather than relative to the mesh's extent.
    below : str
        Why this simplifier may stop below the target, for the stop reason.

    Returns
    -------
    SimplifyResult
        With ``stop_reason`` set when the library stopped outside the suite's tolerance.
    """
    import meshoptimizer

    # The library reads a flat uint32 index buffer and float32 xyz (stride 12 bytes).
    indices = np.ascontiguousarray(mesh.faces.reshape(-1), dtype=np.uint32)
    positions = np.ascontiguousarray(mesh.positions, dtype=np.float32)
    target_index_count = 3 * int(target_faces)
    kept, error = _run(call, indices, positions, target_index_count, target_error)
    if len(kept) == 0:  # no LOD to degrade to: say so instead of returning nothing
        raise MethodError(f"{mesh.name}: meshoptimizer left no triangles for a target of "
                          f"{target_faces} faces (its result error {error:.4g}); ask for "
                          "more faces")
    result = _compact(mesh, kept)

    # Record the error both ways: relative to the extent (the library's default unit)
    # and in model units; simplify_scale is the factor between them.
    scale = float(meshoptimizer.simplify_scale(positions))
    relative = error / scale if absolute else error
    stats = {"backend": f"meshoptimizer {version('meshoptimizer')}",
             "result_error": error, "result_error_units": "absolute" if absolute else "relative",
             "result_error_relative": relative, "result_error_absolute": relative * scale,
             "error_scale": scale,
             "target_error": None if target_error == UNBOUNDED_ERROR else target_error}
    reason = _stop_reason(call, indices, positions, result.n_faces, target_faces,
                          target_error, error, below)
    return SimplifyResult(result, stats, stop_reason=reason)


def uv_density_weight(mesh: Mesh) -> float:
    """The UV weight the meshoptimizer README recommends: the reciprocal of the average
    UV density, 1 / sqrt(sum |UV area| / triangle count); 0 when the UVs have no area.
    """
    uv = mesh.uv[mesh.faces]
    a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    mean_area = float(np.abs(0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])).mean())
    return float(1.0 / np.sqrt(mean_area)) if mean_area > 0 else 0.0


def _run(call, indices, positions, target_index_count, target_error):
    """One library call: the kept index buffer, shape (k, 3), and the result error."""
    destination = np.zeros(len(indices), np.uint32)  # the library may write index_count
    error = np.zeros(1, np.float32)
    count = int(call(destination, indices, positions, target_index_count, target_error, error))
    return destination[:count].reshape(-1, 3), float(error[0])


def _compact(mesh: Mesh, kept: np.ndarray) -> Mesh:
    """The kept triangles over only the vertices they use, attributes carried along."""
    used = np.zeros(mesh.n_vertices, bool)
    used[kept.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    pick = {attr: getattr(mesh, attr)[used] for attr in ("uv", "normals", "colors")
            if getattr(mesh, attr) is not None}
    return mesh.replace(positions=mesh.positions[used], faces=remap[kept].astype(np.int32),
                        **pick)


def _stop_reason(call, indices, positions, reached: int, target: int, target_error: float,
                 error: float, below: str) -> str | None:
    """Why the library stopped outside the tolerance, or None when it is within.

    Above the target the cause is the error bound or the topology rules; the library
    does not say which, so with a bound the call is repeated without one (cheap, and
    only on this path): the bound was the cause if that run gets further.
    """
    tolerance = target_tolerance(target)
    if abs(reached - target) <= tolerance:
        return None
    if reached < target:
        return (f"stopped at {reached} faces, below the target of {target} (tolerance "
                f"{tolerance})" + (f": {below}" if below else ""))
    if target_error != UNBOUNDED_ERROR:
        unbounded, _ = _run(call, indices, positions, 3 * target, UNBOUNDED_ERROR)
        if len(unbounded) < reached:
            return (f"stopped at {reached} faces above the target of {target}: the error "
                    f"bound target_error={target_error:g} allows no coarser result (result "
                    f"error {error:.4g})")
    return (f"stopped at {reached} faces above the target of {target}: no collapse left that "
            f"keeps the seams and borders the library preserves (result error {error:.4g})")


def _checked(p: MeshoptParams) -> MeshoptParams:
    """The parameters, refused when they ask for what the library cannot do sensibly."""
    if p.prune and not p.bound_error:
        # Pruning drops any component whose removal stays under the error bound; with
        # no bound that is every component (measured: bunny-textured to 0 faces at 2 %).
        raise ParamError("prune=true removes components under target_error and, with no "
                         "error bound, can remove the whole mesh: also set bound_error=true")
    return p


def _error_bound(p) -> float:
    return float(p.target_error) if p.bound_error else UNBOUNDED_ERROR


def _options(p: MeshoptParams) -> int:
    import meshoptimizer

    return ((meshoptimizer.SIMPLIFY_LOCK_BORDER if p.lock_border else 0)
            | (meshoptimizer.SIMPLIFY_PRUNE if p.prune else 0)
            | (meshoptimizer.SIMPLIFY_ERROR_ABSOLUTE if p.error_absolute else 0))


def _attributes(mesh: Mesh, p: MeshoptAttributesParams):
    """Per-vertex attributes (n, 2 + 3) or (n, 3) float32, their weights, and stats.

    UVs come first (when the mesh has them), then the vertex normals.
    """
    columns, weights, stats = [], [], {"normal_weight": float(p.normal_weight)}
    if mesh.uv is not None:
        uv_weight = float(p.uv_weight_scale * uv_density_weight(mesh))
        columns.append(mesh.uv)
        weights += [uv_weight, uv_weight]
        stats["uv_weight"] = uv_weight
    columns.append(mesh.vertex_normals)
    weights += [float(p.normal_weight)] * 3
    attributes = np.ascontiguousarray(np.hstack(columns), dtype=np.float32)
    return attributes, np.asarray(weights, np.float32), stats


def _c_scalars(**values) -> dict:
    """Scalars for ``simplify_with_attributes`` as the C types its function takes
    (``size_t`` counts and strides, ``float`` error, ``unsigned`` options); its binding
    declares no argument types (see the module docstring)."""
    typed = {}
    for key, value in values.items():
        if key == "target_error":
            typed[key] = ctypes.c_float(value)
        elif key == "options":
            typed[key] = ctypes.c_uint(value)
        else:
            typed[key] = ctypes.c_size_t(value)
    return typed
