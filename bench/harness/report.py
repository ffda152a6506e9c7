"""The self-contained HTML report of a run directory (``DIR/index.html``).

Everything is inlined (plots and images as base64 PNG), so the file opens from disk
with no network. Sections follow Lindstrom & Turk 2000: a summary table, per model the
d_RMS and Hausdorff curves over face count (Figures 5 and 6), silhouette histograms
(Figure 7), image sheets with difference images (Plate 13), a timing table (Table 1),
and the failures with their errors.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

from bench.harness.results import load_records, records_table, shading_label

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
.note{color:#555;font-size:.9em}
"""


def write_report(run_dir: Path, records: list[dict] | None = None) -> Path:
    """Build ``run_dir/index.html`` from the records found there."""
    run_dir = Path(run_dir)
    records = load_records(run_dir) if records is None else records
    table = records_table(records)
    parts = [f"<!doctype html><html><head><meta charset='utf-8'><title>bench report: "
             f"{html.escape(run_dir.name)}</title><style>{_CSS}</style></head><body>",
             f"<h1>Simplification benchmark: {html.escape(run_dir.name)}</h1>",
             _protocol_note(records), "<h2>Summary</h2>",
             _table_html(table.drop(columns=[c for c in _OPTIONAL_COLUMNS
                                             if table[c].isna().all()]))]
    for model in dict.fromkeys(table.model):
        sub = [r for r in records if r["job"]["model"] == model]
        parts.append(f"<h2>{html.escape(model)}</h2>")
        parts.append(_plots(table[(table.model == model) & (table.status == "ok")]))
        parts.append(_exterior_table(table[(table.model == model) & (table.status == "ok")]))
        parts.append(_silhouette_plot(sub))
        parts.append(_sheets(run_dir, sub))
    parts += ["<h2>Timing</h2>", _timing(records), "<h2>Failures</h2>", _failures(records),
              "</body></html>"]
    path = run_dir / "index.html"
    path.write_text("\n".join(parts))
    return path


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
    env = ok[0].get("environment", {})
    labels = _shadings(ok)
    shadings = " and ".join(s.replace("-spec", " + specular") for s in labels)
    if len(labels) > 1:
        shadings += " shading (each result evaluated under each; the shading column says which)"
    else:
        shadings += " shading"
    return (f"<p class='note'>Protocol v{p['version']}: 24 small-rhombicuboctahedron views at "
            f"{p['resolution']}² with {p['msaa']}× MSAA, {shadings}, 50% gray background, "
            f"headlight; "
            f"Hausdorff with {p['hausdorff_samples']:,} samples each way, as fractions of the "
            f"original's bounding-box diagonal; FLIP on {p['flip_views']} views; silhouettes "
            f"over the 20 dodecahedron views. Commit {html.escape(str(env.get('git_commit')))[:12]}, "
            f"{html.escape(str(env.get('machine', {}).get('processor')))}.</p>")


def _table_html(table) -> str:
    rows = []
    for _, r in table.iterrows():
        cls = f" class='{r.status}'" if r.status != "ok" else ""
        cells = "".join(f"<td>{_cell(v)}</td>" for v in r.values)
        rows.append(f"<tr{cls}>{cells}</tr>")
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table.columns)
    return f"<div class='scroll'><table><tr>{head}</tr>{''.join(rows)}</table></div>"


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    if isinstance(value, float):
        return f"{value:.4g}"
    return html.escape(str(value))


def _fixed(value) -> str:
    """``value`` with three decimals; a dash when missing (a metric that raised)."""
    return "—" if value is None else f"{value:.3f}"


def _png(fig) -> str:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _plots(table) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if table.empty:
        return ""
    # One curve per method, and per evaluation shading when a run has several.
    series = table.method if table.shading.nunique() == 1 else \
        table.method + " (" + table.shading + ")"
    out = []
    for column, title in (("d_rms", "d_RMS (luminance, 0-255) vs faces — cf. Figure 5"),
                          ("hausdorff_mean", "mean Hausdorff (fraction of diagonal) vs faces — cf. Figure 6")):
        fig, ax = plt.subplots(figsize=(6, 4))
        for method, group in table.groupby(series):
            g = group.sort_values("faces")
            ax.plot(g.faces, g[column], marker="o", label=method)
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
        f"<tr><td>{html.escape(r.method)}</td><td>{r.target_faces}</td><td>{_cell(r.faces)}</td>"
        f"<td>{_cell(round(r.faces * r.exterior_share))}</td><td>{r.exterior_share:.1%}</td></tr>"
        for r in table.itertuples())
    return ("<h3>Faces on the exterior — cf. §5.2, Plates 2-3</h3><p class='note'>A face is "
            "exterior when its centroid lies outside the sphere the model's metadata gives "
            "(<code>metrics.interior</code>); the others belong to the hidden interior."
            "</p><table><tr><th>method</th><th>target</th>"
            "<th>faces</th><th>exterior faces</th><th>exterior share</th></tr>"
            f"{rows}</table>")


def _silhouette_plot(records: list[dict]) -> str:
    import matplotlib.pyplot as plt

    ok = [r for r in records if r["status"] == "ok" and r.get("silhouette_histogram")]
    if not ok:
        return ""
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
        ax.bar(np.arange(len(hist)) + k * width, hist, width,
               label=f"{r['job']['label']} ⟨x⟩={r['metrics']['silhouette_mean']:.2f}")
    ax.set_xlabel("number of views in which an edge is a silhouette")
    ax.set_ylabel("share of edges")
    ax.set_title(f"Silhouette histograms at {smallest} faces — cf. Figure 7", fontsize=9)
    ax.legend(fontsize=7)
    return f"<div class='plots'><img alt='silhouette histograms' src='{_png(fig)}'></div>"


def _image_uri(path: Path) -> str | None:
    if not path.exists():
        return None
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode()


def _difference_uri(original: Path, simplified: Path) -> str | None:
    """|ΔY| scaled ×4 and inverted (white = equal), as in Plate 13's difference images."""
    from PIL import Image

    if not (original.exists() and simplified.exists()):
        return None
    from metrics.image import luminance

    a = luminance(np.asarray(Image.open(original).convert("RGB")))
    b = luminance(np.asarray(Image.open(simplified).convert("RGB")))
    diff = (255 - np.clip(4 * np.abs(a - b), 0, 255)).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(diff).save(buf, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _sheets(run_dir: Path, records: list[dict]) -> str:
    from bench.harness.jobs import SHEET_VIEWS, Job
    from metrics.protocol import Protocol

    several = len(_shadings(records)) > 1
    out = []
    for r in records:
        if r["status"] != "ok":
            continue
        job = r["job"]
        proto = Protocol(**job["protocol"])
        key = Job(job["model"], job["method"], job["target_faces"], job["params"], proto).key
        shading = proto.shading + ("-spec" if proto.specular else "")
        orig_dir = run_dir / "images" / f"original__{r['model']['hash'][:12]}__{shading}"
        rows = {"original": [], "result": [], "difference": []}  # one grid row each
        for v in SHEET_VIEWS:
            o, s = orig_dir / f"view{v:02d}.png", run_dir / "images" / key / f"view{v:02d}.png"
            rows["original"].append((f"original, view {v}", _image_uri(o)))
            rows["result"].append((f"{r['metrics'].get('faces')} faces", _image_uri(s)))
            d_views = r.get("per_view", {}).get("d_rms")
            rows["difference"].append((f"|ΔY|×4, d_RMS {d_views[v]:.1f}" if d_views else
                                       "|ΔY|×4", _difference_uri(o, s)))
        figs = [f"<figure><img src='{uri}' alt='{html.escape(caption)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>"
                for row in rows.values() for caption, uri in row if uri]
        evaluated = f", evaluated {shading}" if several else ""
        out.append(f"<h3>{html.escape(job['label'])} at {job['target_faces']} faces{evaluated}: "
                   f"d_RMS {_fixed(r['metrics'].get('d_rms'))}</h3><div class='sheet'>{''.join(figs)}</div>")
        for name in r.get("artifacts") or []:  # images the method asked to show
            uri = _image_uri(run_dir / name)
            if uri:
                caption = Path(name).stem.removeprefix("artifact-")
                out.append(f"<figure class='artifact'><img src='{uri}' alt='{html.escape(caption)}'>"
                           f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    return "".join(out)


def _timing(records: list[dict]) -> str:
    rows = ["<tr><th>model</th><th>method</th><th>faces before</th><th>faces after</th>"
            "<th>seconds</th><th>triangles removed / s</th><th>peak MB</th></tr>"]
    several = len(_shadings(records)) > 1  # then each shading's job simplified on its own
    for r in records:
        if r["status"] != "ok":
            continue
        s = r.get("stats", {})
        label = r["job"]["label"] + (f" ({shading_label(r['job']['protocol'])} job)"
                                     if several else "")
        rows.append(f"<tr><td>{html.escape(r['job']['model'])}</td><td>{html.escape(label)}"
                    f"</td><td>{r['model']['faces']}</td><td>{r['metrics']['faces']}</td>"
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
    out = [f"<h3 class='{r['status']}'>{_job_title(r)}: {r['status']}</h3>"
           f"<pre>{html.escape(str(r.get('error')))}</pre>" for r in bad]
    out += [f"<h3>{_job_title(r)}: metric {html.escape(name)} failed</h3>"
            f"<pre>{html.escape(str(error))}</pre>"
            for r in partial for name, error in r["metric_errors"].items()]
    return "".join(out)


def _job_title(record: dict) -> str:
    job = record["job"]
    return (f"{html.escape(job['model'])} / {html.escape(job['label'])} / "
            f"{job['target_faces']}")
