"""The per-view tile index: 8 x 8-pixel tiles, each listing the faces whose pixel box
overlaps it, to find the faces under a rectangle in one traversal."""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

#: Side of the square tiles of the per-view face index, in pixels.
TILE = 8

#: Tiles of 8 x 8 pixels listed at least this many spare slots (and half their count
#: again) when built; a tile that fills up makes :func:`_tiles_add` report an overflow
#: and the engine rebuilds the index.
TILE_SPARE = 8

#: The tile index: per view and tile, ``ptr`` (V, T + 1) and ``cnt`` (V, T) into
#: ``items`` (face ids, int32), and ``ibox`` (V, m, 4) int32 the tile range each face is
#: listed in.
Tiles = namedtuple("Tiles", "ptr cnt items ibox")


@njit(cache=True)
def build_tiles(fbox, falive, tile, nx, ny):
    """Per view and tile, the live faces whose box overlaps it, with spare room.

    Returns :data:`Tiles`."""
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
            total += cnt[h, i] + cnt[h, i] // 2 + TILE_SPARE
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
    return Tiles(ptr=ptr, cnt=cnt, items=items, ibox=ibox)


@njit(cache=True)
def _tiles_add(tiles, h, f, box, tile, nx):
    """List face ``f`` in the tiles its new ``box`` reaches; False if a tile is full."""
    ptr, cnt, items, ibox = tiles.ptr, tiles.cnt, tiles.items, tiles.ibox
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


@njit(cache=True, _nrt=False)
def _gather(tiles, h, rect, faces, marks, cand, n, grid):
    """Append to ``cand[n:]`` the live, unmarked faces whose box overlaps ``rect`` in
    view ``h``, looking only in the marked tiles (the tiles where something is to be
    drawn; a face listed in no such tile draws nothing there). ``faces`` is (fbox,
    falive), ``marks`` (mark, tick, tmark, ttick): a face is marked where ``mark ==
    tick``, a tile where ``tmark == ttick``; ``grid`` is (tile, nx), the tiles' side and
    count per row."""
    ptr, cnt, items = tiles.ptr, tiles.cnt, tiles.items
    fbox, falive = faces
    mark, tick, tmark, ttick = marks
    tile, nx = grid
    for ty in range(rect[2] // tile, rect[3] // tile + 1):
        for tx in range(rect[0] // tile, rect[1] // tile + 1):
            i = ty * nx + tx
            if tmark[i] != ttick:
                continue
            for k in range(ptr[h, i], ptr[h, i] + cnt[h, i]):
                f = items[k]
                if mark[f] != tick and falive[f] and _overlaps(fbox[h, f], rect):
                    mark[f] = tick
                    cand[n] = f
                    n += 1
    return n
