"""Whether a job after ``bench warmup`` compiles anything:

    .venv/bin/python scripts/warm_check.py [METHOD,...]   (default: every engine method)

In this fresh process, warms up each method as a job of ``bench run`` does, then counts
over every numba dispatcher the suite has loaded the signatures read from numba's cache
and those compiled. After ``bench warmup`` the second count should be 0: the seconds a
job's record gives as ``warm_up`` are then loading, not compiling.
"""

from __future__ import annotations

import sys
import time
import warnings

from numba.core.dispatcher import Dispatcher

from bench.core.registry import registry
from bench.run.warmup import warm_up

ENGINE_METHODS = "quadric,memoryless,canny-texture,image-driven,perceptual-mt,entropy-twin"


def main() -> None:
    names = (sys.argv[1] if len(sys.argv) > 1 else ENGINE_METHODS).split(",")
    warnings.simplefilter("ignore")
    start = time.perf_counter()
    for name in names:
        warm_up(registry("method").load(name))
    seconds = time.perf_counter() - start
    hits = misses = 0
    compiled = set()
    for module in list(sys.modules.values()):
        if not getattr(module, "__name__", "").startswith(("bench", "methods", "metrics")):
            continue
        for value in vars(module).values():
            if isinstance(value, Dispatcher):
                hits += sum(value.stats.cache_hits.values())
                missed = sum(value.stats.cache_misses.values())
                misses += missed
                if missed:
                    compiled.add(f"{module.__name__}.{value.py_func.__name__}")
    print(f"{','.join(names)}: warm-up {seconds:.2f} s; signatures read from the cache "
          f"{hits}, compiled {misses}" + (f" ({', '.join(sorted(compiled))})" if compiled else ""))
    sys.exit(1 if misses else 0)


if __name__ == "__main__":
    main()
