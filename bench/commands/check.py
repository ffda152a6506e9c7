"""``bench check DIR --baseline FILE [--tolerance 0.02] [--format text]``: compare a run
with a baseline; exit 1 when any metric got worse beyond the tolerance, a job newly
fails, a baseline job is missing or a claim that held no longer holds.

``--format markdown`` prints the comparison as a table for a pull-request comment;
``--format json`` prints the run's smaller-is-better metrics as ``[{name, unit, value,
extra}]`` entries, the input github-action-benchmark reads as ``customSmallerIsBetter``
(``json-bigger``: the higher-is-better ones, for ``customBiggerIsBetter``), each entry's
``extra`` naming the baseline's value and the mark. The verdict and the exit code are
the same in every format; the counts line goes to standard error.
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path

from bench.commands import one_line, stdout_closed
from bench.records.check import (
    FAILING_MARKS,
    Row,
    check_tolerance,
    compare,
    load_baseline,
    load_run,
    make_baseline,
    metric_info,
)

FORMATS = ("text", "markdown", "json", "json-bigger")


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="fail on quality regressions against a baseline",
                       description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--baseline", required=True, metavar="FILE")
    p.add_argument("--tolerance", default="0.02", metavar="FRACTION",
                   help="allowed relative change in the bad direction, finite and >= 0 "
                   "(default 0.02)")
    p.add_argument("--all", action="store_true", help="show unchanged metrics too")
    p.add_argument("--format", choices=FORMATS, default="text",
                   help="text (default), markdown (a pull-request comment), json / "
                   "json-bigger (github-action-benchmark's customSmallerIsBetter / "
                   "customBiggerIsBetter)")
    p.set_defaults(run=run)


def run(args) -> int:
    tolerance = check_tolerance(args.tolerance)  # before reading anything
    baseline = load_baseline(Path(args.baseline))
    current = make_baseline(load_run(Path(args.run_dir)))
    rows = compare(baseline, current, tolerance)
    failing = [r for r in rows if r.mark in FAILING_MARKS]
    counts = {m: sum(r.mark == m for r in rows) for m in dict.fromkeys(r.mark for r in rows)}
    summary = ", ".join(f"{n} {m}" for m, n in counts.items())
    verdict = (f"FAILED ({len(failing)} regressions, tolerance {tolerance:g})" if failing
               else "passed")
    shown = [r for r in rows if args.all or r.mark != "same"]
    try:
        if args.format == "text":
            _print_text(shown)
        elif args.format == "markdown":
            print(markdown(shown, verdict, summary))
        else:
            print(json.dumps(benchmark_entries(current, rows,
                                               higher=args.format == "json-bigger"), indent=1))
        sys.stdout.flush()
    except BrokenPipeError:  # `| head`: the reader left; the verdict still stands
        stdout_closed()
    print(f"bench check: {summary}", file=sys.stderr)
    print(f"bench check: {verdict}", file=sys.stderr)
    return 1 if failing else 0


def _print_text(shown: list[Row]) -> None:
    width = max([len(r.job) for r in shown] + [3])
    if shown:
        print(f"{'job':<{width}}  {'metric':<16} {'baseline':>12} {'current':>12}  mark")
    for r in shown:  # job names and values come from files: shown on one line each
        print(one_line(f"{r.job:<{width}}  {r.metric:<16} {_fmt(r.baseline):>12} "
                       f"{_fmt(r.current):>12}  {r.mark}"))


def markdown(shown: list[Row], verdict: str, summary: str) -> str:
    """The comparison as GitHub-flavoured Markdown: the verdict, the counts, and a table
    of ``shown`` with the change in per cent; failing marks in bold. Every cell from a
    file is escaped, so a job name cannot end a cell, start markup, hold HTML, mention
    anyone or link anywhere (:func:`_md`)."""
    lines = [f"**bench check: {_md(verdict)}**", "", _md(summary)]
    if shown:
        lines += ["", "| job | metric | baseline | current | change | mark |",
                  "| --- | --- | ---: | ---: | ---: | --- |"]
        for r in shown:
            mark = f"**{_md(r.mark)}**" if r.mark in FAILING_MARKS else _md(r.mark)
            lines.append(f"| {_md(r.job)} | {_md(r.metric)} | {_md(_fmt(r.baseline))} | "
                         f"{_md(_fmt(r.current))} | {_change(r)} | {mark} |")
    return "\n".join(lines)


def benchmark_entries(current: dict, rows: list[Row], higher: bool) -> list[dict]:
    """github-action-benchmark's entries: every finite metric of the run whose direction
    is ``higher`` (higher is better) or the other, one entry per (job, metric), named
    ``job: metric`` (the job being ``model | method | faces | shading``)."""
    info = metric_info()
    marks = {(r.job, r.metric): r for r in rows}
    out = []
    for job, entry in current["entries"].items():
        for metric, value in entry["metrics"].items():
            unit, direction = info.get(metric, ("", None))
            if direction is not higher or not math.isfinite(value):
                continue
            row = marks.get((job, metric))
            extra = (f"baseline {_fmt(row.baseline)}, {row.mark}" if row is not None
                     else "not in the baseline")
            out.append({"name": one_line(f"{job}: {metric}"), "unit": unit,
                        "value": float(value), "extra": one_line(extra)})
    return out


def _change(r: Row) -> str:
    if isinstance(r.baseline, (int, float)) and isinstance(r.current, (int, float)) \
            and r.baseline and math.isfinite(r.baseline) and math.isfinite(r.current):
        return f"{100 * (r.current - r.baseline) / abs(r.baseline):+.2f} %"
    return ""


#: Put where GitHub would otherwise see a mention (``@name``, which notifies that user
#: or team), an issue reference (``#12``) or an autolinked URL or e-mail address
#: (``http://``, ``www.``, ``a@b.org``): the zero-width joiner shows as nothing and
#: breaks the pattern, so a name from a record cannot ping anyone from a PR comment.
JOINER = "\u200d"
_AUTOLINKS = re.compile(r"(@|#|:(?=//)|(?<![^\W_])www(?=\.))", re.IGNORECASE)


def _md(text) -> str:
    """``text`` safe in a Markdown table cell: one line, HTML and Markdown's own
    characters escaped, mentions, issue references and autolinks broken by
    :data:`JOINER`."""
    text = one_line(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    for ch in "\\|*_`[]#~":
        text = text.replace(ch, "\\" + ch)
    return _AUTOLINKS.sub(lambda m: m.group(0) + JOINER, text)


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.5g}"
    return "" if value is None else str(value)
