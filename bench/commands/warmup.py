"""``bench warmup [--methods A,B]``: compile every method's kernels now.

numba keeps what it compiles on disk, so after this the first real run of a method
loads its kernels in about a second instead of compiling them for minutes (what
``scripts/setup.sh`` does once after installing)."""

from __future__ import annotations

import sys
import time

from bench.core.errors import InputError
from bench.core.registry import registry


def add_parser(sub, name: str) -> None:
    p = sub.add_parser(name, help="compile every method's kernels once (numba caches them)",
                       description=__doc__)
    p.add_argument("--methods", default="", help="only these methods (comma-separated)")
    p.set_defaults(run=run)


def run(args) -> int:
    from tqdm import tqdm

    from bench.run.warmup import warm_up

    methods = registry("method")
    names = [n.strip() for n in args.methods.split(",") if n.strip()] or [
        e.name for e in methods if e.available]
    unknown = [n for n in names if n not in methods]
    if unknown:
        raise InputError(f"--methods: unknown method {unknown[0]!r}; see bench list methods")
    start = time.perf_counter()
    times = {}
    for name in tqdm(names, unit="method", dynamic_ncols=True):
        cls = methods.load(name)
        times[name] = warm_up(cls, cls.Params())
    slowest = sorted(times.items(), key=lambda kv: -kv[1])[:3]
    print(f"bench: warmed up {len(names)} methods in {time.perf_counter() - start:.1f} s "
          f"(slowest: {', '.join(f'{n} {s:.1f} s' for n, s in slowest)})", file=sys.stderr)
    return 0
