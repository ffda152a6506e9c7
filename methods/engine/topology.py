"""Welded topology in flat arrays: per-vertex corner lists, neighbours, the faces of an
edge, and the validity checks of a collapse (link condition, boundary pinch, duplicate
faces, fold-over, non-manifold edges, boundary lock)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.policy import (
    REJECT_BOUNDARY_LOCK,
    REJECT_BOUNDARY_PINCH,
    REJECT_DUPLICATE_FACE,
    REJECT_FOLD_OVER,
    REJECT_LINK_CONDITION,
    REJECT_NON_MANIFOLD,
    VALID,
)


@njit(cache=True, _nrt=False)
def _compact(v, vhead, cnext, falive):
    prev = -1
    c = vhead[v]
    while c != -1:
        nxt = cnext[c]
        if not falive[c // 3]:
            if prev == -1:
                vhead[v] = nxt
            else:
                cnext[prev] = nxt
        else:
            prev = c
        c = nxt


@njit(cache=True, _nrt=False)
def _neighbors(v, F, vhead, cnext, falive, mark, tick, out):
    """Distinct neighbours of v into ``out``; returns their count. ``mark``/``tick``
    deduplicate without clearing (tick[0] is bumped per call)."""
    tick[0] += 1
    t = tick[0]
    mark[v] = t
    n = 0
    for c in corners(v, vhead, cnext):
        f = c // 3
        if falive[f]:
            for k in range(3):
                w = F[f, k]
                if mark[w] != t:
                    mark[w] = t
                    out[n] = w
                    n += 1
    return n


@njit(cache=True, _nrt=False)
def _edge_faces(u, v, F, vhead, cnext, falive, out):
    """Alive faces containing both u and v, into ``out``; returns the count."""
    n = 0
    for c in corners(u, vhead, cnext):
        f = c // 3
        if falive[f] and (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v):
            if n < out.shape[0]:
                out[n] = f
            n += 1
    return n


@njit(cache=True)
def _faces_area(k, faces, P, F):
    """The summed area of the first ``k`` faces listed in ``faces`` (at most its
    length), added in list order."""
    area = 0.0
    for i in range(min(k, faces.shape[0])):
        f = faces[i]
        n = _normal(P[F[f, 0]], P[F[f, 1]], P[F[f, 2]])
        area += 0.5 * math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
    return area


@njit(cache=True)
def _candidate_edges(mesh, efaces):
    """Every edge of the mesh once, as the loop first costs them: each interior edge
    from its smaller end, each boundary edge from its only face, in face order;
    ``(e, 2)`` int64 (``efaces`` is scratch)."""
    F = mesh.F
    edges = np.empty((3 * F.shape[0], 2), np.int64)
    n = 0
    for f in range(F.shape[0]):
        if not mesh.falive[f]:
            continue
        for j in range(3):
            a, b = F[f, j], F[f, (j + 1) % 3]
            if a < b or _edge_faces(a, b, F, mesh.vhead, mesh.cnext, mesh.falive,
                                    efaces) == 1:
                edges[n, 0], edges[n, 1] = a, b
                n += 1
    return edges[:n]


@njit(cache=True, _nrt=False)
def _third(F, f, a, b):
    for k in range(3):
        w = F[f, k]
        if w != a and w != b:
            return w
    return -1


@njit(cache=True)
def _normal(pa, pb, pc):
    return np.cross(pb - pa, pc - pa)


@njit(cache=True, _nrt=False)
def _normal3(a, b, c):
    """(b - a) x (c - a) from 3-tuples of scalars: no temporary arrays in the hot loop."""
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = a, b, c
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    return uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@njit(cache=True, _nrt=False)
def _check(u, v, p, P, links, vboundary, work, limits):
    """VALID if collapsing u into v at p is valid, else the REJECT_* code of the first
    rule it breaks (methods.engine.policy lists the rules), one helper per rule.
    ``links`` is the mesh's (F, vhead, cnext, falive), ``work`` the scratch's (mark,
    tick, nbr_u, nbr_v, efaces), ``limits`` the rules' (cos_limit, boundary_lock): the
    arrays it reads, not the structures, whose every array a call would pass.

    The faces that move are tested in turn, u's each for a duplicate and then a
    fold-over, then v's for a fold-over, so the first face that breaks a rule names the
    rejection."""
    (F, vhead, cnext, falive), cos_limit = links, limits[0]
    k = _edge_faces(u, v, F, vhead, cnext, falive, work[4])
    if k > 2 or k == 0:
        return REJECT_NON_MANIFOLD  # (k == 0 cannot happen for a live edge)
    if not _link_condition(u, v, k, links, work):
        return REJECT_LINK_CONDITION
    code = _boundary_rule(u, v, k, vboundary, limits[1])
    if code != VALID:
        return code
    for side in range(2):
        x = u if side == 0 else v
        y = v if side == 0 else u
        for c in corners(x, vhead, cnext):
            f = c // 3
            if falive[f] and not (F[f, 0] == y or F[f, 1] == y or F[f, 2] == y):
                if side == 0 and _makes_duplicate(f, u, v, links):
                    return REJECT_DUPLICATE_FACE
                if _folds_over(f, x, p, P, F, cos_limit):
                    return REJECT_FOLD_OVER
    return VALID


@njit(cache=True, _nrt=False, inline="always")
def _link_condition(u, v, k, links, work):
    """The link condition: u and v share exactly the k neighbours of the k faces on
    their edge. Leaves v's neighbours marked in ``work``."""
    (F, vhead, cnext, falive), (mark, tick, nbr_u, nbr_v, _) = links, work
    nu = _neighbors(u, F, vhead, cnext, falive, mark, tick, nbr_u)
    _neighbors(v, F, vhead, cnext, falive, mark, tick, nbr_v)  # mark now holds v's
    t = tick[0]
    common = 0
    for i in range(nu):
        w = nbr_u[i]
        if w != v and w != u and mark[w] == t:
            common += 1
    return common == k


@njit(cache=True, _nrt=False, inline="always")
def _boundary_rule(u, v, k, vboundary, boundary_lock):
    """REJECT_BOUNDARY_LOCK for a boundary end under the lock, REJECT_BOUNDARY_PINCH for
    an interior edge (k = 2 faces) joining two boundary vertices, else VALID."""
    if boundary_lock or k == 2:
        bu = vboundary[u]
        bv = vboundary[v]
        if boundary_lock and (bu or bv):
            return REJECT_BOUNDARY_LOCK
        if k == 2 and bu and bv:
            return REJECT_BOUNDARY_PINCH
    return VALID


@njit(cache=True, _nrt=False, inline="always")
def _makes_duplicate(f, u, v, links):
    """True when u's face f (not on the edge) becomes a duplicate of one of v's faces
    once u is renamed v: a face of v (not on the edge) has f's two other vertices."""
    F, vhead, cnext, falive = links
    a = -1
    b = -1
    for j in range(3):
        if F[f, j] != u:
            if a == -1:
                a = F[f, j]
            else:
                b = F[f, j]
    for c2 in corners(v, vhead, cnext):
        g = c2 // 3
        if falive[g] and not (F[g, 0] == u or F[g, 1] == u or F[g, 2] == u):
            if ((F[g, 0] == a or F[g, 1] == a or F[g, 2] == a)
                    and (F[g, 0] == b or F[g, 1] == b or F[g, 2] == b)):
                return True
    return False


@njit(cache=True, _nrt=False, inline="always")
def _folds_over(f, x, p, P, F, cos_limit):
    """True when face f, with its vertex x moved to p, degenerates or turns its normal
    by more than the angle whose cosine is ``cos_limit``."""
    i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
    b0, b1, b2 = _normal3((P[i0, 0], P[i0, 1], P[i0, 2]), (P[i1, 0], P[i1, 1], P[i1, 2]),
                          (P[i2, 0], P[i2, 1], P[i2, 2]))
    if i0 == x:  # the same triangle with x moved to p
        a0, a1, a2 = _normal3((p[0], p[1], p[2]), (P[i1, 0], P[i1, 1], P[i1, 2]),
                              (P[i2, 0], P[i2, 1], P[i2, 2]))
    elif i1 == x:
        a0, a1, a2 = _normal3((P[i0, 0], P[i0, 1], P[i0, 2]), (p[0], p[1], p[2]),
                              (P[i2, 0], P[i2, 1], P[i2, 2]))
    else:
        a0, a1, a2 = _normal3((P[i0, 0], P[i0, 1], P[i0, 2]),
                              (P[i1, 0], P[i1, 1], P[i1, 2]), (p[0], p[1], p[2]))
    lb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    la = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    if la <= 1e-12 * lb or la == 0.0:
        return True
    return lb > 0.0 and (b0 * a0 + b1 * a1 + b2 * a2) / (la * lb) < cos_limit


@njit(cache=True, _nrt=False)
def _gather_profile(a, b, P, links, vboundary, work, pr):
    """The Lindstrom–Turk profile of edge (a, b) into ``pr``
    (:data:`methods.engine.state.Profile`): triangles around either end, their boundary
    edges (oriented as in the triangle) and the link vertices, with their counts, or
    counts (-1, 0, 0) when the workspace is too small. ``links`` is the mesh's (F, vhead,
    cnext, falive), ``work`` the scratch's (efaces, mark, tick)."""
    (F, vhead, cnext, falive), (efaces, mark, tick) = links, work
    tri_a, tri_b, tri_c, bnd_a, bnd_b, link = (pr.tri_a, pr.tri_b, pr.tri_c, pr.bnd_a,
                                               pr.bnd_b, pr.link)
    counts = pr.counts
    counts[0], counts[1], counts[2] = -1, 0, 0  # until gathered: too large
    cap = tri_a.shape[0]
    n_tris = 0
    n_bnd = 0
    n_link = 0
    tick[0] += 1
    t = tick[0]
    mark[a] = t
    mark[b] = t
    for side in range(2):
        x = a if side == 0 else b
        y = b if side == 0 else a
        for c in corners(x, vhead, cnext):
            f = c // 3
            if falive[f]:
                has_y = F[f, 0] == y or F[f, 1] == y or F[f, 2] == y
                if side == 0 or not has_y:  # faces of the edge are counted once
                    if n_tris == cap:
                        return
                    f0, f1, f2 = F[f, 0], F[f, 1], F[f, 2]
                    for d in range(3):  # scalar copies: no temporary views per row
                        tri_a[n_tris, d] = P[f0, d]
                        tri_b[n_tris, d] = P[f1, d]
                        tri_c[n_tris, d] = P[f2, d]
                    n_tris += 1
                    for j in range(3):
                        i0, i1 = F[f, j], F[f, (j + 1) % 3]
                        if (i0 == a or i0 == b or i1 == a or i1 == b) and \
                                vboundary[i0] and vboundary[i1] and \
                                _edge_faces(i0, i1, F, vhead, cnext, falive, efaces) == 1:
                            if n_bnd == cap:
                                return
                            for d in range(3):
                                bnd_a[n_bnd, d] = P[i0, d]
                                bnd_b[n_bnd, d] = P[i1, d]
                            n_bnd += 1
                    for j in range(3):
                        w = F[f, j]
                        if mark[w] != t:
                            mark[w] = t
                            if n_link == cap:
                                return
                            for d in range(3):
                                link[n_link, d] = P[w, d]
                            n_link += 1
    counts[0], counts[1], counts[2] = n_tris, n_bnd, n_link


@njit(cache=True, _nrt=False)
def _has_vertex(F, f, x):
    return F[f, 0] == x or F[f, 1] == x or F[f, 2] == x


def vboundary_of(w, nv: int) -> np.ndarray:
    """(nv,) bool: welded vertices on a boundary edge."""
    flags = np.zeros(nv, bool)
    flags[w.edges[w.boundary].reshape(-1)] = True
    return flags
