"""Plan, execute and record benchmark jobs.

A *job* is one (model, method variant, face budget) under one protocol. The plan is the
cartesian product of what ``bench run`` was given. Jobs run in worker processes
(:class:`WorkerPool`): a crash, a hang past the timeout or an exception becomes a
failed record with its error while the other jobs go on. Each finished job is written
at once as ``DIR/records/<key>.json``; ``--resume`` skips jobs whose record exists.
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import os
import platform
import re
import subprocess
import time
import traceback
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version
from multiprocessing.connection import wait
from pathlib import Path

import numpy as np

from bench.harness.keys import job_key
from bench.harness.results import SCHEMA_VERSION, write_record
from metrics.protocol import Protocol

__all__ = ["Job", "plan", "execute", "run_job", "method_label", "environment", "SHEET_VIEWS"]

#: Protocol views shown in the report's image sheets (spread over the sphere).
SHEET_VIEWS = (0, 7, 13, 20)


def method_label(name: str, params: dict) -> str:
    """``name[key=value,...]`` listing the parameters that differ from the defaults."""
    if not params:
        return name
    return name + "[" + ",".join(f"{k}={_fmt(v)}" for k, v in sorted(params.items())) + "]"


def _fmt(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=,-]+", "-", text).strip("-")


@dataclass(frozen=True)
class Job:
    """One unit of work. ``params`` holds only the overrides of the method's defaults."""

    model: str
    method: str
    target_faces: int
    params: dict = field(default_factory=dict, hash=False)
    protocol: Protocol = Protocol()

    @property
    def label(self) -> str:
        return method_label(self.method, self.params)

    @property
    def key(self) -> str:
        """File-name stem of this job's record: unique, readable, stable (bench.harness.keys)."""
        return job_key(self.model, self.method, self.label, self.params, self.target_faces,
                       self.protocol)

    def as_dict(self) -> dict:
        return {"model": self.model, "method": self.method, "params": dict(self.params),
                "label": self.label, "target_faces": self.target_faces,
                "protocol": self.protocol.as_dict(), "key": self.key}


def plan(models: list[str], variants: list[tuple[str, dict]], budgets: dict[str, list[int]],
         protocols: Protocol | Sequence[Protocol]) -> list[Job]:
    """The cartesian product of models × method variants × each model's budgets ×
    evaluation protocols (one :class:`Protocol` or several), the protocol varying
    fastest. Duplicate jobs (same record key) are planned once."""
    if isinstance(protocols, Protocol):
        protocols = [protocols]
    if not protocols:
        raise ValueError("plan needs at least one evaluation protocol")
    jobs = [Job(model, name, faces, dict(params), protocol)
            for model in models for name, params in variants for faces in budgets[model]
            for protocol in protocols]
    return list({job.key: job for job in jobs}.values())


# -- running one job (inside a worker) ------------------------------------------------------

def run_job(job: Job, run_dir: Path) -> dict:
    """Simplify, evaluate and describe one job; never raises (errors become records)."""
    record = {"schema": SCHEMA_VERSION, "job": job.as_dict(), "status": "failed",
              "error": None, "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
              "environment": environment()}
    try:
        _run_job(job, run_dir, record)
    except Exception as exc:
        from bench.errors import BenchError

        record["status"] = "failed"
        record["error"] = str(exc) if isinstance(exc, BenchError) else \
            f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}"
    return record


def _run_job(job: Job, run_dir: Path, record: dict) -> None:
    from bench.method import parse_params, run_method
    from bench.models import resolve_model
    from bench.registry import registry
    from metrics.protocol import evaluate, original_images

    method_cls = registry("method").load(job.method)
    record["method"] = {"name": method_cls.name, "version": method_cls.version,
                        "view_dependent": method_cls.view_dependent}
    mesh = resolve_model(job.model)
    record["model"] = {"name": mesh.name, "hash": mesh.content_hash, "faces": mesh.n_faces,
                       "render_vertices": mesh.n_vertices,
                       "welded_vertices": mesh.welded.n_vertices}
    if method_cls.needs_uv and mesh.uv is None:
        record.update(status="skipped", error=f"{method_cls.name} needs texture coordinates; "
                      f"{mesh.name} has none")
        return
    params = parse_params(method_cls.Params, [f"{k}={_fmt(v)}" for k, v in job.params.items()])
    record["job"]["params_all"] = dataclasses.asdict(params)

    peak = _PeakMemory()
    # shading-aware methods optimise for the evaluation's shading unless told otherwise
    ctx = {"shading": job.protocol.shading, "specular": job.protocol.specular,
           # work a method may share between the run's jobs (e.g. perceptual-mt's MT)
           "cache_dir": str(run_dir / "cache")}
    result = run_method(method_cls(params), mesh, job.target_faces, ctx)
    stats = dict(result.stats)
    stats["peak_mb"] = peak.megabytes()
    removed = mesh.n_faces - result.mesh.n_faces
    stats["tri_per_s"] = removed / stats["wall_seconds"] if stats["wall_seconds"] > 0 else None
    record.update(stats=stats, stop_reason=result.stop_reason,
                  artifacts=_save_artifacts(run_dir, job, result.artifacts))

    reference = original_images(mesh, job.protocol)
    view_meshes = None
    if result.view_cuts is not None:  # view-dependent: each view imaged with its own cut
        from metrics.views import protocol_cameras

        view_meshes = result.view_cuts(protocol_cameras(mesh), job.protocol)
        stats.update(getattr(result.view_cuts, "stats", {}))
    ev = evaluate(mesh, result.mesh, job.protocol, reference_images=reference,
                  view_meshes=view_meshes)
    record.update(metrics=ev.metrics, per_view=ev.per_view, seconds=ev.seconds,
                  silhouette_histogram=ev.silhouette_histogram, status="ok")
    if ev.errors:  # metrics that raised: the job is ok, those values are missing
        record["metric_errors"] = ev.errors
    _save_sheet_images(run_dir, job, mesh, reference, ev.images)


def _save_sheet_images(run_dir: Path, job: Job, mesh, reference, images) -> None:
    """PNGs of :data:`SHEET_VIEWS` for the report: the original's once per model and
    shading, the result's per job."""
    from PIL import Image

    shading = job.protocol.shading + ("-spec" if job.protocol.specular else "")
    original_dir = run_dir / "images" / f"original__{mesh.content_hash[:12]}__{shading}"
    job_dir = run_dir / "images" / job.key
    for folder, stack in ((original_dir, reference), (job_dir, images)):
        folder.mkdir(parents=True, exist_ok=True)
        for v in SHEET_VIEWS:
            target = folder / f"view{v:02d}.png"
            if folder is original_dir and target.exists():
                continue
            tmp = folder / f".view{v:02d}.{os.getpid()}.png"
            Image.fromarray(stack[v]).save(tmp)
            os.replace(tmp, target)


def _save_artifacts(run_dir: Path, job: Job, artifacts: dict) -> list[str]:
    """Write a method's report images as PNGs beside the job's views; returns the file
    names (relative to the run directory)."""
    from PIL import Image

    names = []
    folder = run_dir / "images" / job.key
    for name, image in artifacts.items():
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"artifact-{_slug(name)}.png"
        Image.fromarray(np.asarray(image, dtype=np.uint8)).save(path)
        names.append(str(path.relative_to(run_dir)))
    return names


class _PeakMemory:
    """Peak resident memory added since construction, in MB (Linux: VmHWM, reset via
    /proc/self/clear_refs; elsewhere the process's lifetime peak)."""

    def __init__(self):
        self.reset = False
        try:
            Path("/proc/self/clear_refs").write_text("5")
            self.reset = True
        except OSError:
            pass
        self.base = _status_kb("VmRSS")

    def megabytes(self) -> float | None:
        if self.reset:
            hwm = _status_kb("VmHWM")
            return None if hwm is None or self.base is None else max(0.0, (hwm - self.base) / 1024)
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _status_kb(field_name: str) -> float | None:
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field_name + ":"):
                return float(line.split()[1])
    except OSError:
        pass
    return None


_ENV = None


def environment() -> dict:
    """Package versions, git commit and machine, recorded with every result."""
    global _ENV
    if _ENV is None:
        versions = {}
        for dist in ("bench-simplify", "numpy", "numba", "pymeshlab", "fast-simplification",
                     "trimesh", "pyrender", "scikit-image", "flip-evaluator", "PyOpenGL"):
            try:
                versions[dist] = version(dist)
            except PackageNotFoundError:
                versions[dist] = None
        try:
            commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                                    cwd=Path(__file__).parent, timeout=5).stdout.strip() or None
        except (OSError, subprocess.SubprocessError):
            commit = None
        _ENV = {"versions": versions, "git_commit": commit, "python": platform.python_version(),
                "machine": {"system": platform.system(), "arch": platform.machine(),
                            "cpus": os.cpu_count(), "processor": _cpu_model()}}
    return _ENV


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


# -- the worker pool -----------------------------------------------------------------------

def _worker_loop(conn, run_dir: str) -> None:
    """Serve jobs until told to stop (None). Runs in a child process."""
    import signal
    import warnings

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's; it stops us
    warnings.simplefilter("ignore")  # per-job warnings are not the user's to read here
    while True:
        job = conn.recv()
        if job is None:
            return
        conn.send(run_job(job, Path(run_dir)))


@dataclass
class _Worker:
    process: mp.Process
    conn: object
    job: Job | None = None
    started: float = 0.0


def _failed(job: Job, error: str) -> dict:
    return {"schema": SCHEMA_VERSION, "job": job.as_dict(), "status": "failed", "error": error,
            "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "environment": environment()}


def execute(jobs: list[Job], run_dir: Path, workers: int = 1, timeout: float = 900.0,
            progress: bool = True) -> list[dict]:
    """Run ``jobs`` in ``workers`` processes, writing each record as it finishes.

    Returns the records in completion order. A worker that crashes or exceeds
    ``timeout`` seconds on a job is replaced; its job gets a failed record.
    """
    from tqdm import tqdm

    run_dir = Path(run_dir)
    ctx = mp.get_context("spawn")  # a fresh interpreter: no inherited GL or thread state
    pending = deque(jobs)
    pool: list[_Worker] = []
    records = []
    bar = tqdm(total=len(jobs), unit="job", disable=not progress, dynamic_ncols=True)

    def spawn() -> _Worker:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_worker_loop, args=(child, str(run_dir)), daemon=True)
        proc.start()
        child.close()
        return _Worker(proc, parent)

    def finish(worker: _Worker, record: dict) -> None:
        write_record(run_dir / "records" / f"{worker.job.key}.json", record)
        records.append(record)
        bar.set_postfix_str(f"{worker.job.model} {worker.job.label} {worker.job.target_faces}: "
                            f"{record['status']}", refresh=False)
        bar.update(1)
        worker.job = None

    try:
        for _ in range(max(1, min(workers, len(jobs)))):
            pool.append(spawn())
        while pending or any(w.job for w in pool):
            for i, w in enumerate(pool):
                if w.job is None and pending:
                    if not w.process.is_alive():  # died between jobs: replace it
                        w.process.join()
                        pool[i] = w = spawn()
                    w.job, w.started = pending.popleft(), time.monotonic()
                    try:
                        w.conn.send(w.job)
                    except (OSError, BrokenPipeError):
                        pass  # seen as a dead worker below: a failed record, not a crash
            busy = [w for w in pool if w.job is not None]
            ready = wait([w.conn for w in busy], timeout=0.5)
            for w in busy:
                if w.conn in ready:
                    try:
                        finish(w, w.conn.recv())
                        continue
                    except (EOFError, OSError):
                        pass  # the worker died mid-job: handled below
                dead = not w.process.is_alive()
                late = time.monotonic() - w.started > timeout
                if dead or late or w.conn in ready:
                    w.process.kill()
                    w.process.join()
                    reason = (f"timed out after {timeout:g} s" if late and not dead else
                              f"worker process died (exit code {w.process.exitcode})")
                    finish(w, _failed(w.job, reason))
                    pool[pool.index(w)] = spawn()
    finally:
        for w in pool:
            try:
                w.conn.send(None)
            except (OSError, BrokenPipeError):
                pass
        for w in pool:
            w.process.join(timeout=5)
            if w.process.is_alive():
                w.process.kill()
        bar.close()
    return records
