"""The papers' claims as data, and their verdicts from a run's records.

A :class:`Claim` is a declarative entry kept with the suite that tests it
(:mod:`bench.records.suites`): what the paper says, where, which metric decides it, and
how — the ratio of one method variant's value to another's, or one variant's value on
its own — with our threshold and the paper's own figure where it gives one.
:func:`evaluate_claim` reads only records (never a number typed in): every (model,
budget, evaluation shading) where the records it needs exist and are ``ok`` gives one
row of evidence (for the metrics of :data:`ANY_TARGET`, which mean the same at any face
count, ``ok, off target`` records count too), and the rows give the verdict:

=====================  ==================================================================
verdict                when
=====================  ==================================================================
``holds``              every row passes the threshold (and, for a ratio the paper gives,
                       our worst ratio is at least as strong as the paper's)
``holds, weaker``      every row passes, but our worst ratio is weaker than the paper's
``mixed``              some rows pass and some do not (the summary says how many)
``does not hold``      no row passes
``no data``            no row could be made (the suite did not run, or its jobs failed)
=====================  ==================================================================

The verdict counts rows; the **class** (:data:`CLASSES`) asks whether the difference is
real, from the per-view values of the records (:mod:`bench.records.stats`, whose limits
apply: views are not independent draws, and a test over them asks whether a method is
better consistently across viewpoints of one model at one budget):

* A ratio claim ("A beats B", with ``against``): in every row, the Wilcoxon signed-rank
  test of A's per-view values against the threshold times B's (for a threshold of 1,
  the plain paired differences), Holm-corrected over the claim's rows (its table).
  ``holds``: every row significant (corrected p < :data:`~bench.records.stats.ALPHA`)
  in the claimed direction; ``contradicted``: some row significant the other way;
  ``holds, not significant``: every row passes but not every one significantly;
  ``does not hold``: the rest. Its p-value is the deciding one (the largest corrected
  p of the rows; when contradicted, the smallest of the contradicting rows), its
  effect the median per-view ratio A / B over every row's views, and a sign test over
  the rows (:func:`~bench.records.stats.sign_test`) is given beside it.
* A threshold claim (a value on its own): in every row, the 95 % bootstrap interval of
  the value over the views, and where it lies: wholly ``above`` or ``below`` the
  threshold, or ``across`` it. ``holds``: every interval wholly on the passing side;
  ``contradicted``: some interval wholly on the failing side; ``holds, not
  significant``: every row passes, some interval across; ``does not hold``: the rest.
* ``no test``: some row has no per-view values of the claim's metric (statistics of the
  method, Hausdorff distances, silhouettes, parts and target distances are one number
  per job): only the verdict decides.

``bench check`` gates on the verdict; a change of class is reported, never failed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["CLASSES", "Claim", "ClaimResult", "VERDICTS", "HOLDING", "evaluate_claim",
           "claim_rows"]

#: The verdicts, best first.
VERDICTS = ("holds", "holds, weaker", "mixed", "does not hold", "no data")
#: The classes of a claim's statistical test (see the module's docstring).
CLASSES = ("holds", "holds, not significant", "does not hold", "contradicted", "no test")
#: Verdicts under which a claim counts as holding (for ``bench check``).
HOLDING = ("holds", "holds, weaker")
#: A claim's metric with this prefix is a statistic of the method's record
#: (``record["stats"]``), not a protocol metric.
STATS_PREFIX = "stats."
#: A claim's metric: the record's distance from its target, |faces - target| / target.
TARGET_DISTANCE = "target_distance"
#: Metrics whose claims read results off their target too (what they say does not
#: depend on the face count reached).
ANY_TARGET = frozenset({TARGET_DISTANCE, "components_lost", "materials_lost"})


@dataclass(frozen=True)
class Claim:
    """One claim of a paper, tested by the records of one suite.

    ``method`` and ``against`` are method labels as a run writes them
    (``name[key=value,...]``). With ``against``, a row's value is ``metric(method) /
    metric(against)`` on the same model, budget and shading; without it, the value is
    ``metric(method)``; a ``metric`` named ``stats.NAME`` is the method's own statistic
    NAME (its record's ``stats``), for what the protocol does not measure. A row passes when its value is below ``below``, or at least
    ``at_least`` (exactly one is given). ``models``, ``faces`` and ``ratios`` (a budget
    as a fraction of the model's faces) narrow the rows; empty, every one of the suite's
    counts. ``shading`` names the evaluation shading (``flat``, ``gouraud-spec``, ...)."""

    name: str
    source: str  # paper and figure or section
    statement: str
    metric: str
    method: str
    against: str | None = None
    below: float | None = None
    at_least: float | None = None
    models: tuple[str, ...] = ()
    faces: tuple[int, ...] = ()
    ratios: tuple[float, ...] = ()
    shading: str | None = None
    #: the paper's own figure as it gives it, e.g. "3.75 vs 4.10" ("" when qualitative)
    paper: str = ""
    #: the same as a value comparable with ours (a ratio), or None
    paper_value: float | None = None
    #: the suite that tests it (set by the suite that lists the claim)
    suite: str = ""
    #: a note for the reader: how our threshold was chosen, what the evidence misses
    note: str = ""

    def __post_init__(self) -> None:
        if (self.below is None) == (self.at_least is None):
            raise ValueError(f"claim {self.name!r}: give exactly one of below, at_least")

    @property
    def test(self) -> str:
        """The pass condition in words, e.g. ``d_rms ratio < 1``."""
        what = f"{self.metric} ratio" if self.against else self.metric
        return f"{what} < {self.below:g}" if self.below is not None else \
            f"{what} >= {self.at_least:g}"

    def passes(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        return value < self.below if self.below is not None else value >= self.at_least


@dataclass
class ClaimResult:
    """A claim's evidence rows and verdict."""

    claim: Claim
    rows: list[dict] = field(default_factory=list)
    verdict: str = "no data"
    #: the class of its test (:data:`CLASSES`); None without rows
    klass: str | None = None
    #: the deciding p-value (ratio claims), after Holm's correction over the rows
    p: float | None = None
    #: the median per-view ratio A / B over every row's views (ratio claims)
    effect: float | None = None
    #: the sign test over the rows: p of passing against failing rows (ratio claims)
    sign_p: float | None = None
    #: where the rows' intervals lie (threshold claims): above, below, across or mixed
    side: str | None = None

    @property
    def passed(self) -> int:
        return sum(r["passes"] for r in self.rows)

    @property
    def worst(self) -> float | None:
        """The value furthest on the failing side (None without rows)."""
        values = [r["value"] for r in self.rows if not math.isnan(r["value"])]
        if not values:
            return None
        return max(values) if self.claim.below is not None else min(values)

    @property
    def summary(self) -> str:
        """The evidence in one line: the value (or its range) and how many rows pass."""
        if not self.rows:
            return "no records"
        values = [r["value"] for r in self.rows if not math.isnan(r["value"])]
        if not values:
            return f"undefined (0 of {len(self.rows)} pass)"
        lo, hi = min(values), max(values)
        shown = f"{lo:.4g}" if lo == hi else f"{lo:.4g}-{hi:.4g}"
        return f"{shown} ({self.passed} of {len(self.rows)} pass)"


def _shading(record: dict) -> str:
    from bench.records.results import shading_label

    return shading_label(record["job"]["protocol"])


def _in_budget(claim: Claim, record: dict) -> bool:
    target = record["job"]["target_faces"]
    if claim.faces and target not in claim.faces:
        return False
    if claim.ratios:
        n = (record.get("model") or {}).get("faces")
        if not isinstance(n, int) or n <= 0:
            return False
        return any(abs(target - r * n) <= 1 for r in claim.ratios)
    return True


def _value(record: dict, metric: str) -> float:
    """``metric`` of ``record``: a protocol metric, or with the prefix ``stats.`` a
    statistic the method recorded (``stats.crossing_share_after``); NaN if missing."""
    if metric == TARGET_DISTANCE:
        faces, target = (record.get("metrics") or {}).get("faces"), record["job"]["target_faces"]
        value = abs(faces - target) / target if isinstance(faces, (int, float)) else None
    elif metric.startswith(STATS_PREFIX):
        value = (record.get("stats") or {}).get(metric[len(STATS_PREFIX):])
    else:
        value = (record.get("metrics") or {}).get(metric)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return math.nan
    return float(value)


def claim_rows(claim: Claim, records: list[dict]) -> list[dict]:
    """The evidence of ``claim`` in ``records``: one row per (model, budget, shading)
    where the claim's records exist and are ``ok``, sorted."""
    from bench.core.method import canonical_label

    wanted = {canonical_label(claim.method): "method"}
    if claim.against:
        wanted[canonical_label(claim.against)] = "against"
    cells: dict[tuple, dict] = {}
    from bench.records.results import EVALUATED, OK

    statuses = EVALUATED if claim.metric in ANY_TARGET else (OK,)
    for r in records:
        job = r.get("job") or {}
        role = wanted.get(canonical_label(job.get("label", "")))
        if role is None or r.get("status") not in statuses:
            continue
        if claim.models and job["model"] not in claim.models:
            continue
        shading = _shading(r)
        if (claim.shading and shading != claim.shading) or not _in_budget(claim, r):
            continue
        key = (job["model"], job["target_faces"], shading)
        cells.setdefault(key, {})[role] = r
    rows = []
    for (model, target, shading), got in sorted(cells.items()):
        if "method" not in got or (claim.against and "against" not in got):
            continue
        mine = _value(got["method"], claim.metric)
        if math.isnan(mine):
            continue  # the metric is undefined for this model (e.g. exterior_share)
        other = got.get("against")
        theirs = _value(other, claim.metric) if other else math.nan
        value = (mine / theirs if theirs else math.nan) if other else mine  # nan stays
        views = _views(got["method"], claim.metric)
        rows.append({"model": model, "target_faces": target, "shading": shading,
                     "method_views": views,
                     "against_views": _views(other, claim.metric) if other else None,
                     "interval": None if other else _interval(got["method"], claim.metric),
                     "faces": _value(got["method"], "faces"), "method_value": mine,
                     "against_value": theirs, "value": value, "passes": claim.passes(value),
                     "method_key": got["method"]["job"].get("key"),
                     "against_key": other["job"].get("key") if other else None})
    return rows


def _views(record: dict, metric: str) -> list[float] | None:
    """``record``'s per-view values of ``metric``, or None when it has none or they do
    not make its reported value (then a test of them would be of something else)."""
    from bench.records.stats import consistent_views

    return consistent_views(record, metric)


def _interval(record: dict, metric: str) -> list[float] | None:
    from bench.records.stats import record_intervals

    return record_intervals(record).get(metric)


def _classify(result: ClaimResult) -> None:
    """Set ``result``'s class and its test's figures (the module's docstring)."""
    claim, rows = result.claim, result.rows
    threshold = claim.below if claim.below is not None else claim.at_least
    if claim.against:
        _classify_ratio(result, threshold)
        return
    sides = []
    for r in rows:
        iv = r["interval"]
        r["side"] = None if iv is None else "below" if iv[1] < threshold else \
            "above" if iv[0] > threshold else "across"
        sides.append(r["side"])
    if None in sides:
        result.klass = "no test"
        return
    passing = "below" if claim.below is not None else "above"
    failing = "above" if passing == "below" else "below"
    result.side = sides[0] if len(set(sides)) == 1 else "mixed"
    if all(side == passing for side in sides):
        result.klass = "holds"
    elif failing in sides:
        result.klass = "contradicted"
    elif all(r["passes"] for r in rows):
        result.klass = "holds, not significant"
    else:
        result.klass = "does not hold"


def _classify_ratio(result: ClaimResult, threshold: float) -> None:
    import numpy as np

    from bench.records.stats import ALPHA, holm, paired, sign_test

    claim, rows = result.claim, result.rows
    if any(r["method_views"] is None or r["against_views"] is None or
           len(r["method_views"]) != len(r["against_views"]) for r in rows):
        result.klass = "no test"
        return
    higher = claim.at_least is not None  # the claimed direction: A above t·B
    tests = [paired(r["method_views"], [threshold * v for v in r["against_views"]],
                    higher_is_better=higher) for r in rows]
    corrected = holm([t.p for t in tests])
    for r, t, p in zip(rows, tests, corrected):
        r.update(p=t.p, p_holm=p, direction=t.direction, share_claimed=t.a_better,
                 share_other=t.b_better)
    significant = [p < ALPHA for p in corrected]
    against = [p for p, s, t in zip(corrected, significant, tests) if s and t.direction < 0]
    if against:
        result.klass, result.p = "contradicted", min(against)
    else:
        result.p = max(corrected)
        if all(s and t.direction > 0 for s, t in zip(significant, tests)):
            result.klass = "holds"
        elif all(r["passes"] for r in rows):
            result.klass = "holds, not significant"
        else:
            result.klass = "does not hold"
    a = np.concatenate([np.asarray(r["method_views"], float) for r in rows])
    b = np.concatenate([np.asarray(r["against_views"], float) for r in rows])
    ratios = a[b != 0] / b[b != 0]
    result.effect = float(np.median(ratios)) if len(ratios) else None
    passed = result.passed
    result.sign_p = sign_test(passed, len(rows) - passed)


def evaluate_claim(claim: Claim, records: list[dict]) -> ClaimResult:
    """``claim``'s rows in ``records`` and its verdict (see the module's table)."""
    result = ClaimResult(claim, claim_rows(claim, records))
    if not result.rows:
        return result
    _classify(result)
    passed = result.passed
    if passed == 0:
        result.verdict = "does not hold"
    elif passed < len(result.rows):
        result.verdict = "mixed"
    else:
        result.verdict = "holds"
        paper, worst = claim.paper_value, result.worst
        if paper is not None and worst is not None:
            weaker = worst > paper if claim.below is not None else worst < paper
            if weaker:
                result.verdict = "holds, weaker"
    return result
