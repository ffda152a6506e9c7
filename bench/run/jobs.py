"""Benchmark jobs: what one is, how it runs, and how its outcome lands in a run folder.

A *job* is one (model, method variant, face budget) under one protocol. The plan is the
cartesian product of what ``bench run`` was given.

A job never writes into the run folder itself. :func:`run_job` returns a
:class:`JobResult`: the record and the files that go with it (the report's sheet
images and a method's artifacts as PNG bytes; the evaluated mesh and the original as
GLB files for the report's 3D view, :func:`mesh_paths`) keyed by their path inside the
run folder.
Whoever asked for the job writes it with :func:`store_result`, files first and the
record last, each atomically: the local pool's parent process, or the Dask client for a
job that ran on a machine that does not see the run folder. So a record on disk always
means a finished job with its images, and ``--resume`` can trust it.

Jobs run in a :class:`JobProcess`, a fresh interpreter that serves one job at a time to
the process that supervises it (the local pool, or a Dask worker). The supervisor is
what survives a job: a crash in native code, a hang past the timeout or an exception
each become one failed record while the other jobs go on. After a failed job the
process is replaced, so whatever broke in it — a lost OpenGL context, a half-built
library state — never reaches the next job; a process that ran well is kept, with its
evaluation renderer (one EGL context, created in its only thread), its imports and its
compiled numba kernels warm.
"""

from __future__ import annotations

import dataclasses
import io
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from multiprocessing.connection import Connection
from pathlib import Path, PurePosixPath

import numpy as np

from bench.core.errors import BenchError
from bench.core.method import method_label, param_text
from bench.records.results import (
    SCHEMA_VERSION,
    result_status,
    shading_label,
    write_file,
    write_record,
)
from bench.records.stats import compute_intervals
from bench.run.keys import job_key
from metrics.protocol import Protocol

__all__ = ["SHEET_VIEWS", "Job", "JobProcess", "JobResult", "environment",
           "evaluate_result", "failed_result", "mesh_paths", "plan",
           "run_job", "sheet_views", "store_result", "use_threads"]

#: Protocol views shown in the report's image sheets (spread over the sphere).
SHEET_VIEWS = (0, 7, 13, 20)


def sheet_views(n_views: int) -> tuple[int, ...]:
    """The views of a job's image sheet among its ``n_views`` evaluation views:
    :data:`SHEET_VIEWS` of the 24-view protocol, every view of a smaller view set
    (``Protocol.views``)."""
    return SHEET_VIEWS if n_views >= 24 else tuple(range(min(n_views, len(SHEET_VIEWS))))


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.=,-]+", "-", text).strip("-")


@dataclass(frozen=True)
class Job:
    """One unit of work. ``params`` holds only the overrides of the method's defaults."""

    model: str
    method: str
    target_faces: int
    params: dict = field(default_factory=dict, hash=False)
    protocol: Protocol = Protocol()  # noqa: RUF009 (frozen: one shared default is safe)

    @property
    def label(self) -> str:
        return method_label(self.method, self.params)

    @property
    def key(self) -> str:
        """File-name stem of this job's record: unique, readable, stable (bench.run.keys)."""
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


# -- a job's outcome ------------------------------------------------------------------------

@dataclass
class JobResult:
    """A finished job: its record and its files, not yet on any disk.

    ``files`` are this job's own (its sheet views, artifacts and mesh); ``shared_files``
    are the original's sheet views and mesh, the same bytes for every job of the model
    (and shading, for views), so they are written only when absent. Keys are paths
    relative to the run folder.
    """

    job: Job
    record: dict
    files: dict[str, bytes] = field(default_factory=dict)
    shared_files: dict[str, bytes] = field(default_factory=dict)

    @property
    def failed(self) -> bool:
        return self.record.get("status") == "failed"


def _death(code: int | None) -> str:
    """Why a job process ended without a result, from its exit code (negative: the
    signal that killed it)."""
    if code is not None and code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        hint = " (the out-of-memory killer sends it)" if -code == signal.SIGKILL else ""
        return f"job process was killed by {name}{hint}"
    return f"job process died (exit code {code})"


def failed_result(job: Job, error: str, worker: dict | None = None) -> JobResult:
    """The record of a job that produced none itself (its process died, it ran out of
    time, its Dask workers were lost)."""
    return JobResult(job, {"schema": SCHEMA_VERSION, "job": job.as_dict(), "status": "failed",
                           "error": error, "created": _now(),
                           "environment": _environment_of(worker)})


def store_result(run_dir: Path, result: JobResult) -> Path:
    """Write a job's files, then its record, into ``run_dir``, each atomically; returns
    the record's path. The record comes last so that its presence means a whole job."""
    run_dir = Path(run_dir)
    for name, data in result.shared_files.items():
        path = _inside(run_dir, name)
        if not path.exists():
            write_file(path, data)
    for name, data in result.files.items():
        write_file(_inside(run_dir, name), data)
    return write_record(run_dir / "records" / f"{result.job.key}.json", result.record)


def _inside(run_dir: Path, name: str) -> Path:
    """``run_dir / name`` for a relative name that stays inside the run folder (names
    come back from other machines on a cluster; none may write elsewhere)."""
    parts = PurePosixPath(name).parts
    if not parts or PurePosixPath(name).is_absolute() or ".." in parts:
        raise ValueError(f"a job's file name must stay inside the run folder: {name!r}")
    return run_dir.joinpath(*parts)


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


# -- running one job (inside a job process) ---------------------------------------------------

#: Seconds a job may spend outside its method: loading the model and warming up (numba
#: may compile for minutes on a cold cache), or evaluating the result. ``--timeout``
#: bounds the method alone, so a 5 ms simplification passes ``--timeout 1``.
PHASE_LIMIT = 1800.0
#: The phases of a job, as the job process reports them to its supervisor.
PHASES = ("setup", "method", "evaluation")


def run_job(job: Job, cache_dir: Path, worker: dict | None = None, mesh=None,
            phase: Callable[[str], None] = lambda name: None) -> JobResult:
    """Simplify, evaluate and describe one job; never raises (errors become records).

    ``cache_dir`` holds work a method shares between jobs on this machine (e.g.
    perceptual-mt's Multi-Triangulation); ``worker`` describes who ran the job (it goes
    into the record's environment); ``mesh`` is the model's mesh when the caller loaded
    it already (a Dask client ships file models, which its workers may not see);
    ``phase(name)`` is told when the method starts (``"method"``) and when it ends
    (``"evaluation"``), so a supervisor can time the method alone. ``worker["threads"]``,
    when given, is how many threads the job's parallel kernels may use
    (:func:`use_threads`); the record's ``environment.worker.threads`` says how many they
    had.
    """
    record = {"schema": SCHEMA_VERSION, "job": job.as_dict(), "status": "failed",
              "error": None, "created": _now(), "environment": _environment_of(worker)}
    result = JobResult(job, record)
    try:
        record["environment"]["worker"]["threads"] = use_threads((worker or {}).get("threads"))
        _run_job(job, Path(cache_dir), result, mesh, phase)
    except Exception as exc:  # noqa: BLE001 (any failure of a job is its record's error)
        record["status"] = "failed"
        record["error"] = str(exc) if isinstance(exc, BenchError) else \
            f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=8)}"
    return result


def use_threads(requested: int | None) -> int:
    """Let numba's parallel kernels use ``requested`` threads in this process (at most
    the pool numba started, the machine's cores unless ``NUMBA_NUM_THREADS`` says
    otherwise; None leaves it as it is) and return how many they will use. Results do
    not depend on it (docs/maintainers.md, "Parallel kernels and numba's cache")."""
    import numba

    if requested is not None:
        numba.set_num_threads(max(1, min(int(requested), numba.config.NUMBA_NUM_THREADS)))
    return numba.get_num_threads()


def _run_job(job: Job, cache_dir: Path, result: JobResult, mesh, phase) -> None:
    from bench.catalog import resolve_model
    from bench.core.method import parse_params, run_method
    from bench.core.registry import registry
    from bench.run.warmup import warm_up, warm_up_evaluation_once
    from metrics.protocol import original_images

    record = result.record
    timings = record["timings"] = {}
    clock = _Stopwatch(timings)
    method_cls = registry("method").load(job.method)
    record["method"] = {"name": method_cls.name, "version": method_cls.version,
                        "view_dependent": method_cls.view_dependent}
    if mesh is None:
        mesh = resolve_model(job.model)
    clock.lap("load")
    record["model"] = {"name": mesh.name, "hash": mesh.content_hash, "faces": mesh.n_faces,
                       "render_vertices": mesh.n_vertices,
                       "welded_vertices": mesh.welded.n_vertices}
    if method_cls.needs_uv and mesh.uv is None:
        record.update(status="skipped", error=f"{method_cls.name} needs texture coordinates; "
                      f"{mesh.name} has none")
        return
    params = parse_params(method_cls.Params,
                          [f"{k}={param_text(v)}" for k, v in job.params.items()])
    record["job"]["params_all"] = dataclasses.asdict(params)

    # the evaluation's kernels, once per process, so that its timings hold none of their
    # compilation or loading (in the warm-up's timing; not the method's peak memory)
    warm_up_evaluation_once()
    peak = _PeakMemory()
    # shading-aware methods optimise for the evaluation's shading unless told otherwise
    ctx = {"shading": job.protocol.shading, "specular": job.protocol.specular,
           # work a method may share between the run's jobs (e.g. perceptual-mt's MT)
           "cache_dir": str(cache_dir)}
    # numba compilation or cache loading is not method time: warm up first, apart
    compile_seconds = warm_up(method_cls, params, ctx)
    clock.lap("warm_up")
    phase("method")
    simplified = run_method(method_cls(params), mesh, job.target_faces, ctx)
    phase("evaluation")
    clock.lap("method")
    stats = _method_stats(simplified, mesh.n_faces, compile_seconds, peak)
    record.update(stats=stats, stop_reason=simplified.stop_reason,
                  artifacts=_artifact_files(job, simplified.artifacts, result.files))

    reference = original_images(mesh, job.protocol)
    clock.lap("reference_images")
    ev, view_stats = evaluate_result(mesh, simplified, job.protocol, reference)
    clock.lap("evaluation")
    stats.update(view_stats)
    _record_evaluation(record, ev, stats, simplified.mesh.n_faces, job.target_faces)
    _sheet_files(job, mesh, reference, ev.images, result)
    clock.lap("sheets")
    _mesh_files(job, mesh, simplified.mesh, result)
    clock.lap("mesh_files")
    timings["total"] = clock.total()


def _method_stats(simplified, faces_before: int, compile_seconds: float, peak) -> dict:
    """The method's own statistics and the job's: its warm-up, peak memory and rate."""
    stats = dict(simplified.stats)
    stats["compile_seconds"] = compile_seconds
    stats["peak_mb"] = peak.megabytes()
    removed = faces_before - simplified.mesh.n_faces
    stats["tri_per_s"] = removed / stats["wall_seconds"] if stats["wall_seconds"] > 0 else None
    return stats


def _record_evaluation(record: dict, ev, stats: dict, faces: int, target: int) -> None:
    """The evaluation's figures into the record, and the job's status."""
    record.update(metrics=ev.metrics, per_view=ev.per_view, seconds=ev.seconds,
                  intervals=compute_intervals(ev.metrics, ev.per_view),
                  silhouette_histogram=ev.silhouette_histogram,
                  status=result_status(faces, target))
    if ev.errors:  # metrics that raised: the job is ok, those values are missing
        record["metric_errors"] = ev.errors
    if ev.screen is not None:  # the screen-size curve, with the method's own prediction
        from metrics.screen import add_library_prediction

        record["screen"] = dict(ev.screen)
        add_library_prediction(record["screen"], stats)


class _Stopwatch:
    """Where a job's time goes, stage by stage, into the record's ``timings``: each
    :meth:`lap` stores the seconds since the previous one under its name."""

    def __init__(self, timings: dict):
        self.timings = timings
        self.start = self.last = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.timings[name] = now - self.last
        self.last = now

    def total(self) -> float:
        """The seconds up to the last lap: the laps' sum, whatever the machine's load
        between that lap and this call."""
        return self.last - self.start


def evaluate_result(original, result, protocol, reference_images=None):
    """Evaluate a method's result against ``original`` under ``protocol``, as every
    record is (``bench run``) and as ``bench simplify --evaluate`` does per level.

    A view-dependent result is imaged view by view with its own cuts
    (:attr:`~bench.core.method.SimplifyResult.view_cuts`); its other metrics use its
    view-independent mesh.

    Returns
    -------
    Evaluation, dict
        The evaluation, and the view cuts' statistics (empty for other methods), which
        belong with the method's.
    """
    from metrics.protocol import evaluate

    view_meshes, view_stats = None, {}
    if result.view_cuts is not None:  # view-dependent: each view imaged with its own cut
        view_meshes = result.view_cuts(protocol.cameras(original), protocol)
        view_stats = dict(getattr(result.view_cuts, "stats", {}))
    ev = evaluate(original, result.mesh, protocol, reference_images=reference_images,
                  view_meshes=view_meshes)
    return ev, view_stats


_ORIGINAL_SHEETS: dict[str, dict[str, bytes]] = {}


def _sheet_files(job: Job, mesh, reference, images, result: JobResult) -> None:
    """PNGs of :data:`SHEET_VIEWS` for the report: the original's once per model and
    shading (encoded once per process), the result's per job."""
    shading = shading_label(job.protocol.as_dict())
    original = f"images/original__{mesh.content_hash[:12]}__{shading}"
    if original not in _ORIGINAL_SHEETS:
        _ORIGINAL_SHEETS[original] = {f"{original}/view{v:02d}.png": _png(reference[v])
                                      for v in sheet_views(len(reference))}
    result.shared_files.update(_ORIGINAL_SHEETS[original])
    for v in sheet_views(len(images)):
        result.files[f"images/{job.key}/view{v:02d}.png"] = _png(images[v])


def mesh_paths(key: str, model_hash: str) -> tuple[str, str]:
    """Where a job's evaluated mesh and its original lie in the run folder, as GLB:
    ``meshes/<job key>.glb`` and ``meshes/original__<hash12>.glb`` (one per model, named
    by its content hash as the original's views are)."""
    return f"meshes/{key}.glb", f"meshes/original__{model_hash[:12]}.glb"


#: The last original this process encoded, by file name: the pool gives a process jobs of
#: the model it ran last where it can, and one entry bounds the memory (a scan of
#: millions of faces is tens of MB as GLB).
_ORIGINAL_MESHES: dict[str, bytes | str] = {}


def _mesh_files(job: Job, original, simplified, result: JobResult) -> None:
    """The job's evaluated mesh (a view-dependent method's view-independent one) as a
    GLB file, and the original's (encoded once per model in a row), each with
    the normals the evaluation's Gouraud shading uses. A mesh that GLB cannot hold
    (coordinates beyond 32-bit floats) leaves the job ok, without that file, and the
    reason in the record's ``mesh_file_error``."""
    mine, theirs = mesh_paths(job.key, original.content_hash)
    if theirs not in _ORIGINAL_MESHES:
        _ORIGINAL_MESHES.clear()
        _ORIGINAL_MESHES[theirs] = _glb(original, "original")
    data = _glb(simplified, "lod")
    errors = []
    for path, made, files in ((theirs, _ORIGINAL_MESHES[theirs], result.shared_files),
                              (mine, data, result.files)):
        if isinstance(made, bytes):
            files[path] = made
        else:
            errors.append(f"{path}: {made}")
    if errors:
        result.record["mesh_file_error"] = "; ".join(errors)


def _glb(mesh, name: str) -> bytes | str:
    """``mesh`` as GLB bytes with the evaluation's vertex normals, or why not (one
    line)."""
    import warnings

    from bench.io.meshio import glb_bytes

    try:
        with warnings.catch_warnings():  # a face or two collapsing in 32-bit floats
            warnings.simplefilter("ignore")
            return glb_bytes(mesh.replace(normals=mesh.vertex_normals), name)
    except Exception as exc:  # noqa: BLE001 (the job's figures stand; the record says why)
        return " ".join(f"{type(exc).__name__}: {exc}".split()) \
            if not isinstance(exc, BenchError) else " ".join(str(exc).split())


def _artifact_files(job: Job, artifacts: dict, files: dict[str, bytes]) -> list[str]:
    """A method's report images as PNGs beside the job's views (added to ``files``);
    returns their names relative to the run folder, for the record."""
    names = []
    for name, image in artifacts.items():
        path = f"images/{job.key}/artifact-{_slug(name)}.png"
        files[path] = _png(np.asarray(image, dtype=np.uint8))
        names.append(path)
    return names


def _png(image: np.ndarray) -> bytes:
    from PIL import Image

    buffer = io.BytesIO()
    # zlib level 3: half the time of the default 6 for 1 % more bytes on renders
    Image.fromarray(image).save(buffer, format="PNG", compress_level=3)
    return buffer.getvalue()


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
                                    cwd=Path(__file__).parent, timeout=5, check=False).stdout.strip() or None
        except (OSError, subprocess.SubprocessError):
            commit = None
        _ENV = {"versions": versions, "git_commit": commit, "python": platform.python_version(),
                "machine": {"system": platform.system(), "arch": platform.machine(),
                            "cpus": os.cpu_count(), "processor": _cpu_model()}}
    return _ENV


def _environment_of(worker: dict | None) -> dict:
    """:func:`environment` with who ran the job (executor, worker name, host)."""
    return {**environment(), "worker": dict(worker or {})}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


# -- the job process --------------------------------------------------------------------------

#: What a job process runs: read the parent's import path from the connection (as
#: multiprocessing's spawn does, so plug-ins found by the parent are found here), then
#: serve jobs. A plain subprocess rather than a multiprocessing child because a Dask
#: worker runs as a daemonic process, which multiprocessing forbids to have children.
_BOOTSTRAP = """\
import sys
from multiprocessing.connection import Connection
conn = Connection(int(sys.argv[1]))
sys.path[:] = conn.recv()
from bench.run.jobs import serve
serve(conn)
"""


def serve(conn: Connection) -> None:
    """Serve jobs from ``conn`` until told to stop (None) or the parent goes away.

    Runs in a job process. Ctrl-C reaches every process of the terminal's process group;
    here it is ignored, so the supervisor alone decides what becomes of a running job.
    """
    import warnings

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    warnings.simplefilter("ignore")  # per-job warnings are not the user's to read here
    _exit_with_parent()
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        job, cache_dir, worker, mesh = message
        conn.send(run_job(job, Path(cache_dir), worker, mesh,
                          lambda name: conn.send(("phase", name))))


def _exit_with_parent() -> None:
    """End this process when its supervisor dies (a Dask worker killed mid-job), so no
    orphan goes on computing a result nobody will collect."""
    parent = os.getppid()

    def watch():
        while True:
            time.sleep(1.0)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


class JobProcess:
    """A job process and its connection, driven by its supervisor one job at a time.

    :meth:`submit` hands a job over; the supervisor waits on :attr:`conn` (readable when
    the job reports a phase, its result is there or the process died) and calls
    :meth:`collect` (None while the job goes on), and :meth:`timed_out` when
    :meth:`expired` says the phase ran out of time: the method's phase has ``timeout``
    seconds, the others :data:`PHASE_LIMIT`. :meth:`run` does all of that for a
    supervisor with one job process (a Dask worker thread).
    """

    def __init__(self, name: str = ""):
        self.name = name
        parent, child = socket.socketpair()
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-c", _BOOTSTRAP, str(child.fileno())],
                pass_fds=(child.fileno(),), stdin=subprocess.DEVNULL)
        finally:
            child.close()
        self.conn = Connection(parent.detach())
        self.conn.send(list(sys.path))
        self.job: Job | None = None
        self.worker: dict | None = None
        self.phase, self.started = "setup", 0.0  # the running job's phase, since when

    @property
    def usable(self) -> bool:
        """Alive and not ended (a process is ended after a failed job)."""
        return not self.conn.closed and self.process.poll() is None

    def submit(self, job: Job, cache_dir: Path, worker: dict | None = None, mesh=None) -> None:
        self.job, self.worker = job, worker
        self.phase, self.started = "setup", time.monotonic()
        try:
            self.conn.send((job, str(cache_dir), worker, mesh))
        except OSError:
            pass  # a dead process: collect() turns it into a failed record

    def collect(self) -> JobResult | None:
        """Once :attr:`conn` is readable: None when the job only reported a new phase
        (it goes on), else its result: the process's own, or a failed one if the process
        died. A process whose job failed is ended (the supervisor starts a fresh one for
        the next job)."""
        try:
            result = self.conn.recv()
        except (EOFError, OSError):
            result = None
        if isinstance(result, tuple) and len(result) == 2 and result[0] == "phase" and \
                result[1] in PHASES:
            self.phase, self.started = result[1], time.monotonic()
            return None
        job, self.job = self.job, None
        if not isinstance(result, JobResult):
            try:
                code = self.process.wait(timeout=2)  # let a dying process report its code
            except subprocess.TimeoutExpired:
                self.kill()
                code = self.process.returncode
            self.conn.close()
            return failed_result(job, _death(code), self.worker)
        if result.failed:  # its result is in: nothing of the process is worth keeping
            self.kill()
        return result

    def _limit(self, timeout: float) -> float:
        return timeout if self.phase == "method" else PHASE_LIMIT

    def expired(self, timeout: float) -> bool:
        """The running job's phase is past its limit (``timeout`` for the method)."""
        return self.job is not None and time.monotonic() - self.started > self._limit(timeout)

    def timed_out(self, timeout: float) -> JobResult:
        """Kill the process over its running job and fail the job for its time."""
        job, self.job = self.job, None
        self.kill()
        why = f"timed out after {timeout:g} s" if self.phase == "method" else \
            f"its {self.phase} took longer than {PHASE_LIMIT:g} s (the job's limit " \
            "outside the method, which --timeout bounds)"
        return failed_result(job, why, self.worker)

    def run(self, job: Job, cache_dir: Path, timeout: float, worker: dict | None = None,
            mesh=None, cancelled: Callable[[], bool] = lambda: False) -> JobResult | None:
        """Run one job to its end, its time limit, or until ``cancelled()`` (checked every
        second; the process is then killed and None returned)."""
        self.submit(job, cache_dir, worker, mesh)
        while True:
            if self.conn.poll(1.0):
                result = self.collect()
                if result is not None:
                    return result
            elif self.expired(timeout):
                return self.timed_out(timeout)
            elif cancelled():
                self.job = None
                self.kill()
                return None

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()
        self.conn.close()

    def close(self, grace: float = 5.0) -> None:
        """Ask the process to stop after its current job; kill it if it does not."""
        if self.process.poll() is None and not self.conn.closed:
            try:
                self.conn.send(None)
            except OSError:
                pass
            try:
                self.process.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                pass
        self.kill()
