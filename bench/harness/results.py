"""Result records: one JSON file per (model, method variant, budget, protocol).

Schema (``schema`` = :data:`SCHEMA_VERSION`)::

    {"schema": 1, "status": "ok" | "failed" | "skipped", "error": str | null,
     "job": {"model", "method", "params", "label", "target_faces", "protocol": {...}},
     "model": {"name", "hash", "faces", "render_vertices", "welded_vertices"},
     "method": {"name", "version", "view_dependent"},
     "metrics": {...}, "per_view": {...}, "silhouette_histogram": [...],
     "metric_errors": {name: error} (only when a metric raised; its value is missing),
     "stats": {...}, "seconds": {...}, "stop_reason": str | null,
     "environment": {"versions", "git_commit", "machine",
                     "worker": {"executor": "local" | "dask", "name", "host",
                                "address" and "attempts" (Dask)}},
     "created": ISO time}

Records are written atomically (temporary file + rename), so an interrupted run leaves
only complete records and ``--resume`` can trust what it finds. A job's images are
written (atomically too) before its record, so a record also means its images exist.
A record of a newer schema is refused; older ones would be migrated by
:func:`load_record`.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from bench.errors import InputError

__all__ = ["CSV_COLUMNS", "SCHEMA_VERSION", "load_record", "load_records", "metric_columns",
           "records_table", "shading_label", "write_file", "write_record", "write_table"]

SCHEMA_VERSION = 1

#: The leading columns of results.csv, in order (DESIGN "Results"; issue "runner").
#: ``shading`` is the evaluation shading (:func:`shading_label`); ``exterior_share`` is
#: empty for models that do not classify their faces (:mod:`metrics.interior`). Every
#: other registered metric that some record has follows ``status``, by name
#: (:func:`metric_columns`); a cell is empty where a record lacks the metric.
CSV_COLUMNS = ["model", "method", "shading", "target_faces", "faces", "d_rms", "ssim", "flip",
               "hausdorff_mean", "hausdorff_max", "silhouette_mean", "boundary_edges",
               "seam_cracks", "exterior_share", "seconds", "tri_per_s", "peak_mb", "status"]


def shading_label(protocol: dict) -> str:
    """The evaluation shading of a record's protocol: ``flat``, ``gouraud``, or either
    with ``-spec`` when specular highlights were on (as in record file names)."""
    return protocol["shading"] + ("-spec" if protocol.get("specular") else "")


def write_record(path: Path, record: dict, sort_keys: bool = True) -> Path:
    """Write ``record`` as JSON to ``path`` atomically (NumPy values as plain numbers).

    Keys are sorted unless ``sort_keys`` is false, for files read by people in the
    order they were built (the LOD sidecar of ``bench simplify``).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(record, f, indent=1, sort_keys=sort_keys, default=_jsonable)
    os.replace(tmp, path)
    return path


def write_file(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder + rename),
    so a reader never sees half a file, whoever else writes the same path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
    return path


def _jsonable(value):
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def load_record(path: Path) -> dict:
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a readable result record ({exc})") from None
    schema = record.get("schema")
    if not isinstance(schema, int) or schema > SCHEMA_VERSION:
        raise InputError(f"{path}: result schema {schema!r} is newer than this bench "
                         f"understands ({SCHEMA_VERSION}); upgrade bench")
    return record


def load_records(run_dir: Path) -> list[dict]:
    """All records under ``run_dir/records``, sorted by model, method, budget."""
    folder = Path(run_dir) / "records"
    if not folder.is_dir():
        raise InputError(f"{run_dir}: not a run directory (no records/ inside); "
                         "create one with bench run --out DIR")
    records = [load_record(p) for p in sorted(folder.glob("*.json"))]
    return sorted(records, key=lambda r: (r["job"]["model"], r["job"]["label"],
                                          -r["job"]["target_faces"],
                                          shading_label(r["job"]["protocol"])))


def metric_columns(records: list[dict]) -> list[str]:
    """Registered metrics outside :data:`CSV_COLUMNS` that some record has, by name:
    the columns results.csv and the report add after ``status``."""
    from bench.registry import registry

    found = set().union(*((r.get("metrics") or {}).keys() for r in records))
    return [name for name in registry("metric").names()
            if name in found and name not in CSV_COLUMNS]


def records_table(records: list[dict]):
    """A pandas DataFrame with :data:`CSV_COLUMNS` and then :func:`metric_columns`
    (one row per record)."""
    import pandas as pd

    extra = metric_columns(records)
    rows = []
    for r in records:
        m, job, stats = r.get("metrics") or {}, r["job"], r.get("stats") or {}
        rows.append({
            "model": job["model"], "method": job["label"],
            "shading": shading_label(job["protocol"]), "target_faces": job["target_faces"],
            "faces": m.get("faces"), "d_rms": m.get("d_rms"), "ssim": m.get("ssim"),
            "flip": m.get("flip"), "hausdorff_mean": m.get("hausdorff_mean"),
            "hausdorff_max": m.get("hausdorff_max"), "silhouette_mean": m.get("silhouette_mean"),
            "boundary_edges": m.get("boundary_edges"), "seam_cracks": m.get("seam_cracks"),
            "exterior_share": m.get("exterior_share"), "seconds": stats.get("wall_seconds"),
            "tri_per_s": stats.get("tri_per_s"), "peak_mb": stats.get("peak_mb"), "status": r["status"],
            **{name: m.get(name) for name in extra},
        })
    return pd.DataFrame(rows, columns=CSV_COLUMNS + extra)


def write_table(run_dir: Path, records: list[dict]) -> Path:
    path = Path(run_dir) / "results.csv"
    records_table(records).to_csv(path, index=False, float_format="%.6g")
    return path
