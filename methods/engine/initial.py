"""The engine's first pass: every edge of the mesh costed once, before the loop, on as
many threads as the job may use.

Before any collapse the costs of the edges do not depend on each other: each
evaluation reads the mesh, the cost terms' inputs (:mod:`methods.engine.terms`) and the
images, and writes only its scratch (and counters). So the edges are cut into chunks of
:data:`CHUNK`, and each of ``threads`` Python threads takes the next chunk and costs it
with its own copy of the scratch (:func:`_worker_state`) in :func:`_cost_range`, which
releases the GIL. Every
edge's cost, kept end and placement land in its own row of the output, so what the
loop queues (in edge order, :func:`methods.engine.loop._collect_candidates`) is the
serial pass's to the bit, whatever the number of threads and however the chunks were
shared out. The counters of the copies are added to the image state's afterwards.

Why threads and not a ``prange`` loop: the kernels here are ordinary cached
functions, so no process ever loads a parallel (parfor) function from another's cache
through a cached serial caller, the case numba cannot reload (docs/maintainers.md,
"Parallel kernels and numba's cache").
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit

from methods.engine.borrow import borrowed
from methods.engine.cost import _evaluate
from methods.engine.state import Images, new_scratch
from methods.engine.topology import _candidate_edges, _edge_faces, _faces_area
from methods.imaging.counters import STAT_RUN_CYCLES, cycles

#: Edges per chunk at most: large enough that taking a chunk costs nothing next to it.
#: The chunks shrink towards the end (guided): each takes ``1 / (GUIDED * threads)`` of
#: the edges left, within ``[MIN_CHUNK, CHUNK]``, so that the threads finish within a
#: small chunk of each other (rendered costs vary from edge to edge). Eight equal chunks
#: per thread left one thread alone for 5-24 ms of the 815-face bunny's ~190 ms pass.
CHUNK = 256
GUIDED = 2
MIN_CHUNK = 4


@njit(cache=True, nogil=True)
def candidate_edges(mesh, scratch):
    """The edges the loop costs first, in its order
    (:func:`methods.engine.topology._candidate_edges`)."""
    return _candidate_edges(mesh, scratch.efaces)


@njit(cache=True, nogil=True)
def _cost_range(span, edges, mesh, rules, terms, scratch, images, out):
    """Cost edges ``edges[lo:hi]``, ``span`` = (lo, hi), into rows ``lo:hi`` of ``out``
    = (costs, keeps, places): the cost, the vertex kept and where it goes; cycles go to
    the run's counter."""
    (lo, hi), (costs, keeps, places) = span, out
    start = cycles()
    # The callers' structures outlive the call (methods.engine.borrow).
    mesh, terms, scratch, images = borrowed((mesh, terms, scratch, images))
    p = scratch.p
    for e in range(lo, hi):
        costs[e], keeps[e] = _evaluate(edges[e, 0], edges[e, 1], mesh, rules, terms,
                                       scratch, images)
        places[e, 0], places[e, 1], places[e, 2] = p[0], p[1], p[2]
    images.img.stats[STAT_RUN_CYCLES] += cycles() - start


@njit(cache=True)
def edge_areas(mesh, scratch, edges):
    """The area of each edge's faces (e,)."""
    areas = np.empty(edges.shape[0])
    for e in range(edges.shape[0]):
        k = _edge_faces(edges[e, 0], edges[e, 1], mesh.F, mesh.vhead, mesh.cnext,
                        mesh.falive, scratch.efaces)
        areas[e] = _faces_area(k, scratch.efaces, mesh.P, mesh.F)
    return areas


def edge_chunks(n: int, threads: int) -> list[tuple[int, int]]:
    """``[lo, hi)`` ranges cutting ``n`` edges in order, each ``1 / (GUIDED * threads)``
    of the edges left, within ``[MIN_CHUNK, CHUNK]`` (the last may be shorter)."""
    chunks, lo = [], 0
    while lo < n:
        size = min(CHUNK, max(MIN_CHUNK, -(-(n - lo) // (GUIDED * threads))))
        chunks.append((lo, min(lo + size, n)))
        lo += size
    return chunks


def own_counters(img):
    """The image state ``img`` with counters and entropy scratch of its own, for another
    thread; the images and the entropy's counts stay shared."""
    ent = img.ent
    own_ent = ent._replace(dcnt=np.zeros_like(ent.dcnt), emark=np.zeros_like(ent.emark),
                           touched=np.zeros_like(ent.touched), delta=np.zeros_like(ent.delta),
                           etick=np.zeros_like(ent.etick))
    return img._replace(stats=np.zeros_like(img.stats), ent=own_ent)


def _worker_state(scratch, images):
    """A thread's own scratch and image state: what an evaluation writes is copied
    (engine scratch, image scratch, counters, the entropy's scratch); what it only
    reads (mesh, images, counts, tile index) is shared."""
    own_iws = type(images.iws)(*(np.array(a) for a in images.iws))
    return (new_scratch(len(scratch.mark)),
            Images(img=own_counters(images.img), tiles=images.tiles, iws=own_iws))


def first_costs(mesh, rules, terms, scratch, images, threads: int | None = None):
    """Every edge the loop starts from, costed: (edges (e, 2), costs (e,), kept ends
    (e,), placements (e, 3)), identical for any ``threads`` (default: numba's thread
    count, which :func:`bench.run.jobs.use_threads` sets per job)."""
    edges = candidate_edges(mesh, scratch)
    n = len(edges)
    costs, keeps, places = np.empty(n), np.empty(n, np.int64), np.empty((n, 3))
    out = (costs, keeps, places)
    threads = numba.get_num_threads() if threads is None else int(threads)
    chunks = edge_chunks(n, max(1, threads))
    threads = max(1, min(threads, len(chunks)))
    if threads == 1:
        _cost_range((0, n), edges, mesh, rules, terms, scratch, images, out)
        return (edges, *out)
    states = [_worker_state(scratch, images) for _ in range(threads)]
    taken = iter(chunks)
    lock = threading.Lock()
    stop = threading.Event()  # an error (or Ctrl-C) anywhere: take no more chunks

    def work(state):
        own_scratch, own_images = state
        try:
            while not stop.is_set():
                with lock:
                    chunk = next(taken, None)
                if chunk is None:
                    return
                _cost_range((chunk[0], chunk[1]), edges, mesh, rules, terms, own_scratch,
                            own_images, out)
        except BaseException:
            stop.set()
            raise

    with ThreadPoolExecutor(threads, thread_name_prefix="first-costs") as pool:
        try:
            for done in [pool.submit(work, state) for state in states]:
                done.result()  # the first error, if any, is raised here
        except BaseException:
            stop.set()
            raise
    for _, own in states:
        images.img.stats[:] += own.img.stats
    return (edges, *out)
