"""Recorded IMU samples: cleaning, increments on the engine's grid, stationarity.

A logged IMU gives rates ``ω_ib^b`` (rad/s) and specific forces ``f^b`` (m/s²) at
irregular time stamps, with stale reads (a row repeating the previous one) and
repeated stamps.  The engine integrates increments on a uniform grid
(``docs/conventions.md``: ``Δθ = ∫ ω dt`` over the interval ending at ``t``), so:

* :func:`clean` drops exact repeats of the previous row (stale reads: the sensor was
  not sampled again) and rows whose stamp repeats the previous one, and counts both;
* :func:`increments` takes each sample's rate as constant over the interval that ends
  at its stamp (the sample-and-hold of a logged rate) and integrates the cumulative
  ``∫ω``, ``∫f`` exactly at any grid of times: an aid epoch falls on a grid point
  even when it falls between two IMU samples, so every aid is applied at its own
  time stamp with the INS propagated to it;
* :func:`stationary` marks the epochs at which the vehicle is at rest (ZUPT).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = [
    "noise_density",
    "ImuLog",
    "ImuCleaning",
    "TimeGoesBack",
    "clean",
    "increments",
    "stationary",
]


class TimeGoesBack(ValueError):
    """A stamp earlier than the previous one; ``row`` is the 0-based data row."""

    def __init__(self, row: int, reason: str) -> None:
        self.row, self.reason = row, reason
        super().__init__(f"row {row}: {reason}")


class ImuLog(NamedTuple):
    """IMU samples in the body frame (x right, y forward, z up).

    Attributes
    ----------
    t : (N,) s, strictly increasing stamps (the end of each sample's interval).
    gyro : (N, 3) rad/s.
    accel : (N, 3) m/s².
    """

    t: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray


class ImuCleaning(NamedTuple):
    """What :func:`clean` did: rows read, stale repeats and repeated stamps dropped, and
    the largest gap between kept samples (s)."""

    rows: int
    repeated_rows: int
    repeated_stamps: int
    max_gap_s: float


def clean(log: ImuLog) -> tuple[ImuLog, ImuCleaning]:
    """Drop stale repeats and repeated stamps (module docstring); stamps must not go back.

    Raises
    ------
    TimeGoesBack : ``"row <i>: time goes backwards ..."`` (0-based data row) when a stamp
        is earlier than the previous one.
    """
    t = np.asarray(log.t, float)
    values = np.concatenate([log.gyro, log.accel], 1)
    dt = np.diff(t)
    back = np.flatnonzero(dt < 0)
    if back.size:
        i = int(back[0]) + 1
        raise TimeGoesBack(i, f"time goes backwards ({t[i]:.6f} s after {t[i - 1]:.6f} s)")
    stale = np.zeros(t.shape, bool)
    stale[1:] = np.all(values[1:] == values[:-1], 1)
    same = np.zeros(t.shape, bool)
    same[1:] = dt == 0
    keep = ~(stale | same)
    kept = ImuLog(t[keep], log.gyro[keep], log.accel[keep])
    gap = float(np.max(np.diff(kept.t))) if kept.t.size > 1 else 0.0
    info = ImuCleaning(int(t.size), int(stale.sum()), int((same & ~stale).sum()), gap)
    return kept, info


def increments(log: ImuLog, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(Δθ, Δv)`` (n, 3) over the intervals between consecutive ``grid`` times.

    Each sample's rate holds over ``(t_{i−1}, t_i]``; the cumulative integrals are
    exact at the samples and linear between them, so sums over any partition of
    ``[grid[0], grid[-1]]`` add up to the same total.  ``grid`` must lie within
    ``[t_0, t_{N−1}]``.
    """
    t = log.t
    if grid[0] < t[0] - 1e-9 or grid[-1] > t[-1] + 1e-9:
        raise ValueError(
            f"the grid [{grid[0]:.3f}, {grid[-1]:.3f}] s leaves the IMU log "
            f"[{t[0]:.3f}, {t[-1]:.3f}] s"
        )
    dt = np.diff(t)[:, None]
    out = []
    for rate in (log.gyro, log.accel):
        cum = np.concatenate([np.zeros((1, 3)), np.cumsum(rate[1:] * dt, 0)])
        at = np.stack([np.interp(grid, t, cum[:, j]) for j in range(3)], -1)
        out.append(np.diff(at, axis=0))
    return out[0], out[1]


def stationary(
    log: ImuLog, times: np.ndarray, window_s: float, accel_tol: float, gyro_tol: float
) -> np.ndarray:
    """(K,) bool: at rest around each time.

    At rest when, over ``[t − window_s, t + window_s]``, the standard deviation of every
    accelerometer axis is below ``accel_tol`` (m/s²) and that of every gyro axis below
    ``gyro_tol`` (rad/s): a still vehicle's IMU reads constant values up to its noise,
    whatever its biases and tilt.  Fewer than 5 samples: not at rest.  The span is
    centred (a recording is processed after the fact) and a window wide on each side: a
    vehicle creeping at constant speed reads still (its IMU sees no acceleration), so
    the acceleration that starts or ends the creep must fall in it; a stop lasts longer.
    """
    lo = np.searchsorted(log.t, times - window_s, side="left")
    hi = np.searchsorted(log.t, times + window_s, side="right")
    out = np.zeros(times.shape, bool)
    for k, (a, b) in enumerate(zip(lo, hi, strict=True)):
        if b - a < 5:
            continue
        out[k] = bool(
            np.all(log.accel[a:b].std(0) < accel_tol) and np.all(log.gyro[a:b].std(0) < gyro_tol)
        )
    return out


def noise_density(log: ImuLog, until: float, tau: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """White-noise density per body axis of a still IMU: gyro (rad/√s), accel (m/s/√s).

    Over the samples before ``until`` (the static window), the Allan deviation at ``tau``
    (non-overlapping clusters of ``tau`` seconds: ``σ_A² = ½ mean((ȳ_{k+1} − ȳ_k)²)``)
    times ``√tau``: for white noise of density N, ``σ_A(τ) = N/√τ``; a constant bias
    cancels.  At τ = 1 s it holds what integrates into the navigation errors over the
    filter's horizon, engine or road vibration included, which a datasheet's angle and
    velocity random walk (a bench figure) leaves out; the high-frequency part of a
    vibration (tens of Hz) averages out in the clusters.

    Raises
    ------
    ValueError : fewer than 3 clusters in the window.
    """
    w = log.t < until
    t = log.t[w]
    if t.size < 2:
        raise ValueError(f"alignment.static_s: {t.size} IMU samples")
    dt = float(np.median(np.diff(t)))
    n = max(1, int(round(tau / dt)))
    K = t.size // n
    if K < 3:
        raise ValueError(
            f"alignment.static_s: {t.size * dt:.3g} s holds fewer than 3 clusters of {tau:g} s"
        )
    out = []
    for y in (log.gyro[w], log.accel[w]):
        means = y[: K * n].reshape(K, n, 3).mean(1)
        adev = np.sqrt(0.5 * np.mean(np.diff(means, axis=0) ** 2, axis=0))
        out.append(adev * np.sqrt(n * dt))
    return out[0], out[1]
