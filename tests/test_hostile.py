"""A hostile-input corpus: bad or odd arguments, run folders, records and baselines given
to ``bench`` as a user would, in a subprocess.

Every case is generated here at test time (no binary blobs) in a folder of its own, and
says what it expects: a clean error (exit code 2, exactly one line on stderr,
``bench: error: ...`` matching a pattern, nothing on stdout) or a correct result (its
exit code and a pattern in its output). For every case: no traceback, no file that
existed before is changed or removed (hashes before and after), and an error leaves no
run folder behind. The cases run three at a time (start-up dominates); none renders
except the one real run (two tiny meshes with qslim). Ctrl-C in ``bench run`` has a test
of its own at the end.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from bench.harness.report import SCRIPT as PAGE_SCRIPT
from bench.io.meshio import save_mesh
from bench.mesh import Mesh
from conftest import TET_FACES, TET_POSITIONS, icosphere

PLUGINS = Path(__file__).parent / "plugins"


@dataclass(frozen=True)
class Case:
    """``bench ARGS`` run in a folder of its own, made by ``files``."""

    args: tuple[str, ...]
    #: "error" (a clean one-line error) or "ok" (a correct result)
    expect: str
    #: regular expression: searched in the error line, or in stdout + stderr when ok
    pattern: str
    files: Callable[[Path], None] | None = None
    #: exit code; default 2 for an error, 0 for a correct result
    code: int | None = None
    #: paths (relative to the folder) that must exist after the case, or must not
    creates: tuple[str, ...] = ()
    absent: tuple[str, ...] = ("out",)
    #: more checks: after(folder, process)
    after: Callable | None = None
    #: renders (started first, so that it overlaps the quick cases)
    slow: bool = False


CASES: dict[str, Case] = {}


def case(name: str, *args: str, expect: str = "error", pattern: str = "", **kw) -> None:
    assert name not in CASES, name
    CASES[name] = Case(tuple(args), expect, pattern, **kw)


# -- inputs --------------------------------------------------------------------------------

def tet(folder: Path, name: str = "tet.obj") -> None:
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    save_mesh(Mesh(TET_POSITIONS, TET_FACES), path)


def a_file(name: str, text: str = "not a folder\n") -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        tet(folder)
        (folder / name).write_text(text)
    return make


def record(label: str = "q", status: str = "ok", model: str = "m", **changes) -> dict:
    """A record as the runner writes it (numbers made up; an ok one without images)."""
    from metrics.protocol import Protocol

    r = {"schema": 1, "status": status, "error": None if status == "ok" else "it broke",
         "job": {"model": model, "method": label.split("[")[0], "params": {}, "label": label,
                 "target_faces": 100, "protocol": Protocol().as_dict()},
         "model": {"name": model, "hash": "0" * 40, "faces": 1000},
         "method": {"name": label, "version": "1", "view_dependent": False},
         "metrics": {"faces": 100, "d_rms": 5.0, "ssim": 0.9, "hausdorff_mean": 0.01,
                     "silhouette_mean": 2.0, "boundary_edges": 0, "seam_cracks": 0},
         "per_view": {"d_rms": [5.0] * 24}, "silhouette_histogram": [1.0] + [0.0] * 20,
         "stats": {"wall_seconds": 1.0, "tri_per_s": 900.0, "peak_mb": 10.0},
         "artifacts": [], "environment": {}}
    r.update(changes)
    return r


FAILED = record("f", status="failed")  # a good record that draws nothing (fast reports)
SECRET = "TOPSECRET-2b9e"


def run_folder(*records, extra: Callable[[Path], None] | None = None) -> Callable:
    """A run folder ``run`` with ``records`` (dicts, or str for a file's raw text), a
    secret beside it and ``extra(folder)`` done last."""
    def make(folder: Path) -> None:
        (folder / "run" / "records").mkdir(parents=True)
        for i, r in enumerate(records):
            text = r if isinstance(r, str) else json.dumps(r)
            (folder / "run" / "records" / f"r{i}.json").write_text(text)
        (folder / "secret.txt").write_text(SECRET + "\n")
        if extra:
            extra(folder)
    return make


def page_is_safe(folder: Path, proc) -> None:
    """No script in the page but the report's own (once), no secret, no terminal escape."""
    page = (folder / "run" / "index.html").read_text()
    assert page.count(PAGE_SCRIPT) == 1
    page = page.replace(PAGE_SCRIPT, "")
    assert "<script" not in page.lower() and SECRET not in page
    assert "\x1b" not in proc.stdout


def baseline_file(data, name: str = "base.json") -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        text = data if isinstance(data, str) else json.dumps(data)
        (folder / name).write_text(text)
    return make


def both(*makers) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        for m in makers:
            m(folder)
    return make


# -- bench run: arguments --------------------------------------------------------------------

RUN = ("run", "--models", "tet.obj", "--methods", "qslim", "--out", "out")

for value in ("nan", "-1", "0", "inf", "abc", "1e400"):
    case(f"run --timeout {value}", *RUN, f"--timeout={value}", files=tet,
         pattern=rf"^--timeout must be a number of seconds above 0, got '{re.escape(value)}'$")
for value in ("-4", "0", "1.5", "abc", ""):
    case(f"run --jobs {value!r}", *RUN, f"--jobs={value}", files=tet,
         pattern=rf"^--jobs must be a whole number of at least 1, got '{re.escape(value)}'$")
for value in ("abc", "100.5", "0", "-3", "1e3", "2,x"):
    bad = value.split(",")[-1]
    case(f"run --faces {value}", *RUN, f"--faces={value}", files=tet,
         pattern=rf"^--faces must be a whole number of at least 1, got '{re.escape(bad)}'$")
case("run --faces ,", *RUN, "--faces=,", files=tet, pattern=r"^--faces: no budget given in ','$")
for value in ("nan", "0", "1.5", "abc", "-0.1", "inf"):
    case(f"run --ratios {value}", *RUN, f"--ratios={value}", files=tet,
         pattern=rf"^--ratios: each must be a fraction in \(0, 1\], got '{re.escape(value)}'$")
case("run --out names a file", *RUN[:-1], "taken.txt", files=a_file("taken.txt"),
     pattern=r"^--out taken\.txt: exists and is not a directory$")
case("run --out below a file", *RUN[:-1], "taken.txt/run", files=a_file("taken.txt"),
     pattern=r"^--out taken\.txt/run: .*taken\.txt is not a directory$")
for methods, message in {
        "qslim[qualitythr=0.5": r"'\[' not closed in 'qslim\[qualitythr=0\.5'",
        "meshopt,qslim[qualitythr=0.5,meshopt": r"'\[' not closed in 'qslim\[qualitythr=0\.5,meshopt'",
        "qslim]": r"unmatched \] in 'qslim\]'",
        "qslim[[qualitythr=0.5]]": r"nested \[ in 'qslim\[\['",
        "qslim[qualitythr=0.5]x": r"'qslim\[qualitythr=0\.5\]x': parameters are written",
        "[qualitythr=0.5]": r"'\[qualitythr=0\.5\]': parameters are written",
        "qslim[qualitythr]": r"'qslim\[qualitythr\]': parameters are written",
        "qslim[qualitythx=1]": r"unknown parameter 'qualitythx'; did you mean 'qualitythr'",
        "qslim[qualitythr=abc]": r"parameter 'qualitythr' expects float, got 'abc'",
        "qslm": r"unknown method 'qslm'; did you mean 'qslim'"}.items():
    case(f"run --methods {methods}", "run", "--models", "tet.obj", "--methods", methods,
         "--out", "out", files=tet, pattern=message)
case("run unknown model", "run", "--models", "tetx", "--methods", "qslim", "--out", "out",
     pattern=r"unknown model 'tetx'")
case("run missing model file", "run", "--models", "gone.obj", "--methods", "qslim",
     "--out", "out", pattern=r"gone\.obj: no such file")
case("run unknown suite", "run", "--suite", "cii", "--out", "out",
     pattern=r"unknown suite 'cii'; did you mean 'ci'")


# -- bench report: run folders and records -------------------------------------------------

REPORT = ("report", "run")
WARNING = r"^bench: warning: run/records/r1\.json: not a"
case("report missing folder", "report", "nowhere", pattern=r"nowhere: not a run directory")
case("report a file", "report", "secret.txt", files=run_folder(),
     pattern=r"secret\.txt: not a run directory")
case("report no records folder", "report", ".", pattern=r"not a run directory \(no records/")
case("report no records", *REPORT, expect="ok", files=run_folder(),
     pattern=r"^bench: wrote run/index\.html$", creates=("run/index.html", "run/results.csv"))
for name, text in {
        "malformed JSON": '{"schema": 1, "status": "ok"',
        "a JSON list": "[1, 2]",
        "a JSON string": '"ok"',
        "empty file": "",
        "binary": "\x00\x01\xfe\xff",
        "deeply nested": "[" * 50_000 + "]" * 50_000,
        "no job": json.dumps({k: v for k, v in FAILED.items() if k != "job"}),
        "no status": json.dumps({k: v for k, v in FAILED.items() if k != "status"}),
        "job a list": json.dumps(FAILED | {"job": []}),
        "target faces a string": json.dumps(FAILED | {"job": FAILED["job"] | {"target_faces": "1"}}),
        "target faces a bool": json.dumps(FAILED | {"job": FAILED["job"] | {"target_faces": True}}),
        "label a number": json.dumps(FAILED | {"job": FAILED["job"] | {"label": 7}}),
        "protocol missing": json.dumps(FAILED | {"job": {k: v for k, v in FAILED["job"].items()
                                                         if k != "protocol"}}),
        "protocol shading odd": json.dumps(FAILED | {"job": FAILED["job"] | {
            "protocol": FAILED["job"]["protocol"] | {"shading": "phong"}}}),
        "metric a string": json.dumps(record(metrics={"d_rms": "5"})),
        "ok without metrics": json.dumps({k: v for k, v in record().items() if k != "metrics"}),
        "per view not numbers": json.dumps(record(per_view={"d_rms": ["a"]})),
        "model hash a path": json.dumps(record(model={"hash": "../../../etc", "faces": 1})),
        "newer schema": json.dumps(FAILED | {"schema": 99}),
        "schema a string": json.dumps(FAILED | {"schema": "1"}),
        "status a script": json.dumps(FAILED | {"status": "<script>alert(1)</script>"}),
        "error a list": json.dumps(FAILED | {"error": ["x"]})}.items():
    case(f"report record {name}", *REPORT, expect="ok", files=run_folder(FAILED, text),
         pattern=WARNING if name != "newer schema" else
         r"^bench: warning: run/records/r1\.json: result schema 99 is newer than this bench",
         creates=("run/index.html",), after=page_is_safe)
case("report record is a folder", *REPORT, expect="ok", files=run_folder(
    FAILED, extra=lambda d: (d / "run" / "records" / "r1.json").mkdir()),
    pattern=WARNING, after=page_is_safe)
def linked_record(folder: Path) -> None:
    (folder / "outside.json").write_text(json.dumps(FAILED | {"error": SECRET}))
    (folder / "run" / "records" / "r1.json").symlink_to(folder / "outside.json")


case("report record links outside", *REPORT, expect="ok",
     files=run_folder(FAILED, extra=linked_record),
     pattern=r"r1\.json: links outside the run folder", after=page_is_safe)
case("report strings with markup", *REPORT, expect="ok", files=run_folder(
    record(label="q[x=<script>alert(1)</script>]", model="<img src=x onerror=alert(1)>",
           metric_errors={"flip": "</pre><script>alert(2)</script>"}),
    FAILED | {"error": "</pre><script>alert(3)</script>"}),
    pattern=r"^bench: wrote run/index\.html$", after=page_is_safe)
case("report strings with terminal escapes", *REPORT, expect="ok", files=run_folder(
    FAILED | {"job": FAILED["job"] | {"model": "m\x1b]0;owned\x07\nfake line"}}),
    pattern=r"m\\x1b\]0;owned\\x07\\nfake line", after=page_is_safe)
case("report mathtext in a label", *REPORT, expect="ok", files=run_folder(
    record(label="q[x=$\\frac{$]")), pattern=r"^bench: wrote run/index\.html$")
case("report not-finite metrics", *REPORT, expect="ok", files=run_folder(
    record(metrics=record()["metrics"] | {"d_rms": math.nan, "faces": math.inf,
                                          "exterior_share": 0.5}, per_view={"d_rms": [1.0]})),
    pattern=r"^bench: wrote run/index\.html$")
for artifact in ("/etc/passwd", "../secret.txt", "../../secret.txt", "records/r0.json",
                 "images/link.png", "images", 42):
    def links(folder: Path) -> None:
        (folder / "run" / "images").mkdir()
        (folder / "run" / "images" / "link.png").symlink_to(folder / "secret.txt")
    case(f"report artifact {artifact!r}", *REPORT, expect="ok",
         files=run_folder(record(artifacts=[artifact]), extra=links),
         pattern=rf"artifact '{re.escape(str(artifact))}': .*; not shown$", after=page_is_safe)
case("report index.html links outside", *REPORT, expect="ok", files=run_folder(
    FAILED, extra=lambda d: (d / "run" / "index.html").symlink_to(d / "secret.txt")),
    pattern=r"^bench: wrote run/index\.html$")  # the secret is an input: hashed, unchanged
case("report results.csv links outside", *REPORT, expect="ok", files=run_folder(
    FAILED, extra=lambda d: (d / "run" / "results.csv").symlink_to(d / "secret.txt")),
    pattern=r"^bench: wrote run/results\.csv$")
case("report index.html is a folder", *REPORT, absent=(), files=run_folder(
    FAILED, extra=lambda d: (d / "run" / "index.html").mkdir()),
    pattern=r"^run/index\.html: cannot write it \(Is a directory\)$")


# -- bench check and bench baseline: baselines -------------------------------------------------

GOOD = record("q")
PROTOCOL = GOOD["job"]["protocol"]["version"]  # the protocol the records are evaluated under
ENTRY = {"status": "ok", "method_version": "1", "protocol_version": PROTOCOL,
         "metrics": {"d_rms": 5.0, "ssim": 0.9}}
BASE = {"schema": 1, "entries": {"m | q | 100 | flat": ENTRY}}
CHECK = ("check", "run", "--baseline", "base.json")
for name, data, message in (
        ("missing", None, r"base\.json: cannot read baseline \(\[Errno 2\]"),
        ("malformed JSON", '{"schema": 1,', r"cannot read baseline \(Expecting"),
        ("a JSON list", "[]", r"not a baseline: expected a JSON object, got list"),
        ("no schema", {"entries": BASE["entries"]}, r"baseline schema None is not 1"),
        ("schema 2", BASE | {"schema": 2}, r"baseline schema 2 is not 1"),
        ("no entries", {"schema": 1}, r"not a baseline: no 'entries' object"),
        ("entries a list", {"schema": 1, "entries": [1]}, r"no 'entries' object"),
        ("empty entries", {"schema": 1, "entries": {}}, r"'entries' is empty"),
        ("entry a number", {"schema": 1, "entries": {"k": 1}}, r"entry 'k' is not an object"),
        ("metric a string", {"schema": 1, "entries": {"k": ENTRY | {"metrics": {"d_rms": "5"}}}},
         r"metric 'd_rms' is '5', not a number"),
        ("no metrics", {"schema": 1, "entries": {"k": {"status": "ok"}}}, r"no 'metrics' object"),
        ("binary", "\x00\xff", r"cannot read baseline")):
    makers = [run_folder(GOOD)] + ([baseline_file(data)] if data is not None else [])
    case(f"check baseline {name}", *CHECK, files=both(*makers), pattern=message, absent=())
case("check baseline is a folder", *CHECK, absent=(), files=both(
    run_folder(GOOD), lambda d: (d / "base.json").mkdir()),
    pattern=r"cannot read baseline \(\[Errno 21\] Is a directory")
for value in ("nan", "inf", "-1", "abc"):
    case(f"check --tolerance {value}", *CHECK, f"--tolerance={value}", absent=(),
         files=both(run_folder(GOOD), baseline_file(BASE)),
         pattern=rf"^--tolerance must be a finite number >= 0 .*got '{value}'$")
case("check a malformed record", *CHECK, absent=(),
     files=both(run_folder(GOOD, "[1]"), baseline_file(BASE)),
     pattern=r"run/records/r1\.json: not a result record: expected a JSON object, got a list$")
case("check no run folder", "check", "nowhere", "--baseline", "base.json", absent=(),
     files=baseline_file(BASE), pattern=r"nowhere: not a run directory")
case("check passes on the same numbers", *CHECK, expect="ok", code=0,
     files=both(run_folder(GOOD), baseline_file(BASE)), pattern=r"^bench check: passed$")
case("check a 30x regression", *CHECK, expect="ok", code=1,
     files=both(run_folder(record(metrics={"d_rms": 150.0, "ssim": 0.9})), baseline_file(BASE)),
     pattern=r"d_rms +5 +150 +worse")
case("check a 30x regression at --tolerance 1e300", *CHECK, "--tolerance", "1e300",
     expect="ok", code=0, files=both(run_folder(record(metrics={"d_rms": 150.0, "ssim": 0.9})),
                                      baseline_file(BASE)), pattern=r"^bench check: passed$")
case("check NaN in the baseline", *CHECK, expect="ok", code=1, files=both(
    run_folder(GOOD), baseline_file(
        '{"schema": 1, "entries": {"m | q | 100 | flat": {"status": "ok", "method_version": '
        f'"1", "protocol_version": "{PROTOCOL}", "metrics": {{"d_rms": NaN, "ssim": 0.9}}}}}}}}')),
    pattern=r"d_rms +nan +5 +not finite")
case("check NaN in the run", *CHECK, expect="ok", code=1, files=both(
    run_folder(record(metrics={"d_rms": math.nan, "ssim": 0.9})), baseline_file(BASE)),
    pattern=r"d_rms +5 +nan +not finite")
case("check infinite ssim is not better", *CHECK, expect="ok", code=1, files=both(
    run_folder(record(metrics={"d_rms": 5.0, "ssim": math.inf})), baseline_file(BASE)),
    pattern=r"ssim +0\.9 +inf +not finite")
case("check a label written with its default", *CHECK, expect="ok", code=0, files=both(
    run_folder(record("qslim")), baseline_file({"schema": 1, "entries": {
        "m | qslim[qualitythr=0.30] | 100 | flat": ENTRY}})), pattern=r"^bench check: passed$")

BASELINE = ("baseline", "run", "--out", "made.json")
case("baseline no records", *BASELINE, files=run_folder(), absent=("made.json",),
     pattern=r"^run: no records to make a baseline of$")
case("baseline a malformed record", *BASELINE, files=run_folder(GOOD, "{"), absent=("made.json",),
     pattern=r"run/records/r1\.json: not a readable result record")
case("baseline a NaN metric", *BASELINE, absent=("made.json",),
     files=run_folder(record(metrics={"d_rms": math.nan})),
     pattern=r"job 'm \| q \| 100 \| flat' has d_rms = nan; a baseline needs finite values")
case("baseline --out a folder", "baseline", "run", "--out", "taken", absent=(),
     files=run_folder(GOOD, extra=lambda d: (d / "taken").mkdir()),
     pattern=r"^taken: cannot write the baseline \(Is a directory\)$")
case("baseline --out below a file", "baseline", "run", "--out", "secret.txt/b.json", absent=(),
     files=run_folder(GOOD), pattern=r"^secret\.txt/b\.json: cannot write the baseline")
case("baseline of a good run", *BASELINE, expect="ok", files=run_folder(GOOD),
     pattern=r"^bench: wrote made\.json \(1 jobs\)$", creates=("made.json",))


# -- a real run: two models with one file name -------------------------------------------------

def two_meshes(folder: Path) -> None:
    for sub in ("A", "B"):
        (folder / sub).mkdir()
        save_mesh(icosphere(1, name="mesh"), folder / sub / "mesh.obj")


def two_records(folder: Path, proc) -> None:
    records = [json.loads(p.read_text()) for p in (folder / "out" / "records").glob("*.json")]
    assert sorted(r["job"]["model"] for r in records) == ["A/mesh.obj", "B/mesh.obj"]
    assert all(r["status"] == "ok" for r in records)


case("run two models named mesh.obj", "run", "--models", "A/mesh.obj,B/mesh.obj",
     "--methods", "qslim", "--faces", "40", "--jobs", "2", "--no-report", "--out", "out",
     expect="ok", files=two_meshes, pattern=r"^bench: 2 jobs", after=two_records, slow=True)


# -- running the corpus ----------------------------------------------------------------------

ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def _hashes(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def _folder_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)[:80] + "-" + \
        hashlib.sha256(name.encode()).hexdigest()[:6]


@pytest.fixture(scope="module")
def outcomes(request, tmp_path_factory):
    """name -> (process, hashes before, hashes after, folder) for the cases selected in
    this session (``-k`` runs only those), three processes at a time."""
    from concurrent.futures import ThreadPoolExecutor

    root = tmp_path_factory.mktemp("hostile")
    env = dict(ENV, BENCH_CACHE=str(root / "cache"))
    selected = [item.callspec.params["name"] for item in request.session.items
                if getattr(item, "originalname", None) == "test_case"
                and item.module.__name__ == __name__]

    def run(name: str):
        c = CASES[name]
        folder = root / _folder_name(name)
        folder.mkdir()
        if c.files:
            c.files(folder)
        before = _hashes(folder)
        proc = subprocess.run([sys.executable, "-m", "bench", *c.args], cwd=folder, env=env,
                              capture_output=True, text=True, timeout=600, check=False)
        return name, (proc, before, _hashes(folder), folder)

    order = sorted(selected, key=lambda n: not CASES[n].slow)
    with ThreadPoolExecutor(max_workers=3) as pool:
        return dict(pool.map(run, order))


@pytest.mark.parametrize("name", list(CASES))
def test_case(outcomes, name):
    c = CASES[name]
    proc, before, after, folder = outcomes[name]
    assert "Traceback" not in proc.stderr + proc.stdout, proc.stderr
    if c.expect == "error":
        assert proc.returncode == (2 if c.code is None else c.code), proc.stderr
        lines = proc.stderr.splitlines()
        assert len(lines) == 1, proc.stderr
        assert lines[0].startswith("bench: error: "), proc.stderr
        assert re.search(c.pattern, lines[0].removeprefix("bench: error: ")), lines[0]
        assert proc.stdout == ""
    else:
        assert c.expect == "ok"
        assert proc.returncode == (0 if c.code is None else c.code), proc.stderr
        assert re.search(c.pattern, proc.stdout + proc.stderr, re.MULTILINE), \
            proc.stdout + proc.stderr
        for line in proc.stderr.splitlines():  # messages, and the run's progress bar
            assert line.startswith("bench") or "|" in line or not line.strip(), line
    changed = {path for path, digest in before.items() if after.get(path) != digest}
    assert not changed, f"inputs changed or removed: {sorted(changed)}"
    for path in c.creates:
        assert (folder / path).exists(), path
    if c.after:
        c.after(folder, proc)
    if c.expect == "error":
        for path in c.absent:
            assert not (folder / path).exists(), f"{path} left behind by an error"


def test_corpus_counts():
    """The corpus's size by outcome (issue 16 asks for at least 60 cases)."""
    counts = Counter(c.expect for c in CASES.values())
    print(f"\nhostile corpus: {len(CASES)} cases: {counts['error']} clean errors, "
          f"{counts['ok']} correct results")
    assert set(counts) <= {"error", "ok"}


# -- Ctrl-C in bench run ---------------------------------------------------------------------

def test_ctrl_c_prints_one_line_and_keeps_the_finished_records(tmp_path):
    """Ctrl-C reaches the whole foreground process group (the run and its workers): the
    workers ignore it and are stopped by the run, which says in one line what it kept.
    One job fails at once (its record is written), the next hangs until interrupted."""
    save_mesh(icosphere(1, name="ico"), tmp_path / "ico.obj")
    env = dict(ENV, BENCH_CACHE=str(tmp_path / "cache"),
               BENCH_PLUGINS="method:hang=misbehaving:Hang,method:raise=misbehaving:Raise",
               PYTHONPATH=os.pathsep.join([str(PLUGINS), ENV.get("PYTHONPATH", "")]))
    proc = subprocess.Popen(
        [sys.executable, "-m", "bench", "run", "--models", "ico.obj", "--methods", "raise,hang",
         "--faces", "40", "--jobs", "1", "--out", "out", "--no-report"], cwd=tmp_path, env=env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    records = tmp_path / "out" / "records"
    deadline = time.monotonic() + 300
    while not (records.is_dir() and any(records.glob("*.json"))):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.2)
    kept = _hashes(records)
    time.sleep(2)  # the worker is in the hanging job by now
    os.killpg(proc.pid, signal.SIGINT)  # as the terminal does on Ctrl-C
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    assert err.splitlines()[-1] == "bench: interrupted; 1 records kept in out; --resume continues"
    assert [line for line in err.splitlines() if line.startswith("bench:")] == [
        "bench: 2 jobs (1 models x 2 methods x budgets x flat shading) with 1 workers -> out",
        "bench: interrupted; 1 records kept in out; --resume continues"]
    assert _hashes(records) == kept
