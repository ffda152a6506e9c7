"""``bench baseline DIR --out FILE``: save a run's metrics as the baseline for bench check."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from bench.core.errors import InputError
from bench.io.atomic import write_atomic
from bench.records.check import load_run, make_baseline


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="save a run as the regression baseline", description=__doc__)
    p.add_argument("run_dir", metavar="DIR")
    p.add_argument("--out", required=True, metavar="FILE")
    p.set_defaults(run=run)


def run(args) -> int:
    baseline = make_baseline(load_run(Path(args.run_dir)))
    if not baseline["entries"]:
        raise InputError(f"{args.run_dir}: no records to make a baseline of")
    for key, entry in baseline["entries"].items():  # a NaN baseline would gate nothing
        for metric, value in entry["metrics"].items():
            if not math.isfinite(value):
                raise InputError(f"{args.run_dir}: job '{key}' has {metric} = {value}; a "
                                 "baseline needs finite values (re-run that job)")
    out = Path(args.out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(out, json.dumps(baseline, indent=1, sort_keys=True) + "\n")
    except OSError as exc:
        raise InputError(f"{out}: cannot write the baseline ({exc.strerror or exc})") from None
    print(f"bench: wrote {out} ({len(baseline['entries'])} jobs)", file=sys.stderr)
    return 0
