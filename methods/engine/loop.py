"""The engine's loop (numba): queue every edge, then pop, re-cost if stale, check,
collapse, update images, stamp and re-queue neighbours, log."""

from __future__ import annotations

import heapq

import numpy as np
from numba import njit, types
from numba.typed import Dict

from methods.engine.collapse import _collapse
from methods.engine.cost import _evaluate
from methods.engine.policy import _N_REJECTIONS
from methods.engine.topology import _check, _edge_faces, _neighbors, _third
from methods.imaging.counters import cycles
from methods.imaging.region import commit_geometry, commit_render
from methods.imaging.tiles import TILE, build_tiles
from metrics.shading import BACKGROUND


@njit(cache=True)
def _push(heap, cost, a, b, sa, sb, p, keep):
    """Queue edge (a, b) at ``cost`` with its endpoints' stamps, the kept vertex's new
    position ``p`` and which end is kept (stamps -1: re-cost when popped)."""
    heapq.heappush(heap, (float(cost), np.int64(a), np.int64(b), np.int64(sa), np.int64(sb),
                          float(p[0]), float(p[1]), float(p[2]), np.int64(keep)))


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
