"""What a cell of the report says: numbers at the precision their measurement supports,
model names as the user gave them.

- :data:`RESOLUTION`: below it a metric's value is not distinguishable from zero (the
  Hausdorff distances of two identical surfaces come out as 2e-18 or 9e-14, rounding
  noise of float64 coordinates); such a value is shown as ``0`` and ranks as a tie with
  any other value under it.
- ``peak_mb`` is measured in pages and allocator blocks: shown to 1 MB, ``<1`` below.
- A model that is a file is shown by its name, its folder on hover: the absolute path
  of the machine a run was made on means nothing to the reader of its report.
"""

from __future__ import annotations

import html
import math
import numbers
from pathlib import PurePath, PurePosixPath, PureWindowsPath

__all__ = ["RESOLUTION", "model_cell", "model_text", "number", "resolved"]

#: Smallest meaningful value of a metric, in its unit. Hausdorff distances are fractions
#: of the bounding-box diagonal (a nanodiagonal is far below any simplification's error
#: and far above float64 rounding); d_RMS is on 0-255 luminance, where one grey level in
#: one pixel of 24 views of 512² is 4e-4; FLIP's one 8-bit step in one pixel of its
#: views is smaller still, 1e-6 is well above its rounding.
RESOLUTION = {"hausdorff_mean": 1e-9, "hausdorff_max": 1e-9, "d_rms": 1e-4, "flip": 1e-6}


def _finite(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and \
        math.isfinite(value)


def resolved(metric: str, value):
    """``value`` with what is under the metric's :data:`RESOLUTION` made 0 (a value that
    is not a finite number is returned as it is)."""
    floor = RESOLUTION.get(metric)
    if floor is not None and _finite(value) and abs(value) < floor:
        return 0.0
    return value


def number(column: str, value) -> str:
    """A cell's text for ``value`` of ``column``: empty when missing, ``0`` under the
    metric's resolution, ``peak_mb`` to 1 MB, other floats to 4 significant digits."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return html.escape(str(value), quote=True)
    if column == "peak_mb":
        return "<1" if 0 <= value < 1 else f"{value:.0f}"
    value = resolved(column, value)
    if value == 0:
        return "0"
    if isinstance(value, numbers.Integral):
        return str(value)
    return f"{value:.4g}"


def _pure(name: str) -> PurePath | None:
    for kind in (PurePosixPath, PureWindowsPath):
        path = kind(name)
        if path.is_absolute():
            return path
    return None


def model_text(name) -> str:
    """A model as the report names it: a registered name or a relative path as given, an
    absolute path by its file name (the ``::`` options of a model spec kept)."""
    name = str(name)
    base, sep, options = name.partition("::")
    path = _pure(base)
    return name if path is None else path.name + sep + options


def model_cell(name) -> str:
    """:func:`model_text` as HTML, with the file's folder (its own name, not the path
    to it) on hover when the model is an absolute path."""
    text = html.escape(model_text(name), quote=True)
    path = _pure(str(name).partition("::")[0])
    if path is None:
        return text
    return f"<span title='in folder {html.escape(path.parent.name, quote=True)}'>{text}</span>"
