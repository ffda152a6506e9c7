"""A Multi-Triangulation (De Floriani et al. 1997) built from the engine's collapse log.

Williams et al. 2003, §2.3: the MT is a DAG whose nodes are local simplification
operations and whose arcs carry triangles. Here a node is one edge collapse of the
shared engine (:func:`methods.engine.simplify_mesh`), in the order the engine took them;
the original triangles hang below the *drain* and the triangles left after the last
collapse below the *source*. Every triangle that ever exists is stored once, with the
node that creates it (its ``creator``; -1 = the drain) and the node that removes it
(its ``destroyer``; -1 = the source). The arc of a triangle runs from its destroyer
(above) down to its creator (below)::

        source                      collapse i removes the triangles of the star of
       /  |   \\                     u (and of v when v moves or its UVs change) and
    c_k  ...   c_j   <- later       creates the new star of v: the removed ones are
      \\   |   /                      its child arcs, the created ones its parent arcs
       c_i ...                       (§2.3: "the triangles removed ... are stored with
        |                             the child arcs of the operation's node")
      drain

A *cut* is stored as the set of *applied* collapses (below the cut, in the paper's
words); it must be closed downwards: a collapse is applied only if every collapse that
created one of its removed triangles is (its children). A triangle is in the cut when
its creator is applied (or is the drain) and its destroyer is not (or is the source).
*Raising* a node refines (un-applies its collapse: the node moves above the cut) and
first raises every applied ancestor; *lowering* applies it and first lowers every
refined descendant (§5.1: "lifting a node may require lifting parent nodes that are
below the cut while dropping a node may require recursively dropping child nodes").

How the collapse sequence is made (§4: "progressive edge collapse simplification with
the goal of minimizing object-space texture deviation"): the engine's ``quadric``
policy with Garland & Heckbert 1998 texture quadrics (position and UV per wedge,
``texture_weight`` 1 on a unit-diagonal model) and its seam rule. It is a proxy: the
texture quadric penalises moving a point off its place in the parameterisation, which
is what texture deviation measures, but it bounds a sum of squared distances, not the
maximum. Untextured meshes use the plain 1997 quadric.

The MT is bookkeeping over the engine's log: per collapse it names the removed and kept
vertices, the new position, the removed faces, the wedge pairs merged across them and
the merged vertex's wedges with their UVs after the collapse, so :func:`from_log`
replays the sequence without a second copy of the engine's rules. The tests check the
replay against the engine's final mesh: the coarsest cut has its positions and UVs.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from bench.core import progress
from bench.core.mesh import Mesh, compact

__all__ = ["Cut", "MultiTriangulation", "build_mt", "from_log"]

#: A collapse that moves the kept vertex by less than this (on the unit-diagonal model)
#: is a half-edge collapse: the vertex keeps its exact input position, as in the engine.
_MOVE_TOLERANCE = 1e-12


@dataclass
class MultiTriangulation:
    """The MT of a mesh: every triangle of every resolution, and the nodes between them.

    Attributes
    ----------
    positions : ndarray of shape (nv, 3) float64
        MT vertices: a render vertex (wedge) of the input, or a new version of one made
        by a collapse (new position or new UV).
    uv : ndarray of shape (nv, 2) float64 or None
    triangles : ndarray of shape (nt, 3) int32
        Every triangle, as MT vertex indices; the first ``n_original`` are the input's
        faces in their order.
    welded : ndarray of shape (nv,) int32
        The input's welded vertex each MT vertex is a version of.
    creator, destroyer : ndarray of shape (nt,) int32
        The node creating / removing each triangle; -1 = drain / source.
    created_start, created : ndarray (c + 1,), (k,) int32
        CSR: the triangles node i creates (its parent arcs).
    removed_start, removed : ndarray (c + 1,), (k,) int32
        CSR: the triangles node i removes (its child arcs).
    parent_start, parents, child_start, children : ndarray int32
        CSR: the nodes destroying node i's created triangles (parents, all > i) and the
        nodes creating its removed triangles (children, all < i).
    delta : ndarray of shape (c,) int32
        Faces gained when node i is raised (refined): removed minus created.
    texture : ndarray or None
        The input's texture image, shared by every cut.
    stats : dict
        Engine statistics and its stop reason.
    """

    positions: np.ndarray
    uv: np.ndarray | None
    triangles: np.ndarray
    welded: np.ndarray
    creator: np.ndarray
    destroyer: np.ndarray
    created_start: np.ndarray
    created: np.ndarray
    removed_start: np.ndarray
    removed: np.ndarray
    parent_start: np.ndarray
    parents: np.ndarray
    child_start: np.ndarray
    children: np.ndarray
    delta: np.ndarray
    n_original: int
    texture: np.ndarray | None = None
    name: str = "mesh"
    stats: dict = field(default_factory=dict)

    @property
    def n_nodes(self) -> int:
        """Collapse nodes (the source and drain are implicit)."""
        return len(self.delta)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    @property
    def coarsest_faces(self) -> int:
        """Faces of the cut just below the source (every collapse applied)."""
        return int(np.count_nonzero(self.destroyer == -1))

    def node_created(self, i: int) -> np.ndarray:
        return self.created[self.created_start[i]:self.created_start[i + 1]]

    def node_removed(self, i: int) -> np.ndarray:
        return self.removed[self.removed_start[i]:self.removed_start[i + 1]]

    def node_parents(self, i: int) -> np.ndarray:
        return self.parents[self.parent_start[i]:self.parent_start[i + 1]]

    def node_children(self, i: int) -> np.ndarray:
        return self.children[self.child_start[i]:self.child_start[i + 1]]

    def cut(self, level: str = "coarsest") -> Cut:
        """A new cut: ``"coarsest"`` (every collapse applied) or ``"finest"`` (none)."""
        if level not in ("coarsest", "finest"):
            raise ValueError(f"level must be 'coarsest' or 'finest', got {level!r}")
        return Cut(self, np.full(self.n_nodes, level == "coarsest"))


class Cut:
    """A cut of a :class:`MultiTriangulation`: which collapses are applied.

    Parameters
    ----------
    mt : MultiTriangulation
    applied : ndarray of shape (c,) bool
        Must be closed downwards (every child of an applied node applied); checked.
    """

    def __init__(self, mt: MultiTriangulation, applied: np.ndarray):
        applied = np.asarray(applied, dtype=np.bool_).copy()
        if applied.shape != (mt.n_nodes,):
            raise ValueError(f"applied must have shape ({mt.n_nodes},), got {applied.shape}")
        self.mt = mt
        self.applied = applied
        bad = _first_open_node(applied, mt.child_start, mt.children)
        if bad >= 0:
            raise ValueError(f"not a cut: collapse {bad} is applied but one of its children "
                             "is not (apply the children first, or use lower_node)")
        self.n_applied_parents, self.n_refined_children = _frontier_counts(
            applied, mt.parent_start, mt.parents, mt.child_start, mt.children)
        self.n_faces = mt.coarsest_faces + int(mt.delta[~applied].sum())
        self._stack = np.empty(max(1, mt.n_nodes), np.int32)
        self._mark = np.zeros(max(1, mt.n_nodes), np.int32)
        self._tick = np.zeros(1, np.int64)

    def copy(self) -> Cut:
        return Cut(self.mt, self.applied)

    def raise_node(self, i: int) -> np.ndarray:
        """Refine node ``i`` (un-apply its collapse) after raising its applied ancestors.

        Returns the nodes raised, in the order raised (``i`` last; empty when ``i`` is
        already above the cut). Lowering them in the reverse order restores the cut.
        """
        self._check_node(i)
        order, self.n_faces = _raise_closure(
            i, self.applied, self.n_faces, self.mt.delta, self.mt.parent_start,
            self.mt.parents, self.mt.child_start, self.mt.children, self.n_applied_parents,
            self.n_refined_children, self._stack, self._mark, self._tick)
        return order

    def lower_node(self, i: int) -> np.ndarray:
        """Apply node ``i``'s collapse after lowering its refined descendants.

        Returns the nodes lowered, in the order lowered (``i`` last; empty when ``i``
        is already below the cut). Raising them in the reverse order restores the cut.
        """
        self._check_node(i)
        order, self.n_faces = _lower_closure(
            i, self.applied, self.n_faces, self.mt.delta, self.mt.parent_start,
            self.mt.parents, self.mt.child_start, self.mt.children, self.n_applied_parents,
            self.n_refined_children, self._stack, self._mark, self._tick)
        return order

    def _check_node(self, i: int) -> None:
        if not 0 <= i < self.mt.n_nodes:
            raise IndexError(f"node {i} out of range (the MT has {self.mt.n_nodes} nodes)")

    def triangles(self) -> np.ndarray:
        """ndarray (n_faces,) int: the MT triangles crossing the cut, in index order."""
        return np.flatnonzero(_in_cut(self.applied, self.mt.creator, self.mt.destroyer))

    def mesh(self) -> Mesh:
        """The cut as a :class:`Mesh` (render vertices = the MT vertices it uses)."""
        tris = self.mt.triangles[self.triangles()]
        used, faces = compact(tris)
        return Mesh(self.mt.positions[used], faces,
                    uv=None if self.mt.uv is None else self.mt.uv[used],
                    texture=self.mt.texture if self.mt.uv is not None else None,
                    name=self.mt.name)


# -- building ------------------------------------------------------------------------------

def build_mt(mesh: Mesh, texture_weight: float = 1.0, target_faces: int = 1,
             boundary_weight: float = 1000.0) -> MultiTriangulation:
    """Simplify ``mesh`` with the engine's quadric policy and build its MT.

    Parameters
    ----------
    mesh : Mesh
    texture_weight : float
        Weight of UVs in the Garland–Heckbert 1998 texture quadrics (the texture
        deviation proxy, see the module docstring); 0 uses the 1997 quadric.
    target_faces : int
        Where the engine stops (it also stops when no valid collapse remains, after
        the stall rule of ``quadric``: ``Policy.stall_rotations``); the coarsest cut
        has about this many faces.
    boundary_weight : float
        The engine's boundary-plane weight.
    """
    from methods.engine.policy import STALL_ROTATIONS, Policy
    from methods.engine.simplify import simplify_mesh

    if mesh.n_faces == 0:
        raise ValueError(f"{mesh.name}: a Multi-Triangulation needs a mesh with faces")
    if texture_weight < 0:
        raise ValueError(f"texture_weight must be >= 0, got {texture_weight}")
    policy = Policy(placement="optimal", texture_weight=texture_weight,
                    boundary_weight=boundary_weight, stall_rotations=STALL_ROTATIONS)
    progress.stage("building the Multi-Triangulation")
    result = simplify_mesh(mesh, max(1, int(target_faces)), policy)
    mt = from_log(mesh, result.log)
    mt.stats = {**result.stats, "engine_stop_reason": result.stop_reason}
    return mt


def from_log(mesh: Mesh, log: dict) -> MultiTriangulation:
    """Replay an engine collapse log on ``mesh`` into a :class:`MultiTriangulation`.

    Parameters
    ----------
    mesh : Mesh
        The mesh the engine simplified.
    log : dict of ndarray
        :attr:`methods.engine.EngineResult.log`: the collapses with their positions,
        removed faces, wedge pairs and the merged vertices' wedges and UVs.
    """
    w = mesh.welded
    P0 = w.positions.astype(np.float64)
    lo = P0.min(axis=0)
    scale = float(np.linalg.norm(P0.max(axis=0) - lo)) or 1.0
    Pn = (P0 - lo) / scale  # the engine's unit-diagonal coordinates
    has_uv = mesh.uv is not None
    uv = mesh.uv.astype(np.float64).copy() if has_uv else np.zeros((mesh.n_vertices, 2))
    i64 = np.int64
    out = _replay(P0.copy(), Pn, w.faces.astype(i64).copy(), mesh.faces.astype(i64).copy(),
                  uv, w.vertex_of.astype(i64), mesh.positions.astype(np.float64),
                  log["removed"].astype(i64), log["kept"].astype(i64),
                  np.ascontiguousarray(log["position"], dtype=np.float64),
                  log["removed_faces"].astype(i64), log["pair_start"].astype(i64),
                  np.ascontiguousarray(log["wedge_pairs"], dtype=i64).reshape(-1, 2),
                  log["wedge_start"].astype(i64), log["wedges"].astype(i64),
                  np.ascontiguousarray(log["wedge_uv"], dtype=np.float64).reshape(-1, 2),
                  lo, scale)
    (positions, uvs, welded, tris, creator, destroyer, c_start, c_list, r_start,
     r_list) = out
    c = len(log["removed"])
    parent_start, parents, child_start, children = _dependencies(creator, destroyer, c)
    delta = (np.diff(r_start) - np.diff(c_start)).astype(np.int32)
    return MultiTriangulation(
        positions=positions, uv=uvs if has_uv else None, triangles=tris.astype(np.int32),
        welded=welded.astype(np.int32), creator=creator.astype(np.int32),
        destroyer=destroyer.astype(np.int32), created_start=c_start.astype(np.int32),
        created=c_list.astype(np.int32), removed_start=r_start.astype(np.int32),
        removed=r_list.astype(np.int32), parent_start=parent_start, parents=parents,
        child_start=child_start, children=children, delta=delta, n_original=mesh.n_faces,
        texture=mesh.texture if has_uv else None, name=mesh.name)


def _dependencies(creator, destroyer, c):
    """Parent and child CSR lists from the triangles' arcs (destroyer above creator)."""
    both = (creator >= 0) & (destroyer >= 0)
    pairs = np.unique(np.stack([creator[both], destroyer[both]], 1).astype(np.int64), axis=0)
    lower, upper = pairs[:, 0], pairs[:, 1]  # upper is a parent of lower

    def csr(keys, values):
        order = np.lexsort((values, keys))
        start = np.zeros(c + 1, np.int32)
        np.add.at(start, keys + 1, 1)
        return np.cumsum(start).astype(np.int32), values[order].astype(np.int32)

    parent_start, parents = csr(lower, upper)
    child_start, children = csr(upper, lower)
    return parent_start, parents, child_start, children


@njit(cache=True)
def _grow(a, n):
    if n < a.shape[0]:
        return a
    b = np.empty((2 * a.shape[0],) + a.shape[1:], a.dtype)
    b[:a.shape[0]] = a
    return b


@njit(cache=True)
def _mapped(wd, pairs, p0, p1):
    """Wedge ``wd`` after the collapse whose pairs are ``pairs[p0:p1]``."""
    for q in range(p0, p1):
        if pairs[q, 0] == wd:
            return pairs[q, 1]
    return wd


@njit(cache=True)
def _replay(Pw, Pn, F, FW, uv, wedge_vertex, wedge_pos, log_removed, log_kept, log_pos,
            log_faces, pair_start, pairs, wedge_start, wedges, wedge_uv, lo, scale):
    """Replay the collapse log; returns the MT arrays (see from_log).

    Per collapse: the removed faces die; the faces around u (renamed to v) and those
    around v whose v corner changed are replaced by new triangles; a wedge of the
    merged vertex gets a new MT vertex when its position or UV changed, or when it
    was u's."""
    nv = Pn.shape[0]
    m = F.shape[0]
    nw = wedge_pos.shape[0]
    c = log_removed.shape[0]
    # vertex -> corner lists (3f + k), dead corners skipped
    vhead = np.full(nv, -1, np.int64)
    cnext = np.full(3 * m, -1, np.int64)
    for corner in range(3 * m - 1, -1, -1):
        x = F[corner // 3, corner % 3]
        cnext[corner] = vhead[x]
        vhead[x] = corner
    falive = np.ones(m, np.bool_)
    # MT vertices: the input's wedges first
    mv_pos = np.empty((nw + 8 * c + 16, 3))
    mv_uv = np.empty((nw + 8 * c + 16, 2))
    mv_welded = np.empty(nw + 8 * c + 16, np.int64)
    for x in range(nw):
        mv_pos[x] = wedge_pos[x]
        mv_uv[x] = uv[x]
        mv_welded[x] = wedge_vertex[x]
    n_mv = nw
    wedge_mv = np.arange(nw)
    # MT triangles: the input's faces first
    tris = np.empty((m + 8 * c + 16, 3), np.int64)
    creator = np.full(m + 8 * c + 16, -1, np.int64)
    destroyer = np.full(m + 8 * c + 16, -1, np.int64)
    for f in range(m):
        for k in range(3):
            tris[f, k] = FW[f, k]
    n_t = m
    face_tri = np.arange(m)
    c_start = np.zeros(c + 1, np.int64)
    r_start = np.zeros(c + 1, np.int64)
    c_list = np.empty(8 * c + 16, np.int64)
    r_list = np.empty(8 * c + 16, np.int64)
    n_c = 0
    n_r = 0
    fresh = np.zeros(256, np.bool_)
    star = np.empty(1024, np.int64)
    pn = np.empty(3)
    for i in range(c):
        u = log_removed[i]
        v = log_kept[i]
        p0, p1 = pair_start[i], pair_start[i + 1]
        w0, w1 = wedge_start[i], wedge_start[i + 1]
        for k in range(3):
            pn[k] = (log_pos[i, k] - lo[k]) / scale
        moved = False
        for k in range(3):
            if abs(pn[k] - Pn[v, k]) > _MOVE_TOLERANCE:
                moved = True
        # the star of u and v (alive faces, each once)
        ns = 0
        for side in range(2):
            x = u if side == 0 else v
            corner = vhead[x]
            while corner != -1:
                f = corner // 3
                if falive[f] and (side == 0 or (F[f, 0] != u and F[f, 1] != u
                                                and F[f, 2] != u)):
                    star = _grow(star, ns)
                    star[ns] = f
                    ns += 1
                corner = cnext[corner]
        # the merged vertex's wedges take their logged UVs
        fresh = _grow(fresh, w1 - w0)
        for q in range(w1 - w0):
            wd = wedges[w0 + q]
            fresh[q] = (moved or wedge_vertex[wd] == u or wedge_uv[w0 + q, 0] != uv[wd, 0]
                        or wedge_uv[w0 + q, 1] != uv[wd, 1])
            uv[wd, 0] = wedge_uv[w0 + q, 0]
            uv[wd, 1] = wedge_uv[w0 + q, 1]
        if moved:
            for k in range(3):
                Pn[v, k] = pn[k]
                Pw[v, k] = log_pos[i, k]
        # new MT vertices for the wedges that changed
        for q in range(w1 - w0):
            wd = wedges[w0 + q]
            wedge_vertex[wd] = v
            if fresh[q]:
                mv_pos = _grow(mv_pos, n_mv)
                mv_uv = _grow(mv_uv, n_mv)
                mv_welded = _grow(mv_welded, n_mv)
                mv_pos[n_mv] = Pw[v]
                mv_uv[n_mv] = uv[wd]
                mv_welded[n_mv] = v
                wedge_mv[wd] = n_mv
                n_mv += 1
        # the removed faces die
        for s in range(2):
            r = log_faces[i, s]
            if r < 0:
                continue
            falive[r] = False
            destroyer[face_tri[r]] = i
            r_list = _grow(r_list, n_r)
            r_list[n_r] = face_tri[r]
            n_r += 1
        # u's faces are renamed; v's faces are replaced when their v corner changed
        for q in range(ns):
            f = star[q]
            if not falive[f]:
                continue
            replace = False
            for k in range(3):
                if F[f, k] == u or F[f, k] == v:
                    wd = _mapped(FW[f, k], pairs, p0, p1)
                    if F[f, k] == u or wedge_mv[wd] != tris[face_tri[f], k]:
                        replace = True
                    F[f, k] = v
                    FW[f, k] = wd
            if not replace:
                continue
            destroyer[face_tri[f]] = i
            r_list = _grow(r_list, n_r)
            r_list[n_r] = face_tri[f]
            n_r += 1
            tris = _grow(tris, n_t)
            creator = _grow(creator, n_t)
            destroyer = _grow(destroyer, n_t)
            for k in range(3):
                tris[n_t, k] = wedge_mv[FW[f, k]]
            creator[n_t] = i
            destroyer[n_t] = -1
            face_tri[f] = n_t
            c_list = _grow(c_list, n_c)
            c_list[n_c] = n_t
            n_c += 1
            n_t += 1
        # u's corners join v's list
        corner = vhead[u]
        last = -1
        while corner != -1:
            last = corner
            corner = cnext[corner]
        if last != -1:
            cnext[last] = vhead[v]
            vhead[v] = vhead[u]
        vhead[u] = -1
        c_start[i + 1] = n_c
        r_start[i + 1] = n_r
    return (mv_pos[:n_mv].copy(), mv_uv[:n_mv].copy(), mv_welded[:n_mv].copy(),
            tris[:n_t].copy(), creator[:n_t].copy(), destroyer[:n_t].copy(), c_start,
            c_list[:n_c].copy(), r_start, r_list[:n_r].copy())


# -- cut operations (numba) ------------------------------------------------------------------

@njit(cache=True)
def _first_open_node(applied, child_start, children):
    """The first applied node with a refined child, or -1 (the cut is closed)."""
    for i in range(applied.shape[0]):
        if applied[i]:
            for j in range(child_start[i], child_start[i + 1]):
                if not applied[children[j]]:
                    return i
    return -1


@njit(cache=True)
def _frontier_counts(applied, parent_start, parents, child_start, children):
    """Per node: how many parents are applied, how many children refined."""
    c = applied.shape[0]
    n_ap = np.zeros(c, np.int32)
    n_rc = np.zeros(c, np.int32)
    for i in range(c):
        for j in range(parent_start[i], parent_start[i + 1]):
            if applied[parents[j]]:
                n_ap[i] += 1
        for j in range(child_start[i], child_start[i + 1]):
            if not applied[children[j]]:
                n_rc[i] += 1
    return n_ap, n_rc


@njit(cache=True)
def _set_refined(i, applied, parent_start, parents, child_start, children, n_ap, n_rc):
    """Un-apply node i (its parents must be refined) and update the frontier counts."""
    applied[i] = False
    for j in range(parent_start[i], parent_start[i + 1]):
        n_rc[parents[j]] += 1
    for j in range(child_start[i], child_start[i + 1]):
        n_ap[children[j]] -= 1


@njit(cache=True)
def _set_applied(i, applied, parent_start, parents, child_start, children, n_ap, n_rc):
    """Apply node i (its children must be applied) and update the frontier counts."""
    applied[i] = True
    for j in range(parent_start[i], parent_start[i + 1]):
        n_rc[parents[j]] -= 1
    for j in range(child_start[i], child_start[i + 1]):
        n_ap[children[j]] += 1


@njit(cache=True)
def _collect(i, want_applied, applied, start, links, stack, mark, tick):
    """Node i and every node reachable from it through ``links`` whose applied state
    is ``want_applied``, into stack[:n]; returns n."""
    tick[0] += 1
    t = tick[0]
    if applied[i] != want_applied:
        return 0
    n = 0
    stack[n] = i
    mark[i] = t
    n += 1
    head = 0
    while head < n:
        x = stack[head]
        head += 1
        for j in range(start[x], start[x + 1]):
            y = links[j]
            if mark[y] != t and applied[y] == want_applied:
                mark[y] = t
                stack[n] = y
                n += 1
    return n


@njit(cache=True)
def _raise_closure(i, applied, n_faces, delta, parent_start, parents, child_start, children,
                   n_ap, n_rc, stack, mark, tick):
    """Refine node i and its applied ancestors, parents first (they have higher
    indices: a parent removes triangles its child created later in the sequence)."""
    n = _collect(i, True, applied, parent_start, parents, stack, mark, tick)
    order = np.sort(stack[:n])[::-1].copy()
    for x in order:
        _set_refined(x, applied, parent_start, parents, child_start, children, n_ap, n_rc)
        n_faces += delta[x]
    return order, n_faces


@njit(cache=True)
def _lower_closure(i, applied, n_faces, delta, parent_start, parents, child_start, children,
                   n_ap, n_rc, stack, mark, tick):
    """Apply node i after its refined descendants, children first (lower indices)."""
    n = _collect(i, False, applied, child_start, children, stack, mark, tick)
    order = np.sort(stack[:n])
    for x in order:
        _set_applied(x, applied, parent_start, parents, child_start, children, n_ap, n_rc)
        n_faces -= delta[x]
    return order, n_faces


@njit(cache=True)
def _in_cut(applied, creator, destroyer):
    """(nt,) bool: the triangles crossing the cut."""
    nt = creator.shape[0]
    out = np.zeros(nt, np.bool_)
    for t in range(nt):
        below = creator[t] < 0 or applied[creator[t]]
        above = destroyer[t] < 0 or not applied[destroyer[t]]
        out[t] = below and above
    return out
