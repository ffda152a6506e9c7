"""Region re-rendering: a view's rectangle around a collapse drawn as it would look
after it (:func:`image_cost`, equation 8 of Lindstrom & Turk 2000) or as it is after
it (:func:`commit_geometry`, :func:`commit_render`)."""

from __future__ import annotations

import numpy as np
from numba import njit

from methods.imaging.counters import cycles
from methods.imaging.entropy import _entropy_change
from methods.imaging.raster import scan_row, shade_pixel
from methods.imaging.rows import (
    _light,
    _pos,
    fill_screen,
    fill_shading,
    project,
    row_box,
    vertex_normal,
)
from methods.imaging.tiles import TILE, _gather, _tiles_add

_MAX_RING = 256  # vertices whose normal a collapse changes (more: 2-ring of a huge fan)


@njit(cache=True)
def _grow(rect, box):
    if box[0] > box[1] or box[2] > box[3]:
        return
    if rect[0] > rect[1]:
        rect[0], rect[1], rect[2], rect[3] = box[0], box[1], box[2], box[3]
    else:
        rect[0], rect[1] = min(rect[0], box[0]), max(rect[1], box[1])
        rect[2], rect[3] = min(rect[2], box[2]), max(rect[3], box[3])


@njit(cache=True)
def _has(F, f, x):
    return F[f, 0] == x or F[f, 1] == x or F[f, 2] == x


@njit(cache=True)
def _faces_around(y, vhead, cnext, falive, mark, tk, out, n):
    c = vhead[y]
    while c != -1:
        f = c // 3
        if falive[f] and mark[f] != tk and n < out.shape[0]:
            mark[f] = tk
            out[n] = f
            n += 1
        c = cnext[c]
    return n


@njit(cache=True)
def _render_view(h, rect, na, u, v, sp, p, P, F, FW, uv, falive, img, tiles, iws, wfrom,
                 wto, npairs, atick, commit, background):
    """Re-render ``rect`` of view ``h`` as the mesh looks after collapsing ``u`` into
    ``v`` at ``p`` (``u = -1``: as it is now, after a collapse already made).

    ``aff[:na]`` are the faces whose geometry changes (with ``u >= 0`` those holding
    both ``u`` and ``v`` disappear); they and any removed faces carry
    ``gmark == atick``, and every face whose shading may change carries
    ``amark == atick``. A pixel keeps its current face unless that face is one of the
    changed ones (a *hole*): the kept faces' depth is known (``DZ``), so only the
    changed faces are scanned over the whole rectangle, and the other faces only over
    the holes' bounding box. Depth ties go to the lower face id, so the result is the
    from-scratch render's. With ``commit`` the pixels go into ``Y``, ``IDS`` and
    ``DZ``; otherwise returns the change of the squared error (equation 8).
    """
    M, eyes, cull, Y0, Y, S, fbox, vn, L, consts, texture, stats, IDS, DZ, ent = img
    (mark, tick, cand, t, depth, ids, vslot, ov_light, wslot, new_uv, ring, rects, buf, n3,
     sp_, box, aff, amark, gmark, rowof, rowmark) = iws
    n_views, height, width = Y.shape
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    start = cycles()
    hc0, hc1, hr0, hr1 = width, -1, height, -1
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            w = IDS[h, r, c]
            if w >= 0 and gmark[w] == atick:
                depth[r - r0, c - c0] = np.inf
                ids[r - r0, c - c0] = -1
                hc0, hc1 = min(hc0, c), max(hc1, c)
                hr0, hr1 = min(hr0, r), max(hr1, r)
            else:
                depth[r - r0, c - c0] = DZ[h, r, c]
                ids[r - r0, c - c0] = w
    n = 0
    for i in range(na):
        f = aff[i]
        if u >= 0 and _has(F, f, u) and _has(F, f, v):
            continue  # removed by the collapse
        cand[n] = f
        rowof[f] = n
        fill_screen(t, n, f, h, u, v, sp, S, F)
        scan_row(t, n, f, c0, c1, r0, r1, cull[h], depth, ids)
        n += 1
    if hc0 <= hc1:  # what the changed faces uncover: every other face over the holes
        tick[0] += 1
        for i in range(na):
            mark[aff[i]] = tick[0]
        hole = box
        hole[0], hole[1], hole[2], hole[3] = hc0, hc1, hr0, hr1
        g0 = cycles()
        n2 = _gather(tiles, h, hole, fbox, falive, mark, tick[0], cand, n, TILE,
                     -(-width // TILE))
        stats[7] += cycles() - g0
        hole_depth = depth[hr0 - r0:, hc0 - c0:]  # views indexed from the holes' corner
        hole_ids = ids[hr0 - r0:, hc0 - c0:]
        for k in range(n, n2):
            f = cand[k]
            rowof[f] = k
            fill_screen(t, k, f, h, -1, -1, sp, S, F)
            scan_row(t, k, f, hc0, hc1, hr0, hr1, cull[h], hole_depth, hole_ids)
        n = n2
    mid = cycles()
    eflags = ent[6]
    if eflags[0] != 0.0:  # viewpoint entropy: the count changes inside the rectangle
        dh = _entropy_change(h, rect, ids, IDS, ent, commit)
        if not commit:
            eflags[3] += abs(dh)
    if eflags[2] == 0.0:  # face ids only, no luminance (entropy without equation 8)
        if commit:
            for r in range(r0, r1 + 1):
                for c in range(c0, c1 + 1):
                    IDS[h, r, c] = ids[r - r0, c - c0]
                    DZ[h, r, c] = depth[r - r0, c - c0]
        stats[2] += n
        stats[3] += cycles() - start
        return 0.0
    tick[0] += 1
    filled = tick[0]  # rows whose shading columns are filled are marked with it
    cost = 0.0
    shaded = 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            f = ids[r - r0, c - c0]
            if f == IDS[h, r, c] and (f < 0 or amark[f] != atick):
                continue  # the same face, unchanged: the same luminance
            y = background
            if f >= 0:
                k = rowof[f]
                if k >= n or cand[k] != f:  # kept face, only its shading changes: a row
                    k = n
                    cand[k] = f
                    rowof[f] = k
                    fill_screen(t, k, f, h, u, v, sp, S, F)
                    n += 1
                if rowmark[k] != filled:
                    fill_shading(t, k, f, h, u, v, p, P, F, FW, uv, L, vslot, ov_light,
                                 wslot, new_uv, wfrom, wto, npairs, consts)
                    rowmark[k] = filled
                y = shade_pixel(t, k, c + 0.5, r + 0.5, eyes[h], consts, texture)
            shaded += 1
            if commit:
                Y[h, r, c] = y
                IDS[h, r, c] = f
                DZ[h, r, c] = depth[r - r0, c - c0]
            else:
                a = Y0[h, r, c] - y
                b = Y0[h, r, c] - Y[h, r, c]
                cost += a * a - b * b
    end = cycles()
    stats[1] += shaded
    stats[2] += n
    stats[3] += end - start
    stats[8] += end - mid
    return cost


@njit(cache=True)
def image_cost(u, v, p, P, F, FW, uv, falive, vhead, cnext, img, tiles, iws, wfrom, wto,
               npairs, targets, nt, target_uv, background):
    """Equation 8 for collapsing ``u`` into ``v`` at ``p``: the change of the summed
    squared luminance error over every view's rectangle. ``targets[:nt]`` are the wedges
    whose texture coordinates become ``target_uv[:nt]``."""
    M, eyes, cull, Y0, Y, S, fbox, vn, L, consts, texture, stats, IDS, DZ, ent = img
    (mark, tick, cand, t, depth, ids, vslot, ov_light, wslot, new_uv, ring, rects, buf, n3,
     sp, box, aff, amark, gmark, rowof, rowmark) = iws
    n_views, height, width = Y.shape
    gouraud = consts[6] != 0.0
    stats[0] += 1
    ent[6][3] = 0.0  # sum of |dH_v| of this evaluation, read by the engine
    setup_start = cycles()
    for i in range(nt):
        wslot[targets[i]] = i
        new_uv[i, 0], new_uv[i, 1] = target_uv[i, 0], target_uv[i, 1]
    # the faces around the edge ([[e]]; those holding both ends disappear)
    tick[0] += 1
    na = _faces_around(u, vhead, cnext, falive, mark, tick[0], aff, 0)
    if not (p[0] == P[v, 0] and p[1] == P[v, 1] and p[2] == P[v, 2]):
        na = _faces_around(v, vhead, cnext, falive, mark, tick[0], aff, na)
    # else a half-edge collapse: v stays, so its faces without u keep their geometry,
    # texture coordinates and pixels (gouraud adds them below, as v's normal changes)
    ns = na
    nr = 0
    if gouraud:  # vertices whose normal changes, and the faces they shade (footnote 3)
        for i in range(na):
            for j in range(3):
                x = F[aff[i], j]
                if x != u and vslot[x] < 0 and nr < ring.shape[0]:
                    vslot[x] = nr
                    ring[nr] = x
                    nr += 1
        for i in range(nr):
            x = ring[i]
            vertex_normal(x, u, v, p, P, F, vhead, cnext, falive, buf, n3)
            for h in range(n_views):
                _light(_pos(x, u, v, p, P, 0), _pos(x, u, v, p, P, 1), _pos(x, u, v, p, P, 2),
                       n3, eyes[h], consts, ov_light[h, i], 0)
            ns = _faces_around(x, vhead, cnext, falive, mark, tick[0], aff, ns)
    atick = tick[0]
    for i in range(ns):
        amark[aff[i]] = atick
    for i in range(na):
        gmark[aff[i]] = atick
    cost = 0.0
    stats[9] += cycles() - setup_start
    for h in range(n_views):
        project(M, h, p, width, height, sp)
        rect = rects[h]
        rect[0], rect[1], rect[2], rect[3] = 0, -1, 0, -1
        for i in range(ns):
            _grow(rect, fbox[h, aff[i]])
        for i in range(na):
            f = aff[i]
            if not (_has(F, f, u) and _has(F, f, v)):
                fill_screen(t, 0, f, h, u, v, sp, S, F)
                row_box(t, 0, width, height, box)
                _grow(rect, box)
        if rect[0] > rect[1] or rect[2] > rect[3]:
            continue
        cost += _render_view(h, rect, na, u, v, sp, p, P, F, FW, uv, falive, img, tiles, iws,
                             wfrom, wto, npairs, atick, False, background)
    for i in range(nr):
        vslot[ring[i]] = -1
    for i in range(nt):
        wslot[targets[i]] = -1
    return cost


@njit(cache=True)
def commit_geometry(v, removed, n_removed, P, F, FW, uv, falive, vhead, cnext, valive, img,
                    tiles, iws):
    """After collapsing into ``v`` (faces ``removed[:n_removed]`` deleted): update screen
    positions, normals, lighting and face boxes, note each view's rectangle, and list
    the changed faces in the tile index. Returns (whether no tile overflowed, how many
    faces around ``v`` changed); after an overflow rebuild the index before
    :func:`commit_render`."""
    M, eyes, cull, Y0, Y, S, fbox, vn, L, consts, texture, stats, IDS, DZ, ent = img
    (mark, tick, cand, t, depth, ids, vslot, ov_light, wslot, new_uv, ring, rects, buf, n3,
     sp, box, aff, amark, gmark, rowof, rowmark) = iws
    n_views, height, width = Y.shape
    gouraud = consts[6] != 0.0
    stats[6] += 1
    tick[0] += 1
    na = _faces_around(v, vhead, cnext, falive, mark, tick[0], aff, 0)
    for h in range(n_views):
        rects[h, 0], rects[h, 1], rects[h, 2], rects[h, 3] = 0, -1, 0, -1
        project(M, h, P[v], width, height, S[h, v])
        for i in range(n_removed):
            _grow(rects[h], fbox[h, removed[i]])
    ns = na
    if gouraud:
        nr = 0
        for i in range(na + n_removed):
            f = aff[i] if i < na else removed[i - na]
            for j in range(3):
                x = F[f, j]
                if valive[x] and vslot[x] < 0 and nr < ring.shape[0]:
                    vslot[x] = nr
                    ring[nr] = x
                    nr += 1
        for i in range(nr):
            x = ring[i]
            vslot[x] = -1
            vertex_normal(x, -1, -1, P[x], P, F, vhead, cnext, falive, buf, vn[x])
            for h in range(n_views):
                _light(P[x, 0], P[x, 1], P[x, 2], vn[x], eyes[h], consts, L[h, x], 0)
            ns = _faces_around(x, vhead, cnext, falive, mark, tick[0], aff, ns)
    for i in range(ns):
        amark[aff[i]] = tick[0]
    for i in range(na):
        gmark[aff[i]] = tick[0]
    for i in range(n_removed):
        gmark[removed[i]] = tick[0]
    ok = True
    for h in range(n_views):
        for i in range(ns):
            _grow(rects[h], fbox[h, aff[i]])
        for i in range(na):
            f = aff[i]
            fill_screen(t, 0, f, h, -1, -1, sp, S, F)
            row_box(t, 0, width, height, fbox[h, f])
            _grow(rects[h], fbox[h, f])
            if ok:
                ok = _tiles_add(tiles, h, f, fbox[h, f], TILE, -(-width // TILE))
    return ok, na


@njit(cache=True)
def commit_render(na, P, F, FW, uv, falive, img, tiles, iws, background):
    """Re-render every view's rectangle noted by :func:`commit_geometry` into the
    images (``na``: its count of changed faces)."""
    M, eyes, cull, Y0, Y, S, fbox, vn, L, consts, texture, stats, IDS, DZ, ent = img
    (mark, tick, cand, t, depth, ids, vslot, ov_light, wslot, new_uv, ring, rects, buf, n3,
     sp, box, aff, amark, gmark, rowof, rowmark) = iws
    atick = tick[0]  # commit_geometry marked the changed faces with it
    none_i = np.full(1, -1, np.int64)
    for h in range(Y.shape[0]):
        rect = rects[h]
        if rect[0] > rect[1] or rect[2] > rect[3]:
            continue
        _render_view(h, rect, na, -1, -1, sp, P[0], P, F, FW, uv, falive, img, tiles, iws,
                     none_i, none_i, 0, atick, True, background)
