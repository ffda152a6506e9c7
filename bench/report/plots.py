"""The report's figures: the curves over face count (Lindstrom & Turk's Figures 5 and 6),
quality against time with its Pareto front, and the silhouette distributions (Figure 7)
as cumulative curves.

Every figure draws a method in its own style (:func:`bench.report.styles.method_styles`),
puts its legend outside the axes and labels log axes with plain numbers (``600``,
``0.01``), at most a handful per axis so they never overlap.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["curves_figure", "pareto_front", "plain_log_axis", "pyplot", "quality_time_figure",
           "silhouette_figure"]


def pyplot():
    """matplotlib's pyplot on the file-only backend, imported only for a report that
    draws (a run of failures alone draws nothing and skips the import)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_text(text: str) -> str:
    """Record text for a matplotlib label: ``$`` would start mathtext (and a malformed
    formula aborts the whole figure), so it is escaped."""
    return str(text).replace("$", r"\$")


def plain(value: float, _pos=None) -> str:
    """A tick label in plain digits: ``600``, ``12,000``, ``0.05``, ``0.0001``."""
    if value == 0 or not math.isfinite(value):
        return "0"
    if abs(value) >= 1:
        return f"{value:,.0f}" if abs(value - round(value)) < 1e-9 * abs(value) else f"{value:,.3g}"
    digits = max(0, -math.floor(math.log10(abs(value))) + 1)
    return f"{value:.{digits}f}".rstrip("0").rstrip(".")


def plain_log_axis(axis) -> None:
    """A log ``axis`` (``ax.xaxis`` or ``ax.yaxis``) labelled in plain digits, call it once
    the data is drawn: 1-2-5 steps over up to 2.5 decades, every digit over less than one,
    powers of ten over more (thinned to 7 labels), unlabelled minor ticks."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    lo, hi = sorted(axis.get_view_interval())
    decades = math.log10(hi / lo) if lo > 0 and hi > 0 else 3.0
    subs = (tuple(float(k) for k in range(1, 10)) if decades < 1 else
            (1.0, 2.0, 5.0) if decades <= 2.5 else (1.0,))
    axis.set_major_locator(LogLocator(base=10, subs=subs, numticks=7 if decades > 2.5 else 30))
    axis.set_major_formatter(FuncFormatter(plain))
    axis.set_minor_formatter(NullFormatter())


def legend_outside(ax, fig) -> None:
    """The legend to the right of the axes, in one column (two past 14 entries)."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                  borderaxespad=0, fontsize=9, frameon=False, ncol=1 if len(handles) <= 14 else 2)


def curves_figure(series: dict, column: str, title: str, styles: dict):
    """One metric over faces on log axes: ``series`` maps a label to (faces, values, style
    key); values that are not finite and positive have no place on log axes."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for label, (x, y, key) in series.items():
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        keep = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
        if keep.any():
            order = np.argsort(x[keep])
            ax.plot(x[keep][order], y[keep][order], label=plot_text(label), markersize=5,
                    **styles[key].plot_kwargs())
    ax.set_xscale("log")
    ax.set_yscale("log")
    plain_log_axis(ax.xaxis)
    plain_log_axis(ax.yaxis)
    ax.set_xlabel("faces")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="major", alpha=.3)
    legend_outside(ax, fig)
    return fig


def pareto_front(points: list[tuple[float, float, str]]) -> list[tuple[float, float, str]]:
    """The points (time, error, label) no other point beats on both (lower time and lower
    error, one strictly), by increasing time."""
    front, best = [], math.inf
    for t, e, label in sorted(points, key=lambda p: (p[0], p[1])):
        if e < best:
            front.append((t, e, label))
            best = e
    return front


def quality_time_figure(panels: list[tuple[str, str, dict]], styles: dict):
    """Error against method seconds, one panel per (title, metric name, ``points``), where
    ``points`` maps a method label to its [(seconds, value, reused)]; each panel's
    Pareto front drawn as a grey step line and the methods on it named. A ``reused``
    point (its seconds leave out a build it reused) is drawn hollow and kept off the
    front."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.8), squeeze=False)
    for ax, (title, metric, points) in zip(axes[0], panels):
        every = []
        for label, pts in sorted(points.items()):
            pts = [(t, v, b) for t, v, b in pts if math.isfinite(t) and math.isfinite(v)
                   and t > 0 and v > 0]
            if not pts:
                continue
            style = styles[label]
            own = [p for p in pts if not p[2]]
            ax.scatter([p[0] for p in own], [p[1] for p in own], color=style.colour,
                       marker=style.marker, s=36, label=plot_text(label), zorder=3)
            hollow = [p for p in pts if p[2]]
            if hollow:
                ax.scatter([p[0] for p in hollow], [p[1] for p in hollow], marker=style.marker,
                           s=36, facecolors="none", edgecolors=style.colour, zorder=3,
                           label=None if own else plot_text(label))
            every += [(t, v, label) for t, v, _ in own]
        front = pareto_front(every)
        if front:
            ax.step([p[0] for p in front], [p[1] for p in front], where="post", color="#444",
                    linewidth=1, linestyle="--", zorder=2,
                    label="Pareto front:\n  " + "\n  ".join(dict.fromkeys(
                        plot_text(p[2]) for p in front)))
        ax.set_xscale("log")
        ax.set_yscale("log")
        plain_log_axis(ax.xaxis)
        plain_log_axis(ax.yaxis)
        ax.set_xlabel("method seconds (log)")
        ax.set_ylabel(metric)
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="major", alpha=.3)
    legend_outside(axes[0][-1], fig)
    return fig


def silhouette_figure(histograms: dict, title: str, styles: dict):
    """Silhouette distributions as cumulative curves: for each label, the share of edges
    that are silhouette edges in at most k of the views, k = 0..20 (``histograms`` maps a
    label to its histogram over k); 12 curves stay readable where 12 grouped bars do not."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for label, hist in histograms.items():
        hist = np.asarray(hist, dtype=float)
        total = hist.sum()
        if not np.isfinite(total) or total <= 0:
            continue
        ax.plot(np.arange(len(hist)), np.cumsum(hist) / total, label=plot_text(label),
                markersize=4, **styles[label].plot_kwargs())
    ax.set_xticks(range(0, 21, 2))
    ax.set_xlabel("views (of 20) in which an edge is a silhouette, at most")
    ax.set_ylabel("share of edges")
    ax.set_ylim(0, 1.02)
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=.3)
    legend_outside(ax, fig)
    return fig
