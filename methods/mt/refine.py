"""Budget refinement of a cut with two queues (Williams et al. 2003, §5.1): refine the
node of largest error, coarsen the one of smallest, until the face budget holds. The
view-independent (object-space) cut is refined by its own triangles instead
(:func:`refine_where_farthest`), not by the node deviation: that is its subtree's
largest, and a collapse that slides a thin part's corner along the part passes its
deviation up to every ancestor though a later one brings the surface back (on the milk
truck at 362 faces, 0.085 of the diagonal over a surface within 0.002, while the wheels
kept 4 faces each). A triangle's own deviation is the cut's error where it lies; forced
raises (as in Hoppe 1997's view-dependent refinement) keep the cut valid.

With two queues, where refinement starts does not matter. Nodes are ranked by (error,
index): errors are monotone up the MT (a parent's is at least its children's,
methods.mt.errors) and a parent's index is larger than its children's, so the ranking is
a strict order in which every parent comes after its children. The refined set of the
cut the loop ends on is then the longest run of top-ranked nodes that fits the budget
(:func:`_refine` says why), whichever cut it started from: the previous view's cut only
saves work, as §5.1 intends. Without the index, equal errors (every invisible node's is
0) would be taken in whatever order the heaps hold them, and the cut would depend on the
start.
"""

from __future__ import annotations

import heapq
import time

import numpy as np
from numba import njit

from methods.mt.bounds import NodeBounds
from methods.mt.csf import ContrastSensitivity
from methods.mt.dag import Cut, MultiTriangulation, _set_applied, _set_refined
from methods.mt.errors import node_errors

#: Tie orders of the two heaps on equal keys: R (keyed by -error) pops the larger node
#: index first, L (keyed by error) the smaller: both follow the (error, index) ranking.
#: (int64 values, not literals: one compiled heap for both; docs/maintainers.md)
_R_TIES = np.int64(-1)
_L_TIES = np.int64(1)


@njit(cache=True)
def _before(ka, va, kb, vb, ties):
    """Whether entry (ka, va) pops before (kb, vb): smaller key, or on equal keys the
    value first in the ``ties`` order (1: smaller value, -1: larger)."""
    return ka < kb or (ka == kb and ties * va < ties * vb)


@njit(cache=True)
def _heap_push(keys, vals, n, key, val, ties):
    """Min-heap push on (keys, vals)[:n], growing the arrays when full; returns
    (keys, vals, new size). Equal keys are ordered by value (see :func:`_before`)."""
    if n == keys.shape[0]:
        k2 = np.empty(2 * n + 16)
        v2 = np.empty(2 * n + 16, np.int64)
        k2[:n] = keys[:n]
        v2[:n] = vals[:n]
        keys, vals = k2, v2
    i = n
    keys[i] = key
    vals[i] = val
    while i > 0:
        p = (i - 1) // 2
        if not _before(keys[i], vals[i], keys[p], vals[p], ties):
            break
        keys[p], keys[i] = keys[i], keys[p]
        vals[p], vals[i] = vals[i], vals[p]
        i = p
    return keys, vals, n + 1


@njit(cache=True)
def _heap_pop(keys, vals, n, ties):
    """Pop the first entry of (keys, vals)[:n] (see :func:`_before`); returns
    (value, new size)."""
    top = vals[0]
    n -= 1
    keys[0] = keys[n]
    vals[0] = vals[n]
    i = 0
    while True:
        a = 2 * i + 1
        if a >= n:
            break
        b = a + 1
        s = a if b >= n or not _before(keys[b], vals[b], keys[a], vals[a], ties) else b
        if not _before(keys[s], vals[s], keys[i], vals[i], ties):
            break
        keys[i], keys[s] = keys[s], keys[i]
        vals[i], vals[s] = vals[s], vals[i]
        i = s
    return top, n


@njit(cache=True)
def _lower_one(i, err, arcs, cut, heaps):
    """Apply frontier node i; it joins R, parents that became lowerable join L.
    ``heaps`` is (R's keys, values, size, L's keys, values, size); returns it updated."""
    rk, rv, nr, lk, lv, nl = heaps
    _set_applied(i, arcs, cut)
    rk, rv, nr = _heap_push(rk, rv, nr, -err[i], i, _R_TIES)
    for j in range(arcs.parent_start[i], arcs.parent_start[i + 1]):
        p = arcs.parents[j]
        if cut.n_rc[p] == 0:
            lk, lv, nl = _heap_push(lk, lv, nl, err[p], p, _L_TIES)
    return rk, rv, nr, lk, lv, nl


@njit(cache=True)
def _raise_one(i, err, arcs, cut, heaps):
    """Refine frontier node i; it joins L, children that became raisable join R
    (``heaps`` as in :func:`_lower_one`)."""
    rk, rv, nr, lk, lv, nl = heaps
    _set_refined(i, arcs, cut)
    lk, lv, nl = _heap_push(lk, lv, nl, err[i], i, _L_TIES)
    for j in range(arcs.child_start[i], arcs.child_start[i + 1]):
        ch = arcs.children[j]
        if cut.n_ap[ch] == 0:
            rk, rv, nr = _heap_push(rk, rv, nr, -err[ch], ch, _R_TIES)
    return rk, rv, nr, lk, lv, nl


@njit(cache=True)
def _frontier(err, cut):
    """R and L rebuilt from the cut's frontier (``heaps`` as in :func:`_lower_one`)."""
    c = cut.applied.shape[0]
    rk = np.empty(c + 16)
    rv = np.empty(c + 16, np.int64)
    lk = np.empty(c + 16)
    lv = np.empty(c + 16, np.int64)
    nr = np.int64(0)
    nl = np.int64(0)
    for i in range(c):
        if cut.applied[i] and cut.n_ap[i] == 0:
            rk, rv, nr = _heap_push(rk, rv, nr, -err[i], i, _R_TIES)
        elif not cut.applied[i] and cut.n_rc[i] == 0:
            lk, lv, nl = _heap_push(lk, lv, nl, err[i], i, _L_TIES)
    return rk, rv, nr, lk, lv, nl


@njit(cache=True)
def _lowering(budget, n_faces, err, arcs, cut, heaps):
    """A lowering phase: apply L's nodes while over ``budget`` and L has one. Returns
    (faces, nodes lowered, the last one or -1, heaps)."""
    lowered = 0
    last = -1
    while n_faces > budget and heaps[5] > 0:
        rk, rv, nr, lk, lv, nl = heaps
        i, nl = _heap_pop(lk, lv, nl, _L_TIES)
        heaps = (rk, rv, nr, lk, lv, nl)
        if cut.applied[i] or cut.n_rc[i] != 0:
            continue  # stale
        heaps = _lower_one(i, err, arcs, cut, heaps)
        n_faces -= arcs.delta[i]
        lowered += 1
        last = i
    return n_faces, lowered, last, heaps


@njit(cache=True)
def _raising(budget, n_faces, err, arcs, cut, heaps):
    """A raising phase: refine R's nodes while within ``budget`` and R has one.
    Returns (faces, nodes raised, the last one or -1, heaps)."""
    raised = 0
    last = -1
    while n_faces <= budget and heaps[2] > 0:
        rk, rv, nr, lk, lv, nl = heaps
        i, nr = _heap_pop(rk, rv, nr, _R_TIES)
        heaps = (rk, rv, nr, lk, lv, nl)
        if not cut.applied[i] or cut.n_ap[i] != 0:
            continue  # stale
        heaps = _raise_one(i, err, arcs, cut, heaps)
        n_faces += arcs.delta[i]
        raised += 1
        last = i
    return n_faces, raised, last, heaps


@njit(cache=True)
def _refine(budget, err, n_faces, arcs, cut):
    """simplifyBudget of §5.1 on ``cut``; returns (faces, raised, lowered).

    R holds applied nodes whose parents are all refined (candidates to raise), keyed
    by -error; L holds refined nodes whose children are all applied (candidates to
    lower), keyed by error. Both are rebuilt from the frontier at the start (the
    paper's updateErrorKeys). Entries go stale when the frontier moves and are skipped
    when popped. The loop alternates a lowering phase (while over budget) and a raising
    phase (while within it) and stops when the node lowered last is the node raised
    last, so it ends after a lowering phase: the cut meets the budget whenever the
    coarsest cut does, and is short of it by less than that node's faces.

    Why the end does not depend on the start, when errors are monotone up the MT: rank
    nodes by (error, index), the order both heaps pop in. Parents outrank their
    children, so the top of R is the highest-ranked applied node and the top of L the
    lowest-ranked refined one. A raising phase refines applied nodes from the top rank
    down and ends at a node x that breaks the budget; then no node above x is applied.
    The lowering phase coarsens refined nodes from the bottom rank up. If it reaches
    x, the refined nodes are exactly those above x and x, over budget, while those
    above x alone fit (they are a subset of the cut before x was raised, and every
    node adds at least one face): it drops x and stops on the longest run of
    top-ranked nodes that fits the budget, the same from any start. If it stops short
    of x, every applied node ranks below x, so the next raising phase ends below x:
    at most one round per node."""
    heaps = _frontier(err, cut)
    last_raised = -1
    raised = 0
    lowered = 0
    # Each round ends on a lower-ranked node than the last (see above), so the loop
    # ends; the cap guards against errors that are not monotone (or NaN).
    for _ in range(4 * cut.applied.shape[0] + 16):
        n_faces, k, last_dropped, heaps = _lowering(budget, n_faces, err, arcs, cut, heaps)
        lowered += k
        if last_raised != -1 and last_dropped == last_raised:
            break
        n_faces, k, last_raised, heaps = _raising(budget, n_faces, err, arcs, cut, heaps)
        raised += k
        if last_raised == -1:
            break
    # only after the guard tripped: back to the budget
    n_faces, k, _, heaps = _lowering(budget, n_faces, err, arcs, cut, heaps)
    return n_faces, raised, lowered + k


def refine(cut: Cut, errors: np.ndarray, budget: int) -> tuple[int, int]:
    """Move ``cut`` to ``budget`` faces greedily by ``errors`` (§5.1), in place.

    Returns (nodes raised, nodes lowered). The result has at most ``budget`` faces
    (unless even the coarsest cut has more) and more than ``budget`` minus the faces of
    the last node lowered. When ``errors`` are monotone up the MT (a parent's at least
    its children's, as every error of methods.mt.errors is), the result is the same
    from any starting cut: the nodes refined are the longest run of the ranking by
    (error, index), from the top, that fits the budget.
    """
    mt = cut.mt
    if budget < 1:
        raise ValueError(f"budget must be at least 1 face, got {budget}")
    errors = np.ascontiguousarray(errors, dtype=np.float64)
    if errors.shape != (mt.n_nodes,):
        raise ValueError(f"errors must have shape ({mt.n_nodes},), got {errors.shape}")
    faces, raised, lowered = _refine(int(budget), errors, int(cut.n_faces), cut.arcs(),
                                     cut.frontier())
    cut.n_faces = int(faces)
    return int(raised), int(lowered)


def refine_where_farthest(cut: Cut, triangle_deviation: np.ndarray, budget: int) -> int:
    """Refine ``cut`` toward ``budget`` faces where its surface lies farthest from the
    original, in place (the object-space cut); returns the nodes raised.

    The triangle of the cut with the largest deviation (ties: the lower index) is
    refined by raising its creator with every applied ancestor that must be raised
    first (:meth:`~methods.mt.dag.Cut.raise_node`), if the faces that adds fit the
    budget; otherwise the cut is left as it was and the triangle stays. Triangles the
    raise brings back join the candidates. It ends when no triangle of the cut can be
    refined within the budget.

    Parameters
    ----------
    cut : Cut
    triangle_deviation : ndarray (nt,) float64
        Per MT triangle (:attr:`methods.mt.bounds.NodeBounds.triangle_deviation`).
    budget : int
        At least 1; a cut that starts above it is left as it is.
    """
    mt = cut.mt
    if budget < 1:
        raise ValueError(f"budget must be at least 1 face, got {budget}")
    dev = np.asarray(triangle_deviation, dtype=np.float64)
    if dev.shape != (mt.n_triangles,):
        raise ValueError(f"triangle_deviation must have shape ({mt.n_triangles},), "
                         f"got {dev.shape}")
    creator, destroyer, applied = mt.creator, mt.destroyer, cut.applied

    def in_cut(t: int) -> bool:
        return ((creator[t] < 0 or applied[creator[t]])
                and (destroyer[t] < 0 or not applied[destroyer[t]]))

    heap = [(-dev[t], int(t)) for t in cut.triangles() if creator[t] >= 0]
    heapq.heapify(heap)
    # a raise that does not fit never will: every node adds faces (delta >= 1), and
    # raising an ancestor first only moves its faces from the raise to the cut
    too_big = np.zeros(mt.n_nodes, np.bool_)
    raised = 0
    while heap:
        _, t = heapq.heappop(heap)
        node = int(creator[t])
        if too_big[node] or not in_cut(t):
            continue
        order = cut.raise_node(node)
        if cut.n_faces > budget:
            for i in order[::-1]:
                cut.lower_node(int(i))
            too_big[node] = True
            continue
        raised += len(order)
        for i in order:
            for u in mt.node_removed(int(i)):
                if creator[u] >= 0 and in_cut(u):
                    heapq.heappush(heap, (-dev[u], int(u)))
    return raised


#: Where each view's refinement starts (:class:`Refiner`).
REFINEMENTS = ("incremental", "scratch")


class Refiner:
    """Per-view cuts of one MT under one error, each view starting from the last cut
    (``refinement="incremental"``, §5.1's two queues with temporal coherence) or from
    the coarsest cut (``"scratch"``, §5.1's simple top-down refinement: the same cut,
    more work). ``error_options`` are the ablation switches of
    :func:`methods.mt.errors.node_errors` (``silhouette_contrast``,
    ``lighting_contrast``, ``feature_size``)."""

    def __init__(self, mt: MultiTriangulation, bounds: NodeBounds, error: str = "perceptual",
                 lighting: str = "gouraud", specular: bool = True, ppd: float = 32.0,
                 peak_sensitivity: float = 200.0, silhouette_factor: float = 10.0,
                 refinement: str = "incremental", **error_options):
        if refinement not in REFINEMENTS:
            raise ValueError(f"refinement must be one of {', '.join(REFINEMENTS)}, "
                             f"got {refinement!r}")
        self.mt, self.bounds = mt, bounds
        self.error, self.lighting, self.specular = error, lighting, specular
        self.ppd, self.silhouette_factor = ppd, silhouette_factor
        self.refinement, self.error_options = refinement, dict(error_options)
        self.csf = ContrastSensitivity(peak_sensitivity)
        self.cut = mt.cut("coarsest")

    def errors(self, camera, resolution: int):
        return node_errors(self.bounds, camera, resolution, self.error, self.lighting,
                           self.specular, self.ppd, self.csf, self.silhouette_factor,
                           **self.error_options)

    def refine_view(self, camera, budget: int, resolution: int) -> dict:
        """Refine the current cut for ``camera`` (or the coarsest, ``"scratch"``);
        returns timing and counts."""
        t = time.perf_counter()
        if self.refinement == "scratch":
            self.cut = self.mt.cut("coarsest")
        err, _ = self.errors(camera, resolution)
        t_err = time.perf_counter() - t
        raised, lowered = refine(self.cut, err, budget)
        return {"seconds": time.perf_counter() - t, "error_seconds": t_err, "raised": raised,
                "lowered": lowered, "faces": self.cut.n_faces,
                "max_error": float(_max_on_cut(self.cut, err))}

    def refine_object(self, budget: int) -> None:
        """The view-independent cut: refined from the coarsest where the texture
        deviation of its own triangles is largest (:func:`refine_where_farthest`)."""
        if self.bounds.triangle_deviation is None:
            raise ValueError("the bounds have no triangle deviations; build them with "
                             "methods.mt.bounds.preprocess")
        self.cut = self.mt.cut("coarsest")
        refine_where_farthest(self.cut, self.bounds.triangle_deviation, budget)


def _max_on_cut(cut: Cut, err: np.ndarray) -> float:
    """The largest error among the applied collapses that could be raised next (the
    simplifications in effect at the cut's frontier): the LOD's imperceptibility
    distance (§3.4) when ``err`` holds imperceptibility distances."""
    frontier = (~cut.applied) & (cut.n_refined_children == 0)
    below = cut.applied & (cut.n_applied_parents == 0)
    pick = err[below] if below.any() else err[frontier]
    return float(pick.max()) if pick.size else 0.0
