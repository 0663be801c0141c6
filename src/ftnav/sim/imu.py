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
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.signal import lfilter

from ftnav.nav.units import (
    deg_per_h,
    deg_per_sqrt_h,
    m_per_s_per_sqrt_h,
    micro_g,
    milli_g,
    parse_quantity,
    ppm,
    standard_g,
)
from ftnav.parallel import default_workers

__all__ = [
    "DATASHEET_KEYS",
    "IMU_PRESETS",
    "IMU_STREAM_KEY",
    "ImuErrorTruth",
    "ImuErrors",
    "ImuSimulation",
    "gauss_markov",
    "imu_preset",
    "simulate_imu_errors",
]

IMU_STREAM_KEY = 0x494D55  #: second spawn-key element of the IMU streams ("IMU" in ASCII)

# field -> (unit family for from_datasheet, sign constraint)
_SPEC: dict[str, tuple[str, str]] = {
    "gyro_bias": ("angular_rate", "any"),
    "gyro_bias_sd": ("angular_rate", "nonnegative"),
    "gyro_markov_sd": ("angular_rate", "nonnegative"),
    "gyro_markov_tau": ("time", "positive"),
    "gyro_arw": ("angle_random_walk", "nonnegative"),
    "gyro_scale_sd": ("dimensionless", "nonnegative"),
    "gyro_misalignment_sd": ("angle", "nonnegative"),
    "accel_bias": ("acceleration", "any"),
    "accel_bias_sd": ("acceleration", "nonnegative"),
    "accel_markov_sd": ("acceleration", "nonnegative"),
    "accel_markov_tau": ("time", "positive"),
    "accel_vrw": ("velocity_random_walk", "nonnegative"),
    "accel_scale_sd": ("dimensionless", "nonnegative"),
    "accel_misalignment_sd": ("angle", "nonnegative"),
}

#: keys of an IMU datasheet table (:meth:`ImuErrors.from_datasheet`), in field order
DATASHEET_KEYS: tuple[str, ...] = tuple(_SPEC)

_OFF_DIAGONAL = (np.array([0, 0, 1, 1, 2, 2]), np.array([1, 2, 0, 2, 0, 1]))


def _show(value) -> str:
    """One-line rendering of a bad input for an error message."""
    return np.array2string(value, separator=", ") if isinstance(value, np.ndarray) else repr(value)


def _axes(value, name: str, constraint: str) -> np.ndarray:
    """Validate one field: scalar or 3 finite values with the right sign -> read-only (3,)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name}: expected a number in SI units (strings with units go through "
            f"ImuErrors.from_datasheet), got {value!r}"
        ) from None
    if a.shape not in ((), (3,)):
        raise ValueError(f"{name}: expected a scalar or 3 values (x, y, z), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {_show(value)}")
    if constraint == "nonnegative" and np.any(a < 0.0):
        raise ValueError(f"{name}: must be >= 0, got {_show(value)}")
    if constraint == "positive" and np.any(a <= 0.0):
        raise ValueError(f"{name}: must be > 0, got {_show(value)}")
    a = np.array(np.broadcast_to(a, (3,)))
    a.flags.writeable = False
    return a


@dataclass(frozen=True, slots=True)
class ImuErrors:
    """True IMU error parameters in SI units (spec §8.3); each a scalar or per-axis (3,).

    Every field is stored as a read-only float64 (3,) array (x, y, z body axes);
    a scalar is broadcast.  ``*_sd`` are standard deviations (≥ 0), ``*_tau``
    correlation times (> 0, unused while the matching σ is 0).  See the module
    docstring for the model and :meth:`from_datasheet` for datasheet units.

    Attributes
    ----------
    gyro_bias : (3,) rad/s, fixed constant drift added to every run (any sign).
    gyro_bias_sd : (3,) rad/s, σ of the random constant drift ε_b drawn per run.
    gyro_markov_sd : (3,) rad/s, steady-state σ of the Markov drift ε_r.
    gyro_markov_tau : (3,) s, its correlation time T_g.
    gyro_arw : (3,) rad/√s, angle random walk.
    gyro_scale_sd : (3,) dimensionless, σ of the scale-factor errors.
    gyro_misalignment_sd : (3,) rad, σ of the misalignment angles of each axis.
    accel_bias : (3,) m/s², fixed constant bias.
    accel_bias_sd : (3,) m/s², σ of the random constant bias.
    accel_markov_sd : (3,) m/s², steady-state σ of the Markov bias ∇.
    accel_markov_tau : (3,) s, its correlation time T_a.
    accel_vrw : (3,) m/s/√s, velocity random walk.
    accel_scale_sd : (3,) dimensionless.  accel_misalignment_sd : (3,) rad.

    Raises
    ------
    ValueError
        ``"imu.<field>: <reason>"`` for a negative σ, τ ≤ 0, NaN/inf, a wrong
        shape or a non-numeric value.
    """

    gyro_bias: ArrayLike = 0.0
    gyro_bias_sd: ArrayLike = 0.0
    gyro_markov_sd: ArrayLike = 0.0
    gyro_markov_tau: ArrayLike = 3600.0
    gyro_arw: ArrayLike = 0.0
    gyro_scale_sd: ArrayLike = 0.0
    gyro_misalignment_sd: ArrayLike = 0.0
    accel_bias: ArrayLike = 0.0
    accel_bias_sd: ArrayLike = 0.0
    accel_markov_sd: ArrayLike = 0.0
    accel_markov_tau: ArrayLike = 3600.0
    accel_vrw: ArrayLike = 0.0
    accel_scale_sd: ArrayLike = 0.0
    accel_misalignment_sd: ArrayLike = 0.0

    def __post_init__(self):
        for name, (_, constraint) in _SPEC.items():
            object.__setattr__(self, name, _axes(getattr(self, name), f"imu.{name}", constraint))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ImuErrors):
            return NotImplemented
        return all(np.array_equal(getattr(self, n), getattr(other, n)) for n in _SPEC)

    def __hash__(self) -> int:
        return hash(tuple(getattr(self, n).tobytes() for n in _SPEC))

    @classmethod
    def from_datasheet(
        cls,
        table: Mapping[str, str | float | Sequence[str | float]],
        *,
        base: ImuErrors | None = None,
        field: str = "imu",
    ) -> ImuErrors:
        """Build from datasheet strings, e.g. a TOML table (units: :func:`parse_quantity`).

        Keys are the field names; each value is ``"<number> <unit>"`` of the field's
        family, or a list of three such strings (x, y, z).  A bare number is accepted
        only when it is 0 or the field is dimensionless.  Fields not given are taken
        from ``base`` (default: all zero, τ = 3600 s).

        Parameters
        ----------
        table : mapping
            E.g. ``{"gyro_bias_sd": "0.1 deg/h", "gyro_arw": "0.01 deg/sqrt(h)",
            "gyro_markov_sd": "0.1 deg/h", "gyro_markov_tau": "2 h",
            "accel_markov_sd": "100 ug", "accel_markov_tau": "1800 s"}``.
        base : ImuErrors, optional
            Values for the keys that ``table`` leaves out (e.g. a preset).
        field : str
            Path of the table, the prefix of error messages (``"imu.gyro_arw: ..."``).

        Raises
        ------
        ValueError
            ``"<field>.<key>: <reason>"``: unknown key, unit of the wrong family,
            unknown unit, NaN/inf, negative σ, τ ≤ 0, not 1 or 3 values.
        """
        if not isinstance(table, Mapping):
            raise ValueError(
                f"{field}: expected a table of '<number> <unit>' strings, "
                f"got {type(table).__name__}"
            )
        values = {}
        for key, raw in table.items():
            path = f"{field}.{key}"
            if key not in _SPEC:
                raise ValueError(f"{path}: unknown key; valid keys: {', '.join(_SPEC)}")
            family, constraint = _SPEC[key]
            if isinstance(raw, Sequence) and not isinstance(raw, str):
                if len(raw) != 3:
                    raise ValueError(f"{path}: expected one value or 3 (x, y, z), got {len(raw)}")
                values[key] = [
                    parse_quantity(v, family, f"{path}[{i}]", constraint=constraint)
                    for i, v in enumerate(raw)
                ]
            else:
                values[key] = parse_quantity(raw, family, path, constraint=constraint)
        if base is not None:
            values = {f.name: getattr(base, f.name) for f in fields(base)} | values
        return cls(**values)


#: Named error sets (SI).  ``seed001`` is S1 Table 1 (spec §8.3); see :func:`imu_preset`.
IMU_PRESETS: dict[str, ImuErrors] = {
    "ideal": ImuErrors(),
    "seed001": ImuErrors(
        gyro_bias_sd=deg_per_h(0.1),
        gyro_markov_sd=deg_per_h(0.1),
        gyro_markov_tau=7200.0,
        gyro_arw=deg_per_sqrt_h(0.01),
        accel_markov_sd=standard_g(1e-4),
        accel_markov_tau=1800.0,
    ),
    "tactical": ImuErrors(
        gyro_bias_sd=deg_per_h(1.0),
        gyro_markov_sd=deg_per_h(0.3),
        gyro_markov_tau=3600.0,
        gyro_arw=deg_per_sqrt_h(0.1),
        gyro_scale_sd=ppm(150.0),
        gyro_misalignment_sd=0.5e-3,
        accel_bias_sd=milli_g(1.0),
        accel_markov_sd=micro_g(50.0),
        accel_markov_tau=3600.0,
        accel_vrw=m_per_s_per_sqrt_h(0.03),
        accel_scale_sd=ppm(300.0),
        accel_misalignment_sd=0.5e-3,
    ),
}


def imu_preset(name: str) -> ImuErrors:
    """The named IMU error set of :data:`IMU_PRESETS`.

    * ``"ideal"``: no error at all.
    * ``"seed001"``: S1 Table 1 (spec §8.3).  Gyro random constant drift σ 0.1 °/h;
      gyro Markov drift σ 0.1 °/h with T_g = 7200 s; gyro "white-noise drift 0.01 °/h"
      read as ARW 0.01 °/√h (spec §8.3 [A]; the literal reading is
      ``gyro_arw = √sigma_to_psd(deg_per_h(0.01), dt)``, negligible); accelerometer
      Markov bias σ 1e-4 g (standard g, 9.80665e-4 m/s²) with T_a = 1800 s.  Table 1
      gives no accelerometer constant bias, no accelerometer white noise, no scale
      factor and no misalignment, so these are zero.  The 0.1 °/h constant drift is
      a per-run random constant (its σ also initializes the filter's P₀, spec §8.3);
      for a fixed value use ``dataclasses.replace(p, gyro_bias=..., gyro_bias_sd=0)``.
    * ``"tactical"`` [A, typical tactical-grade IMU, order of magnitude of published
      FOG/MEMS tactical units]: gyro bias σ 1 °/h, Markov σ 0.3 °/h with τ = 3600 s,
      ARW 0.1 °/√h, scale 150 ppm, misalignment 0.5 mrad; accelerometer bias σ 1 mg,
      Markov σ 50 µg with τ = 3600 s, VRW 0.03 m/s/√h, scale 300 ppm,
      misalignment 0.5 mrad.

    Raises
    ------
    ValueError
        ``"imu.preset: unknown preset ...; valid: ..."``.
    """
    try:
        return IMU_PRESETS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"imu.preset: unknown preset {name!r}; valid: {', '.join(IMU_PRESETS)}"
        ) from None


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


def _markov_inplace(w: np.ndarray, sigma: np.ndarray, tau: np.ndarray, dt: float) -> np.ndarray:
    """Turn standard normals ``w`` (..., K, n) into stationary Gauss-Markov sequences."""
    a = np.exp(-dt / tau)
    w[..., 1:, :] *= sigma * np.sqrt(-np.expm1(-2.0 * dt / tau))
    w[..., 0, :] *= sigma  # stationary start
    if np.all(a == a[0]):
        return lfilter([1.0], [1.0, -a[0]], w, axis=-2)
    out = np.empty_like(w)
    for j, aj in enumerate(a):
        out[..., j] = lfilter([1.0], [1.0, -aj], w[..., j], axis=-1)
    return out


def gauss_markov(white: ArrayLike, sigma: ArrayLike, tau: ArrayLike, dt: float) -> np.ndarray:
    """Stationary first-order Gauss-Markov sequences from standard normals (spec §8.4).

    ``b_0 = σ ε_0``, ``b_k = e^{−dt/τ} b_{k−1} + σ√(1 − e^{−2dt/τ}) ε_k``, so every
    ``b_k ~ N(0, σ²)`` and ``corr(b_k, b_{k+j}) = e^{−j·dt/τ}``.

    Parameters
    ----------
    white : (..., K, n) array_like
        Independent standard normal draws ε.
    sigma : (n,) or scalar, unit
        Steady-state standard deviation, ≥ 0.
    tau : (n,) or scalar, s
        Correlation time, > 0.
    dt : float, s
        Sample interval.

    Returns
    -------
    (..., K, n) ndarray, unit
    """
    w = np.array(white, dtype=float)
    if w.ndim < 2:
        raise ValueError(f"white: expected (..., K, n), got shape {w.shape}")
    n = w.shape[-1]
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (n,))
    tau = np.broadcast_to(np.asarray(tau, dtype=float), (n,))
    if not np.all(np.isfinite(sigma)) or np.any(sigma < 0.0):
        raise ValueError(f"sigma: must be finite and >= 0, got {_show(sigma)}")
    if not np.all(np.isfinite(tau)) or np.any(tau <= 0.0):
        raise ValueError(f"tau: must be finite and > 0, got {_show(tau)}")
    return _markov_inplace(w, sigma, tau, _check_dt(dt))


def _check_dt(dt) -> float:
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt: expected a number of seconds, got {dt!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"dt: must be a finite number > 0, got {dt!r}")
    return value


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
    dt = _check_dt(dt)
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
        return _markov_inplace(_normal_blocks(seed, run_ids, component, K), sd, tau, dt)

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
