"""Costs computed ahead: while the loop re-costs a stale entry, the job's other threads
re-cost the next stale entries it will pop, on the same mesh.

The loop is lazy (Lindstrom & Turk 2000, §4.2.2): it pops entries until one is current
and re-costs each stale one on the way. Between two collapses nothing changes the mesh
or the images, so an edge's cost is the same whenever it is evaluated in that interval.
When :func:`recost` meets a stale entry it holds no cost for, :func:`_peek` looks at
the heap's front for the next entries the loop would re-cost (alive, stale, not
superseded; it stops at the first current one, which the loop takes next), hands one
to each helper thread and costs the first itself. The loop then goes on exactly as
before, but an edge whose cost was computed ahead is not evaluated again; a collapse
drops whatever was not used (:func:`forget`). So every pop, push and collapse is the
serial run's, bit for bit, whatever the number of threads; only the work counters (face
rows, pixels shaded, cycles) include the evaluations that were not used.

The helpers (:func:`costs_ahead` starts ``threads - 1`` of them for a run) are Python
threads that stay inside the cached ``nogil`` function :func:`_serve` for the whole
loop, each with its own copy of what an evaluation writes
(:func:`methods.engine.initial._worker_state`). The loop and the helpers meet through
an array of generation numbers read and written with acquire and release atomics
(:func:`_load_acquire`, :func:`_store_release`), so handing out a batch costs no
Python call, no lock and no parallel (parfor) kernel: a cached loop calling a parallel
kernel is the case numba's cache cannot reload (docs/maintainers.md, "Parallel kernels
and numba's cache"). A waiting side spins and yields its core (``sched_yield``). The
only structure the loop rebuilds, the tile index, reaches the helpers through Python
(:func:`share_tiles`): each returns from :func:`_serve` and comes back with it.
"""

from __future__ import annotations

import heapq
import itertools
import threading
from collections import namedtuple
from contextlib import contextmanager

import numba
import numpy as np
from numba import njit, objmode, types
from numba.core import cgutils
from numba.extending import intrinsic

from methods.engine.borrow import borrowed
from methods.engine.cost import _evaluate
from methods.engine.initial import _worker_state
from methods.engine.state import EVALUATIONS, Images
from methods.engine.topology import _edge_faces
from methods.imaging.counters import STAT_RUN_CYCLES, cycles

#: The costs computed ahead of the loop, one row per thread: ``edges`` (k, 2) in the
#: order the loop would pop them, their ``costs`` (k,), kept ends ``keeps`` (k,; -1:
#: the edge has no faces) and placements ``places`` (k, 3); ``count``
#: (:data:`N_AHEAD_COUNTS`,) int64; ``signal`` (k × :data:`LINE`,) int64, per helper
#: the generation it was handed (at ``row × LINE``) and the one it finished (at
#: ``row × LINE + LINE // 2``), on a cache line of its own.
Ahead = namedtuple("Ahead", "edges costs keeps places count signal")

#: Entries of :data:`Ahead`'s ``count``: rows of the current batch (0 after a
#: collapse), the run's handle (-1: costs are never computed ahead), batches, edges
#: costed in batches, costs taken from a batch by the loop, the last batch's
#: generation, the tile index's version, and 1 once a helper failed.
AHEAD_ROWS = 0
AHEAD_HANDLE = 1
AHEAD_BATCHES = 2
AHEAD_COSTED = 3
AHEAD_USED = 4
AHEAD_GENERATION = 5
AHEAD_TILES = 6
AHEAD_FAILED = 7
N_AHEAD_COUNTS = 8

#: int64 entries per helper in ``signal``: two 64-byte cache lines.
LINE = 16
#: What :func:`_serve` returns (and the generation that tells it to): stop; or come
#: back with the new tile index.
QUIT = -1
RETILE = -2

#: Heap entries :func:`_peek` looks at, per row of a batch, before it gives up.
PEEK_PER_ROW = 8

_sched_yield = types.ExternalFunction("sched_yield", types.int32())

#: The runs that compute costs ahead, by handle: their tile index, for the helpers.
_TILES: dict[int, object] = {}
_HANDLES = itertools.count()


@intrinsic
def _load_acquire(typingctx, ary, i):
    """``ary[i]`` (int64, 1-d) read with acquire ordering."""
    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        a = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, a, [args[1]])
        return builder.load_atomic(ptr, "acquire", 8)

    return types.int64(ary, i), codegen


@intrinsic
def _store_release(typingctx, ary, i, value):
    """``ary[i] = value`` (int64, 1-d) written with release ordering."""
    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        a = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, a, [args[1]])
        builder.store_atomic(args[2], ptr, "release", 8)
        return context.get_dummy_value()

    return types.void(ary, i, value), codegen


@njit(cache=True, inline="always")
def _taken(ahead, a, b, p):
    """(found, cost, keep) of edge (a, b) from the current batch; the placement goes to
    ``p``. The edge must match in order: a cost may depend on it."""
    edges = ahead.edges
    for i in range(ahead.count[AHEAD_ROWS]):
        if edges[i, 0] == a and edges[i, 1] == b and ahead.keeps[i] >= 0:
            p[0], p[1], p[2] = ahead.places[i, 0], ahead.places[i, 1], ahead.places[i, 2]
            return True, ahead.costs[i], ahead.keeps[i]
    return False, 0.0, np.int64(-1)


@njit(cache=True)
def _peek(heap, a, b, mesh, queue, ahead):
    """Fill ``ahead.edges`` with stale edge (a, b) and the next entries at the heap's
    front that the loop would re-cost, as it would pop them: alive, stale, not
    superseded, each edge once. Stops at a current entry (the loop takes it next), when
    the rows are full or after :data:`PEEK_PER_ROW` entries per row. Every entry popped
    is pushed back unchanged; returns the rows filled."""
    edges, stamp, pushed_at = ahead.edges, queue.stamp, queue.pushed_at
    rows = edges.shape[0]
    edges[0, 0], edges[0, 1] = a, b
    n = 1
    if n == rows or len(heap) == 0:
        return n
    popped = [heapq.heappop(heap)]
    while True:
        _, x, y, sx, sy, _, _, _, keep = popped[-1]
        if mesh.valive[x] and mesh.valive[y]:
            if sx == stamp[x] and sy == stamp[y] and keep != -1:
                break  # current
            if sx == -1 or (sx >= pushed_at[x] and sy >= pushed_at[y]):
                new = True
                for i in range(n):
                    if edges[i, 0] == x and edges[i, 1] == y:
                        new = False
                if new:
                    edges[n, 0], edges[n, 1] = x, y
                    n += 1
        if n == rows or len(heap) == 0 or len(popped) >= PEEK_PER_ROW * rows:
            break
        popped.append(heapq.heappop(heap))
    for entry in popped:
        heapq.heappush(heap, entry)
    return n


@njit(cache=True)
def _cost_row(i, ahead, mesh, rules, terms, scratch, images):
    """Row ``i`` of the batch, costed with the given scratch and image state."""
    edges = ahead.edges
    a, b = edges[i, 0], edges[i, 1]
    if _edge_faces(a, b, mesh.F, mesh.vhead, mesh.cnext, mesh.falive, scratch.efaces) == 0:
        ahead.keeps[i] = -1  # the loop drops such an entry without costing it
        return
    ahead.costs[i], ahead.keeps[i] = _evaluate(a, b, mesh, rules, terms, scratch, images)
    p, places = scratch.p, ahead.places
    places[i, 0], places[i, 1], places[i, 2] = p[0], p[1], p[2]


@njit(cache=True, nogil=True)
def _serve(row, tiles, ahead, mesh, rules, terms, scratch, images):
    """A helper's loop: cost row ``row`` of each batch handed to it, until told to quit
    (returns :data:`QUIT`) or handed a batch after the tile index changed from version
    ``tiles`` (returns :data:`RETILE`, the batch still to do)."""
    # The run's structures outlive the helper (methods.engine.borrow).
    mesh, terms, scratch, images = borrowed((mesh, terms, scratch, images))
    signal, handed, finished = ahead.signal, row * LINE, row * LINE + LINE // 2
    while True:
        g = _load_acquire(signal, handed)
        if g == QUIT:
            return QUIT
        if g == _load_acquire(signal, finished):
            _sched_yield()
            continue
        if _load_acquire(ahead.count, AHEAD_TILES) != tiles:  # bumped before g was handed
            return RETILE
        start = cycles()
        _cost_row(row, ahead, mesh, rules, terms, scratch, images)
        # Its working cycles join the run's, so that the image counters' shares of
        # them stay shares of all the work done (as the first pass's do).
        images.img.stats[STAT_RUN_CYCLES] += cycles() - start
        _store_release(signal, finished, g)


@njit(cache=True)
def _hand_out(heap, a, b, mesh, queue, ahead):
    """Fill the batch with stale edge (a, b) and the next stale entries (:func:`_peek`)
    and hand rows 1, 2, ... to the helpers; returns the rows."""
    count, signal = ahead.count, ahead.signal
    n = _peek(heap, a, b, mesh, queue, ahead)
    g = count[AHEAD_GENERATION] + 1
    count[AHEAD_GENERATION] = g
    for i in range(1, n):
        _store_release(signal, i * LINE, g)
    return n


@njit(cache=True)
def _gather(ahead, n, cost, keep, p):
    """Row 0 of the batch is (cost, keep, p); wait until the helpers finished the
    others (raising if one failed)."""
    count, signal, g = ahead.count, ahead.signal, ahead.count[AHEAD_GENERATION]
    ahead.costs[0], ahead.keeps[0] = cost, keep
    ahead.places[0, 0], ahead.places[0, 1], ahead.places[0, 2] = p[0], p[1], p[2]
    for i in range(1, n):
        while _load_acquire(signal, i * LINE + LINE // 2) != g:
            if _load_acquire(count, AHEAD_FAILED) != 0:
                raise RuntimeError("a thread costing edges ahead failed")
            _sched_yield()
    count[AHEAD_ROWS] = n
    if n > 1:
        count[AHEAD_BATCHES] += 1
        count[AHEAD_COSTED] += n


@njit(cache=True)
def recost(a, b, heap, mesh, rules, terms, scratch, images, queue, ahead):
    """The cost of stale edge (a, b) now, counted as an evaluation, as
    :func:`methods.engine.loop._cost` gives it (placement in ``scratch.p``): from the
    current batch if it holds the edge; else evaluated here, while the helpers (if the
    run has any) cost the next stale entries."""
    queue.tally[EVALUATIONS] += 1
    count = ahead.count
    found, cost, keep = _taken(ahead, a, b, scratch.p)
    if found:
        count[AHEAD_USED] += 1
        return cost, keep
    helped = count[AHEAD_HANDLE] >= 0
    n = _hand_out(heap, a, b, mesh, queue, ahead) if helped else 1
    cost, keep = _evaluate(a, b, mesh, rules, terms, scratch, images)
    if helped:
        _gather(ahead, n, cost, keep, scratch.p)
    return cost, keep


@njit(cache=True, inline="always")
def forget(ahead):
    """Drop the current batch: a collapse changed the mesh."""
    ahead.count[AHEAD_ROWS] = 0


def _retile(handle: int, tiles) -> None:
    _TILES[handle] = tiles


@njit(cache=True)
def share_tiles(ahead, tiles):
    """Hand a rebuilt tile index (an ordinary, counted structure) to the helpers: the
    next batch sends each back to Python for it (:func:`_serve`)."""
    count = ahead.count
    handle = count[AHEAD_HANDLE]
    if handle >= 0:
        with objmode():
            _retile(handle, tiles)
        count[AHEAD_TILES] += 1


def ahead_statistics(ahead) -> dict:
    """The batches' counters, for the run's statistics (empty when none ran):
    batches handed out, edges the helpers costed, and re-costs the loop took from a
    batch instead of evaluating them."""
    count = ahead.count
    if count[AHEAD_BATCHES] == 0:
        return {}
    return {"ahead_batches": int(count[AHEAD_BATCHES]),
            "ahead_costs": int(count[AHEAD_COSTED] - count[AHEAD_BATCHES]),
            "ahead_costs_used": int(count[AHEAD_USED])}


@contextmanager
def costs_ahead(mesh, rules, terms, scratch, images, threads: int | None = None):
    """The :data:`Ahead` structure for a run of the loop, with its helpers running:
    ``threads - 1`` of them (default numba's thread count) when the costs are rendered
    and the run does not verify them; otherwise none, and the loop evaluates every cost
    itself. On exit the helpers stop, their counters are added to the image state's,
    and the first error a helper met is raised."""
    threads = numba.get_num_threads() if threads is None else int(threads)
    weights = rules.weights
    rendered = weights.image != 0.0 or weights.entropy != 0.0
    rows = threads if threads > 1 and rendered and not rules.verify else 1
    ahead = Ahead(np.zeros((rows, 2), np.int64), np.zeros(rows), np.full(rows, -1, np.int64),
                  np.zeros((rows, 3)), np.zeros(N_AHEAD_COUNTS, np.int64),
                  np.zeros(rows * LINE, np.int64))
    ahead.count[AHEAD_HANDLE] = -1
    if rows == 1:
        yield ahead
        return
    handle = next(_HANDLES)
    states, helpers, errors = [], [], []

    def serve(row, own_scratch, own_images):
        try:
            while True:
                tiles = int(ahead.count[AHEAD_TILES])
                own = Images(own_images.img, _TILES[handle], own_images.iws)
                if _serve(row, tiles, ahead, mesh, rules, terms, own_scratch, own) == QUIT:
                    return
        except BaseException as error:  # noqa: BLE001 - the loop sees the flag, the exit raises it
            errors.append(error)
            ahead.count[AHEAD_FAILED] = 1

    # Everything from here on is undone by the finally, whatever fails on the way: the
    # helpers started are told to quit and joined, and their counters are kept.
    try:
        _TILES[handle] = images.tiles
        ahead.count[AHEAD_HANDLE] = handle
        for row in range(1, rows):
            states.append(_worker_state(scratch, images))
            helper = threading.Thread(target=serve, args=(row, *states[-1]), daemon=True,
                                      name=f"costs-ahead-{row}")
            helper.start()
            helpers.append(helper)
        yield ahead
    finally:
        for row in range(1, rows):
            ahead.signal[row * LINE] = QUIT
        for helper in helpers:
            helper.join()
        _TILES.pop(handle, None)
        for _, own in states:
            images.img.stats[:] += own.img.stats
        if errors:
            raise errors[0]
