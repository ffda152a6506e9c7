"""The image term of the engine: Lindstrom & Turk 2000, §4.2.

Image-driven simplification costs a collapse by how much it changes the mean-square
luminance error against images of the original, over ``V`` views (equation 8):

    f(e, k) = sum_h sum_{(i, j) in R_h} (y0 - y^{k+1})^2 - (y0 - y^k)^2

where ``R_h`` is view ``h``'s pixel rectangle around the triangles the collapse touches.
This module keeps, inside the engine's numba loop, the images ``Y`` of the *current*
mesh and everything needed to re-render a rectangle of them:

* per view and vertex the screen position, per face and view its pixel bounding box,
  per vertex its unit normal and (gouraud) its lighting in every view;
* a per-view *tile index* (8 x 8-pixel tiles, each listing the faces whose box
  overlaps it) to find the faces under a rectangle;
* :func:`image_cost` renders each view's rectangle as it would look after a *simulated*
  collapse (the kept vertex at its new place, the removed faces gone, new texture
  coordinates and vertex normals) into scratch buffers and returns equation 8;
  :func:`commit_geometry` and :func:`commit_render` do the same for the collapse
  actually made and write it into ``Y``.

Only what can change is drawn (:func:`_render_view`): a pixel whose visible face is
not one of the changed faces keeps that face, whose depth is kept too (``DZ``), so the
changed faces are scanned over the rectangle against those depths, and every other
face is scanned only over the pixels the changed faces used to show (the *holes*):
that is the "un-rendering" of §4.2.3, surfaces hidden behind removed faces reappear.

Rendering is :mod:`methods.raster`'s: each face to draw becomes a row of the per-face
table and the same :func:`~methods.raster.scan_row` and
:func:`~methods.raster.shade_pixel` do the pixels. A pixel goes to the face with the
smaller (depth, face id), whatever order faces are scanned in, which is what a full
render drawing faces in increasing index with ``GL_LESS`` gives. Faces keep their
indices for the life of the engine (a collapse only deletes faces and renames
corners), and every per-vertex quantity is computed by the same function in both
cases (vertex normals summed over incident faces in increasing face index). The
maintained images, face ids and depths therefore equal a from-scratch render **bit for
bit**; ``simplify_mesh(..., verify=True)`` checks it at the end of a run.

The rectangle of a view is the union of the old and the new pixel boxes of every face
around the edge (the paper's ``[[e]] ∪ [[v]]``); with gouraud shading also the boxes of
the faces around the vertices whose normal changes (the paper's footnote 3).

The same region re-renders give the *viewpoint entropy* term of González et al. 2008
(§3, the cost of Castelló et al. 2007; ``ImageTerm.entropy_weight``): the state then
also keeps, per view, the pixel count a_f of every face (and of the background), the
sum S = sum a log a and the total A, so that H_v = log A - S / A. A candidate's new face
ids inside its rectangles, compared with ``IDS``, give the count changes; only the faces
whose count changes enter S and A, so ΔH_v costs one pass over the rectangle
(:func:`_entropy_change`), and a commit updates the counts from the same pixels. With
``weight`` 0 (entropy alone) no pixel is shaded: only ``IDS`` and ``DZ`` are kept.

Tile index versus the paper's row/column buckets: the paper keeps a hash table of
triangles per pixel row and column and intersects the unions over the rectangle with
time stamps. Tiles need no intersection (one traversal), list a small face in one to
four tiles instead of every row and column it spans, and live in flat arrays that numba
traverses quickly. Each tile has spare capacity; a face whose box grows is appended to
the new tiles it reaches, stale entries are filtered by the box test, and the index is
rebuilt only when a tile overflows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from llvmlite import ir
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from methods.raster import (ROW, T_L, T_N, T_P, T_UV, T_W, T_X, T_Y, T_Z, scan_row, shade_pixel,
                            shade_region)

__all__ = ["ImageTerm", "TILE", "STAT_NAMES", "dummy_state", "new_state", "full_render",
           "entropy_init", "entropy_state", "view_entropy"]

#: Side of the square tiles of the per-view face index, in pixels.
TILE = 8
#: Counters kept in the state's ``stats`` array.
STAT_NAMES = ("image_evaluations", "pixels_shaded", "face_rows", "raster_cycles",
              "run_cycles", "tile_rebuilds", "commits", "gather_cycles", "shade_cycles",
              "setup_cycles")
_MAX_RING = 256  # vertices whose normal a collapse changes (more: 2-ring of a huge fan)


@intrinsic
def cycles(typingctx):
    """The CPU cycle counter (``llvm.readcyclecounter``), to split run time by part."""
    sig = types.int64()

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])

    return sig, codegen


# -- per-vertex and per-face quantities ---------------------------------------------------

@njit(cache=True)
def project(M, h, p, width, height, out):
    """Screen (x, y pixels with y down, NDC z, clip w) of point ``p`` in view ``h``."""
    cx = M[h, 0, 0] * p[0] + M[h, 0, 1] * p[1] + M[h, 0, 2] * p[2] + M[h, 0, 3]
    cy = M[h, 1, 0] * p[0] + M[h, 1, 1] * p[1] + M[h, 1, 2] * p[2] + M[h, 1, 3]
    cz = M[h, 2, 0] * p[0] + M[h, 2, 1] * p[1] + M[h, 2, 2] * p[2] + M[h, 2, 3]
    cw = M[h, 3, 0] * p[0] + M[h, 3, 1] * p[1] + M[h, 3, 2] * p[2] + M[h, 3, 3]
    inv_w = 1.0 / cw if cw > 0.0 else 0.0
    out[0] = (cx * inv_w + 1.0) * (0.5 * width)
    out[1] = (1.0 - cy * inv_w) * (0.5 * height)
    out[2] = cz * inv_w
    out[3] = cw


@njit(cache=True)
def row_box(t, k, width, height, out):
    """Pixel box (c0, c1, r0, r1) that :func:`methods.raster.scan_row` visits for row
    ``k`` (c0 > c1 when it visits nothing)."""
    out[0], out[1], out[2], out[3] = 0, -1, 0, -1
    if t[k, T_W] <= 0.0 or t[k, T_W + 1] <= 0.0 or t[k, T_W + 2] <= 0.0:
        return
    x0, x1, x2 = t[k, T_X], t[k, T_X + 1], t[k, T_X + 2]
    y0, y1, y2 = t[k, T_Y], t[k, T_Y + 1], t[k, T_Y + 2]
    if not (np.isfinite(x0) and np.isfinite(x1) and np.isfinite(x2) and np.isfinite(y0)
            and np.isfinite(y1) and np.isfinite(y2)):
        return
    out[0] = int(min(max(np.ceil(min(x0, x1, x2) - 0.5), 0.0), float(width)))
    out[1] = int(max(min(np.floor(max(x0, x1, x2) - 0.5), width - 1.0), -1.0))
    out[2] = int(min(max(np.ceil(min(y0, y1, y2) - 0.5), 0.0), float(height)))
    out[3] = int(max(min(np.floor(max(y0, y1, y2) - 0.5), height - 1.0), -1.0))


@njit(cache=True)
def _light(px, py, pz, n, eye, consts, out, o):
    """Headlight terms of a vertex for both sides, as :func:`methods.raster.vertex_light`:
    out[o:o+4] = (lit front, spec front, lit back, spec back)."""
    tx, ty, tz = eye[0] - px, eye[1] - py, eye[2] - pz
    length = np.sqrt(tx * tx + ty * ty + tz * tz)
    dot = (tx * n[0] + ty * n[1] + tz * n[2]) / length
    for side in range(2):
        c = max(dot if side == 0 else -dot, 0.0)
        out[o + 2 * side] = consts[0] + consts[1] * c
        out[o + 2 * side + 1] = consts[2] * c ** consts[3] if consts[5] != 0.0 else 0.0


@njit(cache=True)
def _sort_small(a, n):
    for i in range(1, n):
        x = a[i]
        j = i - 1
        while j >= 0 and a[j] > x:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = x


@njit(cache=True)
def _pos(x, u, v, p, P, d):
    return p[d] if u >= 0 and (x == u or x == v) else P[x, d]


@njit(cache=True)
def vertex_normal(x, u, v, p, P, F, vhead, cnext, falive, buf, out):
    """Unit area-weighted normal of vertex ``x`` after collapsing ``u`` into ``v`` at
    ``p`` (``u = -1``: the current mesh). Faces are summed in increasing index."""
    n = 0
    for side in range(2):
        y = np.int64(x) if side == 0 else np.int64(u)
        if side == 1 and not (u >= 0 and x == v):
            break
        c = vhead[y]
        while c != -1:
            f = c // 3
            if falive[f]:
                edge = u >= 0 and ((F[f, 0] == u or F[f, 1] == u or F[f, 2] == u) and
                                   (F[f, 0] == v or F[f, 1] == v or F[f, 2] == v))
                if not edge and n < buf.shape[0]:
                    buf[n] = f
                    n += 1
            c = cnext[c]
    _sort_small(buf, n)
    sx = sy = sz = 0.0
    for i in range(n):
        f = buf[i]
        a, b, c = F[f, 0], F[f, 1], F[f, 2]
        ax, ay, az = _pos(a, u, v, p, P, 0), _pos(a, u, v, p, P, 1), _pos(a, u, v, p, P, 2)
        e1x, e1y, e1z = (_pos(b, u, v, p, P, 0) - ax, _pos(b, u, v, p, P, 1) - ay,
                         _pos(b, u, v, p, P, 2) - az)
        e2x, e2y, e2z = (_pos(c, u, v, p, P, 0) - ax, _pos(c, u, v, p, P, 1) - ay,
                         _pos(c, u, v, p, P, 2) - az)
        sx += e1y * e2z - e1z * e2y
        sy += e1z * e2x - e1x * e2z
        sz += e1x * e2y - e1y * e2x
    length = np.sqrt(sx * sx + sy * sy + sz * sz)
    if length > 0.0:
        out[0], out[1], out[2] = sx / length, sy / length, sz / length
    else:
        out[0] = out[1] = out[2] = 0.0


@njit(cache=True)
def fill_screen(t, k, f, h, u, v, sp, S, F):
    """Screen columns of row ``k``: face ``f`` in view ``h`` after collapsing ``u`` into
    ``v`` (whose screen position becomes ``sp``); ``u = -1`` for the current mesh."""
    for j in range(3):
        x = F[f, j]
        if u >= 0 and (x == u or x == v):
            t[k, T_X + j], t[k, T_Y + j], t[k, T_Z + j], t[k, T_W + j] = sp[0], sp[1], \
                sp[2], sp[3]
        else:
            t[k, T_X + j], t[k, T_Y + j], t[k, T_Z + j], t[k, T_W + j] = S[h, x, 0], \
                S[h, x, 1], S[h, x, 2], S[h, x, 3]


@njit(cache=True)
def fill_shading(t, k, f, h, u, v, p, P, F, FW, uv, L, vslot, ov_light, wslot, new_uv,
                 wfrom, wto, npairs, consts):
    """Shading columns of row ``k`` (as :func:`fill_screen`): corner positions and the
    face normal (flat), corner lighting (gouraud; the new lighting of the vertices in
    ``vslot``), texture coordinates (the new ones of the wedges in ``wslot``)."""
    gouraud, textured = consts[6] != 0.0, consts[7] != 0.0
    for j in range(3):
        x = F[f, j]
        moved = u >= 0 and (x == u or x == v)
        for d in range(3):
            t[k, T_P + 3 * j + d] = p[d] if moved else P[x, d]
        if gouraud:
            slot = vslot[v if moved else x]
            for d in range(4):
                t[k, T_L + 4 * j + d] = ov_light[h, slot, d] if slot >= 0 else L[h, x, d]
        if textured:
            w = FW[f, j]
            if u >= 0 and x == u:
                for i in range(npairs):
                    if wfrom[i] == w:
                        w = wto[i]
                        break
            s = wslot[w]
            t[k, T_UV + 2 * j] = new_uv[s, 0] if s >= 0 else uv[w, 0]
            t[k, T_UV + 2 * j + 1] = new_uv[s, 1] if s >= 0 else uv[w, 1]
    if not gouraud:
        e1x = t[k, T_P + 3] - t[k, T_P]
        e1y = t[k, T_P + 4] - t[k, T_P + 1]
        e1z = t[k, T_P + 5] - t[k, T_P + 2]
        e2x = t[k, T_P + 6] - t[k, T_P]
        e2y = t[k, T_P + 7] - t[k, T_P + 1]
        e2z = t[k, T_P + 8] - t[k, T_P + 2]
        nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        inv = 1.0 / length if length > 0.0 else 0.0
        t[k, T_N], t[k, T_N + 1], t[k, T_N + 2] = nx * inv, ny * inv, nz * inv


# -- the tile index -----------------------------------------------------------------------

@njit(cache=True)
def build_tiles(fbox, falive, tile, nx, ny):
    """Per view and tile, the live faces whose box overlaps it, with spare room.

    Returns (ptr (V, T + 1), cnt (V, T), items, ibox (V, m, 4) tile ranges listed)."""
    n_views, m = fbox.shape[0], fbox.shape[1]
    n_tiles = nx * ny
    cnt = np.zeros((n_views, n_tiles), np.int64)
    ibox = np.zeros((n_views, m, 4), np.int32)
    for h in range(n_views):
        for f in range(m):
            ibox[h, f, 0], ibox[h, f, 1], ibox[h, f, 2], ibox[h, f, 3] = 0, -1, 0, -1
            if not falive[f] or fbox[h, f, 0] > fbox[h, f, 1] or fbox[h, f, 2] > fbox[h, f, 3]:
                continue
            ibox[h, f, 0], ibox[h, f, 1] = fbox[h, f, 0] // tile, fbox[h, f, 1] // tile
            ibox[h, f, 2], ibox[h, f, 3] = fbox[h, f, 2] // tile, fbox[h, f, 3] // tile
            for ty in range(ibox[h, f, 2], ibox[h, f, 3] + 1):
                for tx in range(ibox[h, f, 0], ibox[h, f, 1] + 1):
                    cnt[h, ty * nx + tx] += 1
    ptr = np.zeros((n_views, n_tiles + 1), np.int64)
    total = 0
    for h in range(n_views):
        for i in range(n_tiles):
            ptr[h, i] = total
            total += cnt[h, i] + cnt[h, i] // 2 + 8
        ptr[h, n_tiles] = total
    items = np.empty(total, np.int32)
    cnt[:] = 0
    for h in range(n_views):
        for f in range(m):
            for ty in range(ibox[h, f, 2], ibox[h, f, 3] + 1):
                for tx in range(ibox[h, f, 0], ibox[h, f, 1] + 1):
                    i = ty * nx + tx
                    items[ptr[h, i] + cnt[h, i]] = f
                    cnt[h, i] += 1
    return ptr, cnt, items, ibox


@njit(cache=True)
def _tiles_add(tiles, h, f, box, tile, nx):
    """List face ``f`` in the tiles its new ``box`` reaches; False if a tile is full."""
    ptr, cnt, items, ibox = tiles
    if box[0] > box[1] or box[2] > box[3]:
        return True
    tx0, tx1, ty0, ty1 = box[0] // tile, box[1] // tile, box[2] // tile, box[3] // tile
    for ty in range(ty0, ty1 + 1):
        for tx in range(tx0, tx1 + 1):
            if ibox[h, f, 0] <= tx <= ibox[h, f, 1] and ibox[h, f, 2] <= ty <= ibox[h, f, 3]:
                continue  # listed already
            i = ty * nx + tx
            if ptr[h, i] + cnt[h, i] >= ptr[h, i + 1]:
                return False
            items[ptr[h, i] + cnt[h, i]] = f
            cnt[h, i] += 1
    ibox[h, f, 0], ibox[h, f, 1], ibox[h, f, 2], ibox[h, f, 3] = tx0, tx1, ty0, ty1
    return True


@njit(cache=True)
def _overlaps(box, rect):
    return not (box[0] > box[1] or box[2] > box[3] or box[1] < rect[0] or box[0] > rect[1]
                or box[3] < rect[2] or box[2] > rect[3])


@njit(cache=True)
def _gather(tiles, h, rect, fbox, falive, mark, tick, cand, n, tile, nx):
    """Append to ``cand[n:]`` the live, unmarked faces whose box overlaps ``rect``."""
    ptr, cnt, items, _ = tiles
    for ty in range(rect[2] // tile, rect[3] // tile + 1):
        for tx in range(rect[0] // tile, rect[1] // tile + 1):
            i = ty * nx + tx
            for k in range(ptr[h, i], ptr[h, i] + cnt[h, i]):
                f = items[k]
                if mark[f] != tick and falive[f] and _overlaps(fbox[h, f], rect):
                    mark[f] = tick
                    cand[n] = f
                    n += 1
    return n


# -- evaluation and commit ----------------------------------------------------------------

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


# -- viewpoint entropy (González et al. 2008, §3 "Error metric") -----------------------
# ``ent`` = (CNT (V, m + 1) int64 pixels per view of each face, index f + 1, 0 = the
# background; SUM (V,) float64 = sum of a log a over the counted entries; TOT (V,) int64
# = sum of a; dcnt, emark, touched (m + 1,) int64 scratch; flags (4,) float64 = (entropy
# on, background counted, luminance shaded, sum of |dH_v| of the last evaluation);
# etick (1,) int64).

@njit(cache=True)
def _xlogx(a):
    return a * np.log(a) if a > 0.0 else 0.0


@njit(cache=True)
def view_entropy(s, a):
    """H = log A - S / A, with S = sum a_i log a_i and A = sum a_i: the viewpoint
    entropy -sum (a_i / A) log(a_i / A) (natural logarithm); 0 for an empty view."""
    return np.log(a) - s / a if a > 0.0 else 0.0


@njit(cache=True)
def entropy_init(IDS, ent):
    """Set the per-view face pixel counts, their sum of a log a and total from ``IDS``."""
    CNT, SUM, TOT, dcnt, emark, touched, flags, etick = ent
    n_views, height, width = IDS.shape
    first = 0 if flags[1] != 0.0 else 1  # the background is entry 0
    for h in range(n_views):
        for x in range(CNT.shape[1]):
            CNT[h, x] = 0
        for r in range(height):
            for c in range(width):
                CNT[h, IDS[h, r, c] + 1] += 1
        s = 0.0
        a = 0
        for x in range(first, CNT.shape[1]):
            if CNT[h, x] > 0:
                s += _xlogx(float(CNT[h, x]))
                a += CNT[h, x]
        SUM[h] = s
        TOT[h] = a


@njit(cache=True)
def _entropy_change(h, rect, ids, IDS, ent, commit):
    """Change of view ``h``'s entropy when the faces seen in ``rect`` become ``ids``
    (rectangle-relative) instead of ``IDS``: only the faces whose pixel count changes
    enter S = sum a log a and A. With ``commit`` the counts, S and A are updated."""
    CNT, SUM, TOT, dcnt, emark, touched, flags, etick = ent
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    etick[0] += 1
    tk = etick[0]
    n = 0
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            old = IDS[h, r, c] + 1
            new = ids[r - r0, c - c0] + 1
            if old == new:
                continue
            if emark[old] != tk:
                emark[old] = tk
                touched[n] = old
                n += 1
            if emark[new] != tk:
                emark[new] = tk
                touched[n] = new
                n += 1
            dcnt[old] -= 1
            dcnt[new] += 1
    s = SUM[h]
    a = TOT[h]
    for i in range(n):
        x = touched[i]
        d = dcnt[x]
        dcnt[x] = 0
        cur = CNT[h, x]
        if commit:
            CNT[h, x] = cur + d
        if d == 0 or (x == 0 and flags[1] == 0.0):
            continue
        s += _xlogx(float(cur + d)) - _xlogx(float(cur))
        a += d
    dh = view_entropy(s, float(a)) - view_entropy(SUM[h], float(TOT[h]))
    if commit:
        SUM[h] = s
        TOT[h] = a
    return dh


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


# -- state --------------------------------------------------------------------------------

def _workspace(n_views, nv, m, n_wedges, height, width):
    """Scratch arrays: (mark, tick, cand, t, depth, ids, vslot, ov_light, wslot, new_uv,
    ring, rects, buf, n3, sp, box, aff, amark, gmark, rowof, rowmark)."""
    m = max(m, 1)
    return (np.zeros(m, np.int64), np.zeros(1, np.int64), np.empty(m, np.int64),
            np.empty((m, ROW)), np.empty((height, width)), np.empty((height, width), np.int64),
            np.full(nv, -1, np.int64), np.zeros((n_views, _MAX_RING, 4)),
            np.full(n_wedges, -1, np.int64), np.zeros((64, 2)), np.empty(_MAX_RING, np.int64),
            np.empty((n_views, 4), np.int64), np.empty(1024, np.int64), np.empty(3),
            np.empty(4), np.empty(4, np.int64), np.empty(8192, np.int64),
            np.zeros(m, np.int64), np.zeros(m, np.int64), np.zeros(m, np.int64),
            np.zeros(m, np.int64))


def entropy_state(n_views, m, on=False, background=True, shade=True):
    """The ``ent`` member of an image state: per-view face pixel counts and scratch
    (see :func:`entropy_init`); (1, 1) placeholders when the entropy term is off."""
    size = m + 1 if on else 1
    flags = np.array([float(on), float(background), float(shade), 0.0])
    return (np.zeros((n_views if on else 1, size), np.int64), np.zeros(max(n_views, 1)),
            np.zeros(max(n_views, 1), np.int64), np.zeros(size, np.int64),
            np.zeros(size, np.int64), np.zeros(size, np.int64), flags, np.zeros(1, np.int64))


def dummy_state():
    """An image state of the right types for engine runs without the image term."""
    img = (np.zeros((1, 4, 4)), np.zeros((1, 3)), np.zeros(1, np.bool_), np.zeros((1, 1, 1)),
           np.zeros((1, 1, 1)), np.zeros((1, 1, 4)), np.zeros((1, 1, 4), np.int32),
           np.zeros((1, 3)), np.zeros((1, 1, 4)), np.zeros(8), np.zeros((1, 1, 3), np.uint8),
           np.zeros(len(STAT_NAMES), np.int64), np.zeros((1, 1, 1), np.int64),
           np.zeros((1, 1, 1)), entropy_state(1, 1))
    tiles = (np.zeros((1, 2), np.int64), np.zeros((1, 1), np.int64), np.zeros(1, np.int32),
             np.zeros((1, 1, 4), np.int32))
    return img, tiles, _workspace(1, 1, 1, 1, 1, 1)


def new_state(M, eyes, cull, Y0, consts, texture, nv, m, n_wedges, entropy=None):
    """Arrays of an image state; :func:`full_render` fills them.

    Parameters
    ----------
    M : ndarray (V, 4, 4)
        Clip-space transform of each view, applied to engine positions.
    eyes : ndarray (V, 3)
        Eye positions in engine coordinates (the headlight).
    cull : ndarray (V,) bool
        Views drawn with front faces culled (interior views, §5.2).
    Y0 : ndarray (V, H, W)
        Luminance of the original model.
    consts : ndarray (8,)
        :func:`methods.raster.shading_constants`.
    texture : ndarray (h, w, 3) uint8
    nv, m, n_wedges : int
        Vertices, faces and wedges of the engine mesh.
    entropy : (bool, bool), optional
        (background counted, luminance shaded): keep the viewpoint entropy's face pixel
        counts (:func:`entropy_init` fills them after :func:`full_render`).
    """
    n_views, height, width = Y0.shape
    img = (np.ascontiguousarray(M, np.float64), np.ascontiguousarray(eyes, np.float64),
           np.ascontiguousarray(cull, np.bool_), np.ascontiguousarray(Y0, np.float64),
           np.full(Y0.shape, 128.0), np.zeros((n_views, nv, 4)),
           np.zeros((n_views, m, 4), np.int32), np.zeros((nv, 3)), np.zeros((n_views, nv, 4)),
           np.ascontiguousarray(consts, np.float64), np.ascontiguousarray(texture, np.uint8),
           np.zeros(len(STAT_NAMES), np.int64), np.full(Y0.shape, -1, np.int64),
           np.full(Y0.shape, np.inf),
           entropy_state(n_views, m) if entropy is None else
           entropy_state(n_views, m, True, entropy[0], entropy[1]))
    return img, _workspace(n_views, nv, m, n_wedges, height, width)


@njit(cache=True, parallel=True)
def full_render(img, iws, P, F, FW, uv, falive, vhead, cnext, valive, background):
    """Set every per-vertex and per-face quantity from the mesh and render all views
    from scratch into ``Y``, ``IDS`` (the face seen at each pixel, -1 empty) and ``DZ``
    (its depth)."""
    M, eyes, cull, Y0, Y, S, fbox, vn, L, consts, texture, stats, IDS, DZ, ent = img
    vslot, ov_light, wslot, new_uv = iws[6], iws[7], iws[8], iws[9]
    n_views, height, width = Y.shape
    nv, m = P.shape[0], F.shape[0]
    gouraud = consts[6] != 0.0
    for i in prange(nv):
        if not valive[i]:
            continue
        for h in range(n_views):
            project(M, h, P[i], width, height, S[h, i])
    if gouraud:
        for i in prange(nv):
            if not valive[i]:
                continue
            buf = np.empty(1024, np.int64)
            vertex_normal(i, -1, -1, P[i], P, F, vhead, cnext, falive, buf, vn[i])
            for h in range(n_views):
                _light(P[i, 0], P[i, 1], P[i, 2], vn[i], eyes[h], consts, L[h, i], 0)
    live = np.flatnonzero(falive)
    for h in prange(n_views):
        t = np.empty((max(live.shape[0], 1), ROW))
        depth = np.full((height, width), np.inf)
        local = np.full((height, width), -1, np.int32)
        none_i = np.full(1, -1, np.int64)
        for k in range(live.shape[0]):
            fill_screen(t, k, live[k], h, -1, -1, S[h, 0], S, F)
            fill_shading(t, k, live[k], h, -1, -1, P[0], P, F, FW, uv, L, vslot, ov_light,
                         wslot, new_uv, none_i, none_i, 0, consts)
            row_box(t, k, width, height, fbox[h, live[k]])
            scan_row(t, k, k, 0, width - 1, 0, height - 1, cull[h], depth, local)
        shade_region(t, local, 0, width - 1, 0, height - 1, eyes[h], consts, texture,
                     background, Y[h])
        for r in range(height):
            for c in range(width):
                IDS[h, r, c] = live[local[r, c]] if local[r, c] >= 0 else -1
                DZ[h, r, c] = depth[r, c]


# -- the Python side ----------------------------------------------------------------------

@dataclass(frozen=True)
class ImageTerm:
    """The image cost of :func:`methods.engine.simplify_mesh` (Lindstrom & Turk 2000).

    Attributes
    ----------
    cameras : sequence of V metrics.views.Camera
        Fitted to the ORIGINAL model, like ``reference``.
    reference : ndarray (V, H, W)
        Luminance of the original model in those views (``Y^0``), rendered with the
        same settings (:func:`methods.raster.rasterize_luminance`).
    shading : {"flat", "gouraud"}
    specular : bool
    cull_front : sequence of V bool, optional
        Views drawn with front faces culled (§5.2's interior views).
    weight : float
        Multiplies equation 8 in the engine's cost sum. 0 with ``entropy_weight`` set:
        only face ids are rendered (no shading, ``Y`` is not kept up to date).
    constants : metrics.render.ShadingConstants, optional
    entropy_weight : float
        Multiplies the sum over views of |change of the viewpoint entropy| (González et
        al. 2008, §3), computed from the same region re-renders (0: off).
    entropy_background : bool
        Count the background as one more "face" in the entropy (Vázquez et al.'s
        definition); otherwise only the faces' projected areas.
    """

    cameras: tuple
    reference: np.ndarray
    shading: str = "flat"
    specular: bool = False
    cull_front: tuple | None = None
    weight: float = 1.0
    constants: object = None
    entropy_weight: float = 0.0
    entropy_background: bool = True

    def _frame(self, lo, scale):
        """Per-view clip transforms and eyes in engine coordinates (p_world = p * scale
        + lo)."""
        n_views, height, width = self.reference.shape
        affine = np.eye(4)
        affine[:3, :3] *= scale
        affine[:3, 3] = lo
        M = np.stack([c.projection_matrix(width / height) @ c.view_matrix() @ affine
                      for c in self.cameras])
        eyes = (np.stack([np.asarray(c.eye, np.float64) for c in self.cameras]) - lo) / scale
        return M, eyes

    def _new(self, mesh, uv, nv, m, lo, scale):
        from methods.raster import SHADINGS, shading_constants

        if self.shading not in SHADINGS:
            raise ValueError(f"shading must be one of {SHADINGS}, got {self.shading!r}")
        n_views = len(self.cameras)
        if self.reference.ndim != 3 or self.reference.shape[0] != n_views:
            raise ValueError(f"reference must hold one image per camera ({n_views}), got "
                             f"shape {self.reference.shape}")
        constants = self.constants
        if constants is None:
            from metrics.render import DEFAULT_CONSTANTS as constants
        textured = bool(mesh.has_texture)
        consts = shading_constants(constants, self.specular, self.shading == "gouraud",
                                   textured)
        texture = (np.ascontiguousarray(mesh.texture[:, :, :3]) if textured
                   else np.zeros((1, 1, 3), np.uint8))
        cull = np.zeros(n_views, np.bool_)
        if self.cull_front is not None:
            cull[:] = np.asarray(self.cull_front, dtype=np.bool_).reshape(-1)
        M, eyes = self._frame(lo, scale)
        entropy = None
        if self.entropy_weight != 0.0:
            entropy = (bool(self.entropy_background), self.weight != 0.0)
        return new_state(M, eyes, cull, self.reference, consts, texture, nv, m, len(uv),
                         entropy)

    def state(self, mesh, P, F, FW, uv, falive, vhead, cnext, valive, lo, scale):
        """The engine's image state for its arrays, with the images rendered."""
        from methods.raster import BACKGROUND

        img, iws = self._new(mesh, uv, len(P), len(F), lo, scale)
        full_render(img, iws, P, F, FW, uv, falive, vhead, cnext, valive, float(BACKGROUND))
        if self.entropy_weight != 0.0:
            entropy_init(img[12], img[14])
        height, width = self.reference.shape[1:]
        tiles = build_tiles(img[6], falive, TILE, -(-width // TILE), -(-height // TILE))
        return img, tiles, iws

    def statistics(self, mesh, img, verify, P, F, FW, uv, falive, vhead, cnext, valive, lo, scale):
        """Counters of the run; with ``verify``, a from-scratch render of the final mesh
        compared with the maintained images."""
        from methods.raster import BACKGROUND

        counts = dict(zip(STAT_NAMES, (int(x) for x in img[11])))
        out = {k: counts[k] for k in ("image_evaluations", "pixels_shaded", "face_rows",
                                      "tile_rebuilds")}
        if counts["run_cycles"] > 0:  # where the time goes
            for k in ("gather", "shade", "setup"):
                out[f"{k}_share"] = counts[f"{k}_cycles"] / counts["run_cycles"]
        out["rasterizer_share"] = (counts["raster_cycles"] / counts["run_cycles"]
                                   if counts["run_cycles"] > 0 else None)
        Y, Y0 = img[4], img[3]
        shaded = self.weight != 0.0 or self.entropy_weight == 0.0
        if shaded:
            out["image_sse"] = float(np.sum((Y0 - Y) ** 2))
        entropy = self.entropy_weight != 0.0
        if entropy:
            CNT, SUM, TOT = img[14][:3]
            out["view_entropy"] = [float(view_entropy(s, float(a))) for s, a in zip(SUM, TOT)]
        if verify:
            again, iws = self._new(mesh, uv, len(P), len(F), lo, scale)
            full_render(again, iws, P, F, FW, uv, falive, vhead, cnext, valive,
                        float(BACKGROUND))
            if shaded:
                out["image_mismatched_pixels"] = int(np.count_nonzero(again[4] != Y))
            out["face_id_mismatched_pixels"] = int(np.count_nonzero(again[12] != img[12]))
            out["depth_mismatched_pixels"] = int(np.count_nonzero(again[13] != img[13]))
            if entropy:  # the maintained counts and entropies against fresh ones
                entropy_init(again[12], again[14])
                fresh = np.array([view_entropy(s, float(a))
                                  for s, a in zip(again[14][1], again[14][2])])
                out["entropy_count_mismatches"] = int(np.count_nonzero(again[14][0] != CNT))
                out["entropy_max_error"] = float(np.max(np.abs(
                    fresh - np.asarray(out["view_entropy"]))))
        return out
