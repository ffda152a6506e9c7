"""Faults in the local pool: a job process killed with SIGKILL (what the kernel's
out-of-memory killer sends) or out of memory (MemoryError) mid-job is one failed record
with a one-line reason and the run goes on in a fresh process; a whole run killed with
SIGKILL keeps every finished record, and ``--resume`` then runs exactly the rest.

Jobs are a 320-face icosphere under a small protocol; the faulty methods are in
tests/plugins/misbehaving.py, loaded through BENCH_PLUGINS.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bench.io.meshio import save_mesh
from bench.records.results import evaluated
from bench.run.jobs import Job
from bench.run.runner import execute, remaining
from conftest import icosphere
from metrics.protocol import Protocol

pytestmark = pytest.mark.slow

PLUGINS = Path(__file__).parent / "plugins"
SMALL = Protocol(resolution=64, hausdorff_samples=2000)
FAULTY = ("method:kill-self=misbehaving:KillSelf,method:out-of-memory=misbehaving:OutOfMemory,"
          "method:sleep=misbehaving:Sleep")


@pytest.fixture
def ico(tmp_path, monkeypatch) -> str:
    monkeypatch.setenv("BENCH_CACHE", str(tmp_path / "cache"))  # never the user's cache
    monkeypatch.setenv("BENCH_PLUGINS", FAULTY)
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(PLUGINS),
                                                      os.environ.get("PYTHONPATH", "")]))
    path = tmp_path / "ico.obj"
    save_mesh(icosphere(2, name="ico"), path)
    return str(path)


def _records(run_dir: Path) -> dict:
    return {p.stem: json.loads(p.read_text()) for p in (run_dir / "records").glob("*.json")}


def test_a_killed_or_out_of_memory_job_fails_alone(ico, tmp_path):
    """One process for all jobs: each fault fails its own job, and the job after it
    runs in a fresh process and succeeds."""
    killed = Job(ico, "kill-self", 100, {"marker": str(tmp_path / "killed.txt")}, SMALL)
    starved = Job(ico, "out-of-memory", 100, {}, SMALL)
    fine = [Job(ico, "qslim", faces, {}, SMALL) for faces in (100, 60)]
    execute([killed, fine[0], starved, fine[1]], tmp_path / "out", workers=1, timeout=300,
            progress=False)
    records = _records(tmp_path / "out")
    assert len(records) == 4
    assert records[killed.key]["status"] == "failed"
    assert records[killed.key]["error"] == ("job process was killed by SIGKILL (the "
                                            "out-of-memory killer sends it)")
    assert records[starved.key]["status"] == "failed"
    error = records[starved.key]["error"]
    assert "MemoryError" in error and "\n" not in error
    for job in fine:
        assert records[job.key]["status"] == "ok", records[job.key]["error"]
    # --resume runs the two failed jobs again and leaves the finished ones as they are;
    # the killed one's second attempt succeeds (kill-self dies only on its first)
    out = tmp_path / "out"
    kept = {job.key: (out / "records" / f"{job.key}.json").stat().st_mtime_ns for job in fine}
    todo = remaining([killed, fine[0], starved, fine[1]], out)
    assert [job.key for job in todo] == [killed.key, starved.key]
    execute(todo, out, workers=1, timeout=300, progress=False)
    again = _records(out)
    assert evaluated(again[killed.key]), again[killed.key]["error"]
    assert again[starved.key]["status"] == "failed"
    assert {job.key: (out / "records" / f"{job.key}.json").stat().st_mtime_ns
            for job in fine} == kept
    assert all(again[job.key] == records[job.key] for job in fine)


def test_a_run_killed_with_sigkill_is_resumed(ico, tmp_path):
    """SIGKILL to `bench run` itself: its job processes end, every finished record stays
    whole, and `bench run --resume` runs exactly the jobs without one, leaving the others'
    records untouched."""
    out = tmp_path / "out"
    marker = tmp_path / "attempts.txt"
    args = [sys.executable, "-m", "bench", "run", "--models", ico, "--methods",
            f"qslim,sleep[seconds=600,once=true,marker={marker}]", "--faces", "100,60",
            "--jobs", "1", "--timeout", "900", "--out", str(out), "--no-report"]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=dict(os.environ))
    deadline = time.monotonic() + 240
    while not marker.exists():  # the sleeper started: the qslim jobs before it are done
        assert time.monotonic() < deadline and proc.poll() is None, proc.stderr.read()
        time.sleep(0.2)
    sleeper = int(marker.read_text().split()[0])
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    proc.stderr.close()
    deadline = time.monotonic() + 30
    while Path(f"/proc/{sleeper}").exists() and time.monotonic() < deadline:
        time.sleep(0.2)  # the job process watches its parent and ends with it
    state = Path(f"/proc/{sleeper}/stat")
    assert not state.exists() or state.read_text().rsplit(")", 1)[1].split()[0] == "Z"
    before = _records(out)
    assert before and all(evaluated(r) for r in before.values())
    assert not list((out / "records").glob("*.tmp*"))  # no half-written record
    mtimes = {p.name: p.stat().st_mtime_ns for p in (out / "records").iterdir()}

    done = subprocess.run(args + ["--resume"], capture_output=True, text=True, timeout=600,
                          check=False)
    assert done.returncode == 0, done.stderr
    after = _records(out)
    assert len(after) == 4 and all(evaluated(r) for r in after.values())
    for name, mtime in mtimes.items():
        assert (out / "records" / name).stat().st_mtime_ns == mtime
