"""The engine's loop (numba), in the steps of meshoptimizer's ``meshopt_simplifyEdge``
and CGAL's ``Edge_collapse::run``::

    _collect_candidates     queue every edge at its first cost (methods.engine.initial)
    loop:
      _pop_current          pop entries until one is current (re-cost stale ones)
      _check_candidate      the validity rules (methods.engine.topology._check)
      _block                a rejected edge waits for an endpoint to change
      _take                 log, collapse, bring the images up to date
      _requeue              stamp the neighbourhood, release blocked edges, queue the
                            kept vertex's edges (and the removed faces' apexes')

Every helper takes a few named structures of :mod:`methods.engine.state`.
"""

from __future__ import annotations

import heapq
import math

import numba
import numpy as np
from numba import njit, types
from numba.typed import Dict

from methods.corners import corners
from methods.engine.borrow import borrowed
from methods.engine.collapse import _collapse
from methods.engine.cost import _evaluate
from methods.engine.capacity import over_capacity
from methods.engine.parts import empties_a_part, faces_removed
from methods.engine.policy import (
    _N_REJECTIONS,
    REJECT_CAPACITY,
    REJECT_LAST_OF_PART,
    REJECT_MOVE_BOUND,
    REJECT_SEAM_RULE,
    VALID,
)
from methods.engine.state import (
    BLOCKED_INITIAL,
    EVALUATIONS,
    LOG_CHANGED,
    LOG_CHANGED_HEADROOM,
    LOG_CHANGED_MIN,
    LOG_COLLAPSES,
    LOG_PAIRS,
    LOG_WEDGES,
    MISMATCHES,
    N_LOG_COUNTS,
    WEDGE_PAIRS_CAP,
    WEDGE_TARGETS_CAP,
    Blocked,
    Images,
    Log,
    Queue,
    renders,
)
from methods.engine.topology import (
    _check,
    _edge_faces,
    _neighbors,
    _normal3,
    _third,
)
from methods.imaging.counters import STAT_RUN_CYCLES, STAT_TILE_REBUILDS, cycles
from methods.imaging.raster import NO_VERTEX, ZERO
from methods.imaging.region import Scene, commit_geometry, commit_render
from methods.imaging.share import share_tiles
from methods.imaging.tiles import TILE, build_tiles
from metrics.shading import BACKGROUND


@njit(cache=True)
def _push(heap, cost, a, b, sa, sb, p, keep):
    """Queue edge (a, b) at ``cost`` with its endpoints' stamps, the kept vertex's new
    position ``p`` and which end is kept (stamps -1: re-cost when popped)."""
    heapq.heappush(heap, (float(cost), np.int64(a), np.int64(b), np.int64(sa), np.int64(sb),
                          float(p[0]), float(p[1]), float(p[2]), np.int64(keep)))


@njit(cache=True, inline="always")
def _cost(a, b, mesh, rules, terms, scratch, images, queue):
    """:func:`_evaluate` of edge (a, b) (the weighted terms of
    :mod:`methods.engine.terms`), counted; the placement lands in ``scratch.p``."""
    cost, keep = _evaluate(a, b, mesh, rules, terms, scratch, images)
    queue.tally[EVALUATIONS] += 1
    return cost, keep


@njit(cache=True)
def _remember(queue, rules, a, b, nv, cost):
    """With the image term, note the key an edge was queued at (see :func:`_run`)."""
    if renders(rules.weights):
        queue.last_key[min(a, b) * nv + max(a, b)] = cost


@njit(cache=True)
def _collect_candidates(heap, first, rules, queue, nv):
    """Queue every edge with stamps 0 at the cost :func:`methods.engine.initial.first_costs`
    gave it: ``first`` is (edges, costs, kept ends, placements), in edge order."""
    edges, costs, keeps, places = first
    for e in range(edges.shape[0]):
        a, b = edges[e, 0], edges[e, 1]
        _push(heap, costs[e], a, b, ZERO, ZERO, places[e], keeps[e])
        _remember(queue, rules, a, b, nv, costs[e])
    queue.tally[EVALUATIONS] += edges.shape[0]


@njit(cache=True)
def _pop_current(heap, mesh, rules, terms, scratch, images, queue):
    """Pop until an entry is current and return it as (found, cost, fresh, a, b, keep),
    the placement in ``scratch.p``. A stale entry (a stamp changed, or queued lazily) is
    re-costed and pushed back (Lindstrom & Turk 2000, §4.2.2), unless a
    newer entry for its edge was pushed since; entries of dead vertices or edges are
    dropped. With ``verify`` the current entry is re-costed too and a differing cost is
    counted."""
    stamp, pushed_at, p = queue.stamp, queue.pushed_at, scratch.p
    while len(heap) > 0:
        cost, a, b, sa, sb, px, py, pz, keep = heapq.heappop(heap)
        if not mesh.valive[a] or not mesh.valive[b]:
            continue
        stale = sa != stamp[a] or sb != stamp[b] or keep == -1  # or queued lazily
        if stale and sa != -1 and (sa < pushed_at[a] or sb < pushed_at[b]):
            continue  # superseded: a newer entry for this edge was pushed since
        if _edge_faces(a, b, mesh.F, mesh.vhead, mesh.cnext, mesh.falive,
                       scratch.efaces) == 0:
            continue
        if stale or rules.verify:  # one call site: each one is a copy of the costing
            fresh, fresh_keep = _cost(a, b, mesh, rules, terms, scratch, images, queue)
            if stale:  # re-cost lazily and push back
                _push(heap, fresh, a, b, stamp[a], stamp[b], p, fresh_keep)
                _remember(queue, rules, a, b, mesh.P.shape[0], fresh)
                continue
            # verify: the stored cost and placement must be current
            keep = fresh_keep
            if abs(fresh - cost) > 1e-9 * max(1.0, abs(cost)):
                queue.tally[MISMATCHES] += 1
        else:  # current stamps: the queued cost and placement are those of now
            fresh = cost
            p[0], p[1], p[2] = px, py, pz
        return True, cost, fresh, a, b, keep
    return False, 0.0, 0.0, np.int64(0), np.int64(0), np.int64(0)


@njit(cache=True)
def _check_candidate(u, v, fresh, mesh, rules, scratch):
    """VALID, or the rejection code of the first rule that collapsing u into v at
    ``scratch.p`` breaks (an infinite cost is the capacity rule's verdict or the seam
    rule's)."""
    if fresh == np.inf:
        if over_capacity(u, v, mesh, rules, scratch):
            return REJECT_CAPACITY
        return REJECT_SEAM_RULE
    code = _check(u, v, scratch.p, mesh.P, (mesh.F, mesh.vhead, mesh.cnext, mesh.falive),
                  mesh.vboundary, (scratch.mark, scratch.tick, scratch.nbr_u, scratch.nbr_v,
                                   scratch.efaces), (rules.cos_limit, rules.boundary_lock))
    if code == VALID and rules.keep_parts and empties_a_part(u, v, mesh, scratch):
        return REJECT_LAST_OF_PART
    if code == VALID and _beyond_reach(u, v, scratch.p, mesh, _reach(u, v, mesh, rules)):
        return REJECT_MOVE_BOUND
    return code


@njit(cache=True, _nrt=False)
def _reach(u, v, mesh, rules):
    """How far the collapse of u into v may move the surface: the move bound, less the
    larger of the two ends' past moves under ``move_memory``."""
    if rules.move_memory and rules.max_move != np.inf:
        return rules.max_move - max(mesh.drift[u], mesh.drift[v])
    return rules.max_move


@njit(cache=True, _nrt=False)
def _beyond_reach(u, v, p, mesh, r):
    """True when ``p`` lies farther than ``r`` (the move bound) from the plane of a live
    face around u or v: the collapse would leave the surface it replaces by more than
    that. A move within the faces' planes (across a flat panel) is never beyond reach."""
    if r == np.inf:
        return False
    if r < 0.0:
        return True
    for x in (u, v):
        for c in corners(x, mesh.vhead, mesh.cnext):
            if mesh.falive[c // 3]:
                off, length = _plane_offset(c // 3, p, mesh)
                if length != 0.0 and off > r * length:
                    return True
    return False


@njit(cache=True, _nrt=False)
def _largest_offset(u, v, p, mesh):
    """The largest distance from ``p`` to the plane of a live face around u or v."""
    largest = 0.0
    for x in (u, v):
        for c in corners(x, mesh.vhead, mesh.cnext):
            if mesh.falive[c // 3]:
                off, length = _plane_offset(c // 3, p, mesh)
                if length != 0.0:
                    largest = max(largest, off / length)
    return largest


@njit(cache=True, _nrt=False, inline="always")
def _plane_offset(f, p, mesh):
    """(|n · (p - a)|, |n|) for face f = (a, b, d) with normal n = (b - a) × (d - a):
    ``p``'s distance to the face's plane is their ratio."""
    P, F = mesh.P, mesh.F
    a, b, d = F[f, 0], F[f, 1], F[f, 2]
    nx, ny, nz = _normal3((P[a, 0], P[a, 1], P[a, 2]), (P[b, 0], P[b, 1], P[b, 2]),
                          (P[d, 0], P[d, 1], P[d, 2]))
    length = math.sqrt(nx * nx + ny * ny + nz * nz)
    off = nx * (p[0] - P[a, 0]) + ny * (p[1] - P[a, 1]) + nz * (p[2] - P[a, 2])
    return abs(off), length


@njit(cache=True)
def _block(blocked, a, b):
    """Record rejected edge (a, b) in both endpoints' blocked lists (the table doubles
    when full); returns the table."""
    n_rec = blocked.count[0]
    if n_rec == blocked.live.shape[0]:
        blocked = Blocked(end=np.concatenate((blocked.end, np.empty_like(blocked.end))),
                          next=np.concatenate((blocked.next, np.empty_like(blocked.next))),
                          live=np.concatenate((blocked.live, np.zeros_like(blocked.live))),
                          head=blocked.head, count=blocked.count)
    blocked.end[n_rec, 0] = a
    blocked.end[n_rec, 1] = b
    blocked.next[n_rec, 0] = blocked.head[a]
    blocked.next[n_rec, 1] = blocked.head[b]
    blocked.live[n_rec] = True
    blocked.head[a] = n_rec
    blocked.head[b] = n_rec
    blocked.count[0] = n_rec + 1
    return blocked


@njit(cache=True)
def _doubled(a, used, need):
    """``a`` itself when ``need`` more slots fit after ``used``; else a copy twice as
    long (a log list grows, it never truncates)."""
    if used + need <= a.shape[0]:
        return a
    b = np.empty((2 * a.shape[0] + need,) + a.shape[1:], a.dtype)
    b[:used] = a[:used]
    return b


@njit(cache=True)
def _log_collapse(log, u, v, fresh, p):
    """Write collapse (u into v at p, cost ``fresh``) to the log, first making room in
    its lists for what one collapse can add; returns the log (its lists may have
    grown)."""
    n, count = log.count[LOG_COLLAPSES], log.count
    log = Log(cost=log.cost, removed=log.removed, kept=log.kept, pos=log.pos, faces=log.faces,
              start=log.start,
              changed=_doubled(log.changed, count[LOG_CHANGED], np.int64(LOG_CHANGED_HEADROOM)),
              pair_start=log.pair_start,
              pairs=_doubled(log.pairs, count[LOG_PAIRS], np.int64(WEDGE_PAIRS_CAP)),
              wedge_start=log.wedge_start,
              wedges=_doubled(log.wedges, count[LOG_WEDGES], np.int64(WEDGE_TARGETS_CAP)),
              wedge_uv=_doubled(log.wedge_uv, count[LOG_WEDGES], np.int64(WEDGE_TARGETS_CAP)),
              count=count)
    log.cost[n] = fresh
    log.removed[n] = u
    log.kept[n] = v
    log.pos[n] = p
    return log


@njit(cache=True)
def _log_wedges(log, npairs, nt, mesh, rules, scratch):
    """Append the collapse's distinct wedge pairs (``scratch.wmap_from``/``wmap_to``)
    and the merged vertex's wedges (``scratch.wq.targets``) with their new UVs, so the
    log alone says how every render vertex changed."""
    n_p, n_w = log.count[LOG_PAIRS], log.count[LOG_WEDGES]
    for i in range(npairs):  # distinct already (methods.engine.wedges._wedge_pairs)
        log.pairs[n_p, 0] = scratch.wmap_from[i]
        log.pairs[n_p, 1] = scratch.wmap_to[i]
        n_p += 1
    for i in range(nt):
        w = scratch.wq.targets[i]
        log.wedges[n_w] = w
        log.wedge_uv[n_w, 0] = mesh.uv[w, 0] if rules.has_uv else 0.0
        log.wedge_uv[n_w, 1] = mesh.uv[w, 1] if rules.has_uv else 0.0
        n_w += 1
    log.count[LOG_PAIRS] = n_p
    log.count[LOG_WEDGES] = n_w


@njit(cache=True)
def _take(u, v, mesh, rules, terms, scratch, images, record):
    """Collapse u into v at ``scratch.p``: note whether v moves, collapse, log the
    removed faces and merged wedges into ``record`` = (log, kinds) (kinds: the
    collapse kinds' counts), and bring the images (or face ids) up to date. Returns
    (faces removed, images) — the tile index is rebuilt when a commit overflows it (and
    handed to the threads that share the views)."""
    log, kinds = record
    P, p = mesh.P, scratch.p
    stays = p[0] == P[v, 0] and p[1] == P[v, 1] and p[2] == P[v, 2]
    if not stays:
        mesh.moved[v] = True
    if rules.move_memory and rules.max_move != np.inf:
        mesh.drift[v] = max(mesh.drift[u], mesh.drift[v]) + _largest_offset(u, v, p, mesh)
    n = log.count[LOG_COLLAPSES]
    first_changed = log.count[LOG_CHANGED]
    removed, n_changed, npairs, nt = _collapse(u, v, p.copy(), mesh, rules, terms, scratch,
                                               (log.changed, first_changed, kinds))
    log.count[LOG_CHANGED] = n_changed
    _log_wedges(log, npairs, nt, mesh, rules, scratch)
    efaces = scratch.efaces
    for i in range(min(removed, 2)):
        log.faces[n, i] = efaces[i]
    faces_removed(mesh, efaces, min(removed, efaces.shape[0]))
    if renders(rules.weights):
        img, iws = images.img, images.iws
        # the faces that held u: with v in place, the only ones whose geometry changes
        held_u = log.changed[first_changed:n_changed]
        ok, changed = commit_geometry(_commit_scene(mesh, images), v, stays, held_u, efaces,
                                      removed, (mesh.vhead, mesh.cnext), mesh.valive)
        if not ok:
            tiles = build_tiles(img.fbox, mesh.falive, np.int64(TILE),
                                -(-img.Y.shape[2] // TILE), -(-img.Y.shape[1] // TILE))
            img.stats[STAT_TILE_REBUILDS] += 1
            share_tiles(iws.vjob, tiles)
            images = Images(img, tiles, iws)
        commit_render(changed, _commit_scene(mesh, images))
    log.count[LOG_COLLAPSES] = n + 1
    log.start[n + 1] = log.count[LOG_CHANGED]
    log.pair_start[n + 1] = log.count[LOG_PAIRS]
    log.wedge_start[n + 1] = log.count[LOG_WEDGES]
    return removed, images


@njit(cache=True, inline="always")
def _commit_scene(mesh, images):
    """The :data:`~methods.imaging.region.Scene` a commit draws in: a commit merges no
    wedges, so any int64 arrays stand for the wedge map."""
    iws = images.iws
    return Scene(P=mesh.P, F=mesh.F, FW=mesh.FW, uv=mesh.uv, falive=mesh.falive,
                 img=images.img, tiles=images.tiles, iws=iws, wfrom=iws.cand, wto=iws.cand,
                 background=float(BACKGROUND))


@njit(cache=True)
def _release_blocked(heap, blocked, w, cost, p, valive):
    """Re-queue w's blocked edges (their validity may have changed) for re-costing,
    each record once, and empty w's list."""
    j = blocked.head[w]
    while j != -1:
        side = 0 if blocked.end[j, 0] == w else 1
        if blocked.live[j]:
            blocked.live[j] = False
            o = blocked.end[j, 1 - side]
            if valive[o]:
                _push(heap, cost, w, o, NO_VERTEX, NO_VERTEX, p, NO_VERTEX)
        j = blocked.next[j, side]
    blocked.head[w] = -1


@njit(cache=True)
def _requeue(taken, lazy, log, mesh, rules, terms, scratch, images):
    """After ``taken`` = (u, v, removed faces, cost, fresh cost), collapsing u into v:
    stamp v, and its neighbours when costs depend on the triangles around an edge (a
    quadric cost of (w, x) depends only on w and x, which did not change); release the
    neighbours' blocked edges; queue v's edges afresh (``lazy``: the heap, the queue's
    bookkeeping and the blocked edges).

    With the seam rule and pure quadric costs, the apexes of the removed faces get fresh
    entries for their edges too: they lost a face, which can change whether they are
    seam vertices (and so the seam rule's verdict on their edges). (With neighbourhood
    costs they were stamped already and are re-costed lazily.) The eager re-costing is
    one loop over v and the apexes, so :func:`_evaluate` has a single call site here:
    each call site is a copy of the costing for numba and LLVM to compile."""
    (u, v, removed, cost, fresh), (heap, queue, blocked) = taken, lazy
    weights, stamp, p, nbr_v = rules.weights, queue.stamp, scratch.p, scratch.nbr_v
    rendered = renders(weights)
    neighbourhood_cost = weights.memoryless != 0.0 or weights.canny != 0.0 or rendered
    nv = mesh.P.shape[0]
    m = _neighbors(v, mesh.F, mesh.vhead, mesh.cnext, mesh.falive, scratch.mark,
                   scratch.tick, nbr_v)
    stamp[v] += 1
    for i in range(m):
        w = nbr_v[i]
        if neighbourhood_cost and w != v:
            stamp[w] += 1
        _release_blocked(heap, blocked, w, cost, p, mesh.valive)
    if rendered:  # the edges' last keys, re-costed when they reach the front
        for i in range(m):
            w = nbr_v[i]
            if w == v:
                continue
            key = fresh
            kv, ku = min(v, w) * nv + max(v, w), min(u, w) * nv + max(u, w)
            if kv in queue.last_key:
                key = queue.last_key[kv]
            elif ku in queue.last_key:
                key = queue.last_key[ku]
            _push(heap, key, v, w, stamp[v], stamp[w], p, NO_VERTEX)
        queue.pushed_at[v] = stamp[v]
        return
    apexes = min(removed, 2) if rules.seam_rule and not neighbourhood_cost else 0
    n = log.count[LOG_COLLAPSES]
    for k in range(1 + apexes):
        x, nbr, mx = v, nbr_v, m
        if k > 0:  # the apex of the (k-1)-th removed face
            x = _third(mesh.F, log.faces[n - 1, k - 1], u, v)
            if x == -1 or not mesh.valive[x]:
                continue
            stamp[x] += 1
            nbr = scratch.nbr_u
            mx = _neighbors(x, mesh.F, mesh.vhead, mesh.cnext, mesh.falive, scratch.mark,
                            scratch.tick, nbr)
        for i in range(mx):
            y = nbr[i]
            if y == x:
                continue
            c, kept = _cost(x, y, mesh, rules, terms, scratch, images, queue)
            _push(heap, c, x, y, stamp[x], stamp[y], scratch.p, kept)
        queue.pushed_at[x] = stamp[x]


@njit(cache=True)
def _new_log(max_collapses, m):
    """An empty :data:`~methods.engine.state.Log` for ``max_collapses`` collapses of a
    mesh of ``m`` faces."""
    c = max_collapses
    return Log(cost=np.empty(c), removed=np.empty(c, np.int32), kept=np.empty(c, np.int32),
               pos=np.empty((c, 3)), faces=np.full((c, 2), -1, np.int64),
               start=np.zeros(c + 1, np.int64),
               changed=np.empty(max(LOG_CHANGED_MIN, 3 * m), np.int64),
               pair_start=np.zeros(c + 1, np.int64),
               pairs=np.empty((max(WEDGE_PAIRS_CAP, c), 2), np.int64),
               wedge_start=np.zeros(c + 1, np.int64),
               wedges=np.empty(max(WEDGE_TARGETS_CAP, 2 * c), np.int64),
               wedge_uv=np.empty((max(WEDGE_TARGETS_CAP, 2 * c), 2)),
               count=np.zeros(N_LOG_COUNTS, np.int64))


@njit(cache=True)
def _new_queue(nv):
    """An empty :data:`~methods.engine.state.Queue` (and its heap) for ``nv`` vertices.

    ``pushed_at[x]``: x's stamp when entries for all of its edges were last pushed. An
    entry older than that on either end has a newer one in the heap (every edge created
    since then was pushed fresh by the collapse that made it), so it can be dropped.
    ``last_key``: with the image term, the kept vertex's edges are queued lazily too
    (Lindstrom & Turk 2000, §4.2.2: an edge keeps its key and is re-costed when it
    reaches the front); their last keys are remembered per edge."""
    heap = [(0.0, np.int64(0), np.int64(0), np.int64(0), np.int64(0), 0.0, 0.0, 0.0,
             np.int64(0))]
    heap.pop()
    last_key = Dict.empty(key_type=types.int64, value_type=types.float64)
    return heap, Queue(stamp=np.zeros(nv, np.int64), pushed_at=np.zeros(nv, np.int64),
                       last_key=last_key, tally=np.zeros(2, np.int64))


@njit(cache=True)
def _new_blocked(nv):
    """No blocked edges yet. Blocked edges are rejected candidates, re-queued once when
    either endpoint's stamp changes. Each record is linked into both endpoints' lists
    and dies when re-queued, so an edge is pushed once per rejection, never once per
    list it sits in."""
    return Blocked(end=np.empty((BLOCKED_INITIAL, 2), np.int64),
                   next=np.empty((BLOCKED_INITIAL, 2), np.int64),
                   live=np.zeros(BLOCKED_INITIAL, np.bool_), head=np.full(nv, -1, np.int64),
                   count=np.zeros(1, np.int64))


@njit(cache=True, nogil=True)
def _run(mesh, rules, terms, scratch, images, kinds, first):
    """Collapse edges of ``mesh`` until ``rules.target`` faces remain, no valid collapse
    does, or ``rules.max_collapses`` were taken, starting from every edge's first cost
    (``first``: :func:`methods.engine.initial.first_costs`).

    Returns (stopped (1: no valid collapse remains), evaluations, mismatches, rejects
    (counts by rejection code - 1), log (:data:`~methods.engine.state.Log`, trimmed
    by the caller to its ``count``))."""
    run_start = cycles()
    # The hot path sees the state without reference counts (methods.engine.borrow):
    # the arguments outlive the loop, and ``owned_queue`` is read after it.
    mesh, terms, scratch, images, kinds = borrowed((mesh, terms, scratch, images, kinds))
    nv, F = mesh.P.shape[0], mesh.F
    heap, owned_queue = _new_queue(nv)
    queue = borrowed(owned_queue)
    rejects = np.zeros(_N_REJECTIONS, np.int64)
    log = _new_log(rules.max_collapses, F.shape[0])
    blocked = _new_blocked(nv)
    # Collect: every edge, costed once at the original mesh before the loop.
    _collect_candidates(heap, first, rules, queue, nv)
    faces = 0
    for f in range(F.shape[0]):
        if mesh.falive[f]:
            faces += 1
    stopped = 1
    while len(heap) > 0:
        if faces <= rules.target:
            stopped = 0
            break
        # Pop the cheapest current candidate (stale ones are re-costed on the way).
        found, cost, fresh, a, b, keep = _pop_current(heap, mesh, rules, terms, scratch,
                                                      images, queue)
        if not found:
            break
        u = a if keep == b else b
        v = keep
        # Check it; a rejected edge waits until an endpoint changes.
        code = _check_candidate(u, v, fresh, mesh, rules, scratch)
        if code != VALID:
            rejects[code - 1] += 1
            blocked = _block(blocked, a, b)
            continue
        if log.count[LOG_COLLAPSES] >= rules.max_collapses:
            break
        # Take it: log, collapse, update the images.
        log = _log_collapse(log, u, v, fresh, scratch.p)
        removed, images = _take(u, v, mesh, rules, terms, scratch, images, (log, kinds))
        faces -= removed
        mesh.vboundary[v] = mesh.vboundary[v] or mesh.vboundary[u]  # stays a boundary
        # Stamp and re-queue: the costs around v changed.
        _requeue((u, v, removed, cost, fresh), (heap, queue, blocked), log, mesh, rules, terms,
                 scratch, images)
    if faces <= rules.target:
        stopped = 0
    images.img.stats[STAT_RUN_CYCLES] += cycles() - run_start
    tally = owned_queue.tally
    return (stopped, tally[EVALUATIONS], tally[MISMATCHES], rejects, log)


def compile_collapse(mesh, rules, terms, scratch, images, kinds) -> None:
    """Compile (or read from numba's cache) the kernels with which :func:`_run` checks,
    logs and takes a collapse, for the types of these arguments and without running
    them, so that another process can compile the costing meanwhile
    (:func:`methods.engine.simplify.compile_part`)."""
    log = _new_log(rules.max_collapses, mesh.F.shape[0])
    u = np.int64(0)
    for kernel, args in ((_take, (u, u, mesh, rules, terms, scratch, images, (log, kinds))),
                         (_check_candidate, (u, u, 0.0, mesh, rules, scratch)),
                         (_log_collapse, (log, u, u, 0.0, scratch.p))):
        kernel.compile(tuple(numba.typeof(a) for a in args))
