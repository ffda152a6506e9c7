"""The report's trust boundary: a run folder is someone else's data.

A record's strings reach the HTML escaped, a record's artifacts are read only from
inside the run folder and only when they are PNG files, a damaged record is left out
with a warning instead of stopping the report, and index.html, results.csv and records
are replaced atomically. Records are built by hand; nothing is simplified or rendered.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.core.errors import InputError
from bench.records.results import load_records, write_record, write_table
from bench.report.images import RunFiles, run_file
from bench.report.page import write_report
from conftest import made_up_record as record
from conftest import without_own_scripts
from metrics.protocol import Protocol

SCRIPT = "<script>alert(1)</script>"
SECRET = "TOPSECRET-7f3a1c"
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}


def run_folder(root: Path, records: dict) -> Path:
    """``root/run`` with ``records`` (file stem -> dict, or str for raw file text)."""
    run = root / "run"
    (run / "records").mkdir(parents=True)
    for stem, content in records.items():
        text = content if isinstance(content, str) else json.dumps(content)
        (run / "records" / f"{stem}.json").write_text(text)
    return run


def bench(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", *map(str, args)],
                          check=False, capture_output=True, text=True, env=ENV, timeout=300)


@pytest.fixture
def secret(tmp_path) -> Path:
    """A file outside the run folder that must never reach the report, and a PNG-named
    copy of it (so only the location, not the suffix, can keep it out)."""
    path = tmp_path / "secret.txt"
    path.write_text(SECRET + "\n")
    (tmp_path / "secret.png").write_bytes(b"\x89PNG\r\n\x1a\n" + SECRET.encode())
    return path


def _warnings(proc) -> list[str]:
    assert "Traceback" not in proc.stderr
    return [line for line in proc.stderr.splitlines() if line.startswith("bench: warning:")]


def test_record_strings_are_escaped(tmp_path):
    hostile = record(label=f"q[x={SCRIPT}]", model=f"<img src=x onerror=alert(1)>{SCRIPT}")
    failed = record(label="r", status="failed", error=f"</pre>{SCRIPT}<pre>")
    partial = record(label="s", metric_errors={f"<b>{SCRIPT}</b>": SCRIPT})
    run = run_folder(tmp_path, {"status": record(status=SCRIPT), "hostile": hostile,
                                "failed": failed, "partial": partial})
    proc = bench("report", run)
    assert proc.returncode == 0, proc.stderr
    page = without_own_scripts((run / "index.html").read_text())
    assert "<script" not in page.lower() and "<img src=x" not in page.lower()
    assert "<b>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page  # shown, as text
    # the record with the script as its status is left out, and says so
    assert ("&#x27;status&#x27; must be one of &#x27;ok&#x27;, &#x27;ok, off target&#x27;, "
            "&#x27;failed&#x27;, &#x27;skipped&#x27;") in page
    assert len(_warnings(proc)) == 1, proc.stderr


@pytest.mark.parametrize("single_file", [False, True], ids=["files", "single-file"])
def test_artifacts_are_read_only_from_inside_the_run_folder(tmp_path, secret, single_file):
    run = run_folder(tmp_path, {})
    (run / "images").mkdir()
    (run / "images" / "inside.png").symlink_to(tmp_path / "secret.png")
    (run / "images" / "text.png").write_text("not an image\n")
    (run / "images" / "ok.png").write_bytes(_png())
    artifacts = ["/etc/passwd", "../secret.txt", "../secret.png", str(secret),
                 "records/../../secret.png", "images/inside.png", "images/text.png",
                 "records/a.json", "images/ok.png"]
    write_record(run / "records" / "a.json", record(artifacts=artifacts))
    proc = bench("report", run, *["--single-file"] * single_file)
    assert proc.returncode == 0, proc.stderr
    page = (run / "index.html").read_text()
    assert SECRET not in page
    for blob in (secret.read_bytes(), (tmp_path / "secret.png").read_bytes(),
                 Path("/etc/passwd").read_bytes(), b"not an image"):
        assert base64.b64encode(blob).decode()[:24] not in page
    if single_file:  # the one real artifact is shown, inlined
        assert base64.b64encode(_png()).decode() in page
    else:  # ... as a thumbnail linking to the file
        assert ("<a href='images/ok.png'><img src='images/thumbs/ok.jpg' alt='ok'"
                in page)
        written = [p for p in run.rglob("*") if p.is_file() and not p.is_symlink()]
        assert (run / "images" / "thumbs" / "ok.jpg") in written
        assert all(SECRET.encode() not in p.read_bytes() for p in written)
        assert not (run / "images" / "thumbs" / "inside.jpg").exists()
    assert page.count("outside the run folder") == 6
    assert "&#x27;images/inside.png&#x27;: outside the run folder" in page
    assert "&#x27;images/text.png&#x27;: not a PNG file" in page
    assert "&#x27;records/a.json&#x27;: not a .png file" in page
    warnings = _warnings(proc)
    assert len(warnings) == 8, proc.stderr
    assert all(SECRET not in line for line in warnings)


def test_images_are_not_written_through_a_link_out_of_the_run_folder(tmp_path):
    """A run folder whose images/thumbs links elsewhere: the thumbnails are not written
    there, and the report says why."""
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    run = run_folder(tmp_path, {})
    (run / "images").mkdir()
    (run / "images" / "thumbs").symlink_to(outside)
    (run / "images" / "ok.png").write_bytes(_png())
    write_record(run / "records" / "a.json", record(artifacts=["images/ok.png"]))
    proc = bench("report", run)
    assert proc.returncode == 0, proc.stderr
    assert list(outside.iterdir()) == []
    page = (run / "index.html").read_text()
    assert "&#x27;images/thumbs/ok.jpg&#x27;: its folder leaves the run folder" in page
    assert len(_warnings(proc)) == 1, proc.stderr


@pytest.mark.parametrize("name", [".PNG", ".png", "images/.Png"])
def test_a_file_named_only_its_suffix_is_refused(tmp_path, name):
    """A dotfile called ``.PNG`` is no PNG file, whatever the case of its name; an
    upper-case suffix after a name is one."""
    run = tmp_path / "run"
    for path in (run / name, run / "images" / "a.PNG"):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(_png())
    refused = []
    assert run_file(run, name, refused, "image", ".png", 1 << 20) is None
    assert refused == [f"image {name!r}: not a .png file; not shown"]
    assert run_file(run, "images/a.PNG", refused, "image", ".png", 1 << 20) == (
        _png(), "images/a.PNG")


@pytest.mark.parametrize("name", ["a/../../x.js", "../x.js", "/tmp/x.js"])
def test_the_report_writes_no_file_named_out_of_the_run_folder(tmp_path, name):
    run = tmp_path / "run"
    run.mkdir()
    refused = []
    assert RunFiles(run, refused).file(name, b"x") == ""
    assert refused == [f"{name!r}: not a path inside the run folder; not written"]
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["run"]


def _png() -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (2, 2), (10, 200, 30)).save(buf, format="PNG")
    return buf.getvalue()


BAD_RECORDS = {
    "not json": "{\"schema\": 1, ",
    "a list": "[1, 2, 3]",
    "no job": json.dumps({k: v for k, v in record().items() if k != "job"}),
    "faces a string": json.dumps(record(job=record()["job"] | {"target_faces": "100"})),
    "metric a string": json.dumps(record(metrics={"d_rms": "5.0"})),
    "unknown protocol field": json.dumps(record(job=record()["job"] | {
        "protocol": Protocol().as_dict() | {"msaa": 4, "extra": 1}})),
    "hash not hex": json.dumps(record(model={"name": "m", "hash": "../../etc", "faces": 1})),
    "binary": "\x00\xff\xfe",
    "nested": "[" * 100_000,
}


def test_a_bad_record_is_skipped_with_a_warning(tmp_path):
    files = {f"bad{i}": text for i, text in enumerate(BAD_RECORDS.values())}
    run = run_folder(tmp_path, {"good": record(label="good-one"), **files})
    proc = bench("report", run)
    assert proc.returncode == 0, proc.stderr
    warnings = _warnings(proc)
    assert len(warnings) == len(BAD_RECORDS), proc.stderr
    for i, line in enumerate(sorted(warnings)):
        assert f"bad{i}.json: not a" in line
    page = (run / "index.html").read_text()
    assert "good-one" in page and page.count("bad") >= len(BAD_RECORDS)
    assert "Left out of this report" in page
    assert (run / "results.csv").read_text().count("\n") == 2  # header and the good one


def test_a_record_linked_from_outside_the_run_folder_is_not_read(tmp_path):
    outside = tmp_path / "elsewhere.json"
    outside.write_text(json.dumps(record(label="from-elsewhere")))
    run = run_folder(tmp_path, {"good": record()})
    (run / "records" / "link.json").symlink_to(outside)
    skipped = []
    records = load_records(run, skipped=skipped)
    assert [r["job"]["label"] for r in records] == ["q"]
    assert len(skipped) == 1 and "links outside the run folder" in skipped[0]


def test_report_and_table_are_replaced_not_rewritten_in_place(tmp_path):
    """A reader holding the old file (a browser, a spreadsheet) keeps a whole old file:
    the new one is written beside it and renamed over it, so a hard link to the old one
    still shows the old content."""
    run = run_folder(tmp_path, {"a": record()})
    records = load_records(run)
    for name, write in (("index.html", lambda: write_report(run, records)),
                        ("results.csv", lambda: write_table(run, records))):
        (run / name).write_text("old\n")
        os.link(run / name, tmp_path / f"held-{name}")
        write()
        assert (tmp_path / f"held-{name}").read_text() == "old\n"
        assert (run / name).read_text() != "old\n"
    # the report's plots are files of images/; no temporary file is left anywhere
    assert sorted(p.name for p in run.iterdir()) == ["images", "index.html", "records",
                                                     "results.csv"]
    assert not [p for p in run.rglob("*") if p.name.startswith(".")]


def test_outputs_get_the_umask_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        run = run_folder(tmp_path, {})
        write_record(run / "records" / "r.json", record())
        write_report(run, [record()])
        write_table(run, [record()])
    finally:
        os.umask(old)
    plots = list((run / "images").rglob("*.svg"))
    assert plots
    for path in (run / "records" / "r.json", run / "index.html", run / "results.csv", *plots):
        assert path.stat().st_mode & 0o777 == 0o644, path


def _paths(value, prefix=()):
    """Every key path into the dicts (and first list items) of ``value``."""
    if isinstance(value, dict):
        for key, item in value.items():
            yield (*prefix, key)
            yield from _paths(item, (*prefix, key))
    elif isinstance(value, list) and value:
        yield (*prefix, 0)
        yield from _paths(value[0], (*prefix, 0))


MUTATIONS = {"deleted": ..., "null": None, "a string": "<b>x</b>", "a list": [],
             "an object": {}, "NaN": float("nan"), "huge": 1e308, "negative": -1, "true": True}


def test_any_damaged_field_is_refused_at_load_or_harmless_after(tmp_path):
    """Each field of a full record deleted or replaced by a value of another type: the
    record is refused in one line by load_record, or the table, the gate and the report
    all take it. Never a KeyError, TypeError or a formatting error."""
    from bench.records.check import compare, make_baseline
    from bench.records.results import load_record, records_table

    base = record(artifacts=["images/a.png"], metric_errors={"flip": "boom"},
                  stop_reason=None, seconds={"render": 1.0}, mesh_file_error="too big",
                  environment={"git_commit": "abc", "machine": {"processor": "cpu"}})
    base["metrics"]["exterior_share"] = 0.5
    accepted, refused = [], 0
    for i, path in enumerate(_paths(base)):
        for how, value in MUTATIONS.items():
            r = json.loads(json.dumps(base))
            r["job"]["label"] = f"q{i}-{how.replace(' ', '-')}"
            target = r
            for step in path[:-1]:
                target = target[step]
            if how == "deleted":
                if isinstance(target, list):
                    continue
                del target[path[-1]]
            else:
                target[path[-1]] = value
            file = tmp_path / "r.json"
            file.write_text(json.dumps(r))
            try:
                accepted.append(load_record(file))
            except InputError as exc:
                assert "\n" not in str(exc)
                refused += 1
    assert refused and len(accepted) > 100
    records_table(accepted)
    compare(make_baseline([base]), make_baseline(accepted))
    run = tmp_path / "run"
    run.mkdir()
    try:
        write_report(run, accepted)
    except Exception:  # name the first record the report cannot take
        for r in accepted:
            write_report(run, [r])
        raise
