"""The shared edge-collapse engine: welded topology, wedge attributes carried along,
validity checks, a lazily re-evaluated priority queue, and a collapse log.

Every method of the suite that removes edges runs on this engine. The pipeline, in
:func:`simplify_mesh`, for a mesh and a face target::

    arrays at unit diagonal     welded positions/faces, wedge per corner, corner lists,
                                quadrics (vertex planes, or per-wedge 5-D ones)
    _run (numba)                push every edge; pop, re-cost if stale, check, collapse,
                                stamp, push the kept vertex's edges; log each collapse
    _extract                    render vertices again from the surviving wedges

Policies are data, not callbacks (the Python layer never runs per collapse). A
:class:`Policy` names a *placement* (where the surviving vertex goes) and a weighted sum
of *cost terms*; the numba kernel dispatches on those codes. This is CGAL
Surface_mesh_simplification's split into cost, placement and stop, with the stop being
the face target.

============  =========================================================================
placement     where the kept vertex goes
============  =========================================================================
optimal       the quadric minimiser, falling back to the best of the endpoints and the
              midpoint when the quadric is singular (Garland & Heckbert 1997)
endpoints     half-edge collapse: both directions are tried, the cheaper is kept
midpoint      the middle of the edge
memoryless    Lindstrom & Turk 1998 constraints (methods.memoryless_math)
============  =========================================================================

============  =========================================================================
cost term     what it measures
============  =========================================================================
quadric       Garland & Heckbert 1997 planes; with ``texture_weight`` > 0 on meshes with
              UVs, their 1998 quadrics over (x, y, z, u, v), one per wedge
memoryless    Lindstrom & Turk 1998 volume and boundary change at the new position
canny         González et al. 2007: incident area / total area if the edge's UV segment
              crosses a texture border
============  =========================================================================

Topology rules (each rejection is counted and reported):

- *link condition*: the endpoints' common neighbours are exactly the apexes of the
  edge's faces (1 on a boundary edge, 2 inside); otherwise the collapse pinches the
  surface;
- an interior edge between two boundary vertices is not collapsed (it would join two
  boundary loops into a non-manifold vertex);
- no collapse may create a face that duplicates an existing one (this is what stops a
  tetrahedron at 4 faces);
- *fold-over*: no surviving face may rotate its normal by more than
  ``max_normal_rotation`` degrees (default 90°, i.e. flip) or lose its area;
- non-manifold edges (more than two faces) are never collapsed;
- with ``boundary_lock`` no boundary vertex moves or disappears.

Wedges (render vertices) are carried along: the two faces removed by a collapse pair
each wedge of the removed vertex with the wedge of the kept vertex on the same side of
the edge; paired wedges merge, and the merged attribute (UV) is interpolated along the
edge at the new position. A seam edge has different wedges on its two sides, so both
pairs survive separately and the seam stays closed; it never opens, because the welded
topology is never split.

Lazy evaluation (Lindstrom & Turk 2000, §4.2.2): every vertex has a version stamp. A
collapse bumps the stamps of the kept vertex and its neighbours and pushes fresh entries
for the kept vertex's edges; other entries whose stamps changed are re-costed only when
they reach the top of the queue, and pushed back. An entry popped with current stamps is
taken at its stored cost (``verify=True`` checks that this equals a fresh evaluation).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import njit, types
from numba.typed import Dict

from bench.mesh import Mesh
from methods.canny import _walk
from methods.image_cost import (TILE, build_tiles, commit_geometry, commit_render, cycles,
                                dummy_state, image_cost)
from methods.memoryless_math import lt_cost, lt_placement, r5_texture_coordinates, texture_kappa
from methods.raster import BACKGROUND

__all__ = ["Policy", "EngineResult", "simplify_mesh", "PLACEMENTS", "STOP_REASONS",
           "face_quadrics", "initial_quadrics", "quadric_error", "barycentric_uv"]

PLACEMENTS = {"optimal": 0, "endpoints": 1, "midpoint": 2, "memoryless": 3}

#: Rejection counters, in the order of the kernel's ``rejects`` array.
REJECTIONS = ("link condition", "boundary pinch", "duplicate face", "fold-over",
              "non-manifold edge", "boundary lock", "seam rule")

STOP_REASONS = {0: "reached the target", 1: "no valid collapse remains"}
_N_REJECTIONS = len(REJECTIONS)

# Lindstrom–Turk constants: CGAL's defaults (alpha 1°, volume and boundary weights 0.5,
# no shape term), which follow the 1998/1999 papers.
LT_ALPHA_DEG = 1.0
LT_VOLUME_WEIGHT = 0.5
LT_BOUNDARY_WEIGHT = 0.5
LT_SHAPE_WEIGHT = 0.0


@dataclass(frozen=True)
class Policy:
    """How edges are costed and where the kept vertex goes.

    Attributes
    ----------
    placement : str
        A key of :data:`PLACEMENTS`.
    quadric_weight : float
        Weight of the Garland–Heckbert quadric error.
    memoryless_weight : float
        Weight of the Lindstrom–Turk cost (methods.memoryless_math).
    canny_weight : float
        Weight of the González 2007 texture-border penalty (needs ``borders``).
    boundary_weight : float
        Weight of the boundary-preserving planes added to the quadrics (Garland &
        Heckbert 1997 §6.1); 1000 is QSlim's default.
    max_normal_rotation : float
        Degrees a surviving face's normal may turn in one collapse.
    boundary_lock : bool
        Keep boundary vertices fixed.
    texture_weight : float
        > 0: the quadric term uses Garland & Heckbert 1998 wedge quadrics over position
        and ``texture_weight`` × UV (meshes with UVs only); new UVs minimise them.
    r5_uv : bool
        With ``memoryless`` placement, new UVs by the R^5 oriented volumes of Lindstrom
        & Turk 2000 §4.1.1, per texture patch (κ per patch); otherwise UVs of merged
        wedges are interpolated along the collapsed edge.
    seam_rule : bool
        Seam vertices move only along their seam (see ``_evaluate``), so every UV chart
        survives; without it seams stay closed but may drift across charts.
    uv_correction : bool
        González et al. 2008's texture-coordinate correction (§3, the α, β equations):
        a wedge whose vertex moves takes the UV that the texture map of one of its own
        triangles (before the collapse) gives the new position; see ``_uv_correction``.
    boundary_rule : bool
        A boundary vertex is never merged into an interior one (see ``_evaluate``).
    """

    placement: str = "optimal"
    quadric_weight: float = 1.0
    memoryless_weight: float = 0.0
    canny_weight: float = 0.0
    boundary_weight: float = 1000.0
    max_normal_rotation: float = 90.0
    boundary_lock: bool = False
    seam_rule: bool = True
    r5_uv: bool = True
    texture_weight: float = 0.0
    uv_correction: bool = False
    boundary_rule: bool = False

    def __post_init__(self):
        if self.placement not in PLACEMENTS:
            raise ValueError(f"unknown placement {self.placement!r}; choose one of "
                             f"{', '.join(PLACEMENTS)}")
        if not 0 < self.max_normal_rotation <= 180:
            raise ValueError("max_normal_rotation must be in (0, 180] degrees")


@dataclass
class EngineResult:
    """What :func:`simplify_mesh` returns.

    Attributes
    ----------
    mesh : Mesh
        The simplified mesh, render vertices rebuilt from the surviving wedges.
    stop_reason : str or None
        None when the target was reached; otherwise why the engine stopped.
    stats : dict
        collapses, cost evaluations, rejections by rule, seconds.
    log : dict of ndarray
        The collapse sequence: ``removed`` (c,) welded vertex removed by collapse i,
        ``kept`` (c,) the vertex it merged into, ``position`` (c, 3) the kept vertex's
        new position, ``removed_faces`` (c, 2) faces deleted (-1 when only one),
        ``changed_start`` (c + 1,) and ``changed_faces``: CSR lists of the faces whose
        corner moved from ``removed`` to ``kept`` (each is one face removed and one
        created, under the same id).
    """

    mesh: Mesh
    stop_reason: str | None
    stats: dict = field(default_factory=dict)
    log: dict = field(default_factory=dict)
    #: final per-vertex quadrics (nv, 10) and which welded vertices survive (nv,), for
    #: inspection and tests
    quadrics: np.ndarray | None = None
    vertex_alive: np.ndarray | None = None
    #: with an image term: the maintained luminance images of the result (V, H, W)
    images: np.ndarray | None = None


# -- quadrics ---------------------------------------------------------------------------
# A quadric is stored as 10 floats: the upper triangle of the symmetric 4x4 matrix
# [[a2, ab, ac, ad], [., b2, bc, bd], [., ., c2, cd], [., ., ., d2]] of the plane
# equation ax + by + cz + d = 0, so that error(p) = [p 1] Q [p 1]^T.

@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
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
    best = quadric_error(q, pa)
    out[:] = pa
    e = quadric_error(q, pb)
    if e < best:
        best = e
        out[:] = pb
    mid = 0.5 * (pa + pb)
    e = quadric_error(q, mid)
    if e < best:
        best = e
        out[:] = mid
    return best


# -- topology helpers (numba) -------------------------------------------------------------
# Vertex -> face incidence is a singly linked list of corners (3f + k) per vertex:
# vhead[v] is the first corner, cnext[c] the next one. Corners of dead faces are unlinked
# lazily by _compact.

@njit(cache=True)
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


@njit(cache=True)
def _neighbors(v, F, vhead, cnext, falive, mark, tick, out):
    """Distinct neighbours of v into ``out``; returns their count. ``mark``/``tick``
    deduplicate without clearing (tick[0] is bumped per call)."""
    tick[0] += 1
    t = tick[0]
    mark[v] = t
    n = 0
    c = vhead[v]
    while c != -1:
        f = c // 3
        if falive[f]:
            for k in range(3):
                w = F[f, k]
                if mark[w] != t:
                    mark[w] = t
                    out[n] = w
                    n += 1
        c = cnext[c]
    return n


@njit(cache=True)
def _edge_faces(u, v, F, vhead, cnext, falive, out):
    """Alive faces containing both u and v, into ``out``; returns the count."""
    n = 0
    c = vhead[u]
    while c != -1:
        f = c // 3
        if falive[f] and (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v):
            if n < out.shape[0]:
                out[n] = f
            n += 1
        c = cnext[c]
    return n


@njit(cache=True)
def _third(F, f, a, b):
    for k in range(3):
        w = F[f, k]
        if w != a and w != b:
            return w
    return -1


@njit(cache=True)
def _normal(pa, pb, pc):
    return np.cross(pb - pa, pc - pa)


@njit(cache=True)
def _normal3(ax, ay, az, bx, by, bz, cx, cy, cz):
    """(b - a) x (c - a) from scalars: no temporary arrays in the hot loop."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    return uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


# -- validity -------------------------------------------------------------------------------

@njit(cache=True)
def _check(u, v, p, P, F, vhead, cnext, falive, vboundary, mark, tick, nbr_u, nbr_v,
           efaces, cos_limit, boundary_lock):
    """0 if collapsing u into v at p is valid, else 1 + index into REJECTIONS."""
    k = _edge_faces(u, v, F, vhead, cnext, falive, efaces)
    if k > 2 or k == 0:
        return 5  # non-manifold edge (k == 0 cannot happen for a live edge)
    nu = _neighbors(u, F, vhead, cnext, falive, mark, tick, nbr_u)
    nv = _neighbors(v, F, vhead, cnext, falive, mark, tick, nbr_v)  # mark now holds v's
    t = tick[0]
    common = 0
    for i in range(nu):
        w = nbr_u[i]
        if w != v and w != u and mark[w] == t:
            common += 1
    if common != k:
        return 1  # link condition
    if boundary_lock or k == 2:
        bu = vboundary[u]
        bv = vboundary[v]
        if boundary_lock and (bu or bv):
            return 6
        if k == 2 and bu and bv:
            return 2  # boundary pinch
    # Duplicate faces: a face of u (not on the edge) must not coincide with one of v
    # once u is renamed v. Also the fold-over test for every face that moves.
    for side in range(2):
        x = u if side == 0 else v
        y = v if side == 0 else u
        c = vhead[x]
        while c != -1:
            f = c // 3
            if falive[f] and not (F[f, 0] == y or F[f, 1] == y or F[f, 2] == y):
                a = -1
                b = -1
                for j in range(3):
                    if F[f, j] != x:
                        if a == -1:
                            a = F[f, j]
                        else:
                            b = F[f, j]
                if side == 0:
                    c2 = vhead[v]
                    while c2 != -1:
                        g = c2 // 3
                        if falive[g] and not (F[g, 0] == u or F[g, 1] == u or F[g, 2] == u):
                            if ((F[g, 0] == a or F[g, 1] == a or F[g, 2] == a)
                                    and (F[g, 0] == b or F[g, 1] == b or F[g, 2] == b)):
                                return 3  # duplicate face
                        c2 = cnext[c2]
                # fold-over: the face with x moved to p
                i0, i1, i2 = F[f, 0], F[f, 1], F[f, 2]
                b0, b1, b2 = _normal3(P[i0, 0], P[i0, 1], P[i0, 2], P[i1, 0], P[i1, 1],
                                      P[i1, 2], P[i2, 0], P[i2, 1], P[i2, 2])
                if i0 == x:  # the same triangle with x moved to p
                    a0, a1, a2 = _normal3(p[0], p[1], p[2], P[i1, 0], P[i1, 1], P[i1, 2],
                                          P[i2, 0], P[i2, 1], P[i2, 2])
                elif i1 == x:
                    a0, a1, a2 = _normal3(P[i0, 0], P[i0, 1], P[i0, 2], p[0], p[1], p[2],
                                          P[i2, 0], P[i2, 1], P[i2, 2])
                else:
                    a0, a1, a2 = _normal3(P[i0, 0], P[i0, 1], P[i0, 2], P[i1, 0], P[i1, 1],
                                          P[i1, 2], p[0], p[1], p[2])
                lb = math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
                la = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                if la <= 1e-12 * lb or la == 0.0:
                    return 4
                if lb > 0.0:
                    if (b0 * a0 + b1 * a1 + b2 * a2) / (la * lb) < cos_limit:
                        return 4
            c = cnext[c]
    return 0


# -- cost and placement -------------------------------------------------------------------

@njit(cache=True)
def _gather_profile(a, b, P, F, vhead, cnext, falive, vboundary, efaces, mark, tick,
                    tri_a, tri_b, tri_c, bnd_a, bnd_b, link):
    """The Lindstrom–Turk profile of edge (a, b): triangles around either end, their
    boundary edges (oriented as in the triangle) and the link vertices. Returns
    (n_tris, n_bnd, n_link), or (-1, 0, 0) when the workspace is too small."""
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
        c = vhead[x]
        while c != -1:
            f = c // 3
            if falive[f]:
                has_y = F[f, 0] == y or F[f, 1] == y or F[f, 2] == y
                if side == 0 or not has_y:  # faces of the edge are counted once
                    if n_tris == cap:
                        return -1, 0, 0
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
                                return -1, 0, 0
                            bnd_a[n_bnd] = P[i0]
                            bnd_b[n_bnd] = P[i1]
                            n_bnd += 1
                    for j in range(3):
                        w = F[f, j]
                        if mark[w] != t:
                            mark[w] = t
                            if n_link == cap:
                                return -1, 0, 0
                            for d in range(3):
                                link[n_link, d] = P[w, d]
                            n_link += 1
            c = cnext[c]
    return n_tris, n_bnd, n_link


@njit(cache=True)
def _is_seam_vertex(v, FW, vhead, cnext, falive):
    """True when the faces around v use more than one wedge for it."""
    first = -1
    c = vhead[v]
    while c != -1:
        if falive[c // 3]:
            w = FW[c // 3, c % 3]
            if first == -1:
                first = w
            elif w != first:
                return True
        c = cnext[c]
    return False


@njit(cache=True)
def _is_seam_edge(u, v, F, FW, vhead, cnext, falive, efaces):
    """True when the edge's two faces use different wedges for one of its ends."""
    if _edge_faces(u, v, F, vhead, cnext, falive, efaces) != 2:
        return False
    f, g = efaces[0], efaces[1]
    for x in (u, v):
        wf = -1
        wg = -1
        for j in range(3):
            if F[f, j] == x:
                wf = FW[f, j]
            if F[g, j] == x:
                wg = FW[g, j]
        if wf != wg:
            return True
    return False


@njit(cache=True)
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


@njit(cache=True)
def _wedge_pairs(u, v, F, FW, vhead, cnext, falive, efaces, wmap_from, wmap_to):
    """Pairs (wedge of u -> wedge of v) across the faces of edge (u, v): each side of
    the edge merges its own two wedges. Returns the number of pairs."""
    k = _edge_faces(u, v, F, vhead, cnext, falive, efaces)
    npairs = 0
    for i in range(min(k, efaces.shape[0])):
        wu, wv = corner_wedges(F, FW, efaces[i], u, v)
        if wu != wv and npairs < wmap_from.shape[0]:
            wmap_from[npairs] = wu
            wmap_to[npairs] = wv
            npairs += 1
    return npairs


@njit(cache=True)
def _wedge_targets(u, v, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs, targets):
    """The distinct wedges the merged vertex will have (after pairing); returns count."""
    nt = 0
    for side in range(2):
        x = u if side == 0 else v
        c = vhead[x]
        while c != -1:
            f = c // 3
            if falive[f]:
                w = _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs)
                seen = False
                for i in range(nt):
                    if targets[i] == w:
                        seen = True
                if not seen and nt < targets.shape[0]:
                    targets[nt] = w
                    nt += 1
            c = cnext[c]
    return nt


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
    et al. 2008, §3), which :func:`methods.image_cost.image_cost` leaves in the image
    state."""
    cost = weights[3] * _image_term(u, v, p, P, F, FW, uv, falive, vhead, cnext, efaces, ictx)
    if weights[4] != 0.0:
        cost += weights[4] * ictx[0][14][6][3]
    return cost


@njit(cache=True)
def _image_term(u, v, p, P, F, FW, uv, falive, vhead, cnext, efaces, ictx):
    """Equation 8 of Lindstrom & Turk 2000 for collapsing u into v at p, with the
    texture coordinates the collapse would give (methods.image_cost.image_cost)."""
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
def _edge_parameter(u, v, p, P):
    """Where p projects on the edge from u (0) to v (1), clamped."""
    e = P[v] - P[u]
    el2 = e[0] ** 2 + e[1] ** 2 + e[2] ** 2
    t = 0.5
    if el2 > 0.0:
        t = ((p[0] - P[u, 0]) * e[0] + (p[1] - P[u, 1]) * e[1] + (p[2] - P[u, 2]) * e[2]) / el2
        t = min(1.0, max(0.0, t))
    return t


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


# -- one collapse -------------------------------------------------------------------------

@njit(cache=True)
def _mapped(w, wmap_from, wmap_to, npairs):
    for i in range(npairs):
        if wmap_from[i] == w:
            return wmap_to[i]
    return w


@njit(cache=True)
def _r5_update(u, v, p, P, F, FW, falive, vhead, cnext, uv, face_kappa, wmap_from, wmap_to,
               npairs, t_edge, r5ws):
    """Set the new UVs of :func:`_r5_compute`."""
    targets, new_uv = r5ws[6], r5ws[7]
    nt = _r5_compute(u, v, p, P, F, FW, falive, vhead, cnext, uv, face_kappa, wmap_from,
                     wmap_to, npairs, t_edge, r5ws)
    for ti in range(nt):
        uv[targets[ti], 0] = new_uv[ti, 0]
        uv[targets[ti], 1] = new_uv[ti, 1]


@njit(cache=True)
def _r5_compute(u, v, p, P, F, FW, falive, vhead, cnext, uv, face_kappa, wmap_from, wmap_to,
                npairs, t_edge, r5ws):
    """New UVs of every wedge around the merged vertex by Lindstrom & Turk 2000's R^5
    oriented volumes (§4.1.1), each from the triangles of its own texture patch around
    the edge (the removed ones included); a wedge whose patch profile is degenerate
    falls back to interpolation along the edge. Fills ``r5ws``'s targets and new UVs;
    returns how many."""
    tri_a, tri_b, tri_c, uv_a, uv_b, uv_c, targets, new_uv = r5ws
    cap = tri_a.shape[0]
    nt = _wedge_targets(u, v, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs, targets)
    for ti in range(nt):
        t = targets[ti]
        n = 0
        kappa = 1.0
        for side in range(2):
            x = u if side == 0 else v
            c = vhead[x]
            while c != -1:
                f = c // 3
                on_edge = (F[f, 0] == u or F[f, 1] == u or F[f, 2] == u) and \
                          (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v)
                if falive[f] and not (side == 1 and on_edge) and n < cap and \
                        _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs) == t:
                    for d in range(3):
                        tri_a[n, d] = P[F[f, 0], d]
                        tri_b[n, d] = P[F[f, 1], d]
                        tri_c[n, d] = P[F[f, 2], d]
                    for d in range(2):
                        uv_a[n, d] = uv[FW[f, 0], d]
                        uv_b[n, d] = uv[FW[f, 1], d]
                        uv_c[n, d] = uv[FW[f, 2], d]
                    kappa = face_kappa[f]
                    n += 1
                c = cnext[c]
        res, ok = r5_texture_coordinates(p, tri_a, tri_b, tri_c, uv_a, uv_b, uv_c, n, kappa,
                                         LT_ALPHA_DEG)
        if n > 0 and ok:
            new_uv[ti, 0] = res[0]
            new_uv[ti, 1] = res[1]
        else:  # interpolate along the edge when t is a merged pair, else keep
            new_uv[ti, 0] = uv[t, 0]
            new_uv[ti, 1] = uv[t, 1]
            for i in range(npairs):
                if wmap_to[i] == t:
                    a = wmap_from[i]
                    new_uv[ti, 0] = (1.0 - t_edge) * uv[a, 0] + t_edge * uv[t, 0]
                    new_uv[ti, 1] = (1.0 - t_edge) * uv[a, 1] + t_edge * uv[t, 1]
    return nt


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
def _uv_correction(u, v, p, P, F, FW, falive, vhead, cnext, uv, wedge_vertex, wmap_from,
                   wmap_to, npairs, targets, new_uv, moved_t):
    """New UVs of the merged vertex's wedges by :func:`barycentric_uv` (González et al.
    2008, §3), before the collapse changes anything. A wedge whose vertex does not move
    (the kept end of a half-edge collapse) keeps its UV. For one that moves, the paper
    leaves open which "modified triangle" gives the new UV; we take, among the live
    triangles around the edge that use this wedge (or a wedge merging into it), the one
    in which the new position lies deepest (largest smallest barycentric coordinate), so
    a point inside one of them gets that triangle's exact UV. Fills ``targets``,
    ``new_uv`` and ``moved_t`` (1: corrected); returns how many targets."""
    nt = _wedge_targets(u, v, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs, targets)
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
            c = vhead[x]
            while c != -1:
                f = c // 3
                if falive[f] and _mapped(FW[f, c % 3], wmap_from, wmap_to, npairs) == t:
                    depth = barycentric_uv(p, P[F[f, 0]], P[F[f, 1]], P[F[f, 2]],
                                           uv[FW[f, 0]], uv[FW[f, 1]], uv[FW[f, 2]], res)
                    if depth > best:
                        best = depth
                        new_uv[ti, 0], new_uv[ti, 1] = res[0], res[1]
                        moved_t[ti] = 1
                c = cnext[c]
    return nt


@njit(cache=True)
def _count_kinds(u, v, F, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs, kinds):
    """González et al. 2008, Algorithm 2, in welded terms, for collapsing u into v:
    kinds[0] += 1 when the edge's faces pair two different wedge pairs (the real edge
    and its *twin* at a seam or a sub-mesh joint collapse together); kinds[1] += 1 and
    kinds[2] += (their number) when wedges of u have no partner at v (the paper's
    disconnected vertices, which a *fake* edge or a translation brings to v)."""
    distinct = 0
    for i in range(npairs):
        seen = False
        for j in range(i):
            if wmap_from[j] == wmap_from[i] and wmap_to[j] == wmap_to[i]:
                seen = True
        if not seen:
            distinct += 1
    if distinct >= 2:
        kinds[0] += 1
    stranded = 0
    first = np.full(16, -1, np.int64)
    c = vhead[u]
    while c != -1:
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
        c = cnext[c]
    if stranded > 0:
        kinds[1] += 1
        kinds[2] += stranded


@njit(cache=True)
def _has_vertex(F, f, x):
    return F[f, 0] == x or F[f, 1] == x or F[f, 2] == x


@njit(cache=True)
def _collapse(u, v, p, P, Q, F, FW, falive, vhead, cnext, valive, wedge_vertex, uv,
              has_uv, efaces, wmap_from, wmap_to, log_changed, n_changed, use_r5, face_kappa,
              r5ws, WQ, tws, uv_fix, kinds):
    """Merge u into v at p. Returns (faces removed, changed count) and fills efaces with
    the removed faces. ``kinds`` counts twin and stranded-wedge collapses
    (:func:`_count_kinds`); ``uv_fix`` applies :func:`_uv_correction` last."""
    # Pair the wedges of u and v across each removed face (same side of the edge).
    npairs = _wedge_pairs(u, v, F, FW, vhead, cnext, falive, efaces, wmap_from, wmap_to)
    _count_kinds(u, v, F, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs, kinds)
    n_fix = 0
    cap = 64 if uv_fix else 0  # own scratch: the UV updates below reuse r5ws and tws
    fix_t = np.empty(cap, np.int64)
    fix_uv = np.empty((cap, 2))
    fix_m = np.zeros(cap, np.int64)
    if has_uv and uv_fix:
        n_fix = _uv_correction(u, v, p, P, F, FW, falive, vhead, cnext, uv, wedge_vertex,
                               wmap_from, wmap_to, npairs, fix_t, fix_uv, fix_m)
    k = _edge_faces(u, v, F, vhead, cnext, falive, efaces)
    t = _edge_parameter(u, v, p, P)  # for merged attributes
    if has_uv and WQ.shape[0] > 1:  # Garland-Heckbert 1998: merge, then minimise UVs
        targets, g = tws[2], tws[3]
        nt = _wedge_targets(u, v, FW, vhead, cnext, falive, wmap_from, wmap_to, npairs,
                            targets)
        for i in range(npairs):
            for j in range(31):
                WQ[wmap_to[i], j] += WQ[wmap_from[i], j]
        best = np.empty(2)
        for i in range(nt):
            _uv_minimiser(WQ[targets[i]], p, uv[targets[i]], best)
            uv[targets[i], 0] = best[0]
            uv[targets[i], 1] = best[1]
    elif has_uv and use_r5:
        _r5_update(u, v, p, P, F, FW, falive, vhead, cnext, uv, face_kappa, wmap_from,
                   wmap_to, npairs, t, r5ws)
    elif has_uv:
        for i in range(npairs):
            a, b = wmap_from[i], wmap_to[i]
            uv[b, 0] = (1.0 - t) * uv[a, 0] + t * uv[b, 0]
            uv[b, 1] = (1.0 - t) * uv[a, 1] + t * uv[b, 1]
    for i in range(n_fix):  # González et al. 2008's correction replaces the above
        if fix_m[i] == 1:
            uv[fix_t[i], 0] = fix_uv[i, 0]
            uv[fix_t[i], 1] = fix_uv[i, 1]
    for i in range(k):
        falive[efaces[i]] = False
    for i in range(k):  # the apexes of removed faces hold dead corners now
        _compact(_third(F, efaces[i], u, v), vhead, cnext, falive)
    # Rename u to v in its surviving faces; remap paired wedges; move u's other wedges.
    c = vhead[u]
    last = -1
    while c != -1:
        f = c // 3
        if falive[f]:
            j = c % 3
            F[f, j] = v
            w = FW[f, j]
            for i in range(npairs):
                if wmap_from[i] == w:
                    w = wmap_to[i]
                    break
            FW[f, j] = w
            wedge_vertex[w] = v
            log_changed[n_changed] = f
            n_changed += 1
        last = c
        c = cnext[c]
    if last != -1:  # append u's corner list to v's
        cnext[last] = vhead[v]
        vhead[v] = vhead[u]
    vhead[u] = -1
    valive[u] = False
    P[v] = p
    for i in range(10):
        Q[v, i] += Q[u, i]
    _compact(v, vhead, cnext, falive)
    return k, n_changed


@njit(cache=True)
def _push(heap, cost, a, b, sa, sb, p, keep):
    """Queue edge (a, b) at ``cost`` with its endpoints' stamps, the kept vertex's new
    position ``p`` and which end is kept (stamps -1: re-cost when popped)."""
    heapq.heappush(heap, (float(cost), np.int64(a), np.int64(b), np.int64(sa), np.int64(sb),
                          float(p[0]), float(p[1]), float(p[2]), np.int64(keep)))


# -- the loop -----------------------------------------------------------------------------

@njit(cache=True)
def _run(P, Q, F, FW, falive, vhead, cnext, valive, vboundary, wedge_vertex, uv, has_uv,
         target,
         placement, weights, cos_limit, boundary_lock, seam_rule, boundary_rule, verify,
         max_collapses,
         borders, inv_area, moved, use_r5, face_kappa, WQ, img, tiles, iws, uv_fix, kinds):
    run_start = cycles()
    nv = P.shape[0]
    mark = np.zeros(nv, np.int64)
    tick = np.zeros(1, np.int64)
    stamp = np.zeros(nv, np.int64)
    # pushed_at[x]: x's stamp when entries for all of its edges were last pushed. An entry
    # older than that on either end has a newer one in the heap (every edge created
    # since then was pushed fresh by the collapse that made it), so it can be dropped.
    pushed_at = np.zeros(nv, np.int64)
    nbr_u = np.empty(nv, np.int64)
    nbr_v = np.empty_like(nbr_u)
    efaces = np.empty(8, np.int64)
    wmap_from = np.empty(8, np.int64)
    wmap_to = np.empty(8, np.int64)
    qsum = np.empty(10)
    p = np.empty(3)
    cap = 256  # triangles around an edge; a larger profile falls back to the quadric
    ws = (np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 3)),
          np.empty((cap, 3)), np.empty((cap, 3)))
    tws = (np.empty(8, np.int64), np.empty(8, np.int64), np.empty(64, np.int64), np.empty(31))
    r5ws = (np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 3)), np.empty((cap, 2)),
            np.empty((cap, 2)), np.empty((cap, 2)), np.empty(64, np.int64), np.empty((64, 2)))
    ictx = (img, tiles, iws, r5ws, face_kappa, use_r5, has_uv, wmap_from, wmap_to)
    rejects = np.zeros(_N_REJECTIONS, np.int64)
    log_cost = np.empty(max_collapses)
    log_removed = np.empty(max_collapses, np.int32)
    log_kept = np.empty(max_collapses, np.int32)
    log_pos = np.empty((max_collapses, 3))
    log_faces = np.full((max_collapses, 2), -1, np.int64)
    log_start = np.zeros(max_collapses + 1, np.int64)
    log_changed = np.empty(max(16, 3 * F.shape[0]), np.int64)
    n_changed = 0
    evaluations = 0
    mismatches = 0
    # Blocked edges: rejected candidates, re-queued once when either endpoint's stamp
    # changes. Each record is linked into both endpoints' lists and dies when re-queued,
    # so an edge is pushed once per rejection, never once per list it sits in.
    rec_end = np.empty((64, 2), np.int64)
    rec_next = np.empty((64, 2), np.int64)
    rec_live = np.zeros(64, np.bool_)
    blk_head = np.full(nv, -1, np.int64)
    n_rec = 0
    # the Lindstrom-Turk, Canny and image terms look at the triangles around an edge
    rendered = weights[3] != 0.0 or weights[4] != 0.0  # image and/or entropy terms
    neighbourhood_cost = weights[1] != 0.0 or weights[2] != 0.0 or rendered
    no_record = np.empty((0, 2), np.int64)

    heap = [(0.0, np.int64(0), np.int64(0), np.int64(0), np.int64(0), 0.0, 0.0, 0.0,
             np.int64(0))]
    heap.pop()
    # With the image term, the kept vertex's edges are queued lazily too (Lindstrom &
    # Turk 2000, §4.2.2: an edge keeps its key and is re-costed when it reaches the
    # front); their last keys are remembered per edge.
    lazy_new = rendered
    last_key = Dict.empty(key_type=types.int64, value_type=types.float64)
    for f in range(F.shape[0]):
        if not falive[f]:
            continue
        for j in range(3):
            a, b = F[f, j], F[f, (j + 1) % 3]
            if a < b or _edge_faces(a, b, F, vhead, cnext, falive, efaces) == 1:
                cost, keep = _evaluate(a, b, P, Q, F, FW, vhead, cnext, falive, vboundary,
                                       efaces, mark, tick, ws, placement, weights,
                                       seam_rule, boundary_rule,
                                       qsum, p, uv, borders, inv_area, no_record, WQ, tws, ictx)
                evaluations += 1
                _push(heap, cost, a, b, 0, 0, p, keep)
                if lazy_new:
                    last_key[min(a, b) * nv + max(a, b)] = cost

    faces = 0
    for f in range(F.shape[0]):
        if falive[f]:
            faces += 1
    n = 0
    stopped = 1
    while len(heap) > 0:
        if faces <= target:
            stopped = 0
            break
        cost, a, b, sa, sb, px, py, pz, keep = heapq.heappop(heap)
        if not valive[a] or not valive[b]:
            continue
        if sa != stamp[a] or sb != stamp[b] or keep == -1:  # stale, or queued lazily
            if sa != -1 and (sa < pushed_at[a] or sb < pushed_at[b]):
                continue  # superseded: a newer entry for this edge was pushed since
            # re-cost lazily and push back
            if _edge_faces(a, b, F, vhead, cnext, falive, efaces) == 0:
                continue
            cost, keep = _evaluate(a, b, P, Q, F, FW, vhead, cnext, falive, vboundary,
                                       efaces, mark, tick, ws, placement, weights,
                                       seam_rule, boundary_rule,
                                       qsum, p, uv, borders, inv_area, no_record, WQ, tws, ictx)
            evaluations += 1
            _push(heap, cost, a, b, stamp[a], stamp[b], p, keep)
            if lazy_new:
                last_key[min(a, b) * nv + max(a, b)] = cost
            continue
        if _edge_faces(a, b, F, vhead, cnext, falive, efaces) == 0:
            continue
        if verify:  # re-cost: the stored cost and placement must be current
            fresh, keep = _evaluate(a, b, P, Q, F, FW, vhead, cnext, falive, vboundary,
                                    efaces, mark, tick, ws, placement, weights,
                                    seam_rule, boundary_rule,
                                    qsum, p, uv, borders, inv_area, no_record, WQ, tws, ictx)
            evaluations += 1
            if abs(fresh - cost) > 1e-9 * max(1.0, abs(cost)):
                mismatches += 1
        else:  # current stamps: the queued cost and placement are those of now
            fresh = cost
            p[0], p[1], p[2] = px, py, pz
        u = a if keep == b else b
        v = keep
        if fresh == np.inf:
            code = 7  # seam rule
        else:
            code = _check(u, v, p, P, F, vhead, cnext, falive, vboundary, mark, tick, nbr_u,
                          nbr_v, efaces, cos_limit, boundary_lock)
        if code != 0:
            rejects[code - 1] += 1
            if n_rec == rec_live.shape[0]:
                rec_end = np.concatenate((rec_end, np.empty_like(rec_end)))
                rec_next = np.concatenate((rec_next, np.empty_like(rec_next)))
                rec_live = np.concatenate((rec_live, np.zeros_like(rec_live)))
            rec_end[n_rec, 0] = a
            rec_end[n_rec, 1] = b
            rec_next[n_rec, 0] = blk_head[a]
            rec_next[n_rec, 1] = blk_head[b]
            rec_live[n_rec] = True
            blk_head[a] = n_rec
            blk_head[b] = n_rec
            n_rec += 1
            continue
        if n >= max_collapses:
            break
        if n_changed + 4096 > log_changed.shape[0]:  # a vertex has far fewer faces
            log_changed = np.concatenate((log_changed, np.empty_like(log_changed)))
        log_cost[n] = fresh
        log_removed[n] = u
        log_kept[n] = v
        log_pos[n] = p
        if p[0] != P[v, 0] or p[1] != P[v, 1] or p[2] != P[v, 2]:
            moved[v] = True
        removed, n_changed = _collapse(u, v, p.copy(), P, Q, F, FW, falive, vhead, cnext,
                                       valive, wedge_vertex, uv, has_uv, efaces, wmap_from,
                                       wmap_to, log_changed, n_changed, use_r5, face_kappa,
                                       r5ws, WQ, tws, uv_fix, kinds)
        for i in range(min(removed, 2)):
            log_faces[n, i] = efaces[i]
        if rendered:  # bring the images (or face ids) up to date
            ok, changed = commit_geometry(v, efaces, removed, P, F, FW, uv, falive, vhead,
                                          cnext, valive, img, tiles, iws)
            if not ok:
                tiles = build_tiles(img[6], falive, TILE, -(-img[4].shape[2] // TILE),
                                    -(-img[4].shape[1] // TILE))
                img[11][5] += 1
                ictx = (img, tiles, iws, r5ws, face_kappa, use_r5, has_uv, wmap_from, wmap_to)
            commit_render(changed, P, F, FW, uv, falive, img, tiles, iws, float(BACKGROUND))
        n += 1
        log_start[n] = n_changed
        faces -= removed
        vboundary[v] = vboundary[v] or vboundary[u]  # a boundary vertex stays one
        # Stamp v, and its neighbours when costs depend on the triangles around an edge
        # (a quadric cost of (w, x) depends only on w and x, which did not change);
        # requeue the neighbours' blocked edges (their validity may have changed), and
        # push fresh entries for v's edges.
        m = _neighbors(v, F, vhead, cnext, falive, mark, tick, nbr_v)
        stamp[v] += 1
        for i in range(m):
            w = nbr_v[i]
            if neighbourhood_cost and w != v:
                stamp[w] += 1
            j = blk_head[w]
            while j != -1:
                side = 0 if rec_end[j, 0] == w else 1
                if rec_live[j]:
                    rec_live[j] = False
                    o = rec_end[j, 1 - side]
                    if valive[o]:
                        _push(heap, cost, w, o, -1, -1, p, -1)
                j = rec_next[j, side]
            blk_head[w] = -1
        for i in range(m):
            w = nbr_v[i]
            if w == v:
                continue
            if lazy_new:  # the edge's last key, re-costed when it reaches the front
                key = fresh
                kv, ku = min(v, w) * nv + max(v, w), min(u, w) * nv + max(u, w)
                if kv in last_key:
                    key = last_key[kv]
                elif ku in last_key:
                    key = last_key[ku]
                _push(heap, key, v, w, stamp[v], stamp[w], p, -1)
                continue
            c2, k2 = _evaluate(v, w, P, Q, F, FW, vhead, cnext, falive, vboundary,
                               efaces, mark, tick, ws, placement, weights,
                               seam_rule, boundary_rule, qsum,
                               p, uv, borders, inv_area, no_record, WQ, tws, ictx)
            evaluations += 1
            _push(heap, c2, v, w, stamp[v], stamp[w], p, k2)
        pushed_at[v] = stamp[v]
        # The apexes of the removed faces lost a face, which can change whether they are
        # seam vertices (and so the seam rule's verdict on their edges): give them fresh
        # entries too. (With neighbourhood costs they were stamped above and are
        # re-costed lazily.)
        if seam_rule and not neighbourhood_cost:
            for i in range(min(removed, 2)):
                x = log_faces[n - 1, i]
                x = _third(F, x, u, v)
                if x == -1 or not valive[x]:
                    continue
                stamp[x] += 1
                mx = _neighbors(x, F, vhead, cnext, falive, mark, tick, nbr_u)
                for i2 in range(mx):
                    y = nbr_u[i2]
                    if y == x:
                        continue
                    c2, k2 = _evaluate(x, y, P, Q, F, FW, vhead, cnext, falive, vboundary,
                                       efaces, mark, tick, ws, placement, weights,
                                       seam_rule, boundary_rule,
                                       qsum, p, uv, borders, inv_area, no_record, WQ,
                                       tws, ictx)
                    evaluations += 1
                    _push(heap, c2, x, y, stamp[x], stamp[y], p, k2)
                pushed_at[x] = stamp[x]
    if faces <= target:
        stopped = 0
    img[11][4] += cycles() - run_start
    return (stopped, n, evaluations, mismatches, rejects, log_removed[:n], log_kept[:n],
            log_pos[:n], log_faces[:n], log_start[:n + 1], log_changed[:n_changed],
            log_cost[:n])



# -- Python entry point -------------------------------------------------------------------

def _corner_lists(F: np.ndarray, nv: int):
    """vhead (nv,) and cnext (3m,) linking each vertex's corners, in corner order."""
    corners = F.reshape(-1).astype(np.int64)
    order = np.argsort(corners, kind="stable")
    vhead = np.full(nv, -1, np.int64)
    cnext = np.full(len(corners), -1, np.int64)
    sorted_v = corners[order]
    same = sorted_v[1:] == sorted_v[:-1]
    cnext[order[:-1][same]] = order[1:][same]
    first = np.ones(len(order), bool)
    first[1:] = ~same
    vhead[sorted_v[first]] = order[first]
    return vhead, cnext


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


def _face_kappa(P, F, FW, uv) -> np.ndarray:
    """(m,) the texture scale κ of each face's texture patch (Lindstrom & Turk 2000
    §4.1.1); a patch is a set of faces connected through shared wedges."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(F)
    n_w = int(FW.max()) + 1
    rows = np.repeat(np.arange(m), 3)
    graph = coo_matrix((np.ones(3 * m), (rows, m + FW.reshape(-1))), shape=(m + n_w, m + n_w))
    _, labels = connected_components(graph, directed=False)
    patch_of_face = np.unique(labels[:m], return_inverse=True)[1].reshape(-1)
    n_patches = int(patch_of_face.max()) + 1
    kappa = texture_kappa(P, F, uv[FW], patch_of_face, n_patches)
    return kappa[patch_of_face]


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


def vboundary_of(w, nv: int) -> np.ndarray:
    """(nv,) bool: welded vertices on a boundary edge."""
    flags = np.zeros(nv, bool)
    flags[w.edges[w.boundary].reshape(-1)] = True
    return flags


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
    image : methods.image_cost.ImageTerm, optional
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
                         "(methods.canny.texture_borders) for a mesh with UVs")
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
