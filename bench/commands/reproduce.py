"""``bench reproduce [--claims NAME,...] [--out DIR]``: run the suites that the papers'
claims need (each in ``DIR/<suite>``, reusing its records as ``--resume`` does), decide
every claim from the records, and write ``DIR/claims.csv`` and a Reproduction page
(``DIR/index.html``).

Each claim has a verdict (how many of its rows pass) and a class (whether the
difference is significant over the views: ``holds``, ``holds, not significant``, ``does
not hold``, ``contradicted``, or ``no test`` without per-view values), with the deciding
p-value after Holm's correction over its rows (:mod:`bench.records.claims`)."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

from bench.core.errors import InputError, UnknownNameError
from bench.core.registry import suggest
from bench.records.claims import evaluate_claim
from bench.records.suites import SUITES

#: Columns of claims.csv, in order.
CSV_COLUMNS = ["claim", "suite", "source", "statement", "metric", "method", "against",
               "test", "paper", "paper_value", "rows", "passed", "worst", "verdict",
               "class", "p", "effect", "sign_p", "side"]


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="test the papers' claims: run their suites, write a "
                       "claims table", description=__doc__)
    p.add_argument("--claims", help="comma-separated claim names (default: every claim; "
                   "bench list claims)")
    p.add_argument("--out", default="reports/reproduce",
                   help="folder of the suite runs and the claims table "
                   "(default: reports/reproduce)")
    p.add_argument("--jobs", "-j", default=None, metavar="N",
                   help="worker processes for the suite runs (default: CPU count)")
    p.add_argument("--timeout", default="900", metavar="S",
                   help="seconds a job's method may take (default 900)")
    p.add_argument("--no-run", action="store_true", help="decide the claims from the "
                   "records already in DIR; run nothing")
    p.set_defaults(run=run)


def all_claims() -> dict:
    """Every suite's claims by name, in the suites' order."""
    return {c.name: c for s in SUITES.values() for c in s.claims}


def selected(text: str | None) -> list:
    known = all_claims()
    names = [t.strip() for t in (text or "").split(",") if t.strip()]
    for n in names:
        if n not in known:
            raise UnknownNameError(f"unknown claim '{n}'{suggest(n, known)} (bench list "
                                   "claims shows them)")
    return [known[n] for n in names] if names else list(known.values())


def run(args) -> int:
    from bench.commands import one_line
    from bench.commands import run as run_cmd
    from bench.records.results import load_records

    claims = selected(args.claims)
    out = Path(args.out)
    run_cmd._check_out(out)
    suites = list(dict.fromkeys(c.suite for c in claims))
    start, status = time.perf_counter(), 0
    if not args.no_run:
        for i, suite in enumerate(suites, 1):
            print(f"bench reproduce: suite {i} of {len(suites)}: {suite}", file=sys.stderr)
            argv = ["run", "--suite", suite, "--out", str(out / suite), "--resume",
                    "--timeout", args.timeout] + (["--jobs", args.jobs] if args.jobs else [])
            status |= run_cmd.run(_run_parser().parse_args(argv))
    seconds = None if args.no_run else time.perf_counter() - start
    records = {s: load_records(out / s) if (out / s / "records").is_dir() else []
               for s in suites}
    results = [evaluate_claim(c, records[c.suite]) for c in claims]
    _write_csv(out, results)
    from bench.report.claims import write_reproduction

    page = write_reproduction(out, results, seconds)
    width = max(len(c.name) for c in claims)
    test_width = max([26] + [len(c.test) + 1 for c in claims])
    print(f"{'claim':<{width}}  {'test':<{test_width}} {'paper':<22} {'ours':<28} "
          f"{'verdict':<15} {'class':<23} p")
    for res in results:
        print(one_line(f"{res.claim.name:<{width}}  {res.claim.test:<{test_width}} "
                       f"{res.claim.paper or 'qualitative':<22} {res.summary:<28} "
                       f"{res.verdict:<15} {res.klass or '':<23} {_p(res.p)}"))
    took = f" in {seconds / 60:.1f} min" if seconds is not None else ""
    print(f"bench: {len(results)} claims{took}; wrote {out / 'claims.csv'} and {page}",
          file=sys.stderr)
    return status


def _p(p: float | None) -> str:
    """A p-value for the table: 3 significant digits, empty when there is none."""
    return "" if p is None else f"{p:.3g}"


def _run_parser() -> argparse.ArgumentParser:
    """``bench run``'s own parser, so a suite run here has exactly its defaults."""
    from bench.commands import run as run_cmd

    parser = argparse.ArgumentParser(prog="bench")
    run_cmd.add_parser(parser.add_subparsers(), "run")
    return parser


def _write_csv(out: Path, results: list) -> None:
    import pandas as pd

    from bench.io.atomic import write_atomic

    rows = []
    for res in results:
        c = res.claim
        worst = res.worst
        rows.append({"claim": c.name, "suite": c.suite, "source": c.source,
                     "statement": c.statement, "metric": c.metric, "method": c.method,
                     "against": c.against or "", "test": c.test, "paper": c.paper,
                     "paper_value": "" if c.paper_value is None else c.paper_value,
                     "rows": len(res.rows), "passed": res.passed,
                     "worst": "" if worst is None or math.isnan(worst) else worst,
                     "verdict": res.verdict, "class": res.klass or "",
                     **{k: "" if v is None else v for k, v in (
                         ("p", res.p), ("effect", res.effect), ("sign_p", res.sign_p),
                         ("side", res.side))}})
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_atomic(out / "claims.csv", pd.DataFrame(rows, columns=CSV_COLUMNS)
                     .to_csv(index=False))
    except OSError as exc:
        raise InputError(f"{out / 'claims.csv'}: cannot write it ({exc.strerror or exc})") \
            from None
