"""Coverage of the 95 % intervals of :mod:`ftnav.eval.intervals` (issue 23).

Oracle: models whose metric has a closed-form true value.  Each case simulates 2 000
campaigns of ``B = 20`` runs (seeded), forms each campaign's interval from its per-run
statistics as the evaluation does, and counts how often it covers the truth.  The
coverage must be 95 % ± 2 %; the Monte Carlo standard error of a coverage of 0.95 over
2 000 campaigns is 0.49 %, so the band is four standard errors wide.

* RMSE: e ~ N(0, σ²) white over K = 50 epochs; the mean over runs of the per-run RMSE
  has truth ``E[√(χ²_K/K)] σ = σ √(2/K) Γ((K+1)/2) / Γ(K/2)``; the ensemble RMS has
  truth σ.
* Rates: alarms per epoch Bernoulli(p) independent (``p`` = 0.05, 0.5, 0.9), and
  clustered: each run draws its own ``p_b ~ Beta(a, b)`` (a detector whose rate varies
  from run to run; truth ``a/(a+b)``), 100 epochs per run.
* ANEES: NEES χ²(3) white, scaled per run by ``c_b = exp(N(0, 0.3²))`` (runs that are
  more and less consistent); truth ``3 exp(0.3²/2)``.
* Ratios of paired means (a fault window's RMS against the fault-free twin's on the
  same noise): closed-form ratio of the expectations (and the measured shortfall under
  strong skew with 20 runs, stated).
* Median detection delay (bootstrap over runs): one event per run, detected with
  probability 0.8 after an exponential delay of mean 2 s; truth ``2 ln 2``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import gammaln

from ftnav.eval.intervals import (
    Interval,
    bootstrap_interval,
    mean_interval,
    rate_interval,
    ratio_interval,
    rms_interval,
    runs_needed,
)

CAMPAIGNS, B = 2000, 20
TOLERANCE = 0.02


def _coverage(intervals: list[Interval], truth: float) -> float:
    return float(np.mean([i.lo <= truth <= i.hi for i in intervals]))


def _miss(intervals: list[Interval], truth: float) -> float:
    """How far the intervals' coverage of ``truth`` is from 95 %."""
    return abs(_coverage(intervals, truth) - 0.95)


def test_rmse_intervals_cover_the_closed_form_truth():
    rng = np.random.default_rng(1)
    sigma, K = 0.7, 50
    e = rng.normal(0.0, sigma, (CAMPAIGNS, B, K))
    ms = (e**2).mean(-1)
    truth = sigma * math.sqrt(2 / K) * math.exp(gammaln((K + 1) / 2) - gammaln(K / 2))
    assert _miss([mean_interval(r) for r in np.sqrt(ms)], truth) <= TOLERANCE
    assert _miss([rms_interval(r) for r in ms], sigma) <= TOLERANCE


@pytest.mark.parametrize("p", [0.05, 0.5, 0.9])
def test_rate_intervals_cover_independent_trials(p):
    rng = np.random.default_rng(2)
    k = rng.binomial(50, p, (CAMPAIGNS, B))
    assert _miss([rate_interval(kk, np.full(B, 50)) for kk in k], p) <= TOLERANCE


@pytest.mark.parametrize(("a", "b"), [(2, 8), (1, 30), (50, 50)])
def test_rate_intervals_cover_a_rate_that_varies_between_runs(a, b):
    rng = np.random.default_rng(3)
    k = rng.binomial(100, rng.beta(a, b, (CAMPAIGNS, B)))
    assert _miss([rate_interval(kk, np.full(B, 100)) for kk in k], a / (a + b)) <= TOLERANCE


def test_anees_intervals_cover_the_closed_form_truth():
    rng = np.random.default_rng(4)
    s = 0.3
    scale = np.exp(rng.normal(0.0, s, (CAMPAIGNS, B, 1)))
    per_run = (rng.chisquare(3, (CAMPAIGNS, B, 100)) * scale).mean(-1)
    assert _miss([mean_interval(r) for r in per_run], 3 * math.exp(s * s / 2)) <= TOLERANCE


def test_ratio_intervals_cover_the_ratio_of_paired_means():
    """A fault window's RMS against the fault-free twin's on the same noise: per run
    the mean squares ``s_b (1 + u_b)`` and ``s_b`` with a shared ``s_b ~ χ²(10)/10``
    and ``u_b ~ χ²(20)/20``, so the ratio of RMS has truth ``√2``; and the plain ratio
    of means of paired normal values, truth 2."""
    rng = np.random.default_rng(7)
    s = rng.chisquare(10, (CAMPAIGNS, B)) / 10
    faulty = s * (1 + rng.chisquare(20, (CAMPAIGNS, B)) / 20)
    rms_ratios = [ratio_interval(f, c, root=True) for f, c in zip(faulty, s, strict=True)]
    assert _miss(rms_ratios, math.sqrt(2)) <= TOLERANCE
    d = rng.normal(1.0, 0.2, (CAMPAIGNS, B))
    a = 2 * d + rng.normal(0.0, 0.3, (CAMPAIGNS, B))
    assert _miss([ratio_interval(x, y) for x, y in zip(a, d, strict=True)], 2.0) <= TOLERANCE


def test_a_ratio_constant_over_the_runs_has_a_point_interval():
    """Closed form: two methods identical in every run (the β-invariance of a reset every
    epoch, spec §1.6) or proportional: Fieller's discriminant is 0, so the interval is the
    ratio itself, not unbounded (its rounding made ``seed000``'s reset-1 claim undecided)."""
    rng = np.random.default_rng(3)
    for r in (1.0, 0.7, 3.0):
        for _ in range(50):
            d = rng.chisquare(10, B) / 10
            ci = ratio_interval(r * d, d)
            assert ci.lo == pytest.approx(r, rel=1e-6) and ci.hi == pytest.approx(r, rel=1e-6)


def test_ratio_intervals_under_strong_skew_are_short_with_few_runs():
    """The limit stated in :mod:`ftnav.eval.intervals`: with ``u_b ~ χ²(4)/4`` (a fault
    whose effect varies a lot between runs) 20 runs cover about 92 %, not 95 % (no
    normal-theory or percentile-bootstrap interval measured did better: delta 91 %,
    bootstrap 89 %); 80 runs restore it."""
    rng = np.random.default_rng(8)
    for runs, low, high in ((20, 0.90, 0.94), (80, 0.93, 0.97)):
        s = rng.chisquare(10, (CAMPAIGNS, runs)) / 10
        faulty = s * (1 + rng.chisquare(4, (CAMPAIGNS, runs)) / 4)
        cover = _coverage(
            [ratio_interval(f, c, root=True) for f, c in zip(faulty, s, strict=True)],
            math.sqrt(2),
        )
        assert low <= cover <= high, (runs, cover)


def test_median_delay_intervals_cover_the_closed_form_truth():
    rng = np.random.default_rng(5)
    detected = rng.random((CAMPAIGNS, B)) < 0.8
    delay = rng.exponential(2.0, (CAMPAIGNS, B))
    intervals = [
        bootstrap_interval([delay[c, b : b + 1][detected[c, b : b + 1]] for b in range(B)], 0.5)
        for c in range(CAMPAIGNS)
    ]
    assert _miss(intervals, 2 * math.log(2)) <= TOLERANCE


def test_an_interval_shrinks_as_one_over_root_runs():
    """``runs_needed`` against the t interval it predicts (the same population)."""
    rng = np.random.default_rng(6)
    first = mean_interval(rng.normal(1.0, 1.0, 20))
    need = runs_needed(first, first.half_width / 2)
    assert need is not None and 60 <= need <= 100  # ≈ 4 × 20, the t quantile aside
    later = mean_interval(rng.normal(1.0, 1.0, need))
    assert later.half_width == pytest.approx(first.half_width / 2, rel=0.35)


def test_no_interval_from_one_run_or_none():
    assert math.isnan(mean_interval(np.array([1.0])).lo)
    assert math.isnan(rate_interval(np.array([1]), np.array([0])).value)
    assert math.isnan(bootstrap_interval([np.empty(0)] * 3, 0.5).value)
