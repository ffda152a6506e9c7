"""The progress of a long simplification: what a method tells a listener, and the
terminal bar of ``bench simplify`` (bench.core.progress, bench.commands.progress_bar)."""

from __future__ import annotations

import io
import threading
import time

import numpy as np

from bench.commands.progress_bar import FacesBar
from bench.core import progress
from conftest import blob
from methods.engine.policy import Policy
from methods.engine.simplify import simplify_mesh
from methods.image_driven import ImageDriven


class Recorder:
    """A listener that keeps every event in order."""

    def __init__(self):
        self.events = []

    def stage(self, name):
        self.events.append(("stage", name))

    def begin(self, total):
        self.events.append(("begin", total))

    def advance(self, removed):
        self.events.append(("advance", removed))

    def end(self):
        self.events.append(("end",))


def _loops(events):
    """[(total, [removed, ...]), ...] per begin/end pair."""
    loops = []
    for event in events:
        if event[0] == "begin":
            loops.append((event[1], []))
        elif event[0] == "advance":
            loops[-1][1].append(event[1])
    return loops


def test_the_engine_reports_the_exact_faces_removed_at_the_end():
    mesh = blob()
    with progress.listening(Recorder()) as recorder:
        result = simplify_mesh(mesh, 60, Policy())
    (total, removed), = _loops(recorder.events)
    assert total == mesh.n_faces - 60
    assert removed[-1] == mesh.n_faces - result.mesh.n_faces
    assert removed == sorted(removed)
    assert recorder.events[0] == ("begin", total) and recorder.events[-1] == ("end",)


def test_without_a_listener_no_thread_starts(monkeypatch):
    started, start = [], threading.Thread.start

    def recording_start(thread):
        started.append(thread.name)
        start(thread)

    monkeypatch.setattr(threading.Thread, "start", recording_start)
    simplify_mesh(blob(1), 40, Policy())
    assert "bench-progress" not in started
    with progress.listening(Recorder()):
        simplify_mesh(blob(1), 40, Policy())
    assert "bench-progress" in started


def test_a_method_names_its_stages_before_each_loop():
    mesh = blob()
    with progress.listening(Recorder()) as recorder:
        result = ImageDriven(resolution=32, presimplify_faces=200).simplify(mesh, 80)
    kinds = [e[0] for e in recorder.events if e[0] != "advance"]
    assert kinds == ["stage", "begin", "end", "stage", "begin", "end"]
    stages = [e[1] for e in recorder.events if e[0] == "stage"]
    assert stages[0].startswith("pre-simplifying to 200 faces")
    (pre_total, pre), (total, removed) = _loops(recorder.events)
    assert (pre_total, pre[-1]) == (mesh.n_faces - 200, mesh.n_faces - 200)
    assert total == 200 - 80 and removed[-1] == 200 - result.mesh.n_faces


def test_readings_come_while_the_work_runs(monkeypatch):
    monkeypatch.setattr(progress, "POLL_SECONDS", 0.005)
    alive = np.ones(10, bool)
    with progress.listening(Recorder()) as recorder, progress.watching_faces(alive, 2):
        for f in range(8):
            alive[f] = False
            time.sleep(0.05)  # releases the GIL, as the engine's loop does
    (total, removed), = _loops(recorder.events)
    assert total == 8 and removed[-1] == 8
    assert any(0 < r < 8 for r in removed)
    assert removed == sorted(removed)


def test_the_bar_shows_faces_removed_and_is_silent_before_its_delay():
    out = io.StringIO()
    bar = FacesBar("bunny: quadric", delay=0.0, file=out)
    bar.stage("pre-simplifying")
    bar.begin(400)
    bar.advance(100)
    bar.advance(400)
    bar.end()
    text = out.getvalue()
    assert "bunny: quadric, pre-simplifying" in text and "/400" in text
    quiet = io.StringIO()
    bar = FacesBar("bunny: quadric", delay=60.0, file=quiet)
    bar.begin(400)
    bar.advance(200)
    bar.end()
    assert quiet.getvalue() == ""
