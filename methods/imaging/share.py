"""The views of one evaluation (or of one commit) shared between threads.

Every view of an image cost is re-rendered from the same inputs, and writes only its
own scratch and its own results (``ImageScratch.vcost``, ``vdh``; a commit its own
view's images and counts). So the thread that evaluates hands the views out: it
publishes the job (:func:`publish`) in ``ImageScratch.vjob`` and the kept vertex's
position in ``vp``, wakes the helpers (:func:`hand_out`), takes views itself one at a
time (:func:`next_view`) as they do, and waits for them (:func:`wait`). The results are
then summed in view order, so the cost is the one-thread run's to the bit whichever
thread drew which view. The helpers are threads that stay inside the compiled
:func:`methods.imaging.region.serve_views` for the whole run; ``vjob`` holds the
protocol's words, the helpers' each on cache lines of their own.
"""

from __future__ import annotations

import numpy as np
from numba import njit, objmode

from methods.imaging.atomic import fetch_add, load_acquire, sched_yield, store_release

#: int64 words per cache-line group of ``vjob`` (two 64-byte lines).
LINE = 16
#: Helper threads a run may have at most.
MAX_HELPERS = 63
#: ``vjob``'s size: the job's words, the view counter, then one group per helper.
JOB_SIZE = (2 + MAX_HELPERS) * LINE

#: ``vpart``'s size: each thread's running sum of its views' |dH| (thread ``row`` at
#: ``row * LINE``), a group apart.
PART_SIZE = (1 + MAX_HELPERS) * LINE
#: The job's words: the run's helpers (0: none), the generation last handed out, the
#: tile index's version, 1 once a helper failed, the kind of job, and its arguments.
JOB_HELPERS = 0
JOB_GENERATION = 1
JOB_TILES = 2
JOB_FAILED = 3
JOB_KIND = 4
JOB_U = 5
JOB_V = 6
JOB_NA = 7
JOB_NS = 8
JOB_ATICK = 9
JOB_NPAIRS = 10
JOB_HANDLE = 11
#: The next view to take, on a cache line of its own.
JOB_NEXT = LINE
#: Kinds of job: cost the views of a candidate, or commit them after a collapse.
KIND_COST = 0
KIND_COMMIT = 1
#: What a helper returns (and the generation that tells it to): stop; or come back with
#: the new tile index.
QUIT = -1
RETILE = -2


def new_job():
    """A ``vjob`` with no helpers."""
    return np.zeros(JOB_SIZE, np.int64)


@njit(cache=True, inline="always")
def handed(row):
    """Where helper ``row`` (1, 2, ...) finds the generation it was handed."""
    return (1 + row) * LINE


@njit(cache=True, inline="always")
def finished(row):
    """Where helper ``row`` leaves the generation it finished."""
    return (1 + row) * LINE + LINE // 2


def new_partials():
    """A ``vpart``: every thread's running sum 0."""
    return np.zeros(PART_SIZE)


@njit(cache=True)
def publish(job, kind, u, v, na, ns, atick, npairs):
    """Write a job's arguments and reset the view counter (before :func:`hand_out`)."""
    job[JOB_KIND], job[JOB_U], job[JOB_V], job[JOB_NA] = kind, u, v, na
    job[JOB_NS], job[JOB_ATICK], job[JOB_NPAIRS] = ns, atick, npairs
    store_release(job, JOB_NEXT, 0)


@njit(cache=True)
def hand_out(job):
    """Wake the helpers on the job just published; returns its generation."""
    g = job[JOB_GENERATION] + 1
    job[JOB_GENERATION] = g
    for row in range(1, job[JOB_HELPERS] + 1):
        store_release(job, handed(row), g)
    return g


@njit(cache=True, inline="always")
def next_view(job):
    """The next view no thread has taken (the caller stops at the view count)."""
    return fetch_add(job, JOB_NEXT, 1)


@njit(cache=True, inline="always")
def stop_handing(job, n_views):
    """Hand out no more of the job's ``n_views`` views (those taken are still done)."""
    store_release(job, JOB_NEXT, n_views)


@njit(cache=True, inline="always")
def clear_partials(part, helpers):
    """Set the running sums in ``part`` of all ``helpers + 1`` threads to 0 (before
    :func:`hand_out`)."""
    for row in range(helpers + 1):
        part[row * LINE] = 0.0


@njit(cache=True, inline="always")
def partials_sum(part, helpers):
    """The sum of all ``helpers + 1`` threads' running sums in ``part`` (another
    thread's as last seen, so no more than it is while it still adds)."""
    total = 0.0
    for row in range(helpers + 1):
        total += part[row * LINE]
    return total


@njit(cache=True, inline="always")
def add_partial(part, row, x, helpers):
    """Add ``x`` to thread ``row``'s running sum in ``part``; returns
    :func:`partials_sum`."""
    part[row * LINE] += x
    return partials_sum(part, helpers)


@njit(cache=True)
def wait(job, g):
    """Wait until every helper finished generation ``g`` (raising if one failed)."""
    for row in range(1, job[JOB_HELPERS] + 1):
        while load_acquire(job, finished(row)) != g:
            if load_acquire(job, JOB_FAILED) != 0:
                raise RuntimeError("a thread sharing the views failed")
            sched_yield()


@njit(cache=True)
def next_job(job, row, tiles):
    """A helper's wait for its next job: the generation (after which the caller does
    its views and :func:`done`), :data:`QUIT`, or :data:`RETILE` when the tile index
    changed from version ``tiles``."""
    while True:
        g = load_acquire(job, handed(row))
        if g == QUIT:
            return QUIT
        if g != load_acquire(job, finished(row)):
            if load_acquire(job, JOB_TILES) != tiles:  # bumped before g was handed
                return RETILE
            return g
        sched_yield()


@njit(cache=True, inline="always")
def done(job, row, g):
    """Helper ``row`` finished generation ``g``: its views' results and images are
    written (released to the thread that waits)."""
    store_release(job, finished(row), g)


#: The tile index of each run whose views are shared, by handle (``vjob[JOB_HANDLE]``).
TILES: dict[int, object] = {}


def _retile(handle: int, tiles) -> None:
    TILES[handle] = tiles


@njit(cache=True)
def share_tiles(job, tiles):
    """Hand a rebuilt tile index (an ordinary, counted structure) to the helpers: the
    next job sends each back to Python for it (:func:`next_job`)."""
    if job[JOB_HELPERS] > 0:
        handle = job[JOB_HANDLE]
        with objmode():
            _retile(handle, tiles)
        job[JOB_TILES] += 1
