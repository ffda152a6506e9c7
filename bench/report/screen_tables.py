"""Tables and charts of a run's screen-size evaluation (``bench run --screen-sizes``, the
``lod`` suite; metrics/screen.py):

* :func:`switch_table`: per model and method, ``switch_px`` of each level (a bound shown
  as ``>=512`` or ``<32``) and the faces needed at 128 and 64 px: the fewest faces among
  the method's budgets whose switch size is at least that size;
* :func:`best_at`: per model, the method that needs the fewest faces at a size;
* :func:`predictor_table`: per method and model, how well each predicted switch size
  (from the Hausdorff max; from the library's own error for meshoptimizer's rows)
  matches the measured one: the median and range of measured / predicted, and how often
  the prediction would switch too early (predicted larger than measured: the engine
  shows the LOD at a size where it is still distinguishable). A measured bound decides
  "too early" where it can (predicted above a ``<32`` bound: too early; predicted at or
  below a ``>=512`` bound: not) and is left out of the ratios;
* :func:`ablation_table`: the faces needed at 128 px under each τ of
  :data:`metrics.screen.FLIP_ABLATION`;
* :func:`faces_needed_chart`: per model the chart "faces needed vs screen size" (PNG).

``python scripts/screen_table.py RUN_DIR [--charts DIR]`` prints them as Markdown.
"""

from __future__ import annotations

import math
from pathlib import Path

from bench.records.results import evaluated

__all__ = ["switch_rows", "faces_needed", "switch_table", "best_at", "predictor_table",
           "ablation_table", "faces_needed_chart", "markdown"]


def switch_rows(records: list[dict]) -> list[dict]:
    """One row per evaluated record with a screen curve: model, method, faces, the
    switch sizes with their bounds, the predictions and the ablation."""
    rows = []
    for r in records:
        part = r.get("screen")
        if not evaluated(r) or not part:
            continue
        rows.append({"model": r["job"]["model"], "method": r["job"]["label"],
                     "target": r["job"]["target_faces"], "faces": r["metrics"].get("faces"),
                     "switch": part["switch_px"], "switch_rms": part["switch_px_rms"],
                     "predicted": part.get("predicted") or {},
                     "ablation": part.get("ablation") or {}})
    return rows


def _at_least(switch: dict, size: float) -> bool:
    """Whether a switch size (with its bound) is known to be at least ``size``."""
    if switch["bound"] == "<":
        return False  # below the smallest size measured
    return switch["value"] >= size - 1e-9


def faces_needed(rows: list[dict], size: float, key: str = "switch") -> int | None:
    """The fewest faces among ``rows`` (one model and method) indistinguishable at
    ``size``; None if no budget is."""
    good = [row["faces"] for row in rows if _at_least(row[key], size)]
    return min(good) if good else None


def _show(switch: dict) -> str:
    bound = switch["bound"]
    return f"{bound}{switch['value']:.0f}" if bound else f"{switch['value']:.0f}"


def _groups(rows):
    groups: dict = {}
    for row in rows:
        groups.setdefault((row["model"], row["method"]), []).append(row)
    for key in groups:
        groups[key].sort(key=lambda row: -row["target"])
    return dict(sorted(groups.items()))


def switch_table(rows: list[dict], sizes=(128, 64)) -> list[list[str]]:
    """Header and rows: model, method, ``faces:switch_px`` per level, faces needed at
    each of ``sizes``."""
    table = [["model", "method", "levels (faces: switch_px)"] +
             [f"faces at {s} px" for s in sizes]]
    for (model, method), group in _groups(rows).items():
        levels = " ".join(f"{row['faces']}:{_show(row['switch'])}" for row in group)
        table.append([model, method, levels] +
                     [str(faces_needed(group, s) or "-") for s in sizes])
    return table


def best_at(rows: list[dict], size: float = 128) -> list[list[str]]:
    """Per model the method(s) needing the fewest faces at ``size``, and that count."""
    per_model: dict = {}
    for (model, method), group in _groups(rows).items():
        need = faces_needed(group, size)
        if need is not None:
            per_model.setdefault(model, []).append((need, method))
    table = [["model", f"fewest faces at {size} px", "method(s)", "next"]]
    for model, options in sorted(per_model.items()):
        options.sort()
        best = [m for n, m in options if n == options[0][0]]
        rest = [f"{m} {n}" for n, m in options if n != options[0][0]][:3]
        table.append([model, str(options[0][0]), ", ".join(best), ", ".join(rest)])
    return table


def _median(values):
    values = sorted(values)
    n = len(values)
    return None if not n else (values[n // 2] if n % 2 else
                               math.sqrt(values[n // 2 - 1] * values[n // 2]))


def predictor_table(rows: list[dict]) -> list[list[str]]:
    """Per predictor, method and model: measured / predicted (median, min-max, of the
    rows measured between two sizes) and the share of rows where the prediction switches
    too early, of those where it is decidable."""
    table = [["predictor", "model", "method", "n", "median measured/predicted",
              "range", "too early"]]
    for predictor in ("hausdorff", "library"):
        for (model, method), group in _groups(rows).items():
            ratios, early, decided = [], 0, 0
            for row in group:
                predicted = row["predicted"].get(predictor)
                if predicted is None:
                    continue
                value, bound = row["switch"]["value"], row["switch"]["bound"]
                if bound is None:
                    ratios.append(value / predicted)
                    decided += 1
                    early += predicted > value
                elif bound == "<" and predicted >= value:
                    decided += 1
                    early += 1
                elif bound == ">=" and predicted <= value:
                    decided += 1
            if not decided:
                continue
            med = _median(ratios)
            table.append([predictor, model, method, str(decided),
                          "-" if med is None else f"{med:.3g}",
                          f"{min(ratios):.3g}-{max(ratios):.3g}" if ratios else "-",
                          f"{early}/{decided}"])
    return table


def ablation_table(rows: list[dict], size: float = 128) -> list[list[str]]:
    """Faces needed at ``size`` under each τ of the recorded ablation."""
    taus = sorted({t for row in rows for t in row["ablation"]}, key=float)
    table = [["model", "method"] + [f"τ={t}" for t in taus]]
    for (model, method), group in _groups(rows).items():
        cells = []
        for t in taus:
            sub = [{**row, "switch": row["ablation"][t]} for row in group if t in row["ablation"]]
            cells.append(str(faces_needed(sub, size) or "-"))
        table.append([model, method] + cells)
    return table


def faces_needed_figure(rows: list[dict], model: str,
                        sizes=(32, 45, 64, 91, 128, 181, 256, 362, 512)):
    """The figure "faces needed vs screen size" of ``model``: for each method (in its
    report style) the fewest of its budgets indistinguishable at each size, log-log;
    None without data."""
    from bench.report.plots import legend_outside, plain_log_axis, plot_text, pyplot
    from bench.report.styles import method_styles

    groups = {m: g for (mo, m), g in _groups(rows).items() if mo == model}
    if not groups:
        return None
    plt = pyplot()
    styles = method_styles(groups)
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for method, group in groups.items():
        points = [(s, faces_needed(group, s)) for s in sizes]
        points = [(s, f) for s, f in points if f is not None]
        if points:
            ax.plot(*zip(*points), label=plot_text(method), markersize=5,
                    **styles[method].plot_kwargs())
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    plain_log_axis(ax.xaxis)
    plain_log_axis(ax.yaxis)
    ax.set_xlabel("screen size (pixels spanned by the bounding sphere)")
    ax.set_ylabel("faces needed")
    ax.set_title(f"{plot_text(model)}: the fewest faces indistinguishable at each size",
                 fontsize=10)
    ax.grid(True, which="major", alpha=.3)
    legend_outside(ax, fig)
    return fig


def faces_needed_chart(rows: list[dict], model: str, path: Path,
                       sizes=(32, 45, 64, 91, 128, 181, 256, 362, 512)) -> Path | None:
    """:func:`faces_needed_figure` written to ``path`` as PNG; None without data."""
    from bench.report.plots import pyplot

    fig = faces_needed_figure(rows, model, sizes)
    if fig is None:
        return None
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100, bbox_inches="tight")
    pyplot().close(fig)
    return path


def markdown(table: list[list[str]]) -> str:
    """A table (header first) as Markdown."""
    lines = ["| " + " | ".join(table[0]) + " |", "|" + "---|" * len(table[0])]
    lines += ["| " + " | ".join(row) + " |" for row in table[1:]]
    return "\n".join(lines)
