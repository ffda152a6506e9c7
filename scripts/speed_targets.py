"""The suite's speed targets as a benchmark, in one checkout:

    .venv/bin/python scripts/speed_targets.py [--rounds 3] [--rows methods,scale,...]
                                              [--threads T] [--markdown FILE]

Rows (``--rows``, default ``methods,scale,overhead,evaluation``; ``curve``, ``warmup`` and
``firstrun`` take long and run only when named):

- ``methods``: the view-based methods on the papers' models (the bunny to 1,332 faces,
  González et al. 2008's Table 1 sizes), each over qslim's time on the bunny.
- ``scale``: the bunny subdivided twice (``bunny-x16``, 898,752 faces) to 9,000 faces by
  meshopt, quadric, qslim, memoryless and image-driven, each over its baseline in the
  same rounds (quadric over meshopt, memoryless over quadric, image-driven over qslim),
  with each process's peak memory.
- ``curve``: seconds per input face of the engine methods and the baselines on the bunny,
  ``bunny-x4``, ``bunny-x16`` and ``bunny-x64`` (56k to 3.6M faces) to 1 % of the faces.
- ``overhead``: ``bench simplify bunny OUT --method meshopt --faces 1332``, wall time
  of the whole command minus the method's own time: once with an empty mesh cache
  (:mod:`bench.io.cache`), then each round on the cache that filled (the target).
- ``evaluation``: a small ``bench run`` (qslim on the bunny and the torus at the main
  job's budgets, one worker); per stage of the records' ``timings`` the median over the
  jobs, and a job's time outside its method.
- ``warmup``: ``bench warmup`` from an empty numba cache (a fresh ``NUMBA_CACHE_DIR``),
  with as many processes as ``--warmup-jobs`` (default: every core).
- ``firstrun``: the main job (what setup runs after the install) from an empty numba
  cache, whose jobs compile the kernels as they go, then the same run on the cache it
  filled; the first's time over the second's.

Every timed job runs in a fresh process: the model is loaded, the method warmed up on the
tiny meshes of :mod:`bench.run.warmup` (numba's cache loading or compilation is not
method time, as in ``bench run``), then timed (``wall_seconds``, the method's own time).
The jobs take turns round after round, so drift of a shared machine hits them alike; a
figure is the median of the rounds, a target a ratio to a baseline of the same rounds
(seconds do not carry over between machines; ratios do). ``--threads`` sets the jobs'
numba threads (default: every core). ``--markdown FILE`` also writes the tables as
Markdown (the docs' performance page includes that file). Run nothing else meanwhile.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BENCH = [sys.executable, "-m", "bench"]


@dataclass(frozen=True)
class Job:
    """One timed simplification and what it should reach: ``over`` names the job whose
    median it is divided by, ``at_most`` the target for that ratio (None: no target)."""

    name: str
    method: str
    model: str
    faces: int
    over: str | None = None
    at_most: float | None = None
    #: a paper's time for the job, in seconds, shown beside ours (its machine, not ours)
    paper: float | None = None
    #: peak memory target of the job's process, in MB
    peak_mb: float | None = None


#: Lindstrom & Turk 2000's bunny to 1,332 faces, and González et al. 2008's Table 1
#: (815 -> 100, 4,698 -> 500, 13,810 -> 1,000 faces in 12.27, 93.45 and 453.34 s).
METHODS = (
    Job("qslim", "qslim", "bunny", 1332),
    Job("image-driven", "image-driven", "bunny", 1332, over="qslim", at_most=15.0),
    Job("entropy-815", "entropy-twin", "bunny-textured-815", 100, over="qslim", paper=12.27),
    Job("entropy-4698", "entropy-twin", "bunny-textured-4698", 500, over="qslim",
        paper=93.45),
    Job("entropy-13810", "entropy-twin", "torus-13810", 1000, over="qslim", paper=453.34),
)

#: The engine at scale: 898,752 -> 9,000 faces.
SCALE = (
    Job("meshopt", "meshopt", "bunny-x16", 9000),
    Job("qslim", "qslim", "bunny-x16", 9000),
    Job("quadric", "quadric", "bunny-x16", 9000, over="meshopt", at_most=5.0),
    Job("memoryless", "memoryless", "bunny-x16", 9000, over="quadric", at_most=1.5),
    Job("image-driven", "image-driven", "bunny-x16", 9000, over="qslim", at_most=3.0,
        peak_mb=1200.0),
)

#: The scaling curve: every model to 1 % of its faces.
CURVE_MODELS = {"bunny": 56172, "bunny-x4": 224688, "bunny-x16": 898752,
                "bunny-x64": 3595008}
CURVE_METHODS = ("meshopt", "qslim", "quadric", "memoryless", "image-driven")

#: ``bench simplify``'s time outside the method, and a job's outside its method.
OVERHEAD_TARGET = 1.0
EVALUATION_TARGET = 2.5
#: ``bench warmup`` from cold caches.
WARMUP_TARGET = 90.0

#: Seconds one process may take, loading and warm-up included.
JOB_LIMIT = 3600.0

CODE = """
import resource, sys, warnings
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
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(mesh.n_faces, result.mesh.n_faces, result.stats["wall_seconds"], peak)
"""


def _run(cmd: list[str], what: str, env: dict | None = None) -> subprocess.CompletedProcess:
    try:
        out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env,
                             timeout=JOB_LIMIT, check=False)
    except subprocess.TimeoutExpired:
        sys.exit(f"{what}: no result within {JOB_LIMIT:g} s")
    if out.returncode:
        lines = out.stderr.strip().splitlines()
        sys.exit(f"{what}: exit code {out.returncode}" + (f": {lines[-1]}" if lines else ""))
    return out


def _env(threads: int | None) -> dict:
    env = dict(os.environ)
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    return env


def time_job(job: Job, threads: int | None) -> tuple[int, int, float, float]:
    """(input faces, output faces, method seconds, peak MB of the process) of one fresh
    process."""
    out = _run([sys.executable, "-c", CODE, job.method, job.model, str(job.faces)],
               f"{job.name} ({job.model})", _env(threads))
    n_in, n_out, seconds, peak = out.stdout.split()[-4:]
    return int(n_in), int(n_out), float(seconds), float(peak)


def _rounds(jobs, rounds: int, threads: int | None, label: str) -> dict:
    """Each job's runs, taking turns round after round: {name: {"runs", "faces",
    "peak"}}."""
    got = {j.name: {"runs": [], "peak": []} for j in jobs}
    for r in range(rounds):
        for j in jobs:
            n_in, n_out, seconds, peak = time_job(j, threads)
            got[j.name].update(faces=(n_in, n_out))
            got[j.name]["runs"].append(seconds)
            got[j.name]["peak"].append(peak)
            print(f"{label} round {r + 1} {j.name}: {seconds:.3f} s, {peak:.0f} MB",
                  file=sys.stderr, flush=True)
    return got


def _mark(ratio: float, at_most: float | None) -> str:
    if at_most is None:
        return "—"
    return f"≤ {at_most:g}× {'met' if ratio <= at_most else 'NOT met'}"


def method_table(jobs, got: dict, title: str) -> list[str]:
    medians = {j.name: statistics.median(got[j.name]["runs"]) for j in jobs}
    lines = [f"### {title}", "",
             "| job | model | faces | method s (runs) | median s | triangles/s | ratio | "
             "target | peak MB |", "| --- | --- | --- | --- | ---: | ---: | --- | --- | ---: |"]
    for j in jobs:
        med, (n_in, n_out) = medians[j.name], got[j.name]["faces"]
        ratio, target = "—", "—"
        if j.over is not None:
            r = med / medians[j.over]
            ratio, target = f"{r:.2f}× {j.over}", _mark(r, j.at_most)
        if j.paper is not None:
            target = f"paper {j.paper:g} s: {j.paper / med:.0f}× faster here"
        peak = max(got[j.name]["peak"])
        if j.peak_mb is not None:
            target += f"; peak ≤ {j.peak_mb:g} MB {'met' if peak <= j.peak_mb else 'NOT met'}"
        runs = ", ".join(f"{s:.2f}" for s in got[j.name]["runs"])
        lines.append(f"| {j.name} | {j.model} | {n_in:,} → {n_out:,} | {runs} | {med:.2f} | "
                     f"{(n_in - n_out) / med:,.0f} | {ratio} | {target} | {peak:,.0f} |")
    return lines + [""]


def curve_table(rounds: int, threads: int | None) -> list[str]:
    jobs = [Job(f"{m}@{model}", m, model, max(4, faces // 100))
            for model, faces in CURVE_MODELS.items() for m in CURVE_METHODS]
    got = _rounds(jobs, rounds, threads, "curve")
    lines = ["### Scaling: microseconds per input face, to 1 % of the faces", "",
             "| method | " + " | ".join(f"{f:,} faces" for f in CURVE_MODELS.values())
             + " | growth 56k → 3.6M over n log n |",
             "| --- | " + " | ".join("---:" for _ in CURVE_MODELS) + " | ---: |"]
    for m in CURVE_METHODS:
        per = [statistics.median(got[f"{m}@{model}"]["runs"]) / faces * 1e6
               for model, faces in CURVE_MODELS.items()]
        small, big = min(CURVE_MODELS.values()), max(CURVE_MODELS.values())
        growth = (per[-1] / per[0]) / (math.log(big) / math.log(small))
        lines.append(f"| {m} | " + " | ".join(f"{p:.2f}" for p in per) + f" | {growth:.2f} |")
    return lines + ["", "A growth of 1 is n log n exactly; below 1, closer to linear.", ""]


def overhead_table(rounds: int, threads: int | None) -> list[str]:
    """``bench simplify``'s time outside the method: first with an empty mesh cache (a
    file read for the first time, as on a fresh machine before the main job), then the
    rounds on the cache that run filled (the target)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(_env(threads), BENCH_CACHE=str(Path(tmp) / "cache"))
        for label, count in (("first read (empty mesh cache)", 1),
                             ("read from the cache", rounds)):
            runs = []
            for r in range(count):
                start = time.perf_counter()
                out = _run([*BENCH, "simplify", "bunny", str(Path(tmp) / "out.ply"), "--method",
                            "meshopt", "--faces", "1332", "--force"], "bench simplify", env)
                wall = time.perf_counter() - start
                method = float(re.search(r" in ([0-9.]+) s;", out.stderr + out.stdout).group(1))
                runs.append((wall, method))
                print(f"overhead {label} {r + 1}: {wall:.2f} s wall, {method:.3f} s method",
                      file=sys.stderr, flush=True)
            rows.append((label, runs, statistics.median(w - m for w, m in runs)))
    over = rows[-1][2]
    lines = ["### `bench simplify` overhead", "",
             "`bench simplify bunny OUT --method meshopt --faces 1332`; the target is for a "
             "file read before (the main job reads the built-in models).", "",
             "| input | wall s (runs) | method s (runs) | median wall − method | target |",
             "| --- | --- | --- | ---: | --- |"]
    for i, (label, runs, median) in enumerate(rows):
        target = "—" if i < len(rows) - 1 else \
            f"≤ {OVERHEAD_TARGET:g} s {'met' if over <= OVERHEAD_TARGET else 'NOT met'}"
        lines.append(f"| {label} | {', '.join(f'{w:.2f}' for w, _ in runs)} | "
                     f"{', '.join(f'{m:.3f}' for _, m in runs)} | {median:.2f} s | {target} |")
    return lines + [""]


def evaluation_table(rounds: int, threads: int | None, run_dir: str | None) -> list[str]:
    """Per-stage medians over the jobs of ``run_dir``, or of fresh small runs."""
    timings, inside = [], []
    with tempfile.TemporaryDirectory() as tmp:
        dirs = [Path(run_dir)] if run_dir else []
        for r in range(0 if run_dir else rounds):
            out = Path(tmp) / f"run{r}"
            _run([*BENCH, "run", "--models", "bunny,torus", "--methods", "qslim", "--jobs", "1",
                  "--no-report", "--out", str(out)], "bench run", _env(threads))
            dirs.append(out)
            print(f"evaluation round {r + 1} done", file=sys.stderr, flush=True)
        for d in dirs:
            for path in sorted((d / "records").glob("*.json")):
                record = json.loads(path.read_text())
                if record.get("timings", {}).get("total") is not None:
                    timings.append(record["timings"])
                    inside.append(record.get("seconds", {}))
    if not timings:
        return ["### Evaluation", "", "No records with timings.", ""]
    stages = [k for k in timings[0] if k != "total"]
    outside = statistics.median(t["total"] - t.get("method", 0.0) for t in timings)
    lines = ["### A job's time outside its method", "",
             f"{len(timings)} jobs ({run_dir or 'qslim on the bunny and the torus, 2 % and 1 %'}"
             "); median seconds per stage of the records' `timings`.", "",
             "| " + " | ".join(stages) + " | total − method | target |",
             "| " + " | ".join("---:" for _ in stages) + " | ---: | --- |",
             "| " + " | ".join(f"{statistics.median(t.get(s, 0.0) for t in timings):.2f}"
                              for s in stages)
             + f" | {outside:.2f} | ≤ {EVALUATION_TARGET:g} s "
             f"{'met' if outside <= EVALUATION_TARGET else 'NOT met'} |", ""]
    return lines + _inside_table(inside)


def _inside_table(inside: list[dict]) -> list[str]:
    """The evaluation's own stages (the records' ``seconds``): the renders, the shared
    inputs and each metric, median seconds, the largest first (those above 5 ms)."""
    names = {k for s in inside for k in s}
    medians = {k: statistics.median(s.get(k, 0.0) for s in inside) for k in names}
    shown = sorted((k for k in medians if medians[k] >= 0.005), key=lambda k: -medians[k])
    if not shown:
        return []
    return ["Inside `evaluation`, median seconds (the records' `seconds`):", "",
            "| " + " | ".join(k.removeprefix("metric:") for k in shown) + " |",
            "| " + " | ".join("---:" for _ in shown) + " |",
            "| " + " | ".join(f"{medians[k]:.2f}" for k in shown) + " |", ""]


def warmup_table(rounds: int, jobs: int | None) -> list[str]:
    runs = []
    for r in range(rounds):
        cache = tempfile.mkdtemp(prefix="numba-cold-")
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cmd = [*BENCH, "warmup"] + ([] if jobs is None else ["--jobs", str(jobs)])
        start = time.perf_counter()
        out = _run(cmd, "bench warmup", env)
        runs.append(time.perf_counter() - start)
        shutil.rmtree(cache, ignore_errors=True)
        print(f"warmup round {r + 1}: {runs[-1]:.1f} s; {out.stderr.strip().splitlines()[-1]}",
              file=sys.stderr, flush=True)
    med = statistics.median(runs)
    return ["### `bench warmup` from an empty numba cache", "",
            "| processes | seconds (runs) | median | target |", "| --- | --- | ---: | --- |",
            f"| {jobs or os.cpu_count()} | {', '.join(f'{s:.0f}' for s in runs)} | {med:.0f} s | "
            f"≤ {WARMUP_TARGET:g} s {'met' if med <= WARMUP_TARGET else 'NOT met'} |", ""]


#: The main job (what ``scripts/setup.sh`` runs after the install).
MAIN_JOB = ["run", "--models", "bunny,torus", "--no-report"]


def first_run_table(rounds: int) -> list[str]:
    """The main job from an empty numba cache and image cache (its jobs compile the
    kernels as they go), then the same run again on the caches it filled: the first's
    time over the second's."""
    cold, warm, compiles = [], [], []
    for r in range(rounds):
        cache = tempfile.mkdtemp(prefix="numba-cold-")
        with tempfile.TemporaryDirectory() as tmp:
            # numba's cache and the originals' images (BENCH_CACHE) empty, as on a fresh
            # install
            env = dict(os.environ, NUMBA_CACHE_DIR=cache, BENCH_CACHE=str(Path(tmp) / "images"))
            for runs, name in ((cold, "cold"), (warm, "warm")):
                out = Path(tmp) / name
                start = time.perf_counter()
                _run([*BENCH, *MAIN_JOB, "--out", str(out)], f"bench run ({name})", env)
                runs.append(time.perf_counter() - start)
                if name == "cold":
                    compiles.append(max(json.loads(p.read_text()).get("timings", {})
                                        .get("warm_up", 0.0)
                                        for p in (out / "records").glob("*.json")))
        shutil.rmtree(cache, ignore_errors=True)
        print(f"first run round {r + 1}: cold {cold[-1]:.1f} s, warm {warm[-1]:.1f} s",
              file=sys.stderr, flush=True)
    med_cold, med_warm = statistics.median(cold), statistics.median(warm)
    return ["### The main job from an empty numba cache", "",
            f"`bench {' '.join(MAIN_JOB)}`, first from an empty numba cache (its jobs compile "
            "the kernels as they go), then again on the cache it filled.", "",
            "| cold s (runs) | warm s (runs) | median cold − warm | cold / warm | "
            "longest warm-up of a job (runs) |", "| --- | --- | ---: | ---: | --- |",
            f"| {', '.join(f'{x:.0f}' for x in cold)} | {', '.join(f'{x:.0f}' for x in warm)} "
            f"| {med_cold - med_warm:.0f} s | {med_cold / med_warm:.2f}× "
            f"| {', '.join(f'{x:.0f} s' for x in compiles)} |", ""]


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


ROWS = ("methods", "scale", "curve", "overhead", "evaluation", "warmup", "firstrun")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--rows", default="methods,scale,overhead,evaluation",
                        help="which of: " + ", ".join(ROWS))
    parser.add_argument("--threads", type=int, help="numba threads per job (default: all)")
    parser.add_argument("--warmup-jobs", type=int, help="bench warmup --jobs (default: its own)")
    parser.add_argument("--evaluation-run", metavar="DIR",
                        help="take the evaluation row from this run's records instead")
    parser.add_argument("--markdown", metavar="FILE", help="also write the tables here")
    args = parser.parse_args()
    if args.rounds < 1:
        sys.exit(f"--rounds must be at least 1, got {args.rounds}")
    if args.threads is not None and args.threads < 1:
        sys.exit(f"--threads must be at least 1, got {args.threads}")
    rows = [r.strip() for r in args.rows.split(",") if r.strip()]
    unknown = sorted(set(rows) - set(ROWS))
    if unknown:
        sys.exit(f"unknown row(s) {', '.join(unknown)}; choose from {', '.join(ROWS)}")
    lines = [f"Measured on {machine()}, {time.strftime('%Y-%m-%d')}, "
             f"{args.rounds} rounds, numba threads per job: {args.threads or 'all'}.", ""]
    if "methods" in rows:
        lines += method_table(METHODS, _rounds(METHODS, args.rounds, args.threads, "methods"),
                              "The view-based methods")
    if "scale" in rows:
        lines += method_table(SCALE, _rounds(SCALE, args.rounds, args.threads, "scale"),
                              "The engine at scale: 898,752 → 9,000 faces")
    if "curve" in rows:
        lines += curve_table(args.rounds, args.threads)
    if "overhead" in rows:
        lines += overhead_table(args.rounds, args.threads)
    if "evaluation" in rows:
        lines += evaluation_table(args.rounds, args.threads, args.evaluation_run)
    if "warmup" in rows:
        lines += warmup_table(args.rounds, args.warmup_jobs)
    if "firstrun" in rows:
        lines += first_run_table(args.rounds)
    text = "\n".join(lines)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + "\n")


if __name__ == "__main__":
    main()
