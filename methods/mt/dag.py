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

from collections import namedtuple
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from bench.core import progress
from bench.core.mesh import Mesh, compact
from methods.corners import corner_lists, corners

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

    def arcs(self) -> _Arcs:
        """The MT's arcs as the cut's kernels read them (:data:`_Arcs`)."""
        mt = self.mt
        return _Arcs(mt.delta, mt.parent_start, mt.parents, mt.child_start, mt.children)

    def frontier(self) -> _CutArrays:
        """The cut's arrays, which its kernels change in place (:data:`_CutArrays`)."""
        return _CutArrays(self.applied, self.n_applied_parents, self.n_refined_children)

    def raise_node(self, i: int) -> np.ndarray:
        """Refine node ``i`` (un-apply its collapse) after raising its applied ancestors.

        Returns the nodes raised, in the order raised (``i`` last; empty when ``i`` is
        already above the cut). Lowering them in the reverse order restores the cut.
        """
        self._check_node(i)
        order, self.n_faces = _raise_closure(i, self.n_faces, self.arcs(), self.frontier(),
                                             (self._stack, self._mark, self._tick))
        return order

    def lower_node(self, i: int) -> np.ndarray:
        """Apply node ``i``'s collapse after lowering its refined descendants.

        Returns the nodes lowered, in the order lowered (``i`` last; empty when ``i``
        is already below the cut). Raising them in the reverse order restores the cut.
        """
        self._check_node(i)
        order, self.n_faces = _lower_closure(i, self.n_faces, self.arcs(), self.frontier(),
                                             (self._stack, self._mark, self._tick))
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
    has_uv = mesh.uv is not None
    i64 = np.int64
    given = _Given(
        Pw=P0.copy(), Pn=(P0 - lo) / scale,  # Pn: the engine's unit-diagonal coordinates
        F=w.faces.astype(i64).copy(), FW=mesh.faces.astype(i64).copy(),
        uv=mesh.uv.astype(np.float64).copy() if has_uv else np.zeros((mesh.n_vertices, 2)),
        wedge_vertex=w.vertex_of.astype(i64), wedge_pos=mesh.positions.astype(np.float64),
        lo=lo, scale=scale)
    steps = _Steps(
        removed=log["removed"].astype(i64), kept=log["kept"].astype(i64),
        position=np.ascontiguousarray(log["position"], dtype=np.float64),
        faces=log["removed_faces"].astype(i64), pair_start=log["pair_start"].astype(i64),
        pairs=np.ascontiguousarray(log["wedge_pairs"], dtype=i64).reshape(-1, 2),
        wedge_start=log["wedge_start"].astype(i64), wedges=log["wedges"].astype(i64),
        wedge_uv=np.ascontiguousarray(log["wedge_uv"], dtype=np.float64).reshape(-1, 2))
    b = _replay(given, steps)
    n_mv, n_t, n_c, n_r = (int(x) for x in b.n)
    positions, uvs, welded = b.pos[:n_mv].copy(), b.uv[:n_mv].copy(), b.welded[:n_mv]
    tris, creator, destroyer = b.tris[:n_t], b.creator[:n_t], b.destroyer[:n_t]
    c_start, c_list, r_start, r_list = b.c_start, b.created[:n_c], b.r_start, b.removed[:n_r]
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


#: The MT's arcs as the cut's kernels read them: each node's ``delta`` (faces added when
#: it is refined) and its parents and children (CSR lists).
_Arcs = namedtuple("_Arcs", "delta parent_start parents child_start children")
#: A cut's arrays (:class:`Cut`): ``applied`` per node and, per node, its applied parents
#: and refined children (``n_ap``, ``n_rc``), all changed in place.
_CutArrays = namedtuple("_CutArrays", "applied n_ap n_rc")

#: The replay's input: the welded mesh the engine simplified (positions ``Pw`` and their
#: unit-diagonal ``Pn``, faces ``F``; changed by the replay), the render mesh's faces
#: ``FW`` (wedges; changed), each wedge's ``uv`` (changed), welded vertex
#: ``wedge_vertex`` (changed) and input position ``wedge_pos``, and the unit frame
#: (``lo``, ``scale``).
_Given = namedtuple("_Given", "Pw Pn F FW uv wedge_vertex wedge_pos lo scale")
#: The engine's collapse log (:attr:`methods.engine.EngineResult.log`) as int64 and
#: float64 arrays: per collapse the ``removed`` and ``kept`` vertices, the new
#: ``position``, the two removed ``faces`` (-1: none), the merged wedge ``pairs``
#: (CSR by ``pair_start``) and the merged vertex's ``wedges`` with their ``wedge_uv``
#: (CSR by ``wedge_start``).
_Steps = namedtuple("_Steps", "removed kept position faces pair_start pairs wedge_start "
                              "wedges wedge_uv")
#: What the replay keeps between collapses: each vertex's corner list (``vhead``,
#: ``cnext``; corners 3f + k, dead ones left in), the live faces, each face's MT
#: triangle and each wedge's MT vertex.
_Walk = namedtuple("_Walk", "vhead cnext falive face_tri wedge_mv")
#: The MT as it is built: its vertices (``pos``, ``uv``, ``welded``), its triangles
#: (``tris`` of MT vertices, ``creator``, ``destroyer``), the triangles each collapse
#: ``created`` and ``removed`` (CSR by ``c_start`` and ``r_start``), and ``n``: the
#: counts of vertices, triangles, created and removed (:data:`_N_VERTICES`, ...).
_Built = namedtuple("_Built", "pos uv welded tris creator destroyer created removed "
                              "c_start r_start n")
_N_VERTICES, _N_TRIANGLES, _N_CREATED, _N_REMOVED = 0, 1, 2, 3


@njit(cache=True)
def _grow(a, n):
    """``a``, or a copy of it at least twice as long, so that index ``n`` is in it."""
    if n < a.shape[0]:
        return a
    b = np.empty((max(2 * a.shape[0], n + 1),) + a.shape[1:], a.dtype)
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
def _replay(given, steps):
    """Replay the collapse log; returns the MT (:data:`_Built`; see from_log).

    Per collapse: the removed faces die; the faces around u (renamed to v) and those
    around v whose v corner changed are replaced by new triangles; a wedge of the
    merged vertex gets a new MT vertex when its position or UV changed, or when it
    was u's."""
    walk, b = _start(given, steps)
    star = np.empty(1024, np.int64)
    fresh = np.zeros(256, np.bool_)
    pn = np.empty(3)
    for i in range(steps.removed.shape[0]):
        u, v = steps.removed[i], steps.kept[i]
        moved = _moves(given, steps, i, v, pn)
        star, ns = _star(given.F, walk, u, v, star)
        fresh = _merge_wedges(given, steps, walk, b, i, moved, pn, fresh)
        for s in range(2):  # the removed faces die
            r = steps.faces[i, s]
            if r >= 0:
                walk.falive[r] = False
                b = _with_room(b)
                _destroy(b, walk, r, i)
        for q in range(ns):  # u's faces are renamed; v's are replaced if their v corner changed
            f = star[q]
            if walk.falive[f] and _rename(given, steps, walk, b, f, i, u, v):
                b = _with_room(b)
                _destroy(b, walk, f, i)
                _create(b, walk, given.FW, f, i)
        _splice(walk, u, v)
        b.c_start[i + 1] = b.n[_N_CREATED]
        b.r_start[i + 1] = b.n[_N_REMOVED]
    return b


@njit(cache=True)
def _start(given, steps):
    """The walk and the MT before the first collapse: the input's wedges and faces."""
    m, nw, c = given.F.shape[0], given.wedge_pos.shape[0], steps.removed.shape[0]
    vhead, cnext = corner_lists(given.F, given.Pn.shape[0])
    walk = _Walk(vhead=vhead, cnext=cnext, falive=np.ones(m, np.bool_), face_tri=np.arange(m),
                 wedge_mv=np.arange(nw))
    # every wedge of a collapse adds at most one MT vertex
    n_vertices = nw + steps.wedges.shape[0]
    pos, uv = np.empty((n_vertices, 3)), np.empty((n_vertices, 2))
    welded = np.empty(n_vertices, np.int64)
    pos[:nw] = given.wedge_pos
    uv[:nw] = given.uv
    welded[:nw] = given.wedge_vertex
    tris = np.empty((m + 8 * c + 16, 3), np.int64)
    tris[:m] = given.FW
    b = _Built(pos=pos, uv=uv, welded=welded, tris=tris,
               creator=np.full(m + 8 * c + 16, -1, np.int64),
               destroyer=np.full(m + 8 * c + 16, -1, np.int64),
               created=np.empty(8 * c + 16, np.int64), removed=np.empty(8 * c + 16, np.int64),
               c_start=np.zeros(c + 1, np.int64), r_start=np.zeros(c + 1, np.int64),
               n=np.array([nw, m, 0, 0], np.int64))
    return walk, b


@njit(cache=True)
def _moves(given, steps, i, v, pn):
    """Whether collapse ``i`` moves the kept vertex ``v``; its new unit-diagonal
    position goes into ``pn``."""
    for k in range(3):
        pn[k] = (steps.position[i, k] - given.lo[k]) / given.scale
    moved = False
    for k in range(3):
        if abs(pn[k] - given.Pn[v, k]) > _MOVE_TOLERANCE:
            moved = True
    return moved


@njit(cache=True)
def _star(F, walk, u, v, star):
    """The live faces around u, then those around v without u, each once, in ``star``
    (grown when full); returns (star, their count)."""
    ns = np.int64(0)
    for side in range(2):
        x = u if side == 0 else v
        for corner in corners(x, walk.vhead, walk.cnext):
            f = corner // 3
            if walk.falive[f] and (side == 0 or (F[f, 0] != u and F[f, 1] != u
                                                 and F[f, 2] != u)):
                star = _grow(star, ns)
                star[ns] = f
                ns += 1
    return star, ns


@njit(cache=True)
def _merge_wedges(given, steps, walk, b, i, moved, pn, fresh):
    """Collapse ``i``'s merged vertex v: its wedges take their logged UVs and v its new
    position; a wedge whose position or UV changed, or that was u's, gets a new MT
    vertex. Returns ``fresh`` (scratch, grown when short)."""
    u, v = steps.removed[i], steps.kept[i]
    w0, w1 = steps.wedge_start[i], steps.wedge_start[i + 1]
    fresh = _grow(fresh, w1 - w0)
    for q in range(w1 - w0):
        wd = steps.wedges[w0 + q]
        fresh[q] = (moved or given.wedge_vertex[wd] == u
                    or steps.wedge_uv[w0 + q, 0] != given.uv[wd, 0]
                    or steps.wedge_uv[w0 + q, 1] != given.uv[wd, 1])
        given.uv[wd, 0] = steps.wedge_uv[w0 + q, 0]
        given.uv[wd, 1] = steps.wedge_uv[w0 + q, 1]
    if moved:
        for k in range(3):
            given.Pn[v, k] = pn[k]
            given.Pw[v, k] = steps.position[i, k]
    for q in range(w1 - w0):
        wd = steps.wedges[w0 + q]
        given.wedge_vertex[wd] = v
        if fresh[q]:
            x = b.n[_N_VERTICES]
            b.pos[x] = given.Pw[v]
            b.uv[x] = given.uv[wd]
            b.welded[x] = v
            walk.wedge_mv[wd] = x
            b.n[_N_VERTICES] = x + 1
    return fresh


@njit(cache=True)
def _rename(given, steps, walk, b, f, i, u, v):
    """Face ``f``'s corners at u or v become v's, with collapse ``i``'s merged wedges;
    returns whether its MT triangle must be replaced (a corner was u's, or v's corner
    now has another MT vertex)."""
    p0, p1 = steps.pair_start[i], steps.pair_start[i + 1]
    replace = False
    for k in range(3):
        x = given.F[f, k]
        if x == u or x == v:
            wd = _mapped(given.FW[f, k], steps.pairs, p0, p1)
            if x == u or walk.wedge_mv[wd] != b.tris[walk.face_tri[f], k]:
                replace = True
            given.F[f, k] = v
            given.FW[f, k] = wd
    return replace


@njit(cache=True)
def _with_room(b):
    """``b`` with room for one more triangle and one more created and removed."""
    nt = b.n[_N_TRIANGLES]
    return _Built(pos=b.pos, uv=b.uv, welded=b.welded, tris=_grow(b.tris, nt),
                  creator=_grow(b.creator, nt), destroyer=_grow(b.destroyer, nt),
                  created=_grow(b.created, b.n[_N_CREATED]),
                  removed=_grow(b.removed, b.n[_N_REMOVED]), c_start=b.c_start,
                  r_start=b.r_start, n=b.n)


@njit(cache=True)
def _destroy(b, walk, f, i):
    """Face ``f``'s MT triangle is removed by collapse ``i``."""
    t = walk.face_tri[f]
    b.destroyer[t] = i
    b.removed[b.n[_N_REMOVED]] = t
    b.n[_N_REMOVED] += 1


@njit(cache=True)
def _create(b, walk, FW, f, i):
    """Collapse ``i`` creates a new MT triangle for face ``f``."""
    t = b.n[_N_TRIANGLES]
    for k in range(3):
        b.tris[t, k] = walk.wedge_mv[FW[f, k]]
    b.creator[t] = i
    b.destroyer[t] = -1
    walk.face_tri[f] = t
    b.created[b.n[_N_CREATED]] = t
    b.n[_N_CREATED] += 1
    b.n[_N_TRIANGLES] = t + 1


@njit(cache=True)
def _splice(walk, u, v):
    """u's corners join v's list (in front of them)."""
    last = -1
    for corner in corners(u, walk.vhead, walk.cnext):
        last = corner
    if last != -1:
        walk.cnext[last] = walk.vhead[v]
        walk.vhead[v] = walk.vhead[u]
    walk.vhead[u] = -1


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
def _set_refined(i, arcs, cut):
    """Un-apply node i (its parents must be refined) and update the frontier counts
    (:data:`_Arcs`, :data:`_CutArrays`)."""
    cut.applied[i] = False
    for j in range(arcs.parent_start[i], arcs.parent_start[i + 1]):
        cut.n_rc[arcs.parents[j]] += 1
    for j in range(arcs.child_start[i], arcs.child_start[i + 1]):
        cut.n_ap[arcs.children[j]] -= 1


@njit(cache=True)
def _set_applied(i, arcs, cut):
    """Apply node i (its children must be applied) and update the frontier counts
    (:data:`_Arcs`, :data:`_CutArrays`)."""
    cut.applied[i] = True
    for j in range(arcs.parent_start[i], arcs.parent_start[i + 1]):
        cut.n_rc[arcs.parents[j]] -= 1
    for j in range(arcs.child_start[i], arcs.child_start[i + 1]):
        cut.n_ap[arcs.children[j]] += 1


#: :func:`_collect`'s ``want_applied``, typed (one compiled function for both, not one
#: per literal: docs/maintainers.md).
_WANT_APPLIED = np.bool_(True)
_WANT_REFINED = np.bool_(False)


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
def _raise_closure(i, n_faces, arcs, cut, walk):
    """Refine node i and its applied ancestors, parents first (they have higher
    indices: a parent removes triangles its child created later in the sequence).
    ``walk`` is :func:`_collect`'s (stack, mark, tick)."""
    stack, mark, tick = walk
    n = _collect(i, _WANT_APPLIED, cut.applied, arcs.parent_start, arcs.parents, stack, mark,
                 tick)
    order = np.sort(stack[:n])[::-1].copy()
    for x in order:
        _set_refined(x, arcs, cut)
        n_faces += arcs.delta[x]
    return order, n_faces


@njit(cache=True)
def _lower_closure(i, n_faces, arcs, cut, walk):
    """Apply node i after its refined descendants, children first (lower indices)."""
    stack, mark, tick = walk
    n = _collect(i, _WANT_REFINED, cut.applied, arcs.child_start, arcs.children, stack, mark,
                 tick)
    order = np.sort(stack[:n])
    for x in order:
        _set_applied(x, arcs, cut)
        n_faces -= arcs.delta[x]
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
