"""The Dask executor: ``bench run --executor dask`` runs the plan on a Dask cluster.

It only runs jobs; planning, the records, ``--resume`` and the report are the same
code as with the local pool (:mod:`bench.run.runner`). The cluster is a running
``dask scheduler`` at ``--scheduler ADDRESS`` with its ``dask worker`` processes, or,
without an address, a ``distributed.LocalCluster`` of ``--jobs`` worker processes here.

How a job runs on a worker
    The task (:func:`bench.run.dask_worker.run_on_worker`) hands the job to a :class:`~bench.run.jobs.
    JobProcess` that the worker keeps, one per worker thread, created lazily by the
    thread that first needs it and held by a worker plugin (:class:`~bench.run.dask_worker.JobProcesses`) that
    ends them when the worker closes. The job process is where the per-worker state
    lives: the evaluation renderer (one EGL context, made in the process's only
    thread — an OpenGL context belongs to one thread), the loaded libraries and the
    compiled numba kernels. The original's reference images are cached on the worker
    machine's disk (``$BENCH_CACHE``, as with the local pool), so per machine and model;
    a method's shared work (``cache_dir``) goes to the worker's local directory.
    A failed job ends its job process and the next job gets a fresh one, so a context
    that died (or any state a failure left behind) is never used again.

Why a job process under the worker rather than the job in the worker's thread
    Dask has no per-task timeout and cannot stop a running thread, so a job past
    ``--timeout`` could only be abandoned, keeping its worker busy for good. Under the
    worker, the job process is killed at the timeout and the job becomes one failed
    record while the worker goes on; a crash in native code kills the job process, not
    the worker, and becomes a failed record as with the local pool; and a long job that
    holds the GIL cannot starve the worker's heartbeats to the scheduler.

Lost workers
    A worker that dies mid-job (killed, out of memory, its machine gone) is Dask's to
    handle: the scheduler runs the job again elsewhere, up to its
    ``distributed.scheduler.allowed-failures`` times (here :data:`LOST_WORKER_RETRIES`
    for a LocalCluster; a ``dask scheduler`` uses its own configuration, default 3),
    then the job fails with ``KilledWorker``, which becomes one failed record. (Dask's
    ``retries=`` on submit is for tasks that raise; a job never raises — its errors are
    records.) A record says how many attempts its job took
    (``environment.worker.attempts``).

Results come back to the client
    Workers need not see the run folder: a task returns the job's record and its image
    files as bytes, and the client writes them (:func:`bench.run.jobs.
    store_result`). A model given as a file is loaded here and shipped with its jobs.

Flow control
    At most as many jobs are submitted as the cluster has worker threads (re-read as
    workers come and go), so a job starts when it is submitted, a lost worker takes
    down only the job it was running, and Ctrl-C has little to cancel: the finished
    records are on disk, and the running jobs' processes are killed within a second.
"""

from __future__ import annotations

import logging
import sys
import uuid
from collections import deque
from collections.abc import Callable
from typing import Self

from bench.core.errors import ClusterError
from bench.run.jobs import Job, JobResult, failed_result

__all__ = ["CONNECT_TIMEOUT", "LOST_WORKER_RETRIES", "DaskExecutor"]

#: How often a LocalCluster's scheduler reruns a job whose worker died under it.
LOST_WORKER_RETRIES = 2
#: Seconds to wait for a scheduler at ``--scheduler`` before giving up.
CONNECT_TIMEOUT = 10
_INSTALL = "pip install 'bench-simplify[dask]'"


def _distributed():
    try:
        import distributed
    except ImportError:
        raise ClusterError(f"--executor dask needs the distributed package: {_INSTALL}") \
            from None
    return distributed


class DaskExecutor:
    """Runs jobs on a Dask cluster (see the module docstring); a context manager that
    connects on entry and, for a LocalCluster it started, shuts the cluster down on exit.
    """

    def __init__(self, workers: int = 1, scheduler: str | None = None, threads: int = 1):
        self.workers = max(1, int(workers))
        self.scheduler = scheduler
        self.threads = max(1, int(threads))  # per job, for its parallel kernels
        self.client = None
        self.cluster = None

    def __enter__(self) -> Self:
        distributed = _distributed()
        from bench.run.dask_worker import PLUGIN, JobProcesses  # needs distributed

        if self.scheduler:
            try:
                self.client = distributed.Client(self.scheduler, timeout=CONNECT_TIMEOUT)
            except (OSError, TimeoutError, ValueError, TypeError) as exc:
                raise ClusterError(f"cannot reach the Dask scheduler at {self.scheduler} "
                                   f"({_first_line(exc)}); start one with `dask scheduler` "
                                   "or check the address") from None
        else:
            import dask

            # the scheduler of a LocalCluster lives in this process and reads this now
            with dask.config.set({"distributed.scheduler.allowed-failures":
                                  LOST_WORKER_RETRIES}):
                self.cluster = distributed.LocalCluster(
                    n_workers=self.workers, threads_per_worker=1, processes=True,
                    dashboard_address=":0", silence_logs=logging.ERROR,
                    preload=["bench.run.dask_worker"])  # Ctrl-C: the client's alone
            self.client = distributed.Client(self.cluster)
        try:
            self.client.register_plugin(JobProcesses(), name=PLUGIN)
        except Exception as exc:  # noqa: BLE001 (whatever a worker raised, one line here)
            self.__exit__(None, None, None)
            raise ClusterError(f"the Dask workers cannot take bench's jobs ({type(exc).__name__}: "
                               f"{_first_line(exc)}); install this package, the same version, "
                               "on every worker") from None
        where = self.scheduler or f"a LocalCluster of {self.workers} workers"
        print(f"bench: Dask: {where}, {self._threads()} worker threads"
              + (f"; dashboard {link}" if (link := self._dashboard()) else ""),
              file=sys.stderr)
        return self

    def __exit__(self, *exc) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def _threads(self) -> int:
        return sum(self.client.nthreads().values())

    def _dashboard(self) -> str | None:
        services = self.client.scheduler_info(n_workers=0).get("services", {})
        return self.client.dashboard_link if "dashboard" in services else None

    def run(self, jobs: list[Job], timeout: float, done: Callable[[JobResult], None],
            note: Callable[[str], None] = lambda text: None) -> None:
        """Submit ``jobs`` as worker threads free up and hand each result to ``done``
        (``note``, the local executor's word on a long set-up, has nothing to say here:
        the jobs' phases stay on the workers)."""
        distributed = _distributed()
        from bench.run.dask_worker import run_on_worker

        pending = deque(jobs)
        running: dict = {}  # future -> job
        meshes: dict = {}
        told_no_workers = False
        try:
            while pending or running:
                threads = self._threads()
                if threads == 0 and not told_no_workers:
                    print("bench: waiting for Dask workers to join the scheduler",
                          file=sys.stderr)
                    told_no_workers = True
                while pending and len(running) < max(1, threads):
                    job = pending.popleft()
                    future = self.client.submit(
                        run_on_worker, job, self._mesh(job, meshes), timeout, self.threads,
                        key=f"bench-{job.key}-{uuid.uuid4().hex[:8]}", pure=False)
                    running[future] = job
                try:
                    finished, _ = distributed.wait(list(running), timeout=1.0,
                                                   return_when="FIRST_COMPLETED")
                except TimeoutError:
                    continue
                except distributed.client.FuturesCancelledError:
                    raise ClusterError("the Dask scheduler cancelled the run's jobs (did it "
                                       "restart, or lose this client?); the finished records "
                                       "are kept: run again with --resume") from None
                for future in finished:
                    result = self._result(future, running.pop(future))
                    # at once: a result left on a worker that dies is computed again
                    future.release()
                    done(result)
        finally:
            if running:  # Ctrl-C or an error: the running jobs' processes are killed
                self.client.cancel(list(running))

    @staticmethod
    def _mesh(job: Job, meshes: dict):
        """The mesh of a model given as a file, loaded here (workers may not see this
        disk); None for a registered model, which each worker builds itself."""
        from bench.catalog import resolve_model
        from bench.core.registry import registry

        if job.model in registry("model"):
            return None
        if job.model not in meshes:
            meshes[job.model] = resolve_model(job.model)
        return meshes[job.model]

    def _result(self, future, job: Job) -> JobResult:
        distributed = _distributed()
        if future.status == "finished":
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 (e.g. a worker with another bench)
                return failed_result(job, f"the Dask worker's result cannot be read here: "
                                     f"{type(exc).__name__}: {_first_line(exc)}",
                                     {"executor": "dask"})
            if result is None:  # the worker saw the job cancelled, yet it is wanted
                return failed_result(job, "the Dask worker stopped this job as cancelled",
                                     {"executor": "dask"})
            attempts = self._attempts(future.key)
            if attempts is not None:
                result.record["environment"]["worker"]["attempts"] = attempts
            return result
        error = future.exception()
        if isinstance(error, distributed.scheduler.KilledWorker):
            last = error.last_worker
            tries = error.allowed_failures + 1
            return failed_result(
                job, f"lost its Dask worker {tries} times (killed or died mid-job; the last "
                f"was {last.name} at {last.address}); the scheduler allows "
                f"{error.allowed_failures} retries",
                {"executor": "dask", "name": str(last.name), "address": last.address,
                 "attempts": tries})
        return failed_result(job, f"{type(error).__name__} on the Dask worker: "
                             f"{_first_line(error)}", {"executor": "dask"})

    def _attempts(self, key) -> int | None:
        """How many workers the scheduler gave this job (1 + workers lost under it)."""
        def suspicious(dask_scheduler, key=key):  # runs on the scheduler
            task = dask_scheduler.tasks.get(key)
            return None if task is None else task.suspicious

        try:
            lost = self.client.run_on_scheduler(suspicious)
        except Exception:  # noqa: BLE001 (a scheduler that refuses: the count is unknown)
            return None
        return None if lost is None else lost + 1


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__
