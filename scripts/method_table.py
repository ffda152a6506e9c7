"""The README's "which method for what" table, from a run's results.csv.

    python scripts/method_table.py /work/runs/base-ci/results.csv

For each method: how far its image error (d_rms) and geometric error (hausdorff_mean)
are from the best method of the same model, budget and shading (mean of the ratios over
the jobs it finished, 1.00 = always the best), the seam cracks it left (summed), its
median seconds per job, and how many jobs finished ok. Jobs that did not finish ok
(skipped, failed) are left out of every figure and counted in the last column. Rows
are sorted by the d_rms ratio. Reads the CSV only (no suite import), so it runs on any
run folder's results, copied from anywhere.
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
from collections import defaultdict
from pathlib import Path


def table(rows: list[dict]) -> list[dict]:
    ok = [r for r in rows if r["status"] == "ok" and r["d_rms"] and r["hausdorff_mean"]]
    best: dict[tuple, dict[str, float]] = {}
    for r in ok:
        cell = (r["model"], r["target_faces"], r["shading"])
        b = best.setdefault(cell, {"d_rms": float("inf"), "hausdorff_mean": float("inf")})
        for metric in b:
            b[metric] = min(b[metric], float(r[metric]))
    per_method: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        per_method[r["method"]]["all"].append(r)
    for r in ok:
        m = per_method[r["method"]]
        cell = best[(r["model"], r["target_faces"], r["shading"])]
        for metric in ("d_rms", "hausdorff_mean"):
            m[metric].append(float(r[metric]) / cell[metric] if cell[metric] > 0 else 1.0)
        m["seam_cracks"].append(int(float(r["seam_cracks"] or 0)))
        m["seconds"].append(float(r["seconds"]))
    out = []
    for method, m in per_method.items():
        if not m["d_rms"]:
            out.append({"method": method, "ok": 0, "total": len(m["all"])})
            continue
        out.append({"method": method, "d_rms": statistics.fmean(m["d_rms"]),
                    "hausdorff_mean": statistics.fmean(m["hausdorff_mean"]),
                    "seam_cracks": sum(m["seam_cracks"]),
                    "seconds": statistics.median(m["seconds"]),
                    "ok": len(m["d_rms"]), "total": len(m["all"])})
    return sorted(out, key=lambda e: (e.get("d_rms", float("inf")), e["method"]))


def markdown(entries: list[dict]) -> str:
    lines = ["| method | d_rms × best ↓ | Hausdorff × best ↓ | seam cracks ↓ | s / job | jobs ok |",
             "| --- | ---: | ---: | ---: | ---: | ---: |"]
    for e in entries:
        if not e["ok"]:
            lines.append(f"| `{e['method']}` | — | — | — | — | 0 of {e['total']} |")
            continue
        lines.append(f"| `{e['method']}` | {e['d_rms']:.2f} | {e['hausdorff_mean']:.2f} | "
                     f"{e['seam_cracks']} | {e['seconds']:.2g} | {e['ok']} of {e['total']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="a run folder's results.csv")
    args = parser.parse_args(argv)
    try:
        with args.results.open(newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        print(f"method_table: error: {args.results}: {e.strerror}", file=sys.stderr)
        return 2
    needed = {"model", "method", "shading", "target_faces", "d_rms", "hausdorff_mean",
              "seam_cracks", "seconds", "status"}
    missing = needed - set(rows[0] if rows else ())
    if missing:
        print(f"method_table: error: {args.results}: not a results.csv (no column "
              f"{', '.join(sorted(missing))})", file=sys.stderr)
        return 2
    print(markdown(table(rows)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
