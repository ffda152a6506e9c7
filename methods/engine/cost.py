"""Cost and placement of one candidate collapse: the weighted sum of the policy's terms
(quadric, Lindstrom–Turk, Canny, image, entropy) at the placement's point, under the
seam and boundary rules."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.capacity import over_capacity
from methods.engine.policy import (
    BOUNDARY_RULE,
    END_FREE,
    END_KEEP_FIRST,
    END_KEEP_SECOND,
    END_SEAM_EDGE,
    PLACE_ENDPOINTS,
    PLACE_MEMORYLESS,
    PLACE_MIDPOINT,
    SEAM_RULE,
    VERTEX_BOUNDARY,
    VERTEX_INTERIOR,
    VERTEX_ORDINARY,
    VERTEX_SEAM,
)
from methods.engine.state import renders
from methods.engine.terms.canny import _canny_penalty
from methods.engine.terms.lindstrom_turk import (
    ALPHA_DEG,
    BOUNDARY_WEIGHT,
    SHAPE_WEIGHT,
    VOLUME_WEIGHT,
    lt_cost,
    lt_placement,
)
from methods.engine.terms.quadric import _edge_quadric, _optimal_point, best_of_ends, quadric_error
from methods.engine.terms.rendered import _both_ways, _view_cost
from methods.engine.topology import _gather_profile
from methods.engine.wedges import _is_seam_edge, _is_seam_vertex


@njit(cache=True, inline="always")
def _evaluate(a, b, mesh, rules, terms, scratch, images):
    """Cost of collapsing edge (a, b) and where the kept vertex goes.

    ``mesh``, ``rules``, ``terms``, ``scratch`` and ``images`` are the structures of
    :mod:`methods.engine.state`. Returns (cost, keep): keep is the vertex that survives
    (the other is removed), and the new position is written to ``scratch.p``. cost is
    +inf when the seam or boundary rule forbids the collapse, or when it does not fit
    the engine's workspaces (:mod:`methods.engine.capacity`).

    The steps: the summed quadric (:func:`_edge_quadric`), the vertex the rules force
    to stay (:func:`_forced_end`), the Lindstrom–Turk profile when a term or the
    placement needs it, the Canny term (edge only), then the placement
    (:func:`_place`, or the cheaper end, :func:`_cheaper_end`) and the cost there.
    """
    P, out_p = mesh.P, scratch.p
    if over_capacity(a, b, mesh, rules, scratch):  # the capacity rule (capacity.py)
        out_p[:] = P[b]
        return np.inf, b
    _edge_quadric(a, b, mesh, scratch)
    forced = _forced_end(a, b, mesh, rules, scratch)
    if forced == -2:  # forbidden
        out_p[:] = P[b]
        return np.inf, b
    # The profile (and its counts) is read only where it is gathered: under the same
    # condition, by _cost_at and _place.
    weights = rules.weights
    l2 = ((P[a, 0] - P[b, 0]) ** 2 + (P[a, 1] - P[b, 1]) ** 2 + (P[a, 2] - P[b, 2]) ** 2)
    if weights.memoryless != 0.0 or rules.placement == PLACE_MEMORYLESS:
        _gather_profile(a, b, P, (mesh.F, mesh.vhead, mesh.cnext, mesh.falive), mesh.vboundary,
                        (scratch.efaces, scratch.mark, scratch.tick), scratch.profile)
    canny = 0.0
    if weights.canny != 0.0:  # depends on the edge only, not on where the vertex goes
        surface = (P, mesh.F, mesh.FW, mesh.uv, mesh.falive, mesh.vhead, mesh.cnext)
        canny = weights.canny * _canny_penalty(a, b, surface, terms.borders,
                                               terms.canny_per_area, scratch.efaces,
                                               scratch.no_record)
    if forced == -1 and rules.placement == PLACE_ENDPOINTS:
        cost, keep = _cheaper_end(a, b, l2, mesh, rules, terms, scratch, images)
        return cost + canny, keep
    keep = _place(a, b, forced, l2, mesh, rules, scratch)
    cost = _cost_at(out_p, scratch.qsum, weights, scratch.profile, l2) + canny
    if renders(weights):
        cost += _view_cost((a if keep == b else b, keep, out_p), mesh, rules, terms, scratch,
                           images, np.inf)
    return cost, keep


@njit(cache=True, inline="always")
def _forced_end(a, b, mesh, rules, scratch):
    """The vertex the rules keep at its own position (-1: none; -2: the collapse is
    forbidden), from the ends' vertex kinds and the rule tables of
    :mod:`methods.engine.policy` (``SEAM_RULE``, ``BOUNDARY_RULE``; the rules in prose
    are there)."""
    F, FW, vhead, cnext, falive = mesh.F, mesh.FW, mesh.vhead, mesh.cnext, mesh.falive
    forced = -1
    if rules.seam_rule:
        ka = VERTEX_SEAM if _is_seam_vertex(a, FW, vhead, cnext, falive) else VERTEX_ORDINARY
        kb = VERTEX_SEAM if _is_seam_vertex(b, FW, vhead, cnext, falive) else VERTEX_ORDINARY
        verdict = SEAM_RULE[ka, kb]
        if verdict == END_SEAM_EDGE:
            if not _is_seam_edge(a, b, F, FW, vhead, cnext, falive, scratch.efaces):
                return -2
        elif verdict == END_KEEP_FIRST:
            forced = a
        elif verdict == END_KEEP_SECOND:
            forced = b
    if rules.boundary_rule:
        ka = VERTEX_BOUNDARY if mesh.vboundary[a] else VERTEX_INTERIOR
        kb = VERTEX_BOUNDARY if mesh.vboundary[b] else VERTEX_INTERIOR
        verdict = BOUNDARY_RULE[ka, kb]
        if verdict != END_FREE:
            keep = a if verdict == END_KEEP_FIRST else b
            if forced != -1 and forced != keep:  # the seam rule keeps the other end
                return -2
            forced = keep
    return forced


@njit(cache=True, inline="always")
def _cheaper_end(a, b, l2, mesh, rules, terms, scratch, images):
    """The half-edge collapse of (a, b) in its cheaper direction, for :func:`_evaluate`:
    (cost without the Canny term, the kept end), whose position goes into ``scratch.p``."""
    P, qsum, pr, weights = mesh.P, scratch.qsum, scratch.profile, rules.weights
    ca = _cost_at(P[a], qsum, weights, pr, l2)
    cb = _cost_at(P[b], qsum, weights, pr, l2)
    if renders(weights):
        ca, cb = _both_ways(a, b, (ca, cb), mesh, rules, terms, scratch, images)
    keep = a if ca < cb else b
    scratch.p[:] = P[keep]
    return min(ca, cb), keep


@njit(cache=True, inline="always")
def _place(a, b, forced, l2, mesh, rules, scratch):
    """Where the kept vertex of (a, b) goes (into ``scratch.p``), by the end the rules
    force to stay or by the policy's placement; returns the kept vertex."""
    P, out_p, qsum, placement = mesh.P, scratch.p, scratch.qsum, rules.placement
    if forced != -1:
        out_p[:] = P[forced]
        return forced
    if placement == PLACE_MIDPOINT:
        out_p[:] = 0.5 * (P[a] + P[b])
    elif placement == PLACE_MEMORYLESS and scratch.profile.counts[0] > 0:
        q, ok = lt_placement(scratch.profile, l2, ALPHA_DEG, VOLUME_WEIGHT, BOUNDARY_WEIGHT)
        if ok and _near_ring(a, b, l2, mesh, q, LT_RING_BOX_MARGIN):
            out_p[:] = q
        else:  # degenerate profile, or a point far off (the placement guard): the
            # quadric's choice (Lindstrom & Turk fall back to it too)
            _guarded_optimal_point(a, b, l2, mesh, qsum, out_p)
    else:  # optimal, or no profile to place by (counts[0] <= 0: empty, or too large)
        _guarded_optimal_point(a, b, l2, mesh, qsum, out_p)
    return b


#: How far beyond the bounding box of an edge's one-ring the quadric's minimiser may lie,
#: as a fraction of the edge's length (the placement guard, :func:`_near_ring`).
RING_BOX_MARGIN = 0.25
#: The same for Lindstrom & Turk's point, which keeps the volume and so lies farther out
#: on curved parts (a quarter of the edge made memoryless 1.4 % worse on the bunny at
#: 562 faces; the truck's stray points lay 3.7 and 4.4 edge lengths out).
LT_RING_BOX_MARGIN = 1.0


@njit(cache=True, _nrt=False)
def _near_ring(a, b, l2, mesh, p, factor):
    """True when ``p`` lies within the bounding box of the vertices of the faces around
    a and b enlarged by ``factor`` times the edge's length (the placement guard:
    :data:`RING_BOX_MARGIN`, :data:`LT_RING_BOX_MARGIN`).

    A placement on a smooth surface lies within a small fraction of the edge's length of
    its one-ring. On a multi-part asset neither the quadric's minimiser (its own guard,
    within one edge length of the midpoint, is no bound on a long edge: on the glTF milk
    truck a 1.7-unit edge along the body's bottom rim had it 1.6 units below the body)
    nor Lindstrom & Turk's constrained point (3 units off a 0.7-unit edge of a small
    part, on the same truck) always does."""
    P = mesh.P
    margin = factor * np.sqrt(l2)
    # the ring's box holds both ends: a point within the ends' box needs no walk
    if (min(P[a, 0], P[b, 0]) - margin <= p[0] <= max(P[a, 0], P[b, 0]) + margin
            and min(P[a, 1], P[b, 1]) - margin <= p[1] <= max(P[a, 1], P[b, 1]) + margin
            and min(P[a, 2], P[b, 2]) - margin <= p[2] <= max(P[a, 2], P[b, 2]) + margin):
        return True
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    for side in range(2):
        for c in corners(a if side == 0 else b, mesh.vhead, mesh.cnext):
            f = c // 3
            if mesh.falive[f]:
                for j in range(3):
                    x = mesh.F[f, j]
                    lo0, hi0 = min(lo0, P[x, 0]), max(hi0, P[x, 0])
                    lo1, hi1 = min(lo1, P[x, 1]), max(hi1, P[x, 1])
                    lo2, hi2 = min(lo2, P[x, 2]), max(hi2, P[x, 2])
    return (lo0 - margin <= p[0] <= hi0 + margin and lo1 - margin <= p[1] <= hi1 + margin
            and lo2 - margin <= p[2] <= hi2 + margin)


@njit(cache=True, _nrt=False)
def _guarded_optimal_point(a, b, l2, mesh, qsum, out_p):
    """The quadric's minimiser for edge (a, b) (:func:`_optimal_point`), unless it fails
    the placement guard (:func:`_near_ring`): then the best of the endpoints and the
    midpoint, as for an ill-conditioned quadric."""
    P = mesh.P
    _optimal_point(qsum, P[a], P[b], out_p)
    if not _near_ring(a, b, l2, mesh, out_p, RING_BOX_MARGIN):
        best_of_ends(qsum, P[a], P[b], out_p)


@njit(cache=True, _nrt=False, inline="always")
def _cost_at(p, qsum, weights, pr, l2):
    """The quadric and Lindstrom–Turk terms of a collapse to ``p``, weighted: the
    summed quadric ``qsum``, the edge's profile ``pr`` and squared length ``l2``.
    Inlined: called with the profile's seven arrays, it cost the re-costing of the
    loop's requeue a few per cent (docs/experiments.md)."""
    cost = 0.0
    if weights.quadric != 0.0:
        cost += weights.quadric * quadric_error(qsum, p)
    if weights.memoryless != 0.0 and pr.counts[0] > 0:
        cost += weights.memoryless * lt_cost(p, pr, l2, VOLUME_WEIGHT, BOUNDARY_WEIGHT,
                                             SHAPE_WEIGHT)
    return cost
