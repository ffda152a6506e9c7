"""Quality over commits: each metric per (model, method, budget, shading) against the
commit and date its run recorded, with the points where ``bench check`` would have
failed marked — the regression graphs of asv, for a folder of CI artifacts.

A run folder is one point. Its commit is the ``environment.git_commit`` most of its
records carry (the suite's checkout when the run was made; "unknown" where git was not
there) and its date the earliest record's ``created``; points are ordered by date, then
by folder name. Dates are compared as instants, with their UTC offsets
(``…T20:00-08:00`` is after ``…T01:00Z`` of the same day; one without an offset is
taken as UTC), never as text; a run without a readable date comes first. One folder
named twice (by two spellings, or a link) is one point. A point is checked as
``bench check`` would check that run against the run before it (or, given a baseline
file, against that baseline, as CI does with a committed one): a metric marked
``worse``, ``not finite`` or ``newly failing`` there is a failing point, and the check's
verdict is the point's. The page that draws them is
:mod:`bench.report.history`.

Run folders may come from anywhere, so they are read as the report reads them
(:func:`~bench.records.results.load_records` with bad records left out and named).
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from bench.core.errors import InputError
from bench.core.method import canonical_label
from bench.records.check import FAILING_MARKS, compare, load_run, make_baseline, record_key
from bench.records.results import shading_label

__all__ = ["Point", "find_runs", "history_table", "instant", "load_history"]


@dataclass
class Point:
    """One run folder of the history."""

    folder: Path
    commit: str
    date: str
    entries: dict  # bench.records.check.make_baseline's entries of the run
    jobs: dict  # entry key -> (model, method label, target faces, shading)
    when: datetime | None = None  # ``date`` as an instant (None: no readable date)
    verdict: str = "first run"  # the check against the previous run (or the baseline)
    failing: dict = field(default_factory=dict)  # (job, metric) -> failing mark
    skipped: list = field(default_factory=list)  # bad records left out, with why


def find_runs(paths: list[Path]) -> list[Path]:
    """The run folders named: each path is a run folder (it has ``records/``) or a
    folder of run folders (one per commit, as CI artifacts arrive)."""
    runs = []
    for path in map(Path, paths):
        if (path / "records").is_dir():
            runs.append(path)
            continue
        inner = sorted(p for p in path.iterdir() if (p / "records").is_dir()) \
            if path.is_dir() else []
        if not inner:
            raise InputError(f"{path}: no run folder (a folder with records/) in it or "
                             "directly under it; give bench run --out folders")
        runs.extend(inner)
    unique = {}
    for run in runs:  # by identity: ./a, a/ and a link to a are one run
        st = os.stat(run)
        unique.setdefault((st.st_dev, st.st_ino), run)
    return list(unique.values())


def instant(text: str) -> datetime | None:
    """An ISO 8601 time (a record's ``created``) as an aware datetime, UTC when it has no
    offset; None when it does not parse."""
    try:
        when = datetime.fromisoformat(text)
    except (TypeError, ValueError):
        return None
    return when if when.tzinfo is not None else when.replace(tzinfo=UTC)


def load_history(paths: list[Path], tolerance: float = 0.02,
                 baseline: dict | None = None) -> list[Point]:
    """The points of the run folders under ``paths``, ordered, each checked against the
    previous point or against ``baseline`` (a loaded baseline file) when given."""
    points = []
    for folder in find_runs(paths):
        skipped = []
        records = load_run(folder, skipped=skipped)
        commits = Counter(_text(_environment(r).get("git_commit")) or "unknown"
                          for r in records)
        dates = [(when, text) for text in (_text(r.get("created")) for r in records)
                 if (when := instant(text)) is not None]
        when, date = min(dates, default=(None, ""))
        points.append(Point(folder, commits.most_common(1)[0][0] if commits else "unknown",
                            date, make_baseline(records)["entries"],
                            {record_key(r): _job(r) for r in records}, when=when,
                            skipped=skipped))
    points.sort(key=lambda p: (p.when is not None, p.when or _EPOCH, str(p.folder)))
    for before, point in zip([None, *points], points):
        reference = baseline if baseline is not None else \
            None if before is None else {"entries": before.entries}
        if reference is None or not point.entries:
            continue
        rows = compare(reference, {"entries": point.entries}, tolerance)
        failing = [r for r in rows if r.mark in FAILING_MARKS]
        point.failing = {(r.job, r.metric): r.mark for r in failing}
        point.verdict = f"FAILED ({len(failing)})" if failing else "passed"
    return points


_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


def history_table(points: list[Point]):
    """A long pandas table: one row per (run, job, metric) with the run's commit and
    date and the check's failing mark (empty when the point passed)."""
    import pandas as pd

    rows = []
    for i, p in enumerate(points):
        for job, entry in p.entries.items():
            model, method, target, shading = p.jobs[job]
            for metric, value in entry["metrics"].items():
                rows.append({"run": i, "folder": p.folder.name, "commit": p.commit,
                             "date": p.date, "model": model, "method": method,
                             "target_faces": int(target), "shading": shading,
                             "metric": metric, "value": value,
                             "mark": p.failing.get((job, metric), "")})
    columns = ["run", "folder", "commit", "date", "model", "method", "target_faces",
               "shading", "metric", "value", "mark"]
    return pd.DataFrame(rows, columns=columns)


def _job(record: dict) -> tuple:
    job = record["job"]
    return (job["model"], canonical_label(job["label"]), job["target_faces"],
            shading_label(job["protocol"]))


def _environment(record: dict) -> dict:
    env = record.get("environment")
    return env if isinstance(env, dict) else {}


def _text(value) -> str:
    return value if isinstance(value, str) else ""


def as_dict(value) -> dict:
    return value if isinstance(value, dict) else {}
