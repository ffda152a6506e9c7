"""Comparison grids of the report: per model, budget and evaluation shading, one table
with a row per sheet view and a column per method (the original first), each cell the
method's rendered view with its per-view d_RMS, the best of each row marked, and a
toggle that shows the |ΔY| difference images instead.

The images are the sheets' own (:func:`bench.report.page.sheet_images`), so a grid
costs no rendering and no image file of its own.
"""

from __future__ import annotations

import math

from bench.records.results import evaluated, shading_label
from bench.report import script
from bench.report.table import esc

__all__ = ["GRID_SCRIPT", "comparison_grids"]

#: The toggle: a checkbox above each grid swaps the cells' images for the differences.
GRID_SCRIPT = script("grid.js")


def _faces(record: dict) -> str:
    """The result's face count as its grid cell says it ("?" when the record has none)."""
    faces = (record.get("metrics") or {}).get("faces")
    return str(faces) if faces is not None else "?"


def _img(shown, alt: str, cls: str) -> str:
    if shown is None:
        return ""
    img = f"<img class='{cls}' src='{shown.src}' alt='{esc(alt)}' loading='lazy'>"
    return f"<a href='{shown.href}'>{img}</a>" if shown.href else img


def _grids(records: list[dict], images: dict, slug: str) -> list[tuple]:
    """(grid id, budget, shading label, records) of each grid of one model: its ok
    ``records`` with images, grouped by budget and shading, where two methods or more
    meet (with one, its sheet says it all)."""
    groups: dict[tuple, list[dict]] = {}
    for r in records:
        if evaluated(r) and id(r) in images:
            groups.setdefault((r["job"]["target_faces"], shading_label(r["job"]["protocol"])),
                              []).append(r)
    return [(f"grid-{slug}-{n}", target, shading, group)
            for n, ((target, shading), group) in enumerate(sorted(groups.items()))
            if len(group) >= 2]


def grid_links(records: list[dict], images: dict, slug: str) -> str:
    """A line linking a model's curves to its comparison grids, one link per grid."""
    links = [f"<a href='#{grid_id}'>{target} faces, {esc(shading)}</a>"
             for grid_id, target, shading, _ in _grids(records, images, slug)]
    return f"<p class='note'>Comparison grids: {' · '.join(links)}</p>" if links else ""


def comparison_grids(records: list[dict], images: dict, slug: str) -> str:
    """The grids of one model's ok ``records``; ``images`` maps ``id(record)`` to its
    :func:`~bench.report.page.sheet_images` (views in sheet order)."""
    parts = []
    for grid_id, target, shading, group in _grids(records, images, slug):
        head = "<th>view</th><th>original</th>" + "".join(
            f"<th>{esc(r['job']['label'])}</th>" for r in group)
        rows = []
        for i in range(min(len(images[id(r)]) for r in group)):
            cells = [images[id(r)][i] for r in group]
            view = cells[0]["view"]
            values = [c["d_rms"] for c in cells]
            finite = [v for v in values if v is not None and math.isfinite(v)]
            best = min(finite) if finite else None
            original = next((c["original"] for c in cells if c["original"]), None)
            row = [f"<th>{view}</th>", f"<td>{_img(original, f'original, view {view}', 'orig')}"
                   "</td>"]
            for r, c, v in zip(group, cells, values):
                mark = " class='best'" if v is not None and v == best else ""
                label = r["job"]["label"]
                row.append(f"<td{mark}>{_img(c['result'], f'{label}, view {view}', 'view')}"
                           f"{_img(c['difference'], f'{label}, |ΔY| view {view}', 'diff')}"
                           f"<br>{'' if v is None else f'd_RMS {v:.2f}, '}"
                           f"{esc(_faces(r))} faces</td>")
            rows.append("<tr>" + "".join(row) + "</tr>")
        parts.append(
            f"<h3>Comparison at {target} faces, evaluated {esc(shading)}</h3>"
            f"<label><input type='checkbox' class='diff-toggle' data-grid='{grid_id}'> "
            "show |ΔY|×4 instead of the renders</label>"
            f"<div class='scroll'><table class='grid' id='{grid_id}'><thead><tr>{head}</tr>"
            f"</thead><tbody>{''.join(rows)}</tbody></table></div>")
    return "".join(parts)
