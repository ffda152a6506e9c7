"""Print the screen-size tables of a run (bench/report/screen_tables.py) as Markdown:
switch_px per level and faces needed at 128 and 64 px, the fewest faces per model, each
predictor's accuracy and the τ ablation; with --charts DIR also one chart "faces needed
vs screen size" per model.

    python scripts/screen_table.py RUN_DIR [--charts DIR]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bench.core.errors import BenchError
from bench.records.results import load_records
from bench.report.screen_tables import (
    ablation_table,
    best_at,
    faces_needed_chart,
    markdown,
    predictor_table,
    switch_rows,
    switch_table,
)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--charts", type=Path, help="write model.png charts into this folder")
    args = parser.parse_args(argv)
    try:
        rows = switch_rows(load_records(args.run))
    except BenchError as exc:
        print(f"screen_table: error: {exc}", file=sys.stderr)
        return 2
    if not rows:
        print(f"screen_table: error: {args.run} has no screen-size results; run with "
              "--screen-sizes or --suite lod", file=sys.stderr)
        return 2
    for title, table in (("switch_px per level; faces needed", switch_table(rows)),
                         ("fewest faces at 128 px", best_at(rows, 128)),
                         ("fewest faces at 64 px", best_at(rows, 64)),
                         ("predictors (measured / predicted)", predictor_table(rows)),
                         ("faces needed at 128 px per τ", ablation_table(rows))):
        print(f"## {title}\n\n{markdown(table)}\n")
    if args.charts:
        for model in sorted({row["model"] for row in rows}):
            path = faces_needed_chart(rows, model, args.charts / f"{model}.png")
            if path:
                print(f"wrote {path}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
