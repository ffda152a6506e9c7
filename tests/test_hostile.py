"""A hostile-input corpus: bad or odd arguments, run folders, records, baselines and mesh
files given to ``bench`` as a user would, in a subprocess.

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

import numpy as np
import pytest

from bench.core.mesh import Mesh
from bench.io.meshio import save_mesh
from conftest import TET_FACES, TET_POSITIONS, icosphere, without_own_scripts
from conftest import made_up_record as record

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
    #: more environment variables (a plug-in to load, through BENCH_PLUGINS)
    env: tuple[tuple[str, str], ...] = ()
    #: seconds before the case counts as hung (it then fails, with "hung" as stderr)
    timeout: float = 600
    #: the umask bench runs under (None: the test's own)
    umask: int | None = None
    #: standard output is a pipe whose reader has left (as `bench ... | head -1` ends)
    closed_stdout: bool = False


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
    page = without_own_scripts((folder / "run" / "index.html").read_text())
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


# -- bench simplify: the input's files, and inputs that load wrong ---------------------------

SIMPLIFY = ("simplify", "-m", "qslim")
TET_OBJ = "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in TET_POSITIONS) + \
    "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in TET_FACES)
TEXTURED_OBJ = ("mtllib {mtl}\nusemtl t\n"
                + "".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in TET_POSITIONS)
                + "vt 0 0\nvt 1 0\nvt 0 1\n"
                + "".join(f"f {a + 1}/{a % 3 + 1} {b + 1}/{b % 3 + 1} {c + 1}/{c % 3 + 1}\n"
                          for a, b, c in TET_FACES))
GREY16 = [[0, 257, 1000, 65535], [128, 32768, 40000, 65280]]  # a 16-bit grey texture


def text_file(name: str, text: str | bytes) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        data = text.encode() if isinstance(text, str) else text
        (folder / name).write_bytes(data)
    return make


def textured(obj: str = "in.obj", mtl: str = "in.mtl", texture: str = "tex.png",
             image: bytes | str | None = None, uv: str = "") -> Callable[[Path], None]:
    """A textured tetrahedron ``obj`` whose ``mtl`` names ``texture``: an 8-bit PNG, the
    16-bit grey GREY16 (``image="grey16"``), raw bytes, or a folder (``image="folder"``);
    ``uv`` replaces the second texture coordinate's line."""
    def make(folder: Path) -> None:
        from PIL import Image

        text = TEXTURED_OBJ.format(mtl=mtl)
        if uv:
            text = text.replace("vt 1 0\n", uv + "\n")
        (folder / obj).write_text(text)
        (folder / mtl).write_text(f"newmtl t\nKd 1 1 1\nmap_Kd {texture}\n")
        if image == "folder":
            (folder / texture).mkdir()
        elif image == "grey16":
            Image.fromarray(np.array(GREY16, dtype=np.uint16)).save(folder / texture)
        elif image is not None:
            (folder / texture).write_bytes(image)
        else:
            Image.new("RGB", (4, 4), (200, 100, 50)).save(folder / texture)
    return make


def scaled_tet(scale: float) -> str:
    return "".join(f"v {x * scale!r} {y * scale!r} {z * scale!r}\n"
                   for x, y, z in TET_POSITIONS.tolist()) \
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in TET_FACES)


def ascii_ply(cut: Callable[[list[str]], list[str]]) -> Callable[[Path], None]:
    """icosphere(3) (642 vertices, 1280 faces) as an ASCII PLY, its lines passed
    through ``cut``."""
    def make(folder: Path) -> None:
        import trimesh

        ico = icosphere(3)
        data = trimesh.Trimesh(ico.positions, ico.faces, process=False).export(
            file_type="ply", encoding="ascii")
        lines = (data if isinstance(data, str) else data.decode()).splitlines()
        (folder / "trunc.ply").write_text("\n".join(cut(lines)) + "\n")
    return make


def header_end(lines: list[str]) -> int:
    return lines.index("end_header") + 1


def loads_back(name: str, check: Callable) -> Callable:
    """An ``after`` check: the written ``name`` loads, and ``check(mesh)`` holds."""
    def after(folder: Path, proc) -> None:
        from bench.io.meshio import load_mesh

        check(load_mesh(folder / name))
    return after


def area_is(expected: float) -> Callable:
    def check(mesh) -> None:
        from bench.core.mesh import face_areas

        assert face_areas(mesh.positions, mesh.faces).sum() == expected
    return check


def same_positions(scale: float) -> Callable:
    def check(mesh) -> None:
        assert mesh.n_faces == 4
        assert sorted(map(tuple, mesh.welded.positions.tolist())) == \
            sorted(map(tuple, (TET_POSITIONS * scale).tolist()))
    return check


def grey16_scaled(folder: Path, proc) -> None:
    from PIL import Image

    written = np.asarray(Image.open(folder / "out.png"))
    expected = np.rint(np.array(GREY16) * 255 / 65535).astype(np.uint8)
    assert written.shape == (2, 4, 3)
    np.testing.assert_array_equal(written, np.repeat(expected[..., None], 3, axis=-1))


def faces_written(n: int) -> Callable:
    def check(mesh) -> None:
        assert mesh.n_faces == n
    return check


def ico_obj(folder: Path) -> None:
    save_mesh(icosphere(1, name="ico"), folder / "ico.obj")


# 3: the input's files are never written over by accident
case("simplify OUT is IN", *SIMPLIFY, "in.obj", "in.obj", "--faces", "2", files=textured(),
     absent=(), pattern=r"^in\.obj: is the input's mesh file \(in\.obj\); choose another "
     r"output name, or give --force to replace it$")
case("simplify OUT is IN by another path", *SIMPLIFY, "in.obj", "./sub/../in.obj", "--faces", "2",
     files=both(textured(), lambda d: (d / "sub").mkdir()), absent=(),
     pattern=r"^sub/\.\./in\.obj: is the input's mesh file \(in\.obj\)")
for force in ((), ("--force",)):
    case(f"simplify OUT named after IN's texture {' '.join(force)}", *SIMPLIFY, "in.obj",
         "tex.obj", "--faces", "2", *force, files=textured(image="grey16"),
         absent=("tex.obj", "tex.mtl"),
         pattern=r"^tex\.png: is the input's texture \(tex\.png\), which is never written over, "
         r"not even with --force; choose another output name")
case("simplify OUT's MTL is IN's MTL", *SIMPLIFY, "in.obj", "shared.obj", "--faces", "2",
     files=textured(mtl="shared.mtl"), absent=("shared.obj", "shared.png"),
     pattern=r"^shared\.mtl: is the input's material file \(shared\.mtl\); choose another "
     r"output name, or give --force")
case("simplify LOD chain over IN", *SIMPLIFY, "m_LOD1.obj", "m.obj", "--faces", "3,2",
     files=text_file("m_LOD1.obj", TET_OBJ), absent=("m_LOD0.obj", "m_LOD2.obj", "m.obj.lods.json"),
     pattern=r"^m_LOD1\.obj: is the input's mesh file \(m_LOD1\.obj\)")

# 5: valid inputs load right, invalid ones are refused
case("simplify truncated ASCII PLY", *SIMPLIFY, "trunc.ply", "out.obj", "--faces", "100",
     files=ascii_ply(lambda lines: lines[:header_end(lines) + 642 + 303]),
     pattern=r"^trunc\.ply: 945 data lines where its header declares 1922 elements; the file "
     r"is truncated$")
case("simplify ASCII PLY cut in its last line", *SIMPLIFY, "trunc.ply", "out.obj", "--faces",
     "100", files=ascii_ply(lambda lines: lines[:-1] + [lines[-1].rsplit(" ", 2)[0]]),
     pattern=r"^trunc\.ply: its last element \(line 1922 of the data\) is incomplete; the file "
     r"is truncated$")
for scale in (1e100, 1e150, 1e300):
    case(f"simplify coordinates of {scale:g}", *SIMPLIFY, "big.obj", "out.obj", "--faces", "4",
         expect="ok", files=text_file("big.obj", scaled_tet(scale)),
         pattern=r"^big: 4 -> 4 faces", after=loads_back("out.obj", same_positions(scale)))
case("simplify coordinates of 1e100 to 32-bit floats", "simplify", "big.obj", "out.ply",
     "-m", "fast-simplification", "--faces", "2", files=text_file("big.obj", scaled_tet(1e100)),
     pattern=r"^out\.ply: coordinates up to 1e\+100 do not fit the 32-bit floats PLY is "
     r"written with; write \.obj or \.off, or scale the mesh$")
for ext, storage in ((".obj", "10 decimals OBJ"), (".glb", "32-bit floats GLB")):
    case(f"simplify coordinates of 1e-150 to {ext}", "simplify", "tiny.obj", f"out{ext}",
         "-m", "fast-simplification", "--faces", "2", files=text_file("tiny.obj", scaled_tet(1e-150)),
         pattern=rf"^out\{ext}: all 4 faces would collapse to zero area in the {storage} is "
         r"written with \(coordinates too small for them\); scale the mesh first$")
case("simplify concave polygon", *SIMPLIFY, "concave.obj", "out.obj", "--faces", "3",
     expect="ok", files=text_file("concave.obj", "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\n"
                                                 "f 1 2 3 4 5\n"),
     pattern=r"^bench: warning: concave\.obj: triangulated 1 faces with more than 3 corners "
     r"\(1 concave, by ear clipping\)$", after=loads_back("out.obj", area_is(10.0)))
#: An L of area 3 whose fan from its first corner covers 4 (trimesh fans PLY and OFF).
L_CORNERS = "2 0 0\n2 1 0\n1 1 0\n1 2 0\n0 2 0\n0 0 0\n"
case("simplify concave OFF polygon", *SIMPLIFY, "concave.off", "out.obj", "--faces", "4",
     expect="ok", files=text_file("concave.off", "OFF\n6 1 0\n" + L_CORNERS + "6 0 1 2 3 4 5\n"),
     pattern=r"^bench: warning: concave\.off: triangulated 1 faces with more than 3 corners "
     r"\(1 concave, by ear clipping\)$", after=loads_back("out.obj", area_is(3.0)))
case("simplify concave ASCII PLY polygon", *SIMPLIFY, "concave.ply", "out.obj", "--faces", "4",
     expect="ok", files=text_file("concave.ply", "ply\nformat ascii 1.0\nelement vertex 6\n"
                                  "property float x\nproperty float y\nproperty float z\n"
                                  "element face 1\nproperty list uchar int vertex_indices\n"
                                  "end_header\n" + L_CORNERS + "6 0 1 2 3 4 5\n"),
     pattern=r"^bench: warning: concave\.ply: triangulated polygon faces \(1 faces in the file "
     r"became 4 triangles; 1 concave, by ear clipping\)$",
     after=loads_back("out.obj", area_is(3.0)))
def binary_l_ply(order: str) -> bytes:
    """The L of L_CORNERS as a binary PLY (``order`` "<" or ">"), with a double and a
    colour among its vertex properties and a ushort index list."""
    import struct

    kind = "little" if order == "<" else "big"
    header = (f"ply\nformat binary_{kind}_endian 1.0\nelement vertex 6\nproperty double x\n"
              "property float y\nproperty uchar red\nproperty float z\nelement face 1\n"
              "property list uchar ushort vertex_indices\nend_header\n").encode()
    rows = [tuple(float(v) for v in line.split()) for line in L_CORNERS.splitlines()]
    body = b"".join(struct.pack(order + "dfBf", x, y, 7, z) for x, y, z in rows)
    return header + body + struct.pack(order + "B6H", 6, 0, 1, 2, 3, 4, 5)


for order, kind in (("<", "little"), (">", "big")):
    case(f"simplify concave binary {kind}-endian PLY polygon", *SIMPLIFY, "concave.ply",
         "out.obj", "--faces", "4", expect="ok",
         files=text_file("concave.ply", binary_l_ply(order)),
         pattern=r"^bench: warning: concave\.ply: triangulated polygon faces \(1 faces in the "
         r"file became 4 triangles; 1 concave, by ear clipping\)$",
         after=loads_back("out.obj", area_is(3.0)))
case("simplify faces with 1 and 2 corners", *SIMPLIFY, "short.obj", "out.obj", "--faces", "4",
     expect="ok", files=text_file("short.obj", TET_OBJ + "f 1 2\nf 3\n"),
     pattern=r"^bench: warning: short\.obj: ignored 2 faces with fewer than 3 corners \(first "
     r"on line 9\)$", after=loads_back("out.obj", faces_written(4)))
case("simplify vt index out of range", *SIMPLIFY, "vt.obj", "out.obj", "--faces", "2",
     files=text_file("vt.obj", TET_OBJ.replace("f 1 3 2", "f 1/1 3/1 2/9").replace(
         "v 0 0 1\n", "v 0 0 1\nvt 0 0\nvt 1 0\n")),
     pattern=r"^vt\.obj: line 7: texture coordinate index 9 is out of range \(the file has 2 "
     r"texture coordinates\); the file is corrupt or truncated$")
case("simplify vn index out of range", *SIMPLIFY, "vn.obj", "out.obj", "--faces", "2",
     files=text_file("vn.obj", TET_OBJ.replace("f 1 2 4", "f 1//1 2//1 4//-2").replace(
         "v 0 0 1\n", "v 0 0 1\nvn 0 0 1\n")),
     pattern=r"^vn\.obj: line 7: normal index -2 is out of range \(1 normals defined before "
     r"it\); the file is corrupt or truncated$")
def latin_textured(root: Path) -> None:
    """An OBJ whose mtllib and map_Kd name files in Latin-1 bytes (the file system's
    names are UTF-8, as a Windows export copied to Linux has them)."""
    import numpy as np
    from PIL import Image

    Image.fromarray(np.full((8, 8, 3), 200, np.uint8)).save(root / "textur\xe9.png")
    uv = "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nusemtl m\n"
    faces = "f 1/1 3/3 2/2\nf 1/1 2/2 4/4\nf 1/1 4/4 3/3\nf 2/2 3/3 4/4\n"
    (root / "latin.obj").write_bytes(("mtllib mat\xe9riau.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                      "v 0 0 1\n" + uv + faces).encode("latin-1"))
    (root / "mat\xe9riau.mtl").write_bytes("newmtl m\nmap_Kd textur\xe9.png\n".encode("latin-1"))


case("simplify Latin-1 material and texture names", *SIMPLIFY, "latin.obj", "out.obj",
     "--faces", "4", expect="ok", files=latin_textured,
     pattern=r"^latin: 4 -> 4 faces .*; wrote out\.obj, out\.png, out\.mtl$")
case("simplify Latin-1 OBJ", *SIMPLIFY, "latin.obj", "out.obj", "--faces", "4", expect="ok",
     files=text_file("latin.obj", "# mod\xe8le export\xe9\n".encode("latin-1") + TET_OBJ.encode()),
     pattern=r"^latin: 4 -> 4 faces", after=loads_back("out.obj", faces_written(4)))

# 6: texture problems are reported
for name, image, reason in (
        ("corrupt", b"\x89PNG\r\n\x1a\nrubbish", r"tex\.png cannot be read as an image: .+"),
        ("empty", b"", r"tex\.png is empty"),
        ("a folder", "folder", r"tex\.png is a directory")):
    case(f"simplify texture {name}", *SIMPLIFY, "in.obj", "out.obj", "--faces", "4", expect="ok",
         files=textured(image=image),
         pattern=rf"^bench: warning: in\.obj: texture image unreadable \({reason}\); loading "
         r"untextured \(UVs kept\)$")
case("simplify 16-bit texture", *SIMPLIFY, "in.obj", "out.obj", "--faces", "4", expect="ok",
     files=textured(image="grey16"), pattern=r"^in: 4 -> 4 faces", creates=("out.png",),
     after=grey16_scaled)
for value in ("1e300 1e300", "nan 0"):
    shown = "1e+300 1e+300" if value.startswith("1e") else value
    case(f"simplify UV {value}", *SIMPLIFY, "in.obj", "out.obj", "--faces", "2",
         files=textured(uv=f"vt {value}"),
         pattern=rf"^in\.obj: line 8: texture coordinate {re.escape(shown)} is not finite or "
         r"beyond 1e\+06 in magnitude; the file is corrupt$")

# 7: no empty result passes for a success
for method, target in (("qslim", ("--faces", "1")), ("fast-simplification", ("--ratio", "1e-9"))):
    case(f"simplify {method} {' '.join(target)}", "simplify", "ico.obj", "out.obj", "-m", method,
         *target, expect="ok", files=ico_obj,
         pattern=r"^bench: note: stopped short: the backend leaves no faces at a target of 1; "
         r"stopped at 2 faces, the fewest it leaves \(target 2\)$",
         after=loads_back("out.obj", faces_written(2)))


# -- issue 48: a gate no one can slip past, and the last hostile inputs -----------------------

# bench check: duplicate or incomplete records, broken metric plug-ins, pipes, Markdown
case("check two records of one job", *CHECK, absent=(), files=both(
    run_folder(GOOD, record(metrics={"d_rms": 25.0, "ssim": 0.9})), baseline_file(BASE)),
    pattern=r"^run/records/r0\.json and run/records/r1\.json are both records of job "
    r"'m \| q \| 100 \| flat'; a run folder holds one record per job: remove the stale one$")
case("baseline two records of one job", *BASELINE, absent=("made.json",),
     files=run_folder(GOOD, record(metrics={"d_rms": 25.0, "ssim": 0.9})),
     pattern=r"^run/records/r0\.json and run/records/r1\.json are both records of job")
case("check a record without a gated metric", *CHECK, expect="ok", code=1, files=both(
    run_folder(record(metrics={"ssim": 0.9})), baseline_file(BASE)),
    pattern=r"d_rms +5 +missing metric\n(.|\n)*^bench check: FAILED \(1 regressions")
case("check a metric plug-in that fails to import", *CHECK, absent=(), files=both(
    run_folder(GOOD), baseline_file(BASE),
    text_file("raises_on_import.py", "raise RuntimeError('no')\n")),
    env=(("BENCH_PLUGINS", "metric:broken=raises_on_import:METRIC"),),
    pattern=r"^metric 'broken' cannot be loaded: failed to load raises_on_import:METRIC: "
    r"RuntimeError: no; the gate needs every registered metric's direction")
case("check --format json into a closed pipe", *CHECK, "--format", "json", expect="ok",
     files=both(run_folder(GOOD), baseline_file(BASE)), closed_stdout=True,
     pattern=r"^bench check: passed$")
MENTIONS = "@octocat see https://evil.example, www.evil.example, a@b.org and #12"


def no_mentions(folder: Path, proc) -> None:
    """Nothing GitHub would turn into a mention, an issue link or an autolink."""
    assert "octocat" in proc.stdout
    for pattern in (r"@\w", r"://", r"(?i)www\.", r"#\d"):
        assert not re.search(pattern, proc.stdout), (pattern, proc.stdout)


case("check --format markdown with mentions and links", *CHECK, "--format", "markdown",
     expect="ok", code=1, files=both(run_folder(record(model=MENTIONS)), baseline_file(BASE)),
     pattern=r"^\| m \\\| q \\\| 100 \\\| flat \| - \| ok \| .*\*\*missing\*\* \|$",
     after=no_mentions)


# bench history: dates with offsets, one folder under two names, --out
def history_runs(folder: Path) -> None:
    """Run ``early`` (d_rms 5) at 01:00 UTC on 6 November and run ``later`` (d_rms 15)
    at 20:00 on 5 November in UTC-8, which is 04:00 UTC on the 6th: later by three
    hours, though earlier as text."""
    for name, created, d_rms in (("early", "2026-11-06T01:00:00Z", 5.0),
                                 ("later", "2026-11-05T20:00:00-08:00", 15.0)):
        (folder / name / "records").mkdir(parents=True)
        r = record(metrics={"d_rms": d_rms, "ssim": 0.9}) | {
            "created": created, "environment": {"git_commit": name * 5}}
        (folder / name / "records" / "r.json").write_text(json.dumps(r))


def later_fails(folder: Path, proc) -> None:
    import pandas as pd

    table = pd.read_csv(folder / "hist" / "history.csv")
    marks = table[table.metric == "d_rms"].set_index("folder").mark.fillna("")
    assert marks.to_dict() == {"early": "", "later": "worse"}


case("history dates with offsets are instants", "history", "early", "later", "--out", "hist",
     expect="ok", files=history_runs, after=later_fails,
     pattern=r"^bench history: 2 runs, 1 that bench check would have failed; wrote "
     r"hist/index\.html$")
case("history one folder under three names", "history", "early", "sub/../early", "alias",
     "--out", "hist", expect="ok", files=both(history_runs, lambda d: (d / "sub").mkdir(),
                                              lambda d: (d / "alias").symlink_to("early")),
     pattern=r"^bench history: 1 runs, 0 that")
case("history --out an existing file", "history", "early", "--out", "taken.txt",
     files=both(history_runs, a_file("taken.txt")),
     pattern=r"^--out taken\.txt: exists and is not a folder; give a folder")
case("history --out in a run's images", "history", "early", "later", "--out", "early/images",
     files=history_runs, absent=("early/images",),
     pattern=r"^--out early/images: that is inside the run folder early \(its index\.html and "
     r"images/ are the run's report\)")
case("history --out in /proc", "history", "early", "--out", "/proc/hist", files=history_runs,
     pattern=r"^--out /proc/hist: cannot write the history there \(No such file or "
     r"directory\); give a folder you can write to$")


# loaders: sparse accessors, named pipes, faces dropped and split, garbage, overflow
def tet_gltf(sparse: bool = False, image: str | None = None, glb: bool = False) -> bytes:
    """The tetrahedron as a hand-built glTF (or GLB): positions, indices and UVs in one
    buffer; ``sparse``: a sparse accessor moves vertex 3 from (0, 0, 1) to (0, 0, 2);
    ``image``: a base-colour texture of that URI."""
    import base64
    import struct

    blob = (TET_POSITIONS.astype("<f4").tobytes() + TET_FACES.astype("<u2").tobytes()
            + np.array([[0, 0], [1, 0], [0, 1], [1, 1]], "<f4").tobytes())
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
             {"buffer": 0, "byteOffset": 48, "byteLength": 24},
             {"buffer": 0, "byteOffset": 72, "byteLength": 32}]
    position = {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                "min": [0, 0, 0], "max": [1, 1, 1]}
    if sparse:
        views += [{"buffer": 0, "byteOffset": len(blob), "byteLength": 2},
                  {"buffer": 0, "byteOffset": len(blob) + 4, "byteLength": 12}]
        blob += struct.pack("<H2x3f", 3, 0, 0, 2)
        position |= {"max": [1, 1, 2], "sparse": {
            "count": 1, "indices": {"bufferView": 3, "componentType": 5123},
            "values": {"bufferView": 4}}}
    primitive = {"attributes": {"POSITION": 0}, "indices": 1}
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}], "meshes": [{"primitives": [primitive]}],
            "buffers": [{"byteLength": len(blob)}], "bufferViews": views,
            "accessors": [position, {"bufferView": 1, "componentType": 5123, "count": 12,
                                     "type": "SCALAR"},
                          {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"}]}
    if image:
        primitive["attributes"]["TEXCOORD_0"] = 2
        primitive["material"] = 0
        tree |= {"images": [{"uri": image}], "textures": [{"source": 0}], "materials": [
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]}
    if not glb:
        tree["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                     + base64.b64encode(blob).decode())
        return json.dumps(tree).encode()
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    return (struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(blob))
            + struct.pack("<II", len(text), 0x4E4F534A) + text
            + struct.pack("<II", len(blob), 0x004E4942) + blob)


def moved_vertex(mesh) -> None:
    expected = TET_POSITIONS.copy()
    expected[3] = (0, 0, 2)
    assert sorted(map(tuple, mesh.welded.positions.tolist())) == \
        sorted(map(tuple, expected.tolist()))


for ext in (".gltf", ".glb"):
    case(f"simplify {ext} sparse accessor", *SIMPLIFY, f"sparse{ext}", "out.obj", "--faces",
         "4", expect="ok", files=text_file(f"sparse{ext}", tet_gltf(sparse=True,
                                                                     glb=ext == ".glb")),
         pattern=r"^sparse: 4 -> 4 faces", after=loads_back("out.obj", moved_vertex))


def named_pipe(name: str, maker: Callable | None = None) -> Callable[[Path], None]:
    """``maker`` (if any), then ``name`` made a named pipe no one writes to: opening it
    for reading would block for ever."""
    def make(folder: Path) -> None:
        if maker:
            maker(folder)
        (folder / name).unlink(missing_ok=True)
        os.mkfifo(folder / name)
    return make


case("simplify OBJ texture is a named pipe", *SIMPLIFY, "in.obj", "out.obj", "--faces", "4",
     expect="ok", timeout=60, files=named_pipe("tex.png", textured()),
     pattern=r"^bench: warning: in\.obj: texture image unreadable \(tex\.png is not a regular "
     r"file\); loading untextured \(UVs kept\)$")
case("simplify glTF texture is a named pipe", *SIMPLIFY, "in.gltf", "out.obj", "--faces", "4",
     expect="ok", timeout=60, files=named_pipe("tex.png", text_file(
         "in.gltf", tet_gltf(image="tex.png"))),
     pattern=r"^bench: warning: in\.gltf: texture image unreadable \(tex\.png is not a "
     r"regular file\); loading untextured \(UVs kept\)$")
case("simplify input is a named pipe", *SIMPLIFY, "pipe.obj", "out.obj", "--faces", "2",
     timeout=60, files=named_pipe("pipe.obj"),
     pattern=r"^pipe\.obj: is not a regular file \(a named pipe, device or socket\); give a "
     r"mesh file$")
QUAD_AND_2GON = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n4 0 1 2 3\n2 0 4\n3 0 1 4\n"
case("simplify PLY quad and 2-gon", *SIMPLIFY, "mix.ply", "out.obj", "--faces", "3",
     expect="ok", files=text_file("mix.ply", "ply\nformat ascii 1.0\nelement vertex 5\n"
                                  "property float x\nproperty float y\nproperty float z\n"
                                  "element face 3\nproperty list uchar int vertex_indices\n"
                                  "end_header\n" + QUAD_AND_2GON),
     pattern=r"^bench: warning: mix\.ply: triangulated polygon faces \(2 faces in the file "
     r"became 3 triangles\)\nbench: warning: mix\.ply: ignored 1 faces with fewer than 3 "
     r"corners \(first: face 1 of the file, counting from 0\)$",
     after=loads_back("out.obj", faces_written(3)))
case("simplify OFF quad and 2-gon", *SIMPLIFY, "mix.off", "out.obj", "--faces", "3",
     expect="ok", files=text_file("mix.off", "OFF\n5 3 0\n" + QUAD_AND_2GON),
     pattern=r"^bench: warning: mix\.off: triangulated 1 faces with more than 3 corners\n"
     r"bench: warning: mix\.off: ignored 1 faces with fewer than 3 corners \(first on line "
     r"9\)$", after=loads_back("out.obj", faces_written(3)))
GARBAGE = b"garbage\x00\xff\xfe junk\n"
case("simplify garbage OFF", *SIMPLIFY, "junk.off", "out.obj", "--faces", "2",
     files=text_file("junk.off", GARBAGE),
     pattern=r"^junk\.off: not an OFF file \(it does not begin with an OFF header\)")
case("simplify garbage STL", *SIMPLIFY, "junk.stl", "out.obj", "--faces", "2",
     files=text_file("junk.stl", GARBAGE),
     pattern=r"^junk\.stl: not an STL file \(not ASCII STL text, and shorter than a binary "
     r"STL's 84-byte header\)")
case("simplify garbage STL of 170 bytes", *SIMPLIFY, "junk.stl", "out.obj", "--faces", "2",
     files=text_file("junk.stl", GARBAGE * 10 + b"\xff" * 10),
     pattern=r"^junk\.stl: not an STL file \(not ASCII STL text, and 170 bytes where a binary "
     r"STL of \d+ triangles has \d+\)")


def huge_ico(folder: Path) -> None:
    """icosphere(2) scaled to 1.7e308: an edge's squared length overflows."""
    ico = icosphere(2)
    (folder / "huge.obj").write_text(
        "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in (ico.positions * 1.7e308).tolist())
        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in ico.faces.tolist()))


case("simplify coordinates of 1.7e308 overflow", *SIMPLIFY, "huge.obj", "out.obj", "--faces",
     "40", files=huge_ico,
     pattern=r"^out\.obj: \d+ vertices of the result have coordinates that are not finite: "
     r"coordinates this large \(up to 1\.\d+e\+308\) overflow floating-point arithmetic; "
     r"scale the mesh down and simplify again$")

# parameters: one rule for every method (cheap methods here; every one below)
for method, param, message in (
        ("qslim", "qualitythr=nan", r"'qualitythr' must be a finite number, got nan"),
        ("qslim", "boundaryweight=-1", r"'boundaryweight' must be >= 0, got -1"),
        ("fast-simplification", "agg=-1", r"'agg' must be >= 0, got -1"),
        ("meshopt", "target_error=inf", r"'target_error' must be a finite number, got inf"),
        ("meshopt-attributes", "normal_weight=nan",
         r"'normal_weight' must be a finite number, got nan")):
    case(f"simplify {method} -p {param}", "simplify", "tet.obj", "out.obj", "-m", method,
         "-p", param, "--faces", "2", files=tet, pattern=rf"^parameter {message}$")


# files: the umask's mode
def mode_644(folder: Path, proc) -> None:
    for name in ("out.obj", "out.mtl", "out.png"):
        assert (folder / name).stat().st_mode & 0o777 == 0o644, name


case("simplify writes files with the umask's mode", *SIMPLIFY, "in.obj", "out.obj",
     "--faces", "2", expect="ok", umask=0o022, files=textured(), after=mode_644,
     pattern=r"wrote out\.obj, out\.png, out\.mtl$")

# errors: an unreadable input, an unwritable output, broken plug-ins
case("simplify unreadable input", *SIMPLIFY, "mem.obj", "out.obj", "--faces", "2",
     files=lambda d: (d / "mem.obj").symlink_to("/proc/self/mem"),
     pattern=r"^mem\.obj: cannot read it \(Input/output error\); check that the file is "
     r"readable$")
case("simplify OUT in /proc", *SIMPLIFY, "tet.obj", "/proc/out.obj", "--faces", "2",
     files=tet, pattern=r"^/proc/out\.obj: cannot write it \(No such file or directory\); "
     r"give an output in a folder you can write to$")
case("simplify OUT in a folder no one may write", *SIMPLIFY, "tet.obj", "/sys/out.obj",
     "--faces", "2", files=tet,
     pattern=r"^/sys/out\.obj: cannot write it \((Permission denied|Operation not permitted)\)")
for module, code, message in (
        ("exits_on_import", "import sys\nsys.exit(0)\n", r"it called sys\.exit\(0\) on import"),
        ("stops_on_import", "class Stop(BaseException):\n    pass\n\n\nraise Stop('no')\n",
         r"Stop: no")):
    case(f"simplify a method plug-in: {module}", *SIMPLIFY[:1], "tet.obj", "out.obj", "-m",
         "broken", "--faces", "2", files=both(tet, text_file(f"{module}.py", code)),
         env=(("BENCH_PLUGINS", f"method:broken={module}:Method"),),
         pattern=rf"^method 'broken' is unavailable: failed to load {module}:Method: "
         rf"{message}$")


# -- running the corpus ----------------------------------------------------------------------

ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def _hashes(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def _folder_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)[:80] + "-" + \
        hashlib.sha256(name.encode()).hexdigest()[:6]


def _bench(c: Case, folder: Path, env: dict) -> subprocess.CompletedProcess:
    """``bench`` run as the case says; a hung one is killed after ``c.timeout`` seconds
    and comes back with the return code -9 and "hung" as its standard error."""
    command = [sys.executable, "-m", "bench", *c.args]
    proc = subprocess.Popen(command, cwd=folder, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, umask=-1 if c.umask is None
                            else c.umask)
    if c.closed_stdout:
        proc.stdout.close()  # before bench has started: its first write finds no reader
        proc.stdout = None
    try:
        out, err = proc.communicate(timeout=c.timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return subprocess.CompletedProcess(command, -9, "", f"hung: killed after {c.timeout} s")
    return subprocess.CompletedProcess(command, proc.returncode, out or "", err)


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
        proc = _bench(c, folder, dict(env, **dict(c.env)))
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


def test_force_writes_over_the_input_mesh_and_material_not_its_texture(tmp_path):
    """OUT = IN with --force replaces the mesh and its MTL (the corpus keeps inputs
    unchanged, so this runs here); the input's texture, named apart, is kept."""
    textured()(tmp_path)
    texture = (tmp_path / "tex.png").read_bytes()
    proc = subprocess.run([sys.executable, "-m", "bench", "simplify", "in.obj", "in.obj", "-m",
                           "qslim", "--faces", "2", "--force"], cwd=tmp_path, env=ENV,
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert re.search(r"^in: 4 -> 2 faces .*; wrote in\.obj, in\.png, in\.mtl$", proc.stdout), \
        proc.stdout
    assert (tmp_path / "tex.png").read_bytes() == texture
    assert "map_Kd in.png" in (tmp_path / "in.mtl").read_text()


def test_force_keeps_the_replaced_files_mode(tmp_path):
    """OUT = IN with --force writes the new mesh and material with the modes the
    replaced files had (0640 and 0604 here), not a temporary file's 0600."""
    textured()(tmp_path)
    os.chmod(tmp_path / "in.obj", 0o640)
    os.chmod(tmp_path / "in.mtl", 0o604)
    proc = subprocess.run([sys.executable, "-m", "bench", "simplify", "in.obj", "in.obj", "-m",
                           "qslim", "--faces", "2", "--force"], cwd=tmp_path, env=ENV,
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    assert "map_Kd in.png" in (tmp_path / "in.mtl").read_text()  # both were written
    assert (tmp_path / "in.obj").stat().st_mode & 0o777 == 0o640
    assert (tmp_path / "in.mtl").stat().st_mode & 0o777 == 0o604


def _numeric_fields():
    """(method, field, type, declared range) for every numeric parameter of every
    method that loads here."""
    import dataclasses
    import typing

    from bench.core.registry import registry

    out = []
    for entry in registry("method"):
        if not entry.available:
            continue
        cls = entry.load()
        hints = typing.get_type_hints(cls.Params)
        for f in dataclasses.fields(cls.Params):
            if hints[f.name] in (int, float):
                out.append((entry.name, f.name, hints[f.name], f.metadata.get("range", {})))
    return out


@pytest.mark.parametrize("method,name,kind,bounds", _numeric_fields(),
                         ids=lambda v: v if isinstance(v, str) else "")
def test_every_parameter_is_checked_by_the_shared_rule(method, name, kind, bounds):
    """NaN and infinities are refused for every float parameter, and a value just
    outside each declared bound for every number, by the one rule parse_params and
    Method() apply; the default passes it."""
    from bench.core.errors import ParamError
    from bench.core.method import parse_params
    from bench.core.registry import registry

    cls = registry("method").load(method)
    cls(parse_params(cls.Params, []))  # the defaults pass
    bad = ["nan", "inf", "-inf"] if kind is float else []
    step = 1 if kind is int else 1e-9
    bad += [str(kind(b - step)) for k, b in bounds.items() if k == "ge"]
    bad += [str(kind(b)) for k, b in bounds.items() if k in ("gt", "lt")]
    bad += [str(kind(b + step)) for k, b in bounds.items() if k == "le"]
    for value in bad:
        with pytest.raises(ParamError, match=rf"^parameter '{name}' must be "):
            parse_params(cls.Params, [f"{name}={value}"])
        with pytest.raises(ParamError, match=rf"^parameter '{name}' must be "):
            cls(**{name: kind(float(value)) if kind is float else int(value)})


def test_the_built_in_methods_declare_ranges():
    """Every numeric parameter of the built-in methods has a declared range (or is a
    documented exception), so no weight can be negative by mistake."""
    unbounded = {(m, n) for m, n, _, bounds in _numeric_fields() if not bounds}
    assert unbounded == set()


# -- Ctrl-C in bench run ---------------------------------------------------------------------

def _ctrl_c_as_in_a_terminal():
    """In the child before it starts: Ctrl-C has its default meaning, as in a terminal's
    foreground job, even when the tests run where SIGINT is ignored (a shell's
    background job), which the child would otherwise inherit."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


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
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=_ctrl_c_as_in_a_terminal)
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
    threads = len(os.sched_getaffinity(0))  # one job process: every usable core
    assert [line for line in err.splitlines() if line.startswith("bench:")] == [
        "bench: 2 jobs (1 models x 2 methods x budgets x flat shading) with 1 workers, "
        f"{threads} thread{'s' if threads > 1 else ''} per job -> out",
        "bench: interrupted; 1 records kept in out; --resume continues"]
    assert _hashes(records) == kept
