"""The screen-size evaluation (metrics/screen.py): the switch size's interpolation
against an independent oracle, the sizes' checks, the original's convergence, the
sphere against icosphere LODs of known chord error, and nested LODs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import icosphere
from metrics import screen
from metrics.protocol import Protocol
from metrics.screen import (
    AT_LEAST,
    BELOW,
    check_screen_sizes,
    parse_screen_sizes,
    predicted_size,
    switch_size,
)

# -- the interpolation against an oracle ---------------------------------------------------


def _oracle(sizes, values, threshold, steps=20000):
    """The largest S on a fine grid in log S where the error, linear in log S between
    measured sizes, is at most the threshold (None if none)."""
    order = np.argsort(sizes)
    logs = np.log(np.asarray(sizes, float)[order])
    vals = np.asarray(values, float)[order]
    step = (logs[-1] - logs[0]) / (steps - 1)
    grid = np.union1d(np.linspace(logs[0], logs[-1], steps), logs)  # the sizes themselves too
    f = np.interp(grid, logs, vals)
    ok = np.nonzero(f <= threshold)[0]
    return (None if len(ok) == 0 else float(np.exp(grid[ok[-1]]))), step


@settings(max_examples=300, deadline=None)
@given(st.lists(st.integers(1, 4096), min_size=2, max_size=7, unique=True),
       st.data(), st.floats(0.0, 0.2))
def test_switch_size_matches_the_oracle(sizes, data, threshold):
    # no subnormal errors: the oracle's own interpolation (np.interp) rounds them to 0
    # or to 5e-324 between grid points, so it cannot be the reference there
    values = data.draw(st.lists(st.floats(0.0, 0.3, allow_nan=False, allow_subnormal=False),
                                min_size=len(sizes), max_size=len(sizes)))
    value, bound = switch_size(sizes, values, threshold)
    by_size = dict(zip(sizes, values))
    largest, smallest = max(sizes), min(sizes)
    if by_size[largest] <= threshold:
        assert (value, bound) == (largest, AT_LEAST)
    elif all(v > threshold for v in values):
        assert (value, bound) == (smallest, BELOW)
    else:
        expected, step = _oracle(sizes, values, threshold)
        assert bound is None
        assert smallest <= value <= largest
        # within one grid step of the oracle in log S
        assert abs(math.log(value) - math.log(expected)) <= 2 * step + 1e-12


def test_switch_size_by_hand():
    # 512 fails (0.03), 256 passes (0.01): tau 0.02 lies half way, at sqrt(512 * 256)
    value, bound = switch_size([512, 256, 128], [0.03, 0.01, 0.0], 0.02)
    assert bound is None and value == pytest.approx(math.sqrt(512 * 256))
    # the largest passing size counts, not the first from below (non-monotone curve)
    assert switch_size([512, 256, 128], [0.01, 0.05, 0.0], 0.02) == (512, AT_LEAST)
    value, _ = switch_size([512, 256, 128, 64], [0.05, 0.01, 0.05, 0.0], 0.02)
    assert 256 < value < 512
    assert switch_size([64, 32], [0.5, 0.4], 0.02) == (32, BELOW)
    # exactly at the threshold passes
    assert switch_size([64, 32], [0.5, 0.02], 0.02) == (32, None)


def test_predicted_size_is_the_one_pixel_size():
    # a sphere of radius 2 spans S pixels: a deviation of 0.01 is one pixel at S = 400
    assert predicted_size(0.01, 2.0) == pytest.approx(400.0)
    assert predicted_size(0.0, 2.0) is None
    assert predicted_size(float("nan"), 2.0) is None


# -- the sizes ---------------------------------------------------------------------------


@pytest.mark.parametrize("sizes", [[0], [-32], [4097], [512, 0], []])
def test_bad_sizes_are_refused(sizes):
    with pytest.raises(ValueError) as info:
        check_screen_sizes(sizes)
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError):
        Protocol(screen_sizes=tuple(sizes) or (0,))


def test_sizes_are_sorted_and_parsed():
    assert check_screen_sizes([32, 512, 128, 32]) == (512, 128, 32)
    assert parse_screen_sizes("default") == screen.DEFAULT_SCREEN_SIZES
    assert parse_screen_sizes("64, 4096") == (4096, 64)
    with pytest.raises(ValueError, match="whole number"):
        parse_screen_sizes("64,big")


def test_default_protocol_records_no_screen_sizes():
    # records and job keys of runs without screen sizes stay as they were
    assert "screen_sizes" not in Protocol().as_dict()
    assert Protocol(screen_sizes=(32, 512)).as_dict()["screen_sizes"] == [512, 32]


@pytest.mark.parametrize("text", ["0", "-5", "5000", "64,x"])
def test_cli_refuses_bad_sizes_in_one_line(text, tmp_path):
    from test_cli import assert_one_line_error, bench

    proc = bench("run", "--models", "bunny", "--methods", "qslim", "--faces", "500",
                 f"--screen-sizes={text}", "--out", tmp_path / "run", "--no-report")
    assert_one_line_error(proc, "--screen-sizes")


# -- rendering: convergence, chord error, nesting -------------------------------------------


@pytest.fixture(scope="module")
def sphere():
    return icosphere(5, "sphere")  # 20,480 faces: the "original" sphere


def _chord(mesh) -> float:
    """The largest distance between a face of the unit-sphere mesh and the sphere."""
    p = mesh.positions[mesh.faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1)[:, None]
    return float(1.0 - np.abs(np.einsum("ij,ij->i", n, p[:, 0])).min())


def test_supersampled_original_is_converged(sphere, tmp_path):
    from metrics.image import flip_mean

    four = screen.supersampled_images(sphere, Protocol(), 64, factor=4, cache=tmp_path)
    eight = screen.supersampled_images(sphere, Protocol(), 64, factor=8, cache=tmp_path)
    flip = flip_mean(eight, four, views="all")[0]
    # far below the threshold: a quarter of tau (measured: 0.0039 here, 0.0021 on the bunny
    # at 128 px)
    assert flip < screen.SWITCH_FLIP / 2
    # and a real difference is not hidden: the engine's 4x MSAA alone is further away
    drawn = screen.engine_images(sphere, sphere, Protocol(), 64)
    assert flip_mean(four, drawn, views="all")[0] > flip


@pytest.mark.slow
def test_icosphere_switch_follows_the_chord_rule(sphere):
    """Icosphere LODs of the unit sphere, flat shaded: the measured switch size grows
    with detail as the one-pixel chord size 2r/d does, and lies below it by a factor of
    at most 16. Below: the chord rule counts only how far the surface moves, while flat
    shading shows each facet's normal error, an angle of about sqrt(8 d / r) that falls
    only as the square root of the chord d, as a luminance step between neighbouring
    facets; it stays visible after the positions are below a pixel."""
    protocol = Protocol(screen_sizes=(512, 256, 128, 64, 32, 16))
    measured = []
    for level in (3, 4):
        lod = icosphere(level)
        analytic = predicted_size(_chord(lod), 1.0)
        part = screen.summarise(screen.screen_curve(sphere, lod, protocol), sphere, None)
        value, bound = part["switch_px"]["value"], part["switch_px"]["bound"]
        assert bound != BELOW, part
        assert value <= analytic, (level, value, analytic)
        if bound is None:
            assert value >= analytic / 16, (level, value, analytic)
        measured.append(value)
    assert measured[1] > measured[0]


@pytest.mark.slow
def test_nested_lods_never_switch_later_with_fewer_faces():
    """qslim's levels of the bunny (25 % down to 1.5 %): a level with more faces never
    has a switch size smaller than one with fewer, beyond a factor 2^(1/4) (a quarter
    octave: FLIP's noise between views of nearly equal LODs)."""
    from bench.core.method import run_method
    from bench.catalog import resolve_model
    from bench.core.registry import registry

    original = resolve_model("bunny")
    method = registry("method").load("qslim")(registry("method").load("qslim").Params())
    protocol = Protocol(screen_sizes=(512, 256, 128, 64, 32, 16))
    switches = []
    for ratio in (0.25, 0.12, 0.06, 0.03, 0.015):
        lod = run_method(method, original, round(ratio * original.n_faces)).mesh
        part = screen.summarise(screen.screen_curve(original, lod, protocol), original, None)
        switches.append(part["switch_px"]["value"])
    print("switch_px", switches)
    for more, fewer in zip(switches, switches[1:]):
        assert more * 2 ** 0.25 >= fewer, switches
    assert switches[0] > switches[-1], switches


# -- LOD chains, tables, records -------------------------------------------------------------


def test_halving_faces():
    assert screen.halving_faces(56172) == [28086, 14043, 7022, 3511, 1755, 878, 439]
    assert screen.halving_faces(1728) == [864, 432, 216, 108]
    assert screen.halving_faces(1000, floor=200) == [500, 250]
    with pytest.raises(ValueError, match="floor"):
        screen.halving_faces(300, floor=200)


@pytest.mark.filterwarnings("ignore::bench.core.errors.MeshWarning")  # kit's non-manifold edges
def test_lod_suite_budgets_follow_the_models():
    from bench.records.suites import LOD_MODELS, SUITES
    from bench.catalog import resolve_model

    for name, faces in LOD_MODELS.items():
        assert resolve_model(name).n_faces == faces, name
    assert SUITES["lod"].faces["crate"] == (864, 432, 216, 108)


def test_engine_units():
    from bench.core.mesh import Mesh
    from conftest import TET_FACES, TET_POSITIONS

    # a cube's corners: bounding sphere radius sqrt(3), largest side 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    cube = Mesh(corners, np.array([[0, 1, 2], [1, 3, 2]], np.int32))
    units = screen.engine_units({"value": 216.0, "bound": ">="}, cube, screen_height=1080)
    assert units["unreal_screen_size"] == pytest.approx(0.2)
    assert units["unity_relative_height"] == pytest.approx(0.2 * 2 / (2 * math.sqrt(3)))
    assert units["bound"] == ">="
    assert Mesh(TET_POSITIONS, TET_FACES).n_faces == 4


def _row(faces, value, bound=None, hausdorff=None, library=None, method="m", target=None):
    return {"model": "x", "method": method, "target": target or faces, "faces": faces,
            "switch": {"value": value, "bound": bound},
            "switch_rms": {"value": value, "bound": bound},
            "predicted": {k: v for k, v in (("hausdorff", hausdorff), ("library", library))
                          if v is not None},
            "ablation": {"0.01": {"value": value, "bound": bound}}}


def test_faces_needed_and_predictors():
    from bench.report.screen_tables import best_at, faces_needed, predictor_table

    rows = [_row(4000, 512, ">=", hausdorff=400), _row(2000, 200, hausdorff=100),
            _row(1000, 100, hausdorff=150), _row(500, 32, "<", hausdorff=40)]
    assert faces_needed(rows, 128) == 2000   # 1000 faces switch at 100 < 128
    assert faces_needed(rows, 64) == 1000
    assert faces_needed(rows, 32) == 1000    # "< 32" is never enough
    assert faces_needed(rows, 600) is None
    table = predictor_table(rows)
    hausdorff = [r for r in table if r[0] == "hausdorff"][0]
    # decided: 4000 (400 <= 512: not early), 2000 (100 < 200), 1000 (150 > 100: early),
    # 500 (40 >= "<32": early); ratios 2.0 and 0.667: their geometric median
    assert hausdorff[3] == "4" and hausdorff[6] == "2/4"
    assert float(hausdorff[4]) == pytest.approx(math.sqrt(2.0 * 100 / 150), rel=1e-2)
    other = [_row(1500, 130, method="n")]
    assert best_at(rows + other, 128)[1][1:3] == ["1500", "n"]


def test_record_screen_part_is_checked():
    from bench.records.results import record_problem
    from conftest import made_up_record

    record = made_up_record()
    record["screen"] = {"sizes": [64, 32], "flip": [0.1], "d_rms": [1.0, 2.0],
                        "switch_px": {"value": 32, "bound": "<"},
                        "switch_px_rms": {"value": 32, "bound": "<"}}
    assert "flip" in record_problem(record)
    record["screen"]["flip"] = [0.1, 0.2]
    assert record_problem(record) is None
    record["screen"]["switch_px"]["bound"] = "about"
    assert "switch_px" in record_problem(record)


def test_simplify_halving_and_switch_errors_are_one_line(tmp_path):
    from test_cli import assert_one_line_error, bench

    assert_one_line_error(bench("simplify", "crate", tmp_path / "a.glb", "--method", "qslim",
                                "--halving", "5000"), "--halving")
    assert_one_line_error(bench("simplify", "crate", tmp_path / "a.glb", "--method", "qslim",
                                "--faces", "500", "--switch"), "--switch")


def test_evaluate_records_the_curve_only_when_asked(tmp_path, monkeypatch):
    """metrics.protocol.evaluate with screen sizes: the curve, switch_px and its bound;
    without: no screen part and no switch_px (records of other runs are unchanged)."""
    from metrics.protocol import evaluate

    monkeypatch.setenv("BENCH_CACHE", str(tmp_path))
    original, lod = icosphere(4, "sphere"), icosphere(1)
    small = Protocol(resolution=64, hausdorff_samples=20_000)
    plain = evaluate(original, lod, small)
    assert plain.screen is None and "switch_px" not in plain.metrics
    ev = evaluate(original, lod, Protocol(resolution=64, hausdorff_samples=20_000,
                                          screen_sizes=(64, 32)))
    assert ev.screen["sizes"] == [64, 32]
    assert ev.metrics["switch_px"] == ev.screen["switch_px"]["value"]
    # an 80-face icosphere is visibly not a sphere at 64 and 32 px
    assert ev.screen["switch_px"] == {"value": 32.0, "bound": "<"}
    assert ev.metrics["d_rms"] == plain.metrics["d_rms"]  # the 64 px protocol images reused
    assert 0 < ev.screen["predicted"]["hausdorff"] < 64


def test_faces_needed_chart_is_written(tmp_path):
    from PIL import Image

    from bench.report.screen_tables import faces_needed_chart

    rows = [_row(4000, 512, ">="), _row(1000, 100), _row(500, 32, "<"),
            _row(2000, 300, method="n")]
    path = faces_needed_chart(rows, "x", tmp_path / "x.png")
    width, height = Image.open(path).size  # the axes and the legend beside them
    assert width > 600 and 300 < height < 500
    assert faces_needed_chart(rows, "no such model", tmp_path / "y.png") is None
