"""Incremental updates of multi-view luminance images after local mesh changes.

Image-driven simplification (Lindstrom & Turk 2000, §4.2.3) keeps images of the
*current* model in every view and, after an edge collapse, re-renders only the screen
rectangle covering the triangles that changed. :class:`ViewStack` does this on top of
the scan converter of :mod:`methods.raster`:

* the images are first rendered with :func:`methods.raster._raster_kernel` and
  :func:`methods.raster._shade_kernel`, exactly as :func:`methods.raster.rasterize_luminance`;
* after a change, each view's rectangle ``R`` (the union of the old and new pixel
  bounding boxes of the affected faces) is re-rendered from *all* current faces whose
  bounding boxes overlap ``R``, found through a per-view tile index. Re-rendering the
  rectangle from scratch is the "un-rendering": occluded surface behind removed faces
  reappears because every face overlapping the rectangle is drawn again.

Bit-exact equality with a from-scratch render
---------------------------------------------
The incremental images equal ``rasterize_luminance`` of the current mesh bit for bit:

* the same kernels do the per-pixel work. The region is rendered by calling them on an
  image truncated to ``max(row) + 1`` rows and ``max(col) + 1`` columns (the kernels
  sample pixel ``(r, c)`` at ``(c + 0.5, r + 0.5)`` from the top-left corner, so
  truncating at the bottom and right leaves every evaluation unchanged) and on a
  compact copy of the vertices the candidate faces use (the kernels only read vertex
  values, so renumbering vertices changes nothing);
* a pixel's depth test sees the same faces in the same order: every face that covers a
  pixel of ``R`` has a bounding box overlapping ``R`` and is a candidate, and the
  candidates are drawn in increasing face index, so depth ties go to the lowest index
  as in the full render (``<`` test, first drawn wins). Faces are kept in stable
  *slots*: removing a face leaves a hole, changing a face keeps its slot, new faces are
  appended; the current mesh (:meth:`ViewStack.mesh`) lists the live slots in order, so
  its face order is the slot order;
* per-vertex set-up (projection, face normals, vertex normals, per-vertex lighting) is
  recomputed only for the vertices and faces that changed, with the same NumPy
  expressions as the full render, which act row by row (the test checks that the
  results are identical).

Gouraud shading
---------------
Vertex normals are area-weighted sums of the face normals around each *welded* vertex
(:attr:`bench.mesh.Mesh.vertex_normals`). Moving a vertex or changing the faces around
it changes the normals of all vertices of the faces around it, and so the shading of
every face that uses one of those vertices. With ``shading="gouraud"`` the affected set
is therefore grown by the faces incident to any vertex whose normal changed (compared
bit for bit), in line with the paper's footnote 3. The sums are accumulated in the same
order as the full computation (by corner, then by face index), so they are bit-exact.

The tile index
--------------
The paper keeps one bucket (hash table) of triangles per pixel row and per pixel
column, and intersects the row and column unions over the rectangle. Here each view's
image is cut into ``tile x tile`` pixel tiles and each tile lists the faces whose pixel
bounding box overlaps it, as a CSR structure (``ptr``, ``items``) over all views and
tiles, which numba can traverse. A query visits the tiles under the rectangle and
keeps the faces whose *current* bounding box overlaps it. Bounding boxes of faces
changed since the index was built are checked directly (a short "dirty" list) and
the index is rebuilt when that list grows; stale entries are removed by the bounding
box test. Compared with row and column buckets, tiles need no set intersection (one
traversal, no time stamps), and a small face is listed in one to four tiles instead of
in every row and column it spans, at the cost of a coarser culling granularity.

Differences from the paper: there is no depth buffer to keep (the rectangle is re-drawn
from its faces, not composited into old depths); instead the face-ID buffer of the
current mesh is kept (:meth:`ViewStack.face_ids`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from bench.mesh import Mesh, _edge_vectors, _normalize, face_normals
from methods.raster import (BACKGROUND, SHADINGS, _project, _raster_kernel, _shade_kernel,
                            vertex_light)

__all__ = ["ViewStack"]

_EMPTY = np.array([0, -1, 0, -1], np.int64)  # c0, c1, r0, r1 of an empty rectangle


# -- numba helpers ------------------------------------------------------------------------

@njit(cache=True)
def _build_tiles(bbox, alive, tile, nx, ny):
    """CSR of faces per (view, tile): ptr (V, nx*ny + 1) absolute offsets, items."""
    n_views, m = bbox.shape[0], bbox.shape[1]
    n_tiles = nx * ny
    counts = np.zeros((n_views, n_tiles), np.int64)
    for v in range(n_views):
        for f in range(m):
            if not alive[f] or bbox[v, f, 0] > bbox[v, f, 1] or bbox[v, f, 2] > bbox[v, f, 3]:
                continue
            for ty in range(bbox[v, f, 2] // tile, bbox[v, f, 3] // tile + 1):
                for tx in range(bbox[v, f, 0] // tile, bbox[v, f, 1] // tile + 1):
                    counts[v, ty * nx + tx] += 1
    ptr = np.zeros((n_views, n_tiles + 1), np.int64)
    total = 0
    for v in range(n_views):
        for t in range(n_tiles):
            ptr[v, t] = total
            total += counts[v, t]
        ptr[v, n_tiles] = total
    items = np.empty(total, np.int32)
    fill = ptr[:, :n_tiles].copy()
    for v in range(n_views):
        for f in range(m):
            if not alive[f] or bbox[v, f, 0] > bbox[v, f, 1] or bbox[v, f, 2] > bbox[v, f, 3]:
                continue
            for ty in range(bbox[v, f, 2] // tile, bbox[v, f, 3] // tile + 1):
                for tx in range(bbox[v, f, 0] // tile, bbox[v, f, 1] // tile + 1):
                    t = ty * nx + tx
                    items[fill[v, t]] = f
                    fill[v, t] += 1
    return ptr, items


@njit(cache=True)
def _overlaps(bbox, v, f, rect):
    return not (bbox[v, f, 0] > bbox[v, f, 1] or bbox[v, f, 2] > bbox[v, f, 3]
                or bbox[v, f, 1] < rect[0] or bbox[v, f, 0] > rect[1]
                or bbox[v, f, 3] < rect[2] or bbox[v, f, 2] > rect[3])


@njit(cache=True)
def _gather(ptr, items, bbox, alive, dirty, views, rects, tile, nx, mark):
    """Mark (mark[f] = True) every live face whose bounding box overlaps rects[i] in view
    views[i]: faces from the tiles under the rectangle plus the dirty faces."""
    for i in range(views.shape[0]):
        v = views[i]
        rect = rects[i]
        for ty in range(rect[2] // tile, rect[3] // tile + 1):
            for tx in range(rect[0] // tile, rect[1] // tile + 1):
                t = ty * nx + tx
                for k in range(ptr[v, t], ptr[v, t + 1]):
                    f = items[k]
                    if alive[f] and not mark[f] and _overlaps(bbox, v, f, rect):
                        mark[f] = True
        for k in range(dirty.shape[0]):
            f = dirty[k]
            if alive[f] and not mark[f] and _overlaps(bbox, v, f, rect):
                mark[f] = True


class _FixedCamera:
    """A camera whose matrices are computed once (the same arrays every time), so that
    projecting a few moved vertices with :func:`methods.raster._project` is cheap."""

    def __init__(self, camera, aspect):
        self.target = camera.target
        self._aspect = aspect
        self._projection = camera.projection_matrix(aspect)
        self._view = camera.view_matrix()

    def projection_matrix(self, aspect=1.0):
        if aspect != self._aspect:
            raise ValueError("fixed camera used with another aspect ratio")
        return self._projection

    def view_matrix(self):
        return self._view


# -- the image stack ----------------------------------------------------------------------

class ViewStack:
    """Luminance images of a mesh in several views, updated after local changes.

    Parameters
    ----------
    positions : ndarray of shape (n, 3) float64
        Vertex positions.
    faces : ndarray of shape (m, 3) int
        Triangles; their order is the drawing order (depth ties go to the lower index).
    cameras : sequence of V metrics.views.Camera
        Fixed for the life of the stack (typically fitted to the original model).
    width, height : int
        Image size in pixels.
    shading : {"flat", "gouraud"}
        As :func:`methods.raster.rasterize_luminance`; gouraud uses vertex normals
        derived from the current mesh as :attr:`bench.mesh.Mesh.vertex_normals` does.
    tile : int
        Side of the square tiles of the per-view face index, in pixels.
    specular : bool
        Add the specular highlight, as :func:`methods.raster.rasterize_luminance`.
    constants : metrics.render.ShadingConstants, optional
        Defaults to the protocol's constants.

    Notes
    -----
    Faces live in stable slots: :meth:`update` refers to faces by slot, removed slots
    stay empty and new faces get new slots at the end. :meth:`mesh` returns the live
    faces in slot order; :meth:`images` equals ``rasterize_luminance(self.mesh(), ...)``
    bit for bit after any sequence of updates. Untextured meshes only.
    """

    def __init__(self, positions, faces, cameras, width: int = 256, height: int = 256,
                 shading: str = "flat", tile: int = 16, specular: bool = False,
                 constants=None):
        if shading not in SHADINGS:
            raise ValueError(f"shading must be one of {SHADINGS}, got {shading!r}")
        width, height, tile = int(width), int(height), int(tile)
        if width < 1 or height < 1:
            raise ValueError(f"image size must be positive, got {width} x {height}")
        if tile < 1:
            raise ValueError(f"tile must be positive, got {tile}")
        self.cameras = list(cameras)
        if not self.cameras:
            raise ValueError("need at least one camera")
        if constants is None:
            from metrics.render import DEFAULT_CONSTANTS as constants
        self.width, self.height, self.tile = width, height, tile
        self.shading, self.specular = shading, bool(specular)
        self._gouraud = shading == "gouraud"
        self._consts = (float(constants.ambient), float(constants.diffuse),
                        float(constants.specular), float(constants.shininess),
                        float(constants.albedo))
        self._nx = -(-width // tile)
        self._ny = -(-height // tile)
        self._fixed = [_FixedCamera(c, width / height) for c in self.cameras]
        self._eyes = np.stack([np.asarray(c.eye, dtype=np.float64) for c in self.cameras])

        self._positions = np.array(positions, dtype=np.float64).reshape(-1, 3)
        self._faces = np.array(faces, dtype=np.int32).reshape(-1, 3)
        m = len(self._faces)
        self._alive = np.ones(m, np.bool_)
        self._adjacency = [set() for _ in range(len(self._positions))]
        for f, tri in enumerate(self._faces.tolist()):
            for i in tri:
                self._adjacency[i].add(f)

        self._screen = _project(self._positions, self.cameras, width, height)
        self._bbox = self._face_bbox(np.arange(m))
        self._face_n = face_normals(self._positions, self._faces)
        if self._gouraud:
            self._groups = {}
            self._group_of = []
            for i, p in enumerate(self._positions):
                key = p.tobytes()
                self._groups.setdefault(key, set()).add(i)
                self._group_of.append(key)
            self._vertex_n = Mesh(self._positions, self._faces).vertex_normals.copy()
            self._light = self._vertex_light(np.arange(len(self._positions)))
        self._rebuild_index()
        self.last_rects = np.tile(_EMPTY, (len(self.cameras), 1))
        self._render_full()

    # -- accessors ------------------------------------------------------------------------
    @property
    def n_views(self) -> int:
        return len(self.cameras)

    @property
    def positions(self) -> np.ndarray:
        """ndarray of shape (n, 3): current vertex positions (a copy)."""
        return self._positions.copy()

    @property
    def faces(self) -> np.ndarray:
        """ndarray of shape (m', 3) int32: the live faces in slot order."""
        return self._faces[self._alive].copy()

    @property
    def slots(self) -> np.ndarray:
        """ndarray of shape (m',) int: slot of each row of :attr:`faces`."""
        return np.flatnonzero(self._alive)

    def mesh(self) -> Mesh:
        """The current mesh (live faces in slot order, all vertices)."""
        return Mesh(self._positions.copy(), self.faces)

    def images(self) -> np.ndarray:
        """ndarray of shape (V, height, width) float64: current luminance (a view of the
        internal buffer; do not modify)."""
        return self._images

    def face_ids(self) -> np.ndarray:
        """ndarray of shape (V, height, width) int32: index into :attr:`faces` of the face
        seen at each pixel, -1 for background (as :func:`methods.raster.face_id_buffers`
        of :meth:`mesh`)."""
        rank = np.cumsum(self._alive, dtype=np.int64) - 1
        out = np.where(self._ids >= 0, rank[np.maximum(self._ids, 0)], -1)
        return out.astype(np.int32)

    # -- update ---------------------------------------------------------------------------
    def update(self, removed_faces=(), changed_faces=None, new_positions=None,
               added_faces=None) -> np.ndarray:
        """Apply a local mesh change and re-render the affected screen rectangles.

        Parameters
        ----------
        removed_faces : sequence of int
            Slots of faces to delete.
        changed_faces : tuple (slots, triangles), optional
            Faces whose vertex indices change: slots (k,) and new triangles (k, 3).
        new_positions : tuple (vertices, xyz), optional
            Moved vertices (k,) and their new positions (k, 3).
        added_faces : ndarray of shape (a, 3), optional
            New triangles, appended after all existing slots (drawn last).

        Returns
        -------
        ndarray of shape (a,) int
            Slots of the added faces.

        Notes
        -----
        In every view the rectangle re-rendered is the union of the old and new pixel
        bounding boxes of the affected faces: removed, changed and added faces, faces
        around moved vertices and, with gouraud shading, faces around vertices whose
        normal changed. Views where the rectangle holds no pixel centre are untouched.
        ``last_rects[v]`` holds (c0, c1, r0, r1) of the rectangle re-rendered in view v.
        """
        removed = np.unique(np.asarray(removed_faces, dtype=np.int64).reshape(-1))
        if changed_faces is None:
            c_slots, c_tris = np.zeros(0, np.int64), np.zeros((0, 3), np.int32)
        else:
            c_slots = np.asarray(changed_faces[0], dtype=np.int64).reshape(-1)
            c_tris = np.asarray(changed_faces[1], dtype=np.int32).reshape(-1, 3)
        if new_positions is None:
            moved, xyz = np.zeros(0, np.int64), np.zeros((0, 3))
        else:
            moved = np.asarray(new_positions[0], dtype=np.int64).reshape(-1)
            xyz = np.asarray(new_positions[1], dtype=np.float64).reshape(-1, 3)
        added = (np.zeros((0, 3), np.int32) if added_faces is None
                 else np.asarray(added_faces, dtype=np.int32).reshape(-1, 3))
        n = len(self._positions)
        for what, idx, limit in (("removed", removed, len(self._faces)),
                                 ("changed", c_slots, len(self._faces))):
            if len(idx) and (idx.min() < 0 or idx.max() >= limit or not self._alive[idx].all()):
                raise ValueError(f"{what} faces must be live face slots")
        if len(moved) and (moved.min() < 0 or moved.max() >= n):
            raise ValueError("moved vertices out of range")
        for tris in (c_tris, added):
            if len(tris) and (tris.min() < 0 or tris.max() >= n):
                raise ValueError("face vertex index out of range")

        # Faces whose geometry changes, before the change.
        around_moved = set()
        for i in moved.tolist():
            around_moved |= self._adjacency[i]
        old_geom = np.array(sorted(around_moved | set(removed.tolist())
                                   | set(c_slots.tolist())), dtype=np.int64)
        old_box = self._bbox[:, old_geom].copy()
        touched_vertices = set(moved.tolist()) | set(added.reshape(-1).tolist())
        touched_vertices |= set(c_tris.reshape(-1).tolist())
        touched_vertices |= set(self._faces[old_geom].reshape(-1).tolist())

        # Apply the change.
        for f in removed.tolist() + c_slots.tolist():
            for i in self._faces[f].tolist():
                self._adjacency[i].discard(f)
        self._alive[removed] = False
        self._faces[c_slots] = c_tris
        for f, tri in zip(c_slots.tolist(), c_tris.tolist()):
            for i in tri:
                self._adjacency[i].add(f)
        new_slots = np.arange(len(self._faces), len(self._faces) + len(added))
        if len(added):
            self._grow(added)
            for f, tri in zip(new_slots.tolist(), added.tolist()):
                for i in tri:
                    self._adjacency[i].add(f)
        if len(moved):
            if self._gouraud:
                for i in moved.tolist():
                    self._groups[self._group_of[i]].discard(i)
            self._positions[moved] = xyz
            self._screen[:, moved] = _project(xyz, self._fixed, self.width, self.height)
            if self._gouraud:
                for i in moved.tolist():
                    key = self._positions[i].tobytes()
                    self._groups.setdefault(key, set()).add(i)
                    self._group_of[i] = key
        new_geom = set(c_slots.tolist()) | set(new_slots.tolist())
        for i in moved.tolist():
            new_geom |= self._adjacency[i]
        new_geom = np.array(sorted(f for f in new_geom if self._alive[f]), dtype=np.int64)
        if len(new_geom):
            self._face_n[new_geom] = face_normals(self._positions, self._faces[new_geom])
            self._bbox[:, new_geom] = self._face_bbox(new_geom)

        # Gouraud: faces around vertices whose normal changed.
        shade_only = np.zeros(0, np.int64)
        if self._gouraud and touched_vertices:
            changed_v = self._update_vertex_normals(touched_vertices)
            relight = np.array(sorted(set(changed_v) | set(moved.tolist())), dtype=np.int64)
            if len(relight):
                self._light[:, relight] = self._vertex_light(relight)
            faces_v = set()
            for i in changed_v:
                faces_v |= self._adjacency[i]
            shade_only = np.array(sorted(faces_v), dtype=np.int64)

        # The rectangle of each view, then re-render it.
        boxes = [old_box, self._bbox[:, new_geom], self._bbox[:, shade_only]]
        rects = np.tile(_EMPTY, (self.n_views, 1))
        for box in boxes:
            if box.shape[1] == 0:
                continue
            valid = (box[..., 0] <= box[..., 1]) & (box[..., 2] <= box[..., 3])
            big, small = np.iinfo(np.int64).max, np.iinfo(np.int64).min
            c0 = np.where(valid, box[..., 0], big).min(axis=1)
            c1 = np.where(valid, box[..., 1], small).max(axis=1)
            r0 = np.where(valid, box[..., 2], big).min(axis=1)
            r1 = np.where(valid, box[..., 3], small).max(axis=1)
            has = valid.any(axis=1)
            empty = rects[:, 0] > rects[:, 1]
            rects[has, 0] = np.where(empty[has], c0[has], np.minimum(rects[has, 0], c0[has]))
            rects[has, 1] = np.where(empty[has], c1[has], np.maximum(rects[has, 1], c1[has]))
            rects[has, 2] = np.where(empty[has], r0[has], np.minimum(rects[has, 2], r0[has]))
            rects[has, 3] = np.where(empty[has], r1[has], np.maximum(rects[has, 3], r1[has]))
        self._dirty.update(new_geom.tolist())
        if len(self._dirty) > max(256, len(self._faces) // 16):
            self._rebuild_index()
        self.last_rects = rects
        self._render_rects(rects)
        return new_slots

    # -- internals ------------------------------------------------------------------------
    def _grow(self, added):
        k = len(added)
        self._faces = np.concatenate([self._faces, added])
        self._alive = np.concatenate([self._alive, np.ones(k, np.bool_)])
        self._face_n = np.concatenate([self._face_n, np.zeros((k, 3))])
        self._bbox = np.concatenate(
            [self._bbox, np.broadcast_to(_EMPTY, (self.n_views, k, 4))], axis=1)

    def _face_bbox(self, slots):
        """Pixel bounding boxes (V, k, 4) int64 (c0, c1, r0, r1, clipped to the image;
        c0 > c1 or r0 > r1 when empty), with the kernel's rounding."""
        s = self._screen[:, self._faces[slots]]  # (V, k, 3, 4)
        x, y = s[..., 0], s[..., 1]
        lim_x, lim_y = float(self.width + 1), float(self.height + 1)
        with np.errstate(invalid="ignore"):
            c0 = np.clip(np.ceil(x.min(axis=2) - 0.5), -1.0, lim_x)
            c1 = np.clip(np.floor(x.max(axis=2) - 0.5), -1.0, lim_x)
            r0 = np.clip(np.ceil(y.min(axis=2) - 0.5), -1.0, lim_y)
            r1 = np.clip(np.floor(y.max(axis=2) - 0.5), -1.0, lim_y)
        box = np.empty(c0.shape + (4,), np.int64)
        box[..., 0] = np.maximum(np.nan_to_num(c0, nan=lim_x), 0)
        box[..., 1] = np.minimum(np.nan_to_num(c1, nan=-1.0), self.width - 1)
        box[..., 2] = np.maximum(np.nan_to_num(r0, nan=lim_y), 0)
        box[..., 3] = np.minimum(np.nan_to_num(r1, nan=-1.0), self.height - 1)
        return box

    def _rebuild_index(self):
        self._ptr, self._items = _build_tiles(self._bbox, self._alive, self.tile,
                                              self._nx, self._ny)
        self._dirty = set()

    def _vertex_light(self, verts):
        """(V, k, 4) lighting of vertices, with rasterize_luminance's expressions."""
        a, d, ks, shin, _ = self._consts
        return vertex_light(self._positions[verts], self._vertex_n[verts], self._eyes,
                            a, d, ks, shin, self.specular)

    def _update_vertex_normals(self, vertices):
        """Recompute the welded normals of the groups of ``vertices``; return the
        vertices whose normal changed (bit for bit)."""
        groups = {self._group_of[i] for i in vertices}
        changed = []
        for key in groups:
            members = self._groups.get(key, ())
            if not members:
                continue
            pairs = []
            for i in members:
                for f in self._adjacency[i]:
                    for corner in range(3):
                        if self._faces[f, corner] == i:
                            pairs.append((corner, f))
            pairs.sort()
            acc = np.zeros((1, 3))
            if pairs:
                fs = np.array([f for _, f in pairs], dtype=np.int64)
                area_n = np.cross(*_edge_vectors(self._positions, self._faces[fs]))
                for row in area_n:
                    acc[0] += row
            normal = _normalize(acc)[0]
            for i in members:
                if not np.array_equal(self._vertex_n[i], normal):
                    self._vertex_n[i] = normal
                    changed.append(i)
        return changed

    def _shade_args(self, verts, slots, views):
        a, d, ks, shin, albedo = self._consts
        if self._gouraud:
            light = np.ascontiguousarray(self._light[np.ix_(views, verts)])
            face_n = np.zeros((1, 3))
        else:
            light = np.zeros((1, 1, 4))
            face_n = np.ascontiguousarray(self._face_n[slots])
        return (np.ascontiguousarray(self._positions[verts]), face_n,
                np.ascontiguousarray(self._eyes[views]), light, self._gouraud,
                self.specular, a, d, ks, shin, albedo, np.zeros((1, 2)),
                np.zeros((1, 1, 3), np.uint8), False, float(BACKGROUND))

    def _render_full(self):
        views = np.arange(self.n_views)
        slots = np.flatnonzero(self._alive)
        self._images = np.full((self.n_views, self.height, self.width), float(BACKGROUND))
        self._ids = np.full((self.n_views, self.height, self.width), -1, np.int32)
        if len(slots) == 0:
            return
        faces = np.ascontiguousarray(self._faces[slots])
        verts = np.arange(len(self._positions))
        ids = _raster_kernel(self._screen, faces, self.width, self.height)
        positions, face_n, eyes, light, *rest = self._shade_args(verts, slots, views)
        self._images = _shade_kernel(ids, self._screen, positions, faces, face_n, eyes,
                                     light, *rest)
        self._ids = np.where(ids >= 0, slots[np.maximum(ids, 0)], -1).astype(np.int32)

    def _render_rects(self, rects):
        active = np.flatnonzero((rects[:, 0] <= rects[:, 1]) & (rects[:, 2] <= rects[:, 3]))
        if len(active) == 0:
            return
        # All active views in one call of each kernel: the candidate faces of every
        # view are drawn in every active view (a superset, still in slot order, so the
        # pixels inside each view's rectangle are unchanged) on an image truncated to
        # the largest bottom-right corner of the rectangles.
        mark = np.zeros(len(self._faces), np.bool_)
        dirty = np.fromiter(self._dirty, dtype=np.int32, count=len(self._dirty))
        _gather(self._ptr, self._items, self._bbox, self._alive, dirty,
                active.astype(np.int64), np.ascontiguousarray(rects[active]), self.tile,
                self._nx, mark)
        slots = np.flatnonzero(mark)  # increasing: the drawing order of the full render
        act = rects[active]
        if len(slots) == 0:
            for v, (c0, c1, r0, r1) in zip(active, act):
                self._images[v, r0:r1 + 1, c0:c1 + 1] = float(BACKGROUND)
                self._ids[v, r0:r1 + 1, c0:c1 + 1] = -1
            return
        verts, local = np.unique(self._faces[slots], return_inverse=True)
        faces = local.reshape(-1, 3).astype(np.int32)
        screen = np.ascontiguousarray(self._screen[np.ix_(active, verts)])
        width, height = int(act[:, 1].max()) + 1, int(act[:, 3].max()) + 1
        ids = _raster_kernel(screen, faces, width, height)
        positions, face_n, eyes, light, *rest = self._shade_args(verts, slots, active)
        lum = _shade_kernel(ids, screen, positions, faces, face_n, eyes, light, *rest)
        for k, (v, (c0, c1, r0, r1)) in enumerate(zip(active, act)):
            self._images[v, r0:r1 + 1, c0:c1 + 1] = lum[k, r0:r1 + 1, c0:c1 + 1]
            sub = ids[k, r0:r1 + 1, c0:c1 + 1]
            self._ids[v, r0:r1 + 1, c0:c1 + 1] = np.where(sub >= 0, slots[np.maximum(sub, 0)], -1)
