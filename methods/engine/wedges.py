"""Wedges (render vertices) across a collapse: seam vertices and seam edges, which
wedges merge, and the UV rules that give merged wedges their new texture coordinates
(interpolation along the edge, Lindstrom & Turk 2000's R^5 volumes, González et al.
2008's barycentric correction)."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.corners import corners
from methods.engine.state import KIND_STRANDED, KIND_STRANDED_WEDGES, KIND_TWIN
from methods.engine.topology import _edge_faces, _has_vertex


@njit(cache=True, _nrt=False)
def _is_seam_vertex(v, FW, vhead, cnext, falive):
    """True when the faces around v use more than one wedge for it."""
    first = -1
    for c in corners(v, vhead, cnext):
        if falive[c // 3]:
            w = FW[c // 3, c % 3]
            if first == -1:
                first = w
            elif w != first:
                return True
    return False


@njit(cache=True, _nrt=False)
def _is_seam_edge(u, v, F, FW, vhead, cnext, falive, efaces):
    """True when the edge's two faces use different wedges for one of its ends."""
    if _edge_faces(u, v, F, vhead, cnext, falive, efaces) != 2:
        return False
    fu, fv = corner_wedges(F, FW, efaces[0], u, v)
    gu, gv = corner_wedges(F, FW, efaces[1], u, v)
    return fu != gu or fv != gv


@njit(cache=True, _nrt=False)
def corner_wedges(F, FW, f, a, b):
    """The wedges of vertices ``a`` and ``b`` in face ``f`` (-1 when absent)."""
    wa = -1
    wb = -1
    for j in range(3):
        if F[f, j] == a:
            wa = FW[f, j]
        elif F[f, j] == b:
            wb = FW[f, j]
    return wa, wb


@njit(cache=True, _nrt=False)
def _wedge_pairs(u, v, fan, efaces, wmap_from, wmap_to):
    """The distinct pairs (wedge of u -> wedge of v) across the faces of edge (u, v):
    each side of the edge merges its own two wedges, into ``wmap_from``/``wmap_to``.
    Returns the number of pairs. ``fan`` is the mesh's (F, FW, vhead, cnext, falive).

    Off a seam both faces of the edge use the same two wedges, so they give one pair,
    not two: every caller adds a pair's wedge quadric (and interpolates its UV) once per
    pair, and a repeated pair would count the removed wedge twice. Counted twice at
    every collapse, a wedge quadric grows geometrically along a chain of collapses
    until rounding in its reduction over (u, v) swamps the geometry (costs of -1e14 on
    a textured box, whose corners then go first)."""
    F, FW, vhead, cnext, falive = fan
    k = _edge_faces(u, v, F, vhead, cnext, falive, efaces)
    npairs = 0
    for i in range(min(k, efaces.shape[0])):
        wu, wv = corner_wedges(F, FW, efaces[i], u, v)
        if wu == wv:
            continue
        seen = False
        for j in range(npairs):
            if wmap_from[j] == wu and wmap_to[j] == wv:
                seen = True
        if not seen and npairs < wmap_from.shape[0]:
            wmap_from[npairs] = wu
            wmap_to[npairs] = wv
            npairs += 1
    return npairs


@njit(cache=True, _nrt=False)
def _wedge_targets(u, v, fan, pairs, targets):
    """The distinct wedges the merged vertex of (u, v) will have after pairing
    (``pairs``: (wmap_from, wmap_to, npairs)), into ``targets``; returns their count.
    ``fan`` is the mesh's (F, FW, vhead, cnext, falive)."""
    _, FW, vhead, cnext, falive = fan
    wmap_from, wmap_to, npairs = pairs
    nt = 0
    for side in range(2):
        x = u if side == 0 else v
        for c in corners(x, vhead, cnext):
            f = c // 3
            if falive[f]:
                w = _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs)
                seen = False
                for i in range(nt):
                    if targets[i] == w:
                        seen = True
                if not seen:
                    if nt == targets.shape[0]:
                        raise ValueError("more distinct wedges around a collapse than "
                                         "WEDGE_TARGETS_CAP (methods.engine.state)")
                    targets[nt] = w
                    nt += 1
    return nt


@njit(cache=True)
def _edge_parameter(u, v, p, P):
    """Where p projects on the edge from u (0) to v (1), clamped."""
    e = P[v] - P[u]
    el2 = e[0] ** 2 + e[1] ** 2 + e[2] ** 2
    t = 0.5
    if el2 > 0.0:
        t = ((p[0] - P[u, 0]) * e[0] + (p[1] - P[u, 1]) * e[1] + (p[2] - P[u, 2]) * e[2]) / el2
        t = min(1.0, max(0.0, t))
    return t


@njit(cache=True, _nrt=False)
def _mapped(w, wmap_from, wmap_to, npairs):
    for i in range(npairs):
        if wmap_from[i] == w:
            return wmap_to[i]
    return w


@njit(cache=True)
def barycentric_uv(q, p1, p2, p3, t1, t2, t3, out):
    """González et al. 2008, §3 "Texture coordinates": the texture coordinates that the
    triangle (p1, p2, p3) with corner UVs (t1, t2, t3) gives the point ``q``.

    Q - P1 = α U + β V + γ N with U = P2 - P1, V = P3 - P1 and N = U × V; then
    T = α (T2 - T1) + β (T3 - T1) + T1 (γ, the offset along the normal, is dropped).
    As N is orthogonal to U and V, α and β solve the 2 × 2 Gram system
    [U·U U·V; U·V V·V] (α, β) = (Q'·U, Q'·V), the same solution as the paper's 3 × 3
    system. Writes ``out`` (2,) and returns min(α, β, 1 - α - β) (≥ 0: q projects
    inside the triangle), or -inf for a degenerate triangle."""
    ux, uy, uz = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
    vx, vy, vz = p3[0] - p1[0], p3[1] - p1[1], p3[2] - p1[2]
    qx, qy, qz = q[0] - p1[0], q[1] - p1[1], q[2] - p1[2]
    uu = ux * ux + uy * uy + uz * uz
    uv_ = ux * vx + uy * vy + uz * vz
    vv = vx * vx + vy * vy + vz * vz
    det = uu * vv - uv_ * uv_
    if not det > 1e-300 or det <= 1e-14 * uu * vv:
        return -np.inf
    qu = qx * ux + qy * uy + qz * uz
    qv = qx * vx + qy * vy + qz * vz
    alpha = (vv * qu - uv_ * qv) / det
    beta = (uu * qv - uv_ * qu) / det
    out[0] = alpha * (t2[0] - t1[0]) + beta * (t3[0] - t1[0]) + t1[0]
    out[1] = alpha * (t2[1] - t1[1]) + beta * (t3[1] - t1[1]) + t1[1]
    return min(alpha, beta, 1.0 - alpha - beta)


@njit(cache=True)
def _uv_correction(u, v, p, mesh, pairs, fix):
    """New UVs of the merged vertex's wedges by :func:`barycentric_uv` (González et al.
    2008, §3), before the collapse changes anything. A wedge whose vertex does not move
    (the kept end of a half-edge collapse) keeps its UV. For one that moves, the paper
    leaves open which "modified triangle" gives the new UV; we take, among the live
    triangles around the edge that use this wedge (or a wedge merging into it), the one
    in which the new position lies deepest (largest smallest barycentric coordinate), so
    a point inside one of them gets that triangle's exact UV. ``pairs`` is (wmap_from,
    wmap_to, npairs). Fills ``fix`` = (targets, new_uv, moved_t) (1: corrected); returns
    how many targets."""
    P, F, FW, falive, vhead, cnext, uv, wedge_vertex = (
        mesh.P, mesh.F, mesh.FW, mesh.falive, mesh.vhead, mesh.cnext, mesh.uv, mesh.wedge_vertex)
    wmap_from, wmap_to, npairs = pairs
    targets, new_uv, moved_t = fix
    nt = _wedge_targets(u, v, (F, FW, vhead, cnext, falive), pairs, targets)
    res = np.empty(2)
    for ti in range(nt):
        t = targets[ti]
        moved_t[ti] = 0
        x0 = wedge_vertex[t]
        if P[x0, 0] == p[0] and P[x0, 1] == p[1] and P[x0, 2] == p[2]:
            continue
        best = -np.inf
        for side in range(2):
            x = u if side == 0 else v
            for c in corners(x, vhead, cnext):
                f = c // 3
                if falive[f] and _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs) == t:
                    depth = barycentric_uv(p, P[F[f, 0]], P[F[f, 1]], P[F[f, 2]],
                                           uv[FW[f, 0]], uv[FW[f, 1]], uv[FW[f, 2]], res)
                    if depth > best:
                        best = depth
                        new_uv[ti, 0], new_uv[ti, 1] = res[0], res[1]
                        moved_t[ti] = 1
    return nt


@njit(cache=True)
def _count_kinds(u, v, fan, pairs, kinds):
    """González et al. 2008, Algorithm 2, in welded terms, for collapsing u into v:
    kinds[KIND_TWIN] += 1 when the edge's faces pair two different wedge pairs (the real
    edge and its *twin* at a seam or a sub-mesh joint collapse together);
    kinds[KIND_STRANDED] += 1 and kinds[KIND_STRANDED_WEDGES] += (their number) when
    wedges of u have no partner at v (the paper's disconnected vertices, which a *fake*
    edge or a translation brings to v). ``fan`` is the mesh's (F, FW, vhead, cnext,
    falive), ``pairs`` (wmap_from, wmap_to, npairs)."""
    F, FW, vhead, cnext, falive = fan
    wmap_from, wmap_to, npairs = pairs
    distinct = 0
    for i in range(npairs):
        seen = False
        for j in range(i):
            if wmap_from[j] == wmap_from[i] and wmap_to[j] == wmap_to[i]:
                seen = True
        if not seen:
            distinct += 1
    if distinct >= 2:
        kinds[KIND_TWIN] += 1
    stranded = 0
    first = np.full(16, -1, np.int64)
    for c in corners(u, vhead, cnext):
        f = c // 3
        if falive[f] and not _has_vertex(F, f, v):
            w = FW[f, c % 3]
            if _mapped(w, wmap_from, wmap_to, npairs) == w:
                seen = False
                for i in range(min(stranded, 16)):
                    if first[i] == w:
                        seen = True
                if not seen:
                    if stranded < 16:
                        first[stranded] = w
                    stranded += 1
    if stranded > 0:
        kinds[KIND_STRANDED] += 1
        kinds[KIND_STRANDED_WEDGES] += stranded
