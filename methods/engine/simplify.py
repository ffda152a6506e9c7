"""The Python entry point :func:`simplify_mesh`: arrays at unit scale, the loop, and the
render vertices rebuilt from the surviving wedges."""

from __future__ import annotations

import math

import numpy as np

from bench.mesh import Mesh
from methods.engine.loop import _run
from methods.engine.policy import PLACEMENTS, REJECTIONS, EngineResult, Policy
from methods.engine.quadrics import _boundary_corners, initial_quadrics, wedge_quadrics
from methods.engine.topology import _corner_lists, vboundary_of
from methods.engine.wedges import _face_kappa
from methods.imaging.state import dummy_state


def simplify_mesh(mesh: Mesh, target_faces: int, policy: Policy = Policy(),
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
    Costs and quadrics are computed on positions normalised to a unit bounding-box
    diagonal; ``quadrics`` in the result are in those units.
    """
    import time

    if target_faces < 1:
        raise ValueError(f"target_faces must be at least 1, got {target_faces}")
    start = time.perf_counter()
    w = mesh.welded
    # Work on geometry normalised to a unit bounding-box diagonal, so that cost terms of
    # different kinds (quadric, Lindstrom-Turk, Canny area ratios) add up the same way
    # whatever the model's scale. Vertices that never move keep their exact input
    # positions in the output.
    P0 = w.positions.astype(np.float64)
    lo = P0.min(axis=0)
    scale = float(np.linalg.norm(P0.max(axis=0) - lo)) or 1.0
    P = (P0 - lo) / scale
    F = w.faces.astype(np.int64).copy()
    FW = mesh.faces.astype(np.int64).copy()
    wedge_vertex = w.vertex_of.astype(np.int64).copy()
    boundary_corners = _boundary_corners(mesh)
    nv = len(P)
    vboundary = vboundary_of(w, nv)
    vperm = fperm = None
    if image is not None:
        # Renumber vertices and faces along a Morton curve, so that the faces and
        # vertices of a screen region sit close together in memory (the image term
        # reads them per pixel rectangle); ids in the log are mapped back at the end.
        vperm = np.argsort(_morton(P), kind="stable")
        inverse = np.empty_like(vperm)
        inverse[vperm] = np.arange(nv)
        P0, P, vboundary = P0[vperm], P[vperm], vboundary[vperm]
        F, wedge_vertex = inverse[F], inverse[wedge_vertex]
        fperm = np.argsort(_morton(P[F].mean(axis=1)), kind="stable")
        F, FW, boundary_corners = F[fperm], FW[fperm], boundary_corners[fperm]
    falive = np.ones(len(F), bool)
    vhead, cnext = _corner_lists(F, nv)
    valive = np.zeros(nv, bool)
    valive[np.unique(F)] = True
    moved = np.zeros(nv, bool)
    has_uv = mesh.uv is not None
    uv = mesh.uv.copy() if has_uv else np.zeros((1, 2))
    if policy.canny_weight != 0.0 and (borders is None or not has_uv):
        raise ValueError("the Canny term needs texture borders and UVs; pass borders= "
                         "(methods.engine.canny.texture_borders) for a mesh with UVs")
    borders_arr = (np.ascontiguousarray(borders, dtype=np.bool_) if borders is not None
                   else np.zeros((1, 1), np.bool_))
    area = float(np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]),
                                axis=1).sum() / 2)
    inv_area = 1.0 / area if area > 0 else 0.0

    texture_quadrics = policy.texture_weight > 0 and has_uv and policy.quadric_weight != 0
    Q = initial_quadrics(P, F, boundary_corners, policy.boundary_weight,
                         faces=not texture_quadrics)
    WQ = (wedge_quadrics(P, F, FW, uv, policy.texture_weight) if texture_quadrics
          else np.zeros((1, 31)))

    use_r5 = bool(policy.r5_uv and has_uv and policy.placement == "memoryless")
    face_kappa = _face_kappa(P, F, FW, uv) if use_r5 else np.ones(1)
    cos_limit = math.cos(math.radians(policy.max_normal_rotation))
    weights = np.array([policy.quadric_weight, policy.memoryless_weight, policy.canny_weight,
                        0.0 if image is None else image.weight,
                        0.0 if image is None else getattr(image, "entropy_weight", 0.0)],
                       np.float64)
    if image is None:
        img, tiles, iws = dummy_state()
    else:
        if texture_quadrics:
            raise ValueError("the image term does not combine with texture quadrics")
        img, tiles, iws = image.state(mesh, P, F, FW, uv, falive, vhead, cnext, valive, lo,
                                      scale)
    limit = max(1, nv) if max_collapses is None else max(0, int(max_collapses))
    kinds = np.zeros(3, np.int64)
    out = _run(P, Q, F, FW, falive, vhead, cnext, valive, vboundary, wedge_vertex,
               uv, has_uv, int(target_faces), PLACEMENTS[policy.placement], weights, cos_limit,
               bool(policy.boundary_lock),
               bool(policy.seam_rule and mesh.n_vertices != w.n_vertices),
               bool(policy.boundary_rule), bool(verify),
               limit, borders_arr, inv_area, moved, use_r5, face_kappa, WQ, img, tiles, iws,
               bool(policy.uv_correction and has_uv), kinds)
    (stopped, n, evaluations, mismatches, rejects, log_removed, log_kept, log_pos,
     log_faces, log_start, log_changed, log_cost) = out
    image_stats = {} if image is None else image.statistics(
        mesh, img, verify, P, F, FW, uv, falive, vhead, cnext, valive, lo, scale)
    P = np.where(moved[:, None], P * scale + lo, P0)

    simplified = _extract(mesh, P, FW[falive], wedge_vertex, uv if has_uv else None)
    faces = int(falive.sum())
    reason = None
    if stopped:
        counts = ", ".join(f"{name} {int(c)}" for name, c in zip(REJECTIONS, rejects) if c)
        reason = (f"no valid collapse remains at {faces} faces (target {target_faces}); "
                  f"candidates rejected: {counts or 'none'}")
    seconds = time.perf_counter() - start
    stats = {"collapses": int(n), "cost_evaluations": int(evaluations),
             "rejections": {name: int(c) for name, c in zip(REJECTIONS, rejects)},
             "engine_seconds": seconds,
             "collapses_per_second": n / seconds if seconds > 0 else None}
    # González et al. 2008, Algorithm 2: every collapse is a real edge; see _count_kinds
    stats.update(twin_collapses=int(kinds[0]), stranded_collapses=int(kinds[1]),
                 stranded_wedges=int(kinds[2]))
    if verify:
        stats["lazy_mismatches"] = int(mismatches)
    stats.update(image_stats)
    if vperm is not None:  # back to the input's numbering
        log_removed, log_kept = vperm[log_removed], vperm[log_kept]
        log_faces = np.where(log_faces >= 0, fperm[np.maximum(log_faces, 0)], -1)
        log_changed = fperm[log_changed]
        Q, valive = Q[np.argsort(vperm)], valive[np.argsort(vperm)]
    log = {"removed": log_removed, "kept": log_kept, "position": log_pos * scale + lo,
           "removed_faces": log_faces, "changed_start": log_start,
           "changed_faces": log_changed, "cost": log_cost}
    return EngineResult(simplified, reason, stats, log, quadrics=Q, vertex_alive=valive,
                        images=None if image is None else img[4])


def _morton(points: np.ndarray) -> np.ndarray:
    """Morton (Z-order) codes of points in the unit cube, 10 bits per axis."""
    q = np.clip((points * 1023.0).astype(np.int64), 0, 1023)
    code = np.zeros(len(points), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((q[:, axis] >> bit) & 1) << (3 * bit + axis)
    return code


def _extract(mesh: Mesh, P, faces_wedges, wedge_vertex, uv) -> Mesh:
    """Render vertices from the surviving wedges: each keeps its attributes and takes
    the position of the welded vertex it now belongs to."""
    used, faces = np.unique(faces_wedges.reshape(-1), return_inverse=True)
    positions = P[wedge_vertex[used]]
    return mesh.replace(
        positions=positions, faces=faces.reshape(-1, 3).astype(np.int32),
        uv=None if uv is None else uv[used],
        colors=None if mesh.colors is None else mesh.colors[used],
        normals=None)
