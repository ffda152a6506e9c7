"""Contrast sensitivity and imperceptibility distance (Williams et al. 2003, §3).

The CSF of §3, Rushmeier et al.'s (1995) approximation of Daly's model::

    C(f) = (0.008 / f^1.5 + 1)^-0.2 · 1.42 f · e^(-0.3 f) · sqrt(1 + 0.06 e^(0.3 f))

with f in cycles per degree. Choices where the paper is vague or its text is damaged:

- *f, not sqrt(f)*. The seed text prints the two inner factors as ``1.42 sqrt(f)
  e^(-0.3 sqrt(f))`` and ``e^(0.3 sqrt(f))``. That curve peaks at 13 cpd and still
  has 73 % of its peak sensitivity at 60 cpd, which contradicts §3.2 ("peak contrast
  sensitivity occurs around 2-4 cycles per degree") and the acuity limit; with f the
  peak is at 3.6 cpd and sensitivity falls to 0.1 % of the peak at 60 cpd. We use f
  (tested: the peak lies in 2-4 cpd).
- *Absolute scale*. The formula's peak sensitivity is 1.88 (a threshold contrast of
  53 %): it is a shape, not an absolute CSF. Taken literally every node below 53 %
  Michelson contrast would be imperceptible from any distance and only silhouettes
  would ever be refined. :class:`ContrastSensitivity` scales it to
  ``peak_sensitivity`` (default 200, the order of photopic peak sensitivities, a
  threshold of 0.5 %); the shape and the peak frequency are the formula's.
- *Clamp* (§3.2 footnote, Figure 3): below the peak frequency the sensitivity is held
  at its peak, so the threshold contrast rises monotonically with frequency and the
  inversion of §3.4 is single-valued.
- *Lookup tables* (§3: "we represent this computationally expensive empirical formula
  with a lookup table"): the threshold on a log-frequency grid and its inverse on a
  log-contrast grid, :data:`TABLE_SIZE` entries each, linearly interpolated.

Imperceptibility distance (§3.4): a feature of contrast c is visible up to the
frequency f_vis(c) where c meets the threshold. A feature spanning e degrees from the
observer's distance D has its lowest frequency at 1 / (2e) cpd (§3.2); seen from k·D it
spans e/k degrees, so it becomes imperceptible once k ≥ f_vis(c) · 2e. We report that k,
the distance in multiples of the observer's viewing distance (0: never perceptible).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["csf", "ContrastSensitivity", "PEAK_FREQUENCY", "TABLE_SIZE", "MAX_FREQUENCY"]

#: Entries of each lookup table.
TABLE_SIZE = 2048
#: Highest tabulated frequency (cpd): beyond the acuity limit of any observer.
MAX_FREQUENCY = 120.0


def csf(f):
    """Contrast sensitivity of §3 at frequency ``f`` (cycles per degree, > 0).

    Parameters
    ----------
    f : float or ndarray

    Returns
    -------
    float or ndarray
        Unscaled sensitivity (the formula's own values; peak 1.88 at 3.6 cpd).
    """
    f = np.asarray(f, dtype=np.float64)
    if np.any(~(f > 0)):
        raise ValueError("spatial frequency must be positive (cycles per degree)")
    out = ((0.008 / f ** 1.5 + 1.0) ** -0.2 * 1.42 * f * np.exp(-0.3 * f)
           * np.sqrt(1.0 + 0.06 * np.exp(0.3 * f)))
    return float(out) if out.ndim == 0 else out


def _peak_frequency() -> float:
    """argmax of :func:`csf` by golden-section search on [0.5, 20] cpd."""
    a, b = math.log(0.5), math.log(20.0)
    g = (math.sqrt(5) - 1) / 2
    for _ in range(200):
        c, d = b - g * (b - a), a + g * (b - a)
        if csf(math.exp(c)) > csf(math.exp(d)):
            b = d
        else:
            a = c
    return math.exp(0.5 * (a + b))


#: Frequency of peak sensitivity of :func:`csf` (cycles per degree).
PEAK_FREQUENCY = _peak_frequency()


class ContrastSensitivity:
    """The clamped, scaled CSF as lookup tables, and its inversion (§3.4).

    Parameters
    ----------
    peak_sensitivity : float
        Sensitivity at the peak (1 / threshold contrast); see the module docstring.
    """

    def __init__(self, peak_sensitivity: float = 200.0):
        if not peak_sensitivity > 1.0:
            raise ValueError(f"peak_sensitivity must be > 1 (a threshold contrast below "
                             f"100 %), got {peak_sensitivity}")
        self.peak_sensitivity = float(peak_sensitivity)
        self.gain = peak_sensitivity / csf(PEAK_FREQUENCY)
        self.log_f = np.linspace(math.log(PEAK_FREQUENCY), math.log(MAX_FREQUENCY), TABLE_SIZE)
        self.log_threshold = -np.log(self.gain * csf(np.exp(self.log_f)))
        # inverse table on a uniform log-contrast grid from the peak threshold to 1
        self.c_lo = float(self.log_threshold[0])
        self.c_hi = 0.0
        grid = np.linspace(self.c_lo, self.c_hi, TABLE_SIZE)
        self.inverse_log_f = np.interp(grid, self.log_threshold, self.log_f)

    def sensitivity(self, f):
        """Scaled sensitivity, clamped below the peak (exact formula, no table)."""
        f = np.maximum(np.asarray(f, dtype=np.float64), PEAK_FREQUENCY)
        return self.gain * csf(f)

    def threshold(self, f):
        """Threshold contrast at ``f`` cpd (table lookup), clamped below the peak."""
        lf = np.log(np.maximum(np.asarray(f, dtype=np.float64), PEAK_FREQUENCY))
        return np.exp(np.interp(lf, self.log_f, self.log_threshold))

    def visible_frequency(self, contrast):
        """f_vis: the highest frequency at which a grating of Michelson ``contrast`` is
        at threshold; 0 when it is below the peak threshold (never visible)."""
        c = np.asarray(contrast, dtype=np.float64)
        out = _visible_frequency_many(c.reshape(-1), self.c_lo, self.c_hi, self.inverse_log_f)
        return out.reshape(c.shape) if c.ndim else float(out[0])

    def imperceptibility_distance(self, contrast, extent_deg):
        """Distance, in multiples of the viewing distance, beyond which a feature of
        ``contrast`` spanning ``extent_deg`` degrees is imperceptible: f_vis · 2e."""
        return self.visible_frequency(contrast) * 2.0 * np.asarray(extent_deg, np.float64)

    def tables(self):
        """(c_lo, c_hi, inverse_log_f) for :func:`visible_frequency_kernel`."""
        return self.c_lo, self.c_hi, self.inverse_log_f


@njit(cache=True)
def visible_frequency_kernel(contrast, c_lo, c_hi, inverse_log_f):
    """f_vis by the inverse table (log contrast -> log frequency), for numba callers."""
    if not contrast > 0.0:
        return 0.0
    lc = math.log(contrast)
    if lc < c_lo:
        return 0.0
    n = inverse_log_f.shape[0]
    if lc >= c_hi:
        return math.exp(inverse_log_f[n - 1])
    x = (lc - c_lo) / (c_hi - c_lo) * (n - 1)
    i = int(x)
    if i >= n - 1:
        return math.exp(inverse_log_f[n - 1])
    w = x - i
    return math.exp((1.0 - w) * inverse_log_f[i] + w * inverse_log_f[i + 1])


@njit(cache=True)
def _visible_frequency_many(c, c_lo, c_hi, inverse_log_f):
    out = np.empty(c.shape[0])
    for i in range(c.shape[0]):
        out[i] = visible_frequency_kernel(c[i], c_lo, c_hi, inverse_log_f)
    return out
