"""The papers' claims as data: rows and verdicts from records, the suites' scoping, the
gate on claims, and ``bench reproduce`` on records written here (no suite is run)."""

from __future__ import annotations

import copy
import csv
import math

import pytest

from bench.commands.cli import main
from bench.records.check import FAILING_MARKS, baseline_problem, compare, make_baseline
from bench.records.claims import STATS_PREFIX, TARGET_DISTANCE, Claim, evaluate_claim
from bench.records.results import write_record
from bench.records.suites import SUITES, Suite
from conftest import made_up_record


def rec(label, model="m", faces=100, d_rms=5.0, status="ok", shading="flat", specular=False,
        n_faces=1000, **metrics):
    r = made_up_record(label, status=status, model=model)
    r = copy.deepcopy(r)
    r["job"]["target_faces"] = faces
    r["job"]["key"] = f"{model}__{label}__{faces}__{shading}"
    r["job"]["protocol"].update(shading=shading, specular=specular)
    r["model"]["faces"] = n_faces
    r["metrics"].update(d_rms=d_rms, **metrics)
    return r


RATIO = Claim("c", "Paper 2000, Fig. 1", "a beats b", "d_rms", "a", "b", below=1.0)


def test_a_ratio_claim_has_a_row_per_model_budget_and_shading_with_both_methods():
    records = [rec("a", faces=100, d_rms=3.0), rec("b", faces=100, d_rms=4.0),
               rec("a", faces=50, d_rms=6.0), rec("b", faces=50, d_rms=5.0),
               rec("a", faces=20, d_rms=1.0),  # no b at 20: no row
               rec("b", model="n", d_rms=1.0)]  # no a on n: no row
    res = evaluate_claim(RATIO, records)
    assert [(r["target_faces"], r["value"], r["passes"]) for r in res.rows] == [
        (50, 6.0 / 5.0, False), (100, 0.75, True)]
    assert res.verdict == "mixed"
    assert res.summary == "0.75-1.2 (1 of 2 pass)"
    assert res.worst == 1.2


@pytest.mark.parametrize("a, paper, verdict", [
    (3.0, None, "holds"), (3.0, 0.8, "holds"), (3.6, 0.8, "holds, weaker"),
    (4.0, None, "does not hold"), (5.0, 0.8, "does not hold")])
def test_verdicts_compare_with_the_threshold_and_the_papers_ratio(a, paper, verdict):
    claim = Claim("c", "P", "s", "d_rms", "a", "b", below=1.0, paper_value=paper)
    res = evaluate_claim(claim, [rec("a", d_rms=a), rec("b", d_rms=4.0)])
    assert res.verdict == verdict


def test_a_claim_reads_a_method_statistic_with_the_stats_prefix():
    claim = Claim("c", "P", "s", "stats.kept", "a", "b", below=1.0)
    a, b = rec("a"), rec("b")
    a["stats"]["kept"], b["stats"]["kept"] = 0.2, 0.4
    res = evaluate_claim(claim, [a, b])
    assert [(r["value"], r["passes"]) for r in res.rows] == [(0.5, True)]
    del a["stats"]["kept"]  # a statistic the method did not record: no row
    assert evaluate_claim(claim, [a, b]).verdict == "no data"


def test_no_records_failed_jobs_and_undefined_metrics_give_no_data():
    assert evaluate_claim(RATIO, []).verdict == "no data"
    failed = [rec("a", status="failed"), rec("b")]
    assert evaluate_claim(RATIO, failed).verdict == "no data"
    share = Claim("s", "P", "s", "exterior_share", "a", at_least=0.9)
    assert evaluate_claim(share, [rec("a")]).verdict == "no data"  # metric absent


def test_a_value_claim_with_at_least_and_a_zero_reference_that_cannot_be_divided_by():
    share = Claim("s", "P", "s", "exterior_share", "a", at_least=0.9)
    res = evaluate_claim(share, [rec("a", exterior_share=0.9), rec("a", model="n",
                                                                    exterior_share=0.89)])
    assert [(r["model"], r["passes"]) for r in res.rows] == [("m", True), ("n", False)]
    zero = evaluate_claim(RATIO, [rec("a", d_rms=0.0), rec("b", d_rms=0.0)])
    assert math.isnan(zero.rows[0]["value"]) and zero.verdict == "does not hold"


def test_labels_match_in_canonical_form_and_shading_and_ratios_narrow_the_rows():
    # perceptual-mt's default error is "perceptual": the claim's label names it, the
    # records' labels leave it out, as bench run writes them
    claim = Claim("c", "P", "s", "d_rms", "perceptual-mt[error=perceptual]", "qslim",
                  below=1.0, shading="gouraud-spec", ratios=(0.02,))
    spec = {"shading": "gouraud", "specular": True}
    records = [rec("perceptual-mt", faces=20, d_rms=1.0, **spec),
               rec("qslim", faces=20, d_rms=2.0, **spec),
               rec("perceptual-mt", faces=20, d_rms=3.0), rec("qslim", faces=20, d_rms=2.0),
               rec("perceptual-mt", faces=100, **spec), rec("qslim", faces=100, **spec)]
    res = evaluate_claim(claim, records)
    assert [(r["shading"], r["target_faces"], r["value"]) for r in res.rows] == [
        ("gouraud-spec", 20, 0.5)]


def test_a_claim_needs_exactly_one_threshold():
    with pytest.raises(ValueError, match="exactly one"):
        Claim("c", "P", "s", "d_rms", "a", "b")
    with pytest.raises(ValueError, match="exactly one"):
        Claim("c", "P", "s", "d_rms", "a", "b", below=1.0, at_least=0.5)


def test_a_suite_scopes_its_claims_to_its_models_and_budgets():
    s = Suite("s", "d", models=("x", "y"), faces={"x": (10, 30), "y": (20,)},
              claims=(RATIO, Claim("n", "P", "s", "d_rms", "a", below=1.0, models=("x",),
                                   faces=(10,))))
    first, second = s.claims
    assert (first.suite, first.models, first.faces, first.ratios) == ("s", ("x", "y"),
                                                                      (30, 20, 10), ())
    assert (second.models, second.faces) == (("x",), (10,))
    r = Suite("r", "d", models=("x",), ratios=(0.5,), claims=(RATIO,)).claims[0]
    assert (r.faces, r.ratios) == ((), (0.5,))


def test_every_claim_of_the_suites_names_variants_and_metrics_that_exist():
    from bench.records.check import canonical_label, metric_directions

    directions = metric_directions()
    names = [c.name for s in SUITES.values() for c in s.claims]
    assert len(names) == len(set(names)) and len(names) >= 15
    for suite in SUITES.values():
        labels = {canonical_label(f"{m}[{','.join(f'{k}={v}' for k, v in p.items())}]"
                                  if p else m) for m, p in (suite.variants or ())}
        for c in suite.claims:
            assert (c.metric in directions or c.metric == "seam_cracks"
                    or c.metric == TARGET_DISTANCE or c.metric.startswith(STATS_PREFIX)), c.name
            if suite.variants is not None:
                assert canonical_label(c.method) in labels, c.name
                assert c.against is None or canonical_label(c.against) in labels, c.name


def _baseline(records):
    return make_baseline(records)


def test_the_gate_fails_when_a_claim_that_held_stops_holding():
    ci = SUITES["ci"].claims[0]  # image-driven against qslim at 2 % and 1 %
    assert ci.name == "ci-image-driven"
    held = [rec("image-driven", model="bunny", faces=20, d_rms=3.0),
            rec("qslim", model="bunny", faces=20, d_rms=4.0)]
    broken = copy.deepcopy(held)
    broken[0]["metrics"]["d_rms"] = 4.5
    base = _baseline(held)
    assert base["claims"] == {"ci-image-driven": "holds"}
    assert baseline_problem(base) is None
    rows = [r for r in compare(base, _baseline(broken), tolerance=1.0)
            if r.job.startswith("claim ")]
    assert [(r.job, r.baseline, r.current, r.mark) for r in rows] == [
        ("claim ci-image-driven", "holds", "does not hold", "claim broken")]
    assert "claim broken" in FAILING_MARKS
    back = [r.mark for r in compare(_baseline(broken), base) if r.job.startswith("claim ")]
    assert back == ["claim holds"]
    same = [r.mark for r in compare(base, base) if r.job.startswith("claim ")]
    assert same == ["same"]
    gone = dict(base, claims={})
    assert [r.mark for r in compare(base, gone) if r.job.startswith("claim ")] == ["missing"]


def test_a_baseline_with_a_verdict_that_is_not_one_is_refused():
    base = _baseline([rec("q")])
    base["claims"] = {"x": "probably"}
    assert "verdict 'probably'" in baseline_problem(base)


def _write(run_dir, records):
    for r in records:
        write_record(run_dir / "records" / f"{r['job']['key']}.json", r)


def test_reproduce_decides_claims_from_the_records_it_finds(tmp_path, capsys):
    torus = tmp_path / "lt2000-torus"
    _write(torus, [rec("image-driven", model="torus", faces=512, d_rms=6.0),
                   rec("qslim-texture", model="torus", faces=512, d_rms=8.0),
                   rec("memoryless", model="torus", faces=512, d_rms=8.0)])
    code = main(["reproduce", "--no-run", "--out", str(tmp_path), "--claims",
                 "lt2000-plate13,lt2000-plate13-memoryless,lt2000-fig1"])
    assert code == 0
    out = capsys.readouterr().out
    with open(tmp_path / "claims.csv", newline="") as f:
        rows = {r["claim"]: r for r in csv.DictReader(f)}
    assert rows["lt2000-plate13"]["verdict"] == "holds, weaker"  # 0.75 > 5.99 / 8.76
    assert float(rows["lt2000-plate13"]["worst"]) == 0.75
    assert rows["lt2000-plate13-memoryless"]["verdict"] == "holds"  # 0.75 < 5.99 / 7.29
    assert rows["lt2000-fig1"]["verdict"] == "no data"
    assert "lt2000-plate13" in out and "holds, weaker" in out
    page = (tmp_path / "index.html").read_text()
    assert "Reproduction" in page and "lt2000-plate13" in page and "no data" in page


def test_reproduce_names_an_unknown_claim_in_one_line(tmp_path, capsys):
    assert main(["reproduce", "--no-run", "--out", str(tmp_path), "--claims",
                 "lt2000-plate31"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown claim 'lt2000-plate31'" in err[0]
    assert "lt2000-plate13" in err[0]  # the suggestion


def test_bench_list_claims_shows_every_claim(capsys):
    assert main(["list", "claims"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"claims ({sum(len(s.claims) for s in SUITES.values())})")
    assert "w2003-98" in out and "ltdiff 3,123 vs 3,689" in out
