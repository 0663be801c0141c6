"""Closed-form checks of the spec §11 metrics against hand-worked answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from ftnav.eval.metrics import (
    chi2_band,
    detection_stats,
    error_stats,
    nees,
    nees_stats,
    position_norms,
)

# ---------------------------------------------------------------------------
# RMSE
# ---------------------------------------------------------------------------


def test_alternating_unit_error_gives_unit_rmse():
    K = 10
    e = np.where(np.arange(K) % 2 == 0, 1.0, -1.0)
    err = np.stack([e, -e], axis=-1)[None]  # (1, K, 2)
    s = error_stats(err, np.ones(K, dtype=bool))
    np.testing.assert_array_equal(s.rmse, [1.0, 1.0])
    np.testing.assert_array_equal(s.ensemble_rmse, [1.0, 1.0])
    np.testing.assert_array_equal(s.max_abs, [1.0, 1.0])
    assert s.rmse_per_run.shape == (1, 2)


def test_window_selects_epochs():
    err = np.array([1.0, 2.0, 3.0, 4.0])[None, :, None]
    window = np.array([False, False, True, True])
    s = error_stats(err, window)
    assert s.rmse[0] == pytest.approx(np.sqrt((9.0 + 16.0) / 2.0))
    assert s.ensemble_rmse[0] == pytest.approx(np.sqrt(12.5))
    assert s.max_abs[0] == 4.0
    full = error_stats(err, np.ones(4, dtype=bool))
    assert full.rmse[0] == pytest.approx(np.sqrt(30.0 / 4.0))


def test_run_mean_vs_ensemble_rmse():
    err = np.stack([np.ones((5, 1)), 3.0 * np.ones((5, 1))])  # (2, 5, 1)
    s = error_stats(err, np.ones(5, dtype=bool))
    np.testing.assert_allclose(s.rmse_per_run, [[1.0], [3.0]])
    assert s.rmse[0] == pytest.approx(2.0)
    assert s.ensemble_rmse[0] == pytest.approx(np.sqrt(5.0))
    assert s.max_abs[0] == 3.0


def test_position_norms_of_a_3_4_12_error():
    """e = (3, 4, 12) m: horizontal 5 m, 3-D 13 m; their RMS is the horizontal RMS."""
    e = np.array([[[3.0, 4.0, 12.0], [0.0, 0.0, 0.0]]])  # (1, 2, 3)
    norms = position_norms(e)
    np.testing.assert_allclose(norms, [[[5.0, 13.0], [0.0, 0.0]]])
    s = error_stats(norms, np.ones(2, dtype=bool))
    # sqrt(mean_k (e_E² + e_N²)) = sqrt(25 / 2), and likewise sqrt(169 / 2)
    np.testing.assert_allclose(s.rmse, [np.sqrt(12.5), np.sqrt(84.5)])
    with pytest.raises(ValueError, match="shape"):
        position_norms(np.zeros((2, 2)))


def test_empty_window_gives_nan():
    s = error_stats(np.ones((2, 3, 4)), np.zeros(3, dtype=bool))
    assert s.rmse.shape == (4,) and s.rmse_per_run.shape == (2, 4)
    assert all(np.isnan(f).all() for f in s)


# ---------------------------------------------------------------------------
# NEES
# ---------------------------------------------------------------------------


def test_nees_hand_example():
    P = np.diag([4.0, 1.0])
    e = np.array([2.0, 1.0])
    assert nees(e, P) == pytest.approx(2.0)  # 4/4 + 1/1


def test_nees_broadcasts_over_batch():
    P = np.diag([4.0, 1.0])
    e = np.array([[2.0, 1.0], [0.0, 3.0], [4.0, 0.0]])  # (3, 2)
    np.testing.assert_allclose(nees(e, P), [2.0, 9.0, 4.0])


def test_chi2_band_matches_scipy():
    lo, hi = chi2_band(3 * 50, 50)
    assert lo == pytest.approx(chi2.ppf(0.025, 150) / 50)
    assert hi == pytest.approx(chi2.ppf(0.975, 150) / 50)
    assert lo < 3.0 < hi


def test_nees_stats_hand_example():
    v = np.array([[1.0, 2.0, 100.0], [3.0, 4.0, 100.0]])  # (B=2, K=3)
    s = nees_stats(v, n=2, window=np.array([True, True, False]))
    np.testing.assert_allclose(s.nees_mean, [2.0, 3.0, 100.0])
    assert s.anees == pytest.approx(2.5)
    assert s.band == chi2_band(4, 2)
    lo, hi = s.band
    expected = np.mean([(lo <= m <= hi) for m in (2.0, 3.0)])
    assert s.in_band_fraction == pytest.approx(expected)


def test_nees_of_exact_gaussian_errors_is_consistent():
    rng = np.random.default_rng(20240611)
    M, K, n = 50, 500, 3
    A = rng.standard_normal((K, n, n))
    P = A @ np.swapaxes(A, -1, -2) + 0.5 * np.eye(n)  # (K, n, n) SPD
    L = np.linalg.cholesky(P)
    err = np.einsum("kij,mkj->mki", L, rng.standard_normal((M, K, n)))  # (M, K, n)
    v = nees(err, P)
    assert v.shape == (M, K)
    s = nees_stats(v, n, np.ones(K, dtype=bool))
    assert s.in_band_fraction >= 0.93
    sigma = np.sqrt(2.0 * n / (M * K))
    assert abs(s.anees - n) <= 3.0 * sigma


# ---------------------------------------------------------------------------
# Fault detection
# ---------------------------------------------------------------------------

TIMES = np.arange(1.0, 101.0)  # t = 1..100 s, dt = 1 s
WINDOWS = [(10.0, 20.0)]


def _spec_flags() -> np.ndarray:
    f = np.zeros(100, dtype=bool)
    f[(TIMES >= 12) & (TIMES <= 19)] = True  # detection at t = 12
    f[TIMES == 50] = True  # one false alarm
    return f


def test_spec_hand_built_alarm_sequence():
    s = detection_stats(_spec_flags()[None], TIMES, WINDOWS, grace=10.0)
    assert s.events == 1
    assert s.mean_delay_s == pytest.approx(2.0)
    assert s.median_delay_s == pytest.approx(2.0)
    assert s.p95_delay_s == pytest.approx(2.0)
    assert s.missed_rate == 0.0
    assert s.event_rate == 1.0
    assert s.rate == pytest.approx(8.0 / 10.0)
    # N_clean = 100 - 10 fault epochs - 10 grace epochs (t = 20..29) = 80
    assert s.false_alarm_rate == pytest.approx(1.0 / 80.0)
    assert s.false_alarms_per_hour == pytest.approx(3600.0 / 80.0)
    assert s.mean_recovery_s == pytest.approx(0.0)  # flag False at t = 20


def test_missed_event_and_batch_of_two():
    missed = np.zeros(100, dtype=bool)
    s1 = detection_stats(missed[None], TIMES, WINDOWS, grace=10.0)
    assert s1.missed_rate == 1.0 and s1.event_rate == 0.0
    assert np.isnan(s1.mean_delay_s)
    assert s1.rate == 0.0 and s1.false_alarm_rate == 0.0

    s = detection_stats(np.stack([_spec_flags(), missed]), TIMES, WINDOWS, grace=10.0)
    assert s.events == 2
    assert s.event_rate == pytest.approx(0.5)
    assert s.missed_rate == pytest.approx(0.5)
    assert s.mean_delay_s == pytest.approx(2.0)  # detected events only
    assert s.rate == pytest.approx(8.0 / 20.0)
    assert s.false_alarm_rate == pytest.approx(1.0 / 160.0)


def test_recovery_when_flag_lingers_three_epochs():
    f = np.zeros(100, dtype=bool)
    f[(TIMES >= 12) & (TIMES <= 22)] = True  # on at t = 20, 21, 22; off at 23
    s = detection_stats(f[None], TIMES, WINDOWS, grace=10.0)
    assert s.mean_recovery_s == pytest.approx(3.0)
    assert s.false_alarm_rate == 0.0  # lingering alarms fall in the grace period


def test_recovery_when_flag_never_clears():
    f = np.zeros(100, dtype=bool)
    f[TIMES >= 15] = True
    s = detection_stats(f[None], TIMES, WINDOWS, grace=10.0)
    assert s.mean_delay_s == pytest.approx(5.0)
    assert s.mean_recovery_s == pytest.approx((100.0 + 1.0) - 20.0)


def test_a_fault_lasting_past_the_run_has_no_recovery():
    # window [90, 150) in a run ending at 100: detected, but nothing to recover from
    # (was t_end - t_off = -49 s, printed as a recovery time)
    f = np.zeros((2, 100), dtype=bool)
    f[:, 95:] = True
    s = detection_stats(f, TIMES, [(90.0, 150.0), *WINDOWS], grace=10.0)
    assert s.mean_delay_s == pytest.approx(6.0)  # first alarm at t = 96; [10, 20) missed
    assert np.isnan(s.mean_recovery_s)  # [10, 20) never flagged: nothing to recover from
    alone = detection_stats(f, TIMES, [(90.0, 150.0)], grace=10.0)
    assert alone.events == 2 and np.isnan(alone.mean_recovery_s)


def test_a_run_that_never_flagged_the_aid_has_no_recovery():
    """Pd 0 printed a recovery of 0.0 s (found by a user's try): nothing was held, so
    there is nothing to recover from; the detected run's recovery is the mean alone."""
    f = np.zeros((2, 100), dtype=bool)
    f[0, (TIMES >= 12) & (TIMES <= 22)] = True  # run 0: on until t = 22, off at 23
    s = detection_stats(f, TIMES, WINDOWS, grace=10.0)
    assert s.events == 2 and s.missed_rate == pytest.approx(0.5)
    assert s.mean_recovery_s == pytest.approx(3.0)
    assert np.isnan(detection_stats(f[1:], TIMES, WINDOWS, grace=10.0).mean_recovery_s)


def test_an_aid_flagged_again_as_it_comes_back_has_not_recovered():
    """A fault the filter followed (no flag at its end), then the aid's return to the
    truth flagged for 5 s inside the grace period: recovered when that flag clears
    (t = 25 s), not at t_off (0 s, found by a user's try on the drive: 0.08 s against a
    10.5 s lock-out).  An undetected fault whose return is flagged counts the same."""
    f = np.zeros(100, dtype=bool)
    f[(TIMES >= 12) & (TIMES <= 14)] = True  # detected, then followed
    f[(TIMES >= 21) & (TIMES <= 24)] = True  # the return flagged: off at t = 25
    assert detection_stats(f[None], TIMES, WINDOWS, grace=10.0).mean_recovery_s == 5.0
    f[(TIMES >= 12) & (TIMES <= 14)] = False  # undetected: the same recovery
    s = detection_stats(f[None], TIMES, WINDOWS, grace=10.0)
    assert s.missed_rate == 1.0 and s.mean_recovery_s == 5.0
    assert s.false_alarm_rate == 0.0  # the return's flags are in the grace period


def test_no_windows_gives_nan_event_metrics():
    f = np.zeros((3, 100), dtype=bool)
    f[:, :2] = True
    s = detection_stats(f, TIMES, [], grace=10.0)
    assert s.events == 0
    assert np.isnan(s.rate) and np.isnan(s.event_rate) and np.isnan(s.missed_rate)
    assert np.isnan(s.mean_recovery_s)
    assert s.false_alarm_rate == pytest.approx(2.0 / 100.0)


def test_a_recorded_fault_with_nothing_to_detect_is_no_event():
    """On a recording an ``outage`` fault (the aid absent, not wrong) and a fault inside
    a GNSS outage of the schedule (the aid measured nothing) were counted as missed
    detections: Pd 0, missed rate 1 (found by a user's try on the drive)."""
    from types import SimpleNamespace

    from ftnav.eval.recorded import _detection
    from ftnav.model.scenario import Fault

    times = np.arange(1, 101, dtype=float)
    flag = np.zeros((100, 1), bool)
    flag[(times >= 12) & (times < 15), 0] = True  # the bias [10, 20) detected
    available = np.ones((100, 1), bool)
    available[(times >= 40) & (times < 60), 0] = False  # an outage of the schedule
    faults = [
        Fault("gnss", "bias", 10.0, 20.0, np.ones(6)),
        Fault("gnss", "bias", 45.0, 55.0, np.ones(6)),  # inside the schedule's outage
        Fault("gnss", "outage", 70.0, 80.0, np.zeros(6)),
    ]
    rec = SimpleNamespace(sensor_names=("gnss",), faults=faults, times=times)
    d = _detection(rec, flag, 10.0, available)["gnss"]  # type: ignore[arg-type]
    assert d.events == 1 and d.event_rate == 1.0 and d.missed_rate == 0.0
    everything = _detection(rec, flag, 10.0)["gnss"]  # type: ignore[arg-type]
    assert everything.events == 2  # without the availability only the outage fault goes
