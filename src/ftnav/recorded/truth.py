"""A full truth beside a recording (NaveGo's reference): the truth at the filter epochs
and the IMU errors the truth reveals.

The IMU errors are derived from the data, independently of any filter: the error-free
IMU is computed from the truth (the inverse of the strapdown equations, spec §8.2) and
subtracted from the logged one.  Over each truth interval ``(t_{i−1}, t_i]``:

* angular rate ``ω_ib^b = θ_i / Δt + C_n^b (ω_ie^n + ω_en^n)``, where ``θ_i`` is the
  rotation vector of ``C_{i−1}ᵀ C_i`` (``C = C_b^n``: the body rotation over the
  interval) and ``C_n^b`` is taken at the interval's middle rotation;
* specific force ``f^b = C_n^b (Δv^n / Δt + (2 ω_ie^n + ω_en^n) × v^n − g^n)`` with the
  velocity, position and rates at the interval's middle.

The logged IMU is integrated exactly onto the same intervals
(:func:`ftnav.recorded.imu.increments`), so the two are compared interval by interval
whatever the sampling; the mean of the difference over the run is the IMU's constant
bias (its white noise and a Markov bias of correlation time τ ≪ the run average out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ftnav.nav.earth import gravity, omega_en_n, omega_ie_n
from ftnav.recorded.imu import ImuLog, increments

__all__ = ["Truth", "ideal_imu", "imu_bias_against_truth"]


@dataclass(frozen=True, slots=True)
class Truth:
    """The truth at filter epochs and the IMU biases it reveals.

    Attributes
    ----------
    index : (K_t,) 0-based filter epochs that have a truth sample.
    p : (K_t, 3) ``[L, λ, h]``.  v : (K_t, 3) ENU m/s.  C : (K_t, 3, 3) ``C_b^n``.
    gyro_bias, accel_bias : (3,) rad/s, m/s², body frame: the logged IMU minus the
        error-free IMU from the truth, averaged over the run (module docstring).
    gyro_bias_nominal, accel_bias_nominal : (3,) the data set's nominal biases, or None.
    removed_gyro_bias : (3,) rad/s the alignment removed from the log before the filter.
    """

    index: np.ndarray
    p: np.ndarray
    v: np.ndarray
    C: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gyro_bias_nominal: np.ndarray | None
    accel_bias_nominal: np.ndarray | None
    removed_gyro_bias: np.ndarray


def ideal_imu(
    t: np.ndarray, p: np.ndarray, v: np.ndarray, C: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Error-free ``(ω_ib^b, f^b)`` (N−1, 3) over the truth's intervals (module docstring).

    ``t`` (N,) s, ``p`` (N, 3) ``[L, λ, h]``, ``v`` (N, 3) ENU, ``C`` (N, 3, 3) ``C_b^n``.
    """
    dt = np.diff(t)[:, None]
    theta = Rotation.from_matrix(np.swapaxes(C[:-1], -1, -2) @ C[1:]).as_rotvec()
    mid = (Rotation.from_matrix(C[:-1]) * Rotation.from_rotvec(theta / 2)).as_matrix()
    L, h = (p[1:, 0] + p[:-1, 0]) / 2, (p[1:, 2] + p[:-1, 2]) / 2
    vm = (v[1:] + v[:-1]) / 2
    w_ie, w_en = omega_ie_n(L), omega_en_n(L, h, vm)
    g_n = np.stack([np.zeros_like(L), np.zeros_like(L), -gravity(L, h)], -1)
    f_n = np.diff(v, axis=0) / dt + np.cross(2 * w_ie + w_en, vm) - g_n
    to_body = np.swapaxes(mid, -1, -2)
    w_ib = theta / dt + np.einsum("kij,kj->ki", to_body, w_ie + w_en)
    f_b = np.einsum("kij,kj->ki", to_body, f_n)
    return w_ib, f_b


def imu_bias_against_truth(
    log: ImuLog, t: np.ndarray, p: np.ndarray, v: np.ndarray, C: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Mean gyro (rad/s) and accelerometer (m/s²) bias of ``log`` over the truth's
    intervals within the log (module docstring)."""
    inside = (t >= log.t[0]) & (t <= log.t[-1])
    t, p, v, C = t[inside], p[inside], v[inside], C[inside]
    if t.size < 3:
        raise ValueError("reference: fewer than 3 truth samples within the IMU log")
    w_ib, f_b = ideal_imu(t, p, v, C)
    dth, dv = increments(log, t)
    dt = np.diff(t)[:, None]
    return (dth / dt - w_ib).mean(0), (dv / dt - f_b).mean(0)
