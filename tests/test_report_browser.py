"""The report as a browser shows it: headless Chromium opens index.html from disk
(file://), and the DOM it built is checked — the tables are there, every image and link
points at a file inside the run folder, the sorting script runs, the 3D view draws the
LOD it was asked for with WebGL (SwiftShader, Chromium's software renderer: no GPU
here) and no script fails — and screenshots are kept in the test's folder.

One small real run is shared by the module: a 320-face icosphere simplified by qslim at
two budgets, and by a plug-in that raises (tests/plugins/misbehaving.py), so the summary
has a failure to list first. The big run is that run's records and images copied to 13
models (scripts/synthetic_run.py), past the 50 jobs above which each model gets a page.
"""

from __future__ import annotations

import importlib.util
import os
import posixpath
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

from bench.io.meshio import save_mesh
from conftest import icosphere

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(shutil.which("chromium") is None,
                                 reason="Debian chromium not installed")]

ROOT = Path(__file__).parent.parent
PLUGINS = Path(__file__).parent / "plugins"


def _bench(*args, cwd) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(PLUGINS), env.get("PYTHONPATH", "")])
    env["BENCH_PLUGINS"] = "method:raise=misbehaving:Raise"
    env["BENCH_CACHE"] = str(Path(cwd) / "cache")  # never the user's cache
    return subprocess.run([sys.executable, "-m", "bench", *map(str, args)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=600, check=False)


#: WebGL on Chromium's software renderer, asked for explicitly (its automatic fallback
#: is deprecated); without --disable-gpu, which the 3D view must not be given.
WEBGL = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader")


def _chromium(profile: Path, *args: str, webgl: bool = False) -> subprocess.CompletedProcess:
    """Headless Chromium with ``args``; ``webgl``: with WebGL (SwiftShader) instead of
    no GPU at all."""
    gpu = WEBGL if webgl else ("--disable-gpu",)
    return subprocess.run(["chromium", "--headless", "--no-sandbox", *gpu,
                           "--disable-quic", "--no-first-run", "--disable-background-networking",
                           "--disable-component-update", "--disable-sync",
                           f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=120, check=True)


class _Dom(HTMLParser):
    """The elements of a dumped DOM: (tag, attributes) in document order, and the text
    of each script."""

    def __init__(self, text: str):
        super().__init__()
        self.elements: list[tuple[str, dict]] = []
        self.scripts: list[str] = []
        self._in_script = False
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.elements.append((tag, dict(attrs)))
        self._in_script = tag == "script"

    def handle_endtag(self, tag):
        self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.scripts.append(data)

    def all(self, tag: str) -> list[dict]:
        return [attrs for t, attrs in self.elements if t == tag]


def _dump(page: Path, profile: Path, fragment: str = "") -> str:
    return _chromium(profile, "--dump-dom", page.as_uri() + fragment).stdout


def _summary_rows(dom: str) -> list[str]:
    """The body rows of the summary table of a dumped DOM, as HTML, in their order."""
    table = dom[dom.index('<table id="summary"'):]
    return table[table.index("<tbody>"):table.index("</tbody>")].split("<tr")[1:]


def _target(run: Path, page: Path, url: str) -> Path:
    """The file a relative URL of ``page`` names; it must lie inside ``run``."""
    parts = urlsplit(url)
    assert not parts.scheme and not parts.netloc, url  # no data:, no network
    path = (page.parent / unquote(parts.path)).resolve()
    assert path.is_relative_to(run.resolve()), url
    # ... as a browser reads it too: ".." dropped textually, links not followed
    assert not posixpath.normpath(unquote(parts.path)).startswith(("../", "/")), url
    return path


def _broken(run: Path, page: Path, dom: _Dom) -> list[str]:
    """Every <img> source and <a> link of ``dom`` that names no file of ``run``."""
    urls = [a["src"] for a in dom.all("img")] + [a["href"] for a in dom.all("a")
                                                 if not a["href"].startswith("#")]
    return [url for url in urls if not _target(run, page, url).is_file()]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("browser")
    save_mesh(icosphere(2, name="ico"), root / "ico.obj")  # 320 faces
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim,raise", "--faces",
                  "100,60", "--jobs", "1", "--out", "out", cwd=root)
    assert proc.returncode == 1, proc.stderr  # the raising method failed, as it should
    return root / "out"


def test_the_report_opens_from_disk_with_no_broken_links(run, tmp_path):
    page = run / "index.html"
    text = _dump(page, tmp_path / "profile")
    dom = _Dom(text)
    tables = dom.all("table")
    assert {"id": "summary", "class": "sortable"} in tables and len(tables) >= 2
    rows = _summary_rows(text)
    assert len(rows) == 4
    assert all('class="failed"' in r for r in rows[:2])  # failures first, with the reason
    assert all("deliberate failure" in r for r in rows[:2])
    images = dom.all("img")
    # 3 curves, silhouettes and quality against time; the original's 4 sheet views once;
    # 2 sheets of 4 renders and 4 difference images
    assert len(images) == 5 + 4 + 2 * 8
    assert [a["alt"] for a in images].count("original, view 0") == 1
    assert text.count('<details class="sheets">') == 1  # the sheets start collapsed
    assert all(not a["src"].startswith("data:") for a in images)
    assert all(a.get("loading") == "lazy" for a in images)
    assert _broken(run, page, dom) == []
    assert any("sortable and filterable" in s for s in dom.scripts)
    assert dom.all("input")[0]["id"] == "filter"

    shot = tmp_path / "report.png"
    _chromium(tmp_path / "profile", "--window-size=1400,2400", f"--screenshot={shot}",
              page.as_uri())
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("L"), float)
    assert pixels.shape == (2400, 1400)
    assert pixels.std() > 20 and (pixels < 100).mean() > 0.01  # text, tables, images


def test_the_summary_sorts_in_the_browser(run, tmp_path):
    """``#sort=-faces`` clicks the faces header twice: largest first, empty cells last."""
    text = _dump(run / "index.html", tmp_path / "profile", "#sort=-faces")
    assert ('<th aria-sort="descending">faces</th>' in text)
    rows = _summary_rows(text)
    assert "failed" not in rows[0] and "failed" in rows[-1]
    assert "<td>100</td>" in rows[0] and "<td>60</td>" in rows[1]


def _synthetic_run(source: Path, dest: Path, jobs: int, models: int) -> None:
    spec = importlib.util.spec_from_file_location("synthetic_run",
                                                  ROOT / "scripts" / "synthetic_run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.synthesise(source, dest, jobs, models)


def test_a_big_run_has_a_page_per_model(run, tmp_path):
    big = tmp_path / "big"
    _synthetic_run(run, big, jobs=51, models=13)  # 52 jobs
    proc = _bench("report", big, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    pages = sorted(big.glob("model-*.html"))
    assert len(pages) == 13
    index = _Dom(_dump(big / "index.html", tmp_path / "profile"))
    assert index.all("img") == []  # the index holds the table and the links only
    assert {a["href"] for a in index.all("a")} >= {p.name for p in pages}
    assert _broken(big, big / "index.html", index) == []
    shown = {}  # model page -> the models whose results it shows
    for page in pages[:3]:
        dom = _Dom(_dump(page, tmp_path / "profile"))
        assert _broken(big, page, dom) == []
        folders = [unquote(a["src"]).split("/")[-2] for a in dom.all("img")
                   if "/thumbs/" in a["src"] and "original__" not in a["src"]]
        shown[page.name] = {f.split("__")[0] for f in folders}
        assert _viewer(dom)["data-status"] == "closed"  # its model's 3D view: its meshes
        lods = [unquote(o["data-lod"]) for o in dom.all("option") if "data-lod" in o]
        assert lods and {p.split("/")[-1].split("__")[0] for p in lods} == shown[page.name]
    assert all(len(models) == 1 for models in shown.values()), shown
    assert len(set.union(*shown.values())) == 3


def test_a_comparison_grid_puts_the_methods_side_by_side(tmp_path):
    """Two methods at one budget: one grid, a row per sheet view, the original then a
    column per method, each cell's render and difference image and its d_RMS, the best
    of each row marked, and the toggle's script; every image loads from disk."""
    save_mesh(icosphere(2, name="ico"), tmp_path / "ico.obj")
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim,fast-simplification",
                  "--faces", "100", "--jobs", "1", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    page = tmp_path / "out" / "index.html"
    text = _dump(page, tmp_path / "profile")
    dom = _Dom(text)
    grids = [t for t in dom.all("table") if t.get("class") == "grid"]
    assert len(grids) == 1
    # the model's curves (d_RMS, FLIP, Hausdorff) and a link from them to the grid
    plots = [i["alt"] for i in dom.all("img") if i.get("alt", "").endswith(" plot")]
    assert plots == ["d_rms plot", "flip plot", "hausdorff_mean plot"]
    assert [a["href"] for a in dom.all("a") if a.get("href", "").startswith("#grid-")] == [
        "#" + grids[0]["id"]]
    grid = text[text.index('class="grid"'):]
    grid = grid[:grid.index("</table>")]
    head = grid[grid.index("<thead>"):grid.index("</thead>")]
    assert [h for h in ("original", "qslim", "fast-simplification") if h in head] == [
        "original", "qslim", "fast-simplification"]
    rows = grid.split("<tr>")[2:]  # after the header row
    assert len(rows) == 4  # the sheet views
    for row in rows:
        assert row.count('class="best"') >= 1 and row.count("d_RMS ") == 2
        assert row.count('class="view"') == 2 and row.count('class="diff"') == 2
    assert any("show-diff" in s for s in dom.scripts)
    assert [a for a in dom.all("input") if a.get("class") == "diff-toggle"]
    assert _broken(tmp_path / "out", page, dom) == []
    shot = tmp_path / "grid.png"
    _chromium(tmp_path / "profile", "--window-size=1400,2400", f"--screenshot={shot}",
              page.as_uri())


def _viewer(dom: _Dom) -> dict:
    views = [a for a in dom.all("div") if a.get("class") == "viewer3d"]
    assert len(views) == 1, views
    return views[0]


def test_the_3d_view_draws_the_chosen_lod_from_disk(run, tmp_path):
    """``#view3d=<model>&lod=1`` opens the model's view on its second LOD (60 faces
    asked): three.js and both GLBs load from the folder, WebGL draws them, and the page
    reports the triangles it drew — the record's face count — with no script error."""
    import json

    records = [json.loads(p.read_text()) for p in (run / "records").glob("*.json")]
    faces = {r["job"]["target_faces"]: r["metrics"]["faces"] for r in records
             if r["status"] == "ok"}
    page = run / "index.html"
    closed = _viewer(_Dom(_dump(page, tmp_path / "profile")))
    assert closed["data-status"] == "closed"
    lods = [o for o in _Dom(page.read_text()).all("option") if "data-lod" in o]
    assert [int(o["data-faces"]) for o in lods] == [faces[100], faces[60]]
    for option in lods:  # every file the view may load lies in the run folder
        for name in ("data-lod", "data-original", "data-lod-glb", "data-original-glb"):
            assert _target(run, page, option[name]).is_file()
    assert _target(run, page, closed["data-three"]).is_file()

    fragment = f"#view3d={closed['data-model']}&lod=1"
    text = _chromium(tmp_path / "profile", "--virtual-time-budget=30000", "--dump-dom",
                     page.as_uri() + fragment, webgl=True).stdout
    dom = _Dom(text)
    view = _viewer(dom)
    assert view["data-status"] == "ready", text[text.index("v3d-status"):][:400]
    assert int(view["data-faces"]) == faces[60]
    assert int(view["data-original-faces"]) == 320
    assert (view["data-shading"], view["data-wireframe"]) == ("flat", "false")
    assert len(dom.all("canvas")) == 1
    assert not [a for a in dom.all("pre") if a.get("id") == "script-errors"]
    assert "triangles drawn" in text
    assert _broken(run, page, dom) == []  # the GLB download links too

    # the whole page in one window (headless Chromium's screenshot of a page scrolled to
    # the view came out blank), then the view cut out of it
    shot = tmp_path / "page-with-3d-view.png"
    _chromium(tmp_path / "profile", "--virtual-time-budget=30000", "--window-size=1200,6000",
              f"--screenshot={shot}", page.as_uri() + fragment, webgl=True)
    from PIL import Image

    pixels = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    gray = (np.abs(pixels - 128) <= 1).all(axis=2)  # the protocol's background
    rows = np.flatnonzero(gray.sum(axis=1) >= 50)  # rows of gray, in runs (images and
    runs = np.split(rows, np.flatnonzero(np.diff(rows) > 20) + 1)  # the canvas) ...
    rows = next(run for run in runs if run.size > 200)  # ... the canvas's, first
    columns = np.flatnonzero(gray[rows].any(axis=0))  # ... and its columns
    view = pixels[rows[0]:rows[-1] + 1, columns[0]:columns[-1] + 1]
    Image.fromarray(view.astype(np.uint8)).save(tmp_path / "viewer.png")
    half = view.shape[1] // 2
    for side in (view[:, :half], view[:, half:]):  # a lit grey sphere in each viewport
        lit = ~(np.abs(side - 128) <= 1).all(axis=2) & (side.std(axis=2) < 8)
        assert lit.mean() > 0.05


def test_the_3d_view_starts_in_the_chosen_jobs_shading(run, tmp_path):
    """A run with flat and Gouraud jobs (a copy of the module's run, resumed with one
    Gouraud job): the view starts in the shading the LOD the address picks was evaluated
    with, not the first entry's; ``&shading=`` still overrides it. The address is read
    as key=value pairs: a malformed % escape does not stop the view, and a value holding
    "wireframe" is no ``wireframe`` key."""
    folder = tmp_path / "run"
    shutil.copytree(run, folder)
    proc = _bench("run", "--models", "ico.obj", "--methods", "qslim", "--faces", "60",
                  "--shading", "gouraud", "--jobs", "1", "--resume", "--out", folder,
                  cwd=run.parent)
    assert proc.returncode == 1 and "2 of 5 jobs failed" in proc.stderr, proc.stderr  # raise's
    page = folder / "index.html"
    static = _Dom(page.read_text())
    model = _viewer(static)["data-model"]
    lods = [o for o in static.all("option") if "data-lod" in o]
    shadings = [o["data-shading"] for o in lods]
    assert shadings[0] == "flat" and sorted(shadings) == ["flat", "flat", "smooth"]
    smooth, flat = shadings.index("smooth"), len(shadings) - 1 - shadings[::-1].index("flat")
    cases = {  # address: (LOD, shading, wireframe)
        f"#view3d={model}&lod={smooth}&note=wireframe-cube": (smooth, "smooth", "false"),
        f"#view3d={model}&lod={smooth}&shading=flat": (smooth, "flat", "false"),
        f"#x=%E0%A4%A&view3d=%{model}&lod={flat}&wireframe": (flat, "flat", "true"),
    }
    for fragment, (lod, shading, wire) in cases.items():
        text = _chromium(tmp_path / "profile", "--virtual-time-budget=30000", "--dump-dom",
                         page.as_uri() + fragment, webgl=True).stdout
        dom = _Dom(text)
        view = _viewer(dom)
        assert view["data-status"] == "ready", (fragment, text[text.index("v3d-status"):][:400])
        assert view["data-faces"] == lods[lod]["data-faces"], fragment
        assert (view["data-shading"], view["data-wireframe"]) == (shading, wire), fragment
        assert not [a for a in dom.all("pre") if a.get("id") == "script-errors"], fragment
    # a reader who picks the Gouraud job in the selector, then opens the view: a copy of
    # the page whose last script does that
    clicks = ("<script>var s = document.querySelector('.v3d-lod');"
              f"s.selectedIndex = {smooth}; s.dispatchEvent(new Event('change'));"
              "document.querySelector('.v3d-open').click();</script></body>")
    chosen = folder / "chosen.html"
    chosen.write_text(page.read_text().replace("</body>", clicks))
    text = _chromium(tmp_path / "profile", "--virtual-time-budget=30000", "--dump-dom",
                     chosen.as_uri(), webgl=True).stdout
    view = _viewer(_Dom(text))
    assert view["data-status"] == "ready", text[text.index("v3d-status"):][:400]
    assert (view["data-faces"], view["data-shading"]) == (lods[smooth]["data-faces"], "smooth")


@pytest.mark.parametrize("broken", ["no three.js", "no WebGL"])
def test_the_3d_view_says_why_it_cannot_draw(run, tmp_path, broken):
    """A missing library or a browser without WebGL: the reason in the page, as text."""
    folder = tmp_path / "run"
    shutil.copytree(run, folder)
    flags = ["--disable-webgl", "--disable-3d-apis"] if broken == "no WebGL" else []
    if broken == "no three.js":
        (folder / "vendor" / "three.min.js").unlink()
    page = folder / "index.html"
    model = _viewer(_Dom(page.read_text()))["data-model"]
    text = _chromium(tmp_path / "profile", *flags, "--virtual-time-budget=20000",
                     "--dump-dom", page.as_uri() + f"#view3d={model}", webgl=True).stdout
    view = _viewer(_Dom(text))
    assert view["data-status"] == "error"
    status = text[text.index("v3d-status"):][:300]
    why = "cannot load vendor/three.min.js" if broken == "no three.js" else \
        "WebGL is not available in this browser"
    assert why in status, status


#: A script appended to a copy of a page: once it has loaded, the page's size, the window's
#: width and the loaded width of every image, as attributes of <body> for --dump-dom.
_PROBE = ("<script>addEventListener('load', function () {"
          "var d = document.documentElement, b = document.body;"
          "b.setAttribute('data-scroll-width', d.scrollWidth);"
          "b.setAttribute('data-inner-width', innerWidth);"
          "b.setAttribute('data-height', d.scrollHeight);"
          "b.setAttribute('data-unloaded', Array.prototype.filter.call(document.images,"
          " function (i) { return i.complete && i.naturalWidth === 0; }).length);"
          "});</script></body>")


def _probed(page: Path, extra: str = "") -> Path:
    """A copy of ``page`` beside it (relative links still hold) with :data:`_PROBE` and
    ``extra`` before ``</body>``."""
    copy = page.with_name("probed-" + page.name)
    copy.write_text(page.read_text().replace("</body>", extra + _PROBE))
    return copy


def _colour_present(shot: Path, colour: str) -> bool:
    from PIL import Image

    rgb = tuple(int(colour[i:i + 2], 16) for i in (1, 3, 5))
    pixels = np.asarray(Image.open(shot).convert("RGB")).reshape(-1, 3)
    return bool((np.abs(pixels.astype(int) - rgb).max(axis=1) <= 8).any())


def test_the_error_box_shows_errors_thrown_on_purpose(run, tmp_path):
    """The catcher in <head> shows an error thrown in <head> before <body> exists, one
    thrown in <body> and a rejected promise nobody handled; the page as written has no
    box (so the other tests' "no error box" can fail)."""
    from bench.report.page import ERRORS_SCRIPT

    page = run / "index.html"
    text = page.read_text()
    assert ERRORS_SCRIPT in text
    broken = run / "thrown.html"
    broken.write_text(
        text.replace(ERRORS_SCRIPT, ERRORS_SCRIPT + "<script>null.inHead();</script>", 1)
        .replace("</body>", "<script>throw new Error('thrown on purpose');</script>"
                 "<script>Promise.reject(new Error('rejected on purpose'));</script></body>"))
    dom = _dump(broken, tmp_path / "profile")
    assert '<pre id="script-errors"' in dom
    box = dom[dom.index('<pre id="script-errors"'):]
    box = box[:box.index("</pre>")]
    assert "thrown on purpose" in box and "rejected on purpose" in box
    assert "inHead" in box  # null.inHead(): "Cannot read properties of null"
    assert box.count("script error:") == 3
    assert 'id="script-errors"' not in _dump(page, tmp_path / "profile")


def test_the_leaderboard_opens_the_page_and_nothing_scrolls_sideways_at_1400_px(run, tmp_path):
    """At 1,400 px the first screen shows the leaderboard (its method swatch in the
    screenshot), the page has no horizontal scroll, the summary's key columns fit, and
    every image (the quality-against-time plot among them) loads."""
    from bench.report.styles import method_styles

    probed = _probed(run / "index.html")
    text = _chromium(tmp_path / "profile", "--window-size=1400,900", "--hide-scrollbars",
                     "--virtual-time-budget=10000", "--dump-dom", probed.as_uri()).stdout
    dom = _Dom(text)
    body = dom.all("body")[0]
    assert int(body["data-scroll-width"]) <= int(body["data-inner-width"]) == 1400
    assert body["data-unloaded"] == "0"
    assert text.index('id="leaderboard"') < text.index('id="summary"')
    assert {"id": "lb-0", "class": "leaderboard sortable"} in dom.all("table")
    assert any(a.get("id") == "across-models" for a in dom.all("table"))
    plots = [a for a in dom.all("img") if a["alt"].startswith("quality against time")]
    assert len(plots) == 1 and "quality-time" in plots[0]["src"]
    assert 'id="script-errors"' not in text

    shot = tmp_path / "leaderboard.png"
    _chromium(tmp_path / "profile", "--window-size=1400,900", "--hide-scrollbars",
              f"--screenshot={shot}", (run / "index.html").as_uri())
    assert _colour_present(shot, method_styles(["qslim"])["qslim"].colour)


def test_the_scatter_shows_its_points_and_its_legend_outside_the_axes(run, tmp_path):
    """The quality-against-time plot, opened as the browser draws it: qslim's points in
    qslim's colour, the Pareto front named, the legend right of the axes, tick labels
    in plain digits."""
    from bench.report.styles import method_styles

    (svg,) = (run / "images" / "plots").glob("*quality-time*.svg")
    source = svg.read_text()
    assert "Pareto front" in source and "qslim" in source
    assert "10^" not in source and "\\times" not in source and "×" not in source
    page = tmp_path / "plot.html"
    page.write_text(
        "<!doctype html><html><body style='margin:0'>" + source[source.index("<svg"):]
        + "<script>var r = function (id) { return document.getElementById(id)"
        ".getBoundingClientRect(); };"
        "document.body.setAttribute('data-legend-left', r('legend_1').left);"
        "var right = 0; document.querySelectorAll('g[id^=axes_]').forEach(function (a) {"
        " right = Math.max(right, a.firstElementChild.getBoundingClientRect().right); });"
        "document.body.setAttribute('data-axes-right', right);"
        "</script></body></html>")
    dom = _Dom(_dump(page, tmp_path / "profile"))
    body = dom.all("body")[0]
    # the legend starts right of every axes' frame (its background patch, the first
    # element of its group; the legend itself is drawn inside the last axes' group)
    assert float(body["data-legend-left"]) >= float(body["data-axes-right"]) - 1

    shot = tmp_path / "scatter.png"
    _chromium(tmp_path / "profile", "--window-size=1200,500", f"--screenshot={shot}",
              svg.as_uri())
    assert _colour_present(shot, method_styles(["qslim"])["qslim"].colour)
