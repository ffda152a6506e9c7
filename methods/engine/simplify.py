"""The Python entry point :func:`simplify_mesh`: arrays at unit scale, the loop, and the
render vertices rebuilt from the surviving wedges."""

from __future__ import annotations

import math
import time
from collections import namedtuple

import numba
import numpy as np

from bench.core.mesh import Mesh
from bench.core.progress import watching_faces
from bench.io.atlas import face_materials, wedge_tiles
from methods.corners import corner_lists
from methods.engine.initial import edge_areas, first_costs
from methods.engine.loop import _run, compile_collapse
from methods.engine.parts import face_groups
from methods.engine.policy import PLACEMENTS, REJECTIONS, EngineResult, Policy
from methods.engine.scale import scaled, workable_exponent
from methods.engine.state import (
    KIND_STRANDED,
    KIND_STRANDED_WEDGES,
    KIND_TWIN,
    LOG_CHANGED,
    LOG_COLLAPSES,
    LOG_PAIRS,
    LOG_WEDGES,
    N_KINDS,
    WEDGE_QUADRIC_SIZE,
    Images,
    Log,
    MeshArrays,
    Rules,
    Terms,
    Weights,
    new_scratch,
)
from methods.engine.terms.quadric import _boundary_corners, initial_quadrics, wedge_quadrics
from methods.engine.terms.r5 import _face_kappa
from methods.engine.topology import vboundary_of
from methods.engine.views import views_shared
from methods.imaging.state import dummy_state, keeps_luminance

#: The default policy (one shared instance: a Policy is never modified).
DEFAULT_POLICY = Policy()

#: The bounding-box diagonal of the geometry the costs are computed on (:func:`_prepare`).
WORKING_DIAGONAL = 1.0

#: A mean initial base cost at most this many times the rounding noise of the costs
#: measures no scale (:func:`_canny_units`).
CANNY_NOISE_FACTOR = 1000.0


def simplify_mesh(mesh: Mesh, target_faces: int, policy: Policy = DEFAULT_POLICY,
                  verify: bool = False, borders: np.ndarray | None = None,
                  image=None, max_collapses: int | None = None) -> EngineResult:
    """Collapse edges of ``mesh`` until it has at most ``target_faces`` faces (or no
    valid collapse remains) under ``policy``.

    Parameters
    ----------
    mesh : Mesh
    target_faces : int
        At least 1. The result has ``target_faces`` or one fewer faces (a collapse
        removes two faces, one on a boundary) unless the engine stops early.
    policy : Policy
    verify : bool
        Check that every collapse taken at its queued cost has that cost when
        re-evaluated (the lazy-queue invariant); counts go to ``stats``.
    borders : ndarray of shape (h, w) bool, optional
        Texture borders for the Canny term (``policy.canny_weight``).
    image : methods.imaging.region.ImageTerm, optional
        Adds Lindstrom & Turk 2000's image cost (equation 8) with ``image.weight``;
        ``verify`` then also re-renders the final mesh from scratch and counts pixels
        that differ from the incrementally maintained images.
    max_collapses : int, optional
        Stop after this many collapses (for tests and step-by-step inspection).

    Notes
    -----
    Costs and quadrics are computed on positions normalised to a bounding-box diagonal
    of :data:`WORKING_DIAGONAL` (1); ``quadrics`` in the result are in those units. A
    mesh with coordinates beyond 2^±60 is simplified as a copy scaled by a power of two
    (:mod:`methods.engine.scale`) and its result scaled back.
    """
    if target_faces < 1:
        raise ValueError(f"target_faces must be at least 1, got {target_faces}")
    exponent = workable_exponent(mesh.positions)
    if exponent:  # coordinates near 1e300 or 1e-150: simplify at unit scale (exactly)
        return _simplify_scaled(mesh, exponent, target_faces, policy, verify, borders, image,
                                max_collapses)
    start = time.perf_counter()
    s = _setup(mesh, target_faces, policy, verify, borders, image, max_collapses)
    run = _phases(s.arrays, s.rules, s.terms, s.scratch, s.images, s.prep.kinds,
                  _stall_phases(policy, s.rules))
    return _result(mesh, target_faces, policy, image, s.prep, s.arrays, s.rules, s.images,
                   run, s.canny_stats, start)


#: What the loop starts from (:func:`_setup`): the prepared mesh, its arrays, the rules,
#: the terms, the image state, the Canny term's statistics and the scratch.
_Setup = namedtuple("_Setup", "prep arrays rules terms images canny_stats scratch")


def _setup(mesh: Mesh, target_faces: int, policy: Policy, verify, borders, image,
           max_collapses) -> _Setup:
    """The arrays at unit scale, the rules, the terms and the image state of a run."""
    prep = _prepare(mesh, policy, image)
    _check_canny(mesh, policy, borders, image)
    arrays = _quadrics(mesh, policy, prep)
    rules = _rules(mesh, policy, image, prep, target_faces, verify, max_collapses)
    terms = _terms(policy, prep, borders, rules)
    images = _image_state(mesh, image, arrays, prep, _texture_quadrics(mesh, policy))
    canny_stats = {}
    if policy.canny_weight != 0.0 and policy.canny_units == "base-cost":
        terms, canny_stats = _canny_units(arrays, rules, terms, images)
    return _Setup(prep=prep, arrays=arrays, rules=rules, terms=terms, images=images,
                  canny_stats=canny_stats, scratch=new_scratch(len(arrays.P)))


#: The parts of the engine's kernels that :func:`compile_part` compiles on its own.
PARTS = ("costing", "collapse")


def compile_part(part: str, mesh: Mesh) -> None:
    """Compile one part of the engine's kernels for ``mesh``'s types (or read it from
    numba's cache) without simplifying: ``"costing"``, the first costing of every edge
    (:func:`first_costs`, with every cost term); ``"collapse"``, how the loop takes a
    collapse (:func:`methods.engine.loop.compile_collapse`). Two processes compile the
    two at once; the loop (:func:`_run`), compiled after them, reads both from the cache
    (``bench warmup``, :mod:`bench.run.warmup`)."""
    if part not in PARTS:
        raise ValueError(f"unknown part of the engine's kernels {part!r}; one of {PARTS}")
    s = _setup(mesh, max(1, mesh.n_faces // 2), DEFAULT_POLICY, False, None, None, None)
    if part == "costing":
        first_costs(s.arrays, s.rules, s.terms, s.scratch, s.images)
    else:
        compile_collapse(s.arrays, s.rules, s.terms, s.scratch, s.images, s.prep.kinds)


def _simplify_scaled(mesh: Mesh, exponent: int, target_faces: int, policy: Policy, verify,
                     borders, image, max_collapses) -> EngineResult:
    """:func:`simplify_mesh` of ``mesh`` scaled by 2^-``exponent``, its result scaled
    back (exactly: powers of two)."""
    if image is not None:
        raise ValueError("the image term was made for a mesh outside the workable "
                         "scale; scale the mesh first (methods.engine.scale)")
    result = simplify_mesh(scaled(mesh, -exponent), target_faces, policy, verify,
                           borders, image, max_collapses)
    result.mesh = scaled(result.mesh, exponent)
    result.log["position"] = np.ldexp(result.log["position"], exponent)
    return result


def _result(mesh: Mesh, target_faces: int, policy: Policy, image, prep, arrays, rules,
            images, run, canny_stats: dict, start: float) -> EngineResult:
    """The :class:`EngineResult` of a finished run (started at ``start``, a
    ``time.perf_counter()``): the simplified mesh in the input's numbering, the stop
    reason, the statistics and the log."""
    stopped, evaluations, mismatches, rejects, log, stall_phases, stall_collapses = run
    verify = rules.verify
    image_stats = {} if image is None else image.statistics(
        mesh, images.img, verify, arrays.P, arrays.F, arrays.FW, arrays.uv, arrays.falive,
        arrays.vhead, arrays.cnext, arrays.valive, prep.lo, prep.scale)
    tiles = wedge_tiles(mesh)
    simplified, clamped = _extract(mesh, np.where(arrays.moved[:, None],
                                                  arrays.P * prep.scale + prep.lo, prep.P0),
                                   arrays.FW[arrays.falive], arrays.wedge_vertex,
                                   arrays.uv if rules.has_uv else None, tiles)
    reason = _stop_reason(stopped, int(arrays.falive.sum()), target_faces, rejects)
    stats = _statistics(int(log.count[LOG_COLLAPSES]), evaluations, mismatches, rejects,
                        prep.kinds, verify, time.perf_counter() - start)
    if policy.stall_rotations or policy.stall_seams or math.isfinite(policy.max_move):
        stats["stall_phases"], stats["stall_collapses"] = stall_phases, stall_collapses
    stats.update(image_stats)
    stats.update(canny_stats)
    if tiles is not None:
        stats["uvs_kept_in_tile"] = clamped
    out_log, Q, valive = _log_in_input_numbering(log, prep, arrays, tiles)
    return EngineResult(simplified, reason, stats, out_log, quadrics=Q, vertex_alive=valive,
                        images=(images.img.Y if image is not None
                                and keeps_luminance(images.img) else None))


def _check_canny(mesh: Mesh, policy: Policy, borders, image) -> None:
    """The Canny term's inputs: texture borders and UVs, and no image term beside its
    ``base-cost`` units."""
    if policy.canny_weight != 0.0 and (borders is None or mesh.uv is None):
        raise ValueError("the Canny term needs texture borders and UVs; pass borders= "
                         "(methods.engine.terms.canny.texture_borders) for a mesh with UVs")
    if policy.canny_weight != 0.0 and policy.canny_units == "base-cost" and image is not None:
        raise ValueError("canny_units='base-cost' measures the base cost without "
                         "rendering; it does not combine with the image term")


def _stall_phases(policy: Policy, rules: Rules) -> list[tuple[str, dict]]:
    """The stall rule's phases (:attr:`Policy.stall_rotations`) as (name, what each
    changes in the :data:`~methods.engine.state.Rules`), in order; each keeps what the
    ones before it changed."""
    phases = []
    if policy.stall_seams and rules.seam_rule:
        phases.append(("seams released", {"seam_rule": False}))
    for degrees in policy.stall_rotations:
        phases.append((f"{degrees:g} degrees", {"cos_limit": math.cos(math.radians(degrees))}))
    if math.isfinite(policy.max_move) and policy.move_memory:
        phases.append(("move memory dropped", {"move_memory": False}))
    if math.isfinite(policy.max_move):
        phases.append(("move bound lifted", {"max_move": math.inf}))
    return phases


def _phases(arrays: MeshArrays, rules: Rules, terms, scratch, images, kinds, phases):
    """The loop, then the stall rule (:func:`_stall_phases`): while it stops with no
    valid collapse, the loop again under the next phase's rules, with the collapses the
    run has left. Returns (stopped, evaluations, mismatches, rejects, log (the phases'
    logs joined), the names of the stall phases that ran, collapses per stall phase)."""
    stopped, evaluations, mismatches, rejects, log = _loop(arrays, rules, terms, scratch,
                                                           images, kinds)
    names, stall_collapses = [], []
    allowed = rules.max_collapses  # in all: the phases' logs are joined into ``log``
    for name, changes in phases:
        if not stopped or int(log.count[LOG_COLLAPSES]) >= allowed:
            break
        rules = rules._replace(**changes,
                               max_collapses=allowed - int(log.count[LOG_COLLAPSES]))
        stopped, more, mm, rj, rest = _loop(arrays, rules, terms, scratch, images, kinds)
        names.append(name)
        stall_collapses.append(int(rest.count[LOG_COLLAPSES]))
        evaluations, mismatches, rejects = evaluations + more, mismatches + mm, rejects + rj
        log = _joined(log, rest)
    return stopped, evaluations, mismatches, rejects, log, names, stall_collapses


def _stop_reason(stopped, faces: int, target_faces: int, rejects) -> str | None:
    """Why the run stopped above its target (None when it did not): the faces left and
    the candidates rejected by each rule."""
    if not stopped:
        return None
    counts = ", ".join(f"{name} {int(c)}" for name, c in zip(REJECTIONS, rejects) if c)
    return (f"no valid collapse remains at {faces} faces (target {target_faces}); "
            f"candidates rejected: {counts or 'none'}")


def _loop(arrays: MeshArrays, rules: Rules, terms, scratch, images, kinds):
    """Every live edge costed (:func:`first_costs`), then the loop (:func:`_run`), with
    the progress bar and the views shared among the job's threads."""
    first = first_costs(arrays, rules, terms, scratch, images)
    args = (arrays, rules, terms, scratch, images, kinds, first)
    # Compiled (or read from numba's cache) before the helpers start: they wait for
    # work spinning on a core, which a compile of minutes would waste.
    _run.compile(tuple(numba.typeof(a) for a in args))
    with (views_shared(arrays, rules, scratch, images),
          watching_faces(arrays.falive, rules.target)):
        return _run(*args)


def _joined(first, then):
    """One :data:`~methods.engine.state.Log` of the collapses of ``first`` followed by
    those of ``then``, each trimmed to its counts, the CSR starts of ``then`` shifted."""
    n = [int(log.count[LOG_COLLAPSES]) for log in (first, then)]
    used = {name: [int(log.count[k]) for log in (first, then)]
            for name, k in (("changed", LOG_CHANGED), ("pairs", LOG_PAIRS),
                            ("wedges", LOG_WEDGES), ("wedge_uv", LOG_WEDGES))}

    def rows(name):
        return np.concatenate([getattr(first, name)[:n[0]], getattr(then, name)[:n[1]]])

    def lists(name):
        return np.concatenate([getattr(first, name)[:used[name][0]],
                               getattr(then, name)[:used[name][1]]])

    def starts(name, shift):
        return np.concatenate([getattr(first, name)[:n[0] + 1],
                               getattr(then, name)[1:n[1] + 1] + shift])

    return Log(cost=rows("cost"), removed=rows("removed"), kept=rows("kept"), pos=rows("pos"),
               faces=rows("faces"), start=starts("start", used["changed"][0]),
               changed=lists("changed"), pair_start=starts("pair_start", used["pairs"][0]),
               pairs=lists("pairs"), wedge_start=starts("wedge_start", used["wedges"][0]),
               wedges=lists("wedges"), wedge_uv=lists("wedge_uv"), count=first.count + then.count)


#: What :func:`_prepare` hands on: positions ``P0`` (input units) and ``P`` (unit
#: diagonal) after renumbering, the frame ``lo``/``scale``, the engine's face and wedge
#: arrays, the permutations (None without renumbering) and the ``kinds`` counters.
_Prepared = namedtuple("_Prepared", "P0 P lo scale mesh boundary_corners vperm fperm kinds")


def _prepare(mesh: Mesh, policy: Policy, image) -> _Prepared:
    """Welded arrays at unit bounding-box diagonal, renumbered along a Morton curve
    with the image term; the quadrics are left to :func:`_quadrics`."""
    w = mesh.welded
    # Work on geometry normalised to a unit bounding-box diagonal, so that cost terms of
    # different kinds (quadric, Lindstrom-Turk, Canny area ratios) add up the same way
    # whatever the model's scale. Vertices that never move keep their exact input
    # positions in the output.
    P0 = w.positions.astype(np.float64)
    lo = P0.min(axis=0)
    scale = (float(np.linalg.norm(P0.max(axis=0) - lo)) or 1.0) / WORKING_DIAGONAL
    P = (P0 - lo) / scale
    F = w.faces.astype(np.int64).copy()
    FW = mesh.faces.astype(np.int64).copy()
    wedge_vertex = w.vertex_of.astype(np.int64).copy()
    boundary_corners = _boundary_corners(mesh)
    nv = len(P)
    vboundary = vboundary_of(w, nv)
    vperm = fperm = None
    if image is not None:
        P0, P, vboundary, F, FW, wedge_vertex, boundary_corners, vperm, fperm = _renumber(
            P0, P, vboundary, F, FW, wedge_vertex, boundary_corners)
    falive = np.ones(len(F), bool)
    vhead, cnext = corner_lists(F, nv)
    valive = np.zeros(nv, bool)
    valive[np.unique(F)] = True
    uv = mesh.uv.copy() if mesh.uv is not None else np.zeros((1, 2))
    materials = face_materials(mesh)
    if materials is not None and fperm is not None:
        materials = materials[fperm]
    group, group_live = face_groups(F, nv, materials)
    arrays = MeshArrays(P=P, Q=None, F=F, FW=FW, falive=falive, vhead=vhead, cnext=cnext,
                        valive=valive, vboundary=vboundary, wedge_vertex=wedge_vertex,
                        uv=uv, moved=np.zeros(nv, bool), WQ=None, group=group,
                        group_live=group_live, drift=np.zeros(nv))
    return _Prepared(P0, P, lo, scale, arrays, boundary_corners, vperm, fperm,
                     np.zeros(N_KINDS, np.int64))


def _renumber(P0, P, vboundary, F, FW, wedge_vertex, boundary_corners):
    """Renumber vertices and faces along a Morton curve, so that the faces and vertices
    of a screen region sit close together in memory (the image term reads them per
    pixel rectangle); ids in the log are mapped back at the end."""
    nv = len(P)
    vperm = np.argsort(_morton(P), kind="stable")
    inverse = np.empty_like(vperm)
    inverse[vperm] = np.arange(nv)
    P0, P, vboundary = P0[vperm], P[vperm], vboundary[vperm]
    F, wedge_vertex = inverse[F], inverse[wedge_vertex]
    fperm = np.argsort(_morton(P[F].mean(axis=1)), kind="stable")
    F, FW, boundary_corners = F[fperm], FW[fperm], boundary_corners[fperm]
    return P0, P, vboundary, F, FW, wedge_vertex, boundary_corners, vperm, fperm


def _quadrics(mesh: Mesh, policy: Policy, prep: _Prepared) -> MeshArrays:
    """The engine's mesh arrays with their quadrics: per-vertex planes (Garland &
    Heckbert 1997, boundary planes weighted by ``boundary_weight``), or with
    ``texture_weight`` per-wedge 5-D quadrics (their 1998 paper)."""
    a = prep.mesh
    texture_quadrics = _texture_quadrics(mesh, policy)
    Q = initial_quadrics(a.P, a.F, prep.boundary_corners, policy.boundary_weight,
                         faces=not texture_quadrics)
    WQ = (wedge_quadrics(a.P, a.F, a.FW, a.uv, policy.texture_weight) if texture_quadrics
          else np.zeros((1, WEDGE_QUADRIC_SIZE)))
    return a._replace(Q=Q, WQ=WQ)


def _texture_quadrics(mesh: Mesh, policy: Policy) -> bool:
    return policy.texture_weight > 0 and mesh.uv is not None and policy.quadric_weight != 0


def _rules(mesh: Mesh, policy: Policy, image, prep: _Prepared, target_faces, verify,
           max_collapses) -> Rules:
    """The policy as the kernel's codes (:data:`methods.engine.state.Rules`)."""
    has_uv = mesh.uv is not None
    weights = Weights(
        quadric=float(policy.quadric_weight), memoryless=float(policy.memoryless_weight),
        canny=float(policy.canny_weight), image=float(0.0 if image is None else image.weight),
        entropy=float(0.0 if image is None else getattr(image, "entropy_weight", 0.0)))
    nv = len(prep.P)
    limit = max(1, nv) if max_collapses is None else max(0, int(max_collapses))
    return Rules(placement=PLACEMENTS[policy.placement], weights=weights,
                 cos_limit=math.cos(math.radians(policy.max_normal_rotation)),
                 boundary_lock=bool(policy.boundary_lock),
                 seam_rule=bool(policy.seam_rule
                                and mesh.n_vertices != mesh.welded.n_vertices),
                 boundary_rule=bool(policy.boundary_rule), verify=bool(verify),
                 has_uv=bool(has_uv),
                 use_r5=bool(policy.r5_uv and has_uv and policy.placement == "memoryless"),
                 uv_fix=bool(policy.uv_correction and has_uv),
                 keep_parts=bool(policy.keep_parts), target=int(target_faces),
                 max_collapses=limit, max_move=float(policy.max_move) * WORKING_DIAGONAL,
                 move_memory=bool(policy.move_memory))


def _terms(policy: Policy, prep: _Prepared, borders, rules: Rules) -> Terms:
    """Inputs of the Canny and R^5 terms: texture borders, 1 / the total area at unit
    diagonal (the Canny penalty per unit area in ``canny_units="area"``; see
    :func:`_canny_units` for the other), κ per face."""
    P, F, FW, uv = prep.mesh.P, prep.mesh.F, prep.mesh.FW, prep.mesh.uv
    borders_arr = (np.ascontiguousarray(borders, dtype=np.bool_) if borders is not None
                   else np.zeros((1, 1), np.bool_))
    area = float(np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]),
                                axis=1).sum() / 2)
    inv_area = 1.0 / area if area > 0 else 0.0
    face_kappa = _face_kappa(P, F, FW, uv) if rules.use_r5 else np.ones(1)
    return Terms(borders=borders_arr, canny_per_area=inv_area, face_kappa=face_kappa)


def _canny_units(arrays: MeshArrays, rules: Rules, terms: Terms, images) -> tuple:
    """``terms`` with the Canny penalty in the base cost's units (``canny_units=
    "base-cost"``), and what was measured, for the statistics.

    Every edge of the mesh is costed once without the penalty, as the loop will queue
    it (:func:`methods.engine.initial.first_costs`). The penalty of equation 2 of
    González et al. 2007, the area ratio r_e = a_e / A_T (a_e the area of the edge's
    faces, A_T the mesh's), becomes r_e × c̄ / r̄: c̄ is the mean of the finite
    initial base costs and r̄ the mean of r_e over the same edges, so per unit of area
    the penalty is c̄ / ā (ā the mean a_e), and an edge of average area that crosses a
    border costs one average collapse more. Scaling the mesh by s multiplies a quadric
    cost by s⁴ (area-weighted squared distances), and so c̄ and the penalty, which is
    c̄ times a pure number: with a geometric base cost (no texture quadrics, whose UV
    terms do not scale with the mesh), cost and penalty keep their ratio whatever
    :data:`WORKING_DIAGONAL` (by a power of two, the chosen collapses are the same to
    the bit).

    A mesh whose base costs are all zero but for rounding (a box of flat faces with
    affine UVs: costs of ±1e-18 at unit diagonal) has no scale to measure. Base costs
    are never negative but by rounding, so the largest negative one's magnitude is the
    rounding noise of this mesh's costs; when c̄ is not above
    :data:`CANNY_NOISE_FACTOR` times it, the penalty is r_e / r̄, a pure number that
    alone orders the edges, as equation 2 does among equal costs."""
    base = rules._replace(weights=rules.weights._replace(canny=0.0))
    scratch = new_scratch(len(arrays.P))
    edges, costs, _, _ = first_costs(arrays, base, terms, scratch, images)
    areas = edge_areas(arrays, scratch, edges)
    finite = np.isfinite(costs)
    costs, areas = costs[finite], areas[finite]
    mean_cost = float(costs.mean()) if len(costs) else 0.0
    noise = max(0.0, -float(costs.min())) if len(costs) else 0.0
    mean_area = float(areas.mean()) if len(areas) else 0.0
    measured = mean_cost > 0.0 and mean_cost > CANNY_NOISE_FACTOR * noise
    if not mean_area > 0.0:
        per_area = 0.0
    elif measured:
        per_area = mean_cost / mean_area
    else:
        per_area = 1.0 / mean_area
    return terms._replace(canny_per_area=per_area), {
        "canny_base_cost": mean_cost if measured else 0.0,
        "canny_cost_noise": noise, "canny_edges_costed": len(costs)}


def _image_state(mesh: Mesh, image, a: MeshArrays, prep: _Prepared, texture_quadrics):
    """The image term's state with the original's images rendered, or placeholders of
    the same types without it."""
    if image is None:
        return Images(*dummy_state())
    if texture_quadrics:
        raise ValueError("the image term does not combine with texture quadrics")
    return Images(*image.state(mesh, a.P, a.F, a.FW, a.uv, a.falive, a.vhead, a.cnext,
                               a.valive, prep.lo, prep.scale))


def _statistics(n, evaluations, mismatches, rejects, kinds, verify, seconds) -> dict:
    """The run's counters as :attr:`EngineResult.stats`."""
    stats = {"collapses": int(n), "cost_evaluations": int(evaluations),
             "rejections": {name: int(c) for name, c in zip(REJECTIONS, rejects)},
             "engine_seconds": seconds,
             "collapses_per_second": n / seconds if seconds > 0 else None}
    # González et al. 2008, Algorithm 2: every collapse is a real edge; see _count_kinds
    stats.update(twin_collapses=int(kinds[KIND_TWIN]),
                 stranded_collapses=int(kinds[KIND_STRANDED]),
                 stranded_wedges=int(kinds[KIND_STRANDED_WEDGES]))
    if verify:
        stats["lazy_mismatches"] = int(mismatches)
    return stats


def _log_in_input_numbering(log, prep: _Prepared, a: MeshArrays, tiles=None):
    """The kernel's log trimmed to its collapses, in the input's vertex and face
    numbering and units, with the final quadrics and live vertices; merged wedges' UVs
    kept in their material's tile as in :func:`_extract`."""
    n, n_changed = int(log.count[LOG_COLLAPSES]), int(log.count[LOG_CHANGED])
    removed, kept, faces = log.removed[:n], log.kept[:n], log.faces[:n]
    changed, Q, valive = log.changed[:n_changed], a.Q, a.valive
    if prep.vperm is not None:  # back to the input's numbering
        vperm, fperm = prep.vperm, prep.fperm
        removed, kept = vperm[removed], vperm[kept]
        faces = np.where(faces >= 0, fperm[np.maximum(faces, 0)], -1)
        changed = fperm[changed]
        Q, valive = Q[np.argsort(vperm)], valive[np.argsort(vperm)]
    n_pairs, n_wedges = int(log.count[LOG_PAIRS]), int(log.count[LOG_WEDGES])
    out = {"removed": removed, "kept": kept, "position": log.pos[:n] * prep.scale + prep.lo,
           "removed_faces": faces, "changed_start": log.start[:n + 1],
           "changed_faces": changed, "cost": log.cost[:n],
           # wedges (render vertices) are never renumbered
           "pair_start": log.pair_start[:n + 1], "wedge_pairs": log.pairs[:n_pairs],
           "wedge_start": log.wedge_start[:n + 1], "wedges": log.wedges[:n_wedges],
           "wedge_uv": _in_tiles(log.wedge_uv[:n_wedges], log.wedges[:n_wedges], tiles)[0]}
    return out, Q, valive


def _morton(points: np.ndarray) -> np.ndarray:
    """Morton (Z-order) codes of points in the unit cube, 10 bits per axis."""
    q = np.clip((points * 1023.0).astype(np.int64), 0, 1023)
    code = np.zeros(len(points), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


def _extract(mesh: Mesh, P, faces_wedges, wedge_vertex, uv, tiles=None):
    """Render vertices from the surviving wedges: each keeps its attributes and takes
    the position of the welded vertex it now belongs to. Returns the mesh and how many
    UVs :func:`_in_tiles` moved back into their material's tile."""
    used, faces = np.unique(faces_wedges.reshape(-1), return_inverse=True)
    positions = P[wedge_vertex[used]]
    uv, clamped = (None, 0) if uv is None else _in_tiles(uv[used], used, tiles)
    return mesh.replace(
        positions=positions, faces=faces.reshape(-1, 3).astype(np.int32), uv=uv,
        colors=None if mesh.colors is None else mesh.colors[used],
        normals=None), clamped


def _in_tiles(uv: np.ndarray, wedges: np.ndarray, tiles):
    """``uv`` of ``wedges`` clamped into each wedge's material tile
    (:func:`bench.io.atlas.wedge_tiles`) on a mesh with several materials; unchanged
    otherwise. Returns the UVs and how many moved.

    The seam rule keeps each face's wedges within one material, but a merged wedge's
    new UV can leave its chart: the texture quadrics' minimiser, or an extrapolation
    along the edge, may lie beyond the chart's border, which in an atlas is another
    material's tile (on ``two-materials`` at 10 %, two faces near a pole sampled the
    other texture). The clamp keeps each wedge on its own material's texels."""
    if tiles is None:
        return uv, 0
    kept = np.clip(uv, tiles[wedges, :2], tiles[wedges, 2:])
    return kept, int((kept != uv).any(axis=1).sum())
