"""Metric plug-ins: a third-party metric is computed by the protocol with the inputs it
declares and lands in the record, results.csv, index.html and ``bench check`` like a
built-in one.

The third-party package is written into a temporary folder and registered through
``BENCH_PLUGINS`` (the entry-point path of :mod:`bench.core.registry`, without installing).
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bench.core.mesh import Mesh
from bench.core.metric import NEEDS, Metric, Value
from bench.core.registry import Registry
from bench.io.meshio import save_mesh
from metrics.protocol import Protocol, evaluate

#: A third party's module: what its authors would ship, registered in their
#: pyproject.toml under [project.entry-points."bench.metrics"].
THIRD_PARTY = '''
import os

import numpy as np

from bench.core.metric import Metric, Value
from metrics.shading import luminance


def luma_gap(original, simplified, ctx):
    """Mean absolute luminance difference per view, and its mean over views."""
    gap = np.abs(luminance(ctx["original_images"]) - luminance(ctx["simplified_images"]))
    per_view = gap.mean(axis=(1, 2))
    return Value(per_view.mean(), per_view)


def far_share(original, simplified, ctx):
    """The one-sided maximum over the two-sided one, from the shared Metro result."""
    h = ctx["hausdorff"]
    return h["forward_max"] / h["symmetric_max"] if h["symmetric_max"] > 0 else 1.0


def broken(original, simplified, ctx):
    raise ZeroDivisionError("deliberately broken third-party metric")


LUMA_GAP = Metric("luma_gap", "luminance (0-255)",
                  os.environ.get("TP_LUMA_GAP_HIGHER") == "1",  # the direction under test
                  "mean |dY| over the protocol views", luma_gap, needs={"images"})
FAR_SHARE = Metric("far_share", "", None, "forward max / symmetric max", far_share,
                   needs={"hausdorff"})
BROKEN = Metric("tp_broken", "", False, "always raises", broken)
'''

PLUGINS = ("metric:luma_gap=tp_metrics:LUMA_GAP,metric:far_share=tp_metrics:FAR_SHARE,"
           "metric:tp_broken=tp_metrics:BROKEN")


# -- the Metric declaration ---------------------------------------------------------------

def test_a_metric_declares_known_needs_and_always_gets_the_meshes():
    m = Metric("x", "", None, "", lambda o, s, ctx: 0.0, needs={"images"})
    assert m.needs == {"images", "meshes"}
    assert Metric("y", "", None, "", lambda o, s, ctx: 0.0).needs == {"meshes"}
    with pytest.raises(ValueError, match=r"needs \['pixels'\].*choose from"):
        Metric("z", "", None, "", lambda o, s, ctx: 0.0, needs={"images", "pixels"})
    assert set(NEEDS) == {"meshes", "images", "view_meshes", "hausdorff", "silhouette",
                          "topology", "parts", "screen"}


def test_value_is_a_float_with_per_view_values():
    import pickle

    v = Value(np.float64(2.5), np.array([2.0, 3.0]))
    assert v == 2.5 and isinstance(v, float) and v.per_view == (2.0, 3.0)
    back = pickle.loads(pickle.dumps(v))
    assert back == 2.5 and back.per_view == (2.0, 3.0)


def test_image_metrics_render_nothing():
    from metrics import image

    with pytest.raises(ValueError, match="no simplified_images.*metrics.protocol.evaluate"):
        image.D_RMS.compute(None, None, {"original_images": np.zeros((24, 8, 8, 3), np.uint8)})
    # computing all three image metrics loads neither the protocol nor a renderer
    probe = textwrap.dedent("""
        import sys
        import numpy as np
        from metrics import image
        a = np.full((24, 16, 16, 3), 100, np.uint8)
        ctx = {"original_images": a, "simplified_images": a}
        values = [m.compute(None, None, ctx) for m in (image.D_RMS, image.SSIM, image.FLIP)]
        loaded = [m for m in ("metrics.protocol", "metrics.render", "pyrender")
                  if m in sys.modules]
        print(values, loaded)
    """)
    path = os.pathsep.join([str(Path(__file__).resolve().parents[1]),
                            os.environ.get("PYTHONPATH", "")])
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          check=False, timeout=120, env={**os.environ, "PYTHONPATH": path})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["[0.0,", "1.0,", "0.0]", "[]"]


# -- evaluate: shared inputs once, every metric, per-metric failures ---------------------

def _square(z: float = 0.0, n: int = 4) -> Mesh:
    """An n×n grid of unit cells in the plane z = ``z``, two triangles per cell."""
    xs, ys = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1))
    positions = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)])
    faces = []
    for i in range(n):
        for j in range(n):
            a = i * (n + 1) + j
            faces += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return Mesh(positions, np.array(faces, dtype=np.int32), name=f"square{z}")


@pytest.fixture
def counted(monkeypatch, tmp_path):
    """Counts of the protocol's expensive shared steps (the real functions, counted)."""
    from metrics import geometry, protocol

    monkeypatch.setenv("BENCH_CACHE", str(tmp_path / "cache"))
    calls = {"render_views": 0, "hausdorff": 0}
    for module, name in ((protocol, "render_views"), (geometry, "hausdorff")):
        real = getattr(module, name)

        def wrapper(*args, _real=real, _name=name, **kwargs):
            calls[_name] += 1
            return _real(*args, **kwargs)

        monkeypatch.setattr(module, name, wrapper)
    return calls


SMALL = Protocol(resolution=32, msaa=1, hausdorff_samples=500)


def test_evaluate_computes_shared_inputs_once_for_every_metric(counted):
    from metrics import geometry, image

    seen = {}

    def images_and_hausdorff(original, simplified, ctx):
        seen["ctx"] = ctx
        return Value(1.5, [float(v) for v in range(24)])

    mine = Metric("mine", "", True, "", images_and_hausdorff, needs={"images", "hausdorff"})
    metrics = [("d_rms", image.D_RMS), ("hausdorff_mean", geometry.HAUSDORFF_MEAN),
               ("hausdorff_max", geometry.HAUSDORFF_MAX), ("mine", mine)]
    ev = evaluate(_square(), _square(0.01), SMALL, metrics=metrics)
    # the original's images (cached on disk) and the result's: one render each;
    # three metrics read the Metro distances, sampled once
    assert counted == {"render_views": 2, "hausdorff": 1}
    assert seen["ctx"]["simplified_images"].shape == (24, 32, 32, 3)
    assert seen["ctx"]["hausdorff"] is not None and seen["ctx"]["protocol"] is SMALL
    assert ev.metrics["mine"] == 1.5 and ev.per_view["mine"] == list(map(float, range(24)))
    assert ev.metrics["hausdorff_max"] == ev.metrics["symmetric_max"]  # Metro fields stay
    assert set(ev.metrics) >= {"forward_mean", "backward_max", "d_rms", "hausdorff_mean"}
    assert len(ev.per_view["d_rms"]) == 24 and ev.errors == {}
    assert not seen["ctx"]["simplified_images"].flags.writeable


def test_a_failing_metric_is_an_error_of_that_metric_only(counted):
    from metrics import topology

    metrics = [("faces", topology.FACES),
               ("raises", Metric("raises", "", False, "", lambda o, s, c: 1 / 0)),
               ("text", Metric("text", "", False, "", lambda o, s, c: "high")),
               ("undefined", Metric("undefined", "", False, "", lambda o, s, c: math.nan)),
               ("nothing", Metric("nothing", "", False, "", lambda o, s, c: None))]
    ev = evaluate(_square(), _square(0.01, n=2), SMALL, metrics=metrics)
    assert ev.metrics["faces"] == 8 and isinstance(ev.metrics["faces"], int)
    assert ev.errors == {"raises": "ZeroDivisionError: division by zero",
                         "text": "TypeError: returned str 'high', not a number"}
    assert not {"raises", "text", "undefined", "nothing"} & set(ev.metrics)


def test_evaluate_uses_every_registered_metric(monkeypatch, tmp_path):
    import types
    from importlib.metadata import EntryPoint

    import bench.core.registry

    module = types.ModuleType("tp_registered")
    module.CONST = Metric("const", "", False, "", lambda o, s, c: 7.0)
    monkeypatch.setitem(sys.modules, "tp_registered", module)
    eps = [EntryPoint("const", "tp_registered:CONST", "bench.metrics"),
           EntryPoint("gone", "tp_no_such_module:X", "bench.metrics")]
    monkeypatch.setitem(bench.core.registry._cache, "metric", Registry("metric", eps))
    monkeypatch.setenv("BENCH_CACHE", str(tmp_path / "cache"))
    ev = evaluate(_square(), _square(0.01), SMALL)
    assert ev.metrics["const"] == 7.0 and "d_rms" not in ev.metrics  # only what is registered
    assert "cannot import tp_no_such_module" in ev.errors["gone"]


# -- end to end: record, results.csv, index.html, bench check -----------------------------
# One `bench run` of qslim on a 320-face icosphere under the real protocol (about 15 s,
# most of it FLIP and process start-up), shared by the tests below.

def _bench(*args, cwd, check=None, **env_extra):
    """``python -m bench ARGS`` with the third-party package on the path and registered."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(cwd) / "site"), env.get("PYTHONPATH", "")])
    env["BENCH_PLUGINS"] = PLUGINS
    env["BENCH_CACHE"] = str(Path(cwd) / "cache")  # never the user's cache
    env.update(env_extra)
    proc = subprocess.run([sys.executable, "-m", "bench", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600, check=False)
    if check is not None:
        assert proc.returncode == check, proc.stdout + proc.stderr
    return proc


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    import trimesh

    root = tmp_path_factory.mktemp("metric-plugins")
    (root / "site").mkdir()
    (root / "site" / "tp_metrics.py").write_text(textwrap.dedent(THIRD_PARTY))
    sphere = trimesh.creation.icosphere(subdivisions=2)  # 320 faces
    save_mesh(Mesh(sphere.vertices, sphere.faces, name="ico"), root / "ico.obj")
    _bench("run", "--models", "ico.obj", "--methods", "qslim", "--faces", "100", "--jobs", "1",
           "--out", "out", cwd=root, check=0)
    record = json.loads(next((root / "out" / "records").glob("*.json")).read_text())
    return root, record


@pytest.mark.slow
def test_listed_with_its_origin(run):
    root, _ = run
    listing = _bench("list", "metrics", cwd=root, check=0).stdout
    assert "luma_gap" in listing and "$BENCH_PLUGINS" in listing


@pytest.mark.slow
def test_in_the_record(run):
    _, record = run
    assert record["status"] == "ok"
    assert record["metrics"]["luma_gap"] > 0
    assert len(record["per_view"]["luma_gap"]) == 24
    assert record["metrics"]["luma_gap"] == pytest.approx(np.mean(record["per_view"]["luma_gap"]))
    assert 0 < record["metrics"]["far_share"] <= 1
    # the job stands; the broken metric is noted, its value missing
    assert "tp_broken" not in record["metrics"]
    assert record["metric_errors"] == {
        "tp_broken": "ZeroDivisionError: deliberately broken third-party metric"}
    assert record["metrics"]["d_rms"] > 0 and len(record["per_view"]["d_rms"]) == 24


@pytest.mark.slow
def test_in_results_csv_after_the_built_in_columns(run):
    from bench.records.results import CSV_COLUMNS

    root, record = run
    table = pd.read_csv(root / "out" / "results.csv")
    # the built-in columns keep their order; the other registered metrics follow by name
    # ... and last the intervals over views of those with per-view values
    assert list(table.columns) == CSV_COLUMNS + [
        "components_lost", "components_lost_area", "far_share", "luma_gap", "materials_lost",
        "non_manifold_edges", "render_vertices", "welded_vertices", "d_rms_lo", "d_rms_hi",
        "flip_lo", "flip_hi", "ssim_lo", "ssim_hi", "luma_gap_lo", "luma_gap_hi"]
    assert table.luma_gap[0] == pytest.approx(record["metrics"]["luma_gap"], rel=1e-5)


@pytest.mark.slow
def test_in_the_report(run):
    root, record = run
    html = (root / "out" / "index.html").read_text()
    start = html.index("<h2>All results</h2>")
    summary = html[start:html.index("</table>", start)]
    # a plug-in's metrics are among the columns behind the table's "all columns" toggle
    assert re.search(r"<th[^>]*>luma_gap</th>", summary)
    assert re.search(r"<th[^>]*>far_share</th>", summary)
    # with per-view values whose mean it is, the cell carries its interval as a tooltip
    assert re.search(rf"<td[^>]* title='95 % interval over views: [^']*'[^>]*>"
                     rf"{record['metrics']['luma_gap']:.4g}</td>", summary)
    assert "metric tp_broken failed" in html and "deliberately broken" in html


@pytest.mark.slow
def test_in_bench_check_with_its_direction(run, tmp_path):
    root, _ = run
    out = tmp_path / "out"
    shutil.copytree(root / "out", out)
    base = tmp_path / "base.json"
    _bench("baseline", str(out), "--out", str(base), cwd=root, check=0)
    entry = next(iter(json.loads(base.read_text())["entries"].values()))
    assert "luma_gap" in entry["metrics"]  # directed: gated
    assert "far_share" not in entry["metrics"]  # descriptive: recorded, not gated
    same = _bench("check", str(out), "--baseline", str(base), "--all", cwd=root, check=0)
    assert any("luma_gap" in line and line.endswith("same") for line in same.stdout.splitlines())

    path = next((out / "records").glob("*.json"))
    record = json.loads(path.read_text())
    record["metrics"]["luma_gap"] *= 1.5
    path.write_text(json.dumps(record))
    # registered as lower-is-better: 50 % higher is worse, and fails the gate
    worse = _bench("check", str(out), "--baseline", str(base), cwd=root, check=1)
    assert any("luma_gap" in line and line.endswith("worse") for line in worse.stdout.splitlines())
    # the same numbers under a registration that says higher is better: an improvement
    better = _bench("check", str(out), "--baseline", str(base), cwd=root, check=0,
                    TP_LUMA_GAP_HIGHER="1")
    assert any("luma_gap" in line and line.endswith("better")
               for line in better.stdout.splitlines())

    # a metric that raises where the baseline has a value fails the gate
    del record["metrics"]["luma_gap"]
    record["metric_errors"]["luma_gap"] = "RuntimeError: broke"
    path.write_text(json.dumps(record))
    failing = _bench("check", str(out), "--baseline", str(base), cwd=root, check=1)
    assert any("luma_gap" in line and "RuntimeError: broke" in line and
               line.endswith("newly failing") for line in failing.stdout.splitlines())


def test_a_metric_is_built_by_keyword_as_the_docs_show():
    from bench.core.metric import Metric

    def count(original, simplified, ctx):
        return simplified.n_faces

    by_keyword = Metric(name="n", unit="faces", higher_is_better=None, summary="faces",
                        compute=count, needs={"topology"})
    positional = Metric("n", "faces", None, "faces", count, needs={"topology"})
    assert by_keyword == positional
    assert by_keyword.needs == frozenset({"topology", "meshes"})
    assert by_keyword.direction == "descriptive"
