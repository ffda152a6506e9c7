"""The report's first section: which method is best here, and at what cost.

Per model, budget and evaluation shading, the methods that reached their target are
ranked by d_RMS, with FLIP, SSIM, the mean Hausdorff distance, seconds and faces beside;
results off their target are listed under the ranking, not in it. The first place is a
*winner* only when its d_RMS is significantly lower, view by view, than every other
ranked method's (Wilcoxon signed-rank tests of the per-view values,
:func:`bench.records.stats.paired`, Holm-corrected over the comparisons of the group);
otherwise the methods it does not beat significantly are *tied* with it. Values under a
metric's resolution (:data:`bench.report.cells.RESOLUTION`) rank as equal.

Above the tables, a summary across models: per method, its mean rank, its wins
(significant first places), ties for first and losses (groups where the first place
beats it significantly).

Extra columns: :data:`EXTRA_COLUMNS` holds optional columns (a name, a header, a unit,
whether higher is better, and a function of the record giving the value or None); a
column is shown only when some record of the page has a value for it.
"""

from __future__ import annotations

import html
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from bench.records.results import OFF_TARGET_STATUS, OK, shading_label
from bench.records.stats import ALPHA, consistent_views, holm, paired
from bench.report.cells import model_cell, number, resolved
from bench.report.styles import method_styles

__all__ = ["EXTRA_COLUMNS", "Column", "Group", "leaderboard_html", "rank_groups",
           "reuse_note"]


class Column(NamedTuple):
    """A leaderboard column: ``key`` (the cell's column for formatting), ``header``,
    ``unit``, ``higher`` (True, False, or None: no direction) and ``value(record)``."""

    key: str
    header: str
    unit: str
    higher: bool | None
    value: Callable[[dict], object]


def _metric(name: str) -> Callable[[dict], object]:
    return lambda r: (r.get("metrics") or {}).get(name)


#: The columns every leaderboard shows, in order, after the rank and the method.
COLUMNS = (Column("d_rms", "d_RMS", "0-255", False, _metric("d_rms")),
           Column("flip", "FLIP", "0-1", False, _metric("flip")),
           Column("ssim", "SSIM", "0-1", True, _metric("ssim")),
           Column("hausdorff_mean", "Hausdorff mean", "of diagonal", False,
                  _metric("hausdorff_mean")),
           Column("seconds", "seconds", "s", False,
                  lambda r: (r.get("stats") or {}).get("wall_seconds")),
           Column("faces", "faces", "", None, _metric("faces")))

#: Optional columns after :data:`COLUMNS` (e.g. the largest screen size at which a result
#: is indistinguishable, once the screen-size evaluation records it); shown when some
#: record has a value.
def _switch_px(record: dict):
    """A result's switch size (``--screen-sizes``, the lod suites): a number, or a bound
    as text (``≥512``, ``<32``); None without a screen-size evaluation."""
    switch = (record.get("screen") or {}).get("switch_px")
    if not isinstance(switch, dict) or not _finite(switch.get("value")):
        return None
    bound = {">=": "≥", "<": "<"}.get(switch.get("bound"))
    return f"{bound}{switch['value']:.0f}" if bound else round(switch["value"])


EXTRA_COLUMNS: list[Column] = [
    # the screen-size evaluation's answer, where a run has it
    Column("switch_px", "switch px", "px", True, _switch_px),
]


def _finite(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and \
        math.isfinite(value)


@dataclass
class Group:
    """One model, budget and shading: ``ranked`` records (best first) with their
    ``ranks`` (1 for the first place and every method tied with it), ``verdict``
    (``winner``, ``tie`` or ``alone``/``untested``), ``worse`` the labels the first place
    beats significantly, and ``off`` the results off their target."""

    model: str
    target: int
    shading: str
    ranked: list[dict] = field(default_factory=list)
    ranks: list[int] = field(default_factory=list)
    verdict: str = "alone"
    worse: set = field(default_factory=set)
    p: dict = field(default_factory=dict)  # label -> Holm-adjusted p against the first
    off: list[dict] = field(default_factory=list)


def _label(r: dict) -> str:
    return str(r["job"]["label"])


def rank_groups(records: list[dict]) -> list[Group]:
    """The leaderboard's groups of ``records``, in the order models first appear, then by
    budget (largest first) and shading."""
    groups: dict[tuple, Group] = {}
    for r in records:
        if r.get("status") not in (OK, OFF_TARGET_STATUS):
            continue
        job = r["job"]
        key = (job["model"], job["target_faces"], shading_label(job["protocol"]))
        g = groups.setdefault(key, Group(*key))
        d = (r.get("metrics") or {}).get("d_rms")
        if r["status"] == OFF_TARGET_STATUS:
            g.off.append(r)
        elif _finite(d):
            g.ranked.append(r)
        else:
            g.off.append(r)  # no d_RMS to rank it by: listed with the unranked
    order = {m: i for i, m in enumerate(dict.fromkeys(r["job"]["model"] for r in records))}
    out = sorted(groups.values(), key=lambda g: (order[g.model], -g.target, g.shading))
    for g in out:
        _decide(g)
    return out


def _decide(g: Group) -> None:
    g.ranked.sort(key=lambda r: (resolved("d_rms", r["metrics"]["d_rms"]), _label(r)))
    if len(g.ranked) < 2:
        g.ranks = [1] * len(g.ranked)
        return
    best = g.ranked[0]
    first = consistent_views(best, "d_rms")
    tests = []
    for r in g.ranked[1:]:
        other = consistent_views(r, "d_rms")
        equal = resolved("d_rms", r["metrics"]["d_rms"]) == \
            resolved("d_rms", best["metrics"]["d_rms"])
        if first is None or other is None or len(first) != len(other) or equal:
            tests.append((r, None))
        else:
            tests.append((r, paired(first, other)))
    known = [(r, t) for r, t in tests if t is not None]
    adjusted = holm([t.p for _, t in known]) if known else []
    for (r, t), p in zip(known, adjusted):
        g.p[_label(r)] = p
        if t.verdict(p, ALPHA) == "A better":
            g.worse.add(_label(r))
    if any(t is None for _, t in tests) and not g.worse:
        g.verdict = "untested"
    else:
        g.verdict = "winner" if len(g.worse) == len(g.ranked) - 1 else "tie"
    # every method the first place does not beat significantly shares the first rank;
    # the others keep their place in order of d_RMS
    g.ranks = [1 if i == 0 or _label(r) not in g.worse else i + 1
               for i, r in enumerate(g.ranked)]


def reuse_note(record: dict, records: list[dict]) -> str:
    """A note for a job that reused what another job built (a ``*_cache`` statistic
    that is not ``built``): whose build and how long it took; empty otherwise."""
    stats = record.get("stats") or {}
    for key, source in stats.items():
        if not key.endswith("_cache") or source in (None, "built"):
            continue
        job = record["job"]
        for other in records:
            o = other.get("stats") or {}
            if o.get(key) == "built" and other["job"]["model"] == job["model"] and \
                    other["job"]["method"] == job["method"]:
                secs = o.get("wall_seconds")
                took = f" in {secs:.3g} s" if _finite(secs) else ""
                return (f"reused what the {other['job']['target_faces']}-face job "
                        f"built{took} ({key.removesuffix('_cache')}, from {source}); "
                        "its own seconds leave that build out")
        return (f"reused a {key.removesuffix('_cache')} built before this run (from "
                f"{source}); its own seconds leave that build out")
    return ""


def _extra(records: list[dict]) -> list[Column]:
    return [c for c in EXTRA_COLUMNS if any(c.value(r) is not None for r in records)]


def _head(columns: list[Column]) -> str:
    cells = "<th>rank</th><th>method</th>"
    for c in columns:
        arrow = "" if c.higher is None else " ↑" if c.higher else " ↓"
        unit = f"<br><span class='unit'>{html.escape(c.unit)}{arrow}</span>" \
            if c.unit or arrow else ""
        cells += f"<th>{html.escape(c.header)}{unit}</th>"
    return f"<thead><tr>{cells}</tr></thead>"


def _swatch(label: str, styles: dict) -> str:
    style = styles.get(label)
    colour = style.colour if style else "#888"
    return (f"<span class='swatch' style='background:{colour}'></span>"
            f"{html.escape(label)}")


def _row(g: Group, r: dict, rank, columns, styles, records, cls: str = "") -> str:
    label = _label(r)
    cells = [f"<td>{rank}</td>", f"<td class='method'>{_swatch(label, styles)}</td>"]
    for c in columns:
        value = c.value(r)
        text = number(c.key, value)
        title = ""
        if c.key == "seconds":
            note = reuse_note(r, records)
            if note:
                text += " <span class='reused' title='" + html.escape(note, quote=True) + \
                    "'>reused build</span>"
        if c.key == "d_rms" and label in g.p:
            title = f" title='Holm-adjusted p against the first place: {g.p[label]:.3g}'"
        cells.append(f"<td{title}>{text}</td>")
    return f"<tr{cls}>{''.join(cells)}</tr>"


#: Ranked rows a leaderboard shows before its "all" toggle (every method tied for first
#: is shown, however many).
SHOWN_ROWS = 5


def _group_html(g: Group, n: int, columns, styles, records) -> str:
    rows = []
    for i, (r, rank) in enumerate(zip(g.ranked, g.ranks)):
        if rank == 1 and g.verdict == "winner":
            cls, shown = " class='winner'", "1 (winner)"
        elif rank == 1 and len(g.ranked) > 1:
            cls, shown = " class='tied'", "1 (tie)" if g.verdict == "tie" else "1 (untested)"
        else:
            cls, shown = "", str(rank)
        if i >= SHOWN_ROWS and rank != 1:
            cls = cls[:-1] + " extra'" if cls else " class='extra'"
        rows.append(_row(g, r, shown, columns, styles, records, cls))
    for r in g.off:
        rows.append(_row(g, r, "off target", columns, styles, records,
                         " class='off-target extra'"))
    hidden = sum("extra" in row.split(">", 1)[0] for row in rows)
    toggle = (f"<label class='note'><input type='checkbox' class='all-columns' "
              f"data-table='lb-{n}'> all {len(rows)} results ({hidden} more)</label>"
              if hidden else "")
    if g.verdict == "winner":
        verdict = (f"<b>{html.escape(_label(g.ranked[0]))}</b> wins: lower d_RMS than each "
                   "of the others, significantly over the views")
    elif g.verdict == "tie":
        tied = [_label(r) for r, k in zip(g.ranked, g.ranks) if k == 1]
        verdict = (f"no significant winner: {', '.join(map(html.escape, tied))} tie for "
                   "first")
    elif g.verdict == "untested":
        verdict = "first place not tested (a result has no per-view d_RMS)"
    else:
        verdict = "one ranked method" if g.ranked else "no ranked method"
    return (f"<h3 class='lb-title'>{model_cell(g.model)}, {g.target} faces, "
            f"{html.escape(g.shading)}</h3><p class='note'>{verdict}.</p>"
            f"<table id='lb-{n}' class='leaderboard sortable'>{_head(columns)}<tbody>"
            f"{''.join(rows)}</tbody></table>{toggle}")


def _summary(groups: list[Group], styles) -> str:
    stats: dict[str, dict] = {}
    for g in groups:
        for r, rank in zip(g.ranked, g.ranks):
            s = stats.setdefault(_label(r), {"ranks": [], "wins": 0, "ties": 0, "losses": 0})
            s["ranks"].append(rank)
            if rank == 1 and g.verdict == "winner":
                s["wins"] += 1
            elif rank == 1 and len(g.ranked) > 1:
                s["ties"] += 1
            if _label(r) in g.worse:
                s["losses"] += 1
    if not stats:
        return ""
    order = sorted(stats, key=lambda m: (sum(stats[m]["ranks"]) / len(stats[m]["ranks"]),
                                         -stats[m]["wins"], m))
    rows = "".join(
        f"<tr><td class='method'>{_swatch(m, styles)}</td>"
        f"<td>{sum(stats[m]['ranks']) / len(stats[m]['ranks']):.2f}</td>"
        f"<td>{len(stats[m]['ranks'])}</td><td>{stats[m]['wins']}</td>"
        f"<td>{stats[m]['ties']}</td><td>{stats[m]['losses']}</td></tr>" for m in order)
    return ("<table id='across-models' class='sortable'><thead><tr><th>method</th>"
            "<th>mean rank</th><th>groups</th><th>wins</th><th>ties for first</th>"
            f"<th>losses</th></tr></thead><tbody>{rows}</tbody></table>")


#: The screen size of the leaderboard's "faces at" table (issue: faces at 128 px).
FACES_AT_PX = 128


def _faces_at(records: list[dict]) -> str:
    """With screen sizes evaluated (``--screen-sizes``, the lod suites): per model the
    fewest faces indistinguishable from the original at :data:`FACES_AT_PX`, the
    methods that get there and the next ones; empty otherwise."""
    from bench.report.screen_tables import best_at, switch_rows
    from bench.report.table import sortable_table

    head, *body = best_at(switch_rows(records), FACES_AT_PX)
    if not body:
        return ""
    return (f"<h3>Faces at {FACES_AT_PX} px</h3><p class='note'>Per model, the fewest "
            "faces of the run's budgets whose result is indistinguishable from the "
            f"original where its bounding sphere spans {FACES_AT_PX} pixels (switch_px "
            f"&ge; {FACES_AT_PX}; docs/screen.md), and the methods that get there.</p>"
            + sortable_table(head, body, "faces-at"))


def leaderboard_html(records: list[dict]) -> str:
    """The leaderboard section of ``records``: the summary across models, then a table
    per model, budget and shading; empty when no job was evaluated."""
    groups = rank_groups(records)
    if not groups:
        return ""
    labels = [_label(r) for g in groups for r in g.ranked + g.off]
    styles = method_styles(labels)
    columns = list(COLUMNS) + _extra([r for g in groups for r in g.ranked + g.off])
    tables = "".join(_group_html(g, n, columns, styles, records)
                     for n, g in enumerate(groups))
    return ("<section id='leaderboard'><h2>Leaderboard</h2>"
            "<p class='note'>Per model, budget and shading, the methods that reached their "
            "target ranked by d_RMS (lower is better). A <span class='winner'>winner</span> "
            "has a lower d_RMS than every other ranked method, significantly over the "
            f"views (Wilcoxon signed-rank, Holm-corrected within the group, α = {ALPHA}); "
            "otherwise the methods the first place does not beat are "
            "<span class='tied'>tied</span> with it. Results off their target are listed "
            f"below each ranking, not in it; past the first {SHOWN_ROWS} a tick shows "
            "the rest. Across models: a method's mean rank, its wins, "
            "ties for first and losses (groups where the first place beats it).</p>"
            f"{_summary(groups, styles)}{_faces_at(records)}{tables}</section>")
