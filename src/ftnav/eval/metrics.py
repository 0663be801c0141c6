"""Monte Carlo evaluation metrics (spec §11).

Pure NumPy functions on arrays with a leading Monte Carlo run axis ``B``:

* :func:`error_stats` -- per-axis RMSE (per run, run-averaged and ensemble) and
  max ``|e|`` over an evaluation window ``W``.
* :func:`position_norms` -- horizontal ``sqrt(e_E² + e_N²)`` and 3-D position error,
  whose :func:`error_stats` give the horizontal and 3-D RMS of spec §11.
* :func:`nees`, :func:`nees_stats`, :func:`chi2_band` -- normalized estimation
  error squared ``eps_k = e_kᵀ P_k⁻¹ e_k``, its run average ``eps_bar_k`` with the
  two-sided chi-square band ``[chi2_{Mn}(0.025), chi2_{Mn}(0.975)] / M`` and the
  time-averaged ANEES.
* :func:`detection_stats` -- detection probability, missed-detection and
  false-alarm rates, detection delay and recovery time of one detector on one
  subsystem against ground-truth fault windows ``[t_on, t_off)``.

Nothing here loops over runs; loops run over fault windows only.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.stats import chi2

from ftnav.core.kalman import prior_nis

__all__ = [
    "ErrorStats",
    "NeesStats",
    "position_norms",
    "DetectionStats",
    "DetectionEvents",
    "detection_events",
    "summarize_detection",
    "error_stats",
    "nees",
    "nees_stats",
    "chi2_band",
    "detection_stats",
]


# ---------------------------------------------------------------------------
# Estimation error
# ---------------------------------------------------------------------------


class ErrorStats(NamedTuple):
    """Per-axis error statistics over an evaluation window (spec §11).

    Attributes
    ----------
    rmse : (n,) mean over the ``B`` runs of the per-run RMSE, same unit as the error.
    rmse_per_run : (B, n) per-run RMSE ``sqrt(mean_{k in W} e_{j,k}^2)``.
    ensemble_rmse : (n,) ``sqrt`` of the mean of ``e^2`` over runs and window epochs.
    max_abs : (n,) maximum ``|e|`` over runs and window epochs.
    """

    rmse: np.ndarray
    rmse_per_run: np.ndarray
    ensemble_rmse: np.ndarray
    max_abs: np.ndarray


def error_stats(err: np.ndarray, window: np.ndarray) -> ErrorStats:
    """RMSE and max absolute error per axis over an evaluation window (spec §11).

    Parameters
    ----------
    err : (B, K, n) array
        Estimate minus truth for ``B`` Monte Carlo runs, ``K`` epochs and ``n``
        axes (any consistent unit, e.g. m, m/s, rad).
    window : (K,) bool array
        Epochs belonging to the evaluation window ``W``.

    Returns
    -------
    ErrorStats
        See :class:`ErrorStats`.  If ``window`` selects no epoch, every field is
        filled with ``np.nan`` (same shapes); callers should check
        ``window.any()`` first.
    """
    err = np.asarray(err, dtype=float)
    window = np.asarray(window, dtype=bool)
    if err.ndim != 3:
        raise ValueError(f"err must have shape (B, K, n), got {err.shape}")
    B, K, n = err.shape
    if window.shape != (K,):
        raise ValueError(f"window must have shape ({K},), got {window.shape}")
    if not window.any():
        nan_n = np.full(n, np.nan)
        return ErrorStats(nan_n, np.full((B, n), np.nan), nan_n.copy(), nan_n.copy())

    e = err[:, window, :]  # (B, Kw, n)
    sq = e * e
    rmse_per_run = np.sqrt(sq.mean(axis=1))
    return ErrorStats(
        rmse=rmse_per_run.mean(axis=0),
        rmse_per_run=rmse_per_run,
        ensemble_rmse=np.sqrt(sq.mean(axis=(0, 1))),
        max_abs=np.abs(e).max(axis=(0, 1)),
    )


def position_norms(err_enu: np.ndarray) -> np.ndarray:
    """Horizontal and 3-D length of position errors (spec §11 horizontal RMS).

    Parameters
    ----------
    err_enu : (..., 3) array
        Position error East, North, Up (m).

    Returns
    -------
    (..., 2) array
        ``[sqrt(e_E² + e_N²), sqrt(e_E² + e_N² + e_U²)]`` (m).  :func:`error_stats` of
        these gives, per run, ``sqrt(mean_k (e_E² + e_N²))``: the horizontal RMS error.
    """
    e = np.asarray(err_enu, dtype=float)
    if e.shape[-1:] != (3,):
        raise ValueError(f"err_enu must have shape (..., 3), got {e.shape}")
    horizontal = np.hypot(e[..., 0], e[..., 1])
    return np.stack([horizontal, np.hypot(horizontal, e[..., 2])], axis=-1)


# ---------------------------------------------------------------------------
# Consistency (NEES)
# ---------------------------------------------------------------------------


class NeesStats(NamedTuple):
    """NEES consistency summary over an evaluation window (spec §11).

    Attributes
    ----------
    anees : float
        Mean NEES over runs and window epochs (expected ``n`` if consistent).
    band : tuple of float
        Two-sided 95% band for the run-averaged NEES at one epoch,
        ``chi2.ppf([0.025, 0.975], M n) / M``.
    in_band_fraction : float
        Fraction of window epochs whose run-averaged NEES lies inside ``band``
        (expect about 0.95).
    nees_mean : (K,) array
        Run-averaged NEES ``eps_bar_k`` at every epoch (all epochs, not only ``W``).
    """

    anees: float
    band: tuple[float, float]
    in_band_fraction: float
    nees_mean: np.ndarray


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalized estimation error squared ``eps = eᵀ P⁻¹ e`` (spec §11).

    Uses a linear solve, never an explicit inverse.

    Parameters
    ----------
    err : (..., n) array
        Estimate minus truth.
    P : (..., n, n) array
        Filter covariance of the estimate (SPD); leading axes broadcast with ``err``.

    Returns
    -------
    (...,) array
        Dimensionless NEES; ``~ chi2(n)`` for a consistent filter.
    """
    err = np.asarray(err, dtype=float)
    P = np.asarray(P, dtype=float)
    if P.shape[-2:] != (err.shape[-1], err.shape[-1]):
        raise ValueError(f"P shape {P.shape} incompatible with err shape {err.shape}")
    batch = np.broadcast_shapes(err.shape[:-1], P.shape[:-2])
    n = err.shape[-1]
    e = np.broadcast_to(err, (*batch, n))
    # eᵀ P⁻¹ e is the NIS of z = e against the prior (0, P) with H = I, R = 0: one
    # compiled Cholesky pass (LU where P is not numerically positive definite)
    return prior_nis(np.zeros_like(e), P, e, np.eye(n), np.zeros((n, n)))


def chi2_band(dof_total: int, runs: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided chi-square band for a run-averaged statistic (spec §11).

    If ``M eps_bar ~ chi2(M n)``, the band is
    ``[chi2_{Mn}((1-c)/2), chi2_{Mn}((1+c)/2)] / M``.

    Parameters
    ----------
    dof_total : int
        Total degrees of freedom ``M n`` (runs times state dimension).
    runs : int
        Number of Monte Carlo runs ``M`` used for the average.
    confidence : float, optional
        Two-sided coverage ``c`` (default 0.95).

    Returns
    -------
    tuple of float
        ``(lower, upper)`` bounds for the run-averaged statistic.
    """
    if runs <= 0 or dof_total <= 0:
        raise ValueError("dof_total and runs must be positive")
    if not 0.0 < confidence < 1.0:
        raise ValueError("confidence must lie in (0, 1)")
    alpha = 1.0 - confidence
    lo, hi = chi2.ppf([alpha / 2.0, 1.0 - alpha / 2.0], dof_total) / runs
    return float(lo), float(hi)


def nees_stats(nees_values: np.ndarray, n: int, window: np.ndarray) -> NeesStats:
    """Run-averaged NEES, ANEES and chi-square band coverage (spec §11).

    Parameters
    ----------
    nees_values : (B, K) array
        NEES per run and epoch (e.g. from :func:`nees`); ``M = B`` runs.
    n : int
        State (error) dimension of each NEES sample.
    window : (K,) bool array
        Epochs of the evaluation window ``W``.

    Returns
    -------
    NeesStats
        ``anees`` and ``in_band_fraction`` are ``nan`` if ``window`` is empty;
        ``nees_mean`` and ``band`` are always computed.
    """
    v = np.asarray(nees_values, dtype=float)
    window = np.asarray(window, dtype=bool)
    if v.ndim != 2:
        raise ValueError(f"nees_values must have shape (B, K), got {v.shape}")
    B, K = v.shape
    if window.shape != (K,):
        raise ValueError(f"window must have shape ({K},), got {window.shape}")
    band = chi2_band(B * n, B)
    nees_mean = v.mean(axis=0)
    if not window.any():
        return NeesStats(float("nan"), band, float("nan"), nees_mean)
    w = nees_mean[window]
    inside = (w >= band[0]) & (w <= band[1])
    return NeesStats(
        anees=float(v[:, window].mean()),
        band=band,
        in_band_fraction=float(inside.mean()),
        nees_mean=nees_mean,
    )


# ---------------------------------------------------------------------------
# Fault detection
# ---------------------------------------------------------------------------


class DetectionStats(NamedTuple):
    """Fault-detection performance of one detector on one subsystem (spec §11).

    Attributes
    ----------
    rate : float
        Per-epoch detection probability ``Pd`` = alarmed fault epochs / fault
        epochs, pooled over runs; ``nan`` if there are no fault epochs.
    event_rate : float
        Detected events / events (``1 - missed_rate``); ``nan`` if no events.
    missed_rate : float
        Events with no alarm inside ``[t_on, t_off)`` / events; ``nan`` if no events.
    false_alarm_rate : float
        Alarmed clean epochs / clean epochs, pooled over runs, where clean epochs
        lie outside every window and outside the grace period
        ``[t_off, t_off + G)`` after each window; ``nan`` if none.
    false_alarms_per_hour : float
        ``false_alarm_rate * 3600 / dt`` (alarms per hour of clean operation).
    mean_delay_s, median_delay_s, p95_delay_s : float
        Mean, median and 95th percentile (linear interpolation) of the detection
        delay ``t_first_alarm - t_on`` in s over detected events of all runs;
        ``nan`` if nothing was detected.
    mean_recovery_s : float
        Mean over events of all runs of the time in s from ``t_off`` until the
        flag is False at an epoch ``>= t_off`` and stays so through the grace
        period ``[t_off, t_off + G)`` (an alarm there is the fault's: the aid
        re-flagged as it comes back, after a fault the filter followed, has not
        recovered); if it never clears, the time ``(times[-1] + dt) - t_off`` is
        used.  Left out: events that last to the end of the run (nothing to
        recover from yet) and events of runs that never flagged the aid over the
        window and its grace period (nothing was held: no recovery to time, not a
        recovery of 0 s); ``nan`` if no events remain.
    events : int
        Number of fault events times number of runs.
    """

    rate: float
    event_rate: float
    missed_rate: float
    false_alarm_rate: float
    false_alarms_per_hour: float
    mean_delay_s: float
    median_delay_s: float
    p95_delay_s: float
    mean_recovery_s: float
    events: int


def _merge_windows(windows: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    """Sort ``[t_on, t_off)`` windows and merge overlapping ones."""
    merged: list[list[float]] = []
    for t_on, t_off in sorted((float(a), float(b)) for a, b in windows):
        if t_off <= t_on:
            continue  # empty window
        if merged and t_on < merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], t_off)
        else:
            merged.append([t_on, t_off])
    return [(a, b) for a, b in merged]


def _ratio(num: float, den: float) -> float:
    return float(num) / float(den) if den > 0 else float("nan")


class DetectionEvents(NamedTuple):
    """Per-run counts behind :class:`DetectionStats` (its sufficient statistics: the
    intervals of :mod:`ftnav.eval.intervals` are built from them).

    Attributes
    ----------
    fault_alarms : (B,) alarmed fault epochs of each run.
    fault_epochs : fault epochs of one run (the same in every run).
    clean_alarms : (B,) alarmed clean epochs of each run (:class:`DetectionStats`).
    clean_epochs : clean epochs of one run.
    delays : (B, E) detection delay in s of each run's E events, NaN where missed.
    recoveries : (B, E) recovery time in s of each event (:class:`DetectionStats`);
        NaN for an event that lasts to the end of the run (nothing to recover from).
    dt : the epoch spacing in s.
    """

    fault_alarms: np.ndarray
    fault_epochs: int
    clean_alarms: np.ndarray
    clean_epochs: int
    delays: np.ndarray
    recoveries: np.ndarray
    dt: float


def detection_events(
    flags: np.ndarray,
    times: np.ndarray,
    windows: Sequence[tuple[float, float]],
    grace: float,
) -> DetectionEvents:
    """Each run's alarms, detections, delays and recoveries against ground-truth fault
    windows (the parameters and epoch classes of :func:`detection_stats`)."""
    flags = np.asarray(flags, dtype=bool)
    times = np.asarray(times, dtype=float)
    if flags.ndim != 2:
        raise ValueError(f"flags must have shape (B, K), got {flags.shape}")
    B, K = flags.shape
    if times.shape != (K,):
        raise ValueError(f"times must have shape ({K},), got {times.shape}")
    dt = float(times[1] - times[0]) if K > 1 else 1.0
    t_end = float(times[-1]) + dt if K > 0 else 0.0

    fault = np.zeros(K, dtype=bool)
    graced = np.zeros(K, dtype=bool)
    delays: list[np.ndarray] = []
    recoveries: list[np.ndarray] = []
    for t_on, t_off in _merge_windows(windows):
        in_win = (times >= t_on) & (times < t_off)
        graced |= (times >= t_off) & (times < t_off + grace)
        if not in_win.any():
            continue
        fault |= in_win

        # Detection: first alarm inside the window, vectorized over runs.
        alarmed = flags[:, in_win]  # (B, Kw)
        detected = alarmed.any(axis=1)
        first = np.argmax(alarmed, axis=1)
        delays.append(np.where(detected, times[in_win][first] - t_on, np.nan))

        # Recovery: the first epoch at/after t_off where the flag is False and stays so
        # through the grace period (alarms there are the fault's: an aid re-flagged as it
        # comes back has not recovered); none for a run that never flagged the aid over
        # the window and its grace (nothing was held: nothing to recover from).
        after = times >= t_off
        fa = flags[:, after]  # (B, Ka)
        ta = times[after]
        in_grace = ta < t_off + grace  # a prefix of the epochs after t_off
        flagged = detected | (fa & in_grace).any(axis=1)
        if t_off >= t_end:  # the fault lasts to the end of the run: no recovery to time
            rec = np.full(B, np.nan)
        elif fa.shape[1] == 0:
            rec = np.where(flagged, t_end - t_off, np.nan)
        else:
            idx = np.arange(fa.shape[1])
            last = np.max(np.where(fa & in_grace, idx, -1), axis=1)  # last alarm in grace
            clear = ~fa & (idx > last[:, None])
            first_clear = np.argmax(clear, axis=1)
            rec = np.where(clear.any(axis=1), ta[first_clear] - t_off, t_end - t_off)
            rec = np.where(flagged, rec, np.nan)
        recoveries.append(rec)

    clean = ~fault & ~graced
    return DetectionEvents(
        flags[:, fault].sum(1),
        int(fault.sum()),
        flags[:, clean].sum(1),
        int(clean.sum()),
        np.stack(delays, 1) if delays else np.empty((B, 0)),
        np.stack(recoveries, 1) if recoveries else np.empty((B, 0)),
        dt,
    )


def detection_stats(
    flags: np.ndarray,
    times: np.ndarray,
    windows: Sequence[tuple[float, float]],
    grace: float,
) -> DetectionStats:
    """Detection delay, Pd, missed-detection, false-alarm and recovery metrics (spec §11).

    Parameters
    ----------
    flags : (B, K) bool array
        Alarm flag of the detector per Monte Carlo run and epoch.
    times : (K,) array
        Epoch times in s, uniformly spaced with ``dt = times[1] - times[0]``
        (``dt = 1.0`` if ``K == 1``).
    windows : sequence of (t_on, t_off)
        Ground-truth fault windows ``[t_on, t_off)`` in s of THIS subsystem, the
        same for every run.  Overlapping windows are merged into one event;
        windows containing no epoch are ignored.
    grace : float
        Grace period ``G`` in s after each ``t_off`` excluded from false-alarm
        counting (spec default 10 s).

    Returns
    -------
    DetectionStats
        See :class:`DetectionStats`.

    Notes
    -----
    Epoch ``k`` is a fault epoch if ``t_on <= times[k] < t_off`` for some window.
    The delay of an event uses the first alarmed epoch inside its window,
    ``times[k_first] - t_on``; an event with no alarm inside it is missed.
    """
    return summarize_detection(detection_events(flags, times, windows, grace))


def summarize_detection(ev: DetectionEvents) -> DetectionStats:
    """:class:`DetectionStats` of the per-run :class:`DetectionEvents`."""
    B = ev.fault_alarms.shape[0]
    rate = _ratio(ev.fault_alarms.sum(), B * ev.fault_epochs)
    fa_rate = _ratio(ev.clean_alarms.sum(), B * ev.clean_epochs)
    events = ev.delays.size
    detected = np.isfinite(ev.delays)
    event_rate = _ratio(detected.sum(), events)
    missed_rate = 1.0 - event_rate if events > 0 else float("nan")
    # the delays in event order within each run, as pooled before: window by window
    d = ev.delays.T[detected.T]
    if d.size:
        mean_d, med_d, p95_d = float(d.mean()), float(np.median(d)), float(np.percentile(d, 95))
    else:
        mean_d = med_d = p95_d = float("nan")
    rec = np.ascontiguousarray(ev.recoveries.T)  # window by window, as pooled before
    rec = rec[np.isfinite(rec)]  # a fault lasting to the end of the run has no recovery
    mean_rec = float(rec.mean()) if rec.size else float("nan")
    return DetectionStats(
        rate=rate,
        event_rate=event_rate,
        missed_rate=missed_rate,
        false_alarm_rate=fa_rate,
        false_alarms_per_hour=fa_rate * 3600.0 / ev.dt,
        mean_delay_s=mean_d,
        median_delay_s=med_d,
        p95_delay_s=p95_d,
        mean_recovery_s=mean_rec,
        events=events,
    )
