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
    values = data.draw(st.lists(st.floats(0.0, 0.3, allow_nan=False), min_size=len(sizes),
                                max_size=len(sizes)))
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
    from bench.method import run_method
    from bench.models import resolve_model
    from bench.registry import registry

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
