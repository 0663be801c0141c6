"""Containers, random streams and validation shared by the aiding-sensor models (spec §9).

Every sensor of :mod:`ftnav.sensors` follows one contract (:class:`AidingSensor`):

1. ``simulate_errors(truth, seed, runs, stream)`` draws the sensor errors of each Monte
   Carlo run in the sensor's **metric measurement space** (m, m/s or rad per
   measurement row) as an :class:`AidErrors`: a coloured part (Gauss-Markov, random
   constants), a white part, and per-run random constants that do not live in that
   space (e.g. the Doppler scale factor δK);
2. the caller adds faults to ``coloured + white`` (spec §9.6; a noise-std fault scales
   ``white`` only) and calls ``output(truth, errors_metric, constants)`` for the raw
   output a real device would log (geodetic position, body-frame velocity, a
   quaternion, ...);
3. the filter calls ``measure(q, v, p, raw_k, w_ib)`` at its INS solution for the
   nonlinear innovation source ``z = INS − aid`` and the analytic Jacobians
   (:class:`Linearized`); ``w_ib`` is the gyro's rate at the epoch (its mean over the
   epoch's increments, the fed-back biases removed), read by a sensor at a lever arm
   (the GNSS antenna's velocity) and ignored by the others.

Conventions (spec §0, ``docs/conventions.md``): ENU navigation frame, ``p = [L, λ, h]``
(rad, rad, m), errors computed − true, attitude error φ with
``C̃_b^n = exp(−[φ×]) C_b^n ≈ (I − [φ×]) C_b^n`` (:func:`ftnav.nav.attitude.attitude_error`),
18 common error states in the order of spec §8.3 (:data:`ftnav.nav.error_model.STATES_18`).

Sign of the metric error in z.  ``e`` is the aid's own error for GNSS, DNS, CNS and
ADS (``aid = truth + e`` in measurement space), so ``z = H x − e + …``; the TAN
metric error is defined the other way round (spec §9.2 note in :mod:`.tan`), so
``z = H x + e``.  Each sensor states it as ``z_per_error`` (``∂z/∂e`` = −1 or +1): an
additive fault ``Δz = γ`` (spec §9.6) is the metric offset ``z_per_error · γ``.

Random streams (style §5).  Run ``r`` of root ``seed`` draws the errors of the sensor
with stream number ``s`` from ``SeedSequence(seed, spawn_key=(r, 1000 + s, c))``, one
``c`` per error component (listed by each sensor), so run r is bit-identical alone or
in any batch, and the IMU streams (``ftnav.sim.imu``, second key 0x494D55) and the
per-run stream ``spawn_key=(r,)`` never coincide with these.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from ftnav.core.markov import gauss_markov
from ftnav.model.system import PrivateStates

__all__ = [
    "N_STATES",
    "SENSOR_STREAM_OFFSET",
    "AidTruth",
    "AidErrors",
    "Linearized",
    "AidingSensor",
    "run_generator",
    "standard_normals",
    "markov_errors",
    "markov_private",
    "check_truth",
    "check_errors_metric",
]

N_STATES = 18  #: number of common INS error states (spec §8.3)
SENSOR_STREAM_OFFSET = 1000  #: second spawn-key element of sensor stream s is 1000 + s


class AidTruth(NamedTuple):
    """Truth at the K aid epochs, shared by all runs.

    Attributes
    ----------
    t : (K,) s, epoch times (spaced by the sensor's ``dt``).
    p : (K, 3) ``[L, λ, h]`` in rad, rad, m.
    v : (K, 3) m/s, ENU velocity.
    q : (K, 4) scalar-first ``q_b^n``.
    w : (K, 3) rad/s, the body's rate ``ω_ib^b`` (what an ideal gyro reads), or None
        where no sensor reads it (a sensor at a lever arm refuses None).
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    q: np.ndarray
    w: np.ndarray | None = None


class AidErrors(NamedTuple):
    """Simulated sensor errors of B runs in the sensor's metric measurement space.

    Attributes
    ----------
    coloured : (B, K, m) Gauss-Markov / random-constant parts.
    white : (B, K, m) white part (a noise-std fault scales only this).
    constants : (B, c) per-run random constants outside the metric space (e.g. the
        Doppler scale factor δK); (B, 0) if none.
    """

    coloured: np.ndarray
    white: np.ndarray
    constants: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """(B, K, m) ``coloured + white``, the metric error without faults."""
        return self.coloured + self.white


class Linearized(NamedTuple):
    """Nonlinear innovation source and Jacobians of one epoch for B runs (spec §9).

    Attributes
    ----------
    z : (B, m) ``z = INS − aid`` in the metric measurement space; non-finite values
        (off-map, missing data) are replaced by 0 and flagged in ``valid``.
    H : (B, m, 18) columns on the common INS error states (spec §8.3 order).
    H_private : (B, m, p) columns on the sensor's private states (p may be 0).
    valid : (B,) bool, False where the sensor's gating rejects the epoch.
    """

    z: np.ndarray
    H: np.ndarray
    H_private: np.ndarray
    valid: np.ndarray


@runtime_checkable
class AidingSensor(Protocol):
    """What the fusion code needs from an aiding sensor (module docstring).

    Optional: a class attribute ``pseudo = True`` marks a pseudo-measurement whose
    output is constant by design (the vehicle constraints): the engine then does not
    read its repeats as a frozen sensor (:attr:`ftnav.model.system.Epoch.repeated`).
    """

    @property
    def name(self) -> str: ...

    @property
    def dt(self) -> float: ...

    @property
    def dim(self) -> int: ...

    @property
    def components(self) -> tuple[str, ...]: ...

    @property
    def R(self) -> np.ndarray: ...

    @property
    def private(self) -> PrivateStates | None: ...

    def simulate_errors(
        self, truth: AidTruth, seed: int, runs: range, stream: int
    ) -> AidErrors: ...

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray: ...

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized: ...


def run_generator(seed: int, run: int, sensor_stream: int, component: int) -> np.random.Generator:
    """Stream of one error component of one sensor in run ``run`` (module docstring).

    ``Generator(SeedSequence(seed, spawn_key=(run, 1000 + sensor_stream, component)))``.
    """
    return np.random.default_rng(
        np.random.SeedSequence(
            seed, spawn_key=(run, SENSOR_STREAM_OFFSET + sensor_stream, component)
        )
    )


def _check_runs(seed, runs, stream) -> None:
    for name, value in (("seed", seed), ("stream", stream)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
            raise ValueError(f"{name}: expected an integer >= 0, got {value!r}")
    if not isinstance(runs, range) or len(runs) < 1 or runs.start < 0:
        raise ValueError(f"runs: expected a non-empty range of run indices >= 0, got {runs!r}")


def standard_normals(
    seed: int, runs: range, stream: int, component: int, shape: tuple[int, ...]
) -> np.ndarray:
    """(B, *shape) standard normals; run ``runs[b]``'s block drawn in one call from its stream."""
    _check_runs(seed, runs, stream)
    out = np.empty((len(runs),) + tuple(shape))
    for b, r in enumerate(runs):
        run_generator(int(seed), r, int(stream), component).standard_normal(out=out[b])
    return out


def markov_errors(
    seed: int,
    runs: range,
    stream: int,
    component: int,
    K: int,
    sigma: np.ndarray,
    tau: np.ndarray,
    dt: float,
) -> np.ndarray:
    """(B, K, n) stationary first-order Gauss-Markov sequences (spec §8.4).

    Exact discrete form ``b_{k+1} = e^{−dt/τ} b_k + w_k``, ``var(w_k) = σ²(1 − e^{−2dt/τ})``,
    ``b_0 ~ N(0, σ²)`` (:func:`ftnav.sim.imu.gauss_markov`), one stream per run.

    Parameters
    ----------
    sigma, tau : (n,) steady-state σ (≥ 0, unit of the error) and correlation time (s, > 0).
    dt : float, s, sample interval.
    """
    sigma = np.atleast_1d(np.asarray(sigma, dtype=float))
    tau = np.broadcast_to(np.asarray(tau, dtype=float), sigma.shape)
    white = standard_normals(seed, runs, stream, component, (K, sigma.size))
    return gauss_markov(white, sigma, tau, dt)


def markov_private(
    names: tuple[str, ...], sigma: np.ndarray, tau: np.ndarray, dt: float, H: np.ndarray
) -> PrivateStates:
    """Private first-order Gauss-Markov states: ``F = diag(e^{−dt/τ})``,
    ``Q = diag(σ²(1 − e^{−2dt/τ}))``, ``x0 = 0``, ``P0 = diag(σ²)`` (spec §8.4, §1.7)."""
    sigma = np.asarray(sigma, dtype=float)
    tau = np.asarray(tau, dtype=float)
    return PrivateStates(
        names=tuple(names),
        F=np.diag(np.exp(-dt / tau)),
        Q=np.diag(sigma**2 * -np.expm1(-2.0 * dt / tau)),
        x0=np.zeros(sigma.size),
        P0=np.diag(sigma**2),
        H=np.asarray(H, dtype=float),
    )


def check_truth(truth: AidTruth, dt: float, prefix: str) -> int:
    """Validate an :class:`AidTruth` and return K; epochs must be spaced by ``dt``."""
    if not isinstance(truth, AidTruth):
        raise ValueError(f"truth: expected AidTruth, got {type(truth).__name__}")
    t = np.asarray(truth.t, dtype=float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"truth.t: expected shape (K,) with K >= 1, got {t.shape}")
    K = t.size
    for name, n in (("p", 3), ("v", 3), ("q", 4)):
        a = np.asarray(getattr(truth, name))
        if a.shape != (K, n):
            raise ValueError(f"truth.{name}: expected shape ({K}, {n}), got {a.shape}")
    if K > 1 and not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-9):
        raise ValueError(f"truth.t: epochs must be spaced by {prefix}.dt = {dt} s")
    return K


def check_errors_metric(
    errors_metric, constants, B_K_m: tuple[int | None, int, int], c: int
) -> tuple[np.ndarray, np.ndarray]:
    """Validate ``errors_metric`` (B, K, m) and ``constants`` (B, c); return them as float."""
    e = np.asarray(errors_metric, dtype=float)
    _, K, m = B_K_m
    if e.ndim != 3 or e.shape[1:] != (K, m):
        raise ValueError(f"errors_metric: expected shape (B, {K}, {m}), got {e.shape}")
    cst = np.asarray(constants, dtype=float)
    if cst.shape != (e.shape[0], c):
        raise ValueError(f"constants: expected shape ({e.shape[0]}, {c}), got {cst.shape}")
    return e, cst


# ----------------------------------------------------------------------------- validation


def check_float(
    prefix: str,
    name: str,
    value,
    *,
    low: float | None = None,
    strict: bool = False,
    n: int | None = None,
):
    """Validate a finite number (or ``n`` numbers) with an optional lower bound.

    Returns a float, or a tuple of ``n`` floats when ``n`` is given (a scalar is
    broadcast).  Raises ``ValueError("<prefix>.<name>: ...")``.
    """
    path = f"{prefix}.{name}"
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: expected a number, got {value!r}") from None
    allowed = ((),) if n is None else ((), (n,))
    if isinstance(value, bool) or a.shape not in allowed:
        want = "a number" if n is None else f"a number or {n} numbers"
        raise ValueError(f"{path}: expected {want}, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{path}: must be finite, got {value!r}")
    if low is not None:
        bad = np.any(a <= low) if strict else np.any(a < low)
        if bad:
            raise ValueError(f"{path}: must be {'>' if strict else '>='} {low:g}, got {value!r}")
    if n is None:
        return float(a)
    return tuple(float(x) for x in np.broadcast_to(a, (n,)))


def check_choice(prefix: str, name: str, value, choices: tuple) -> None:
    """Raise ``ValueError("<prefix>.<name>: ...")`` unless ``value`` is one of ``choices``."""
    if value not in choices or isinstance(value, bool):
        raise ValueError(
            f"{prefix}.{name}: expected one of {', '.join(map(repr, choices))}, got {value!r}"
        )


def check_bool(prefix: str, name: str, value) -> None:
    """Raise ``ValueError("<prefix>.<name>: ...")`` unless ``value`` is a bool."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{prefix}.{name}: expected true or false, got {value!r}")


def check_name(name) -> None:
    """A sensor name: a non-empty string."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name: expected a non-empty string, got {name!r}")


def check_common(obj, optional_sigmas: tuple[str, ...] = ()) -> None:
    """Validate the ``name`` and ``dt`` fields and the optional assumed-σ overrides."""
    check_name(obj.name)
    check_float(obj.name, "dt", obj.dt, low=0.0, strict=True)
    for field in optional_sigmas:
        value = getattr(obj, field)
        if value is not None:
            check_float(obj.name, field, value, low=0.0, strict=True)


def as_batch(a, n: tuple[int, ...], name: str, B: int | None = None) -> np.ndarray:
    """``a`` as float (B, *n); raises ``ValueError("<name>: ...")`` on a wrong shape."""
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 1 + len(n) or arr.shape[1:] != n or (B is not None and arr.shape[0] != B):
        want = f"({'B' if B is None else B}{''.join(f', {k}' for k in n)})"
        raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    return arr


def finite_or_zero(a: np.ndarray) -> np.ndarray:
    """``a`` with non-finite entries replaced by 0 (gated entries of :class:`Linearized`)."""
    return np.where(np.isfinite(a), a, 0.0)
