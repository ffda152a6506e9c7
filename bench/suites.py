"""Named experiment suites for ``bench run --suite NAME``.

A suite fixes models, method variants (a method name plus parameter overrides) and
face budgets, so an experiment is one reproducible command.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Suite", "SUITES", "get_suite"]


@dataclass(frozen=True)
class Suite:
    name: str
    description: str
    models: tuple[str, ...]
    #: (method, params) pairs; None = every available, view-independent method
    variants: tuple[tuple[str, dict], ...] | None = None
    ratios: tuple[float, ...] = ()
    #: model -> face budgets, taking precedence over ratios
    faces: dict = field(default_factory=dict)
    shading: str = "flat"


SUITES = {
    "ci": Suite(
        "ci", "small enough for CI: bunny and torus at 2% and 1% of their faces, every "
        "available method", models=("bunny", "torus"), ratios=(0.02, 0.01)),
}


def get_suite(name: str) -> Suite:
    from bench.errors import UnknownNameError
    from bench.registry import suggest

    if name not in SUITES:
        raise UnknownNameError(f"unknown suite '{name}'{suggest(name, SUITES)} "
                               f"(suites: {', '.join(sorted(SUITES))})")
    return SUITES[name]
