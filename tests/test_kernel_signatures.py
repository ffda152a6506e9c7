"""Each kernel is compiled once per set of argument types, not once more per literal.

numba compiles a function called with a literal constant (``f(x, 0)``) for that
literal, apart from the same function called with a variable, and while it types a
counter that starts at a literal (``n = 0`` ... ``f(n)`` ... ``n += 1``) it compiles a
copy for the literal first. Each copy carries the function's whole call tree, so the
kernels pass typed constants (:data:`methods.imaging.raster.ZERO`, ``NO_VERTEX``;
docs/maintainers.md). This reads numba's on-disk index of every cached kernel of
``methods`` (what any process compiled since the newest source changed) and fails when
one function holds two signatures that differ only in literals.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections import Counter
from pathlib import Path

import pytest
from numba.core import types
from numba.core.registry import CPUDispatcher

import methods
from bench.core.registry import registry
from bench.run.warmup import warm_up

#: Literal copies kept on purpose: one per coordinate axis or colour channel of a
#: function of a few lines, each folded to its constant.
DELIBERATE = {"methods.imaging.rows._pos", "methods.imaging.raster._bilerp"}


def _cached_kernels():
    for info in pkgutil.walk_packages(methods.__path__, "methods."):
        module = importlib.import_module(info.name)
        for obj in vars(module).values():
            if (isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == module.__name__
                    and hasattr(obj._cache, "_cache_file")):
                yield f"{module.__name__}.{obj.py_func.__qualname__}", obj


#: The newest source of ``methods``: an index entry older than it may have been compiled
#: for callers that have changed since (numba checks a kernel's own file only).
NEWEST_SOURCE = max(p.stat().st_mtime for p in Path(methods.__file__).parent.rglob("*.py"))


def _signatures(dispatcher) -> list[tuple]:
    """The signatures numba's index holds for the function's current source, compiled
    since the newest source of ``methods`` (so a cache older than an update is not read
    as the current code's)."""
    cache_file = dispatcher._cache._cache_file
    folder = Path(cache_file._cache_path)
    return [key[0] for key, data in cache_file._load_index().items()
            if (folder / data).exists() and (folder / data).stat().st_mtime >= NEWEST_SOURCE]


@pytest.mark.slow
def test_no_kernel_is_compiled_again_for_a_literal_argument():
    methods_ = registry("method")
    for name in ("memoryless", "image-driven", "entropy-twin", "canny-texture"):
        cls = methods_.load(name)
        warm_up(cls, cls.Params())  # compiles what the cache lacks (nothing after a warm-up)
    twice, indexed = {}, 0
    for name, kernel in _cached_kernels():
        sigs = _signatures(kernel)
        indexed += bool(sigs)
        plain = Counter(tuple(types.unliteral(t) for t in sig) for sig in sigs)
        if name not in DELIBERATE and any(n > 1 for n in plain.values()):
            twice[name] = [str(s) for s in sigs if any(isinstance(t, types.Literal) for t in s)]
    if not indexed:  # a fresh clone after bench warmup (as in CI) checks every kernel
        pytest.skip("no cached kernel of methods was compiled since its newest source "
                    "changed (numba's cache is off, or older than the sources)")
    assert not twice, f"compiled again for literal arguments: {twice}"
