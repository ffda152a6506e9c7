"""Execute a plan of benchmark jobs and record each as it finishes.

One code path whatever runs the jobs: :func:`execute` takes the planned jobs, hands
them to an *executor* and writes every result it gets back into the run folder
(:func:`bench.run.jobs.store_result`: images, then the record, atomically) while the
progress bar advances. The executor only runs jobs:

* ``local`` (:class:`LocalPool`, the default): ``workers`` job processes on this
  machine, supervised here;
* ``dask`` (:class:`bench.run.cluster.DaskExecutor`): a Dask cluster, at a
  scheduler's address or a ``LocalCluster`` of ``workers`` processes.

Either way a crash, a hang past the timeout or an exception becomes a failed record
while the other jobs go on, and an interrupted run leaves every finished record on disk
for ``--resume``, which skips jobs whose record exists (in :mod:`bench.commands.run`).
"""

from __future__ import annotations

import json
import os
import time
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import wait
from pathlib import Path
from typing import Self

from bench.core.errors import InputError
from bench.records.results import EVALUATED
from bench.run.jobs import (
    SHEET_VIEWS,
    Job,
    JobProcess,
    JobResult,
    environment,
    plan,
    run_job,
    store_result,
)

__all__ = ["EXECUTORS", "SHEET_VIEWS", "Families", "Job", "JobResult", "LocalPool",
           "environment", "execute", "next_job", "plan", "remaining", "run_job"]

#: The executors ``bench run --executor`` offers.
EXECUTORS = ("local", "dask")


def remaining(jobs: list[Job], run_dir: Path) -> list[Job]:
    """The jobs ``--resume`` runs: those without a finished record in ``run_dir`` (a
    record is written only when a job ends, whichever executor ran it), and those whose
    record says it failed or cannot be read, so a job lost to a killed worker, a timeout
    or a crash gets another go; ok and skipped jobs are kept as they are."""
    def finished(job: Job) -> bool:
        path = Path(run_dir) / "records" / f"{job.key}.json"
        try:
            return json.loads(path.read_text(encoding="utf-8")).get("status") in (
                *EVALUATED, "skipped")
        except (OSError, ValueError, AttributeError):
            return False

    return [job for job in jobs if not finished(job)]


def execute(jobs: list[Job], run_dir: Path, workers: int = 1, timeout: float = 900.0,
            progress: bool = True, executor: str = "local",
            scheduler: str | None = None, threads: int | None = None) -> list[dict]:
    """Run ``jobs`` with ``executor``, writing each record into ``run_dir`` as it finishes.

    Returns the records in completion order. ``workers`` is the number of job processes
    (local) or of a LocalCluster's workers (dask without ``scheduler``); ``scheduler`` is
    a Dask scheduler's address (dask only). A job whose method runs past ``timeout``
    seconds is failed, as is one whose set-up or evaluation runs past
    :data:`~bench.run.jobs.PHASE_LIMIT`. ``threads`` is how many threads each job's
    parallel kernels may use (None: :func:`default_threads` of ``workers``).
    """
    from tqdm import tqdm

    if executor not in EXECUTORS:
        raise InputError(f"unknown executor {executor!r}; choose one of {', '.join(EXECUTORS)}")
    if scheduler and executor != "dask":
        raise InputError("--scheduler is the address of a Dask scheduler: it needs "
                         "--executor dask")
    run_dir = Path(run_dir)
    if not jobs:
        return []
    records = []
    if executor == "dask":
        from bench.run.cluster import DaskExecutor

        pool = DaskExecutor(workers, scheduler, threads or default_threads(workers, scheduler))
    else:
        pool = LocalPool(workers, run_dir / "cache", threads or default_threads(workers))
    with pool:  # a cluster that cannot be reached fails here, before the progress bar
        bar = tqdm(total=len(jobs), unit="job", disable=not progress, dynamic_ncols=True)

        def done(result: JobResult) -> None:
            store_result(run_dir, result)
            records.append(result.record)
            job = result.job
            bar.set_postfix_str(f"{job.model} {job.label} {job.target_faces}: "
                                f"{result.record['status']}", refresh=False)
            bar.update(1)

        try:
            pool.run(jobs, timeout, done, lambda text: bar.set_postfix_str(text))
        finally:
            bar.close()
    return records


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity, which ``taskset`` and
    container limits narrow), not all the machine has."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # no affinity on this system
        return os.cpu_count() or 1


def default_threads(workers: int, scheduler: str | None = None) -> int:
    """Threads per job when ``bench run`` is not told: this machine's usable cores
    (:func:`usable_cores`) shared by its ``workers`` job processes (jobs x threads <= cores, at least 1 each); 1 on a Dask
    scheduler's workers, whose machines this one does not know (each worker thread runs a
    job; --threads gives a job more)."""
    if scheduler:
        return 1
    return max(1, usable_cores() // max(1, workers))


def _group(job: Job) -> tuple[str, str]:
    """Jobs of one method on one model may share work through the run's cache (e.g.
    perceptual-mt's Multi-Triangulation and its bounds, built once per model)."""
    return job.model, job.method


class Families:
    """What a run's jobs build once and share: the kernel families
    (:attr:`bench.core.method.Method.kernels`) they warm up, so that two job processes
    never compile the same numba kernels side by side, and a model's shared work (a
    method that :attr:`~bench.core.method.Method.shares_work`, e.g. perceptual-mt's
    Multi-Triangulation), so that two processes never build it side by side.

    A job's *families* are its method's kernel families, the method itself (whose own
    kernels its first job compiles) and, for a method that shares work, its model's
    work. The first job to need a family that is not yet known to be built *claims*
    it: that job's warm-up compiles the kernels on a cold numba cache, or reads them
    from the cache in a second on a warm one. Jobs needing a claimed family wait; a
    kernel family is *built* once its job has left its set-up (the warm-up), a model's
    work once its job has ended; a kernel family is released unbuilt if its job ended
    in its set-up (skipped, failed or timed out), and a model's work if its job failed,
    for the next job to claim. The run knows nothing of the cache at its start, so on a
    warm one a process may wait while the claiming job loads its model and reads the
    kernels from the cache (about a second for the built-in models), and on a cold one
    no family is compiled in both processes at once: ``bench run`` then compiles about
    as fast as ``bench warmup`` does, with the baselines' jobs, which need no family,
    running meanwhile on the other process. (The evaluation's kernels, a few seconds,
    are compiled by each process's first job, in both at once on a cold cache.) The
    local executor only: a Dask worker's jobs compile what they need as before.
    """

    def __init__(self, kernels: dict[str, tuple[str, ...]],
                 shares_work: frozenset[str] | set[str] = frozenset()):
        # each method's kernel families and its own kernels
        self.by_method = {method: (*(("kernels", f) for f in families), ("method", method))
                          for method, families in kernels.items()}
        self.shares_work = set(shares_work)
        self.built: set[tuple[str, ...]] = set()
        self.claims: dict[tuple[str, ...], object] = {}

    def needs(self, job: Job) -> tuple[tuple[str, ...], ...]:
        """The families ``job`` needs."""
        work = (("work", job.model, job.method),) if job.method in self.shares_work else ()
        return self.by_method.get(job.method, ()) + work

    def _unbuilt(self, job: Job) -> list[tuple[str, ...]]:
        return [f for f in self.needs(job) if f not in self.built]

    def waits(self, job: Job) -> bool:
        """Whether ``job`` needs a family that another job is building."""
        return any(f in self.claims for f in self._unbuilt(job))

    def builds_kernels(self, job: Job) -> bool:
        """Whether ``job`` would be the first to build one of the kernel families."""
        return any(f[0] == "kernels" and f not in self.claims for f in self._unbuilt(job))

    def claim(self, job: Job, owner) -> None:
        for family in self._unbuilt(job):
            self.claims.setdefault(family, owner)

    def left_setup(self, owner) -> None:
        """``owner``'s job has warmed up: the kernels it claimed are built."""
        self._settle(owner, built=True, kinds=("kernels", "method"))

    def ended(self, owner, left_setup: bool, failed: bool = False) -> None:
        """``owner``'s job ended, after its set-up or in it: its kernels are built if it
        left its set-up, else released; its model's work is built unless the job
        failed, else released for the next job to build."""
        self._settle(owner, built=left_setup, kinds=("kernels", "method"))
        self._settle(owner, built=not failed, kinds=("work",))

    def _settle(self, owner, built: bool, kinds: tuple[str, ...]) -> None:
        for family in [f for f, o in self.claims.items() if o == owner and f[0] in kinds]:
            del self.claims[family]
            if built:
                self.built.add(family)


def next_job(pending: deque, running: set, last: tuple[str, str] | None,
             families: Families | None = None, owner=None) -> Job | None:
    """Take from ``pending`` the job a free process should run next, or None if every
    waiting job needs kernels another process is compiling or work another process is
    building (:class:`Families`; the process then waits). First a job that is the first
    to build a kernel family, needing the fewest families (the engine's, the long
    compile, starts at once, and the families built on it as soon as it is built);
    then one of the group (:func:`_group`) this process ran last, so what it cached in
    memory is reused; else the first whose group no other process is running, so two
    processes do not build the same shared work side by side; else the first ready
    one."""
    ready = [job for job in pending if families is None or not families.waits(job)]
    if not ready:
        return None
    builders = [job for job in ready if families is not None and families.builds_kernels(job)]
    if builders:
        job = min(builders, key=lambda j: len(families.needs(j)))  # the first of equals
    else:
        free = [job for job in ready if _group(job) not in running]
        job = next((j for j in free if _group(j) == last), free[0] if free else ready[0])
    pending.remove(job)
    if families is not None:
        families.claim(job, owner)
    return job


def _families(jobs: list[Job]) -> Families:
    """The :class:`Families` of ``jobs``' methods (from the method registry)."""
    from bench.core.registry import registry

    methods = registry("method")
    classes = {}
    for name in dict.fromkeys(job.method for job in jobs):
        try:
            classes[name] = methods.load(name)
        except Exception:  # noqa: BLE001 - the job process loads it, or fails the job
            classes[name] = None  # e.g. a plug-in this process's registry does not know
    return Families({name: tuple(getattr(cls, "kernels", ())) for name, cls in classes.items()},
                    {name for name, cls in classes.items() if getattr(cls, "shares_work", False)})


#: Seconds of a job's set-up after which the progress bar says what it is doing: on a
#: first run, numba compiles the kernels there for minutes while the bar stands still.
SETUP_NOTE_AFTER = 10.0


def setup_note(procs, after: float = SETUP_NOTE_AFTER) -> str | None:
    """A line for the progress bar about the first of ``procs`` whose job has been in
    its set-up for more than ``after`` seconds, or None."""
    now = time.monotonic()
    for proc in procs:
        if proc is not None and proc.job is not None and proc.phase == "setup" \
                and now - proc.started > after:
            job = proc.job
            return (f"{job.model} {job.label} {job.target_faces}: setting up for "
                    f"{now - proc.started:.0f} s (loading the model and warming up: a "
                    "first run compiles numba's kernels, cached for the next)")
    return None


class LocalPool:
    """``workers`` job processes on this machine, each given a job when free
    (:func:`next_job`: the plan's order, except that the first job to need a kernel
    family not yet built goes first, a job waits while another process compiles a
    family it needs (:class:`Families`), a process keeps to its last model and method
    where it can, and two processes avoid running the same pair).

    A process that dies or runs past the timeout is killed and replaced (lazily, when
    there is a job for it); its job gets a failed record. ``cache_dir`` is the run
    folder's ``cache/``, shared by the processes (they see the same disk).
    """

    def __init__(self, workers: int, cache_dir: Path, threads: int = 1):
        self.workers = max(1, int(workers))
        self.cache_dir = Path(cache_dir)
        self.threads = max(1, int(threads))
        self.slots: list[JobProcess | None] = []

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        for proc in self.slots:
            if proc is None:
                continue
            if proc.job is not None:  # still busy: Ctrl-C or an error here; nobody waits
                proc.kill()
            else:
                proc.close()
        self.slots = []

    def run(self, jobs: list[Job], timeout: float, done: Callable[[JobResult], None],
            note: Callable[[str], None] = lambda text: None) -> None:
        """Run ``jobs``, handing each result to ``done`` and a job's long set-up to
        ``note`` (:func:`setup_note`)."""
        pending = deque(jobs)
        families = _families(jobs)
        self.slots = [None] * min(self.workers, len(jobs))
        last: list[tuple[str, str] | None] = [None] * len(self.slots)
        noted = False  # the bar shows a set-up note: cleared once no set-up is long
        while pending or any(p is not None and p.job is not None for p in self.slots):
            for i, proc in enumerate(self.slots):
                if pending and (proc is None or proc.job is None):
                    running = {_group(p.job) for p in self.slots
                               if p is not None and p.job is not None}
                    job = next_job(pending, running, last[i], families, i)
                    if job is None:  # it waits for kernels another process compiles
                        continue
                    if proc is None or not proc.usable:  # first job, or replaced
                        self.slots[i] = proc = JobProcess()
                    last[i] = _group(job)
                    proc.submit(job, self.cache_dir, self._worker(i))
            busy = [(i, p) for i, p in enumerate(self.slots) if p is not None and p.job is not None]
            ready = wait([p.conn for _, p in busy], timeout=0.5)
            for i, proc in busy:
                if proc.conn in ready:
                    result = proc.collect()  # None: the job only reported a phase
                    if result is None:
                        if proc.phase != "setup":
                            families.left_setup(i)
                        continue
                elif proc.expired(timeout):
                    result = proc.timed_out(timeout)
                else:
                    continue
                families.ended(i, left_setup=proc.phase != "setup", failed=result.failed)
                done(result)
                noted = False  # the finished job's line has replaced the note
            text = setup_note(self.slots)
            if text or noted:
                note(text or "")
            noted = bool(text)

    def _worker(self, slot: int) -> dict:
        import platform

        return {"executor": "local", "name": f"local-{slot}", "host": platform.node(),
                "threads": self.threads}
