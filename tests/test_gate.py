"""The regression gate cannot be talked out of failing: a tolerance that is NaN, infinite
or negative is refused, a NaN or infinite value on either side is a failure of its own
(``not finite``), and a baseline file that is not a baseline is a one-line error.
Baselines and records are built by hand; nothing is simplified or rendered.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import pytest

from bench.core.errors import InputError
from bench.records.check import FAILING_MARKS, compare, load_baseline, make_baseline
from metrics.protocol import Protocol

ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def _record(**metrics) -> dict:
    return {"schema": 1, "status": "ok", "error": None,
            "job": {"model": "m", "method": "q", "params": {}, "label": "q",
                    "target_faces": 100, "protocol": Protocol().as_dict()},
            "model": {"name": "m", "hash": "0" * 40, "faces": 1000},
            "method": {"name": "q", "version": "1", "view_dependent": False},
            "metrics": metrics}


def _bench(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *map(str, args)], check=False,
                          capture_output=True, text=True, env=ENV, timeout=120)


def _marks(before: dict, after: dict, tolerance: float = 0.02) -> dict:
    rows = compare(make_baseline([_record(**before)]), make_baseline([_record(**after)]),
                   tolerance)
    return {r.metric: r.mark for r in rows}


@pytest.mark.parametrize("tolerance", [math.nan, math.inf, -math.inf, -1, -1e-9])
def test_a_tolerance_that_would_pass_or_fail_anything_is_refused(tolerance):
    with pytest.raises(InputError, match="--tolerance must be a finite number >= 0"):
        compare(make_baseline([_record(d_rms=1.0)]), make_baseline([_record(d_rms=30.0)]),
                tolerance)


def test_identical_values_are_same_at_zero_tolerance():
    assert _marks({"d_rms": 3.0}, {"d_rms": 3.0}, 0.0) == {"d_rms": "same"}


def test_another_model_under_the_same_name_is_not_comparable():
    """A model the engine makes (bunny-textured-815) changes with the engine: its
    results, even a baseline's, are of another input, neither worse nor better."""
    old, new = _record(d_rms=3.0), _record(d_rms=4.0)
    new["model"]["hash"] = "1" * 40
    rows = compare(make_baseline([old]), make_baseline([new]))
    assert [(r.metric, r.baseline, r.current, r.mark) for r in rows] == [
        ("model", "0" * 12, "1" * 12, "not comparable")]
    baseline = make_baseline([old])
    del baseline["entries"][next(iter(baseline["entries"]))]["model_hash"]  # an older one
    assert {r.mark for r in compare(baseline, make_baseline([new]))} == {"worse"}


@pytest.mark.parametrize("before, after", [
    ({"d_rms": math.nan}, {"d_rms": 5.0}),    # NaN in the baseline is never "better"
    ({"d_rms": 5.0}, {"d_rms": math.nan}),    # a metric turning NaN is not "not comparable"
    ({"d_rms": math.nan}, {"d_rms": math.nan}),
    ({"ssim": 0.9}, {"ssim": math.inf}),      # higher is better, but infinity is no gain
    ({"d_rms": math.inf}, {"d_rms": 5.0}),
    ({"d_rms": math.nan}, {}),
])
def test_a_value_that_is_not_finite_fails_the_gate(before, after):
    (metric,) = before
    marks = _marks(before, after)
    assert marks[metric] == "not finite"
    assert "not finite" in FAILING_MARKS


def test_the_gate_refuses_bad_tolerances_on_the_command_line(tmp_path):
    for value in ("nan", "inf", "-1", "abc", ""):
        proc = _bench("check", tmp_path, "--baseline", tmp_path / "b.json",
                      f"--tolerance={value}")
        assert proc.returncode == 2, (value, proc.stderr)
        assert proc.stderr.splitlines() == [
            ("bench: error: --tolerance must be a finite number >= 0 (a fraction, e.g. 0.02), "
             f"got '{value}'")]


BAD_BASELINES = {
    "not json": ("{\"schema\": 1,", "cannot read baseline"),
    "a list": ("[]", "not a baseline: expected a JSON object, got list"),
    "no schema": ("{\"entries\": {}}", "baseline schema None is not 1"),
    "no entries": ("{\"schema\": 1}", "not a baseline: no 'entries' object"),
    "entries a list": ("{\"schema\": 1, \"entries\": []}", "no 'entries' object"),
    "empty": ("{\"schema\": 1, \"entries\": {}}", "'entries' is empty"),
    "entry a string": ("{\"schema\": 1, \"entries\": {\"a\": \"x\"}}", "entry 'a' is not an object"),
    "no status": ("{\"schema\": 1, \"entries\": {\"a\": {\"metrics\": {}}}}", "'status' is None"),
    "metric a string": (json.dumps({"schema": 1, "entries": {"a": {
        "status": "ok", "method_version": "1", "protocol_version": "1",
        "metrics": {"d_rms": "5"}}}}), "metric 'd_rms' is '5', not a number"),
    "no metrics": (json.dumps({"schema": 1, "entries": {"a": {
        "status": "ok", "method_version": "1", "protocol_version": "1"}}}), "no 'metrics'"),
    "binary": ("\udcff\x00", "cannot read baseline"),
}


@pytest.mark.parametrize("case", list(BAD_BASELINES))
def test_a_malformed_baseline_is_a_one_line_error(tmp_path, case):
    text, message = BAD_BASELINES[case]
    path = tmp_path / "b.json"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    with pytest.raises(InputError) as info:
        load_baseline(path)
    assert message in str(info.value)
    assert "\n" not in str(info.value)


def test_bench_baseline_refuses_what_would_gate_nothing(tmp_path):
    """A baseline of NaN, or of no jobs, would pass every run; a baseline that cannot be
    written is one line, not a traceback, and leaves nothing behind."""
    (tmp_path / "run" / "records").mkdir(parents=True)
    empty = _bench("baseline", tmp_path / "run", "--out", tmp_path / "b.json")
    assert empty.returncode == 2 and empty.stderr.splitlines() == [
        f"bench: error: {tmp_path / 'run'}: no records to make a baseline of"]
    (tmp_path / "run" / "records" / "a.json").write_text(json.dumps(_record(d_rms=math.nan)))
    nan = _bench("baseline", tmp_path / "run", "--out", tmp_path / "b.json")
    assert nan.returncode == 2 and nan.stderr.splitlines() == [
        (f"bench: error: {tmp_path / 'run'}: job 'm | q | 100 | flat' has d_rms = nan; a "
         "baseline needs finite values (re-run that job)")]
    assert not (tmp_path / "b.json").exists()

    (tmp_path / "run" / "records" / "a.json").write_text(json.dumps(_record(d_rms=1.0)))
    (tmp_path / "taken").mkdir()
    into_dir = _bench("baseline", tmp_path / "run", "--out", tmp_path / "taken")
    assert into_dir.returncode == 2, into_dir.stderr
    assert into_dir.stderr.splitlines() == [
        f"bench: error: {tmp_path / 'taken'}: cannot write the baseline (Is a directory)"]
    assert list((tmp_path / "taken").iterdir()) == [] and len(list(tmp_path.iterdir())) == 2
