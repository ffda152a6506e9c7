"""Region re-rendering: a view's rectangle around a collapse drawn as it would look
after it (:func:`image_cost`, equation 8 of Lindstrom & Turk 2000) or as it is after
it (:func:`commit_geometry`, :func:`commit_render`).

Every function a view's re-render passes through (:func:`_take_views` down to the
scans) is compiled without reference counting (numba's ``_nrt=False``): each takes the
image state and scratch, some 60 arrays, whose counts it would otherwise raise on entry
and lower on exit, atomically, once per array and call. They allocate nothing and
return no array, and every array they see is held by a caller for the whole call
(``docs/maintainers.md``, "State in the numba kernels"). A function added to that path
keeps to the same rule; one that must allocate is compiled as usual."""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from methods.corners import corners
from methods.imaging.counters import (
    STAT_COMMITS,
    STAT_FACE_ROWS,
    STAT_GATHER_CYCLES,
    STAT_HELPER_VIEWS,
    STAT_IMAGE_EVALUATIONS,
    STAT_PIXELS_SHADED,
    STAT_RASTER_CYCLES,
    STAT_RUN_CYCLES,
    STAT_SETUP_CYCLES,
    STAT_SHADE_CYCLES,
    cycles,
)
from methods.imaging.entropy import _entropy_change
from methods.imaging.raster import NO_VERTEX, ZERO, behind, scan_row, shade_pixel, wins_any
from methods.imaging.rows import (
    _light,
    _pos,
    fill_screen,
    fill_shading,
    project,
    removed_by,
    row_box,
    vertex_normal,
)
from methods.imaging.share import (
    JOB_ATICK,
    JOB_HELPERS,
    JOB_KIND,
    JOB_NA,
    JOB_NPAIRS,
    JOB_NS,
    JOB_U,
    JOB_V,
    KIND_COMMIT,
    KIND_COST,
    add_partial,
    clear_partials,
    done,
    hand_out,
    next_job,
    next_view,
    partials_sum,
    publish,
    stop_handing,
    wait,
)
from methods.imaging.tiles import TILE, _gather, _tiles_add

#: Vertices whose normal one collapse changes (the 1-ring of the edge's faces); more
#: raises (a fan of hundreds of triangles).
_MAX_RING = 256
MAX_RING = _MAX_RING
#: Faces whose geometry or shading one collapse changes (around the edge and the ring).
AFFECTED_CAP = 8192
#: Wedges whose texture coordinates one collapse changes (the engine's
#: WEDGE_TARGETS_CAP).
NEW_UV_CAP = 64

#: :func:`_render_view`'s ``commit``, typed (one compiled render for both, not one per
#: literal: see :data:`methods.imaging.raster.ZERO`).
DRAW_COST = np.bool_(False)
DRAW_COMMIT = np.bool_(True)

#: What a thread draws its views from: the mesh's arrays (``P``, ``F``, ``FW``, ``uv``,
#: ``falive``), the image state ``img``, the tile index, the thread's own workspace
#: ``iws``, the merged wedges' map of the collapse being costed (``wfrom``, ``wto``;
#: any int64 arrays for a commit, which merges none) and the background's luminance.
Scene = namedtuple("Scene", "P F FW uv falive img tiles iws wfrom wto background")

#: One change to draw: ``u`` collapsed into ``v`` at ``p`` (``u = v = -1``: the mesh as
#: it is, after a collapse was made), ``sp`` the screen position of ``p`` in the view
#: being drawn, ``iws.aff[:na]`` the faces whose geometry changes and ``iws.aff[:ns]``
#: those whose shading may (marked with ``atick``), ``npairs`` the wedge pairs merged.
Change = namedtuple("Change", "u v p sp na ns atick npairs")


@njit(cache=True, _nrt=False)
def _grow(rect, box):
    if box[0] > box[1] or box[2] > box[3]:
        return
    if rect[0] > rect[1]:
        rect[0], rect[1], rect[2], rect[3] = box[0], box[1], box[2], box[3]
    else:
        rect[0], rect[1] = min(rect[0], box[0]), max(rect[1], box[1])
        rect[2], rect[3] = min(rect[2], box[2]), max(rect[3], box[3])


@njit(cache=True)
def _add_to_ring(x, ring, vslot, nr):
    """Append vertex ``x`` to the ring of vertices whose normal changes (slot ``nr``)."""
    if nr == ring.shape[0]:
        raise ValueError("a collapse changes the normals of more vertices than MAX_RING "
                         "(methods.imaging.region)")
    vslot[x] = nr
    ring[nr] = x
    return nr + 1


@njit(cache=True, inline="always")
def _add_face(f, falive, mark, tk, out, n):
    """Append face ``f`` to ``out[n:]`` if it is alive and not marked ``tk`` (marking
    it); returns the new count."""
    if falive[f] and mark[f] != tk:
        if n == out.shape[0]:
            raise ValueError("a collapse affects more faces than AFFECTED_CAP "
                             "(methods.imaging.region)")
        mark[f] = tk
        out[n] = f
        n += 1
    return n


@njit(cache=True, _nrt=False)
def _faces_around(y, vhead, cnext, falive, mark, tk, out, n):
    """Append to ``out[n:]`` the live faces of vertex ``y`` not marked ``tk`` (marking
    them); returns the new count."""
    for c in corners(y, vhead, cnext):
        n = _add_face(c // 3, falive, mark, tk, out, n)
    return n


@njit(cache=True, _nrt=False)
def _render_view(scene, h, rect, change, commit):
    """Re-render ``rect`` of view ``h`` as the mesh looks after the ``change``
    (:data:`Change`: collapsing ``u`` into ``v`` at ``p``; ``u = -1``: as it is now,
    after a collapse already made).

    ``iws.aff[:na]`` are the faces whose geometry changes (with ``u >= 0`` those holding
    both ``u`` and ``v`` disappear); they and any removed faces carry
    ``gmark == atick``, and every face whose shading may change carries
    ``amark == atick``. A pixel keeps its current face unless that face is one of the
    changed ones (a *hole*): the kept faces' depth is known (``DZ``), so only the
    changed faces are scanned over the whole rectangle, and the other faces only over
    the holes' bounding box. Depth ties go to the lower face id, so the result is the
    from-scratch render's. With ``commit`` the pixels go into ``Y``, ``IDS`` and
    ``DZ``; otherwise returns the change of the squared error (equation 8) and, with the
    viewpoint entropy, leaves |dH| of the view in ``iws.vdh[h]``.
    """
    img, iws = scene.img, scene.iws
    stats, ent = img.stats, img.ent
    start = cycles()
    # Holes: the pixels whose face changes; the others keep their face and depth.
    nh, far = _open_holes(h, rect, img, iws, change.atick)
    # The changed faces, over the whole rectangle.
    n = _scan_changed(scene, h, rect, change, far)
    if nh > 0:  # what the changed faces uncover: every other face over the holes
        n = _fill_holes(scene, h, rect, change, nh, n)
    mid = cycles()
    if ent.on:  # viewpoint entropy: the count changes inside the rectangle
        dh = _entropy_change(h, rect, iws.ids, img.IDS, ent, commit)
        if not commit:
            iws.vdh[h] = abs(dh)
    if not ent.shade:  # face ids only, no luminance (entropy without equation 8)
        if commit:
            _commit_ids(h, rect, img, iws)
        stats[STAT_FACE_ROWS] += n
        stats[STAT_RASTER_CYCLES] += cycles() - start
        return 0.0
    # Shade the pixels whose face or shading changed.
    cost, shaded, n = _shade_changes(scene, h, rect, change, n, commit)
    end = cycles()
    stats[STAT_PIXELS_SHADED] += shaded
    stats[STAT_FACE_ROWS] += n
    stats[STAT_RASTER_CYCLES] += end - start
    stats[STAT_SHADE_CYCLES] += end - mid
    return cost


@njit(cache=True, inline="always")
def _is_hole(w, gmark, atick):
    """Whether a pixel showing face ``w`` (-1: none) is a hole: its face changes."""
    return w >= 0 and gmark[w] == atick


@njit(cache=True, _nrt=False)
def _open_holes(h, rect, img, iws, atick):
    """Start ``iws.depth``/``iws.ids`` (rectangle-relative) from view ``h``'s current
    depth and faces, with the pixels of changed faces (``gmark == atick``) emptied;
    returns the number of holes (listed in ``iws.holes``) and the rectangle's farthest
    depth (infinite with a hole or an empty pixel)."""
    IDS, DZ, gmark, depth, ids, holes = (img.IDS, img.DZ, iws.gmark, iws.depth, iws.ids,
                                         iws.holes)
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    cols = c1 - c0 + 1
    nh = 0
    for r in range(r0, r1 + 1):
        # rows of views indexed from 0, so that the depth copy is a plain vector copy
        zsrc, zdst = DZ[h, r, c0:c1 + 1], depth[r - r0]
        isrc, idst = IDS[h, r, c0:c1 + 1], ids[r - r0]
        for j in range(cols):
            zdst[j] = zsrc[j]
        for j in range(cols):
            w = isrc[j]
            if _is_hole(w, gmark, atick):
                zdst[j] = np.inf
                w = -1
                holes[nh, 0], holes[nh, 1] = r, c0 + j
                nh += 1
            idst[j] = w
    if nh > 0:
        return nh, np.inf
    far = -np.inf
    for i in range(r1 - r0 + 1):
        zrow = depth[i]
        for j in range(cols):
            far = max(far, zrow[j])
    return nh, far


@njit(cache=True, _nrt=False)
def _scan_changed(scene, h, rect, change, far):
    """Scan the changed faces ``iws.aff[:na]`` (after the collapse, those of the edge
    gone) over ``rect``; they become table rows 0..n-1. Returns n. A face wholly behind
    the rectangle's farthest depth ``far`` is not scanned: it would win no pixel."""
    F, img, iws = scene.F, scene.img, scene.iws
    u, v, sp = change.u, change.v, change.sp
    cand, rowof, t, aff = iws.cand, iws.rowof, iws.t, iws.aff
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    n = np.int64(0)
    for i in range(change.na):
        f = aff[i]
        if removed_by(F, f, u, v):
            continue
        cand[n] = f
        rowof[f] = n
        fill_screen((t, n, f, h), (u, v, sp), img.S, F)
        if not behind(t, n, far):
            scan_row(t, n, f, (c0, c1, r0, r1), img.cull[h], iws.depth, iws.ids)
        n += 1
    return n


@njit(cache=True, _nrt=False)
def _fill_holes(scene, h, rect, change, nh, n):
    """Scan every other face whose box meets the open holes' box in a tile holding an
    open hole (stamped in ``iws.hmark``; from the tile index) over that box, each row
    only from its first open hole to its last (``iws.spans``), as table rows n..;
    returns the new row count. The rectangle's ``nh`` holes are listed in
    ``iws.holes``; one is open unless the changed faces' scan put a (depth, id) there
    no larger than that of the face it showed before. An unchanged face wins no pixel
    but an open hole: every kept pixel shows the nearest of the faces before the
    collapse, and every face at a settled hole was behind the one shown there before,
    so no unchanged face can beat it. For the same reason a face wholly behind the
    farthest depth in an open hole is not scanned."""
    F, img, iws, sp = scene.F, scene.img, scene.iws, change.sp
    mark, tick, cand, rowof, t, aff = iws.mark, iws.tick, iws.cand, iws.rowof, iws.t, iws.aff
    IDS, DZ, depth, ids, hmark = img.IDS, img.DZ, iws.depth, iws.ids, iws.hmark
    width = img.Y.shape[2]
    nx = -(-width // TILE)
    r0, c0 = rect[2], rect[0]
    tick[0] += 1
    otick = tick[0]
    # The holes left open: where the changed faces now show nothing, or something
    # farther (or of a higher id at the same depth) than the face they showed before.
    # Every unchanged face at a hole was behind the face shown there before, so at a
    # settled hole it loses to the new one too.
    oc0, oc1, or0, or1 = width, np.int64(-1), img.Y.shape[1], np.int64(-1)
    spans = iws.spans
    for r in range(r0, rect[3] + 1):
        spans[r, 0], spans[r, 1] = width, -1
    far = -np.inf  # the farthest depth in an open hole, after the changed faces' scan
    for i in range(nh):
        r, c = iws.holes[i, 0], iws.holes[i, 1]
        z, f = depth[r - r0, c - c0], ids[r - r0, c - c0]
        if f >= 0 and (z < DZ[h, r, c] or (z == DZ[h, r, c] and f <= IDS[h, r, c])):
            continue  # settled: no unchanged face can win here
        oc0, oc1 = min(oc0, c), max(oc1, c)
        or0, or1 = min(or0, r), max(or1, r)
        spans[r, 0], spans[r, 1] = min(spans[r, 0], c), max(spans[r, 1], c)
        hmark[(r // TILE) * nx + c // TILE] = otick
        far = max(far, z)
    if oc0 > oc1:
        return n
    for i in range(change.na):
        mark[aff[i]] = otick
    hole = iws.box
    hole[0], hole[1], hole[2], hole[3] = oc0, oc1, or0, or1
    g0 = cycles()
    n2 = _gather(scene.tiles, h, hole, (img.fbox, scene.falive), (mark, otick, hmark, otick),
                 cand, n, (TILE, nx))
    img.stats[STAT_GATHER_CYCLES] += cycles() - g0
    hole_depth = depth[or0 - r0:, oc0 - c0:]  # views indexed from the open holes' corner
    hole_ids = ids[or0 - r0:, oc0 - c0:]
    for k in range(n, n2):
        f = cand[k]
        rowof[f] = k
        fill_screen((t, k, f, h), (NO_VERTEX, NO_VERTEX, sp), img.S, F)
        if not behind(t, k, far):
            scan_row(t, k, f, (oc0, oc1, or0, or1), img.cull[h], hole_depth, hole_ids, spans)
    return n2


@njit(cache=True, _nrt=False)
def _commit_ids(h, rect, img, iws):
    """Write the rectangle's faces and depths into view ``h``'s ``IDS`` and ``DZ``."""
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    for r in range(r0, r1 + 1):
        for c in range(c0, c1 + 1):
            img.IDS[h, r, c] = iws.ids[r - r0, c - c0]
            img.DZ[h, r, c] = iws.depth[r - r0, c - c0]


@njit(cache=True, _nrt=False)
def _shade_changes(scene, h, rect, change, n, commit):
    """Shade the rectangle's pixels whose face changed, or whose face's shading may have
    (``amark == atick``): into ``Y``, ``IDS``, ``DZ`` with ``commit``, else summing the
    change of the squared error. A kept face seen there gets a table row on first use.
    Returns (cost, pixels shaded, row count)."""
    P, F, FW, uv, img, iws = scene.P, scene.F, scene.FW, scene.uv, scene.img, scene.iws
    u, v, p, sp, atick = change.u, change.v, change.p, change.sp, change.atick
    Y0, Y, S, L, shading, texture, IDS, DZ, eyes = (img.Y0, img.Y, img.S, img.L,
                                                     img.shading, img.texture, img.IDS,
                                                     img.DZ, img.eyes)
    tick, cand, t, depth, ids, amark, rowof, rowmark = (iws.tick, iws.cand, iws.t, iws.depth,
                                                        iws.ids, iws.amark, iws.rowof,
                                                        iws.rowmark)
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    tick[0] += 1
    filled = tick[0]  # rows whose shading columns are filled are marked with it
    cost = 0.0
    shaded = 0
    cols = c1 - c0 + 1
    for r in range(r0, r1 + 1):
        before, after = IDS[h, r, c0:c1 + 1], ids[r - r0]  # rows indexed from 0
        for j in range(cols):
            f = after[j]
            if f == before[j] and (f < 0 or amark[f] != atick):
                continue  # the same face, unchanged: the same luminance
            c = c0 + j
            y = scene.background
            if f >= 0:
                k = rowof[f]
                if k >= n or cand[k] != f:  # kept face, only its shading changes: a row
                    k = n
                    cand[k] = f
                    rowof[f] = k
                    fill_screen((t, k, f, h), (u, v, sp), S, F)
                    n += 1
                if rowmark[k] != filled:
                    fill_shading((t, k, f, h), (u, v, p), (P, F, FW, uv),
                                 (L, iws.vslot, iws.ov_light),
                                 (iws.wslot, iws.new_uv, scene.wfrom, scene.wto, change.npairs),
                                 shading)
                    rowmark[k] = filled
                y = shade_pixel(t, k, c + 0.5, r + 0.5, eyes[h], shading, texture)
            shaded += 1
            if commit:
                Y[h, r, c] = y
                IDS[h, r, c] = f
                DZ[h, r, c] = depth[r - r0, c - c0]
            else:
                a = Y0[h, r, c] - y
                b = Y0[h, r, c] - Y[h, r, c]
                cost += a * a - b * b
    return cost, shaded, n


@njit(cache=True)
def image_cost(scene, u, v, p, npairs, corner_lists, new_uv, bound):
    """Equation 8 for collapsing ``u`` into ``v`` at ``p``, in the :data:`Scene` of the
    evaluating thread (its wedge map holding ``npairs`` pairs): the change of the summed
    squared luminance error over every view's rectangle. ``corner_lists`` are the mesh's
    (vhead, cnext); ``new_uv`` is (targets, nt, target_uv): ``targets[:nt]`` are the
    wedges whose texture coordinates become ``target_uv[:nt]``. The sum of |dH| over the views
    goes to ``img.ent.delta[0]``. The set-up is this thread's; the views are shared
    with the run's helpers, if any (:mod:`methods.imaging.share`), and taken in the
    order ``iws.vorder``.

    ``bound``: once the views done sum to more |dH| than this, the others are not
    rendered and ``img.ent.delta[0]`` is inf (the caller knows the collapse loses
    whatever they give; the returned cost then covers the views done). ``np.inf``:
    every view is rendered."""
    img, iws = scene.img, scene.iws
    targets, nt, target_uv = new_uv
    img.stats[STAT_IMAGE_EVALUATIONS] += 1
    setup_start = cycles()
    if nt > iws.new_uv.shape[0]:
        raise ValueError("more new texture coordinates than NEW_UV_CAP "
                         "(methods.imaging.region)")
    for i in range(nt):
        iws.wslot[targets[i]] = i
        iws.new_uv[i, 0], iws.new_uv[i, 1] = target_uv[i, 0], target_uv[i, 1]
    vhead, cnext = corner_lists
    na, ns, nr = _affected(u, v, p, scene.P, (scene.F, vhead, cnext, scene.falive), img, iws)
    img.stats[STAT_SETUP_CYCLES] += cycles() - setup_start
    n_views = img.Y.shape[0]
    job, part = iws.vjob, iws.vpart
    helpers = job[JOB_HELPERS]
    iws.vp[0], iws.vp[1], iws.vp[2] = p[0], p[1], p[2]
    iws.vbound[0] = bound
    for h in range(n_views):  # a view left undone adds nothing
        iws.vcost[h] = iws.vdh[h] = 0.0
    clear_partials(part, helpers)
    publish(job, np.int64(KIND_COST), u, v, na, ns, iws.tick[0], npairs)
    g = hand_out(job) if helpers > 0 else 0
    _take_views(ZERO, scene)
    if g > 0:
        wait(job, g)
    # the views' results, summed in view order whichever thread drew which
    cost = dh = 0.0
    for h in range(n_views):
        cost += iws.vcost[h]
        dh += iws.vdh[h]
    if partials_sum(part, helpers) > bound:
        dh = np.inf
    img.ent.delta[0] = dh
    for i in range(nr):
        iws.vslot[iws.ring[i]] = -1
    for i in range(nt):
        iws.wslot[targets[i]] = -1
    return cost


@njit(cache=True)
def _affected(u, v, p, P, topology, img, iws):
    """The set-up of :func:`image_cost` for collapsing ``u`` into ``v`` at ``p``
    (``topology``: the mesh's F, vhead, cnext, falive): the faces around the edge in
    ``iws.aff[:na]`` (marked in ``gmark``), with the faces whose shading changes after
    them up to ``ns`` (marked in ``amark``), and under Gouraud shading the ``nr``
    vertices whose normal changes in ``iws.ring`` (their lighting in ``iws.ov_light``;
    the caller frees their ``vslot``). Returns (na, ns, nr)."""
    F, vhead, cnext, falive = topology
    mark, tick, vslot, aff = iws.mark, iws.tick, iws.vslot, iws.aff
    # the faces around the edge ([[e]]; those holding both ends disappear)
    tick[0] += 1
    na = _faces_around(u, vhead, cnext, falive, mark, tick[0], aff, ZERO)
    if not (p[0] == P[v, 0] and p[1] == P[v, 1] and p[2] == P[v, 2]):
        na = _faces_around(v, vhead, cnext, falive, mark, tick[0], aff, na)
    # else a half-edge collapse: v stays, so its faces without u keep their geometry,
    # texture coordinates and pixels (gouraud adds them below, as v's normal changes)
    ns = na
    nr = ZERO
    if img.shading.gouraud:  # vertices whose normal changes, and the faces they shade
        for i in range(na):  # (footnote 3)
            for j in range(3):
                x = F[aff[i], j]
                if x != u and vslot[x] < 0:
                    nr = _add_to_ring(x, iws.ring, vslot, nr)
        for i in range(nr):
            x = iws.ring[i]
            vertex_normal(x, (u, v, p), (P, F, vhead, cnext, falive), iws.buf, iws.n3)
            for h in range(img.Y.shape[0]):
                _light(_pos(x, u, v, p, P, 0), _pos(x, u, v, p, P, 1), _pos(x, u, v, p, P, 2),
                       iws.n3, img.eyes[h], img.shading, iws.ov_light[h, i], 0)
            ns = _faces_around(x, vhead, cnext, falive, mark, tick[0], aff, ns)
    for i in range(ns):
        iws.amark[aff[i]] = tick[0]
    for i in range(na):
        iws.gmark[aff[i]] = tick[0]
    return na, ns, nr


@njit(cache=True)
def rank_views(iws):
    """Order ``iws.vorder`` by the |dH| the last evaluation left in ``iws.vdh``, largest
    first (ties by view): the next evaluation of a collapse much like it then passes
    its bound, if it does, after the fewest views."""
    order, vdh = iws.vorder, iws.vdh
    for k in range(order.shape[0]):
        order[k] = k
    for k in range(1, order.shape[0]):
        h = order[k]
        j = k
        while j > 0 and vdh[order[j - 1]] < vdh[h]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = h


@njit(cache=True)
def commit_geometry(scene, v, stays, held, removed, n_removed, corner_lists, valive):
    """After collapsing into ``v`` (faces ``removed[:n_removed]`` deleted), in the
    evaluating thread's :data:`Scene` (``corner_lists``: the mesh's vhead, cnext;
    ``valive``: its live vertices): update screen positions, normals, lighting and face
    boxes, note each view's rectangle, and list the changed faces in the tile index.
    Returns (whether no tile overflowed, how many faces changed their geometry); after
    an overflow rebuild the index before :func:`commit_render`.

    With ``stays`` (v kept its position: a half-edge collapse) only the faces
    ``held`` (those that held the removed vertex) change their geometry; the other
    faces around ``v`` keep their pixels, and are re-shaded only where the luminance is
    kept (their texture coordinates or normals may change). Otherwise every face
    around ``v`` changes."""
    P, F, falive, img, tiles, iws = (scene.P, scene.F, scene.falive, scene.img, scene.tiles,
                                     scene.iws)
    vhead, cnext = corner_lists
    S, fbox = img.S, img.fbox
    tick, t, rects, sp, aff = iws.tick, iws.t, iws.rects, iws.sp, iws.aff
    amark, gmark = iws.amark, iws.gmark
    n_views, height, width = img.Y.shape
    img.stats[STAT_COMMITS] += 1
    tick[0] += 1
    # aff[:na]: the faces whose geometry changes; aff[:nall]: those around v whose
    # shading may change
    if stays:
        na = ZERO
        for i in range(held.shape[0]):
            na = _add_face(held[i], falive, iws.mark, tick[0], aff, na)
        nall = na
        if img.ent.shade or img.shading.gouraud:
            nall = _faces_around(v, vhead, cnext, falive, iws.mark, tick[0], aff, na)
    else:
        na = nall = _faces_around(v, vhead, cnext, falive, iws.mark, tick[0], aff, ZERO)
    for h in range(n_views):
        rects[h, 0], rects[h, 1], rects[h, 2], rects[h, 3] = 0, -1, 0, -1
        project(img.M, h, P[v], width, height, S[h, v])
        for i in range(n_removed):
            _grow(rects[h], fbox[h, removed[i]])
    ns = nall
    if img.shading.gouraud:
        ns = _relight(nall, removed, n_removed, P, (F, vhead, cnext, falive), valive, img,
                      iws)
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
            fill_screen((t, ZERO, f, h), (NO_VERTEX, NO_VERTEX, sp), S, F)
            row_box(t, ZERO, width, height, fbox[h, f])
            _grow(rects[h], fbox[h, f])
            if ok:
                ok = _tiles_add(tiles, h, f, fbox[h, f], TILE, -(-width // TILE))
    return ok, na


@njit(cache=True)
def _relight(nall, removed, n_removed, P, topology, valive, img, iws):
    """Under Gouraud shading, after a collapse: the normals and lighting of the live
    vertices of the faces ``iws.aff[:nall]`` and ``removed[:n_removed]``, and the faces
    they shade added to ``iws.aff`` after ``nall``; returns the new count (``topology``:
    F, vhead, cnext, falive)."""
    F, vhead, cnext, falive = topology
    ring, vslot, vn = iws.ring, iws.vslot, img.vn
    nr = ZERO
    for i in range(nall + n_removed):
        f = iws.aff[i] if i < nall else removed[i - nall]
        for j in range(3):
            x = F[f, j]
            if valive[x] and vslot[x] < 0:
                nr = _add_to_ring(x, ring, vslot, nr)
    ns = nall
    for i in range(nr):
        x = ring[i]
        vslot[x] = -1
        vertex_normal(x, (NO_VERTEX, NO_VERTEX, P[x]), (P, F, vhead, cnext, falive), iws.buf,
                      vn[x])
        for h in range(img.Y.shape[0]):
            _light(P[x, 0], P[x, 1], P[x, 2], vn[x], img.eyes[h], img.shading, img.L[h, x], 0)
        ns = _faces_around(x, vhead, cnext, falive, iws.mark, iws.tick[0], iws.aff, ns)
    return ns


@njit(cache=True)
def commit_render(na, scene):
    """Re-render every view's rectangle noted by :func:`commit_geometry` into the
    images (``na``: its count of changed faces), the views shared with the run's
    helpers, if any. A commit merges no wedges (npairs 0): the scene's ``wfrom`` and
    ``wto`` may be any int64 arrays."""
    iws = scene.iws
    job = iws.vjob
    # commit_geometry marked the changed faces with the tick
    publish(job, np.int64(KIND_COMMIT), NO_VERTEX, NO_VERTEX, na, na, iws.tick[0], ZERO)
    g = hand_out(job) if job[JOB_HELPERS] > 0 else 0
    _take_views(ZERO, scene)
    if g > 0:
        wait(job, g)


@njit(cache=True, _nrt=False)
def _cost_view(scene, h, change):
    """View ``h``'s part of :func:`image_cost`: its rectangle re-rendered as after the
    collapse; the change of the squared error goes to ``iws.vcost[h]``, |dH| to
    ``iws.vdh[h]`` (left at the 0 :func:`image_cost` put there for a view the collapse
    does not touch)."""
    F, img, iws = scene.F, scene.img, scene.iws
    u, v, sp = change.u, change.v, change.sp
    S, fbox, t, box, aff = img.S, img.fbox, iws.t, iws.box, iws.aff
    height, width = img.Y.shape[1], img.Y.shape[2]
    project(img.M, h, change.p, width, height, sp)
    rect = iws.rects[h]
    rect[0], rect[1], rect[2], rect[3] = 0, -1, 0, -1
    for i in range(change.ns):
        _grow(rect, fbox[h, aff[i]])
    for i in range(change.na):
        f = aff[i]
        if not removed_by(F, f, u, v):
            fill_screen((t, ZERO, f, h), (u, v, sp), S, F)
            row_box(t, ZERO, width, height, box)
            _grow(rect, box)
    if rect[0] > rect[1] or rect[2] > rect[3]:
        return
    if img.ent.on and _unchanged(scene, h, rect, change):
        return
    iws.vcost[h] = _render_view(scene, h, rect, change, DRAW_COST)


@njit(cache=True, _nrt=False)
def _unchanged(scene, h, rect, change):
    """Whether collapsing ``u`` into ``v`` leaves view ``h`` as it is: no pixel shows a
    face whose geometry or shading changes (``iws.aff[:ns]``; the entropy's per-face
    pixel counts say so at once) and no changed face, as after the collapse, wins a
    pixel of ``rect`` (probed on the view's own depths and faces, so nothing is
    copied)."""
    F, img, iws = scene.F, scene.img, scene.iws
    u, v, sp = change.u, change.v, change.sp
    counts, aff, t = img.ent.counts, iws.aff, iws.t
    for i in range(change.ns):
        if counts[h, aff[i] + 1] != 0:
            return False
    c0, c1, r0, r1 = rect[0], rect[1], rect[2], rect[3]
    depth, ids = img.DZ[h, r0:, c0:], img.IDS[h, r0:, c0:]  # indexed from the corner
    for i in range(change.na):
        f = aff[i]
        if removed_by(F, f, u, v):
            continue
        fill_screen((t, ZERO, f, h), (u, v, sp), img.S, F)
        if wins_any(t, ZERO, f, (c0, c1, r0, r1), img.cull[h], depth, ids):
            return False
    return True


@njit(cache=True, _nrt=False)
def _take_views(row, scene):
    """Render the published job's views, one at a time, until none is left (a cost's
    in the order ``iws.vorder``, until their |dH| passes ``iws.vbound``); returns how
    many this thread (``row``: 0 the evaluating one, 1, 2, ... the helpers) took."""
    img, iws = scene.img, scene.iws
    job = iws.vjob
    kind, helpers, bound = job[JOB_KIND], job[JOB_HELPERS], iws.vbound[0]
    # a commit draws the mesh as it is (u = v = -1, no pairs); its p is never read
    change = Change(u=job[JOB_U], v=job[JOB_V], p=iws.vp if kind == KIND_COST else scene.P[0],
                    sp=iws.sp, na=job[JOB_NA], ns=job[JOB_NS], atick=job[JOB_ATICK],
                    npairs=job[JOB_NPAIRS])
    n_views = img.Y.shape[0]
    taken = 0
    while True:
        k = next_view(job)
        if k >= n_views:
            return taken
        taken += 1
        if kind == KIND_COST:
            h = iws.vorder[k]
            _cost_view(scene, h, change)
            if add_partial(iws.vpart, row, iws.vdh[h], helpers) > bound:
                stop_handing(job, n_views)  # the other views cannot change the verdict
            continue
        h = k
        rect = iws.rects[h]
        if rect[0] > rect[1] or rect[2] > rect[3]:
            continue
        _render_view(scene, h, rect, change, DRAW_COMMIT)


@njit(cache=True, nogil=True)
def serve_views(row, tiles_version, scene):
    """A helper's loop: take views of each job handed to it, until told to quit
    (returns :data:`~methods.imaging.share.QUIT`) or handed a job after the tile index
    changed from ``tiles_version`` (returns ``RETILE``, the job still to do)."""
    img, job = scene.img, scene.iws.vjob
    while True:
        g = next_job(job, row, tiles_version)
        if g < 0:
            return g
        start = cycles()
        img.stats[STAT_HELPER_VIEWS] += _take_views(row, scene)
        # its working cycles join the run's, so that the image counters' shares of them
        # stay shares of all the work done (as the first pass's do)
        img.stats[STAT_RUN_CYCLES] += cycles() - start
        done(job, row, g)
