"""Quadric error metrics: Garland & Heckbert 1997 plane quadrics per vertex (with
boundary planes) and their 1998 quadrics over (x, y, z, u, v) per wedge."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.core.mesh import Mesh
from methods.engine.state import QUADRIC_SIZE
from methods.engine.wedges import _wedge_pairs, _wedge_targets


@njit(cache=True, _nrt=False)
def _plane_quadric(q, n, d, weight):
    a, b, c = n[0], n[1], n[2]
    q[0] += weight * a * a
    q[1] += weight * a * b
    q[2] += weight * a * c
    q[3] += weight * a * d
    q[4] += weight * b * b
    q[5] += weight * b * c
    q[6] += weight * b * d
    q[7] += weight * c * c
    q[8] += weight * c * d
    q[9] += weight * d * d


@njit(cache=True, _nrt=False)
def quadric_error(q, p):
    """[p 1] Q [p 1]^T for a 10-float quadric ``q`` and a point ``p`` (3,)."""
    x, y, z = p[0], p[1], p[2]
    return (q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x
            + q[4] * y * y + 2 * q[5] * y * z + 2 * q[6] * y
            + q[7] * z * z + 2 * q[8] * z + q[9])


@njit(cache=True)
def face_quadrics(P, F, alive):
    """Per-vertex quadrics (nv, 10) of area-weighted face planes (Garland & Heckbert
    1997 §5); boundary planes are added by _add_boundary_quadrics."""
    nv = P.shape[0]
    Q = np.zeros((nv, 10))
    n = np.empty(3)
    for f in range(F.shape[0]):
        if not alive[f]:
            continue
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        e1 = P[b] - P[a]
        e2 = P[c] - P[a]
        n[0] = e1[1] * e2[2] - e1[2] * e2[1]
        n[1] = e1[2] * e2[0] - e1[0] * e2[2]
        n[2] = e1[0] * e2[1] - e1[1] * e2[0]
        length = math.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
        if length == 0.0:
            continue
        area = 0.5 * length
        n /= length
        d = -(n[0] * P[a, 0] + n[1] * P[a, 1] + n[2] * P[a, 2])
        for k in range(3):
            _plane_quadric(Q[F[f, k]], n, d, area)
    return Q


@njit(cache=True)
def _add_boundary_quadrics(Q, P, F, alive, is_boundary_corner, weight):
    """Add the §6.1 boundary planes; ``is_boundary_corner[f, k]`` marks the edge from
    corner k to corner k+1 of face f as a boundary edge."""
    m = np.empty(3)
    for f in range(F.shape[0]):
        if not alive[f]:
            continue
        a, b, c = P[F[f, 0]], P[F[f, 1]], P[F[f, 2]]
        fn = np.cross(b - a, c - a)
        fl = math.sqrt(fn[0] ** 2 + fn[1] ** 2 + fn[2] ** 2)
        if fl == 0.0:
            continue
        fn /= fl
        for k in range(3):
            if not is_boundary_corner[f, k]:
                continue
            i, j = F[f, k], F[f, (k + 1) % 3]
            e = P[j] - P[i]
            el2 = e[0] ** 2 + e[1] ** 2 + e[2] ** 2
            if el2 == 0.0:
                continue
            m[:] = np.cross(e, fn)
            m /= math.sqrt(m[0] ** 2 + m[1] ** 2 + m[2] ** 2)
            d = -(m[0] * P[i, 0] + m[1] * P[i, 1] + m[2] * P[i, 2])
            _plane_quadric(Q[i], m, d, weight * el2)
            _plane_quadric(Q[j], m, d, weight * el2)


@njit(cache=True, _nrt=False)
def _optimal_point(q, pa, pb, out):
    """Minimise the quadric: solve the 3x3 system; if it is ill-conditioned, or its
    solution lies farther than the edge's length from the edge's midpoint, take the best
    of the endpoints and the midpoint. Writes ``out``; returns the error.

    The distance guard matters on tube-like regions (the torus): there the quadric is
    nearly flat along the tube, passes the determinant test, and its minimiser can lie
    far along the valley at almost no error, which tears the surface."""
    a00, a01, a02, a11, a12, a22 = q[0], q[1], q[2], q[4], q[5], q[7]
    b0, b1, b2 = -q[3], -q[6], -q[8]
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    scale = abs(a00) + abs(a11) + abs(a22)
    if scale > 0.0 and abs(det) > 1e-10 * scale * scale * scale:
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        out[0] = (c00 * b0 + c01 * b1 + c02 * b2) / det
        out[1] = (c01 * b0 + c11 * b1 + c12 * b2) / det
        out[2] = (c02 * b0 + c12 * b1 + c22 * b2) / det
        d0 = out[0] - 0.5 * (pa[0] + pb[0])
        d1 = out[1] - 0.5 * (pa[1] + pb[1])
        d2 = out[2] - 0.5 * (pa[2] + pb[2])
        e0, e1, e2 = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
        if d0 * d0 + d1 * d1 + d2 * d2 <= e0 * e0 + e1 * e1 + e2 * e2:
            return quadric_error(q, out)
    return best_of_ends(q, pa, pb, out)


@njit(cache=True, _nrt=False)
def best_of_ends(q, pa, pb, out):
    """The best of the endpoints and the midpoint under quadric ``q``, into ``out``;
    returns its error (the fallback of :func:`_optimal_point`). The midpoint is tried
    in ``out`` itself: nothing is allocated."""
    best = quadric_error(q, pa)
    end = pa
    e = quadric_error(q, pb)
    if e < best:
        best = e
        end = pb
    for i in range(3):
        out[i] = 0.5 * (pa[i] + pb[i])
    e = quadric_error(q, out)
    if e < best:
        return e
    for i in range(3):
        out[i] = end[i]
    return best


@njit(cache=True)
def _group_quadric(t, WQ, wmap_from, wmap_to, npairs, out):
    """The 5-D quadric (31 floats: A 5x5, b 5, c) of wedge t and the wedges merging
    into it."""
    for i in range(31):
        out[i] = WQ[t, i]
    for i in range(npairs):
        if wmap_to[i] == t:
            for j in range(31):
                out[j] += WQ[wmap_from[i], j]


@njit(cache=True)
def _uv_minimiser(g, p, uv_now, out):
    """The (u, v) minimising the 5-D quadric g at position p: -A_uu^-1 (A_up p + b_u).
    Returns False (and writes uv_now) when A_uu is singular."""
    a00, a01, a11 = g[3 * 5 + 3], g[3 * 5 + 4], g[4 * 5 + 4]
    det = a00 * a11 - a01 * a01
    if abs(det) <= 1e-12 * (abs(a00) + abs(a11)) ** 2 or det == 0.0:
        out[0] = uv_now[0]
        out[1] = uv_now[1]
        return False
    r0 = g[25 + 3]
    r1 = g[25 + 4]
    for k in range(3):
        r0 += g[3 * 5 + k] * p[k]
        r1 += g[4 * 5 + k] * p[k]
    out[0] = -(a11 * r0 - a01 * r1) / det
    out[1] = -(-a01 * r0 + a00 * r1) / det
    return True


@njit(cache=True)
def _add_reduced(g, uv_now, qsum):
    """Add to the 3-D quadric qsum the 5-D quadric g minimised over (u, v) (the Schur
    complement), or with (u, v) fixed at uv_now when A_uu is singular."""
    a00, a01, a11 = g[18], g[19], g[24]
    det = a00 * a11 - a01 * a01
    idx = (0, 1, 2, 4, 5, 7)
    rows = (0, 0, 0, 1, 1, 2)
    cols = (0, 1, 2, 1, 2, 2)
    if abs(det) <= 1e-12 * (abs(a00) + abs(a11)) ** 2 or det == 0.0:
        u0, u1 = uv_now[0], uv_now[1]
        for n in range(6):
            qsum[idx[n]] += g[rows[n] * 5 + cols[n]]
        for k in range(3):  # b'_k = b_k + A_k3 u0 + A_k4 u1
            qsum[(3, 6, 8)[k]] += g[25 + k] + g[k * 5 + 3] * u0 + g[k * 5 + 4] * u1
        qsum[9] += (g[30] + 2.0 * (g[28] * u0 + g[29] * u1)
                    + a00 * u0 * u0 + 2.0 * a01 * u0 * u1 + a11 * u1 * u1)
        return
    i00, i01, i11 = a11 / det, -a01 / det, a00 / det  # A_uu^-1
    # M = A_pu A_uu^-1 (3x2)
    for n in range(6):
        r, c = rows[n], cols[n]
        m0 = g[r * 5 + 3] * i00 + g[r * 5 + 4] * i01
        m1 = g[r * 5 + 3] * i01 + g[r * 5 + 4] * i11
        qsum[idx[n]] += g[r * 5 + c] - (m0 * g[3 * 5 + c] + m1 * g[4 * 5 + c])
    bu0, bu1 = g[28], g[29]
    for k in range(3):
        m0 = g[k * 5 + 3] * i00 + g[k * 5 + 4] * i01
        m1 = g[k * 5 + 3] * i01 + g[k * 5 + 4] * i11
        qsum[(3, 6, 8)[k]] += g[25 + k] - (m0 * bu0 + m1 * bu1)
    qsum[9] += g[30] - (bu0 * (i00 * bu0 + i01 * bu1) + bu1 * (i01 * bu0 + i11 * bu1))


def _boundary_corners(mesh: Mesh) -> np.ndarray:
    """(m, 3) bool: corner k of face f starts a boundary edge (k -> k+1)."""
    w = mesh.welded
    he = np.sort(w.faces[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
    boundary = {tuple(e) for e in w.edges[w.boundary].tolist()}
    if not boundary:
        return np.zeros(w.faces.shape, bool)
    keys = he[:, 0].astype(np.int64) * (w.n_vertices + 1) + he[:, 1]
    bkeys = np.array([a * (w.n_vertices + 1) + b for a, b in boundary], np.int64)
    return np.isin(keys, bkeys).reshape(-1, 3)


def initial_quadrics(P: np.ndarray, F: np.ndarray, boundary_corners: np.ndarray,
                     boundary_weight: float, faces: bool = True) -> np.ndarray:
    """Per welded vertex (nv, 10): face planes plus boundary planes (see face_quadrics).

    Parameters
    ----------
    P : ndarray of shape (nv, 3) float64
    F : ndarray of shape (m, 3) int
    boundary_corners : ndarray of shape (m, 3) bool
        Corner k of face f starts a boundary edge (see _boundary_corners).
    boundary_weight : float
    faces : bool
        Include the face planes (False when wedge quadrics over position and texture
        coordinates carry them, see :func:`wedge_quadrics`).
    """
    alive = np.ones(len(F), bool)
    Q = face_quadrics(P, F, alive) if faces else np.zeros((len(P), 10))
    if boundary_weight > 0:
        _add_boundary_quadrics(Q, P, F, alive, boundary_corners, boundary_weight)
    return Q


def wedge_quadrics(P: np.ndarray, F: np.ndarray, FW: np.ndarray, uv: np.ndarray,
                   texture_weight: float) -> np.ndarray:
    """Garland & Heckbert 1998 quadrics over (x, y, z, w·u, w·v), one per wedge.

    Each face's corners, lifted to R^5 with its own wedges' UVs, span a plane; the
    quadric of a point X is its squared distance to that plane, ||X - p||² minus the
    squared projections on the plane's orthonormal basis e1, e2 (GH98 §3.2), weighted
    by the face's area and added to the face's three wedges. So a seam vertex has one
    quadric per side. Layout per row: A (5x5, row-major), b (5), c.

    Parameters
    ----------
    P : ndarray of shape (nv, 3)
    F, FW : ndarray of shape (m, 3) int
        Welded faces and the wedge (render vertex) of each corner.
    uv : ndarray of shape (n_wedges, 2)
    texture_weight : float
        Scale of texture coordinates against positions (unit-diagonal geometry), like
        MeshLab's ``extratcoordw``.

    Returns
    -------
    ndarray of shape (n_wedges, 31)
        In plain (x, y, z, u, v): the weight is folded into the matrix.
    """
    X = np.concatenate([P[F], texture_weight * uv[FW]], axis=2)  # (m, 3, 5)
    p, q, r = X[:, 0], X[:, 1], X[:, 2]
    e1 = q - p
    l1 = np.linalg.norm(e1, axis=1, keepdims=True)
    e1 = np.divide(e1, l1, out=np.zeros_like(e1), where=l1 > 0)
    e2 = r - p
    e2 = e2 - np.sum(e2 * e1, axis=1, keepdims=True) * e1
    l2 = np.linalg.norm(e2, axis=1, keepdims=True)
    e2 = np.divide(e2, l2, out=np.zeros_like(e2), where=l2 > 0)
    area = 0.5 * np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]),
                                axis=1)
    pe1 = np.sum(p * e1, axis=1, keepdims=True)
    pe2 = np.sum(p * e2, axis=1, keepdims=True)
    A = (np.eye(5)[None] - e1[:, :, None] * e1[:, None, :] - e2[:, :, None] * e2[:, None, :])
    b = pe1 * e1 + pe2 * e2 - p
    c = np.sum(p * p, axis=1) - pe1[:, 0] ** 2 - pe2[:, 0] ** 2
    # Express the quadric in plain (u, v): X = S (x, y, z, u, v) with S = diag(1,1,1,w,w),
    # so A -> S A S and b -> S b; the minimising (u, v) are then the UVs themselves.
    scale = np.array([1.0, 1.0, 1.0, texture_weight, texture_weight])
    A = A * scale[None, :, None] * scale[None, None, :]
    b = b * scale[None, :]
    per_face = np.concatenate([A.reshape(-1, 25), b, c[:, None]], axis=1) * area[:, None]
    WQ = np.zeros((int(FW.max()) + 1 if len(uv) <= FW.max() else len(uv), 31))
    for corner in range(3):
        np.add.at(WQ, FW[:, corner], per_face)
    return WQ


@njit(cache=True, inline="always")
def _edge_quadric(a, b, mesh, scratch):
    """``scratch.qsum`` = the quadric of edge (a, b): the endpoints' vertex quadrics,
    plus with wedge quadrics (Garland-Heckbert 1998, over (x, y, z, u, v)) each merged
    wedge's group quadric reduced at its UV."""
    Q, qsum, WQ = mesh.Q, scratch.qsum, mesh.WQ
    for i in range(QUADRIC_SIZE):
        qsum[i] = Q[a, i] + Q[b, i]
    if WQ.shape[0] > 1:
        gfrom, gto, targets, g = (scratch.wq.gfrom, scratch.wq.gto, scratch.wq.targets,
                                  scratch.wq.g)
        fan = (mesh.F, mesh.FW, mesh.vhead, mesh.cnext, mesh.falive)
        npairs = _wedge_pairs(a, b, fan, scratch.efaces, gfrom, gto)
        nt = _wedge_targets(a, b, fan, (gfrom, gto, npairs), targets)
        for i in range(nt):
            _group_quadric(targets[i], WQ, gfrom, gto, npairs, g)
            _add_reduced(g, mesh.uv[targets[i]], qsum)
