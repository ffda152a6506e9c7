"""Cost and placement of one candidate collapse: the weighted sum of the policy's terms
(quadric, Lindstrom–Turk, Canny, image, entropy) at the placement's point, under the
seam and boundary rules."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from methods.engine.canny import _walk
from methods.engine.lindstrom_turk import lt_cost, lt_placement
from methods.engine.policy import (
    LT_ALPHA_DEG,
    LT_BOUNDARY_WEIGHT,
    LT_SHAPE_WEIGHT,
    LT_VOLUME_WEIGHT,
)
from methods.engine.quadrics import _add_reduced, _group_quadric, _optimal_point, quadric_error
from methods.engine.topology import _edge_faces, _gather_profile, _normal
from methods.engine.wedges import (
    _edge_parameter,
    _is_seam_edge,
    _is_seam_vertex,
    _r5_compute,
    _wedge_pairs,
    _wedge_targets,
    corner_wedges,
)
from methods.imaging.region import image_cost
from metrics.shading import BACKGROUND


@njit(cache=True)
def _evaluate(a, b, P, Q, F, FW, vhead, cnext, falive, vboundary, efaces, mark, tick, ws,
              placement, weights, seam_rule, boundary_rule, qsum, out_p, uv, borders, inv_area,
              no_record, WQ, tws, ictx):
    """Cost of collapsing edge (a, b) and where the kept vertex goes.

    ``weights`` = (quadric, memoryless, canny, image, entropy) cost-term weights; ``ws`` =
    the Lindstrom–Turk workspace (tri_a, tri_b, tri_c, bnd_a, bnd_b, link). Returns
    (cost, keep): keep is the vertex that survives (the other is removed), and the new
    position is written to ``out_p``. cost is +inf when the seam rule forbids the
    collapse.

    Seam rule (``seam_rule``), as vertex kinds: a seam vertex (two or more wedges) may
    only move along its seam. So an edge between a seam vertex and an ordinary one is a
    half-edge collapse onto the seam vertex, which stays where it is; an edge between two
    seam vertices must itself be a seam edge (else it would cut a UV chart in two), and
    may then be placed freely.

    Boundary rule (``boundary_rule``): likewise a boundary vertex is never merged into an
    interior one (the hole would grow into the surface); an edge from a boundary vertex
    to an interior one keeps the boundary vertex where it is.
    """
    w_q, w_lt = weights[0], weights[1]
    for i in range(10):
        qsum[i] = Q[a, i] + Q[b, i]
    if WQ.shape[0] > 1:  # Garland-Heckbert 1998: wedge quadrics over (x, y, z, u, v)
        gfrom, gto, targets, g = tws
        npairs = _wedge_pairs(a, b, F, FW, vhead, cnext, falive, efaces, gfrom, gto)
        nt = _wedge_targets(a, b, FW, vhead, cnext, falive, gfrom, gto, npairs, targets)
        for i in range(nt):
            _group_quadric(targets[i], WQ, gfrom, gto, npairs, g)
            _add_reduced(g, uv[targets[i]], qsum)
    forced = -1  # the vertex that must be kept, at its own position
    if seam_rule:
        sa = _is_seam_vertex(a, FW, vhead, cnext, falive)
        sb = _is_seam_vertex(b, FW, vhead, cnext, falive)
        if sa and sb:
            if not _is_seam_edge(a, b, F, FW, vhead, cnext, falive, efaces):
                out_p[:] = P[b]
                return np.inf, b
        elif sa:
            forced = a
        elif sb:
            forced = b
    if boundary_rule and vboundary[a] != vboundary[b]:  # the boundary end stays
        bkeep = a if vboundary[a] else b
        if forced != -1 and forced != bkeep:  # the seam rule wants the other end kept
            out_p[:] = P[b]
            return np.inf, b
        forced = bkeep
    tri_a, tri_b, tri_c, bnd_a, bnd_b, link = ws
    n_tris = n_bnd = n_link = 0
    l2 = ((P[a, 0] - P[b, 0]) ** 2 + (P[a, 1] - P[b, 1]) ** 2 + (P[a, 2] - P[b, 2]) ** 2)
    if w_lt != 0.0 or placement == 3:
        n_tris, n_bnd, n_link = _gather_profile(a, b, P, F, vhead, cnext, falive, vboundary,
                                                efaces, mark, tick, tri_a, tri_b, tri_c, bnd_a,
                                                bnd_b, link)
    canny = 0.0
    if weights[2] != 0.0:  # depends on the edge only, not on where the vertex goes
        canny = weights[2] * _canny_penalty(a, b, P, F, FW, uv, borders, vhead, cnext,
                                            falive, efaces, inv_area, no_record)
    keep = b
    if forced != -1:
        keep = forced
        out_p[:] = P[forced]
    elif placement == 1:  # endpoints: half-edge collapse, the cheaper direction
        ca = _cost_at(P[a], qsum, w_q, w_lt, tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris,
                      n_bnd, link, n_link, l2)
        cb = _cost_at(P[b], qsum, w_q, w_lt, tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris,
                      n_bnd, link, n_link, l2)
        if weights[3] != 0.0 or weights[4] != 0.0:
            ca += _view_cost(b, a, P[a], P, F, FW, uv, falive, vhead, cnext, efaces, weights,
                             ictx)
            cb += _view_cost(a, b, P[b], P, F, FW, uv, falive, vhead, cnext, efaces, weights,
                             ictx)
        keep = a if ca < cb else b
        out_p[:] = P[keep]
        return min(ca, cb) + canny, keep
    elif placement == 2:
        out_p[:] = 0.5 * (P[a] + P[b])
    elif placement == 3 and n_tris > 0:
        q, ok = lt_placement(tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris, n_bnd, link, n_link,
                             l2, LT_ALPHA_DEG, LT_VOLUME_WEIGHT, LT_BOUNDARY_WEIGHT)
        if ok:
            out_p[:] = q
        else:  # degenerate profile: the quadric's choice (Lindstrom & Turk fall back too)
            _optimal_point(qsum, P[a], P[b], out_p)
    else:
        _optimal_point(qsum, P[a], P[b], out_p)
    cost = _cost_at(out_p, qsum, w_q, w_lt, tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris,
                    n_bnd, link, n_link, l2) + canny
    if weights[3] != 0.0 or weights[4] != 0.0:
        cost += _view_cost(a if keep == b else b, keep, out_p, P, F, FW, uv, falive, vhead,
                           cnext, efaces, weights, ictx)
    return cost, keep


@njit(cache=True)
def _view_cost(u, v, p, P, F, FW, uv, falive, vhead, cnext, efaces, weights, ictx):
    """The rendered cost terms of collapsing u into v at p, from one re-render of the
    affected rectangles: ``weights[3]`` × equation 8 of Lindstrom & Turk 2000 plus
    ``weights[4]`` × the sum over views of |change of the viewpoint entropy| (González
    et al. 2008, §3), which :func:`methods.imaging.region.image_cost` leaves in the image
    state."""
    cost = weights[3] * _image_term(u, v, p, P, F, FW, uv, falive, vhead, cnext, efaces, ictx)
    if weights[4] != 0.0:
        cost += weights[4] * ictx[0][14][6][3]
    return cost


@njit(cache=True)
def _image_term(u, v, p, P, F, FW, uv, falive, vhead, cnext, efaces, ictx):
    """Equation 8 of Lindstrom & Turk 2000 for collapsing u into v at p, with the
    texture coordinates the collapse would give (methods.imaging.region.image_cost)."""
    img, tiles, iws, r5ws, face_kappa, use_r5, has_uv, wfrom, wto = ictx
    targets, new_uv = r5ws[6], r5ws[7]
    npairs = 0
    nt = 0
    if has_uv:
        npairs = _wedge_pairs(u, v, F, FW, vhead, cnext, falive, efaces, wfrom, wto)
        t_edge = _edge_parameter(u, v, p, P)
        if use_r5:
            nt = _r5_compute(u, v, p, P, F, FW, falive, vhead, cnext, uv, face_kappa, wfrom,
                             wto, npairs, t_edge, r5ws)
        else:  # merged wedges interpolated along the edge, as _collapse does
            for i in range(npairs):
                targets[i] = wto[i]
                for d in range(2):
                    new_uv[i, d] = (1.0 - t_edge) * uv[wfrom[i], d] + t_edge * uv[wto[i], d]
            nt = npairs
    return image_cost(u, v, p, P, F, FW, uv, falive, vhead, cnext, img, tiles, iws, wfrom,
                      wto, npairs, targets, nt, new_uv, float(BACKGROUND))


@njit(cache=True)
def _canny_penalty(a, b, P, F, FW, uv, borders, vhead, cnext, falive, efaces, inv_area,
                   no_record):
    """González et al. 2007, equations 1-2: (area of the edge's faces) / (total area)
    when the edge's UV segment, in any of its faces' charts, crosses a texture border;
    0 otherwise. ``inv_area`` is 1 / the original's total area (positions normalised)."""
    k = _edge_faces(a, b, F, vhead, cnext, falive, efaces)
    h, w = borders.shape
    crossing = False
    area = 0.0
    for i in range(min(k, efaces.shape[0])):
        f = efaces[i]
        wa, wb = corner_wedges(F, FW, f, a, b)
        if not crossing:
            _, hit = _walk(uv[wa, 0] * w, uv[wa, 1] * h, uv[wb, 0] * w, uv[wb, 1] * h,
                           borders, no_record)
            crossing = hit
        n = _normal(P[F[f, 0]], P[F[f, 1]], P[F[f, 2]])
        area += 0.5 * math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
    return area * inv_area if crossing else 0.0


@njit(cache=True)
def _cost_at(p, qsum, w_q, w_lt, tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris, n_bnd, link,
             n_link, l2):
    cost = 0.0
    if w_q != 0.0:
        cost += w_q * quadric_error(qsum, p)
    if w_lt != 0.0 and n_tris > 0:
        cost += w_lt * lt_cost(p, tri_a, tri_b, tri_c, bnd_a, bnd_b, n_tris, n_bnd, link,
                               n_link, l2, LT_VOLUME_WEIGHT, LT_BOUNDARY_WEIGHT,
                               LT_SHAPE_WEIGHT)
    return cost
