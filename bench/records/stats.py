"""Is a difference real? Intervals over views and paired tests between methods.

Every image metric of a record is one number summarising the protocol's views (24, or
FLIP's subset of them), and its per-view values are kept in the record's ``per_view``
(:class:`bench.core.metric.Value`). This module turns those into

* **intervals** (:func:`interval`, :func:`record_intervals`): a 95 % bootstrap
  confidence interval of the reported value over the views, from
  :func:`scipy.stats.bootstrap` with a fixed seed (:data:`SEED`), so the same record
  always gets the same interval. The statistic resampled is the one that made the
  reported value from the per-view values, so the interval is an interval *of that
  value*: ``d_rms`` is the RMS over every pixel of every view and its per-view values
  are each view's own RMS (:func:`metrics.image.d_rms`), so its statistic is
  ``sqrt(mean(per_view ** 2))``; SSIM and FLIP are means of their per-view values
  (:data:`STATISTICS`). A metric whose value its statistic does not reproduce from
  ``per_view`` gets no interval rather than an interval of something else.

  The method is BCa (bias-corrected and accelerated), scipy's default: per-view errors
  are skewed (a few grazing views carry most of a mesh's error) and the RMS is a
  non-linear statistic, and BCa corrects the percentile interval for both the bias
  and the skew of the bootstrap distribution (second-order accurate), where the plain
  percentile interval is only first-order accurate. When BCa is undefined (all the
  views resample to the same value, e.g. identical views) the percentile interval of
  the same resamples is used, which is then the single value itself. With FLIP's six
  views the interval is coarse: six values cannot say much.

* **paired tests** (:func:`paired`): two methods on the same model, budget and shading
  are compared view by view, with the Wilcoxon signed-rank test
  (:func:`scipy.stats.wilcoxon`) on the paired per-view differences. Zero differences
  are dropped before the test (Wilcoxon's own treatment, ``zero_method="wilcox"``);
  when every difference is zero the two are identical on every view: p = 1, a tie.
  Alongside: the median difference and the share of views where each is better.
* **a sign test over cells** (:func:`sign_test`): across models and budgets, the
  number of cells each method wins, against a fair coin
  (:func:`scipy.stats.binomtest`), exact ties left out.
* **Holm's correction** (:func:`holm`) of the p-values of one table of comparisons
  (step-down, so it controls the family-wise error rate at the level given without
  assuming the tests independent).

Limits, which every figure made with this module carries:

* Views are not independent draws from a population of viewpoints: they are a fixed
  set of directions around one mesh, and neighbouring views see much of the same
  surface. An interval over views says how much the figure depends on *which* views
  were taken, not how it would vary on another mesh; a test over views asks whether
  one method is better *consistently across viewpoints* of this model at this budget,
  not whether it is better on models in general (that is the sign test over cells,
  which has little power with few cells: with four cells it can never reach p < 0.05).
* The paired test uses the per-view values, not the reported value: a method can have
  the lower RMS over all views yet be worse on most views (a few views dominate an
  RMS). The verdict then follows the views, and the reported values remain what they are.
* Significance is at :data:`ALPHA` after Holm's correction within the table it is
  stated for; a tie means "no consistent difference found", not "equal".
"""

from __future__ import annotations

import math
import warnings
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["ALPHA", "CONFIDENCE", "SEED", "STATISTICS", "Paired", "compute_intervals",
           "consistent_views", "holm", "interval", "paired", "record_intervals", "sign_test",
           "statistic_of"]

#: The confidence level of every interval.
CONFIDENCE = 0.95
#: The level of every test, after Holm's correction within its table.
ALPHA = 0.05
#: The bootstrap's seed: every interval is drawn with ``np.random.default_rng(SEED)``.
SEED = 20000
#: Bootstrap resamples (scipy's default).
RESAMPLES = 9999
#: How a metric's value is made from its per-view values (any other metric: the mean).
STATISTICS = {"d_rms": "rms"}


def _rms(x, axis=-1):
    return np.sqrt(np.mean(np.square(x), axis=axis))


def _mean(x, axis=-1):
    return np.mean(x, axis=axis)


def statistic_of(metric: str):
    """The function that makes ``metric``'s value from its per-view values."""
    return _rms if STATISTICS.get(metric) == "rms" else _mean


def interval(values, metric: str = "", confidence: float = CONFIDENCE,
             seed: int = SEED) -> tuple[float, float] | None:
    """The bootstrap interval (BCa) of ``metric``'s statistic over ``values`` (per-view
    values), or None with fewer than two finite values. Deterministic: always drawn
    with ``np.random.default_rng(seed)``."""
    from scipy.stats import bootstrap

    x = np.asarray(values, dtype=float)
    if x.ndim != 1 or len(x) < 2 or not np.all(np.isfinite(x)):
        return None
    stat = statistic_of(metric)
    if np.all(x == x[0]):  # every resample is the same value
        v = float(stat(x))
        return v, v
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a degenerate BCa falls back below
        res = bootstrap((x,), stat, n_resamples=RESAMPLES, confidence_level=confidence,
                        method="BCa", vectorized=True, rng=np.random.default_rng(seed))
        lo, hi = res.confidence_interval
        if not (math.isfinite(lo) and math.isfinite(hi)):
            res = bootstrap((x,), stat, n_resamples=RESAMPLES, confidence_level=confidence,
                            method="percentile", vectorized=True,
                            rng=np.random.default_rng(seed))
            lo, hi = res.confidence_interval
    return float(lo), float(hi)


def record_intervals(record: dict) -> dict[str, list[float]]:
    """Metric name -> [lo, hi]: the record's stored ``intervals`` (records of schema 2
    on), or else computed from its ``per_view`` values (older records), for every
    metric whose statistic of ``per_view`` reproduces its reported value. Computed ones
    are kept in the record's dict (in memory; its file is not touched), so a report
    that reads them twice (results.csv and the summary table) bootstraps once."""
    stored = record.get("intervals")
    if isinstance(stored, dict):
        return stored
    record["intervals"] = compute_intervals(record.get("metrics") or {},
                                            record.get("per_view") or {})
    return record["intervals"]


def compute_intervals(metrics: dict, per_view: dict) -> dict[str, list[float]]:
    """Metric name -> [lo, hi] for every metric of ``metrics`` with per-view values in
    ``per_view`` whose statistic reproduces its value (to 1e-9, relative)."""
    out = {}
    for name in sorted(per_view):
        x = consistent_views({"metrics": metrics, "per_view": per_view}, name)
        got = None if x is None else interval(x, name)
        if got is not None:
            out[name] = [got[0], got[1]]
    return out


def consistent_views(record: dict, metric: str) -> list[float] | None:
    """``record``'s per-view values of ``metric`` when they are finite and make its
    reported value (:func:`statistic_of`, to 1e-9 relative), else None."""
    views = (record.get("per_view") or {}).get(metric)
    value = (record.get("metrics") or {}).get(metric)
    if not isinstance(views, list) or not views or isinstance(value, bool) or \
            not isinstance(value, (int, float)):
        return None
    x = np.asarray(views, dtype=float)
    if not np.all(np.isfinite(x)) or not math.isclose(
            float(statistic_of(metric)(x)), float(value), rel_tol=1e-9, abs_tol=1e-12):
        return None
    return [float(v) for v in x]


@dataclass(frozen=True)
class Paired:
    """The view-by-view comparison of method A with method B on one cell.

    ``median_difference`` is the median of A - B over the views; ``a_better`` and
    ``b_better`` the shares of views where each is better (the rest are exact ties);
    ``p`` the two-sided Wilcoxon signed-rank p-value; ``direction`` +1 when A is
    better (its signed ranks dominate in its favour), -1 when B is, 0 when neither."""

    n: int
    median_difference: float
    a_better: float
    b_better: float
    p: float
    direction: int

    def verdict(self, p: float | None = None, alpha: float = ALPHA) -> str:
        """``A better``, ``B better`` or ``tie`` at ``alpha`` (``p``: a corrected
        p-value in place of the test's own)."""
        p = self.p if p is None else p
        if p < alpha and self.direction:
            return "A better" if self.direction > 0 else "B better"
        return "tie"

    def as_dict(self) -> dict:
        return asdict(self)


def paired(a, b, higher_is_better: bool = False) -> Paired:
    """Wilcoxon signed-rank test of per-view values ``a`` against ``b`` (same views,
    same order). Zero differences are dropped; with none left, p = 1 (a tie)."""
    from scipy.stats import rankdata, wilcoxon

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape or a.ndim != 1 or len(a) == 0:
        raise ValueError(f"paired values need the same views: got {a.shape} and {b.shape}")
    d = a - b
    if not np.all(np.isfinite(d)):
        raise ValueError("paired values must be finite")
    gain = -d if not higher_is_better else d  # > 0 where A is better
    nonzero = gain[gain != 0]
    n = len(a)
    median = float(np.median(d))
    a_better, b_better = float(np.sum(gain > 0) / n), float(np.sum(gain < 0) / n)
    if len(nonzero) == 0:
        return Paired(n, median, a_better, b_better, 1.0, 0)
    ranks = rankdata(np.abs(nonzero))
    plus, minus = ranks[nonzero > 0].sum(), ranks[nonzero < 0].sum()
    direction = int(np.sign(plus - minus))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # small-sample notes of scipy
        p = float(wilcoxon(nonzero, zero_method="wilcox").pvalue)
    if not math.isfinite(p):
        p = 1.0
    return Paired(n, median, a_better, b_better, min(p, 1.0), direction)


def sign_test(wins: int, losses: int) -> float:
    """Two-sided sign test of ``wins`` against ``losses`` (ties left out before):
    the binomial p-value of a fair coin; 1 with no untied cell."""
    from scipy.stats import binomtest

    if wins + losses == 0:
        return 1.0
    return float(binomtest(wins, wins + losses, 0.5).pvalue)


def holm(pvalues) -> list[float]:
    """Holm's step-down adjusted p-values, in the order given: the i-th smallest of m
    p-values is multiplied by (m - i + 1), made non-decreasing along that order and
    capped at 1. A hypothesis is rejected at level alpha when its adjusted p < alpha."""
    p = [float(v) for v in pvalues]
    m = len(p)
    order = sorted(range(m), key=lambda i: p[i])
    adjusted, running = [0.0] * m, 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[i]))
        adjusted[i] = running
    return adjusted
