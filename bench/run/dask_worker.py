"""What a Dask worker runs for ``bench run --executor dask``: the task and the worker
plugin that keeps the worker's job processes (:mod:`bench.run.cluster` explains the
design). Imported only where ``distributed`` is installed: by the client once it has
checked, and by the workers when they unpickle the plugin and the task.
"""

from __future__ import annotations

import platform
import signal
import threading
from pathlib import Path

from distributed import WorkerPlugin, get_worker
from distributed.worker import thread_state

from bench.run.jobs import Job, JobProcess, JobResult

__all__ = ["PLUGIN", "JobProcesses", "dask_setup", "run_on_worker"]

#: The name the worker plugin is registered under.
PLUGIN = "bench-job-processes"


class JobProcesses(WorkerPlugin):
    """The worker's job processes, one per worker thread, each created lazily by the
    thread that uses it; ended when the worker closes (or the plugin is replaced).

    A method's shared work goes to ``<worker local directory>/bench-cache``: the worker
    may not see the client's run folder, and its local directory is its own scratch.
    """

    def setup(self, worker) -> None:
        self.cache_dir = Path(worker.local_directory) / "bench-cache"
        self.info = {"executor": "dask", "name": str(worker.name), "address": worker.address,
                     "host": platform.node()}
        self._local = threading.local()
        self._lock = threading.Lock()
        self._processes: list[JobProcess] = []

    def teardown(self, worker) -> None:
        with self._lock:
            processes, self._processes = self._processes, []
        for proc in processes:
            if proc.job is not None:
                proc.kill()
            else:
                proc.close(grace=2.0)

    def run(self, job: Job, mesh, timeout: float, cancelled, threads: int = 1
            ) -> JobResult | None:
        proc = getattr(self._local, "process", None)
        if proc is None or not proc.usable:  # first job of this thread, or after a failure
            proc = self._local.process = JobProcess()
            with self._lock:
                self._processes = [p for p in self._processes if p.usable] + [proc]
        return proc.run(job, self.cache_dir, timeout, {**self.info, "threads": threads}, mesh,
                        cancelled)


def run_on_worker(job: Job, mesh, timeout: float, threads: int = 1) -> JobResult | None:
    """The Dask task: run ``job`` in this worker thread's job process, its parallel
    kernels on ``threads`` threads. Returns None if the client cancelled the job while it
    ran (its process is then killed)."""
    worker = get_worker()
    processes = worker.plugins.get(PLUGIN)
    if processes is None:  # the client registers the plugin on every worker, joining
        processes = JobProcesses()  # ones too; this only guards against a race
        processes.setup(worker)
        worker.plugins[PLUGIN] = processes
    key = thread_state.key

    def cancelled() -> bool:
        task = worker.state.tasks.get(key)
        return task is None or task.state in ("cancelled", "released", "forgotten")

    return processes.run(job, mesh, timeout, cancelled, threads)


def dask_setup(worker) -> None:
    """Preloaded into the workers of the LocalCluster that ``bench run`` starts.

    Ctrl-C in a terminal reaches every process of its group, these workers included;
    the client alone answers it (it keeps the finished records and closes the cluster),
    so here it is ignored rather than printed as each worker's traceback.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
