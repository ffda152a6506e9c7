"""The views of each evaluation shared with the job's other threads.

An image cost re-renders every view's rectangle around a candidate collapse, and the
views do not depend on each other: each reads the mesh, the images and the set-up the
evaluating thread made (the faces the collapse changes, their marks, the new
lighting), and writes only its own scratch and its own result. So while the loop runs,
``threads - 1`` helper threads stay inside the compiled
:func:`methods.imaging.region.serve_views`; each evaluation (and each commit of a
collapse to the images) publishes its job, and the loop and the helpers take its views
one at a time (:mod:`methods.imaging.share`). The results are summed in view order,
so every cost, and so every collapse, is the one-thread run's bit for bit, whichever
thread drew which view.

Why not a ``prange`` over the views: the loop is a cached function, and a cached
function calling a parallel (parfor) kernel is the case numba's cache cannot reload
(docs/maintainers.md, "Parallel kernels and numba's cache"). The helpers are ordinary
cached ``nogil`` functions on Python threads, and they meet the loop through atomics
on one array (:mod:`methods.imaging.atomic`), so handing out a job costs no Python
call and no lock. The only structure the loop rebuilds, the tile index, reaches them
through Python (:func:`methods.imaging.share.share_tiles`).
"""

from __future__ import annotations

import itertools
import threading
from contextlib import contextmanager

import numba
import numpy as np

from methods.engine.initial import own_counters
from methods.engine.state import renders
from methods.imaging.region import Scene, serve_views
from methods.imaging.share import (
    JOB_FAILED,
    JOB_HANDLE,
    JOB_HELPERS,
    JOB_TILES,
    MAX_HELPERS,
    QUIT,
    TILES,
    finished,
    handed,
)
from metrics.shading import BACKGROUND

_HANDLES = itertools.count()

#: The scratch each helper has of its own; the rest of ``ImageScratch`` (the set-up of
#: the job, the per-view rectangles and results, the job itself) it shares.
OWN_SCRATCH = ("mark", "tick", "cand", "t", "depth", "ids", "sp", "box", "rowof",
               "rowmark", "hmark", "holes", "spans")


def helper_state(images):
    """A helper's image state and scratch: its own counters, entropy scratch and render
    scratch (:data:`OWN_SCRATCH`); the run's images, counts and job."""
    iws = images.iws
    return (own_counters(images.img),
            iws._replace(**{k: np.array(getattr(iws, k)) for k in OWN_SCRATCH}))


@contextmanager
def views_shared(mesh, rules, scratch, images, threads: int | None = None):
    """Run the loop inside this with ``threads - 1`` helpers (default numba's thread
    count, which :func:`bench.run.jobs.use_threads` sets per job) taking views of
    its evaluations and commits, when the costs are rendered; otherwise none. On exit
    the helpers stop, their counters are added to the image state's, and the first
    error a helper met is raised."""
    threads = numba.get_num_threads() if threads is None else int(threads)
    weights = rules.weights
    rendered = renders.py_func(weights)
    helpers = min(threads - 1, MAX_HELPERS) if rendered else 0
    if helpers <= 0:
        yield
        return
    job = images.iws.vjob
    handle = next(_HANDLES)
    states, started, errors = [], [], []
    background = float(BACKGROUND)

    def serve(row, own_img, own_iws):
        try:
            while True:
                version = int(job[JOB_TILES])
                scene = Scene(P=mesh.P, F=mesh.F, FW=mesh.FW, uv=mesh.uv, falive=mesh.falive,
                              img=own_img, tiles=TILES[handle], iws=own_iws,
                              wfrom=scratch.wmap_from, wto=scratch.wmap_to,
                              background=background)
                if serve_views(row, version, scene) == QUIT:
                    return
        except BaseException as error:  # noqa: BLE001 - the loop sees the flag, the exit raises it
            errors.append(error)
            job[JOB_FAILED] = 1

    # Everything from here on is undone by the finally, whatever fails on the way: the
    # helpers started are told to quit and joined, and their counters are kept.
    try:
        TILES[handle] = images.tiles
        job[JOB_HANDLE] = handle
        job[JOB_HELPERS] = helpers
        for row in range(1, helpers + 1):
            states.append(helper_state(images))
            helper = threading.Thread(target=serve, args=(row, *states[-1]), daemon=True,
                                      name=f"views-{row}")
            helper.start()
            started.append(helper)
        yield
    finally:
        for row in range(1, helpers + 1):
            job[handed(row)] = QUIT
        for helper in started:
            helper.join()
        job[JOB_HELPERS] = job[JOB_FAILED] = 0
        for row in range(1, helpers + 1):
            job[handed(row)] = job[finished(row)] = 0
        TILES.pop(handle, None)
        for own_img, _ in states:
            images.img.stats[:] += own_img.stats
        if errors:
            raise errors[0]
