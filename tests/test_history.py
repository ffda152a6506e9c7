"""`bench history` (quality over commits) and `bench check --format`: records built by
hand, run folders written as `bench run` writes them; nothing is simplified or rendered.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pandas as pd
import pytest

from bench.records.history import load_history
from bench.report.history import write_history
from metrics.protocol import Protocol

ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def _record(method: str, commit: str, day: int, status: str = "ok", **metrics) -> dict:
    return {"schema": 1, "status": status, "error": None if status == "ok" else "boom",
            "job": {"model": "m<b>", "method": method, "params": {}, "label": method,
                    "target_faces": 100, "protocol": Protocol().as_dict()},
            "model": {"name": "m<b>", "hash": "0" * 40, "faces": 1000},
            "method": {"name": method, "version": "1", "view_dependent": False},
            "metrics": metrics if status == "ok" else {},
            "environment": {"git_commit": commit},
            "created": f"2026-11-{day:02d}T10:00:00+00:00"}


def _run(folder, *records):
    (folder / "records").mkdir(parents=True)
    for r in records:
        (folder / "records" / f"{r['job']['method']}.json").write_text(json.dumps(r))
    return folder


@pytest.fixture
def three_runs(tmp_path):
    """Three commits' runs, in a folder whose names sort against their dates: the
    second makes qslim's d_rms 10 % worse, the third makes it good again and fails
    quadric."""
    runs = tmp_path / "artifacts"
    _run(runs / "c", _record("qslim", "c" * 40, 3, d_rms=5.0, ssim=0.9),
         _record("quadric", "c" * 40, 3, d_rms=4.0, ssim=0.9))
    _run(runs / "a", _record("qslim", "a" * 40, 1, d_rms=5.0, ssim=0.9),
         _record("quadric", "a" * 40, 1, d_rms=4.0, ssim=0.9))
    _run(runs / "b", _record("qslim", "b" * 40, 2, d_rms=5.5, ssim=0.9),
         _record("quadric", "b" * 40, 2, d_rms=4.0, ssim=0.95))
    # "c" is the newest: quadric fails there
    (runs / "c" / "records" / "quadric.json").write_text(
        json.dumps(_record("quadric", "c" * 40, 3, status="failed")))
    return runs


def _bench(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *map(str, args)], check=False,
                          capture_output=True, text=True, env=ENV, timeout=120, cwd=cwd)


def test_points_are_ordered_by_date_and_checked_against_the_run_before(three_runs):
    points = load_history([three_runs])
    assert [p.commit[0] for p in points] == ["a", "b", "c"]
    assert [p.date[:10] for p in points] == ["2026-11-01", "2026-11-02", "2026-11-03"]
    first, second, third = points
    assert first.verdict == "first run" and not first.failing
    assert second.failing == {("m<b> | qslim | 100 | flat", "d_rms"): "worse"}
    assert second.verdict == "FAILED (1)"
    # qslim back to 5.0 is better, not a failure; quadric newly failing is
    assert third.failing == {("m<b> | quadric | 100 | flat", "status"): "newly failing"}


def test_a_fixed_baseline_checks_every_run_as_ci_does(three_runs, tmp_path):
    from bench.records.check import make_baseline
    from bench.records.results import load_records

    baseline = make_baseline(load_records(three_runs / "b"))  # the worse qslim
    points = load_history([three_runs], baseline=baseline)
    assert [p.verdict for p in points] == ["FAILED (1)", "passed", "FAILED (1)"]
    # qslim's 5.0 against the baseline's 5.5 is better; quadric's SSIM 0.9 is worse
    assert points[0].failing == {("m<b> | quadric | 100 | flat", "ssim"): "worse"}


def test_the_page_table_and_figures(three_runs, tmp_path):
    out = tmp_path / "history"
    points = load_history([three_runs])
    page = write_history(points, out, ["d_rms", "ssim"])
    text = page.read_text()
    assert "m&lt;b&gt;" in text and "m<b>" not in text  # names are escaped
    assert text.count("<tr") == 1 + 3  # a row per run
    assert text.count("FAILED (1)") == 2
    svgs = sorted((out / "images" / "plots").glob("*.svg"))
    assert len(svgs) == 1 and f"images/plots/{svgs[0].name}" in text  # one (model, budget)
    table = pd.read_csv(out / "history.csv")
    assert len(table) == 2 * 2 + 2 * 2 + 1 * 2  # (runs' ok jobs) x (d_rms, ssim)
    marked = table[table["mark"].notna()]
    assert marked[["run", "method", "metric", "value", "mark"]].values.tolist() == \
        [[1, "qslim", "d_rms", 5.5, "worse"]]


def test_the_command(three_runs, tmp_path):
    proc = _bench("history", three_runs, "--out", tmp_path / "h", "--metrics", "d_rms")
    assert proc.returncode == 0, proc.stderr
    assert "3 runs, 2 that bench check would have failed" in proc.stderr
    assert (tmp_path / "h" / "index.html").is_file()


@pytest.mark.parametrize("args, message", [
    (["--metrics", "d_rmss"], "--metrics: no metric 'd_rmss'; did you mean 'd_rms'?"),
    (["--out", "RUN"], "that is a run folder"),
    (["--tolerance", "nan"], "--tolerance must be a finite number >= 0"),
])
def test_bad_arguments_are_one_line_errors(three_runs, tmp_path, args, message):
    args = [str(three_runs / "a") if a == "RUN" else a for a in args]
    before = sorted(p.name for p in (three_runs / "a").iterdir())
    proc = _bench("history", three_runs, *args)
    assert proc.returncode == 2
    (line,) = proc.stderr.splitlines()
    assert line.startswith("bench: error: ") and message in line
    assert sorted(p.name for p in (three_runs / "a").iterdir()) == before  # nothing written


def test_a_folder_without_runs_is_a_one_line_error(tmp_path):
    (tmp_path / "empty").mkdir()
    proc = _bench("history", tmp_path / "empty", "--out", tmp_path / "h")
    assert proc.returncode == 2
    assert proc.stderr.splitlines() == [
        (f"bench: error: {tmp_path / 'empty'}: no run folder (a folder with records/) in it "
        "or directly under it; give bench run --out folders")]


def _check(three_runs, tmp_path, fmt):
    baseline = tmp_path / "base.json"
    made = _bench("baseline", three_runs / "a", "--out", baseline)
    assert made.returncode == 0, made.stderr
    return _bench("check", three_runs / "b", "--baseline", baseline, "--format", fmt)


def test_check_as_markdown(three_runs, tmp_path):
    proc = _check(three_runs, tmp_path, "markdown")
    assert proc.returncode == 1
    lines = proc.stdout.splitlines()
    assert lines[0] == "**bench check: FAILED (1 regressions, tolerance 0.02)**"
    assert "| job | metric | baseline | current | change | mark |" in lines
    assert r"| m&lt;b&gt; \| qslim \| 100 \| flat | d\_rms | 5 | 5.5 | +10.00 % | **worse** |" \
        in lines
    assert r"| m&lt;b&gt; \| quadric \| 100 \| flat | ssim | 0.9 | 0.95 | +5.56 % | better |" \
        in lines


def test_check_as_github_action_benchmark_entries(three_runs, tmp_path):
    smaller = json.loads(_check(three_runs, tmp_path, "json").stdout)
    bigger = json.loads(_check(three_runs, tmp_path, "json-bigger").stdout)
    assert {e["name"]: (e["value"], e["extra"]) for e in smaller} == {
        "m<b> | qslim | 100 | flat: d_rms": (5.5, "baseline 5, worse"),
        "m<b> | quadric | 100 | flat: d_rms": (4.0, "baseline 4, same")}
    assert {e["name"]: e["value"] for e in bigger} == {
        "m<b> | qslim | 100 | flat: ssim": 0.9, "m<b> | quadric | 100 | flat: ssim": 0.95}
    assert {e["unit"] for e in smaller} == {"luminance (0-255)"}


def test_runs_of_one_commit_get_distinct_labels_in_readable_type(three_runs, tmp_path):
    from bench.report.history import run_labels

    # the same commit run again on the same day (a re-run, another machine)
    _run(three_runs / "d", _record("qslim", "c" * 40, 3, d_rms=5.0, ssim=0.9))
    points = load_history([three_runs])
    labels = run_labels(points)
    assert len(set(labels)) == len(points) == 4
    assert [p.commit[0] for p in points].count("c") == 2
    out = tmp_path / "history"
    write_history(points, out, ["d_rms"])
    svg = next((out / "images" / "plots").glob("*.svg")).read_text()
    # tick labels are text (svg.fonttype none): every run's number, no type under 9 px
    for i in range(4):
        assert f"#{i} " in svg
    sizes = [float(s) for s in re.findall(r"font-size:\s*([0-9.]+)px", svg)]
    assert sizes and min(sizes) >= 9
