"""Whether a job after ``bench warmup`` compiles anything:

    .venv/bin/python scripts/warm_check.py [METHOD,...]   (default: every engine method)

In this fresh process, warms up each method as a job of ``bench run`` does and evaluates
a tiny result under the protocol (its kernels: views, shading, SSIM), then counts over
every numba dispatcher the suite has loaded the signatures read from numba's cache and
those compiled. After ``bench warmup`` the second count should be 0: the seconds a
job's record gives as ``warm_up`` are then loading, not compiling.
"""

from __future__ import annotations

import sys
import time
import warnings

from numba.core.dispatcher import Dispatcher

from bench.core.registry import registry
from bench.records.suites import ENGINE_METHODS
from bench.run.warmup import warm_up, warm_up_evaluation


def main() -> None:
    names = sys.argv[1].split(",") if len(sys.argv) > 1 else list(ENGINE_METHODS)
    warnings.simplefilter("ignore")
    start = time.perf_counter()
    for name in names:
        warm_up(registry("method").load(name))
    warm_up_evaluation()
    seconds = time.perf_counter() - start
    # each dispatcher once, though every module that imports it holds it too
    dispatchers = {id(value): value for module in list(sys.modules.values())
                   if getattr(module, "__name__", "").startswith(("bench", "methods", "metrics"))
                   for value in vars(module).values() if isinstance(value, Dispatcher)}
    hits = sum(sum(d.stats.cache_hits.values()) for d in dispatchers.values())
    misses = sum(sum(d.stats.cache_misses.values()) for d in dispatchers.values())
    compiled = {f"{d.py_func.__module__}.{d.py_func.__name__}" for d in dispatchers.values()
                if sum(d.stats.cache_misses.values())}
    print(f"{','.join(names)}: warm-up {seconds:.2f} s; signatures read from the cache "
          f"{hits}, compiled {misses}" + (f" ({', '.join(sorted(compiled))})" if compiled else ""))
    sys.exit(1 if misses else 0)


if __name__ == "__main__":
    main()
