"""Intervals over views, paired tests, Holm's correction, the claims' classes and
``bench compare``: small hand-computed cases, scipy as the oracle where it is one, and
records written by hand (nothing is simplified or rendered)."""

from __future__ import annotations

import copy
import csv
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import bootstrap

from bench.commands.cli import main
from bench.records.check import FAILING_MARKS, baseline_problem, compare, make_baseline
from bench.records.claims import Claim, evaluate_claim
from bench.records.results import (
    SCHEMA_VERSION,
    interval_table,
    load_record,
    load_records,
    write_record,
    write_table,
)
from bench.records.stats import (
    SEED,
    compute_intervals,
    holm,
    interval,
    paired,
    record_intervals,
    sign_test,
)
from bench.records.suites import SUITES
from conftest import made_up_record

RNG = np.random.default_rng(46)
#: 24 per-view values, skewed as image errors are.
VIEWS = list(RNG.gamma(2.0, 3.0, size=24))


def _rms(x, axis=-1):
    return np.sqrt(np.mean(np.square(x), axis=axis))


# -- intervals ---------------------------------------------------------------------------

def test_identical_views_give_the_value_itself():
    assert interval([3.0] * 24, "d_rms") == (3.0, 3.0)
    assert interval([0.5] * 6, "flip") == (0.5, 0.5)


def test_too_few_or_broken_views_give_no_interval():
    assert interval([1.0], "d_rms") is None
    assert interval([1.0, math.nan, 2.0], "ssim") is None


def test_d_rms_bootstraps_the_root_mean_square_of_the_views_and_others_the_mean():
    lo, hi = interval(VIEWS, "d_rms")
    oracle = bootstrap((np.asarray(VIEWS),), _rms, method="BCa", vectorized=True,
                       rng=np.random.default_rng(SEED)).confidence_interval
    assert (lo, hi) == (oracle.low, oracle.high)
    assert lo < _rms(np.asarray(VIEWS)) < hi  # the interval is of the reported value
    mean = bootstrap((np.asarray(VIEWS),), np.mean, method="BCa",
                     rng=np.random.default_rng(SEED)).confidence_interval
    assert interval(VIEWS, "ssim") == pytest.approx((mean.low, mean.high), rel=1e-12)
    assert interval(VIEWS, "ssim") != (lo, hi)  # not the same statistic


def test_intervals_are_deterministic():
    assert interval(VIEWS, "d_rms") == interval(list(VIEWS), "d_rms")
    record = _consistent(made_up_record("a"), VIEWS)
    assert compute_intervals(record["metrics"], record["per_view"]) == \
        compute_intervals(record["metrics"], record["per_view"])


def test_an_interval_is_only_of_a_value_its_views_make():
    metrics = {"d_rms": float(_rms(np.asarray(VIEWS))), "ssim": 0.9}
    got = compute_intervals(metrics, {"d_rms": VIEWS, "ssim": VIEWS})  # ssim: not their mean
    assert list(got) == ["d_rms"]


def _consistent(record: dict, views, metric: str = "d_rms") -> dict:
    """``record`` with ``metric``'s per-view values ``views`` and its value made of them."""
    record = copy.deepcopy(record)
    x = np.asarray(views, dtype=float)
    record["per_view"][metric] = [float(v) for v in x]
    record["metrics"][metric] = float(_rms(x) if metric == "d_rms" else x.mean())
    return record


def test_an_old_record_without_intervals_still_reports_them(tmp_path):
    old = _consistent(made_up_record("a"), VIEWS)
    assert old["schema"] == 1 and "intervals" not in old
    new = copy.deepcopy(old)
    new["schema"] = SCHEMA_VERSION
    new["intervals"] = compute_intervals(new["metrics"], new["per_view"])
    new["job"]["label"] = new["job"]["method"] = "b"
    write_record(tmp_path / "records" / "a.json", old)
    write_record(tmp_path / "records" / "b.json", new)
    records = load_records(tmp_path)
    assert record_intervals(records[0]) == records[1]["intervals"]
    write_table(tmp_path, records)
    rows = list(csv.DictReader((tmp_path / "results.csv").open()))
    assert [r["method"] for r in rows] == ["a", "b"]
    lo, hi = interval(VIEWS, "d_rms")
    for r in rows:
        assert float(r["d_rms_lo"]) == pytest.approx(lo, rel=1e-5)
        assert float(r["d_rms_hi"]) == pytest.approx(hi, rel=1e-5)
    table = interval_table([made_up_record("c", status="failed")])
    assert "d_rms_lo" not in table.columns  # nothing to show: no empty columns


def test_a_record_of_the_next_schema_is_refused_and_bad_intervals_are_named(tmp_path):
    from bench.core.errors import InputError

    r = made_up_record("a", schema=SCHEMA_VERSION + 1)
    write_record(tmp_path / "r.json", r)
    with pytest.raises(InputError, match="newer than this bench"):
        load_record(tmp_path / "r.json")
    r = made_up_record("a", schema=SCHEMA_VERSION, intervals={"d_rms": [1.0]})
    write_record(tmp_path / "r.json", r)
    with pytest.raises(InputError, match="'intervals' has 'd_rms' that is not a pair"):
        load_record(tmp_path / "r.json")


def test_the_summary_table_shows_the_interval_when_pointed_at():
    from bench.report.table import summary_html
    from bench.records.results import records_table

    records = [_consistent(made_up_record("a"), VIEWS)]
    page = summary_html(records_table(records), records, {})
    lo, hi = interval(VIEWS, "d_rms")
    assert f"title='95 % interval over views: {lo:.4g} to {hi:.4g}'" in page


# -- paired tests ------------------------------------------------------------------------

def test_identical_methods_are_a_tie_with_p_one():
    t = paired(VIEWS, VIEWS)
    assert (t.p, t.direction, t.verdict(), t.a_better, t.b_better, t.median_difference) == \
        (1.0, 0, "tie", 0.0, 0.0, 0.0)


def test_a_hand_computed_case():
    # A - B = [1, 2, 3, -4] with lower better: A is worse on three views. Ranks 1..4,
    # W+ = 6, W- = 4; 7 of the 16 sign patterns have W <= 4, so p = 2 * 7 / 16.
    t = paired([2.0, 3.0, 4.0, 1.0], [1.0, 1.0, 1.0, 5.0])
    assert t.p == 0.875
    assert (t.median_difference, t.a_better, t.b_better) == (1.5, 0.25, 0.75)
    assert t.direction == -1 and t.verdict() == "tie"


def test_better_on_every_view_is_significant_and_a_fair_coin_is_not():
    b = np.asarray(VIEWS)
    a = b - np.linspace(0.1, 2.4, 24)  # lower on all 24 views, no tied magnitudes
    t = paired(a, b)
    assert t.p == 2 / 2 ** 24  # the exact two-sided p of the most extreme signs
    assert (t.direction, t.verdict(), t.a_better) == (1, "A better", 1.0)
    assert paired(b, a).verdict() == "B better"
    assert paired(-a, -b, higher_is_better=True).verdict() == "A better"
    assert paired(a, b, higher_is_better=True).verdict() == "B better"
    coin = np.random.default_rng(7).choice([-1.0, 1.0], size=24)
    t = paired(b + coin * np.linspace(0.1, 2.4, 24), b)
    assert t.p > 0.05 and t.verdict() == "tie"


def test_zero_differences_are_dropped_before_the_test():
    b = np.asarray(VIEWS)
    a = b.copy()
    a[:4] -= [1.0, 2.0, 3.0, 4.0]  # better on 4 views, equal on 20
    t = paired(a, b)
    assert t.p == 2 / 2 ** 4
    assert (t.a_better, t.b_better, t.median_difference) == (4 / 24, 0.0, 0.0)


def test_unpaired_values_are_refused():
    with pytest.raises(ValueError, match="same views"):
        paired([1.0, 2.0], [1.0])


def test_the_sign_test_is_the_binomial_of_a_fair_coin():
    assert sign_test(4, 0) == 0.125
    assert sign_test(10, 0) == 2 / 1024
    assert sign_test(0, 0) == 1.0
    assert sign_test(3, 3) == 1.0


# -- Holm --------------------------------------------------------------------------------

def test_holm_on_a_hand_example():
    # sorted 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1: 0.02, 0.03, 0.06, 0.04 -> 0.06
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([]) == []
    assert holm([0.5, 0.9]) == [1.0, 1.0]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0, 1), min_size=1, max_size=12),
       st.sampled_from([0.01, 0.05, 0.1]))
def test_holm_rejects_what_the_step_down_procedure_rejects(ps, alpha):
    adjusted = holm(ps)
    rejected = set()  # Holm's procedure itself: reject the k-th smallest while p <= a/(m-k)
    for k, i in enumerate(sorted(range(len(ps)), key=lambda i: ps[i])):
        if ps[i] > alpha / (len(ps) - k):
            break
        rejected.add(i)
    assert {i for i, p in enumerate(adjusted) if p <= alpha} == rejected
    assert all(p <= q <= 1 for p, q in zip(ps, adjusted))


# -- the claims' classes -------------------------------------------------------------------

def _rec(label, views, model="m", faces=100, metric="d_rms"):
    r = made_up_record(label, model=model)
    r["job"]["target_faces"] = faces
    r["job"]["key"] = f"{model}__{label}__{faces}"
    return _consistent(r, views, metric)


RATIO = Claim("c", "P", "a beats b", "d_rms", "a", "b", below=1.0)
BASE = np.asarray(VIEWS) + 1.0
STEP = np.linspace(0.1, 2.4, 24)


def test_a_ratio_claim_better_on_every_view_holds():
    res = evaluate_claim(RATIO, [_rec("a", BASE - STEP), _rec("b", BASE),
                                 _rec("a", BASE - STEP, faces=50), _rec("b", BASE, faces=50)])
    assert (res.verdict, res.klass) == ("holds", "holds")
    assert res.p == pytest.approx(2 * 2 / 2 ** 24)  # Holm over the two rows
    assert res.effect < 1 and res.sign_p == 0.5


def test_a_ratio_claim_on_a_coin_flip_holds_but_not_significantly():
    coin = np.random.default_rng(7).choice([-1.0, 1.0], size=24)
    a = BASE + coin * STEP * 0.1
    a[0] = BASE[0] - 5  # the RMS of a is lower: the row passes
    res = evaluate_claim(RATIO, [_rec("a", a), _rec("b", BASE)])
    assert res.verdict == "holds" and res.klass == "holds, not significant"


def test_a_ratio_claim_is_contradicted_by_a_significant_other_way_and_a_tie_does_not_hold():
    res = evaluate_claim(RATIO, [_rec("a", BASE + STEP), _rec("b", BASE)])
    assert (res.verdict, res.klass) == ("does not hold", "contradicted")
    assert res.p == 2 / 2 ** 24
    res = evaluate_claim(RATIO, [_rec("a", BASE), _rec("b", BASE)])
    assert (res.verdict, res.klass, res.p) == ("does not hold", "does not hold", 1.0)


def test_a_ratio_claim_against_a_threshold_tests_a_against_the_threshold_times_b():
    claim = Claim("c", "P", "a beats b by 10 %", "d_rms", "a", "b", below=0.9)
    res = evaluate_claim(claim, [_rec("a", BASE * 0.95), _rec("b", BASE)])
    assert (res.verdict, res.klass) == ("does not hold", "contradicted")
    res = evaluate_claim(claim, [_rec("a", BASE * 0.8), _rec("b", BASE)])
    assert (res.verdict, res.klass) == ("holds", "holds")


@pytest.mark.parametrize("views, side, klass", [
    (np.linspace(0.80, 0.85, 24), "above", "holds"),
    (np.linspace(0.40, 0.50, 24), "below", "contradicted"),
    (np.linspace(0.40, 1.02, 24), "across", "holds, not significant")])
def test_a_threshold_claim_says_where_its_interval_lies(views, side, klass):
    claim = Claim("t", "P", "ssim at least 0.7", "ssim", "a", at_least=0.7)
    res = evaluate_claim(claim, [_rec("a", views, metric="ssim")])
    assert (res.side, res.klass) == (side, klass)
    assert res.rows[0]["interval"] == list(interval(views, "ssim"))


def test_claims_without_per_view_values_have_no_test():
    wild = {c.name: c for c in SUITES["wild"].claims}["wild-quadric-target"]
    claim = Claim("t", "P", "on target", wild.metric, "quadric", below=wild.below)
    r = made_up_record("quadric", status="ok, off target")
    r["metrics"]["faces"] = 104
    res = evaluate_claim(claim, [r])
    assert (res.verdict, res.klass, res.p) == ("holds", "no test", None)
    # per-view values that do not make the value are not tested either
    res = evaluate_claim(RATIO, [made_up_record("a", metrics={"d_rms": 4.0}),
                                 made_up_record("b")])
    assert (res.verdict, res.klass) == ("holds", "no test")


def test_the_gate_reports_a_changed_class_and_does_not_fail_on_it():
    ci = SUITES["ci"].claims[0]
    held = [_rec("image-driven", BASE - STEP, model="bunny", faces=20),
            _rec("qslim", BASE, model="bunny", faces=20)]
    weak = copy.deepcopy(held)
    weak[0] = _rec("image-driven", BASE - STEP * 0.01 * np.resize([1, -1], 24),
                   model="bunny", faces=20)
    weak[0]["per_view"]["d_rms"][0] -= 3  # still passes, no longer consistently
    weak[0] = _consistent(weak[0], weak[0]["per_view"]["d_rms"])
    before, after = make_baseline(held), make_baseline(weak)
    assert before["claims"] == after["claims"] == {ci.name: "holds"}
    assert (before["claim_classes"], after["claim_classes"]) == (
        {ci.name: "holds"}, {ci.name: "holds, not significant"})
    rows = [(r.metric, r.baseline, r.current, r.mark) for r in compare(before, after)
            if r.job.startswith("claim ")]
    assert rows == [("verdict", "holds", "holds", "same"),
                    ("class", "holds", "holds, not significant", "class changed")]
    assert "class changed" not in FAILING_MARKS
    old = {k: v for k, v in before.items() if k != "claim_classes"}  # an older baseline
    assert baseline_problem(old) is None
    assert [r.mark for r in compare(old, after) if r.job.startswith("claim ")] == ["same"]
    assert "claim_classes" in baseline_problem(dict(before, claim_classes={"x": "maybe"}))


# -- bench compare ---------------------------------------------------------------------------

def _run(tmp_path):
    records = [_rec("a", BASE - STEP, model="m", faces=100), _rec("b", BASE, model="m", faces=100),
               _rec("a", BASE, model="m", faces=50), _rec("b", BASE, model="m", faces=50),
               _rec("a", BASE + STEP, model="n", faces=100), _rec("b", BASE, model="n", faces=100),
               _rec("c", BASE, model="n", faces=100)]
    for r in records:
        write_record(tmp_path / "records" / f"{r['job']['key']}.json", r)
    return tmp_path


def test_bench_compare_gives_a_verdict_per_model_and_budget(tmp_path, capsys):
    run = _run(tmp_path)
    assert main(["compare", str(run), "--methods", "a,b", "--format", "json"]) == 0
    out, err = capsys.readouterr()
    data = json.loads(out)
    got = [(r["model"], r["target_faces"], r["verdict"]) for r in data["rows"]]
    assert got == [("m", 50, "tie"), ("m", 100, "A better"), ("n", 100, "B better")]
    assert data["rows"][0]["p"] == 1.0 and data["rows"][1]["p_holm"] == 3 * 2 / 2 ** 24
    assert data["sign_test"] == {"a_wins": 1, "b_wins": 1, "ties": 1, "p": 1.0,
                                 "unit": "luminance (0-255)"}
    assert "sign test over rows: a better in 1, b in 1, 1 equal; p = 1" in err
    assert main(["compare", str(run), "--methods", "a,b"]) == 0
    text = capsys.readouterr().out.splitlines()
    assert text[0] == "A = a, B = b" and text[1].split()[0] == "model" and len(text) == 5
    assert main(["compare", str(run), "--methods", "b,a", "--format", "markdown"]) == 0
    md = capsys.readouterr().out
    assert "| n | 100 | flat |" in md and md.count("A better") == 2  # header and row n


@pytest.mark.parametrize("methods, message", [
    ("a,zz", "method 'zz' has no record in this run; its methods are: a, b, c"),
    ("a", "--methods needs two different method labels"),
    ("a,a", "--methods needs two different method labels")])
def test_bench_compare_refuses_bad_methods_in_one_line(tmp_path, capsys, methods, message):
    assert main(["compare", str(_run(tmp_path)), "--methods", methods]) == 2
    err = capsys.readouterr().err
    assert err.startswith("bench: error: ") and message in err and err.count("\n") == 1


def test_reproduce_and_list_carry_the_classes(tmp_path, capsys):
    run = tmp_path / "ci"
    for r in [_rec("image-driven", BASE - STEP, model="bunny", faces=20),
              _rec("qslim", BASE, model="bunny", faces=20)]:
        write_record(run / "records" / f"{r['job']['key']}.json", r)
    assert main(["reproduce", "--no-run", "--out", str(tmp_path), "--claims",
                 "ci-image-driven,g2007-torus"]) == 0
    out = capsys.readouterr().out
    with open(tmp_path / "claims.csv", newline="") as f:
        rows = {r["claim"]: r for r in csv.DictReader(f)}
    got = rows["ci-image-driven"]
    assert (got["verdict"], got["class"], float(got["p"])) == ("holds", "holds", 2 / 2 ** 24)
    assert float(got["effect"]) < 1 and float(got["sign_p"]) == 1.0
    assert (rows["g2007-torus"]["verdict"], rows["g2007-torus"]["class"]) == ("no data", "")
    line = next(x for x in out.splitlines() if x.startswith("ci-image-driven"))
    assert line.split()[-3:] == ["holds", "holds", "1.19e-07"]
    page = (tmp_path / "index.html").read_text()
    assert "<th>class</th>" in page and "ci-image-driven: holds (holds)" in page
    assert main(["list", "claims"]) == 0
    listed = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()[2:]}
    assert "wilcoxon over views" in listed["ci-image-driven"]
    assert "no test" in listed["wild-quadric-target"]
    from bench.commands.list import claim_class_test

    assert claim_class_test(Claim("t", "P", "s", "ssim", "a", at_least=0.7)) == \
        "interval over views"
