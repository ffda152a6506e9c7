"""The HTML report of a run directory: ``DIR/index.html``, and above :data:`PAGE_LIMIT`
jobs one page per model (``DIR/model-<slug>.html``) linked from it.

Sections follow Lindstrom & Turk 2000: a summary table (sortable and filterable,
:mod:`bench.report.table`), per model the d_RMS, FLIP and Hausdorff curves over face
count (Figures 5 and 6), silhouette histograms (Figure 7), comparison grids of the
methods side by side (:mod:`bench.report.grid`), a 3D view of the original and
any LOD orbited together (:mod:`bench.report.viewer`), image sheets with
difference images (Plate 13), a timing table (Table 1), and the failures with their
errors. Every page catches its scripts' errors and shows them at its top.

Images are files of the run folder linked by relative URLs (thumbnails linking to the
full PNGs, plots as SVG; :mod:`bench.report.images`), so the folder opens from
disk with no server and can be zipped or published as it is; ``single_file=True``
(``--single-file``) inlines every image as base64 instead, in one page, and leaves the
3D view out with a note (it needs the run folder's meshes and three.js as files).

A run folder may come from someone else, so nothing in it is trusted: every string from
a record is HTML-escaped where it is written, only records that pass
:func:`~bench.records.results.record_problem` are shown, and images are read only from
inside the run folder and only when they are PNG files
(:func:`~bench.report.images.run_png`), meshes likewise and only as whole,
self-contained GLB files (:func:`~bench.report.viewer.run_glb`). What is left
out for any of these reasons is listed under "Warnings" at the top of the report and
given as a :class:`~bench.core.errors.RecordWarning`.
"""

from __future__ import annotations

import hashlib
import math
import numbers
import re
import warnings
from collections import Counter
from pathlib import Path

from bench.core.errors import RecordWarning
from bench.io.atomic import write_atomic
from bench.records.results import (
    EVALUATED,
    OFF_TARGET_STATUS,
    evaluated,
    image_settings,
    load_records,
    records_table,
    shading_label,
)
from bench.report import asset, script
from bench.report.cells import model_cell, model_text, number
from bench.report.grid import GRID_SCRIPT, comparison_grids, grid_links
from bench.report.images import Inline, RunFiles, Shown, difference_png, run_png
from bench.report.leaderboard import leaderboard_html, reuse_note
from bench.report.plots import (
    curves_figure,
    plot_text,
    pyplot,
    quality_time_figure,
    silhouette_figure,
)
from bench.report.styles import method_styles
from bench.report.table import SCRIPT, sortable_table, summary_html
from bench.report.table import cell as _cell
from bench.report.table import esc as _esc
from bench.report.viewer import VIEWER_SCRIPT, Viewers, single_file_note

__all__ = ["ERRORS_SCRIPT", "PAGE_LIMIT", "SCRIPT", "as_dict", "figure", "html_page",
           "plot_text", "pyplot", "write_report"]

#: Above this many jobs the report is one page per model, linked from index.html, so no
#: page holds more than one model's images.
PAGE_LIMIT = 50

_CSS = asset("report.css")

#: In every page's head: an error of any script (or a promise nobody handled) is shown
#: as text at the top of the page, never a silently blank part.
ERRORS_SCRIPT = script("errors.js")

#: Summary-table columns left out when no record of the run defines them.
_OPTIONAL_COLUMNS = ("exterior_share",)


def write_report(run_dir: Path, records: list[dict] | None = None,
                 skipped: list[str] | tuple = (), single_file: bool = False) -> Path:
    """Build ``run_dir/index.html`` (atomically) from the records found there; returns
    its path.

    ``skipped`` lists the one-line reasons of records the caller left out (they are
    shown under "Warnings"); with ``records`` None the records are loaded here, bad ones
    left out with a warning each. ``single_file`` inlines every image in one page;
    otherwise images are written under ``run_dir/images/`` and, above
    :data:`PAGE_LIMIT` jobs, each model gets a page of its own.
    """
    run_dir = Path(run_dir)
    notes = list(skipped)
    if records is None:
        before = len(notes)
        records = load_records(run_dir, skipped=notes)
        for note in notes[before:]:
            warnings.warn(note, RecordWarning, stacklevel=2)
    refused = []  # images and meshes left out of the sheets and 3D views, with why
    out = Inline() if single_file else RunFiles(run_dir, refused)
    viewers = None if single_file else Viewers(run_dir, out, refused)
    table = records_table(records)
    models = list(dict.fromkeys(table.model))
    slugs = _slugs(models)
    split = not single_file and len(records) > PAGE_LIMIT
    sections = {m: _model_section(run_dir, m, records, table, out, refused, slugs[m], viewers)
                for m in models}
    for note in refused:
        warnings.warn(note, RecordWarning, stacklevel=2)
    links = {m: f"model-{slugs[m]}.html" if split else f"#m-{slugs[m]}" for m in models}
    summary = [leaderboard_html(records),
               "<h2>All results</h2>", summary_html(_summary_table(table), records, links),
               _claims_html(records)]
    ends = ["<h2>Not applicable</h2>", _not_applicable(records),
            "<h2>Failures</h2>", _failures(records)]
    if split:
        for m in models:
            write_atomic(run_dir / links[m], _model_page(run_dir, m, sections[m], records,
                                                         _viewer_scripts(viewers, slugs[m])))
        body = [*summary, _model_list(models, links, table), *ends]
    else:
        body = [*summary, *(part for m in models for part in sections[m]),
                "<h2>Timing</h2>", _timing(records), *ends]
    page = html_page(f"bench report: {_esc(run_dir.name)}",
                     [f"<h1>Simplification benchmark: {_esc(run_dir.name)}</h1>",
                      _warnings_html(notes + refused), _protocol_note(records), *body],
                     [] if split else _viewer_scripts(viewers))
    return write_atomic(run_dir / "index.html", page)


def html_page(title: str, parts: list[str], scripts: list[str] | tuple = ()) -> str:
    """A whole HTML page: ``title``, ``parts`` and ``scripts`` (after the report's own)
    are HTML already."""
    head = (f"<!doctype html><html><head><meta charset='utf-8'><title>{title}</title>"
            f"<style>{_CSS}</style>{ERRORS_SCRIPT}</head><body>")
    return "\n".join([head, *parts, SCRIPT, GRID_SCRIPT, *scripts, "</body></html>"])


def _viewer_scripts(viewers: Viewers | None, slug: str | None = None) -> list[str]:
    """The 3D view's script, for a page that holds a 3D view: the whole report's page
    (``slug`` None) when some model's section has one, a model's page (``slug`` its
    slug) when that model's section has one."""
    if viewers is None:
        return []
    wanted = viewers.used if slug is None else slug in viewers.shown
    return [VIEWER_SCRIPT] if wanted else []


def _model_page(run_dir: Path, model: str, section: list[str], records: list[dict],
                scripts: list[str]) -> str:
    """The page of one model in a split report: its section and its timing table, then
    ``scripts``."""
    own = [r for r in records if r["job"]["model"] == model]
    return html_page(f"bench report: {_esc(run_dir.name)} / {_esc(model_text(model))}",
                     [f"<p><a href='index.html'>← summary of {_esc(run_dir.name)}</a></p>",
                      f"<h1>Simplification benchmark: {_esc(run_dir.name)}, {model_cell(model)}</h1>",
                      _protocol_note(own), *section,
                      "<h2>Timing</h2>", _timing(own)],
                     scripts)


def _model_list(models: list[str], links: dict[str, str], table) -> str:
    """Links to the model pages, each with its number of jobs and failures."""
    items = []
    for m in models:
        statuses = Counter(table.status[table.model == m])
        bad = ", ".join(f"{statuses[s]} {word}" for s, word in
                        (("failed", "failed"), ("skipped", "not applicable")) if statuses[s])
        items.append(f"<li><a href='{links[m]}'>{model_cell(m)}</a>: {sum(statuses.values())} jobs"
                     f"{f' ({bad})' if bad else ''}</li>")
    return ("<h2>Models</h2><p class='note'>One page per model, with its plots, image "
            f"sheets and timing.</p><ul>{''.join(items)}</ul>")


def _model_section(run_dir: Path, model: str, records: list[dict], table, out,
                   refused: list[str], slug: str, viewers: Viewers | None) -> list[str]:
    """A model's heading, plots, exterior table, silhouette histograms, comparison grids,
    3D view (a note instead with ``viewers`` None: ``--single-file``) and sheets."""
    own = [r for r in records if r["job"]["model"] == model]
    ok = table[(table.model == model) & table.status.isin(EVALUATED)]
    images = {id(r): sheet_images(run_dir, r, refused, out)  # by record: a key may be
              for r in own if evaluated(r)}                   # missing in an older run
    if viewers is None:
        view = single_file_note(own)
    else:
        keys = {id(r): _image_folders(run_dir, r)[0] for r in own if evaluated(r)}
        view = viewers.section(own, keys, slug, len(_shadings(own)) > 1)
    reused = {(r["job"]["label"], r["job"]["target_faces"], shading_label(r["job"]["protocol"]))
              for r in own if evaluated(r) and reuse_note(r, own)}
    return [f"<h2 id='m-{slug}'>{model_cell(model)}</h2>",
            _quality_time(ok, model, out, slug, reused),
            _plots(ok, out, slug),
            grid_links(own, images, slug), _exterior_table(ok), _silhouette_plot(own, out, slug),
            _screen_sizes(own, out, slug),
            comparison_grids(own, images, slug), view,
            _sheets(run_dir, own, refused, out, images)]


def _screen_sizes(own: list[dict], out, slug: str) -> str:
    """With screen sizes evaluated (``--screen-sizes``, the lod suite): the chart of the
    faces each method needs per screen size and the table of its levels' switch sizes."""
    from bench.report.screen_tables import faces_needed_figure, switch_rows, switch_table

    rows = switch_rows(own)
    if not rows:
        return ""
    model = rows[0]["model"]
    fig = faces_needed_figure(rows, model)
    chart = "" if fig is None else _img(out.plot(fig, f"{slug}-screen"), "faces needed", out)
    head, *body = switch_table(rows)
    table = sortable_table(head, body)
    return ("<h3>Screen sizes</h3><p class='note'>The size in pixels that the model's "
            "bounding sphere spans on screen, from which each result is indistinguishable "
            "from the original (switch_px: FLIP within the protocol's threshold of the "
            "original's own; docs/screen.md). ≥512 and &lt;32 are bounds: the sizes "
            f"measured.</p><div class='plots'>{chart}</div>{table}")


def _slugs(models: list[str]) -> dict[str, str]:
    """A file-name part per model: lower-case letters, digits and ``-``, with a short
    hash of the name where two names would give the same part (or none)."""
    base = {m: re.sub(r"[^a-z0-9]+", "-", model_text(m).lower()).strip("-")[:40] for m in models}
    counts = Counter(base.values())
    return {m: b if b and counts[b] == 1 else
            f"{b}-{hashlib.sha1(str(m).encode()).hexdigest()[:8]}".lstrip("-")
            for m, b in base.items()}


def _summary_table(table):
    return table.drop(columns=[c for c in _OPTIONAL_COLUMNS if table[c].isna().all()])


def _warnings_html(notes: list[str]) -> str:
    if not notes:
        return ""
    items = "".join(f"<li>{_esc(n)}</li>" for n in notes)
    return (f"<div class='warnings'><h2>Warnings</h2><p>Left out of this report:</p>"
            f"<ul>{items}</ul></div>")


def _shadings(records: list[dict]) -> list[str]:
    """The distinct evaluation shadings of ``records`` (``flat``, ``gouraud-spec``, ...)."""
    return list(dict.fromkeys(shading_label(r["job"]["protocol"]) for r in records))


def _evaluation_words(protocol: dict) -> str:
    """A record's evaluation label in words: ``gouraud + specular``, with the image
    settings that are not the default (``at 1024² on the representative view``)."""
    resolution, views = image_settings(protocol)
    words = protocol["shading"] + (" + specular" if protocol.get("specular") else "")
    if resolution is not None:
        words += f" at {resolution}²"
    if views is not None:
        words += f" on the {views} view set"
    return words


def _protocol_note(records: list[dict]) -> str:
    ok = [r for r in records if evaluated(r)]
    if not ok:
        return "<p class='note'>No successful jobs.</p>"
    p = ok[0]["job"]["protocol"]
    env = as_dict(ok[0].get("environment"))
    labels = list(dict.fromkeys(_evaluation_words(r["job"]["protocol"]) for r in ok))
    shadings = " and ".join(labels)
    if len(labels) > 1:
        shadings += " shading (each result evaluated under each; the shading column says which)"
    else:
        shadings += " shading"
    view_set = p.get("views", "rhombicuboctahedron")
    views = ("24 small-rhombicuboctahedron views" if view_set == "rhombicuboctahedron"
             else f"the {_esc(view_set)} view set")
    return (f"<p class='note'>Protocol v{_esc(p['version'])}: {views} "
            f"at {p['resolution']}² with {p['msaa']}× MSAA, {_esc(shadings)}, 50% gray "
            f"background, headlight; "
            f"Hausdorff with {p['hausdorff_samples']:,} samples each way, as fractions of the "
            f"original's bounding-box diagonal; FLIP on "
            f"{_esc(p['flip_views'] if view_set == 'rhombicuboctahedron' else 'all')} views; "
            f"silhouettes over the 20 dodecahedron views. "
            f"Commit {_esc(str(env.get('git_commit'))[:12])}, "
            f"{_esc(as_dict(env.get('machine')).get('processor'))}.</p>")


def as_dict(value) -> dict:
    """``value`` if it is a dict, else an empty one (for optional, unchecked parts)."""
    return value if isinstance(value, dict) else {}


def _fixed(value, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals; a dash when missing (a metric that raised) or
    not a number."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return "—"
    return f"{value:.{digits}f}"


def _plots(table, out, slug: str) -> str:
    """The d_RMS, FLIP and Hausdorff curves of one model's evaluated rows over faces."""
    import pandas as pd

    if table.empty:
        return ""
    # One curve per method, and per evaluation shading when a run has several; a method
    # keeps its style across the shadings (and across every figure of the report).
    several = table.shading.nunique() > 1
    styles = method_styles(table.method)
    imgs = []
    curves = (("d_rms", "d_RMS (luminance, 0-255) vs faces — cf. Figure 5"),
              ("flip", "FLIP (mean over views, 0-1) vs faces"),
              ("hausdorff_mean", "mean Hausdorff (fraction of diagonal) vs faces — cf. Figure 6"))
    for column, title in curves:
        values = pd.to_numeric(table[column], errors="coerce") if column in table else None
        if values is None or not values.gt(0).any():
            continue  # FLIP is optional, and a metric that is 0 everywhere has no log curve
        series = {}
        for (method, shading), group in table.groupby(["method", "shading"], sort=True):
            label = f"{method} ({shading})" if several else method
            series[label] = (pd.to_numeric(group.faces, errors="coerce"),
                             pd.to_numeric(group[column], errors="coerce"), method)
        fig = curves_figure(series, column, title, styles)
        imgs.append(_img(out.plot(fig, f"{slug}-{column}"), f"{column} plot", out))
    return "<div class='plots'>" + "".join(imgs) + "</div>"


def _quality_time(table, model: str, out, slug: str, reused: set = frozenset()) -> str:
    """One model's d_RMS and FLIP against method seconds (log), a row of panels per
    shading, each panel with its Pareto front: the results no other beats on both quality
    and time. ``table``: the model's evaluated rows (those off target are left out);
    ``reused``: (method, budget, shading) of jobs whose seconds leave out a build they
    reused, drawn hollow and kept off the front."""
    import pandas as pd

    ok = table[table.status == "ok"]
    styles = method_styles(ok.method)
    imgs = []
    for shading, group in ok.groupby("shading", sort=True):
        panels = []
        seconds = pd.to_numeric(group.seconds, errors="coerce")
        for column, name in (("d_rms", "d_RMS"), ("flip", "FLIP")):
            values = pd.to_numeric(group[column], errors="coerce")
            if not values.gt(0).any():
                continue
            points = {}
            for method, secs, v, target in zip(group.method, seconds, values,
                                               group.target_faces):
                points.setdefault(method, []).append(
                    (float(secs), float(v), (method, target, shading) in reused))
            panels.append((f"{plot_text(model_text(model))}, {shading}: {name} vs time",
                           name, points))
        if panels:
            fig = quality_time_figure(panels, styles)
            src = out.plot(fig, f"{slug}-quality-time-{_file_part(shading)}")
            imgs.append(_img(src, f"quality against time, {_esc(model_text(model))}", out))
    if not imgs:
        return ""
    return ("<h3>Quality against time</h3><p class='note'>Each point is a result that "
            "reached its target (one per budget); lower and further left is better. The "
            "dashed line is the Pareto front: the results no other beats on both error and "
            "seconds, its methods named in the legend. Seconds are the method's own, "
            "compile time apart; a hollow point reused what another job built (its seconds "
            "leave that build out) and is not on the front.</p><div class='plots qt'>" + "".join(imgs) + "</div>")


def _file_part(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-") or "x"


def _img(src: str, alt: str, out) -> str:
    """An ``<img>`` of a plot (``alt`` is the report's own text); none when the plot
    could not be written."""
    if not src:
        return ""
    return f"<img alt='{alt}' src='{src}'{_LAZY if out.files else ''}>"


#: Images below the first screen are fetched as they scroll into view.
_LAZY = " loading='lazy'"


def figure(shown: Shown, caption: str, cls: str = "") -> str:
    """An image with its caption; a thumbnail links to its full-size image."""
    if shown.href is None:
        img = f"<img src='{shown.src}' alt='{_esc(caption)}'>"
    else:
        img = (f"<a href='{shown.href}'><img src='{shown.src}' alt='{_esc(caption)}'"
               f"{_LAZY}></a>")
    return (f"<figure{f' class={cls!r}' if cls else ''}>{img}"
            f"<figcaption>{_esc(caption)}</figcaption></figure>")


def _exterior_table(table) -> str:
    """Share of each result's faces on the exterior (L&T 2000 §5.2), for models whose
    metadata classifies faces; empty otherwise."""
    table = table[table.exterior_share.notna()]
    if table.empty:
        return ""
    # The share does not depend on the evaluation shading: one row per distinct result.
    table = table.drop_duplicates(subset=["method", "target_faces", "faces", "exterior_share"])
    rows = "".join(
        f"<tr><td>{_esc(r.method)}</td><td>{_esc(r.target_faces)}</td><td>{_cell(r.faces)}</td>"
        f"<td>{_cell(_exterior_faces(r.faces, r.exterior_share))}</td>"
        f"<td>{r.exterior_share:.1%}</td></tr>"
        for r in table.itertuples())
    return ("<h3>Faces on the exterior — cf. §5.2, Plates 2-3</h3><p class='note'>A face is "
            "exterior when its centroid lies outside the sphere the model's metadata gives "
            "(<code>metrics.interior</code>); the others belong to the hidden interior."
            "</p><table><tr><th>method</th><th>target</th>"
            "<th>faces</th><th>exterior faces</th><th>exterior share</th></tr>"
            f"{rows}</table>")


def _exterior_faces(faces, share) -> int | None:
    """The number of exterior faces, or None when a damaged record makes it undefined."""
    product = faces * share if faces is not None else math.nan
    return round(product) if math.isfinite(product) else None


def _silhouette_plot(records: list[dict], out, slug: str) -> str:
    ok = [r for r in records if evaluated(r) and r.get("silhouette_histogram")]
    if not ok:
        return ""
    smallest = min(r["job"]["target_faces"] for r in ok)
    # Silhouettes do not depend on the evaluation shading: one curve per method variant.
    first = {}
    for r in ok:
        if r["job"]["target_faces"] == smallest:
            first.setdefault(r["job"]["label"], r)
    styles = method_styles(first)
    hists = {label: r["silhouette_histogram"] for label, r in first.items()}
    means = ", ".join(f"{label} {_fixed(r['metrics'].get('silhouette_mean'), 2)}"
                      for label, r in first.items())
    fig = silhouette_figure(hists, f"Silhouettes at {smallest} faces, cumulative — cf. "
                                   "Figure 7", styles)
    src = out.plot(fig, f"{slug}-silhouettes")
    return (f"<div class='plots'>{_img(src, 'silhouette distributions', out)}</div>"
            f"<p class='note'>Mean number of views in which an edge is a silhouette: "
            f"{_esc(means)}.</p>")


def _sheets(run_dir: Path, records: list[dict], refused: list[str], out, images: dict) -> str:
    """The image sheets of ``records``' ok jobs (their views in ``images``, by
    ``id(record)``: :func:`sheet_images`) and their artifacts; images that cannot be
    shown safely are left out with a reason in ``refused``."""
    several = len(_shadings(records)) > 1
    parts, originals = [], set()
    for r in sorted((r for r in records if evaluated(r)),
                    key=lambda r: shading_label(r["job"]["protocol"])):
        job = r["job"]
        shading = shading_label(job["protocol"])
        under = f", evaluated {_esc(shading)}" if several else ""
        if shading not in originals and any(c["original"] for c in images[id(r)]):
            originals.add(shading)  # the original's views once per model and shading
            parts.append(f"<h3>The original{under}</h3><div class='sheet'>"
                         f"{''.join(_original_figures(images[id(r)]))}</div>")
        parts.append(f"<h3>{_esc(job['label'])} at {job['target_faces']} faces{under}: "
                     f"d_RMS {_fixed(r['metrics'].get('d_rms'))}</h3><div class='sheet'>"
                     f"{''.join(_sheet_figures(r, images[id(r)]))}</div>")
        for name in r.get("artifacts") or []:  # images the method asked to show
            png = run_png(run_dir, name, refused,
                          what=f"{job['label']} / {job['target_faces']} artifact")
            shown = out.view(png) if png else None
            if shown:
                parts.append(figure(shown, Path(name).stem.removeprefix("artifact-"),
                                     "artifact"))
    if not parts:
        return ""
    jobs = sum(evaluated(r) for r in records)
    return (f"<details class='sheets'><summary>Image sheets of {jobs} results: the "
            "original's views once, then each result's renders and |ΔY| difference images"
            f"</summary>{''.join(parts)}</details>")


def sheet_images(run_dir: Path, record: dict, refused: list[str], out) -> list[dict]:
    """A job's sheet views as shown (``original``, ``result``, ``difference``: a
    :class:`Shown` or None each) with the view's ``d_rms`` (None when the record has
    none), in :data:`~bench.run.jobs.SHEET_VIEWS` order (every view of a smaller
    view set, ``Protocol.views``); ``view`` is the view's index."""
    from bench.run.jobs import sheet_views
    from metrics.views import VIEW_SET_SIZES

    key, original = _image_folders(run_dir, record)
    d_views = (record.get("per_view") or {}).get("d_rms") or []
    views = []
    view_set = record["job"]["protocol"].get("views", "rhombicuboctahedron")
    for v in sheet_views(VIEW_SET_SIZES.get(view_set, 24)):
        o = run_png(run_dir, f"{original}/view{v:02d}.png", refused) if original else None
        s = run_png(run_dir, f"images/{key}/view{v:02d}.png", refused)
        diff = difference_png(o, s)
        d = d_views[v] if v < len(d_views) and isinstance(d_views[v], numbers.Real) else None
        views.append({"view": v, "original": out.view(o) if o else None,
                      "result": out.view(s) if s else None,
                      "difference": out.difference(diff, s) if diff else None,
                      "d_rms": None if d is None else float(d)})
    return views


def _sheet_figures(record: dict, views: list[dict]) -> list[str]:
    """A job's sheet from its :func:`sheet_images`: the result's views and their
    differences from the original's, one grid row each (the original's own views are
    shown once per model and shading, :func:`_original_figures`)."""
    faces = f"{record['metrics'].get('faces')} faces"
    rows = [[(f"{faces}, view {c['view']}", c["result"]) for c in views],
            [(f"|ΔY|×4, d_RMS {_fixed(c['d_rms'], 1)}" if c["d_rms"] is not None
              else "|ΔY|×4", c["difference"]) for c in views]]
    return [figure(shown, caption) for row in rows for caption, shown in row if shown]


def _original_figures(views: list[dict]) -> list[str]:
    return [figure(c["original"], f"original, view {c['view']}") for c in views
            if c["original"]]


def _image_folders(run_dir: Path, record: dict) -> tuple[str, str | None]:
    """The job key the record's views are filed under (an older run's where the record
    has no key) and the folder of its original's views (None without a model hash)."""
    from bench.run.jobs import Job
    from bench.run.keys import legacy_job_key
    from metrics.protocol import Protocol

    job = record["job"]
    proto = Protocol(**job["protocol"])
    key = job.get("key") or Job(job["model"], job["method"], job["target_faces"],
                                job.get("params") or {}, proto).key
    if not job.get("key") and not (run_dir / "images" / key).is_dir():  # an older run
        key = legacy_job_key(job["model"], job["label"], job["target_faces"], proto)
    digest = record["model"].get("hash")
    shading = shading_label(job["protocol"])
    return key, f"images/original__{digest[:12]}__{shading}" if digest else None


def _timing(records: list[dict]) -> str:
    rows = []
    several = len(_shadings(records)) > 1  # then each shading's job simplified on its own
    for r in records:
        if not evaluated(r):
            continue
        s = r.get("stats") or {}
        label = r["job"]["label"] + (f" ({shading_label(r['job']['protocol'])} job)"
                                     if several else "")
        rows.append(f"<tr><td>{model_cell(r['job']['model'])}</td><td>{_esc(label)}</td>"
                    f"<td>{_cell(r['model'].get('faces'))}</td>"
                    f"<td>{_cell(r['metrics'].get('faces'))}</td>"
                    f"{_timing_cells(r, s, records)}{_outside_cell(r)}</tr>")
    return ("<p class='note'>cf. Table 1 of Lindstrom & Turk 2000.</p><table class='sortable'>"
            f"<thead>{_TIMING_HEAD}</thead><tbody>{''.join(rows)}</tbody></table>")


def _timing_cells(record: dict, stats: dict, records: list[dict]) -> str:
    """Seconds, triangles removed per second and peak MB of a job; a job that reused
    another's build says so, and its rate (of a time without the build) is left out."""
    note = reuse_note(record, records)
    if note:
        return (f"<td title='{_esc(note)}'>{_cell(stats.get('wall_seconds'))} "
                "<span class='reused'>reused build</span></td><td>—</td>"
                f"<td>{number('peak_mb', stats.get('peak_mb'))}</td>")
    return (f"<td>{_cell(stats.get('wall_seconds'))}</td><td>{_cell(stats.get('tri_per_s'))}"
            f"</td><td>{number('peak_mb', stats.get('peak_mb'))}</td>")


def _outside_cell(record: dict) -> str:
    """The job's time outside its method (load, warm-up, the evaluation, the report's
    files), each stage on hover; empty for a record without ``timings``."""
    t = record.get("timings")
    if not isinstance(t, dict) or not isinstance(t.get("total"), (int, float)):
        return "<td></td>"
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in t.items()
                       if k not in ("total", "method") and isinstance(v, (int, float)))
    outside = t["total"] - (t.get("method") or 0.0)
    return f"<td title='{_esc(stages)}'>{outside:.2f}</td>"


_TIMING_HEAD = ("<tr><th>model</th><th>method</th><th>faces before</th><th>faces after</th>"
                "<th>seconds</th><th>triangles removed / s</th><th>peak MB</th>"
                "<th title='load, warm-up, evaluation and the report files of the job'>"
                "seconds outside the method</th></tr>")


def _claims_html(records: list[dict]) -> str:
    """The papers' claims that this run's records decide (those with rows), each with its
    verdict and the class of its test, as ``bench reproduce`` decides them."""
    from bench.records.claims import evaluate_claim
    from bench.records.suites import SUITES

    decided = []
    for suite in SUITES.values():
        for claim in suite.claims:
            result = evaluate_claim(claim, records)
            if result.rows:
                decided.append(result)
    if not decided:
        return ""
    rows = "".join(
        f"<tr><td>{_esc(r.claim.name)}</td><td>{_esc(r.claim.source)}</td>"
        f"<td>{_esc(r.claim.statement)}</td><td>{_esc(r.summary)}</td>"
        f"<td class='{_VERDICT_CLASS.get(r.verdict, '')}'>{_esc(r.verdict)}</td>"
        f"<td>{_esc(r.klass or '')}</td><td>{'' if r.p is None else f'{r.p:.3g}'}</td></tr>"
        for r in decided)
    return ("<h2>Claims this run decides</h2><p class='note'>The papers' claims whose "
            "models, methods and budgets this run holds, decided from its records as "
            "<code>bench reproduce</code> decides them (the class says whether the "
            "difference is significant over the views; p after Holm's correction). The "
            "suite a claim belongs to may hold more rows than this run.</p>"
            "<div class='scroll'><table class='claims'><thead><tr><th>claim</th>"
            "<th>source</th><th>statement</th><th>ours</th><th>verdict</th><th>class</th>"
            f"<th>p</th></tr></thead><tbody>{rows}</tbody></table></div>")


_VERDICT_CLASS = {"holds": "best", "holds, weaker": "", "mixed": "skipped",
                  "does not hold": "failed", "no data": "skipped"}


def _not_applicable(records: list[dict]) -> str:
    """Jobs a method did not run because it does not apply (``skipped``: e.g. a texture
    method on a model without texture coordinates), one line each: not failures."""
    skipped = [r for r in records if r["status"] == "skipped"]
    if not skipped:
        return "<p>None.</p>"
    items = "".join(f"<li>{_job_title(r)}: {_esc(_first_line(r.get('error')))}</li>"
                    for r in skipped)
    return f"<ul class='not-applicable'>{items}</ul>"


def _first_line(text) -> str:
    lines = [line for line in str(text or "").splitlines() if line.strip()]
    return lines[0].strip() if lines else "(no reason given)"


def _failures(records: list[dict]) -> str:
    """Failed jobs with their errors, results off their target with the reason the
    method gave, then metrics that raised in evaluated jobs (whose other figures
    stand). Jobs that do not apply are under "Not applicable"."""
    bad = [r for r in records if r["status"] == "failed"]
    off = [r for r in records if r["status"] == OFF_TARGET_STATUS]
    partial = [r for r in records if evaluated(r) and r.get("metric_errors")]
    if not bad and not partial and not off:
        return "<p>None.</p>"
    out = [f"<h3 class='{_esc(r['status'])}'>{_job_title(r)}: {_esc(r['status'])}</h3>"
           f"<pre>{_esc(r.get('error'))}</pre>" for r in bad]
    out += [f"<h3 class='off-target'>{_job_title(r)}: off target, "
            f"{_esc((r.get('metrics') or {}).get('faces'))} faces</h3>"
            f"<pre>{_esc(r.get('stop_reason') or 'the method gave no reason')}</pre>"
            for r in off]
    out += [f"<h3>{_job_title(r)}: metric {_esc(name)} failed</h3>"
            f"<pre>{_esc(error)}</pre>"
            for r in partial for name, error in r["metric_errors"].items()]
    return "".join(out)


def _job_title(record: dict) -> str:
    job = record["job"]
    return f"{model_cell(job['model'])} / {_esc(job['label'])} / {_esc(job['target_faces'])}"
