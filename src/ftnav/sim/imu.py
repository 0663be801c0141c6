"""IMU error model and simulation: bias, Gauss-Markov drift, white noise, scale, misalignment.

Spec §8.3 (error states and S1 Table 1), §8.4 (discrete Gauss-Markov), §10.2
(errors are added to the ideal increments after the truth is generated, so truth
and corruption stay apart).  Units are SI throughout (``docs/conventions.md``);
datasheet units enter only through :meth:`ImuErrors.from_datasheet` and
:mod:`ftnav.nav.units`.

Error model, per sensor triad (gyro: increments Δθ in rad, rate errors in rad/s;
accelerometer: Δv in m/s, errors in m/s²), for interval ``k`` = ``(t_{k−1}, t_k]``:

    Δθ̃_k = (I + S + M) Δθ_k + (b + m_k)·dt + n_k,      n_k ~ N(0, N²·dt)

* ``b``: constant bias = fixed value + a random constant ``N(0, σ_b²)`` drawn per run
  (ε_b / a constant ∇ in spec §8.3);
* ``m_k``: first-order Gauss-Markov drift (ε_r, ∇), exact discrete form (spec §8.4)
  ``m_{k+1} = e^{−dt/τ} m_k + w_k``, ``var(w_k) = σ²(1 − e^{−2dt/τ})``, started from
  its stationary distribution ``m_1 ~ N(0, σ²)``.  ``m_k`` is the value at ``t_{k−1}``
  held over interval k (zero-order hold); the mean over the interval differs from it
  by ``σ√(2dt/3τ)`` rms, i.e. 1e-3 σ for dt = 0.01 s, τ = 7200 s, far below the white
  noise;
* ``n_k``: white noise integrated over the interval, angle (velocity) random walk
  ``N`` in rad/√s (m/s/√s), so ``std(n_k) = N·√dt``;
* ``S = diag(s)``, ``s_i ~ N(0, σ_s,i²)``: scale-factor errors;
* ``M``: misalignment (non-orthogonality), zero diagonal, ``M[i, j] ~ N(0, σ_m,i²)``
  for ``j ≠ i``: sensor axis i leans by two small angles toward the other axes.

Randomness (style §5, ``docs/conventions.md``).  Run ``r`` of root ``seed`` draws its
IMU errors from the streams ``SeedSequence(seed, spawn_key=(r, IMU_STREAM_KEY, c))``,
``c`` = 0 constants (24 normals: gyro bias, scale, misalignment, then the same for
the accelerometer), 1 gyro Markov, 2 gyro white noise, 3 accelerometer Markov,
4 accelerometer white noise.  These are descendants of the run's stream
``SeedSequence(seed, spawn_key=(r,))`` (:func:`ftnav.sim.linear.run_generator`) but
never equal to it, so aiding-sensor noise drawn from that stream stays independent of
the IMU errors.  One stream per component keeps common random numbers between error
settings (switching the scale factor off leaves the noise realization unchanged) and
lets a zero component skip its draw.  Run r is bit-identical alone or in a batch; each
run's (K, 3) block is drawn in one call, runs in a thread pool of
:func:`ftnav.parallel.default_workers` threads (one run's block, milliseconds of work,
is the smallest task; the result does not depend on the thread count); the Markov
recursion runs over all runs at once with :func:`scipy.signal.lfilter`.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ftnav.core.markov import check_dt, gauss_markov_inplace
from ftnav.model.imu import ImuErrors
from ftnav.parallel import default_workers

__all__ = ["IMU_STREAM_KEY", "ImuErrorTruth", "ImuSimulation", "simulate_imu_errors"]

IMU_STREAM_KEY = 0x494D55  #: second spawn-key element of the IMU streams ("IMU" in ASCII)

_OFF_DIAGONAL = (np.array([0, 0, 1, 1, 2, 2]), np.array([1, 2, 0, 2, 0, 1]))


class ImuErrorTruth(NamedTuple):
    """True IMU errors of each run, to score the filters' bias estimates.

    Leading axis B (runs) is absent for a single run given as (K, 3).
    Components whose σ is zero are read-only broadcast views of zeros.

    Attributes
    ----------
    gyro_bias : (B, 3) rad/s, constant drift (fixed + random), ε_b of spec §8.3.
    gyro_markov : (B, K, 3) rad/s, Markov drift ε_r; ``[:, k−1]`` acts over interval k.
    gyro_scale : (B, 3) scale-factor errors s (``S = diag(s)``).
    gyro_misalignment : (B, 3, 3) rad, misalignment M (zero diagonal).
    accel_bias : (B, 3) m/s², constant bias.
    accel_markov : (B, K, 3) m/s², Markov bias ∇.
    accel_scale : (B, 3).  accel_misalignment : (B, 3, 3) rad.
    """

    gyro_bias: np.ndarray
    gyro_markov: np.ndarray
    gyro_scale: np.ndarray
    gyro_misalignment: np.ndarray
    accel_bias: np.ndarray
    accel_markov: np.ndarray
    accel_scale: np.ndarray
    accel_misalignment: np.ndarray


class ImuSimulation(NamedTuple):
    """Corrupted increments and the errors that made them.

    Attributes
    ----------
    dtheta : (B, K, 3) rad, measured angle increments.
    dv : (B, K, 3) m/s, measured velocity increments.
    truth : ImuErrorTruth.
    """

    dtheta: np.ndarray
    dv: np.ndarray
    truth: ImuErrorTruth


def _generator(seed: int, run: int, component: int) -> np.random.Generator:
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(run, IMU_STREAM_KEY, component))
    )


def _normal_blocks(seed: int, runs: range, component: int, K: int) -> np.ndarray:
    """(B, K, 3) standard normals, run b's block drawn in one call from its own stream."""
    out = np.empty((len(runs), K, 3))

    def fill(b: int) -> None:
        _generator(seed, runs[b], component).standard_normal(out=out[b])

    threads = min(default_workers(), len(runs))
    if threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(fill, range(len(runs))))
    else:
        for b in range(len(runs)):
            fill(b)
    return out


def _misalignment(draws: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """(B, 3, 3) zero-diagonal M with row i scaled by ``sd[i]`` from (B, 6) normals."""
    M = np.zeros(draws.shape[:1] + (3, 3))
    M[:, _OFF_DIAGONAL[0], _OFF_DIAGONAL[1]] = draws * sd[_OFF_DIAGONAL[0]]
    return M


def _corrupt(ideal, scale, mis, bias, markov, noise_sd, seed, runs, component, dt, K):
    """``(I + S + M) x + (b + m + n/dt)·dt`` for one triad, (B, K, 3), n the white noise.

    Written as in-place passes over one (B, K, 3) buffer: this is the memory-bound part.
    """
    B = len(runs)
    if np.any(noise_sd):
        out = _normal_blocks(seed, runs, component, K)
        out *= noise_sd / math.sqrt(dt)  # white rate samples, std N/√dt
        if markov is not None:
            out += markov
    elif markov is not None:
        out = markov.copy()
    else:
        out = np.zeros((B, K, 3))
    out += bias[:, None, :]
    out *= dt
    if np.any(scale) or np.any(mis):
        A = mis + scale[:, :, None] * np.eye(3)
        x = ideal[..., None, :]  # (…, K, 1, 3): Σ_j A_ij x_j as three broadcast terms
        out += A[:, None, :, 0] * x[..., 0]
        out += A[:, None, :, 1] * x[..., 1]
        out += A[:, None, :, 2] * x[..., 2]
    out += ideal
    return out


def simulate_imu_errors(
    dtheta: ArrayLike,
    dv: ArrayLike,
    dt: float,
    errors: ImuErrors,
    seed: int,
    first_run: int = 0,
    *,
    runs: int | None = None,
) -> ImuSimulation:
    """Corrupt ideal IMU increments with the error model of the module docstring.

    Spec §8.3 (error states), §8.4 (exact discrete Gauss-Markov), §10.2 (errors
    are added to the ideal increments).

    Parameters
    ----------
    dtheta : (B, K, 3) or (K, 3) array_like, rad
        Ideal body-frame angle increments over each IMU interval.
    dv : same shape as ``dtheta``, m/s
        Ideal body-frame velocity increments.
    dt : float, s
        IMU interval.
    errors : ImuErrors
        True error parameters (not what a filter assumes).
    seed : int
        Root seed (≥ 0); run r draws from the streams described in the module docstring.
    first_run : int
        Index of the first run of this batch (runs ``first_run .. first_run + B − 1``).
    runs : int, optional
        Number of runs B.  With (K, 3) inputs, the same ideal increments are
        corrupted B times and the outputs are (B, K, 3); without it, (K, 3) inputs
        are one run and every output drops the run axis.

    Returns
    -------
    ImuSimulation
        ``dtheta`` and ``dv`` corrupted, same shape as the inputs (or (B, K, 3)),
        and ``truth``, the :class:`ImuErrorTruth` of each run.

    Raises
    ------
    ValueError
        ``"<argument>: <reason>"`` for bad shapes, ``dt`` ≤ 0, a bad seed or run count.
    """
    if not isinstance(errors, ImuErrors):
        raise ValueError(f"errors: expected ImuErrors, got {type(errors).__name__}")
    dt = check_dt(dt)
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    for name, a in (("dtheta", dtheta), ("dv", dv)):
        if a.ndim not in (2, 3) or a.shape[-1] != 3 or a.shape[-2] < 1:
            raise ValueError(f"{name}: expected shape (B, K, 3) or (K, 3), got {a.shape}")
    if dv.shape != dtheta.shape:
        raise ValueError(f"dv: expected the shape of dtheta {dtheta.shape}, got {dv.shape}")
    for name, value, low in (("seed", seed, 0), ("first_run", first_run, 0)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
            raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
    if runs is not None and (
        isinstance(runs, bool) or not isinstance(runs, int | np.integer) or runs < 1
    ):
        raise ValueError(f"runs: expected an integer >= 1, got {runs!r}")
    single = dtheta.ndim == 2 and runs is None
    K = dtheta.shape[-2]
    if dtheta.ndim == 3:
        if runs is not None and runs != dtheta.shape[0]:
            raise ValueError(f"runs: {runs} does not match the batch axis of dtheta {dtheta.shape}")
        B = dtheta.shape[0]
    else:
        B = 1 if runs is None else int(runs)
    seed, first_run = int(seed), int(first_run)
    run_ids = range(first_run, first_run + B)
    e = errors

    c = np.stack([_generator(seed, r, 0).standard_normal(24) for r in run_ids])
    gyro_bias = e.gyro_bias + e.gyro_bias_sd * c[:, 0:3]
    gyro_scale = e.gyro_scale_sd * c[:, 3:6]
    gyro_mis = _misalignment(c[:, 6:12], e.gyro_misalignment_sd)
    accel_bias = e.accel_bias + e.accel_bias_sd * c[:, 12:15]
    accel_scale = e.accel_scale_sd * c[:, 15:18]
    accel_mis = _misalignment(c[:, 18:24], e.accel_misalignment_sd)

    def markov(sd, tau, component):
        if not np.any(sd):
            return None
        return gauss_markov_inplace(_normal_blocks(seed, run_ids, component, K), sd, tau, dt)

    gyro_markov = markov(e.gyro_markov_sd, e.gyro_markov_tau, 1)
    out_theta = _corrupt(
        dtheta, gyro_scale, gyro_mis, gyro_bias, gyro_markov, e.gyro_arw, seed, run_ids, 2, dt, K
    )
    accel_markov = markov(e.accel_markov_sd, e.accel_markov_tau, 3)
    out_v = _corrupt(
        dv, accel_scale, accel_mis, accel_bias, accel_markov, e.accel_vrw, seed, run_ids, 4, dt, K
    )

    zeros = np.broadcast_to(np.zeros(()), (B, K, 3))
    truth = ImuErrorTruth(
        gyro_bias,
        zeros if gyro_markov is None else gyro_markov,
        gyro_scale,
        gyro_mis,
        accel_bias,
        zeros if accel_markov is None else accel_markov,
        accel_scale,
        accel_mis,
    )
    if single:
        truth = ImuErrorTruth(*(a[0] for a in truth))
        return ImuSimulation(out_theta[0], out_v[0], truth)
    return ImuSimulation(out_theta, out_v, truth)
