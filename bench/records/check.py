"""Regression gate: compare a run with a committed baseline, metric by metric.

Each metric's direction comes from its registration (``higher_is_better``); counts
without a direction are not checked. A metric is *worse* when it moved in the bad
direction by more than ``tolerance × |baseline|`` (plus 1e-12, so 0 → 1 crack counts).

Marks: ``worse``, ``better``, ``same``, ``newly failing`` (baseline ok, now failed),
``fixed`` (baseline failed, now ok), ``not comparable`` (method or protocol version
changed, or the model's content under the same name, e.g. a model the engine makes: the
numbers cannot be compared), ``not finite`` (NaN or infinite on either side:
no comparison with it can be trusted, and NaN compares false both ways, so it would pass
for ``same``), ``missing`` (in the baseline, not in the run), ``missing metric`` (a
gated metric the baseline has for a job that the run's record of it lacks: the same
method and protocol on the same model define the same metrics, so a record without one
is damaged or cut down, and passing it would let any regression of that metric
through), ``new`` (in the run only). ``worse``, ``not finite``, ``newly failing``,
``missing`` and ``missing metric`` fail the check. The
tolerance must be finite and at least 0: NaN or infinity would let any change pass, and
a negative one would fail identical values.

The protocol never records NaN (an undefined metric is left out of the record), so a NaN
in a record or a baseline is damage or a plug-in's bug, and a baseline file is checked
by shape (:func:`load_baseline`) before it gates anything.

The papers' claims (:mod:`bench.records.claims`) are gated too: a baseline keeps the
verdict of every claim its run has records for, and a claim that held there (``holds``
or ``holds, weaker``) and no longer holds is ``claim broken``, which fails the check;
one that now holds and did not is ``claim holds``; another change of verdict is
``changed``. A claim of the baseline the run cannot decide is ``missing``. A baseline
also keeps each claim's class (whether its difference is significant,
:data:`~bench.records.claims.CLASSES`; baselines made before have none): a claim whose
class changed is ``class changed``, reported and never failing (the gate stays the
exact verdict).

A metric registered by a third-party package is checked like a built-in one, by its own
``higher_is_better``. A metric that raised in an ok job (its value missing, its error in
the record's ``metric_errors``) is ``newly failing`` where the baseline has a value.
Metrics of the run that the baseline lacks (a newly registered metric) are not compared:
make a new baseline to gate them.

Jobs are matched by ``model | method label | target faces | evaluation shading``, never
by the record's file name, and a run folder holds one record per job: two records of one
job (an old copy left beside a new one) are an error naming both files
(:func:`load_run`), never one of them silently winning. Labels are compared in their canonical form
(:func:`canonical_label`), as ``bench run`` writes them now: a baseline written when
explicit defaults stayed in the label (``image-driven[interior_views=0]``) or values kept
their typed form (``qualitythr=0.50``) matches the same job of a current run.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass
from pathlib import Path

from bench.core.errors import InputError
from bench.core.method import canonical_label

__all__ = ["BASELINE_SCHEMA", "FAILING_MARKS", "baseline_problem", "canonical_label",
           "check_tolerance", "compare", "load_baseline", "load_run", "make_baseline",
           "metric_directions", "metric_info", "record_key"]

BASELINE_SCHEMA = 1
FAILING_MARKS = ("worse", "not finite", "newly failing", "missing", "missing metric",
                 "claim broken")


def metric_info(skip_broken: bool = True) -> dict[str, tuple[str, bool | None]]:
    """Registered metric name -> (unit, higher_is_better). A plug-in that cannot be
    loaded is left out (a report then shows its values unitless), unless
    ``skip_broken`` is false: then a plug-in that cannot be imported is an
    :class:`~bench.core.errors.UnavailableError`, and one whose backend is missing still
    gives its unit and direction (they need no backend)."""
    from bench.core.registry import registry

    out = {}
    for entry in registry("metric"):
        if skip_broken:
            if not entry.available:
                continue
            metric = entry.load()
        else:
            metric = entry.definition()
        out[entry.name] = (str(metric.unit), metric.higher_is_better)
    return out


def metric_directions() -> dict[str, bool]:
    """Registered metric name -> higher_is_better, for metrics that have a direction. The
    gate's: a metric plug-in that cannot be loaded is an error here, never a metric
    silently left ungated."""
    from bench.core.errors import UnavailableError

    try:
        info = metric_info(skip_broken=False)
    except UnavailableError as exc:
        raise UnavailableError(f"{exc}; the gate needs every registered metric's direction: "
                               "fix the plug-in or uninstall it") from None
    return {name: higher for name, (_, higher) in info.items() if higher is not None}


def load_run(run_dir: Path, skipped: list[str] | None = None) -> list[dict]:
    """The records of the run folder ``run_dir``
    (:func:`~bench.records.results.load_records`, ``skipped`` as there), refused with an
    :class:`InputError` naming both files when two of them are records of one job."""
    from bench.records.results import load_records

    paths = []
    records = load_records(Path(run_dir), skipped=skipped, paths=paths)
    seen = {}
    for path, record in zip(paths, records):
        key = record_key(record)
        if key in seen:
            raise InputError(f"{seen[key]} and {path} are both records of job {_show(key)}; "
                             "a run folder holds one record per job: remove the stale one")
        seen[key] = path
    return records


def _key(model: str, label: str, target: int, shading: str) -> str:
    """``model | method | target | shading``; the shading is the evaluation's, with
    ``-spec`` when specular was on (:func:`bench.records.results.shading_label`)."""
    return f"{model} | {canonical_label(label)} | {target} | {shading}"


def record_key(record: dict) -> str:
    """The key a baseline gives ``record``'s job: ``model | method | target | shading``."""
    from bench.records.results import shading_label

    job = record["job"]
    return _key(job["model"], job["label"], job["target_faces"], shading_label(job["protocol"]))


def _canonical_entries(entries: dict) -> dict:
    """``entries`` keyed by :func:`_key` of their parsed key (a baseline's own keys may
    predate canonical labels)."""
    out = {}
    for key, entry in entries.items():
        parts = key.split(" | ")
        if len(parts) == 4:
            key = " | ".join([parts[0], canonical_label(parts[1]), *parts[2:]])
        out.setdefault(key, entry)
    return out


def make_baseline(records: list[dict]) -> dict:
    """The comparable essence of a run: status, versions and directed metrics per job.

    Metrics that are missing (undefined for that model) are left out, so they can be
    neither a regression nor an improvement; a NaN or infinite value is kept, for
    :func:`compare` to mark ``not finite``.
    """
    directions = metric_directions()
    entries = {}
    for r in records:
        key = record_key(r)
        metrics = r.get("metrics") or {}
        entries[key] = {
            "status": r["status"],
            "method_version": (r.get("method") or {}).get("version"),
            "protocol_version": r["job"]["protocol"]["version"],
            "metrics": {k: metrics[k] for k in directions if _number(metrics.get(k))},
        }
        model_hash = (r.get("model") or {}).get("hash")
        if isinstance(model_hash, str):  # the input itself, e.g. a model made by the engine
            entries[key]["model_hash"] = model_hash
        errors = {k: v for k, v in (r.get("metric_errors") or {}).items() if k in directions}
        if errors:  # metrics that raised in an ok job (metrics.protocol.evaluate)
            entries[key]["metric_errors"] = errors
    out = {"schema": BASELINE_SCHEMA, "entries": dict(sorted(entries.items()))}
    classes: dict[str, str] = {}
    claims = claim_verdicts(records, classes)
    if claims:
        out["claims"], out["claim_classes"] = claims, dict(sorted(classes.items()))
    return out


def claim_verdicts(records: list[dict], classes: dict | None = None) -> dict[str, str]:
    """Claim name -> verdict, for every claim of every suite that ``records`` have
    evidence for (a claim is scoped to its suite's models and budgets, so a run decides
    the claims of the suite it ran, and no others unless it ran their jobs too). Their
    classes go to ``classes`` when it is given."""
    from bench.records.claims import evaluate_claim
    from bench.records.suites import SUITES

    out = {}
    for suite in SUITES.values():
        for claim in suite.claims:
            result = evaluate_claim(claim, records)
            if result.rows:
                out[claim.name] = result.verdict
                if classes is not None:
                    classes[claim.name] = result.klass
    return dict(sorted(out.items()))


def _number(value) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _finite(value) -> bool:
    return _number(value) and math.isfinite(value)


def check_tolerance(tolerance) -> float:
    """``tolerance`` as a float; :class:`InputError` unless it is finite and >= 0."""
    try:
        value = float(tolerance)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"--tolerance must be a finite number >= 0 (a fraction, e.g. 0.02), "
                         f"got {tolerance!r}")
    return value


def load_baseline(path: Path) -> dict:
    """The baseline in ``path``; :class:`InputError` with a one-line reason when it is not
    readable JSON or not a baseline (:func:`baseline_problem`)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as exc:  # ValueError: JSON, UTF-8
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"{path}: cannot read baseline ({reason}); create one with "
                         "bench baseline DIR --out FILE") from None
    schema = data.get("schema") if isinstance(data, dict) else None
    if isinstance(data, dict) and schema != BASELINE_SCHEMA:
        raise InputError(f"{path}: baseline schema {schema!r} is not "
                         f"{BASELINE_SCHEMA}; regenerate it with bench baseline")
    problem = baseline_problem(data)
    if problem:
        raise InputError(f"{path}: not a baseline: {problem}; create one with "
                         "bench baseline DIR --out FILE")
    return data


def baseline_problem(data) -> str | None:
    """Why ``data`` is not a baseline :func:`compare` can use (one line), or None. An
    empty one is refused too: it would pass every run."""
    from bench.records.results import STATUSES

    if not isinstance(data, dict):
        return f"expected a JSON object, got {type(data).__name__}"
    entries = data.get("entries")
    if not isinstance(entries, dict):
        return "no 'entries' object"
    if not entries:
        return "'entries' is empty (it would pass any run)"
    for key, entry in entries.items():
        where = f"entry {_show(key)}"
        if not isinstance(entry, dict):
            return f"{where} is not an object"
        if entry.get("status") not in STATUSES:
            return f"{where}: 'status' is {_show(entry.get('status'))}"
        for name in ("method_version", "protocol_version"):
            if not isinstance(entry.get(name), (str, int, type(None))) or \
                    isinstance(entry.get(name), bool):
                return f"{where}: '{name}' is {_show(entry.get(name))}"
        if not isinstance(entry.get("model_hash", ""), str):
            return f"{where}: 'model_hash' is {_show(entry.get('model_hash'))}"
        metrics = entry.get("metrics")
        if not isinstance(metrics, dict):
            return f"{where}: no 'metrics' object"
        for name, value in metrics.items():
            if not _number(value):
                return f"{where}: metric {_show(name)} is {_show(value)}, not a number"
        errors = entry.get("metric_errors", {})
        if not isinstance(errors, dict) or not all(isinstance(v, str) for v in errors.values()):
            return f"{where}: 'metric_errors' is not an object of strings"
    from bench.records.claims import VERDICTS

    claims = data.get("claims", {})
    if not isinstance(claims, dict):
        return "'claims' is not an object"
    for name, verdict in claims.items():
        if verdict not in VERDICTS:
            return f"claim {_show(name)}: verdict {_show(verdict)} is not one of {VERDICTS}"
    from bench.records.claims import CLASSES

    classes = data.get("claim_classes", {})
    if not isinstance(classes, dict) or not all(v in CLASSES for v in classes.values()):
        return f"'claim_classes' is not an object of classes ({', '.join(CLASSES)})"
    return None


def _show(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


@dataclass
class Row:
    job: str
    metric: str
    baseline: float | str | None
    current: float | str | None
    mark: str


def compare(baseline: dict, current: dict, tolerance: float = 0.02) -> list[Row]:
    """Rows of (job, metric, baseline, current, mark) for every job and metric."""
    tolerance = check_tolerance(tolerance)
    directions = metric_directions()
    rows = []
    old_all = _canonical_entries(baseline["entries"])
    new_all = _canonical_entries(current["entries"])
    for key in sorted(set(old_all) | set(new_all)):
        old, new = old_all.get(key), new_all.get(key)
        if new is None:
            rows.append(Row(key, "-", old["status"], None, "missing"))
            continue
        if old is None:
            rows.append(Row(key, "-", None, new["status"], "new"))
            continue
        if (old["method_version"], old["protocol_version"]) != (new["method_version"],
                                                                 new["protocol_version"]):
            rows.append(Row(key, "version", f"m{old['method_version']}/p{old['protocol_version']}",
                            f"m{new['method_version']}/p{new['protocol_version']}",
                            "not comparable"))
            continue
        if old.get("model_hash") and new.get("model_hash") and \
                old["model_hash"] != new["model_hash"]:  # another input under the same name
            rows.append(Row(key, "model", old["model_hash"][:12], new["model_hash"][:12],
                            "not comparable"))
            continue
        if old["status"] == "ok" and new["status"] != "ok":
            rows.append(Row(key, "status", old["status"], new["status"], "newly failing"))
            continue
        if old["status"] != "ok" and new["status"] == "ok":
            rows.append(Row(key, "status", old["status"], new["status"], "fixed"))
            continue
        for metric, before in old["metrics"].items():
            after = new["metrics"].get(metric)
            if after is None and metric in new.get("metric_errors", {}):
                error = (new["metric_errors"][metric].splitlines() or [""])[0]
                rows.append(Row(key, metric, before, error[:60], "newly failing"))
                continue
            if not _finite(before) or (after is not None and not _finite(after)):
                rows.append(Row(key, metric, before, after, "not finite"))
                continue
            if metric not in directions:  # no longer registered: nothing to judge it by
                rows.append(Row(key, metric, before, after, "not comparable"))
                continue
            if after is None:
                rows.append(Row(key, metric, before, after, "missing metric"))
                continue
            delta = (after - before) if directions[metric] else (before - after)  # >0 = better
            slack = tolerance * abs(before) + 1e-12
            mark = "worse" if delta < -slack else "better" if delta > slack else "same"
            rows.append(Row(key, metric, before, after, mark))
    return rows + _compare_claims(baseline.get("claims", {}), current.get("claims", {}),
                                  baseline.get("claim_classes", {}),
                                  current.get("claim_classes", {}))


def _compare_claims(old: dict, new: dict, old_classes: dict | None = None,
                    new_classes: dict | None = None) -> list[Row]:
    """Rows for the claims' verdicts and changed classes (the module's docstring)."""
    from bench.records.claims import HOLDING

    rows = []
    for name in sorted(set(old) | set(new)):
        before, after = old.get(name), new.get(name)
        if after is None:
            mark = "missing"
        elif before is None:
            mark = "new"
        elif before == after:
            mark = "same"
        elif before in HOLDING and after not in HOLDING:
            mark = "claim broken"
        elif after in HOLDING and before not in HOLDING:
            mark = "claim holds"
        else:
            mark = "changed"
        rows.append(Row(f"claim {name}", "verdict", before, after, mark))
        was, now = (old_classes or {}).get(name), (new_classes or {}).get(name)
        if was is not None and now is not None and was != now:
            rows.append(Row(f"claim {name}", "class", was, now, "class changed"))
    return rows
