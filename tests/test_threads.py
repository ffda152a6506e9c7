"""Threads per job: the default shares the cores among the job processes, a job's
parallel kernels use what it is given, and the result does not depend on it."""

from __future__ import annotations

import os
import subprocess
import sys

import numba
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.run.jobs import use_threads
from bench.run.runner import default_threads, usable_cores
from conftest import blob

CORES = usable_cores()


@pytest.fixture
def restore_threads():
    before = numba.get_num_threads()
    yield
    numba.set_num_threads(before)


def test_usable_cores_are_the_affinity():
    assert usable_cores() == len(os.sched_getaffinity(0)) <= (os.cpu_count() or 1)


def test_default_threads_keep_jobs_times_threads_within_the_cores():
    for workers in range(1, 2 * CORES + 2):
        threads = default_threads(workers)
        assert threads >= 1
        assert workers * threads <= max(CORES, workers)
    assert default_threads(1) == CORES
    assert default_threads(CORES + 1) == 1
    assert default_threads(1, "tcp://somewhere:8786") == 1  # a cluster's cores are unknown here


def test_use_threads_sets_numbas_threads_within_its_pool(restore_threads):
    assert use_threads(1) == 1 == numba.get_num_threads()
    assert use_threads(10_000) == numba.config.NUMBA_NUM_THREADS
    assert use_threads(0) == 1
    assert use_threads(None) == numba.get_num_threads()  # None: left as it is


@pytest.mark.parametrize("shading,entropy", [("flat", 0.0), ("gouraud", 0.0), ("flat", 1.0)])
def test_first_costs_do_not_depend_on_the_threads(shading, entropy, monkeypatch):
    """The engine's first pass (methods.engine.initial) costs every edge the same, with
    the same counters, on 1 thread or on 3 sharing chunks of 7 edges."""
    import methods.engine.initial as initial
    import methods.engine.simplify as simplify
    from methods.engine.policy import Policy
    from methods.imaging.counters import STAT_NAMES
    from methods.imaging.raster import rasterize_luminance
    from methods.imaging.state import ImageTerm
    from metrics.views import silhouette_cameras

    mesh = blob()
    cameras = silhouette_cameras(mesh)
    term = ImageTerm(tuple(cameras), rasterize_luminance(mesh, cameras, 40, 40,
                                                          shading=shading),
                     shading=shading, weight=1.0, entropy_weight=entropy)
    monkeypatch.setattr(initial, "CHUNK", 7)
    seen = []

    def both(mesh_arrays, rules, terms, scratch, images, threads=None):
        counted = [i for i, name in enumerate(STAT_NAMES) if not name.endswith("cycles")]
        runs = []
        for n in (3, 1):  # the single-thread run last: its counters stay in the state
            before = images.img.stats.copy()
            out = initial.first_costs(mesh_arrays, rules, terms, scratch, images, n)
            runs.append((out, (images.img.stats - before)[counted]))
            if n == 3:
                images.img.stats[:] = before
        (three, stats3), (one, stats1) = runs
        for x, y in zip(three, one):
            assert np.array_equal(x, y)
        assert np.array_equal(stats3, stats1) and stats1[0] > 0
        seen.append(len(one[0]))
        return one

    monkeypatch.setattr(simplify, "first_costs", both)
    policy = Policy(placement="endpoints" if entropy else "memoryless",
                    quadric_weight=0.0, memoryless_weight=0.0, boundary_weight=0.0)
    simplify.simplify_mesh(mesh, mesh.n_faces // 2, policy, image=term, max_collapses=3)
    assert seen and seen[0] > 3 * 7


@given(st.integers(0, 3000), st.integers(1, 8))
def test_edge_chunks_cut_the_edges_in_order_and_shrink(n, threads):
    from methods.engine.initial import CHUNK, MIN_CHUNK, edge_chunks

    chunks = edge_chunks(n, threads)
    assert [e for lo, hi in chunks for e in range(lo, hi)] == list(range(n))
    sizes = [hi - lo for lo, hi in chunks]
    assert all(MIN_CHUNK <= size <= CHUNK for size in sizes[:-1])
    assert all(0 < size <= CHUNK for size in sizes[-1:])
    assert sizes == sorted(sizes, reverse=True)  # the small ones last, for the tail
    if n >= 2 * CHUNK * threads:  # a large pass: full chunks first
        assert sizes[0] == CHUNK


def test_an_error_in_the_first_pass_stops_every_thread(monkeypatch):
    """An error while costing one chunk is raised, and the other thread stops taking
    chunks (it may finish the one it holds)."""
    import threading

    import methods.engine.initial as initial
    from methods.engine.policy import Policy
    from methods.engine.simplify import simplify_mesh

    monkeypatch.setattr(initial, "CHUNK", 4)
    calls = []
    lock = threading.Lock()

    def failing(lo, hi, *args):
        with lock:
            calls.append(lo)
            if len(calls) == 3:
                raise ValueError("a collapse affects more faces than AFFECTED_CAP")

    monkeypatch.setattr(initial, "_cost_range", failing)
    monkeypatch.setattr(initial.numba, "get_num_threads", lambda: 2)
    mesh = blob()
    with pytest.raises(ValueError, match="AFFECTED_CAP"):
        simplify_mesh(mesh, 10, Policy())
    assert len(calls) <= 10 < 3 * mesh.n_faces // 2 // 4  # not the other chunks


@pytest.mark.slow
@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
@pytest.mark.parametrize("method", ["image-driven", "entropy-twin"])
def test_one_and_two_threads_give_the_same_mesh_bit_for_bit(method, restore_threads):
    from bench.catalog.torus import make_torus
    from bench.core.method import run_method
    from bench.core.registry import registry

    cls = registry("method").load(method)
    mesh = blob() if method == "image-driven" else make_torus(24, 16, texture_size=64)
    results = []
    for threads in (1, 2):
        use_threads(threads)
        results.append(run_method(cls(), mesh, mesh.n_faces // 10).mesh)
    one, two = results
    assert np.array_equal(one.faces, two.faces)
    assert np.array_equal(one.positions, two.positions)
    if one.uv is not None:
        assert np.array_equal(one.uv, two.uv)


@pytest.mark.parametrize("command", [["run", "--models", "bunny"], ["simplify", "bunny",
                                                                    "out.obj", "-m", "qslim",
                                                                    "--faces", "100"]])
def test_a_bad_thread_count_is_one_line(command, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "bench", *command, "--threads", "0"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          check=False)
    assert proc.returncode != 0
    assert proc.stderr.strip() == "bench: error: --threads must be a whole number of at " \
        "least 1, got '0'"
    assert not (tmp_path / "out.obj").exists()


def _image_run(mesh, target, threads, monkeypatch, entropy=0.0):
    """simplify_mesh with Lindstrom & Turk's image term (or the viewpoint entropy) on
    ``threads`` threads."""
    import methods.engine.views as views
    from methods.engine.policy import Policy
    from methods.engine.simplify import simplify_mesh
    from methods.imaging.raster import rasterize_luminance
    from methods.imaging.state import ImageTerm
    from metrics.views import silhouette_cameras

    monkeypatch.setattr(views.numba, "get_num_threads", lambda: threads)
    cameras = silhouette_cameras(mesh)
    term = ImageTerm(tuple(cameras), rasterize_luminance(mesh, cameras, 48, 48),
                     weight=1.0, entropy_weight=entropy)
    policy = Policy(placement="endpoints" if entropy else "memoryless", quadric_weight=0.0,
                    memoryless_weight=0.0 if entropy else 1e-3, boundary_weight=0.0)
    return simplify_mesh(mesh, target, policy, image=term)


@pytest.mark.parametrize("entropy", [0.0, 1.0])
def test_shared_views_change_nothing(entropy, monkeypatch):
    """With helpers taking views of each evaluation and commit (methods.engine.views),
    the loop takes the serial run's collapses bit for bit, with as many evaluations; the
    helpers render views, and the run rebuilds its tile index on the way (which the
    helpers must pick up)."""
    from conftest import icosphere

    mesh = icosphere(3)
    one = _image_run(mesh, 40, 1, monkeypatch, entropy)
    three = _image_run(mesh, 40, 3, monkeypatch, entropy)
    assert one.stats["helper_views"] == 0
    assert three.stats["helper_views"] > 0 and three.stats["tile_rebuilds"] > 0
    for key in ("collapses", "cost_evaluations", "tile_rebuilds"):
        assert one.stats[key] == three.stats[key]
    assert np.array_equal(one.mesh.faces, three.mesh.faces)
    assert np.array_equal(one.mesh.positions, three.mesh.positions)
    for key in ("removed", "kept", "position", "cost"):
        assert np.array_equal(one.log[key], three.log[key])


def _run_with_failing_helper(monkeypatch, serve):
    """Run the image term on 2 threads with ``serve`` in place of the helpers' loop, in
    a thread of its own so that a loop waiting for ever fails the test instead of
    hanging it: the error the run raised."""
    import threading

    import methods.engine.views as views
    from conftest import icosphere

    outcome = []

    def run():
        try:
            _image_run(icosphere(3), 40, 2, monkeypatch)
        except BaseException as error:  # noqa: BLE001 - the caller looks at it
            outcome.append(error)

    monkeypatch.setattr(views, "serve_views", serve)
    loop = threading.Thread(target=run, daemon=True)
    loop.start()
    loop.join(timeout=120)
    assert not loop.is_alive(), "the loop kept waiting for a helper that had failed"
    assert len(outcome) == 1, "the run finished although its helper failed"
    return outcome[0]


def test_a_failing_helper_fails_the_run(monkeypatch):
    """An error in a helper thread is raised by the run, which does not wait for it."""

    def failing(*args):
        raise ValueError("a collapse affects more faces than AFFECTED_CAP")

    error = _run_with_failing_helper(monkeypatch, failing)
    assert isinstance(error, ValueError) and "AFFECTED_CAP" in str(error)


def test_a_helper_failing_mid_run_fails_the_run(monkeypatch):
    """A helper that fails while the loop waits for it to finish a job (here: on its
    way back after the first tile rebuild) makes the loop raise instead of waiting for
    ever, and the run raises the helper's error."""
    import methods.engine.views as views

    real, calls = views.serve_views, []

    def fails_second_time(*args):
        calls.append(args[0])
        if len(calls) > 1:
            raise ValueError("a collapse affects more faces than AFFECTED_CAP")
        return real(*args)

    error = _run_with_failing_helper(monkeypatch, fails_second_time)
    assert calls == [1, 1]
    assert isinstance(error, ValueError) and "AFFECTED_CAP" in str(error)
