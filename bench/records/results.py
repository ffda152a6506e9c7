"""Result records: one JSON file per (model, method variant, budget, protocol).

Schema (``schema`` = :data:`SCHEMA_VERSION`)::

    {"schema": 2, "status": "ok" | "failed" | "skipped", "error": str | null,
     "job": {"model", "method", "params", "label", "target_faces", "protocol": {...}},
     "model": {"name", "hash", "faces", "render_vertices", "welded_vertices"},
     "method": {"name", "version", "view_dependent"},
     "metrics": {...}, "per_view": {...}, "intervals": {name: [lo, hi]},
     "silhouette_histogram": [...],
     "metric_errors": {name: error} (only when a metric raised; its value is missing),
     "stats": {...}, "seconds": {...}, "timings": {...}, "stop_reason": str | null,
     "environment": {"versions", "git_commit", "machine",
                     "worker": {"executor": "local" | "dask", "name", "host",
                                "address" and "attempts" (Dask)}},
     "created": ISO time}

``timings`` says where the job's own wall time went, in seconds per stage: ``load`` (the model), ``warm_up`` (numba's cache, a method's first call
in the process), ``method``, ``reference_images`` (the original's views, rendered once
per model and protocol in a worker), ``evaluation`` (the result's renders and every
metric; ``seconds`` splits it), ``sheets`` and ``mesh_files`` (the PNGs and GLBs for the
report), and ``total``. Records written before it have none.

Records are written atomically (:func:`bench.io.atomic.write_atomic`), so an
interrupted run leaves only complete records and ``--resume`` can trust what it finds.
A job's images are written (atomically too) before its record, so a record also means
its images exist.
A record of a newer schema is refused; older ones are read as they are.

Schema 2 added ``intervals``: the 95 % bootstrap interval over the views of every metric
with per-view values (:func:`bench.records.stats.compute_intervals`), computed when the
record is written. A schema-1 record has none; whatever reads intervals asks
:func:`bench.records.stats.record_intervals`, which computes them from its ``per_view``
with the same function and seed, so old and new records report the same interval for
the same views. results.csv adds ``NAME_lo`` and ``NAME_hi`` columns after the others
for every metric that some record has an interval of (:func:`write_table`).

A run folder may come from someone else (a CI artifact, a colleague's study), so every
record is untrusted input: :func:`load_record` checks its shape and the types of the
fields the table, the gate and the report read (:func:`record_problem`) and refuses
anything else with a one-line reason, and :func:`load_records` reads only files inside
the run folder's ``records/``. ``results.csv`` is written atomically too.
"""

from __future__ import annotations

import json
import numbers
import typing
from dataclasses import fields
from pathlib import Path

from bench.core.errors import InputError
from bench.io.atomic import write_atomic
from bench.io.jsonable import json_default

__all__ = [
    "CSV_COLUMNS",
    "OFF_TARGET",
    "SCHEMA_VERSION",
    "STATUSES",
    "evaluated",
    "interval_table",
    "load_record",
    "load_records",
    "metric_columns",
    "record_problem",
    "records_table",
    "result_status",
    "shading_label",
    "write_file",
    "write_record",
    "write_table",
]

SCHEMA_VERSION = 2

#: The statuses a record can have: ``ok``, ``ok, off target`` (evaluated, but its face
#: count is more than :data:`OFF_TARGET` away from the target: compared with nothing
#: at another face count, never marked best), ``failed``, ``skipped``.
OK = "ok"
OFF_TARGET_STATUS = "ok, off target"
STATUSES = (OK, OFF_TARGET_STATUS, "failed", "skipped")
#: The statuses of records with figures.
EVALUATED = (OK, OFF_TARGET_STATUS)
#: The relative distance from its target beyond which a result is off target.
OFF_TARGET = 0.10


def evaluated(record: dict) -> bool:
    """True for a record with figures: ``ok`` or ``ok, off target``."""
    return record.get("status") in EVALUATED


def result_status(faces: int, target: int) -> str:
    """``ok`` when ``faces`` is within :data:`OFF_TARGET` of ``target``, else ``ok, off
    target``."""
    return OK if abs(faces - target) <= OFF_TARGET * target else OFF_TARGET_STATUS

#: The leading columns of results.csv, in order (DESIGN "Results"; issue "runner").
#: ``shading`` is the evaluation shading (:func:`shading_label`); ``exterior_share`` is
#: empty for models that do not classify their faces (:mod:`metrics.interior`). Every
#: other registered metric that some record has follows ``status``, by name
#: (:func:`metric_columns`); a cell is empty where a record lacks the metric.
#: ``library_error`` is the error the method's library reports for its result (the
#: meshopt rows: meshoptimizer's result_error, relative to the mesh's extent), empty for
#: methods that report none.
CSV_COLUMNS = ["model", "method", "shading", "target_faces", "faces", "d_rms", "ssim", "flip",
               "hausdorff_mean", "hausdorff_max", "silhouette_mean", "boundary_edges",
               "seam_cracks", "exterior_share", "library_error", "seconds", "tri_per_s",
               "peak_mb", "status"]


def shading_label(protocol: dict) -> str:
    """The evaluation shading of a record's protocol: ``flat``, ``gouraud``, or either
    with ``-spec`` when specular highlights were on (as in record file names); a
    resolution other than 512 adds ``-<pixels>`` and a view set other than the 24
    views adds ``-<name>`` (``gouraud-spec-1024-representative``), so results under
    different image settings are never matched (by ``bench check``, the claims, the
    report). The default protocol's labels are the ones records always had."""
    resolution, views = image_settings(protocol)
    label = protocol["shading"] + ("-spec" if protocol.get("specular") else "")
    if resolution is not None:
        label += f"-{resolution}"
    if views is not None:
        label += f"-{views}"
    return label


def image_settings(protocol: dict) -> tuple:
    """A record's protocol's image settings that are not the default, as (resolution,
    view set), each None at its default (512, the 24 rhombicuboctahedron views)."""
    resolution = protocol.get("resolution", 512)
    views = protocol.get("views", "rhombicuboctahedron")
    return (resolution if resolution != 512 else None,
            views if views != "rhombicuboctahedron" else None)


def write_record(path: Path, record: dict, sort_keys: bool = True) -> Path:
    """Write ``record`` as JSON to ``path`` atomically (NumPy values as plain numbers).

    Keys are sorted unless ``sort_keys`` is false, for files read by people in the
    order they were built (the LOD sidecar of ``bench simplify``).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomic(path, json.dumps(record, indent=1, sort_keys=sort_keys,
                                         default=json_default))


def write_file(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically, making its folder if needed, so a reader
    never sees half a file, whoever else writes the same path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_atomic(path, data)


def load_record(path: Path) -> dict:
    """The record in ``path``; :class:`InputError` with a one-line reason when the file is
    not readable JSON or not a record this bench can use (:func:`record_problem`)."""
    try:
        record = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:  # ValueError: JSON, UTF-8
        raise InputError(f"{path}: not a readable result record "
                         f"({_one_line(exc) or type(exc).__name__})") from None
    schema = record.get("schema") if isinstance(record, dict) else None
    if isinstance(schema, int) and not isinstance(schema, bool) and schema > SCHEMA_VERSION:
        raise InputError(f"{path}: result schema {schema!r} is newer than this bench "
                         f"understands ({SCHEMA_VERSION}); upgrade bench")
    problem = record_problem(record)
    if problem:
        raise InputError(f"{path}: not a result record: {problem}")
    return record


def load_records(run_dir: Path, skipped: list[str] | None = None,
                 paths: list[Path] | None = None) -> list[dict]:
    """All records under ``run_dir/records``, sorted by model, method, budget.

    A bad record (unreadable, malformed, or a link to a file outside the run folder)
    raises :class:`InputError`, unless ``skipped`` is a list: then its one-line reason is
    appended there and the other records are returned, so that one damaged file does not
    hide a whole run from its report. Given a list ``paths``, the file of each record
    returned is appended to it, in the same order.
    """
    folder = Path(run_dir) / "records"
    if not folder.is_dir():
        raise InputError(f"{run_dir}: not a run directory (no records/ inside); "
                         "create one with bench run --out DIR")
    inside = folder.resolve()
    records = []
    for path in sorted(folder.glob("*.json")):
        try:
            if not path.resolve().is_relative_to(inside):
                raise InputError(f"{path}: links outside the run folder; not read")
            records.append((path, load_record(path)))
        except InputError as exc:
            if skipped is None:
                raise
            skipped.append(str(exc))
    records.sort(key=lambda pr: (pr[1]["job"]["model"], pr[1]["job"]["label"],
                                 -pr[1]["job"]["target_faces"],
                                 shading_label(pr[1]["job"]["protocol"])))
    if paths is not None:
        paths.extend(p for p, _ in records)
    return [r for _, r in records]


def record_problem(record) -> str | None:
    """Why ``record`` is not a usable result record (one line), or None.

    Checks what :func:`records_table`, the gate (:mod:`bench.records.check`) and the
    report read: the job's identity and protocol, the status, and the types of the
    metrics, per-view values, histogram, statistics, artifacts and errors. Strings are
    not judged by content (the report escapes them); numbers must be numbers, so no
    later format or comparison can fail on a string where a number belongs.
    """
    if not isinstance(record, dict):
        return f"expected a JSON object, got {_kind(record)}"
    schema = record.get("schema")
    if not _is_int(schema) or schema < 1:
        return f"'schema' must be a positive integer, got {_show(schema)}"
    if record.get("status") not in STATUSES:
        return (f"'status' must be one of {', '.join(map(repr, STATUSES))}, "
                f"got {_show(record.get('status'))}")
    job = record.get("job")
    if not isinstance(job, dict):
        return f"'job' must be an object, got {_kind(job)}"
    for name in ("model", "method", "label"):
        if not isinstance(job.get(name), str) or not job[name]:
            return f"'job.{name}' must be a non-empty string, got {_show(job.get(name))}"
    if not _is_int(job.get("target_faces")) or job["target_faces"] < 1:
        return f"'job.target_faces' must be a positive integer, got {_show(job.get('target_faces'))}"
    if not isinstance(job.get("params", {}), dict):
        return f"'job.params' must be an object, got {_kind(job['params'])}"
    if "key" in job and not isinstance(job["key"], str):
        return f"'job.key' must be a string, got {_kind(job['key'])}"
    problem = _protocol_problem(job.get("protocol"))
    if problem:
        return problem
    if record.get("error") is not None and not isinstance(record["error"], str):
        return f"'error' must be a string or null, got {_kind(record['error'])}"
    ok = evaluated(record)
    for name, check in _PARTS.items():
        value = record.get(name)
        if value is None:
            if ok and name in _NEEDED_IF_OK:
                return f"an ok record needs '{name}'"
            continue
        problem = check(value)
        if problem:
            return f"'{name}' {problem}"
    return None


#: Protocol fields added after records were first written; a record without one was
#: made under the field's default.
_LATER_PROTOCOL_FIELDS = frozenset({"views", "screen_sizes"})


def _protocol_problem(protocol) -> str | None:
    """Every field of :class:`~metrics.protocol.Protocol`, of its type, and no other."""
    from metrics.protocol import Protocol

    if not isinstance(protocol, dict):
        return f"'job.protocol' must be an object, got {_kind(protocol)}"
    hints = typing.get_type_hints(Protocol)
    names = [f.name for f in fields(Protocol)]
    unknown = sorted(set(protocol) - set(names), key=str)
    if unknown:
        return f"'job.protocol' has unknown field {_show(unknown[0])}"
    for name in names:
        if name not in protocol:
            if name in _LATER_PROTOCOL_FIELDS:
                continue  # a record made before the field existed: its default
            return f"'job.protocol' lacks '{name}'"
        value, kind = protocol[name], hints[name]
        if typing.get_origin(kind) is typing.Literal:
            good = value in typing.get_args(kind)
        elif kind is bool:
            good = isinstance(value, bool)
        elif typing.get_origin(kind) is tuple:  # screen_sizes: positive whole numbers
            good = isinstance(value, list) and all(_is_int(v) and v > 0 for v in value)
        elif kind is int:
            good = _is_int(value) and value > 0
        else:
            good = isinstance(value, kind)
        if not good:
            return f"'job.protocol.{name}' is {_show(value)}, not a valid {name}"
    return None


def _numbers_or_null(values: dict) -> str | None:
    if not isinstance(values, dict):
        return f"must be an object, got {_kind(values)}"
    for name, value in values.items():
        if value is not None and not _is_number(value):
            return f"has {_show(name)} = {_show(value)}, not a number"
    return None


def _number_lists(values: dict) -> str | None:
    if not isinstance(values, dict):
        return f"must be an object, got {_kind(values)}"
    for name, series in values.items():
        if series is not None and not _number_list(series):
            return f"has {_show(name)} that is not a list of numbers"
    return None


def _pairs(values) -> str | None:
    if not isinstance(values, dict):
        return f"must be an object, got {_kind(values)}"
    for name, pair in values.items():
        if not (_number_list(pair) and len(pair) == 2):
            return f"has {_show(name)} that is not a pair of numbers [lo, hi]"
    return None


def _number_list(values) -> bool:
    return isinstance(values, list) and all(_is_number(v) for v in values)


def _model_part(model) -> str | None:
    if not isinstance(model, dict):
        return f"must be an object, got {_kind(model)}"
    digest = model.get("hash")
    if digest is not None and not (isinstance(digest, str) and digest and
                                   all(c in "0123456789abcdef" for c in digest)):
        return f"has a 'hash' that is not hexadecimal: {_show(digest)}"
    if model.get("faces") is not None and not _is_int(model["faces"]):
        return f"has 'faces' = {_show(model['faces'])}, not an integer"
    return None


def _strings(values) -> str | None:
    if not isinstance(values, dict) or not all(isinstance(v, str) for v in values.values()):
        return "must be an object of strings"
    return None


#: Optional parts of a record and their checks (a message fragment, or None when fine).
_PARTS = {
    "model": _model_part,
    "method": lambda v: None if isinstance(v, dict) else f"must be an object, got {_kind(v)}",
    "metrics": _numbers_or_null,
    "per_view": _number_lists,
    "intervals": _pairs,
    "silhouette_histogram": lambda v: None if _number_list(v) else "must be a list of numbers",
    "stats": lambda v: None if isinstance(v, dict) else f"must be an object, got {_kind(v)}",
    "seconds": lambda v: None if isinstance(v, dict) else f"must be an object, got {_kind(v)}",
    "timings": _numbers_or_null,
    "artifacts": lambda v: None if isinstance(v, list) else f"must be a list, got {_kind(v)}",
    "metric_errors": _strings,
    "stop_reason": lambda v: None if isinstance(v, str) else f"must be a string, got {_kind(v)}",
    "mesh_file_error": lambda v: None if isinstance(v, str) else f"must be a string, got {_kind(v)}",
    "screen": lambda v: _screen_problem(v),
}


def _screen_problem(part) -> str | None:
    from metrics.screen import screen_part_problem

    return screen_part_problem(part)
#: What the report shows of every ok job.
_NEEDED_IF_OK = ("model", "metrics")


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value) -> bool:
    """A JSON number (NaN and infinities included: the gate flags them)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _kind(value) -> str:
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean",
            type(None): "null"}.get(type(value), "a number")


def _show(value, limit: int = 60) -> str:
    """``value`` for a one-line message: repr (so control characters and newlines are
    escaped, never printed) and cut to ``limit`` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def metric_columns(records: list[dict]) -> list[str]:
    """Registered metrics outside :data:`CSV_COLUMNS` that some record has, by name:
    the columns results.csv and the report add after ``status``."""
    from bench.core.registry import registry

    found = set().union(*((r.get("metrics") or {}).keys() for r in records))
    return [name for name in registry("metric").names()
            if name in found and name not in CSV_COLUMNS]


def records_table(records: list[dict]):
    """A pandas DataFrame with :data:`CSV_COLUMNS` and then :func:`metric_columns`
    (one row per record)."""
    import pandas as pd

    from metrics import screen

    extra = metric_columns(records)
    if any(r.get("screen") for r in records):  # the screen-size evaluation's bounds
        extra += list(screen.CSV_COLUMNS)
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
            "exterior_share": m.get("exterior_share"),
            "library_error": stats.get("library_error"), "seconds": stats.get("wall_seconds"),
            "tri_per_s": stats.get("tri_per_s"), "peak_mb": stats.get("peak_mb"), "status": r["status"],
            **{name: m.get(name) for name in extra},
            **(screen.csv_columns(r.get("screen")) if r.get("screen") else {}),
        })
    return pd.DataFrame(rows, columns=CSV_COLUMNS + extra)


def interval_table(records: list[dict]):
    """:func:`records_table` of ``records`` with, after its columns, ``NAME_lo`` and
    ``NAME_hi`` for every metric some record has an interval of
    (:func:`bench.records.stats.record_intervals`), empty where a record has none."""
    from bench.records.stats import record_intervals

    table = records_table(records)
    intervals = [record_intervals(r) if evaluated(r) else {} for r in records]
    names = sorted(set().union(*intervals), key=lambda n: (n not in CSV_COLUMNS, n))
    for name in names:
        for end, side in (("lo", 0), ("hi", 1)):
            table[f"{name}_{end}"] = [iv[name][side] if name in iv else None
                                      for iv in intervals]
    return table


def write_table(run_dir: Path, records: list[dict]) -> Path:
    """Write ``run_dir/results.csv`` (atomically: a spreadsheet open on it, or a second
    ``bench report``, never sees half a table): :func:`interval_table` of ``records``."""
    text = interval_table(records).to_csv(index=False, float_format="%.6g")
    return write_atomic(Path(run_dir) / "results.csv", text)
