"""The self-contained HTML report of a run directory (``DIR/index.html``).

Everything is inlined (plots and images as base64 PNG), so the file opens from disk
with no network. Sections follow Lindstrom & Turk 2000: a summary table, per model the
d_RMS and Hausdorff curves over face count (Figures 5 and 6), silhouette histograms
(Figure 7), image sheets with difference images (Plate 13), a timing table (Table 1),
and the failures with their errors.

A run folder may come from someone else, so nothing in it is trusted: every string from
a record is HTML-escaped where it is written, only records that pass
:func:`~bench.harness.results.record_problem` are shown, and images are read only from
inside the run folder and only when they are PNG files (:func:`_run_png`). What is left
out for any of these reasons is listed under "Warnings" at the top of the report and
given as a :class:`~bench.errors.RecordWarning`.
"""

from __future__ import annotations

import base64
import html
import io
import math
import numbers
import warnings
from pathlib import Path

import numpy as np

from bench.errors import RecordWarning
from bench.harness.results import load_records, records_table, shading_label, write_atomic

__all__ = ["write_report"]

_CSS = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1400px;color:#222}
h1{font-size:1.5em}h2{margin-top:2em;border-bottom:1px solid #ccc}
table{border-collapse:collapse;font-size:.85em;margin:1em 0}
td,th{border:1px solid #ddd;padding:3px 7px;text-align:right;white-space:nowrap}
th{background:#f3f3f3}td:first-child,td:nth-child(2){text-align:left}
.failed{background:#fde2e2}.skipped{color:#888}
.sheet{display:grid;grid-template-columns:repeat(4,164px);gap:4px;margin:.5em 0 1.5em}
.scroll{overflow-x:auto}
.sheet figure{margin:0;text-align:center;font-size:.75em}
.sheet img{width:160px;height:160px;image-rendering:pixelated}
.plots img{max-width:48%}
.artifact img{max-width:512px;image-rendering:pixelated}.artifact{margin:0 0 1.5em}
pre{background:#f7f7f7;padding:.5em;white-space:pre-wrap;font-size:.8em}
.note{color:#555;font-size:.9em}.warnings{background:#fff4d6;padding:.3em 1em}
"""

#: The first bytes of every PNG file.
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Largest image inlined (a sheet view is well under 1 MB, a 1024² artifact a few MB).
_MAX_IMAGE_BYTES = 32 << 20


def write_report(run_dir: Path, records: list[dict] | None = None,
                 skipped: list[str] | tuple = ()) -> Path:
    """Build ``run_dir/index.html`` (atomically) from the records found there.

    ``skipped`` lists the one-line reasons of records the caller left out (they are
    shown under "Warnings"); with ``records`` None the records are loaded here, bad ones
    left out with a warning each.
    """
    run_dir = Path(run_dir)
    notes = list(skipped)
    if records is None:
        before = len(notes)
        records = load_records(run_dir, skipped=notes)
        for note in notes[before:]:
            warnings.warn(note, RecordWarning, stacklevel=2)
    table = records_table(records)
    body = [_protocol_note(records), "<h2>Summary</h2>",
            _table_html(table.drop(columns=[c for c in _OPTIONAL_COLUMNS
                                            if table[c].isna().all()]))]
    refused = []  # images left out of the sheets, with why
    for model in dict.fromkeys(table.model):
        sub = [r for r in records if r["job"]["model"] == model]
        body.append(f"<h2>{_esc(model)}</h2>")
        body.append(_plots(table[(table.model == model) & (table.status == "ok")]))
        body.append(_exterior_table(table[(table.model == model) & (table.status == "ok")]))
        body.append(_silhouette_plot(sub))
        body.append(_sheets(run_dir, sub, refused))
    for note in refused:
        warnings.warn(note, RecordWarning, stacklevel=2)
    body += ["<h2>Timing</h2>", _timing(records), "<h2>Failures</h2>", _failures(records)]
    parts = [(f"<!doctype html><html><head><meta charset='utf-8'><title>bench report: "
              f"{_esc(run_dir.name)}</title><style>{_CSS}</style></head><body>"),
             f"<h1>Simplification benchmark: {_esc(run_dir.name)}</h1>",
             _warnings_html(notes + refused), *body, "</body></html>"]
    return write_atomic(run_dir / "index.html", "\n".join(parts))


def _esc(value) -> str:
    """Any value from a record as HTML text (quotes escaped too, for attributes)."""
    return html.escape(str(value), quote=True)


def _warnings_html(notes: list[str]) -> str:
    if not notes:
        return ""
    items = "".join(f"<li>{_esc(n)}</li>" for n in notes)
    return (f"<div class='warnings'><h2>Warnings</h2><p>Left out of this report:</p>"
            f"<ul>{items}</ul></div>")


#: Summary-table columns left out when no record of the run defines them.
_OPTIONAL_COLUMNS = ("exterior_share",)


def _shadings(records: list[dict]) -> list[str]:
    """The distinct evaluation shadings of ``records`` (``flat``, ``gouraud-spec``, ...)."""
    return list(dict.fromkeys(shading_label(r["job"]["protocol"]) for r in records))


def _protocol_note(records: list[dict]) -> str:
    ok = [r for r in records if r["status"] == "ok"]
    if not ok:
        return "<p class='note'>No successful jobs.</p>"
    p = ok[0]["job"]["protocol"]
    env = _dict(ok[0].get("environment"))
    labels = _shadings(ok)
    shadings = " and ".join(s.replace("-spec", " + specular") for s in labels)
    if len(labels) > 1:
        shadings += " shading (each result evaluated under each; the shading column says which)"
    else:
        shadings += " shading"
    return (f"<p class='note'>Protocol v{_esc(p['version'])}: 24 small-rhombicuboctahedron "
            f"views at {p['resolution']}² with {p['msaa']}× MSAA, {_esc(shadings)}, 50% gray "
            f"background, headlight; "
            f"Hausdorff with {p['hausdorff_samples']:,} samples each way, as fractions of the "
            f"original's bounding-box diagonal; FLIP on {_esc(p['flip_views'])} views; "
            f"silhouettes over the 20 dodecahedron views. "
            f"Commit {_esc(str(env.get('git_commit'))[:12])}, "
            f"{_esc(_dict(env.get('machine')).get('processor'))}.</p>")


def _dict(value) -> dict:
    """``value`` if it is a dict, else an empty one (for optional, unchecked parts)."""
    return value if isinstance(value, dict) else {}


def _table_html(table) -> str:
    rows = []
    for _, r in table.iterrows():
        cls = f" class='{_esc(r.status)}'" if r.status != "ok" else ""
        cells = "".join(f"<td>{_cell(v)}</td>" for v in r.values)
        rows.append(f"<tr{cls}>{cells}</tr>")
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table.columns)
    return f"<div class='scroll'><table><tr>{head}</tr>{''.join(rows)}</table></div>"


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.4g}"
    return _esc(value)


def _fixed(value, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals; a dash when missing (a metric that raised) or
    not a number."""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        return "—"
    return f"{value:.{digits}f}"


def _plot_text(text: str) -> str:
    """Record text for a matplotlib label: ``$`` would start mathtext (and a malformed
    formula aborts the whole figure), so it is escaped."""
    return str(text).replace("$", r"\$")


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _pyplot():
    """matplotlib's pyplot on the file-only backend, imported only for a report that
    draws (a run of failures alone draws nothing and skips the import)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plots(table) -> str:
    import pandas as pd

    if table.empty:
        return ""
    plt = _pyplot()
    # One curve per method, and per evaluation shading when a run has several.
    series = table.method if table.shading.nunique() == 1 else \
        table.method + " (" + table.shading + ")"
    series = series.map(_plot_text)
    out = []
    for column, title in (("d_rms", "d_RMS (luminance, 0-255) vs faces — cf. Figure 5"),
                          ("hausdorff_mean", "mean Hausdorff (fraction of diagonal) vs faces — cf. Figure 6")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for method, group in table.groupby(series):
            # log axes: a value that is not finite and positive has no place on them
            # (an infinite face count would abort the figure)
            x, y = (pd.to_numeric(group[c], errors="coerce") for c in ("faces", column))
            keep = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
            if keep.any():
                g = group[keep].sort_values("faces")
                ax.plot(g.faces.astype(float), g[column].astype(float), marker="o", label=method)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("faces")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=.3)
        out.append(f"<img alt='{column} plot' src='{_png(fig)}'>")
    return "<div class='plots'>" + "".join(out) + "</div>"


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


def _silhouette_plot(records: list[dict]) -> str:
    ok = [r for r in records if r["status"] == "ok" and r.get("silhouette_histogram")]
    if not ok:
        return ""
    plt = _pyplot()
    smallest = min(r["job"]["target_faces"] for r in ok)
    # Silhouettes do not depend on the evaluation shading: one bar set per method variant.
    first = {}
    for r in ok:
        if r["job"]["target_faces"] == smallest:
            first.setdefault(r["job"]["label"], r)
    chosen = list(first.values())
    fig, ax = plt.subplots(figsize=(7, 3.5))
    width = 0.8 / len(chosen)
    for k, r in enumerate(chosen):
        hist = np.asarray(r["silhouette_histogram"])
        mean = _fixed(r["metrics"].get("silhouette_mean"), 2)
        ax.bar(np.arange(len(hist)) + k * width, hist, width,
               label=_plot_text(f"{r['job']['label']} ⟨x⟩={mean}"))
    ax.set_xlabel("number of views in which an edge is a silhouette")
    ax.set_ylabel("share of edges")
    ax.set_title(f"Silhouette histograms at {smallest} faces — cf. Figure 7", fontsize=9)
    ax.legend(fontsize=7)
    return f"<div class='plots'><img alt='silhouette histograms' src='{_png(fig)}'></div>"


def _run_png(run_dir: Path, relative, refused: list[str] | None = None,
             what: str = "") -> bytes | None:
    """The bytes of the PNG file ``run_dir/relative``, or None.

    Refused (None, and a reason appended to ``refused`` when given): a name that is not
    a relative string, a path that leaves the run folder (``..``, an absolute path, a
    link to elsewhere), a name without ``.png``, a file that does not start with the PNG
    signature or is over :data:`_MAX_IMAGE_BYTES`. A file that is simply absent is None
    (and a reason only for ``what``-named images a record promised).
    """
    def refuse(why: str) -> None:
        if refused is not None:
            refused.append(f"{what or 'image'} {str(relative)!r}: {why}; not shown")

    if not isinstance(relative, (str, Path)) or not str(relative):
        refuse("not a file name")
        return None
    path = run_dir / relative
    root = run_dir.resolve()
    try:
        resolved = path.resolve()
    except (OSError, RuntimeError):  # RuntimeError: a symlink loop
        refuse("cannot be resolved")
        return None
    if Path(relative).is_absolute() or not resolved.is_relative_to(root):
        refuse("outside the run folder")
        return None
    if resolved.suffix.lower() != ".png":
        refuse("not a .png file")
        return None
    try:
        if not resolved.is_file():
            if what:
                refuse("no such file in the run folder")
            return None
        if resolved.stat().st_size > _MAX_IMAGE_BYTES:
            refuse(f"larger than {_MAX_IMAGE_BYTES >> 20} MB")
            return None
        data = resolved.read_bytes()
    except OSError as exc:
        refuse(f"unreadable ({exc.strerror or exc})")
        return None
    if not data.startswith(_PNG_SIGNATURE):
        refuse("not a PNG file")
        return None
    return data


def _data_uri(data: bytes | None) -> str | None:
    return None if data is None else "data:image/png;base64," + base64.b64encode(data).decode()


def _difference_uri(original: bytes | None, simplified: bytes | None) -> str | None:
    """|ΔY| scaled ×4 and inverted (white = equal), as in Plate 13's difference images;
    None when either image is missing or the two cannot be compared."""
    from PIL import Image

    if original is None or simplified is None:
        return None
    from metrics.image import luminance

    try:
        a = luminance(np.asarray(Image.open(io.BytesIO(original)).convert("RGB")))
        b = luminance(np.asarray(Image.open(io.BytesIO(simplified)).convert("RGB")))
        diff = (255 - np.clip(4 * np.abs(a - b), 0, 255)).astype(np.uint8)
    except (OSError, ValueError, Image.DecompressionBombError):  # damaged, or sizes differ
        return None
    buf = io.BytesIO()
    Image.fromarray(diff).save(buf, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _sheets(run_dir: Path, records: list[dict], refused: list[str]) -> str:
    """The image sheets of ``records``' ok jobs and their artifacts; images that cannot
    be shown safely are left out with a reason in ``refused``."""
    from bench.harness.keys import legacy_job_key
    from bench.harness.jobs import SHEET_VIEWS, Job
    from metrics.protocol import Protocol

    several = len(_shadings(records)) > 1
    out = []
    for r in records:
        if r["status"] != "ok":
            continue
        job = r["job"]
        proto = Protocol(**job["protocol"])
        key = job.get("key") or Job(job["model"], job["method"], job["target_faces"],
                                    job.get("params") or {}, proto).key
        if not job.get("key") and not (run_dir / "images" / key).is_dir():  # an older run
            key = legacy_job_key(job["model"], job["label"], job["target_faces"], proto)
        shading = proto.shading + ("-spec" if proto.specular else "")
        digest = r["model"].get("hash")
        orig_dir = f"images/original__{digest[:12]}__{shading}" if digest else None
        rows = {"original": [], "result": [], "difference": []}  # one grid row each
        d_views = (r.get("per_view") or {}).get("d_rms") or []
        for v in SHEET_VIEWS:
            o = _run_png(run_dir, f"{orig_dir}/view{v:02d}.png", refused) if orig_dir else None
            s = _run_png(run_dir, f"images/{key}/view{v:02d}.png", refused)
            rows["original"].append((f"original, view {v}", _data_uri(o)))
            rows["result"].append((f"{r['metrics'].get('faces')} faces", _data_uri(s)))
            rows["difference"].append((f"|ΔY|×4, d_RMS {_fixed(d_views[v], 1)}"
                                       if v < len(d_views) else "|ΔY|×4", _difference_uri(o, s)))
        figs = [f"<figure><img src='{uri}' alt='{_esc(caption)}'>"
                f"<figcaption>{_esc(caption)}</figcaption></figure>"
                for row in rows.values() for caption, uri in row if uri]
        evaluated = f", evaluated {_esc(shading)}" if several else ""
        out.append(f"<h3>{_esc(job['label'])} at {job['target_faces']} faces{evaluated}: "
                   f"d_RMS {_fixed(r['metrics'].get('d_rms'))}</h3><div class='sheet'>{''.join(figs)}</div>")
        for name in r.get("artifacts") or []:  # images the method asked to show
            uri = _data_uri(_run_png(run_dir, name, refused,
                                     what=f"{job['label']} / {job['target_faces']} artifact"))
            if uri:
                caption = Path(name).stem.removeprefix("artifact-")
                out.append(f"<figure class='artifact'><img src='{uri}' alt='{_esc(caption)}'>"
                           f"<figcaption>{_esc(caption)}</figcaption></figure>")
    return "".join(out)


def _timing(records: list[dict]) -> str:
    rows = [("<tr><th>model</th><th>method</th><th>faces before</th><th>faces after</th>"
             "<th>seconds</th><th>triangles removed / s</th><th>peak MB</th></tr>")]
    several = len(_shadings(records)) > 1  # then each shading's job simplified on its own
    for r in records:
        if r["status"] != "ok":
            continue
        s = r.get("stats") or {}
        label = r["job"]["label"] + (f" ({shading_label(r['job']['protocol'])} job)"
                                     if several else "")
        rows.append(f"<tr><td>{_esc(r['job']['model'])}</td><td>{_esc(label)}</td>"
                    f"<td>{_cell(r['model'].get('faces'))}</td>"
                    f"<td>{_cell(r['metrics'].get('faces'))}</td>"
                    f"<td>{_cell(s.get('wall_seconds'))}</td><td>{_cell(s.get('tri_per_s'))}</td>"
                    f"<td>{_cell(s.get('peak_mb'))}</td></tr>")
    return "<p class='note'>cf. Table 1 of Lindstrom & Turk 2000.</p><table>" + "".join(rows) + "</table>"


def _failures(records: list[dict]) -> str:
    """Failed and skipped jobs with their errors, then metrics that raised in ok jobs
    (whose other figures stand)."""
    bad = [r for r in records if r["status"] != "ok"]
    partial = [r for r in records if r["status"] == "ok" and r.get("metric_errors")]
    if not bad and not partial:
        return "<p>None.</p>"
    out = [f"<h3 class='{_esc(r['status'])}'>{_job_title(r)}: {_esc(r['status'])}</h3>"
           f"<pre>{_esc(r.get('error'))}</pre>" for r in bad]
    out += [f"<h3>{_job_title(r)}: metric {_esc(name)} failed</h3>"
            f"<pre>{_esc(error)}</pre>"
            for r in partial for name, error in r["metric_errors"].items()]
    return "".join(out)


def _job_title(record: dict) -> str:
    job = record["job"]
    return f"{_esc(job['model'])} / {_esc(job['label'])} / {_esc(job['target_faces'])}"
