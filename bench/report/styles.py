"""One look per method, shared by every figure and page of the report.

A method keeps its style whatever the run: the built-in methods, in the order of their
names, take the first styles of :data:`COLOURS` x :data:`MARKERS` x :data:`DASHES`, and
any other label of a run (a plug-in, a method with parameters) the next ones in the
order of their labels. The first 20 styles differ in colour already; every style differs
from the others in at least one of colour, marker and dash, and no two of the first 16
share a marker and a colour, so 16 methods can be told apart even in grey print.

The colours are matplotlib's ``tab20`` (strong tones first, then their light pairs).
"""

from __future__ import annotations

from typing import NamedTuple

__all__ = ["COLOURS", "DASHES", "MARKERS", "Style", "method_styles", "style_at"]

#: tab20, the ten strong tones then the ten light ones.
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf", "#aec7e8", "#ffbb78", "#98df8a", "#ff9896",
           "#c5b0d5", "#c49c94", "#f7b6d2", "#c7c7c7", "#dbdb8d", "#9edae5")
#: matplotlib markers, 13 of them (13 and 20 are coprime: colour and marker cycle apart).
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p", "d")
#: matplotlib line styles: the dash changes every 20 styles, once every colour is used.
DASHES = ("-", "--", "-.", ":")


class Style(NamedTuple):
    """A method's look: ``colour`` (``#rrggbb``), matplotlib ``marker`` and ``dash``."""

    colour: str
    marker: str
    dash: str

    def plot_kwargs(self) -> dict:
        """Keyword arguments of ``Axes.plot`` for this style."""
        return {"color": self.colour, "marker": self.marker, "linestyle": self.dash}


def style_at(index: int) -> Style:
    """The ``index``-th style: colour, marker and dash cycle with periods 20, 13 and 80,
    so styles repeat only after 1,040."""
    return Style(COLOURS[index % len(COLOURS)], MARKERS[index % len(MARKERS)],
                 DASHES[(index // len(COLOURS)) % len(DASHES)])


def _builtin_methods() -> list[str]:
    try:
        from bench.core.registry import registry

        return sorted(registry("method").names())
    except Exception:  # noqa: BLE001 - a broken plug-in must not cost the report its plots
        return []


def method_styles(labels, builtin: list[str] | None = None) -> dict[str, Style]:
    """The style of each method label in ``labels``: a built-in method's by its place
    among the built-in names (``builtin``, the registry's by default), any other label
    after them in the order of the labels."""
    builtin = _builtin_methods() if builtin is None else sorted(builtin)
    place = {name: i for i, name in enumerate(builtin)}
    others = sorted({str(x) for x in labels} - set(place))
    place.update({label: len(builtin) + i for i, label in enumerate(others)})
    return {str(label): style_at(place[str(label)]) for label in labels}
