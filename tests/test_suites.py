"""Suites with several evaluation protocols: the plan, the command-line overrides, and how
results.csv, the regression gate and the report tell the protocols apart.

Nothing here simplifies or renders a mesh: plans are compared with hand-written
expectations, and records are built by hand.
"""

from __future__ import annotations

import math

import pytest

from bench.commands.cli import build_parser
from bench.records.check import compare, make_baseline
from bench.records.results import CSV_COLUMNS, records_table, shading_label
from bench.records.suites import SUITES, Suite, evaluation_protocols, get_suite
from bench.run.runner import plan
from metrics.protocol import PROTOCOL_VERSION, Protocol

FLAT, GOURAUD_SPEC = Protocol("flat"), Protocol("gouraud", specular=True)


# -- plan ---------------------------------------------------------------------------------

def test_plan_with_one_protocol_is_unchanged():
    jobs = plan(["a", "b"], [("m", {}), ("n", {"k": 1})], {"a": [10, 5], "b": [7]}, FLAT)
    assert [(j.model, j.label, j.target_faces) for j in jobs] == [
        ("a", "m", 10), ("a", "m", 5), ("a", "n[k=1]", 10), ("a", "n[k=1]", 5),
        ("b", "m", 7), ("b", "n[k=1]", 7)]
    assert {j.protocol for j in jobs} == {FLAT}


def test_plan_runs_every_job_under_every_protocol():
    jobs = plan(["a"], [("m", {}), ("n", {})], {"a": [10, 5]}, [FLAT, GOURAUD_SPEC])
    assert len(jobs) == 1 * 2 * 2 * 2
    assert [(j.label, j.target_faces, j.protocol) for j in jobs[:4]] == [
        ("m", 10, FLAT), ("m", 10, GOURAUD_SPEC), ("m", 5, FLAT), ("m", 5, GOURAUD_SPEC)]
    assert len({j.key for j in jobs}) == 8  # one record file each
    assert jobs[0].key == f"a__m__10__flat-p{PROTOCOL_VERSION}"
    assert jobs[1].key == f"a__m__10__gouraud-spec-p{PROTOCOL_VERSION}"


def test_plan_drops_duplicate_jobs_and_needs_a_protocol():
    jobs = plan(["a"], [("m", {})], {"a": [10, 10]}, [FLAT, FLAT])
    assert len(jobs) == 1
    with pytest.raises(ValueError, match="at least one"):
        plan(["a"], [("m", {})], {"a": [10]}, [])


# -- protocols of a run -------------------------------------------------------------------

def _pairs(protocols):
    return [(p.shading, p.specular) for p in protocols]


def test_a_suite_brings_its_protocols():
    shading = get_suite("lt2000-shading")
    assert _pairs(evaluation_protocols(shading)) == [("flat", False), ("gouraud", True)]
    assert _pairs(evaluation_protocols(get_suite("ci"))) == [("flat", False)]
    assert _pairs(evaluation_protocols()) == [("flat", False)]


def test_command_line_shading_and_specular_override():
    suite = get_suite("lt2000-shading")
    assert _pairs(evaluation_protocols(suite, "gouraud")) == [("gouraud", False)]
    assert _pairs(evaluation_protocols(suite, "flat", True)) == [("flat", True)]
    # --specular alone: on for each of the suite's protocols (duplicates merged)
    assert _pairs(evaluation_protocols(suite, None, True)) == [("flat", True), ("gouraud", True)]
    assert _pairs(evaluation_protocols(None, None, True)) == [("flat", True)]
    with pytest.raises(ValueError, match="shading must be one of"):
        evaluation_protocols(suite, "phong")


@pytest.mark.parametrize("protocols, message", [
    ((), "at least one"), ((("phong", False),), "is not"), ((("flat", "yes"),), "is not"),
    ((("flat", False), ("flat", False)), "twice")])
def test_suite_protocols_are_validated(protocols, message):
    with pytest.raises(ValueError, match=message):
        Suite("bad", "a bad suite", ("bunny",), protocols=protocols)


# -- the lt2000 suites --------------------------------------------------------------------

def test_lt2000_bunny_budgets_are_table_1_scaled():
    budgets = get_suite("lt2000-bunny").faces["bunny"]
    # Table 1: 2,899 / 1,333 / 654 / 304 / 143 of 69,451 faces, times 56,172 / 69,451
    assert budgets == (2345, 1332, 1078, 529, 246, 116)
    assert [round(f * 56172 / 69451) for f in (2899, 1333, 654, 304, 143)] == \
        [2345, 1078, 529, 246, 116]


def test_lt2000_suites_name_their_experiments():
    expected = {
        "lt2000-bunny": (("bunny",), ["image-driven", "memoryless", "qslim",
                                      "fast-simplification"]),
        "lt2000-torus": (("torus",), ["image-driven", "memoryless", "qslim-texture",
                                      "quadric"]),
        "lt2000-interior": (("interior",), ["image-driven[interior_views=0]",
                                            "image-driven[interior_views=10]", "memoryless",
                                            "qslim"]),
        "lt2000-shading": (("bunny",), ["image-driven[shading=flat]",
                                        "image-driven[shading=gouraud,specular=true]",
                                        "qslim"]),
    }
    for name, (models, labels) in expected.items():
        suite = SUITES[name]
        assert suite.models == models
        budgets = {m: list(suite.faces[m]) for m in models}
        jobs = plan(list(models), list(suite.variants), budgets, evaluation_protocols(suite))
        assert list(dict.fromkeys(j.label for j in jobs)) == labels
    assert SUITES["lt2000-torus"].faces == {"torus": (512,)}
    assert SUITES["lt2000-interior"].faces == {"interior": (2000,)}


@pytest.mark.parametrize("name", sorted(SUITES))
def test_suite_variants_are_valid_method_parameters(name):
    """What ``bench run --suite`` checks before any work starts, for every suite."""
    from bench.core.method import param_text, parse_params
    from bench.core.registry import registry

    for method, params in SUITES[name].variants or ():
        cls = registry("method").load(method)
        parsed = parse_params(cls.Params, [f"{k}={param_text(v)}" for k, v in params.items()])
        for key, value in params.items():
            assert getattr(parsed, key) == value


def test_lt2000_shading_plans_each_variant_under_both_shadings():
    suite = get_suite("lt2000-shading")
    jobs = plan(list(suite.models), list(suite.variants), dict(suite.faces),
                evaluation_protocols(suite))
    assert len(jobs) == 3 * 2
    assert sorted(j.key for j in jobs) == sorted(
        f"bunny__{label}__1332__{shading}-p{PROTOCOL_VERSION}"
        for label in ("image-driven-shading=flat", "image-driven-shading=gouraud,specular=true",
                      "qslim")
        for shading in ("flat", "gouraud-spec"))


def test_bench_run_plans_a_suite_under_each_protocol(monkeypatch, tmp_path):
    """``bench run --suite`` hands the runner one job per protocol (execute replaced)."""
    import bench.commands.run as run_command
    from bench.core.mesh import Mesh
    from bench.io.meshio import save_mesh
    from conftest import TET_FACES, TET_POSITIONS

    model = str(tmp_path / "tet.obj")
    save_mesh(Mesh(TET_POSITIONS, TET_FACES), model)
    monkeypatch.setitem(SUITES, "two-shadings", Suite(
        "two-shadings", "test", (model,), variants=(("qslim", {}),), faces={model: (2,)},
        protocols=(("flat", False), ("gouraud", True))))
    planned = []
    monkeypatch.setattr(run_command, "execute", lambda jobs, *a, **k: planned.append(jobs))
    monkeypatch.setattr(run_command, "finish", lambda out, **options: 0)

    def bench_run(*extra):
        planned.clear()
        args = build_parser().parse_args(["run", "--suite", "two-shadings", "--out",
                                          str(tmp_path / "out"), *extra])
        assert run_command.run(args) == 0
        return [(j.protocol.shading, j.protocol.specular) for j in planned[0]]

    assert bench_run() == [("flat", False), ("gouraud", True)]
    assert bench_run("--shading", "gouraud") == [("gouraud", False)]
    assert bench_run("--specular") == [("flat", True), ("gouraud", True)]


# -- results.csv, bench check and the report ----------------------------------------------

def _record(label, protocol, d_rms, status="ok", exterior_share=None, model="m"):
    metrics = {"faces": 100, "d_rms": d_rms, "ssim": 0.9, "hausdorff_mean": 0.01,
               "silhouette_mean": 2.0, "boundary_edges": 0, "seam_cracks": 0}
    if exterior_share is not None:
        metrics["exterior_share"] = exterior_share
    return {"schema": 1, "status": status, "error": None,
            "job": {"model": model, "method": label, "params": {}, "label": label,
                    "target_faces": 100, "protocol": protocol.as_dict()},
            "model": {"name": model, "hash": "0" * 40, "faces": 1000},
            "method": {"name": label, "version": "1", "view_dependent": False},
            "metrics": metrics, "per_view": {"d_rms": [d_rms] * 24},
            "silhouette_histogram": [1.0] + [0.0] * 20,
            "stats": {"wall_seconds": 1.0, "tri_per_s": 900.0, "peak_mb": 10.0},
            "environment": {}}


def test_results_table_has_the_evaluation_shading_and_exterior_share():
    records = [_record("q", FLAT, 5.0), _record("q", GOURAUD_SPEC, 7.0, exterior_share=0.75)]
    table = records_table(records)
    assert list(table.columns) == CSV_COLUMNS
    assert table.shading.tolist() == ["flat", "gouraud-spec"]
    assert table.d_rms.tolist() == [5.0, 7.0]
    assert math.isnan(table.exterior_share[0]) and table.exterior_share[1] == 0.75
    assert shading_label({"shading": "gouraud", "specular": False}) == "gouraud"


def test_check_keys_tell_shadings_and_specular_apart():
    records = [_record("q", FLAT, 5.0), _record("q", Protocol("flat", specular=True), 6.0),
               _record("q", GOURAUD_SPEC, 7.0)]
    entries = make_baseline(records)["entries"]
    assert sorted(entries) == ["m | q | 100 | flat", "m | q | 100 | flat-spec",
                               "m | q | 100 | gouraud-spec"]
    assert entries["m | q | 100 | gouraud-spec"]["metrics"]["d_rms"] == 7.0
    # a regression under one protocol is reported under that protocol only
    worse = make_baseline(records[:2] + [_record("q", GOURAUD_SPEC, 9.0)])
    marks = {(r.job, r.metric): r.mark for r in compare(make_baseline(records), worse)}
    assert marks[("m | q | 100 | gouraud-spec", "d_rms")] == "worse"
    assert marks[("m | q | 100 | flat", "d_rms")] == "same"


def test_undefined_exterior_share_is_never_a_regression():
    """Undefined is absent from the record (metrics.protocol leaves it out): absent on
    both sides it is no row; defined in the baseline and absent from the run's record of
    the same job it is a missing metric (the same model defines the same metrics, so the
    record is damaged), and a NaN there is not "undefined" but damage: both fail."""
    defined = make_baseline([_record("q", FLAT, 5.0, exterior_share=0.9)])
    undefined = make_baseline([_record("q", FLAT, 5.0)])
    assert "exterior_share" not in undefined["entries"]["m | q | 100 | flat"]["metrics"]
    assert defined["entries"]["m | q | 100 | flat"]["metrics"]["exterior_share"] == 0.9
    marks = {r.metric: r.mark for r in compare(undefined, undefined)}
    assert "exterior_share" not in marks
    marks = {r.metric: r.mark for r in compare(defined, undefined)}
    assert marks["exterior_share"] == "missing metric"
    nan = make_baseline([_record("q", FLAT, 5.0, exterior_share=math.nan)])
    assert {r.metric: r.mark for r in compare(defined, nan)}["exterior_share"] == "not finite"
    lower = make_baseline([_record("q", FLAT, 5.0, exterior_share=0.5)])
    assert {r.metric: r.mark for r in compare(defined, lower)}["exterior_share"] == "worse"


def test_report_shows_each_evaluation_shading_and_the_exterior_share(tmp_path):
    from bench.report.page import write_report

    records = [_record("q", FLAT, 5.0), _record("q", GOURAUD_SPEC, 7.0),
               _record("q", FLAT, 4.0, model="interior", exterior_share=0.95)]
    page = write_report(tmp_path, records).read_text()
    assert "flat and gouraud + specular shading" in page
    assert "<th>shading</th>" in page and "<td>gouraud-spec</td>" in page
    assert "at 100 faces, evaluated gouraud-spec: d_RMS 7.000" in page
    assert "Faces on the exterior" in page and "95.0%" in page
    assert page.count("Faces on the exterior") == 1  # only for the model that defines it

    plain = write_report(tmp_path, [_record("q", FLAT, 5.0)]).read_text()
    assert "exterior_share" not in plain and "evaluated flat" not in plain
    assert "Faces on the exterior" not in plain


# -- protocol options: the image settings of another paper (w2003-paper) -------------------

PAPER = Protocol("gouraud", specular=True, resolution=1024, views="representative")


def test_views_is_a_recorded_protocol_option_with_the_24_views_by_default():
    assert Protocol().views == "rhombicuboctahedron"
    assert Protocol().as_dict()["views"] == "rhombicuboctahedron"
    with pytest.raises(ValueError, match="views must be one of"):
        Protocol(views="front")
    with pytest.raises(ValueError, match="resolution"):
        Protocol(resolution=0)


def test_a_suite_protocol_may_set_resolution_and_views():
    protocols = evaluation_protocols(get_suite("w2003-paper"))
    assert protocols == [PAPER]
    both = evaluation_protocols(get_suite("w2003-ablation"))
    assert both == [GOURAUD_SPEC, PAPER]
    # --shading replaces the suite's protocols by one at the default image settings
    assert evaluation_protocols(get_suite("w2003-paper"), "flat") == [FLAT]
    assert evaluation_protocols(get_suite("w2003"))[0] == GOURAUD_SPEC  # unchanged


@pytest.mark.parametrize("protocols, message", [
    ((("flat", False, {"msaa": 1}),), "not one of resolution, views"),
    ((("flat", False, {"views": "front"}),), "views must be one of"),
    ((("flat", False, {"resolution": -5}),), "resolution"),
    ((("flat", False, "1024"),), "must be a dict"),
    ((("flat", False), ("flat", False, {"resolution": 512})), "twice")])
def test_suite_protocol_options_are_validated(protocols, message):
    with pytest.raises(ValueError, match=message):
        Suite("bad", "a bad suite", ("bunny",), protocols=protocols)


def test_the_default_protocol_keeps_its_keys_and_labels():
    job = plan(["bunny"], [("perceptual-mt", {})], {"bunny": [1123]}, [GOURAUD_SPEC, PAPER])
    assert job[0].key == f"bunny__perceptual-mt__1123__gouraud-spec-p{PROTOCOL_VERSION}"
    assert job[1].key.startswith(f"bunny__perceptual-mt__1123__gouraud-spec-p{PROTOCOL_VERSION}-")
    assert shading_label(GOURAUD_SPEC.as_dict()) == "gouraud-spec"
    assert shading_label(PAPER.as_dict()) == "gouraud-spec-1024-representative"
    assert shading_label(Protocol(resolution=256).as_dict()) == "flat-256"
    mesh = type("M", (), {"content_hash": "a" * 40})()
    assert GOURAUD_SPEC.image_key(mesh) == f"{'a' * 16}-p{PROTOCOL_VERSION}-gouraud-spec-512-msaa4"
    assert PAPER.image_key(mesh).endswith("-1024-msaa4-representative")


def test_records_under_the_two_settings_are_never_matched():
    from bench.records.claims import evaluate_claim

    records = [_record("q", GOURAUD_SPEC, 5.0), _record("q", PAPER, 6.0)]
    entries = make_baseline(records)["entries"]
    assert sorted(entries) == ["m | q | 100 | gouraud-spec",
                               "m | q | 100 | gouraud-spec-1024-representative"]
    claim = next(c for c in get_suite("w2003-paper").claims if c.name == "w2003-98-paper")
    ours = [_record(lab, p, v, model="bunny") for lab, p, v in [
        ("perceptual-mt", GOURAUD_SPEC, 1.0), ("perceptual-mt[error=screen]", GOURAUD_SPEC, 2.0),
        ("perceptual-mt", PAPER, 3.0), ("perceptual-mt[error=screen]", PAPER, 4.0)]]
    for r in ours:
        r["job"]["target_faces"], r["model"]["faces"] = 20, 1000
    rows = evaluate_claim(claim, ours).rows
    assert [(r["shading"], r["value"]) for r in rows] == [
        ("gouraud-spec-1024-representative", 0.75)]
    # a suite of one protocol scopes its claims to it: w2003-98 reads our protocol only
    ours_claim = next(c for c in get_suite("w2003").claims if c.name == "w2003-98")
    assert ours_claim.shading == "gouraud-spec"
    assert [(r["shading"], r["value"]) for r in evaluate_claim(ours_claim, ours).rows] == [
        ("gouraud-spec", 0.5)]
    assert evaluate_claim(ours_claim, ours[2:]).verdict == "no data"
    # several protocols: a claim names its own (lt2000-shading's do)
    assert all(c.shading for c in get_suite("lt2000-shading").claims)


def test_a_record_made_before_views_existed_is_read_as_the_24_views():
    from bench.records.results import record_problem

    old = _record("q", GOURAUD_SPEC, 5.0)
    del old["job"]["protocol"]["views"]
    assert record_problem(old) is None
    assert shading_label(old["job"]["protocol"]) == "gouraud-spec"
    bad = _record("q", GOURAUD_SPEC, 5.0)
    bad["job"]["protocol"]["views"] = "front"
    assert "views" in record_problem(bad)
