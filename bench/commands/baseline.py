"""``bench baseline DIR --out FILE``: save a run's metrics as the baseline for bench check."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from bench.harness.check import make_baseline
from bench.harness.results import load_records


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="save a run as the regression baseline", description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--out", required=True, metavar="FILE")
    p.set_defaults(run=run)


def run(args) -> int:
    baseline = make_baseline(load_records(Path(args.run_dir)))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(baseline, indent=1, sort_keys=True) + "\n")
    print(f"bench: wrote {args.out} ({len(baseline['entries'])} jobs)", file=sys.stderr)
    return 0
