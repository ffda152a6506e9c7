"""``bench history RUN_DIR... [--out reports/history]``: each metric per (model, method,
budget, shading) against the commit and date recorded in the runs, with the points
where ``bench check`` would have failed marked in red. A RUN_DIR is a run folder or a
folder of them (one per commit, as CI artifacts arrive). Writes OUT/index.html,
OUT/history.csv and the figures under OUT/images/."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from bench.core.errors import InputError

#: The metrics drawn unless ``--metrics`` says otherwise.
DEFAULT_METRICS = ("d_rms", "flip", "ssim", "hausdorff_mean")


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="quality over commits, from several runs",
                       description=__doc__)
    p.add_argument("run_dirs", metavar="RUN_DIR", nargs="+")
    p.add_argument("--out", default="reports/history", metavar="DIR",
                   help="where the page goes (default reports/history; not a run folder)")
    p.add_argument("--baseline", metavar="FILE", help="check every run against this "
                   "baseline (as CI does) instead of against the run before it")
    p.add_argument("--tolerance", default="0.02", metavar="FRACTION",
                   help="as bench check's (default 0.02)")
    p.add_argument("--metrics", default=",".join(DEFAULT_METRICS), metavar="LIST",
                   help=f"metrics to draw, comma-separated (default {','.join(DEFAULT_METRICS)})")
    p.set_defaults(run=run)


def run(args) -> int:
    from bench.core.registry import suggest
    from bench.records.check import check_tolerance, load_baseline, metric_info
    from bench.records.history import load_history
    from bench.report.history import write_history

    tolerance = check_tolerance(args.tolerance)
    known = metric_info()
    metrics = [m.strip() for m in args.metrics.split(",") if m.strip()]
    for m in metrics:
        if m not in known:
            raise InputError(f"--metrics: no metric {m!r}{suggest(m, known)}; "
                             "bench list metrics shows them")
    out = Path(args.out)
    check_out(out)
    baseline = load_baseline(Path(args.baseline)) if args.baseline else None
    points = load_history([Path(d) for d in args.run_dirs], tolerance, baseline)
    reference = f"the baseline {Path(args.baseline).name}" if baseline else "the run before it"
    try:
        page = write_history(points, out, metrics, reference)
    except OSError as exc:
        raise InputError(f"--out {out}: cannot write the history there "
                         f"({exc.strerror or exc}); give a folder you can write to") from None
    failed = sum(p.verdict.startswith("FAILED") for p in points)
    print(f"bench history: {len(points)} runs, {failed} that bench check would have failed; "
          f"wrote {page}", file=sys.stderr)
    return 0


def check_out(out: Path) -> None:
    """InputError unless ``out`` can be the history's folder: not a file, and neither a
    run folder nor anywhere inside one (its ``images/`` included: the run's report owns
    them)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder; give a folder for the "
                         "history, e.g. reports/history")
    here = out.resolve()
    for folder in (here, *here.parents):
        if (folder / "records").is_dir():
            where = "a run folder" if folder == here else \
                f"inside the run folder {os.path.relpath(folder)}"
            raise InputError(f"--out {out}: that is {where} (its index.html and images/ are "
                             "the run's report); give another folder, e.g. reports/history")
