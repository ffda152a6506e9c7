"""``bench compare DIR --methods A,B [--metric d_rms] [--format text]``: is A better than
B in DIR's run? One row per model, budget and shading where both have an ok record: the
metric's value of each, the median per-view difference A - B, the share of views where
each is better, the Wilcoxon signed-rank p-value over the views, the same after Holm's
correction over the table's rows, and the verdict at 0.05 after the correction: ``A
better``, ``B better`` or ``tie``. A last line gives the sign test over the rows (the
rows each method has the better value in, exact ties left out).

The views are not independent draws: a verdict says whether one method is better
consistently across the viewpoints of that model at that budget, and the sign test,
whether it is across the models and budgets of the run (with four rows or fewer it
cannot be significant). ``no test`` marks a row whose records have no per-view values
of the metric (see :mod:`bench.records.stats`). ``--format markdown`` prints the table
for a pull-request comment, ``--format json`` as objects; the sign test line goes to
standard error in every format.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from bench.commands import one_line
from bench.core.errors import InputError

FORMATS = ("text", "markdown", "json")
COLUMNS = ("model", "target_faces", "shading", "a_value", "b_value", "median_difference",
           "a_better", "b_better", "p", "p_holm", "verdict")


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="test view by view whether one method beats another",
                       description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--methods", required=True, metavar="A,B",
                   help="two method labels of the run, as in its results.csv")
    p.add_argument("--metric", default="d_rms",
                   help="a metric with per-view values (default d_rms; ssim, flip)")
    p.add_argument("--format", choices=FORMATS, default="text",
                   help="text (default), markdown (a pull-request comment) or json")
    p.set_defaults(run=run)


def run(args) -> int:
    from bench.records.results import load_records

    a, b = _methods(args.methods)
    records = load_records(Path(args.run_dir))
    rows, sign = compare_methods(records, a, b, args.metric)
    if args.format == "json":
        print(json.dumps({"a": a, "b": b, "metric": args.metric, "rows": rows,
                          "sign_test": sign}, indent=1))
    elif args.format == "markdown":
        print(markdown(rows, a, b, args.metric, sign))
    else:
        _print_text(rows, a, b)
    print(f"bench compare: {one_line(_sign_line(sign, a, b))}", file=sys.stderr)
    return 0


def _methods(text: str) -> tuple[str, str]:
    names = [t.strip() for t in text.split(",")]
    if len(names) != 2 or not all(names) or names[0] == names[1]:
        raise InputError(f"--methods needs two different method labels, A,B; got {text!r}")
    return names[0], names[1]


def compare_methods(records: list[dict], a: str, b: str, metric: str = "d_rms"
                    ) -> tuple[list[dict], dict]:
    """The rows of the comparison of ``a`` with ``b`` on ``metric`` (the module's
    docstring) and the sign test over them, as plain data."""
    from bench.core.method import canonical_label
    from bench.records.check import metric_info
    from bench.records.results import OK, shading_label
    from bench.records.stats import ALPHA, consistent_views, holm, paired, sign_test

    unit, higher = metric_info().get(metric, ("", None))
    if higher is None:
        raise InputError(f"--metric {metric!r} is not a metric with a direction; "
                         "choose d_rms, ssim or flip (bench list metrics)")
    wanted = {canonical_label(a): "a", canonical_label(b): "b"}
    labels = sorted({r["job"]["label"] for r in records})
    for name in (a, b):
        if canonical_label(name) not in {canonical_label(x) for x in labels}:
            raise InputError(f"method {name!r} has no record in this run; its methods are: "
                             f"{', '.join(labels) or 'none'}")
    cells: dict[tuple, dict] = {}
    for r in records:
        side = wanted.get(canonical_label(r["job"]["label"]))
        if side and r["status"] == OK:
            key = (r["job"]["model"], r["job"]["target_faces"], shading_label(r["job"]["protocol"]))
            cells.setdefault(key, {})[side] = r
    rows, tests = [], []
    for (model, target, shading), got in sorted(cells.items(), key=lambda kv: (
            kv[0][0], kv[0][1], kv[0][2])):
        if len(got) < 2:
            continue
        va, vb = (consistent_views(got[s], metric) for s in ("a", "b"))
        row = {"model": model, "target_faces": target, "shading": shading,
               "a_value": (got["a"]["metrics"] or {}).get(metric),
               "b_value": (got["b"]["metrics"] or {}).get(metric)}
        test = paired(va, vb, higher) if va and vb and len(va) == len(vb) else None
        if test is not None:
            row.update(median_difference=test.median_difference, a_better=test.a_better,
                       b_better=test.b_better, p=test.p)
        rows.append(row)
        tests.append(test)
    corrected = iter(holm([t.p for t in tests if t is not None]))
    for row, test in zip(rows, tests):
        if test is None:
            row.update(median_difference=None, a_better=None, b_better=None, p=None,
                       p_holm=None, verdict="no test")
        else:
            row["p_holm"] = next(corrected)
            row["verdict"] = test.verdict(row["p_holm"], ALPHA)
    wins = losses = 0
    for row in rows:
        x, y = row["a_value"], row["b_value"]
        if isinstance(x, (int, float)) and isinstance(y, (int, float)) and x != y:
            if (x > y) == higher:
                wins += 1
            else:
                losses += 1
    sign = {"a_wins": wins, "b_wins": losses, "ties": len(rows) - wins - losses,
            "p": sign_test(wins, losses), "unit": unit}
    return rows, sign


def _sign_line(sign: dict, a: str, b: str) -> str:
    return (f"sign test over rows: {a} better in {sign['a_wins']}, {b} in {sign['b_wins']}, "
            f"{sign['ties']} equal; p = {sign['p']:.3g}")


def _fmt(value, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return f"{value:.{digits}g}" if isinstance(value, float) else str(value)


def _share(value) -> str:
    return "" if value is None else f"{value:.0%}"


def _cells(row: dict) -> list[str]:
    return [str(row["model"]), str(row["target_faces"]), str(row["shading"]),
            _fmt(row["a_value"]), _fmt(row["b_value"]), _fmt(row["median_difference"]),
            _share(row["a_better"]), _share(row["b_better"]), _fmt(row["p"], 3),
            _fmt(row["p_holm"], 3), row["verdict"]]


def _print_text(rows: list[dict], a: str, b: str) -> None:
    print(one_line(f"A = {a}, B = {b}"))
    head = ["model", "target", "shading", "A", "B", "median A-B", "A better", "B better",
            "p", "p (Holm)", "verdict"]
    table = [head] + [_cells(r) for r in rows]
    width = [max(len(one_line(t[i])) for t in table) for i in range(len(head))]
    for t in table:
        print(one_line("  ".join(c.ljust(w) for c, w in zip(t, width))).rstrip())


def markdown(rows: list[dict], a: str, b: str, metric: str, sign: dict) -> str:
    """The comparison as a GitHub-flavoured Markdown table, every cell escaped."""
    from bench.commands.check import _md

    lines = [f"**bench compare: A = {_md(a)}, B = {_md(b)}, {_md(metric)}**", "",
             ("| model | target | shading | A | B | median A-B | A better | B better | p | "
              "p (Holm) | verdict |"),
             "| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    lines += ["| " + " | ".join(_md(c) for c in _cells(r)) + " |" for r in rows]
    lines += ["", _md(_sign_line(sign, a, b))]
    return "\n".join(lines)
