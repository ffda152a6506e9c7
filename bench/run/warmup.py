"""Compilation is not method time: run a method once on a tiny mesh before timing it.

The engine's kernels are numba functions cached on disk. The first call in a fresh
install compiles them (minutes on two cores); every later process loads them from the
cache (about a second), and pymeshlab and the renderers have first-call costs of their
own. A run's timings should hold none of that, so each worker warms a method up on
:func:`tiny_meshes` before its first job of that method and records the time as
``compile_seconds``, apart from ``wall_seconds``. ``bench warmup`` (run by
``scripts/setup.sh --no-run``) fills numba's cache once, so the next run starts warm:
:func:`warm_up_all` runs every method once and evaluates a tiny result (the protocol's
own kernels), in several processes at a time. Methods declare the families of kernels
they run (:attr:`bench.core.method.Method.kernels`); one method of a family compiles it
(:func:`schedule` says which), and the others that need it start once it is cached, so
no two processes compile the same kernels.
"""

from __future__ import annotations

import gc
import time
import warnings
from contextlib import contextmanager
from functools import cache

import numpy as np

from bench.core.mesh import Mesh

__all__ = ["tiny_meshes", "warm_up", "warm_up_all", "warm_up_evaluation",
           "warm_up_evaluation_once", "schedule", "EVALUATION", "WARM"]

#: The methods (by name and parameters) this process has warmed up.
WARM: set = set()


@cache
def tiny_meshes() -> tuple[Mesh, Mesh]:
    """An untextured and a textured UV sphere of 112 faces (the textured one with a seam
    and a 16² texture), enough to reach every kernel of every method once."""
    from bench.catalog.torus import make_torus

    lat, lon = 8, 8
    theta = np.linspace(0, np.pi, lat + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, lon, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    positions = np.vstack([[0, 0, 1], ring, [0, 0, -1]])
    n, last = len(ring), len(ring) + 1
    faces = [[0, 1 + j, 1 + (j + 1) % lon] for j in range(lon)]
    for i in range(lat - 2):
        for j in range(lon):
            a, b = 1 + i * lon + j, 1 + i * lon + (j + 1) % lon
            faces += [[a, a + lon, b], [b, a + lon, b + lon]]
    faces += [[last, 1 + n - lon + (j + 1) % lon, 1 + n - lon + j] for j in range(lon)]
    plain = Mesh(positions, np.asarray(faces, np.int32), name="warmup")
    textured = make_torus(8, 7, texture_size=16).replace(name="warmup-textured")
    return plain, textured


#: Python's cyclic collector while compiling: a collection of the young objects every
#: 100,000 allocations instead of 700. numba's compiler makes millions of small objects
#: that live until a function is compiled, and at the default thresholds the collector
#: took about a tenth of a cold compile (a profile of quadric's kernels). With these the
#: same compile took 9 % and 16 % less wall time (two measurements) and its peak memory
#: grew from 1.1 to 1.4 GB; with the collector off, about the same time and 2.8 GB.
COMPILE_GC_THRESHOLDS = (100_000, 50, 100)


@contextmanager
def fewer_collections():
    """Python's cyclic collector at :data:`COMPILE_GC_THRESHOLDS` for the block."""
    before = gc.get_threshold()
    gc.set_threshold(*COMPILE_GC_THRESHOLDS)
    try:
        yield
    finally:
        gc.set_threshold(*before)


@contextmanager
def with_helpers():
    """numba's parallel kernels at two threads or more for the block, where numba
    started two: a job of ``bench run --jobs 2`` has one thread, and so its method no
    view helpers (``methods.engine.views``), but the warm-up compiles the helpers'
    kernels too, so that a later run with more threads per job compiles nothing."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(max(before, min(2, numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def warm_up(method_cls, params=None, ctx=None) -> float:
    """Run ``method_cls(params)`` on both tiny meshes once per process and return the
    seconds it took (0 when this process already warmed it up, or when the method says
    it ``warms_up`` not). Failures are ignored: a method that cannot run on a tiny mesh
    fails, or not, on the real one."""
    from bench.core.method import run_method

    key = (method_cls.name, repr(params))
    if key in WARM or not getattr(method_cls, "warms_up", True):
        return 0.0
    start = time.perf_counter()
    for mesh in tiny_meshes():
        if getattr(method_cls, "needs_uv", False) and mesh.uv is None:
            continue
        with warnings.catch_warnings(), fewer_collections(), with_helpers():
            warnings.simplefilter("ignore")
            try:
                run_method(method_cls(params), mesh, mesh.n_faces // 2,
                           {k: v for k, v in (ctx or {}).items() if k != "cache_dir"})
            except Exception:  # noqa: BLE001 - best effort, see the docstring
                pass
    WARM.add(key)
    return time.perf_counter() - start


#: The task of :func:`warm_up_all` that compiles the protocol's kernels (not a method).
EVALUATION = "(evaluation)"


def warm_up_evaluation() -> float:
    """Evaluate a tiny result under the default protocol, once, so the evaluation's
    kernels are compiled; returns the seconds it took."""
    from metrics.protocol import Protocol, evaluate

    start = time.perf_counter()
    plain, _ = tiny_meshes()
    with warnings.catch_warnings(), fewer_collections():
        warnings.simplefilter("ignore")
        evaluate(plain, plain.keep_faces(plain.faces[::2]),
                 Protocol(resolution=64, hausdorff_samples=1000))
    return time.perf_counter() - start


def warm_up_evaluation_once() -> float:
    """:func:`warm_up_evaluation` in a process that has not yet run it; else 0. A
    failure is ignored, as in :func:`warm_up`: the job's own evaluation reports it."""
    if EVALUATION in WARM:
        return 0.0
    start = time.perf_counter()
    try:
        warm_up_evaluation()
    except Exception:  # noqa: BLE001 - best effort, see the docstring
        pass
    WARM.add(EVALUATION)
    return time.perf_counter() - start


#: Families whose cold compile is split into parts that processes compile at once, before
#: the method that builds the family: the family's module and the parts its
#: ``compile_part(part, mesh)`` takes. The engine's costing and its collapse are two
#: halves of its compile that need nothing of each other; the loop, which needs both,
#: is compiled after them (by the builder, reading both from the cache).
SPLIT = {"engine": ("methods.engine.simplify", ("costing", "collapse"))}


def part_tasks(families) -> dict[str, tuple[str, ...]]:
    """The part tasks of each split family among ``families``: ``"(engine: costing)"``."""
    return {f: tuple(f"({f}: {p})" for p in SPLIT[f][1]) for f in sorted(families) if f in SPLIT}


def warm_up_part(name: str) -> float:
    """Compile part task ``name`` (:data:`SPLIT`) on both tiny meshes; its seconds."""
    import importlib

    family, part = name.strip("()").split(": ")
    compile_part = importlib.import_module(SPLIT[family][0]).compile_part
    start = time.perf_counter()
    for mesh in tiny_meshes():
        with warnings.catch_warnings(), fewer_collections(), with_helpers():
            warnings.simplefilter("ignore")
            compile_part(part, mesh)
    return time.perf_counter() - start


def _warm_task(name: str) -> tuple[str, float]:
    """One task of :func:`warm_up_all` in a worker process: (name, seconds)."""
    if name == EVALUATION:
        return name, warm_up_evaluation()
    if name.startswith("(") and ": " in name:
        return name, warm_up_part(name)
    from bench.core.registry import registry

    cls = registry("method").load(name)
    return name, warm_up(cls, cls.Params())


def schedule(kernels: dict[str, tuple[str, ...]],
             parts: dict[str, tuple[str, ...]] | None = None) -> list[tuple[str, set[str]]]:
    """The order of :func:`warm_up_all`'s tasks, each with the tasks it waits for.

    ``kernels`` maps each task to the kernel families it needs. Each family is built by
    the task that needs fewest families (then by name), so that a builder compiles
    little besides its own family; a task waits for the builder of every family it
    needs. The engine's family is the long one (minutes cold) and every other family's
    kernels run with it, so its builder needs it alone and starts first: the other
    families' builders then compile theirs in both processes at once as soon as it is
    cached, rather than one after another in the process that built the engine.
    ``parts`` (:func:`part_tasks`) maps a family to tasks that compile parts of it: they
    come first, and the family's builder waits for them."""
    parts = parts or {}
    order = sorted(kernels, key=lambda n: (len(kernels[n]), n))
    builder: dict[str, str] = {}
    for name in order:
        for family in kernels[name]:
            builder.setdefault(family, name)
    builds = set(builder.values())
    tasks = [(name, ({builder[f] for f in kernels[name]} - {name})
              | {p for f in kernels[name] if builder[f] == name for p in parts.get(f, ())})
             for name in order]
    first = [(p, set()) for f in sorted(parts) if f in builder for p in parts[f]]
    ready = [t for t in tasks if not t[1]]
    return (first + [t for t in ready if t[0] in builds]
            + [t for t in ready if t[0] not in builds] + [t for t in tasks if t[1]])


def warm_up_all(names: list[str], jobs: int = 1, on_done=lambda name, seconds: None,
                on_plan=lambda tasks: None) -> dict[str, float]:
    """Warm up the methods ``names`` and the evaluation, in ``jobs`` processes at a
    time (this process when 1), as :func:`schedule` orders them, with the parts of the
    split families (:data:`SPLIT`) first when ``jobs`` > 1 (one process gains nothing
    from them); ``on_plan`` is told the tasks' names, ``on_done`` of each task as it
    ends. Returns each task's seconds."""
    from bench.core.registry import registry

    methods = registry("method")
    kernels = {n: tuple(getattr(methods.load(n), "kernels", ())) for n in names}
    kernels[EVALUATION] = ()
    families = {f for needs in kernels.values() for f in needs}
    tasks = schedule(kernels, part_tasks(families) if jobs > 1 else None)
    on_plan([name for name, _ in tasks])
    times: dict[str, float] = {}
    if jobs <= 1:
        for name, _ in tasks:
            times[name] = _warm_task(name)[1]
            on_done(name, times[name])
        return times

    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    waiting = list(tasks)
    running = {}
    with ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
        while waiting or running:
            for task in [t for t in waiting if t[1] <= set(times)][:jobs - len(running)]:
                waiting.remove(task)
                running[pool.submit(_warm_task, task[0])] = task[0]
            if not running:  # cannot happen: every wait is on an earlier task
                raise RuntimeError(f"warm-up tasks wait on each other: {waiting}")
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                name, seconds = future.result()
                del running[future]
                times[name] = seconds
                on_done(name, seconds)
    return times
