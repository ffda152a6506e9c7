"""The runner end to end: isolation of failing jobs, records, results.csv, the report,
--resume, and the regression gate (bench baseline / bench check).

One small run is shared by the module: a 320-face icosphere simplified by qslim (which
works) and by three plug-ins that crash, hang and raise (tests/plugins/misbehaving.py,
loaded through BENCH_PLUGINS).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.io.meshio import save_mesh
from bench.records.results import CSV_COLUMNS, SCHEMA_VERSION
from conftest import icosphere
from metrics.protocol import PROTOCOL_VERSION

pytestmark = pytest.mark.slow

PLUGINS = Path(__file__).parent / "plugins"


def _bench(*args, cwd, check=None):
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(PLUGINS), env.get("PYTHONPATH", "")])
    env["BENCH_PLUGINS"] = ("method:crash=misbehaving:Crash,method:hang=misbehaving:Hang,"
                            "method:raise=misbehaving:Raise")
    env["BENCH_CACHE"] = str(Path(cwd) / "cache")  # never the user's cache
    proc = subprocess.run([sys.executable, "-m", "bench", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600)
    if check is not None:
        assert proc.returncode == check, proc.stdout + proc.stderr
    return proc


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("runner")
    save_mesh(icosphere(2, name="ico"), root / "ico.obj")  # 320 faces
    # the timeout bounds the method alone: qslim's jobs take seconds (start-up, warm-up,
    # evaluation) and their method milliseconds
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim,crash,hang,raise",
                  "--faces", "100,60", "--timeout", "5", "--jobs", "2", "--out", "out",
                  cwd=root)
    return root, proc


def _records(out: Path) -> dict:
    records = {}
    for path in (out / "records").glob("*.json"):
        r = json.loads(path.read_text())
        records[(r["job"]["label"], r["job"]["target_faces"])] = r
    return records


def test_failures_are_isolated(run):
    root, proc = run
    assert proc.returncode == 1  # some jobs failed, and the run says so
    records = _records(root / "out")
    assert "6 of 8 jobs failed" in proc.stderr, {k: r["error"] for k, r in records.items()}
    assert len(records) == 8
    for faces in (100, 60):
        assert records[("qslim", faces)]["status"] == "ok"
        assert "died (exit code 139)" in records[("crash", faces)]["error"]
        assert "timed out after 5 s" in records[("hang", faces)]["error"]
        assert "deliberate failure" in records[("raise", faces)]["error"]


def test_the_timeout_bounds_the_method_not_the_job(run):
    """qslim's jobs took longer than --timeout 5 in all (a fresh process, the warm-up
    and an evaluation of 24 views) and passed: only their method's milliseconds count."""
    root, _ = run
    r = _records(root / "out")[("qslim", 100)]
    assert r["status"] == "ok" and r["stats"]["wall_seconds"] < 5
    outside = sum(r["seconds"].values()) + r["stats"]["compile_seconds"]
    assert outside > 0.5  # the evaluation is real work: it is not what the 5 s bound


def test_timings_say_where_the_job_went(run):
    """Every stage of an evaluated job is timed, and together they are the job's own
    wall time; the method's stage holds its reported seconds."""
    root, _ = run
    r = _records(root / "out")[("qslim", 100)]
    t = r["timings"]
    assert sorted(t) == sorted(["load", "warm_up", "method", "reference_images",
                                "evaluation", "sheets", "mesh_files", "total"])
    assert all(v >= 0 for v in t.values())
    assert np.isclose(sum(v for k, v in t.items() if k != "total"), t["total"], rtol=1e-6)
    assert t["method"] >= r["stats"]["wall_seconds"]
    assert t["evaluation"] >= sum(r["seconds"].values()) - 1e-6
    failed = _records(root / "out")[("raise", 100)]
    assert sorted(failed["timings"]) == ["load", "warm_up"]  # as far as it got


def test_record_contents(run):
    root, _ = run
    r = _records(root / "out")[("qslim", 100)]
    assert r["schema"] == SCHEMA_VERSION == 2
    assert r["job"]["protocol"]["version"] == PROTOCOL_VERSION
    assert r["method"]["version"] == "1"
    assert len(r["model"]["hash"]) == 40
    assert abs(r["metrics"]["faces"] - 100) <= 2
    assert len(r["per_view"]["d_rms"]) == 24
    assert len(r["silhouette_histogram"]) == 21
    assert np.isclose(sum(r["silhouette_histogram"]), 1.0)
    assert r["environment"]["versions"]["pymeshlab"]
    assert r["stats"]["tri_per_s"] > 0
    assert r["stats"]["compile_seconds"] >= 0  # the warm-up, apart from wall_seconds
    # --jobs 2 and no --threads: the cores shared by the two job processes
    assert r["environment"]["worker"]["threads"] == max(1, len(os.sched_getaffinity(0)) // 2)
    # the evaluated mesh and the original as GLB, for the report's 3D view; none for a
    # failed job
    meshes = root / "out" / "meshes"
    assert (meshes / f"{r['job']['key']}.glb").is_file()
    assert (meshes / f"original__{r['model']['hash'][:12]}.glb").is_file()
    assert sorted(p.name for p in meshes.glob("*.glb")) == sorted(
        [f"original__{r['model']['hash'][:12]}.glb"] +
        [f"{x['job']['key']}.glb" for x in _records(root / "out").values()
         if x["status"] == "ok"])


def test_results_csv_and_report(run):
    root, _ = run
    table = pd.read_csv(root / "out" / "results.csv")
    # the built-in columns, then the registered metrics they do not show, by name, then
    # the intervals over views
    assert list(table.columns) == CSV_COLUMNS + [
        "components_lost", "components_lost_area", "materials_lost", "non_manifold_edges",
        "render_vertices", "welded_vertices", "d_rms_lo", "d_rms_hi", "flip_lo", "flip_hi",
        "ssim_lo", "ssim_hi"]
    assert len(table) == 8
    assert sorted(table.status.unique()) == ["failed", "ok"]
    html = (root / "out" / "index.html").read_text()
    assert "deliberate failure" in html and "data:image" not in html
    assert "src='images/thumbs/" in html  # images are files of the run folder ...
    assert "http://" not in html and "https://" not in html  # ... and nothing is fetched


def test_method_variant_label(run):
    root, _ = run
    proc = _bench("run", "--models", "ico.obj", "--methods", "raise[message=boom]",
                  "--faces", "100", "--jobs", "1", "--out", "variant", cwd=root)
    table = pd.read_csv(root / "variant" / "results.csv")
    assert table.method.tolist() == ["raise[message=boom]"]
    assert proc.returncode == 1


def test_resume_skips_finished_jobs_and_runs_failed_ones_again(run, tmp_path):
    root, _ = run
    out = tmp_path / "out"
    shutil.copytree(root / "out", out)
    shutil.copy(root / "ico.obj", tmp_path / "ico.obj")
    kept = {p.name: p.stat().st_mtime_ns for p in (out / "records").glob("*qslim*.json")}
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim", "--faces", "100,60",
                  "--out", "out", "--resume", "--no-report", cwd=tmp_path)
    assert "0 jobs" in proc.stderr
    assert proc.returncode == 1  # the directory still holds the failed jobs
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim,raise", "--faces",
                  "100,60", "--out", "out", "--resume", "--no-report", cwd=tmp_path)
    assert "2 jobs" in proc.stderr  # the two failed raise jobs, run again
    assert {p.name: p.stat().st_mtime_ns for p in (out / "records").glob("*qslim*.json")} \
        == kept
    records = _records(out)
    assert "deliberate failure" in records[("raise", 100)]["error"]


def test_check_passes_on_itself_and_fails_on_doctored_results(run, tmp_path):
    root, _ = run
    out = tmp_path / "out"
    shutil.copytree(root / "out", out)
    _bench("baseline", str(out), "--out", str(tmp_path / "base.json"), cwd=root, check=0)
    passed = _bench("check", str(out), "--baseline", str(tmp_path / "base.json"), cwd=root,
                    check=0)
    assert "passed" in passed.stderr

    path = next(p for p in (out / "records").glob("*qslim__100*.json"))
    record = json.loads(path.read_text())
    record["metrics"]["d_rms"] *= 1.10  # 10 % worse, beyond the 2 % tolerance
    record["metrics"]["ssim"] *= 1.05   # better
    path.write_text(json.dumps(record))
    failed = _bench("check", str(out), "--baseline", str(tmp_path / "base.json"), cwd=root,
                    check=1)
    lines = failed.stdout.splitlines()
    assert any("d_rms" in line and line.endswith("worse") for line in lines)
    assert any("ssim" in line and line.endswith("better") for line in lines)
    assert "FAILED" in failed.stderr
    # a looser tolerance lets the same change pass
    _bench("check", str(out), "--baseline", str(tmp_path / "base.json"), "--tolerance", "0.2",
           cwd=root, check=0)

    record["method"]["version"] = "2"
    path.write_text(json.dumps(record))
    changed = _bench("check", str(out), "--baseline", str(tmp_path / "base.json"), cwd=root,
                     check=0)
    assert "not comparable" in changed.stdout

    other = next(p for p in (out / "records").glob("*qslim__60*.json"))
    record = json.loads(other.read_text())
    record["status"] = "failed"
    other.write_text(json.dumps(record))
    newly = _bench("check", str(out), "--baseline", str(tmp_path / "base.json"), cwd=root,
                   check=1)
    assert "newly failing" in newly.stdout


@pytest.mark.skipif(shutil.which("chromium") is None, reason="Debian chromium not installed")
def test_report_renders_in_a_browser(run, tmp_path):
    """Open the report as a person would and check the screenshot is a page, not blank."""
    from PIL import Image

    root, _ = run
    shot = tmp_path / "report.png"
    subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                    "--no-first-run", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync",
                    f"--user-data-dir={tmp_path / 'profile'}", "--window-size=1200,2000",
                    f"--screenshot={shot}", (root / "out" / "index.html").as_uri()],
                   capture_output=True, timeout=120, check=True)
    pixels = np.asarray(Image.open(shot).convert("L"), float)
    assert pixels.shape == (2000, 1200)
    assert pixels.std() > 20  # text, tables and images, not an empty page
    assert (pixels < 100).mean() > 0.01  # dark text and figures present
