"""The page of ``bench history`` (:mod:`bench.records.history` reads and checks the
runs): ``OUT/index.html`` with a table of the runs and, per model, budget and shading, a
row of panels (one per metric) with a line per method over the runs, the points where
``bench check`` would have failed crossed out in red; ``OUT/history.csv`` holds the data.
"""

from __future__ import annotations

import warnings
from collections import Counter
from pathlib import Path

from bench.core.errors import RecordWarning
from bench.io.atomic import write_atomic
from bench.records.check import metric_info
from bench.records.history import Point, history_table
from bench.report.images import RunFiles, Shown
from bench.report.page import figure, html_page
from bench.report.plots import legend_outside, plot_text, pyplot
from bench.report.styles import method_styles
from bench.report.table import esc

__all__ = ["write_history"]


def write_history(points: list[Point], out: Path, metrics: list[str],
                  reference: str = "the previous run") -> Path:
    """``out/index.html`` (a table of the runs and a figure per model, budget and
    shading with a panel per metric), ``out/history.csv`` and the figures' SVG files
    under ``out/images/``; returns the page's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    table = history_table(points)
    write_atomic(out / "history.csv", table.to_csv(index=False, float_format="%.9g"))
    refused = []
    files = RunFiles(out, refused)
    info = metric_info()
    shown = [m for m in metrics if m in set(table.metric)]
    parts = [f"<h1>Quality over {len(points)} runs</h1>",
             (f"<p class='note'>Each point is a run folder, at the commit and date it "
             f"recorded; a red cross is a value <code>bench check</code> would have failed "
             f"against {esc(reference)}. Metrics: {esc(', '.join(shown) or 'none')}. The "
             "data: <a href='history.csv'>history.csv</a>.</p>"),
             _runs_table(points)]
    notes = [f"{p.folder.name}: {note}" for p in points for note in p.skipped]
    if notes:
        parts.append("<div class='warnings'><p>Left out:</p><ul>"
                     + "".join(f"<li>{esc(n)}</li>" for n in notes) + "</ul></div>")
    groups = table[table.metric.isin(shown)].groupby(["model", "target_faces", "shading"],
                                                     sort=True)
    model = None
    for n, ((name, target, shading), group) in enumerate(groups):
        if name != model:
            model = name
            parts.append(f"<h2>{esc(name)}</h2>")
        caption = f"{name}, {target} faces, {shading} shading"
        src = files.plot(_figure(group, points, shown, info), f"history-{n:04d}")
        if src:
            parts.append(figure(Shown(src), caption, "history"))
    for note in refused + notes:
        warnings.warn(note, RecordWarning, stacklevel=2)
    return write_atomic(out / "index.html", html_page("bench history", parts))


def _runs_table(points: list[Point]) -> str:
    rows = []
    for i, p in enumerate(points):
        jobs = Counter(e["status"] for e in p.entries.values())
        status = ", ".join(f"{n} {s}" for s, n in sorted(jobs.items()))
        cls = " class='failed'" if p.verdict.startswith("FAILED") else ""
        rows.append(f"<tr{cls}><td>{i}</td><td>{esc(p.commit[:12])}</td><td>{esc(p.date)}</td>"
                    f"<td>{esc(p.folder.name)}</td><td>{esc(status)}</td>"
                    f"<td>{esc(p.verdict)}</td></tr>")
    return ("<table><thead><tr><th>#</th><th>commit</th><th>date</th><th>folder</th>"
            "<th>jobs</th><th>bench check</th></tr></thead><tbody>"
            + "".join(rows) + "</tbody></table>")


def run_labels(points: list[Point]) -> list[str]:
    """The x label of each run: its number in the table of runs, its commit and its date;
    runs of one commit (a re-run, a run on another machine) differ by their number."""
    return [f"#{i} {p.commit[:7]}\n{p.date[:10]}" for i, p in enumerate(points)]


def _figure(group, points: list[Point], metrics: list[str], info: dict):
    """A row of panels, one per metric: a line per method over the runs (each method in
    its report style), failing points crossed out in red, the legend right of the
    panels."""
    plt = pyplot()
    present = [m for m in metrics if m in set(group.metric)]
    fig, axes = plt.subplots(1, len(present), figsize=(4.4 * len(present), 3.4),
                             squeeze=False)
    every = max(1, len(points) // 8)  # at most about 8 labelled runs: they stay readable
    ticks = list(range(0, len(points), every))
    labels = run_labels(points)
    styles = method_styles(group.method)
    for ax, metric in zip(axes[0], present):
        rows = group[group.metric == metric]
        for method, line in rows.groupby("method", sort=True):
            line = line.sort_values("run")
            ax.plot(line.run, line.value.astype(float), markersize=5,
                    label=plot_text(method), **styles[method].plot_kwargs())
            bad = line[line.mark != ""]
            ax.plot(bad.run, bad.value.astype(float), "x", color="red", markersize=10,
                    markeredgewidth=2)
        unit, higher = info.get(metric, ("", None))
        arrow = "" if higher is None else " (higher is better)" if higher else \
            " (lower is better)"
        ax.set_title(f"{metric}{arrow}", fontsize=11)
        ax.set_ylabel(unit, fontsize=10)
        ax.set_xticks(ticks, [plot_text(labels[i]) for i in ticks], fontsize=9)
        ax.tick_params(axis="y", labelsize=9)
        ax.grid(True, alpha=.3)
    legend_outside(axes[0][-1], fig)
    fig.tight_layout()
    return fig
