"""Confidence intervals of Monte Carlo metrics from per-run sufficient statistics.

Every metric of a campaign is an average over independent runs of something each run
measured, so its interval is built from one number (or one count pair) per run, never
from the epochs as if they were independent (they are not: a filter's errors are
correlated in time, a detector's alarms come in bursts).  One method per kind:

* **means over runs** -- the RMSE (mean over runs of the per-run RMSE), the ANEES (mean
  over runs of the per-run mean NEES), a recovery time: Student-t on the ``B`` per-run
  values, :func:`mean_interval` (valid by the central limit theorem over runs; each
  per-run value is itself an average over many epochs);
* **root mean squares** -- the ensemble RMSE ``sqrt(mean e²)``: the t interval of the
  per-run mean squares, mapped through the square root (monotone), :func:`rms_interval`;
* **ratios of means over the same runs** -- a method's error with the fault against
  without it, one method against another on the same noise: Fieller's interval with
  Student's quantile on the paired per-run values, :func:`ratio_interval` (measured: 95 %
  for mildly skewed per-run values, 92 % with 20 runs of strongly skewed ones);
* **rates** -- detection probability per epoch, per event, false-alarm rate: the
  Wilson score interval with the effective number of trials of a cluster sample
  (runs are the clusters): ``n_eff = p(1-p) / Var(p̂)`` with the between-run
  (ratio-estimator) variance, kept within ``[B, n]`` -- the plain Wilson interval when
  the trials are independent or the runs show no spread (p̂ = 0 or 1),
  :func:`rate_interval` (Wilson 1927; Kish 1965 for the design effect);
* **order statistics of pooled events** -- median and 95th-percentile detection delay:
  the percentile bootstrap over runs (runs resampled with replacement, the statistic
  recomputed over the resampled runs' events; a fixed generator so an interval is
  reproducible), :func:`bootstrap_interval`.

:func:`runs_needed` estimates the runs an interval needs to reach a half-width (or to
decide a comparison), from the ``1/sqrt(B)`` shrinkage of the interval.

The coverage of each kind against models with a closed-form truth is a statistical
test (``tests/statistical/test_interval_coverage.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm, t

__all__ = [
    "CONFIDENCE",
    "Interval",
    "bootstrap_interval",
    "decide",
    "mean_interval",
    "rate_interval",
    "ratio_interval",
    "rms_interval",
    "runs_needed",
]

#: The two-sided confidence of every interval ftnav reports.
CONFIDENCE = 0.95

#: Bootstrap replicates and the generator's seed (reproducible intervals).
BOOTSTRAP_REPLICATES = 2000
BOOTSTRAP_SEED = 20261203


@dataclass(frozen=True, slots=True)
class Interval:
    """A metric's value with its two-sided confidence interval.

    Attributes
    ----------
    value : the point estimate (as reported without the interval).
    lo, hi : the interval's bounds (NaN where it cannot be formed, e.g. one run).
    runs : the independent runs it rests on.
    method : ``"t"``, ``"t-rms"``, ``"wilson-cluster"`` or ``"bootstrap"`` (module
        docstring).
    """

    value: float
    lo: float
    hi: float
    runs: int
    method: str

    @property
    def half_width(self) -> float:
        """Half the interval's width (NaN without an interval)."""
        return 0.5 * (self.hi - self.lo)

    def excludes(self, threshold: float) -> bool:
        """Whether ``threshold`` lies outside the interval (a decided comparison)."""
        return bool(threshold < self.lo or threshold > self.hi)


_NAN = float("nan")


def _t_quantile(runs: int, confidence: float) -> float:
    return float(t.ppf(0.5 + confidence / 2.0, runs - 1))


def mean_interval(per_run: np.ndarray, confidence: float = CONFIDENCE) -> Interval:
    """Student-t interval of the mean over runs of ``per_run`` ((B,) values, NaN-free
    runs only; module docstring)."""
    x = np.asarray(per_run, float).ravel()
    x = x[np.isfinite(x)]
    B = x.size
    if B == 0:
        return Interval(_NAN, _NAN, _NAN, 0, "t")
    m = float(x.mean())
    if B < 2:
        return Interval(m, _NAN, _NAN, B, "t")
    h = _t_quantile(B, confidence) * float(x.std(ddof=1)) / math.sqrt(B)
    return Interval(m, m - h, m + h, B, "t")


def rms_interval(per_run_ms: np.ndarray, confidence: float = CONFIDENCE) -> Interval:
    """Interval of ``sqrt(mean over runs of the per-run mean squares)``: the t interval
    of the mean square, through the square root (its lower bound kept ≥ 0)."""
    ms = mean_interval(per_run_ms, confidence)
    root = math.sqrt(ms.value) if ms.value >= 0 else _NAN
    lo = math.sqrt(max(ms.lo, 0.0)) if math.isfinite(ms.lo) else _NAN
    hi = math.sqrt(ms.hi) if math.isfinite(ms.hi) else _NAN
    return Interval(root, lo, hi, ms.runs, "t-rms")


def ratio_interval(
    numerator: np.ndarray,
    denominator: np.ndarray,
    root: bool = False,
    confidence: float = CONFIDENCE,
) -> Interval:
    """Interval of the ratio of two means over the same runs, ``Σ a_b / Σ d_b`` (paired:
    a method's error with and without a fault, or against another method on the same
    noise), by Fieller's theorem with Student's quantile (the set of ``r`` for which
    ``ā - r d̄`` is not significantly non-zero; Fieller 1954).  ``root``: the square
    root of the ratio (a ratio of RMS from the per-run mean squares), its bounds mapped
    through the (monotone) root.  NaN bounds when the denominator's mean is not
    significantly positive (the set is unbounded)."""
    a = np.asarray(numerator, float).ravel()
    d = np.asarray(denominator, float).ravel()
    keep = np.isfinite(a) & np.isfinite(d)
    a, d = a[keep], d[keep]
    B = int(a.size)
    method = "fieller-rms" if root else "fieller"
    if B == 0 or d.mean() <= 0:
        return Interval(_NAN, _NAN, _NAN, B, method)
    am, dm = float(a.mean()), float(d.mean())
    r = am / dm
    lo = hi = _NAN
    if B >= 2:
        q2 = _t_quantile(B, confidence) ** 2
        c = np.cov(a, d) / B  # the variances and covariance of the two means
        A = dm * dm - q2 * c[1, 1]
        b = am * dm - q2 * c[0, 1]
        disc = b * b - A * (am * am - q2 * c[0, 0])
        if -1e-12 * b * b <= disc < 0.0:  # a ratio constant over the runs: 0, but rounded
            disc = 0.0
        if A > 0 and disc >= 0:
            lo, hi = (b - math.sqrt(disc)) / A, (b + math.sqrt(disc)) / A
    if not root:
        return Interval(r, lo, hi, B, method)
    lo = math.sqrt(max(lo, 0.0)) if math.isfinite(lo) else _NAN
    hi = math.sqrt(hi) if math.isfinite(hi) else _NAN
    return Interval(math.sqrt(r), lo, hi, B, method)


def decide(interval: Interval, threshold: float, holds_below: bool) -> bool | None:
    """A comparison ``value < threshold`` (``holds_below``) or ``value > threshold``
    decided by its interval: True when the whole interval is on the holding side, False
    when it is wholly on the other, None (undecided) when it contains the threshold or
    there is no interval."""
    if not (math.isfinite(interval.lo) and math.isfinite(interval.hi)):
        return None
    if interval.hi < threshold:
        return holds_below
    if interval.lo > threshold:
        return not holds_below
    return None


def _wilson(p: float, n: float, z: float) -> tuple[float, float]:
    den = 1.0 + z * z / n
    centre = (p + z * z / (2.0 * n)) / den
    half = z * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def rate_interval(
    successes: np.ndarray, trials: np.ndarray, confidence: float = CONFIDENCE
) -> Interval:
    """Wilson interval of a rate pooled over runs, with the cluster design effect.

    Parameters
    ----------
    successes, trials : (B,) per-run counts (e.g. alarmed fault epochs and fault
        epochs); runs without a trial are left out.

    Returns
    -------
    Interval
        ``value`` the pooled rate ``Σ successes / Σ trials``; the Wilson bounds with
        ``n_eff = p̂(1-p̂) / Var(p̂)`` trials, ``Var(p̂)`` the ratio estimator's
        between-run variance ``B/(B-1) Σ (a_b - p̂ n_b)² / (Σ n_b)²``, ``n_eff`` kept
        within ``[B, Σ n_b]``; every trial independent when the runs show no spread
        (p̂ = 0 or 1: nothing to estimate a clustering from).
    """
    a = np.asarray(successes, float).ravel()
    n = np.asarray(trials, float).ravel()
    keep = n > 0
    a, n = a[keep], n[keep]
    B, total = int(a.size), float(n.sum())
    if B == 0:
        return Interval(_NAN, _NAN, _NAN, 0, "wilson-cluster")
    p = float(a.sum()) / total
    if B < 2:
        return Interval(p, _NAN, _NAN, B, "wilson-cluster")
    var = B / (B - 1) * float(np.sum((a - p * n) ** 2)) / total**2
    binomial = p * (1.0 - p)
    # no between-run spread (every run the same fraction, e.g. no alarm at all): no
    # evidence of clustering, the trials count as independent (the rule-of-three bound)
    n_eff = total if var <= 0.0 or binomial <= 0.0 else binomial / var
    n_eff = min(max(n_eff, float(B)), total)
    # the variance rests on B runs: Student's quantile with B - 1 degrees of freedom
    # (Korn & Graubard 1998), the normal one when the trials are independent
    z = float(norm.ppf(0.5 + confidence / 2.0))
    if n_eff < total:
        z = _t_quantile(B, confidence)
    lo, hi = _wilson(p, n_eff, z)
    return Interval(p, min(lo, p), max(hi, p), B, "wilson-cluster")


def bootstrap_interval(
    per_run: list[np.ndarray],
    q: float | None = None,
    confidence: float = CONFIDENCE,
    replicates: int = BOOTSTRAP_REPLICATES,
) -> Interval:
    """Percentile bootstrap over runs of the mean (``q`` None) or the ``q`` quantile
    (linear interpolation) of events pooled over runs.

    Parameters
    ----------
    per_run : one (E_b,) array of events per run (e.g. its detection delays; empty
        when the run had none).

    Returns
    -------
    Interval
        ``value`` the statistic of all runs' events; the bounds the
        ``(1 ± confidence)/2`` quantiles of the statistic over ``replicates`` resamples
        of the runs (a fixed generator: the same interval every time).
    """
    B = len(per_run)
    width = max((len(x) for x in per_run), default=0)
    if B == 0 or width == 0:
        return Interval(_NAN, _NAN, _NAN, B, "bootstrap")
    table = np.full((B, width), np.nan)
    for b, x in enumerate(per_run):
        table[b, : len(x)] = x

    def stat(rows: np.ndarray) -> np.ndarray:
        ok = np.isfinite(rows)
        count = ok.sum(-1)
        out = np.full(rows.shape[0], np.nan)
        some = count > 0
        if q is None:
            out[some] = np.where(ok, rows, 0.0)[some].sum(-1) / count[some]
        else:  # NaN sorts last: the quantile of each row's first ``count`` values
            s = np.sort(rows[some], -1)
            pos = q * (count[some] - 1)
            below = np.floor(pos).astype(int)
            above = np.minimum(below + 1, count[some] - 1)
            r = np.arange(s.shape[0])
            frac = pos - below
            out[some] = s[r, below] * (1.0 - frac) + s[r, above] * frac
        return out

    value = float(stat(table.reshape(1, -1))[0])
    if B < 2 or not math.isfinite(value):
        return Interval(value, _NAN, _NAN, B, "bootstrap")
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    picks = table[rng.integers(0, B, (replicates, B))].reshape(replicates, -1)
    stats = stat(picks)
    stats = stats[np.isfinite(stats)]
    lo, hi = np.quantile(stats, [0.5 - confidence / 2.0, 0.5 + confidence / 2.0])
    return Interval(value, float(min(lo, value)), float(max(hi, value)), B, "bootstrap")


def runs_needed(interval: Interval, half_width: float) -> int | None:
    """Runs for ``interval``'s half-width to shrink to ``half_width`` (∝ 1/√B); None
    when it cannot be estimated (no interval, or a zero target)."""
    h = interval.half_width
    if not (math.isfinite(h) and half_width > 0 and interval.runs > 0):
        return None
    return max(interval.runs, math.ceil(interval.runs * (h / half_width) ** 2))
