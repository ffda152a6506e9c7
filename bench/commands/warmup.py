"""``bench warmup [--methods A,B] [--jobs N]``: compile every method's kernels now, and
the evaluation's.

numba keeps what it compiles on disk, so after this the first real run of a method
loads its kernels in about a second instead of compiling them for minutes
(``scripts/setup.sh --no-run`` does it once after installing; without ``--no-run`` the
main job's jobs compile them as they go)."""

from __future__ import annotations

import sys
import time

from bench.core.errors import InputError
from bench.core.registry import registry


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="compile every method's kernels once (numba caches them)",
                       description=__doc__)
    p.add_argument("--methods", default="", help="only these methods (comma-separated)")
    p.add_argument("--jobs", "-j", metavar="N", help="processes compiling at a time, at "
                   "least 1 (default: the CPU count)")
    p.set_defaults(run=run)


def run(args) -> int:
    import os

    from tqdm import tqdm

    from bench.commands.run import whole_number
    from bench.run.warmup import warm_up_all

    methods = registry("method")
    names = [n.strip() for n in args.methods.split(",") if n.strip()] or [
        e.name for e in methods if e.available]
    unknown = [n for n in names if n not in methods]
    if unknown:
        raise InputError(f"--methods: unknown method {unknown[0]!r}; see bench list methods")
    jobs = whole_number(args.jobs, "--jobs") if args.jobs is not None else \
        len(os.sched_getaffinity(0))
    start = time.perf_counter()
    with tqdm(total=len(names) + 1, unit="task", dynamic_ncols=True) as bar:
        def done(name, seconds):
            bar.set_postfix_str(f"{name} {seconds:.1f} s")
            bar.update()

        def plan(tasks):
            bar.total = len(tasks)
            bar.refresh()

        times = warm_up_all(names, jobs, done, plan)
    slowest = sorted(times.items(), key=lambda kv: -kv[1])[:3]
    print(f"bench: warmed up {len(names)} methods and the evaluation in "
          f"{time.perf_counter() - start:.1f} s with {jobs} process{'es' if jobs > 1 else ''} "
          f"(slowest: {', '.join(f'{n} {s:.1f} s' for n, s in slowest)})", file=sys.stderr)
    return 0
