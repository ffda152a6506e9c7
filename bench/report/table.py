"""The report's summary table, and the few lines of script that sort and filter it.

One row per record: failed and skipped jobs first, with the first line of their error
as the reason; numbers right-aligned, each column's unit and direction (from the
metric's registration, :class:`bench.core.metric.Metric`) in a second header row; in each
group of ok jobs of one model, budget and evaluation shading, the best value of each
metric that has a direction is marked. A value with per-view values carries its 95 %
bootstrap interval over the views as the cell's tooltip
(:func:`bench.records.stats.record_intervals`). Every string from a record is HTML-escaped.

The script (:data:`SCRIPT`) is the page's only one and needs no network: a click on a
header sorts the rows by that column (numbers as numbers, empty cells last; a second
click reverses), the text box shows only the rows that contain every word typed, and
``#sort=COLUMN`` (``#sort=-COLUMN`` descending) in the page's address sorts on load.
"""

from __future__ import annotations

import html

import numpy as np

from bench.records.check import metric_info
from bench.records.results import OFF_TARGET_STATUS
from bench.report import script
from bench.report.cells import model_cell, number, resolved

__all__ = ["SCRIPT", "cell", "esc", "sortable_table", "summary_html"]

SCRIPT = script("table.js")

#: Units of the summary's columns that are not metrics (a metric's is its registration's).
_UNITS = {"target_faces": "faces", "seconds": "s", "tri_per_s": "triangles/s", "peak_mb": "MB"}
#: Columns of text (left-aligned); every other column holds numbers.
_TEXT_COLUMNS = ("model", "method", "shading", "status", "reason")
#: Failed jobs first, then skipped ones, then the rest (in the order of the records).
_STATUS_ORDER = {"failed": 0, "skipped": 1}
#: Longest reason shown in the table (the whole error is under "Failures").
_REASON_CHARS = 160


def esc(value) -> str:
    """Any value from a record as HTML text (quotes escaped too, for attributes)."""
    return html.escape(str(value), quote=True)


def sortable_table(head: list[str], body: list[list[str]], table_id: str | None = None) -> str:
    """A table of plain strings (``head`` and rows of ``body``), every cell escaped, that
    the page's script sorts by a click on a header."""
    ident = f" id='{esc(table_id)}'" if table_id else ""
    rows = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>"
                   for row in body)
    return (f"<table{ident} class='sortable'><thead><tr>"
            + "".join(f"<th>{esc(h)}</th>" for h in head)
            + f"</tr></thead><tbody>{rows}</tbody></table>")


def cell(value) -> str:
    """A table cell's text: floats to 4 significant digits, missing values empty."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.4g}"
    return esc(value)


def summary_html(table, records: list[dict], links: dict[str, str]) -> str:
    """The summary table of ``table`` (:func:`~bench.records.results.records_table` of
    ``records``, row i from ``records[i]``), each model name linking to ``links[model]``,
    with the filter box and a note on how to read it."""
    reasons = [_reason(r) for r in records]
    columns = _columns(list(table.columns), any(reasons))
    metrics = metric_info()
    best = _best_cells(table, {c: up for c, (_, up) in metrics.items()
                               if c in table.columns and up is not None})
    from bench.records.results import evaluated
    from bench.records.stats import record_intervals

    intervals = [record_intervals(r) if evaluated(r) else {} for r in records]
    rows = [_row(table.iloc[i], i, reasons[i], columns, best, links, intervals[i])
            for i in sorted(range(len(table)), key=lambda i: _STATUS_ORDER.get(table.status.iat[i], 2))]
    heads = "".join(f"<th{_more(c)}>{html.escape(c)}</th>" for c in columns)
    units = "".join(_unit_cell(c, metrics).replace("<th", "<th" + _more(c), 1)
                    for c in columns)
    left = ",".join(f"#summary {tag}:nth-child({columns.index(c) + 1})"
                    for c in _TEXT_COLUMNS if c in columns for tag in ("td", "th"))
    return (f"<style>#summary td{{text-align:right}}{left}{{text-align:left}}</style>"
            f"{_HOW_TO_READ}<div class='scroll'><table id='summary' class='sortable'>"
            f"<thead><tr>{heads}</tr><tr class='units'>{units}</tr></thead>"
            f"<tbody>{''.join(rows)}</tbody></table></div>")


#: The columns shown before the toggle, in this order: what answers "which method, at
#: what cost"; every other column follows them, hidden until "all columns" is ticked.
KEY_COLUMNS = ("model", "method", "shading", "target_faces", "faces", "d_rms", "flip", "ssim",
               "seconds", "status", "reason")


def _columns(columns: list[str], reasons: bool) -> list[str]:
    """The table's columns: :data:`KEY_COLUMNS` first (the reason only when some job has
    one), where a failure's row shows its status without scrolling, then the rest."""
    have = set(columns) | ({"reason"} if reasons else set())
    front = [c for c in KEY_COLUMNS if c in have]
    return front + [c for c in columns if c not in front]


_HOW_TO_READ = (
    "<p class='note'>Click a column header to sort (again to reverse); the box shows only "
    "the rows that contain every word typed. Units are under the names; ↓ lower is better, "
    "↑ higher is better, and the best value of each model, budget and shading is "
    "<span class='best'>marked</span> (the lowest or highest value, which need not be "
    "significantly better: bench compare tests it view by view). A value with per-view "
    "values shows its 95 % bootstrap interval over the views when pointed at. Failed and skipped jobs come first, with their "
    "reason. A word <code>column:text</code> (<code>model:torus faces:655</code>) looks in "
    "that column only. The key columns come first; the others are a tick away.</p><p>"
    "<input id='filter' type='search' size='40' placeholder='filter, e.g. model:bunny qslim' "
    "aria-label='filter the summary table'> <label><input type='checkbox' class='all-columns' "
    "data-table='summary'> all columns</label></p>")


def _more(column: str) -> str:
    """The class of a column hidden behind the "all columns" toggle."""
    return "" if column in KEY_COLUMNS else " class='more'"


def _row(row, i: int, reason: str, columns: list[str], best: set, links: dict,
         intervals: dict | None = None) -> str:
    cells = []
    for c in columns:
        if c == "reason":
            cells.append(f"<td class='reason' title='{esc(reason)}'>{esc(reason)}</td>"
                         if reason else "<td></td>")
            continue
        text = model_cell(row[c]) if c == "model" else number(c, row[c])
        if c == "model" and row[c] in links:
            text = f"<a href='{links[row[c]]}'>{text}</a>"
        lo_hi = (intervals or {}).get(c)
        title = (f" title='95 % interval over views: {lo_hi[0]:.4g} to {lo_hi[1]:.4g}'"
                 if lo_hi and text else "")
        classes = " ".join(k for k, on in (("best", (i, c) in best),
                                           ("more", c not in KEY_COLUMNS)) if on)
        mark = f" class='{classes}'" if classes else ""
        cells.append(f"<td{mark}{title}>{text}</td>")
    status = row["status"]
    cls = f" class='{esc(status.replace(', ', '-').replace(' ', '-'))}'" if status != "ok" else ""
    return f"<tr{cls}>{''.join(cells)}</tr>"


def _unit_cell(column: str, metrics: dict) -> str:
    unit, up = metrics.get(column, (_UNITS.get(column, ""), None))
    if up is None:
        return f"<th>{esc(unit)}</th>"
    arrow, direction = ("↑", "higher") if up else ("↓", "lower")
    return f"<th title='{direction} is better'>{esc(unit)} {arrow}</th>"


def _reason(record: dict) -> str:
    """The first line of a failed or skipped job's error, at most :data:`_REASON_CHARS`
    characters, control characters shown escaped; empty for an ok job."""
    if record.get("status") == "ok":
        return ""
    if record.get("status") == OFF_TARGET_STATUS:
        faces = (record.get("metrics") or {}).get("faces")
        text = _printable(record.get("stop_reason") or
                          f"{faces} faces for a target of {record['job']['target_faces']}")
        return text if len(text) <= _REASON_CHARS else text[:_REASON_CHARS - 1] + "…"
    error = record.get("error")
    lines = [line for line in str(error).splitlines() if line.strip()] if error else []
    text = _printable(lines[0].strip()) if lines else "(no reason given)"
    return text if len(text) <= _REASON_CHARS else text[:_REASON_CHARS - 1] + "…"


def _printable(text: str) -> str:
    """``text`` with control characters shown escaped (as ``bench.commands.one_line``)."""
    return "".join(ch if ch.isprintable() else repr(ch)[1:-1] for ch in text)


def _best_cells(table, directions: dict[str, bool]) -> set[tuple[int, str]]:
    """(row position, column) of the best finite value of each metric with a direction
    in each group of ok rows of one model, budget and shading; ties are all marked, and
    a group whose values are all equal (or that has one value) marks none."""
    import pandas as pd

    best = set()
    ok = table.reset_index(drop=True)
    ok = ok[ok.status == "ok"]
    for _, group in ok.groupby(["model", "target_faces", "shading"], sort=False):
        for column, higher in directions.items():
            values = pd.to_numeric(group[column], errors="coerce").astype(float)
            values = values[np.isfinite(values)].map(lambda v, c=column: resolved(c, v))
            if values.nunique() < 2:
                continue
            target = values.max() if higher else values.min()
            best.update((int(i), column) for i in values.index[values == target])
    return best
