"""Each kernel is compiled once per set of argument types, not once more per literal.

numba compiles a function called with a literal constant (``f(x, 0)``) for that
literal, apart from the same function called with a variable, and while it types a
counter that starts at a literal (``n = 0`` ... ``f(n)`` ... ``n += 1``) it compiles a
copy for the literal first. Each copy carries the function's whole call tree, so the
kernels pass typed constants (:data:`methods.imaging.raster.ZERO`, ``NO_VERTEX``;
docs/maintainers.md). This reads numba's on-disk index of every cached kernel of
``methods`` (what any process compiled for the current sources) and fails when one
function holds two signatures that differ only in literals.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections import Counter

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


def _signatures(dispatcher) -> list[tuple]:
    """The signatures numba's index holds for the function's current source."""
    return [key[0] for key in dispatcher._cache._cache_file._load_index()]


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
    assert indexed > 100, f"numba's index holds only {indexed} kernels: is the cache on?"
    assert not twice, f"compiled again for literal arguments: {twice}"
