"""``bench check DIR --baseline FILE [--tolerance 0.02]``: compare a run with a baseline;
exit 1 when any metric got worse beyond the tolerance, a job newly fails, or a baseline
job is missing."""

from __future__ import annotations

import sys
from pathlib import Path

from bench.commands import one_line
from bench.harness.check import (
    FAILING_MARKS,
    check_tolerance,
    compare,
    load_baseline,
    make_baseline,
)
from bench.harness.results import load_records


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="fail on quality regressions against a baseline",
                       description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--baseline", required=True, metavar="FILE")
    p.add_argument("--tolerance", default="0.02", metavar="FRACTION",
                   help="allowed relative change in the bad direction, finite and >= 0 "
                   "(default 0.02)")
    p.add_argument("--all", action="store_true", help="show unchanged metrics too")
    p.set_defaults(run=run)


def run(args) -> int:
    tolerance = check_tolerance(args.tolerance)  # before reading anything
    baseline = load_baseline(Path(args.baseline))
    current = make_baseline(load_records(Path(args.run_dir)))
    rows = compare(baseline, current, tolerance)
    shown = [r for r in rows if args.all or r.mark != "same"]
    width = max([len(r.job) for r in shown] + [3])
    if shown:
        print(f"{'job':<{width}}  {'metric':<16} {'baseline':>12} {'current':>12}  mark")
    for r in shown:  # job names and values come from files: shown on one line each
        print(one_line(f"{r.job:<{width}}  {r.metric:<16} {_fmt(r.baseline):>12} "
                       f"{_fmt(r.current):>12}  {r.mark}"))
    failing = [r for r in rows if r.mark in FAILING_MARKS]
    counts = {m: sum(r.mark == m for r in rows) for m in dict.fromkeys(r.mark for r in rows)}
    print("bench check: " + ", ".join(f"{n} {m}" for m, n in counts.items()), file=sys.stderr)
    if failing:
        print(f"bench check: FAILED ({len(failing)} regressions, tolerance {tolerance:g})",
              file=sys.stderr)
        return 1
    print("bench check: passed", file=sys.stderr)
    return 0


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.5g}"
    return "" if value is None else str(value)
