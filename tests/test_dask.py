"""`bench run --executor dask` on a real distributed.LocalCluster (worker processes on
this machine): the same records as the local pool, a lost worker retried then one
record, an interrupted run resumed, a worker that cannot render failing clearly, and
the one-line errors of the command line.

Jobs are a 320-face icosphere from a file (so the client ships the mesh) evaluated under
a small protocol (64² images, 2,000 Hausdorff samples): the executors are under test
here, not the metrics. The test-only methods (sleep, kill-worker) are in
tests/plugins/misbehaving.py, loaded through BENCH_PLUGINS; the worker processes and
their job processes inherit this process's environment and import path.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numba
import pytest

from bench.io.meshio import save_mesh
from bench.records.results import evaluated
from bench.run.jobs import Job, JobResult, store_result
from bench.run.runner import execute, remaining
from conftest import icosphere
from metrics.protocol import Protocol

PLUGINS = Path(__file__).parent / "plugins"
SMALL = Protocol(resolution=64, hausdorff_samples=2000)


@pytest.fixture
def ico(tmp_path, monkeypatch) -> str:
    """The model file, with the environment the cluster's processes inherit."""
    monkeypatch.setenv("BENCH_CACHE", str(tmp_path / "cache"))  # never the user's cache
    monkeypatch.setenv("BENCH_PLUGINS", "method:sleep=misbehaving:Sleep,"
                       "method:kill-worker=misbehaving:KillWorker")
    monkeypatch.syspath_prepend(str(PLUGINS))
    path = tmp_path / "ico.obj"
    save_mesh(icosphere(2, name="ico"), path)
    return str(path)


def _records(run_dir: Path) -> dict:
    return {p.stem: json.loads(p.read_text()) for p in (run_dir / "records").glob("*.json")}


def _gone(pid: int, within: float = 10.0) -> bool:
    """Whether process ``pid`` has ended (or is a zombie) within ``within`` seconds."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state == "Z":
            return True
        time.sleep(0.2)
    return False


def _wait_for(predicate, within: float, what: str):
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.2)
    raise AssertionError(f"gave up waiting for {what} after {within:g} s")


def test_local_pool_and_dask_give_identical_records(ico, tmp_path):
    jobs = [Job(ico, "qslim", faces, {}, SMALL) for faces in (100, 60)]
    execute(jobs, tmp_path / "local", workers=1, timeout=300, progress=False)
    records = execute(jobs, tmp_path / "dask", workers=2, timeout=300, progress=False,
                      executor="dask", threads=1)
    assert len(records) == 2
    local, dask = _records(tmp_path / "local"), _records(tmp_path / "dask")
    assert sorted(local) == sorted(dask) == sorted(j.key for j in jobs)
    for key in local:
        a, b = local[key], dask[key]
        assert a["status"] == b["status"] == "ok", (a["error"], b["error"])
        assert a["metrics"] == b["metrics"]
        assert a["per_view"] == b["per_view"]
        assert a["silhouette_histogram"] == b["silhouette_histogram"]
        assert a["model"] == b["model"]
        assert a["environment"]["worker"]["executor"] == "local"
        # one job process: all the cores (numba's pool, at most); on Dask as told
        assert a["environment"]["worker"]["threads"] == min(len(os.sched_getaffinity(0)),
                                                           numba.config.NUMBA_NUM_THREADS)
        assert b["environment"]["worker"]["threads"] == 1
        worker = b["environment"]["worker"]
        assert worker["executor"] == "dask" and worker["name"] in ("0", "1")
        assert worker["address"].startswith("tcp://") and worker["attempts"] == 1
    # the client wrote the images the workers sent back, byte for byte the local pool's
    images = sorted(p.relative_to(tmp_path / "local")
                    for p in (tmp_path / "local" / "images").rglob("*.png"))
    assert len(images) == 4 + 2 * 4  # the original's 4 sheet views, then 4 per job
    for name in images:
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "local" / name).read_bytes()
    # ... and the meshes (GLB) for the 3D view: the original's once, then one per job
    meshes = sorted(p.relative_to(tmp_path / "local")
                    for p in (tmp_path / "local" / "meshes").rglob("*.glb"))
    assert len(meshes) == 1 + 2
    for name in meshes:
        assert (tmp_path / "dask" / name).read_bytes() == (tmp_path / "local" / name).read_bytes()
    assert not list((tmp_path / "dask").rglob("*.tmp"))  # atomic writes left nothing behind


@pytest.mark.slow
def test_worker_killed_mid_job_is_retried_and_the_rest_completes(ico, tmp_path):
    """SIGKILL to the worker running a job: the scheduler runs the job again on another
    worker, where it finishes; the record says it took two attempts; nothing is lost."""
    marker = tmp_path / "attempts.txt"
    sleeper = Job(ico, "sleep", 100, {"seconds": "600", "marker": str(marker), "once": "true"},
                  SMALL)
    jobs = [sleeper, Job(ico, "qslim", 100, {}, SMALL), Job(ico, "qslim", 60, {}, SMALL)]
    killed = {}

    def kill_the_sleepers_worker():
        line = _wait_for(lambda: marker.exists() and marker.read_text().split("\n")[0],
                         240, "the sleeping job to start")
        killed["job"], killed["worker"] = map(int, line.split())
        os.kill(killed["worker"], signal.SIGKILL)

    killer = threading.Thread(target=kill_the_sleepers_worker, daemon=True)
    killer.start()
    execute(jobs, tmp_path / "out", workers=2, timeout=900, progress=False, executor="dask")
    killer.join(timeout=1)
    assert killed, "the worker was never killed"

    records = _records(tmp_path / "out")
    assert sorted(records) == sorted(j.key for j in jobs)  # nothing lost
    assert all(evaluated(r) for r in records.values()), [r["error"] for r in records.values()]
    assert records[sleeper.key]["environment"]["worker"]["attempts"] == 2
    attempts = [tuple(map(int, line.split())) for line in marker.read_text().splitlines()]
    assert len(attempts) == 2  # (job process, worker) of each attempt
    assert attempts[0][1] == killed["worker"] != attempts[1][1]
    assert _gone(killed["job"])  # the killed worker's job process did not live on


@pytest.mark.slow
def test_job_that_keeps_losing_its_worker_fails_once(ico, tmp_path):
    """A job that kills every worker it is given: retried the allowed number of times,
    then one failed record that says so; the other job completes."""
    from bench.run.cluster import LOST_WORKER_RETRIES

    killer = Job(ico, "kill-worker", 100, {}, SMALL)
    other = Job(ico, "qslim", 100, {}, SMALL)
    execute([killer, other], tmp_path / "out", workers=2, timeout=900, progress=False,
            executor="dask")
    records = _records(tmp_path / "out")
    assert sorted(records) == sorted([killer.key, other.key])
    lost = records[killer.key]
    assert lost["status"] == "failed"
    assert lost["error"].startswith(f"lost its Dask worker {LOST_WORKER_RETRIES + 1} times")
    assert f"allows {LOST_WORKER_RETRIES} retries" in lost["error"]
    assert lost["environment"]["worker"]["attempts"] == LOST_WORKER_RETRIES + 1
    assert records[other.key]["status"] == "ok", records[other.key]["error"]


@pytest.mark.slow
def test_job_past_the_timeout_fails_and_its_worker_goes_on(ico, tmp_path):
    """Dask has no per-task timeout: the worker kills the job's process at --timeout,
    the job gets one failed record, and the same worker runs the next job."""
    marker = tmp_path / "attempts.txt"
    late = Job(ico, "sleep", 100, {"seconds": "600", "marker": str(marker)}, SMALL)
    after = Job(ico, "qslim", 100, {}, SMALL)
    execute([late, after], tmp_path / "out", workers=1, timeout=10, progress=False,
            executor="dask")
    records = _records(tmp_path / "out")
    assert records[late.key]["status"] == "failed"
    assert records[late.key]["error"] == "timed out after 10 s"
    assert records[after.key]["status"] == "ok", records[after.key]["error"]
    assert records[late.key]["environment"]["worker"]["name"] == \
        records[after.key]["environment"]["worker"]["name"]
    (line,) = marker.read_text().splitlines()  # one attempt: a timeout is not retried
    assert _gone(int(line.split()[0]))


@pytest.mark.slow
def test_interrupted_dask_run_is_resumed(ico, tmp_path):
    """Ctrl-C during a Dask run keeps every finished record and stops the running jobs'
    processes; --resume (here with the local pool) runs exactly the rest."""
    # one marker per slow job: "once" means the first attempt at *that* job sleeps (a
    # shared marker let the second job skip its sleep and finish before the Ctrl-C)
    markers = [tmp_path / f"attempts-{faces}.txt" for faces in (100, 60)]
    finished = [Job(ico, "qslim", faces, {}, SMALL) for faces in (100, 60)]
    slow = [Job(ico, "sleep", faces, {"seconds": "600", "marker": str(marker), "once": "true"},
                SMALL) for faces, marker in zip((100, 60), markers)]
    out = tmp_path / "out"

    def interrupt_when_the_slow_jobs_run():
        _wait_for(lambda: len(_records(out)) == 2 if (out / "records").is_dir() else False,
                  240, "the quick jobs' records")
        _wait_for(lambda: all(m.exists() and m.read_text().count("\n") == 1 for m in markers),
                  240, "both slow jobs to start")
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, to this process

    threading.Thread(target=interrupt_when_the_slow_jobs_run, daemon=True).start()
    # Ctrl-C raises KeyboardInterrupt here even when the tests run where SIGINT is
    # ignored (a shell's background job), as it does in a terminal
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            execute(finished + slow, out, workers=2, timeout=900, progress=False,
                    executor="dask")
    finally:
        signal.signal(signal.SIGINT, previous)
    before = _records(out)
    assert sorted(before) == sorted(j.key for j in finished)
    assert all(evaluated(r) for r in before.values())
    for marker in markers:  # the interrupted jobs' processes ended
        (line,) = marker.read_text().splitlines()
        assert _gone(int(line.split()[0]))
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / "records").iterdir()}

    todo = remaining(finished + slow, out)
    assert todo == slow
    execute(todo, out, workers=2, timeout=300, progress=False)  # the local pool
    after = _records(out)
    assert sorted(after) == sorted(j.key for j in finished + slow)
    assert all(evaluated(r) for r in after.values())
    for name, mtime in mtimes.items():  # the finished records were not run again
        assert (out / "records" / name).stat().st_mtime_ns == mtime
    for marker in markers:  # each slow job: interrupted, then resumed
        assert len(marker.read_text().splitlines()) == 2


@pytest.mark.slow
def test_worker_that_cannot_render_gives_a_clear_failed_record(ico, tmp_path):
    """A worker whose OpenGL is unusable (no EGL) fails its job with a one-line reason
    that names the problem and the fix, in seconds; the run does not hang."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None, env={"PYOPENGL_PLATFORM": "invalid"}) as cluster:
        start = time.monotonic()
        records = execute([Job(ico, "qslim", 100, {}, SMALL)], tmp_path / "out", timeout=600,
                          progress=False, executor="dask", scheduler=cluster.scheduler_address)
        elapsed = time.monotonic() - start
    (record,) = records
    assert record["status"] == "failed"
    assert record["error"].startswith("cannot create an EGL rendering context")
    assert "PYOPENGL_PLATFORM=invalid" in record["error"]
    assert "install libegl1" in record["error"] and "\n" not in record["error"]
    assert record["environment"]["worker"]["name"] == "0"
    assert elapsed < 300


def _bench(*args, cwd, env=None):
    full = dict(os.environ, **(env or {}))
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=cwd, env=full,
                          capture_output=True, text=True, timeout=300, check=False)


@pytest.mark.parametrize("case", ["no distributed", "scheduler without dask"])
def test_command_line_errors_are_one_line(ico, tmp_path, case):
    args = ["run", "--models", ico, "--methods", "qslim", "--faces", "100", "--out",
            str(tmp_path / "out")]
    path = list(sys.path)
    if case == "no distributed":  # an import path where distributed cannot be imported
        blocker = tmp_path / "blocker" / "distributed"
        blocker.mkdir(parents=True)
        (blocker / "__init__.py").write_text("raise ImportError('not installed here')\n")
        path.insert(0, str(blocker.parent))
        args += ["--executor", "dask"]
        expected = "--executor dask needs the distributed package: pip install"
    else:
        args += ["--scheduler", "tcp://127.0.0.1:9"]
        expected = "--scheduler is the address of a Dask scheduler: it needs --executor dask"
    proc = _bench(*args, cwd=tmp_path, env={"PYTHONPATH": os.pathsep.join(path)})
    assert proc.returncode == 2, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if line.startswith("bench: error:")]
    assert len(errors) == 1 and expected in errors[0], proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out" / "records").exists()


def test_unreachable_scheduler_is_a_clear_error_soon(ico, tmp_path, monkeypatch):
    from bench.core.errors import ClusterError
    from bench.run import cluster

    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", 2)  # 10 s in use; the same path
    start = time.monotonic()
    with pytest.raises(ClusterError, match=r"^cannot reach the Dask scheduler at "
                       r"tcp://127\.0\.0\.1:9 \(Timed out .* after 2 s\); start one"):
        execute([Job(ico, "qslim", 100, {}, SMALL)], tmp_path / "out", progress=False,
                executor="dask", scheduler="tcp://127.0.0.1:9")  # nothing listens there
    assert time.monotonic() - start < 30
    assert not (tmp_path / "out" / "records").exists()


def test_results_are_written_inside_the_run_folder_only(tmp_path):
    job = Job("ico", "qslim", 100)
    record = {"schema": 1, "job": job.as_dict(), "status": "ok"}
    path = store_result(tmp_path, JobResult(job, record, {"images/a/view00.png": b"png"}))
    assert json.loads(path.read_text())["status"] == "ok"
    assert (tmp_path / "images" / "a" / "view00.png").read_bytes() == b"png"
    for name in ("../outside.png", "/tmp/outside.png"):
        with pytest.raises(ValueError, match="inside the run folder"):
            store_result(tmp_path / "run", JobResult(job, record, {name: b"x"}))
    assert not (tmp_path / "outside.png").exists()
    assert not (tmp_path / "run" / "records").exists()  # no record without its files
