"""``json.dumps(..., default=json_default)``: numpy scalars and arrays as JSON numbers and
lists, for records and caches alike."""

from __future__ import annotations

import numpy as np

__all__ = ["json_default"]


def json_default(value):
    """A numpy scalar as its Python value, an array as nested lists; a TypeError naming
    the type for anything else (as :func:`json.dumps` expects of ``default``)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
