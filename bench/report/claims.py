"""The "Reproduction" page of ``bench reproduce``: ``DIR/index.html``.

A table of every claim (paper, figure, test, the paper's figure, ours, verdict, and the
class, p-value and effect of its test over the views), then
per claim its evidence: the rows it was decided on, the two methods' values over the
budgets (when it has several), and the first protocol view of the worst row for each
method, linking the full image of the suite's run folder ``DIR/<suite>/`` (whose own
report has every view and difference image). Everything shown comes from records, so
it is escaped and images pass :func:`~bench.report.images.run_png` as in the
run report.
"""

from __future__ import annotations

import math
from pathlib import Path
from urllib.parse import quote

from bench.io.atomic import write_atomic
from bench.records.claims import ClaimResult
from bench.report.images import RunFiles, run_png
from bench.report.page import figure, html_page, pyplot
from bench.report.table import esc

__all__ = ["write_reproduction"]

_VERDICT_CLASS = {"holds": "best", "holds, weaker": "", "mixed": "skipped",
                  "does not hold": "failed", "no data": "skipped"}


def _num(value, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return f"{value:.{digits}g}"


def write_reproduction(out_dir: Path, results: list[ClaimResult], seconds: float | None,
                       refused: list[str] | None = None) -> Path:
    """Write ``out_dir/index.html`` for ``results``; returns its path."""
    refused = [] if refused is None else refused
    files = RunFiles(out_dir, refused)
    rows = []
    for res in results:
        c = res.claim
        rows.append(
            f"<tr><td><a href='#c-{quote(c.name)}'>{esc(c.name)}</a></td><td>{esc(c.source)}"
            f"</td><td>{esc(c.test)}</td><td>{esc(c.paper or 'qualitative')}</td>"
            f"<td>{esc(res.summary)}</td><td class='{_VERDICT_CLASS[res.verdict]}'>"
            f"{esc(res.verdict)}</td><td>{esc(res.klass or '')}</td><td>{_num(res.p, 3)}"
            f"</td><td>{_num(res.effect)}{esc(_side(res))}</td></tr>")
    head = ("<table><thead><tr><th>claim</th><th>source</th><th>test</th><th>paper</th>"
            "<th>ours</th><th>verdict</th><th>class</th><th>p</th><th>effect</th></tr>"
            "</thead><tbody>" + "".join(rows) + "</tbody></table>")
    took = f" The suites ran in {seconds / 60:.1f} min." if seconds is not None else ""
    parts = ["<h1>Reproduction: the papers' claims under this protocol</h1>",
             f"<p class='note'>Every verdict is computed from the records of the suite "
             f"runs in this folder (one folder per suite, each with its own report).{took} "
             "A ratio is the first method's value over the second's on the same model, "
             "budget and shading. The verdict counts the rows that pass; the class says "
             "whether the difference is significant over the views: for a ratio, Wilcoxon "
             "signed-rank tests of the per-view values, Holm-corrected over the claim's "
             "rows (p is the deciding corrected p-value, the effect the median per-view "
             "ratio); for a value against a threshold, where its 95 % bootstrap interval "
             "over the views lies. Views are not independent draws: a test asks whether a "
             "method is better consistently across the viewpoints of one model, not on "
             "other models. <i>no test</i>: the metric has no per-view values.</p>", head]
    parts += [_section(out_dir, res, files) for res in results]
    if refused:
        parts.insert(1, "<div class='warnings'><p>Left out:</p><ul>"
                     + "".join(f"<li>{esc(n)}</li>" for n in refused) + "</ul></div>")
    return write_atomic(out_dir / "index.html", html_page("bench reproduce", parts))


def _section(out_dir: Path, res: ClaimResult, files: RunFiles) -> str:
    c = res.claim
    vs = f" against <b>{esc(c.against)}</b>" if c.against else ""
    klass = f" ({esc(res.klass)})" if res.klass else ""
    parts = [f"<h2 id='c-{quote(c.name)}'>{esc(c.name)}: {esc(res.verdict)}{klass}</h2>",
             f"<p>{esc(c.statement)} ({esc(c.source)}). <b>{esc(c.method)}</b>{vs}, "
             f"{esc(c.test)}; the paper: {esc(c.paper or 'qualitative')}. Suite "
             f"<a href='{quote(c.suite)}/index.html'>{esc(c.suite)}</a>.</p>"]
    if c.note:
        parts.append(f"<p class='note'>{esc(c.note)}</p>")
    if not res.rows:
        parts.append("<p>No records: run the suite (bench reproduce runs it).</p>")
        return "\n".join(parts)
    header = ["model", "target", "faces", "shading", c.method]
    if c.against:
        header += [c.against, "ratio", "views claimed way", "p (Holm)"]
    else:
        header += ["95 % interval", "side"]
    body = []
    for r in res.rows:
        cells = [esc(r["model"]), str(r["target_faces"]), _num(r["faces"], 6),
                 esc(r["shading"]), _num(r["method_value"])]
        if c.against:
            share = r.get("share_claimed")
            cells += [_num(r["against_value"]), _num(r["value"]),
                      "" if share is None else f"{share:.0%}", _num(r.get("p_holm"), 3)]
        else:
            iv = r.get("interval")
            cells += ["" if iv is None else f"{_num(iv[0])} to {_num(iv[1])}",
                      esc(r.get("side") or "")]
        mark = "" if r["passes"] else " class='failed'"
        body.append(f"<tr{mark}>" + "".join(f"<td>{x}</td>" for x in cells) + "</tr>")
    parts.append("<table><thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header)
                 + "</tr></thead><tbody>" + "".join(body) + "</tbody></table>")
    parts.append(_curve(res, files))
    parts.append(_views(out_dir, res, files))
    return "\n".join(p for p in parts if p)


def _side(res: ClaimResult) -> str:
    """Where a threshold claim's intervals lie, for the table's effect column."""
    return f"intervals {res.side}" if res.side else ""


def _curve(res: ClaimResult, files: RunFiles) -> str:
    """The claim's metric over faces for each method and model, when some model has
    more than one budget."""
    c = res.claim
    by_model: dict[str, list[dict]] = {}
    for r in res.rows:
        by_model.setdefault(f"{r['model']} ({r['shading']})", []).append(r)
    if all(len(v) < 2 for v in by_model.values()):
        return ""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    for model, rows in by_model.items():
        rows = sorted(rows, key=lambda r: r["target_faces"])
        x = [r["target_faces"] for r in rows]
        ax.plot(x, [r["method_value"] for r in rows], marker="o",
                label=f"{c.method}, {model}".replace("$", r"\$"))
        if c.against:
            ax.plot(x, [r["against_value"] for r in rows], marker="s", linestyle="--",
                    label=f"{c.against}, {model}".replace("$", r"\$"))
    ax.set_xscale("log")
    ax.set_xlabel("target faces")
    ax.set_ylabel(c.metric)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=.3)
    src = files.plot(fig, f"claim-{c.name}")
    return f"<div class='plots'><img alt='{esc(c.metric)} plot' src='{src}'></div>" if src \
        else ""


def _views(out_dir: Path, res: ClaimResult, files: RunFiles) -> str:
    """The first view of the worst row, for each method of the claim."""
    c = res.claim
    worst = max(res.rows, key=lambda r: (-math.inf if math.isnan(r["value"]) else
                                         r["value"] * (1 if c.below is not None else -1)))
    figures = []
    for label, key in ((c.method, worst["method_key"]), (c.against, worst["against_key"])):
        if not label or not isinstance(key, str):
            continue
        png = run_png(out_dir, f"{c.suite}/images/{key}/view00.png", files.refused)
        shown = files.view(png) if png else None
        if shown is not None:
            figures.append(figure(shown, f"{label}, {worst['model']} at "
                                         f"{worst['target_faces']} faces, view 0"))
    return f"<div class='sheet'>{''.join(figures)}</div>" if figures else ""
