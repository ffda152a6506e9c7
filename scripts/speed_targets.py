"""The view-based methods' speed targets as a benchmark, in one checkout:

    .venv/bin/python scripts/speed_targets.py [--rounds 3] [--jobs NAME,...] [--threads T]

Each job runs in a fresh process: the model is loaded, the method is warmed up on the
tiny meshes of :mod:`bench.run.warmup` (numba's cache loading or compilation is not
method time, as in ``bench run``), then timed on the model (``wall_seconds``, the
method's own time). The jobs take turns round after round, so drift of a shared machine
hits them alike; the table gives each job's median, the triangles it removes per second
and its median over qslim's median of the same rounds, against the targets below.
``--threads`` sets the threads of the jobs' numba kernels (``NUMBA_NUM_THREADS``;
default: every core). Run nothing else meanwhile.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Target:
    """One timed job and what it should reach (None: no target on that figure)."""

    name: str
    method: str
    model: str
    faces: int
    seconds: float | None = None
    over_qslim: float | None = None


#: Lindstrom & Turk 2000's bunny to 1,332 faces, and González et al. 2008's Table 1
#: (815 -> 100, 4,698 -> 500, 13,810 -> 1,000 faces: 10x, 20x and 20x faster than the
#: paper's 12.27, 93.45 and 453.34 s).
TARGETS = (
    Target("qslim", "qslim", "bunny", 1332),
    Target("image-driven", "image-driven", "bunny", 1332, seconds=11.0, over_qslim=15.0),
    Target("entropy-815", "entropy-twin", "bunny-textured-815", 100, seconds=1.2),
    Target("entropy-4698", "entropy-twin", "bunny-textured-4698", 500, seconds=4.7),
    Target("entropy-13810", "entropy-twin", "torus-13810", 1000, seconds=22.7),
)

#: Seconds one job's process may take, loading and warm-up included.
JOB_LIMIT = 1800.0

CODE = """
import sys, warnings
import bench
from bench.run.warmup import warm_up
from bench.core.method import run_method
from bench.catalog import resolve_model
from bench.core.registry import registry
cls = registry("method").load(sys.argv[1])
mesh = resolve_model(sys.argv[2])
warm_up(cls)
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    result = run_method(cls(), mesh, int(sys.argv[3]))
print(mesh.n_faces, result.mesh.n_faces, result.stats["wall_seconds"])
"""


def time_job(target: Target, threads: int | None = None) -> tuple[int, int, float]:
    """(input faces, output faces, method seconds) of one fresh process."""
    env = dict(os.environ)
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    try:
        out = subprocess.run([sys.executable, "-c", CODE, target.method, target.model,
                              str(target.faces)], cwd=ROOT, capture_output=True, text=True,
                             timeout=JOB_LIMIT, check=False, env=env)
    except subprocess.TimeoutExpired:
        sys.exit(f"{target.name}: no result within {JOB_LIMIT:g} s")
    if out.returncode:
        lines = out.stderr.strip().splitlines()
        sys.exit(f"{target.name}: exit code {out.returncode}" + (f": {lines[-1]}" if lines else ""))
    n_in, n_out, seconds = out.stdout.split()[-3:]
    return int(n_in), int(n_out), float(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, help="numba threads per job (default: all)")
    parser.add_argument("--jobs", default=",".join(t.name for t in TARGETS),
                        help="which of: " + ", ".join(t.name for t in TARGETS))
    args = parser.parse_args()
    if args.rounds < 1:
        sys.exit(f"--rounds must be at least 1, got {args.rounds}")
    if args.threads is not None and args.threads < 1:
        sys.exit(f"--threads must be at least 1, got {args.threads}")
    names = args.jobs.split(",")
    unknown = sorted(set(names) - {t.name for t in TARGETS})
    if unknown:
        sys.exit(f"unknown job(s) {', '.join(unknown)}; choose from "
                 + ", ".join(t.name for t in TARGETS))
    chosen = [t for t in TARGETS if t.name in names or t.name == "qslim"]
    times: dict[str, list[float]] = {t.name: [] for t in chosen}
    sizes: dict[str, tuple[int, int]] = {}
    for r in range(args.rounds):
        for t in chosen:
            n_in, n_out, seconds = time_job(t, args.threads)
            sizes[t.name] = (n_in, n_out)
            times[t.name].append(seconds)
            print(f"round {r + 1} {t.name}: {seconds:.3f} s", flush=True)
    qslim = statistics.median(times["qslim"])
    print(f"\nthreads per job: {args.threads or 'all'} (numba); {args.rounds} rounds")
    print("\n| job | faces | method s (runs) | median s | triangles/s | over qslim | target |")
    print("| --- | --- | --- | ---: | ---: | ---: | --- |")
    for t in chosen:
        med = statistics.median(times[t.name])
        n_in, n_out = sizes[t.name]
        goals = []
        if t.seconds is not None:
            goals.append(f"≤ {t.seconds:g} s {'met' if med <= t.seconds else 'NOT met'}")
        if t.over_qslim is not None:
            goals.append(f"≤ {t.over_qslim:g}× {'met' if med / qslim <= t.over_qslim else 'NOT met'}")
        runs = ", ".join(f"{s:.2f}" for s in times[t.name])
        print(f"| {t.name} | {n_in:,} → {n_out:,} | {runs} | {med:.2f} | "
              f"{(n_in - n_out) / med:,.0f} | {med / qslim:.1f} | {'; '.join(goals) or '—'} |")


if __name__ == "__main__":
    main()
