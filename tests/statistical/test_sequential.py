"""The sequential tests of spec §3.3 against their published run lengths and Monte Carlo.

Oracles:

* the published average run lengths of the two-sided CUSUM with k = 0.5, h = 5 on
  N(μ, 1) (Montgomery, *Introduction to Statistical Quality Control*, table 9.11; the
  issue's figures): ARL₀ ≈ 465-471, 38 at a 0.5σ shift, 10.4 at 1σ, 4.01 at 2σ;
* Siegmund's approximation (an independent formula) against the Brook–Evans chain;
* Monte Carlo of :class:`~ftnav.fdi.sequential.CusumDetector` itself (the code that runs
  in the filters), within 3.5 standard errors: the run length of a CUSUM is close to
  geometric, so its standard deviation is about its mean and the standard error of the
  mean of n run lengths is ``mean/√n``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.fdi.sequential import (
    CusumDetector,
    GlrDetector,
    cusum_arl,
    cusum_threshold,
    glr_threshold,
    siegmund_arl,
    variance_cusum_arl,
    variance_threshold,
)
from ftnav.fusion.config import Cusum, Glr
from ftnav.fusion.detection import Detection
from ftnav.model.system import Sensor


def two_sided(h: float, k: float, mu: float) -> float:
    """ARL of the two-sided CUSUM from its one-sided ARLs (Lucas & Crosier)."""
    up, down = cusum_arl(h, k, mu), cusum_arl(h, k, -mu)
    return 1.0 / (1.0 / up + 1.0 / down)


def test_brook_evans_chain_gives_the_published_run_lengths():
    assert 465.0 <= two_sided(5.0, 0.5, 0.0) <= 471.0
    assert two_sided(5.0, 0.5, 1.0) == pytest.approx(10.4, abs=0.15)
    assert two_sided(5.0, 0.5, 0.5) == pytest.approx(38.0, abs=0.5)
    assert two_sided(5.0, 0.5, 2.0) == pytest.approx(4.01, abs=0.02)


@pytest.mark.parametrize("mu", [0.0, 0.5, 1.0])
def test_chain_agrees_with_siegmund(mu):
    # Siegmund's formula is an approximation that drifts away at large shifts (3 % at 2σ,
    # where the chain gives the published 4.01)
    assert cusum_arl(5.0, 0.5, mu) == pytest.approx(siegmund_arl(5.0, 0.5, mu), rel=0.02)


def test_thresholds_invert_the_run_length():
    for arl0, k in ((465.4, 0.5), (1e4, 0.5), (1e5, 0.25)):
        assert cusum_arl(cusum_threshold(arl0 * 2, k), k) == pytest.approx(arl0 * 2, rel=1e-4)
    h = variance_threshold(2e4, 4.0, 3)
    assert variance_cusum_arl(h, 4.0, 3) == pytest.approx(2e4, rel=1e-4)


def run_lengths(detector, mu: float, runs: int, rng, m: int = 1, scale: float = 1.0) -> np.ndarray:
    """First-alarm times of ``runs`` independent runs of one aid on N(mu, scale²)."""
    state = detector.init(runs, 1)
    length = np.zeros(runs, int)
    alive = np.ones(runs, bool)
    tested = np.ones((runs, 1), bool)
    k = 0
    while alive.any() and k < 100_000:
        k += 1
        nu = mu + scale * rng.standard_normal((runs, m))
        state, out = detector.step(state, [nu], tested)
        fired = alive & out.raw[:, 0]
        length[fired] = k
        alive &= ~fired
    assert not alive.any()
    return length


@pytest.mark.parametrize(("mu", "published"), [(0.0, 465.4), (1.0, 10.4), (0.5, 38.0)])
def test_cusum_detector_has_the_published_run_lengths(mu, published):
    # arl0 = 465.4 gives each one-sided CUSUM ARL₀ 930.8: h = 5.0
    det = CusumDetector([1], arl0=465.4, drift=0.5)
    assert det.h_mean[0] == pytest.approx(5.0, abs=2e-3)
    rng = np.random.default_rng(20)
    runs = 4000 if mu == 0.0 else 2000
    rl = run_lengths(det, mu, runs, rng)
    se = rl.std() / np.sqrt(runs)
    assert abs(rl.mean() - published) < 3.5 * se, (rl.mean(), published, se)


def test_variance_cusum_meets_its_arl0_and_detects_a_noise_step():
    det = CusumDetector([3], arl0=300.0, drift=0.5, variance_ratio=4.0)
    rng = np.random.default_rng(3)
    rl = run_lengths(det, 0.0, 3000, rng, m=3)
    se = rl.std() / np.sqrt(rl.size)
    # the union of 7 nearly independent CUSUMs: ARL₀ within a few % of the target
    assert abs(rl.mean() - 300.0) < 3.5 * se + 0.05 * 300.0, rl.mean()
    slow = run_lengths(CusumDetector([3], arl0=300.0, drift=0.5), 0.0, 500, rng, m=3, scale=2.0)
    fast = run_lengths(det, 0.0, 500, rng, m=3, scale=2.0)
    assert fast.mean() < 0.5 * slow.mean()  # σ x2 is seen by the variance CUSUM first


def test_glr_false_alarms_no_more_often_than_its_setting():
    det = GlrDetector([3], arl0=200.0, window=16, memory=0)  # the textbook test
    assert det.h[0] == pytest.approx(glr_threshold(200.0, 16, 3))
    rng = np.random.default_rng(7)
    rl = run_lengths(det, 0.0, 1000, rng, m=3)
    assert rl.mean() >= 200.0  # Bonferroni over the windows: at least the target
    shifted = run_lengths(det, 1.0, 500, rng, m=3)
    assert shifted.mean() < 10.0  # a 1σ shift on every component: caught in a few tests


def test_glr_sees_a_small_shift_a_single_epoch_test_misses():
    rng = np.random.default_rng(11)
    glr = GlrDetector([1], arl0=1e3, window=64, memory=0)
    rl = run_lengths(glr, 0.5, 400, rng)
    # a single-epoch χ²(1) test at the same per-test rate 1e-3 fires on a 0.5σ shift
    # once in ~450 tests (P(|x + 0.5| > 3.29) ≈ 2.2e-3)
    assert rl.mean() < 60.0


def _ar1(rng, runs: int, steps: int, rho: float) -> np.ndarray:
    """(steps, runs) unit-variance AR(1) sequences: correlated innovations."""
    x = np.zeros((steps, runs))
    x[0] = rng.standard_normal(runs)
    e = rng.standard_normal((steps, runs)) * np.sqrt(1.0 - rho**2)
    for k in range(1, steps):
        x[k] = rho * x[k - 1] + e[k]
    return x


def _alarms(det, x: np.ndarray, start: int = 0) -> np.ndarray:
    """(runs,) raw alarms of one aid fed the sequences ``x`` (steps, runs) after ``start``."""
    runs = x.shape[1]
    state, tested = det.init(runs, 1), np.ones((runs, 1), bool)
    count = np.zeros(runs, int)
    for k in range(x.shape[0]):
        state, out = det.step(state, [x[k][:, None]], tested)
        count += out.raw[:, 0] & (k >= start)
    return count


def test_glr_learns_the_null_level_of_correlated_innovations():
    """AR(1) innovations, ρ = 0.8: the long-run variance is (1 + ρ)/(1 − ρ) = 9 times the
    white one, so the textbook GLR alarms far more often than its setting; learning each
    window's null level (the default) brings the rate after the warm-up back to the order
    of the setting, and a 3σ mean shift after the warm-up is still caught."""
    rng = np.random.default_rng(5)
    runs, steps, warm = 200, 4000, 2000
    x = _ar1(rng, runs, steps, 0.8)
    white = GlrDetector([1], arl0=1e3, window=32, memory=0)
    learned = GlrDetector([1], arl0=1e3, window=32)
    rate_white = _alarms(white, x, warm).sum() / (runs * (steps - warm))
    rate_learned = _alarms(learned, x, warm).sum() / (runs * (steps - warm))
    assert rate_white > 20 * 1e-3, rate_white
    assert rate_learned < 3 * 1e-3, rate_learned
    shifted = x.copy()
    shifted[warm:] += 3.0
    caught = _alarms(learned, shifted[: warm + 32], warm)
    assert (caught > 0).mean() >= 0.95


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="arl0"):
        CusumDetector([1], arl0=0.5)
    with pytest.raises(ValueError, match="drift"):
        CusumDetector([1], arl0=100.0, drift=0.0)
    with pytest.raises(ValueError, match="variance_ratio"):
        CusumDetector([1], arl0=100.0, variance_ratio=1.0)
    with pytest.raises(ValueError, match="window"):
        GlrDetector([1], arl0=100.0, window=0)


@pytest.mark.parametrize(
    "config", [Cusum(kind="cusum", arl0=1e4), Glr(kind="glr", arl0=1e4, window=16)]
)
def test_a_gated_constraint_is_left_to_its_gate(config):
    """The sequential tests run on the aids of a device only (:mod:`ftnav.fusion.detection`):
    a 4σ shift of a gated pseudo-measurement's innovation (a constraint in a turn) never
    raises them, while the same shift of a device's aid alarms within the closed-form
    epochs — the first at which the statistic passes the threshold (GLR: ``w μ²`` over
    the window w = 1 at once; CUSUM: ``n (μ − k) > h``)."""
    device = Sensor("gnss", None, np.eye(2), np.eye(2))
    constraint = Sensor("nhc", None, np.eye(2), np.eye(2), gate=1e-3)
    detection = Detection(config, sensors=(device, constraint))
    state = detection.init(1, 2)
    mu, tested = 4.0, np.ones((1, 2), dtype=bool)
    shifted = [np.full((1, 2), mu), np.full((1, 2), mu)]
    zeros = np.zeros((1, 2))
    first, flags = None, []
    for k in range(1, 40):
        state, out = detection.step(state, zeros, zeros, tested, zeros, innovations=shifted)
        assert out is not None
        flags.append(bool(out.flag[0, 1]))
        if first is None and out.flag[0, 0]:
            first = k
    assert not any(flags)
    if isinstance(config, Glr):  # ‖(μ, μ)‖² = 2μ² = 32 against the χ²(2) threshold
        assert 2 * mu**2 > glr_threshold(1e4, 16, 2)
        assert first == 1
    else:  # each component's CUSUM gains μ − k per epoch (two components: one alarms)
        h = cusum_threshold(2 * 2 * 1e4, 0.5)
        assert first == int(np.floor(h / (mu - 0.5))) + 1
