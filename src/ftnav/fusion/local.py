"""Pieces shared by every architecture: masked local updates, VB noise, detection.

A *local filter* processes one sensor.  Its update is done for the whole batch
and then selected per run with a mask, so runs whose measurement is missing,
NaN (counted), or isolated keep their prior.  Shapes: batch B, common states
``n_c``, local states ``n_i``, measurement ``m_i``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.core import vb as vbk
from ftnav.fdi.chi2 import ChiSquareDetector, DetectorOutput, DetectorState, state_statistic
from ftnav.fdi.rbf import RBFDetector, RBFModel
from ftnav.model.scenario import Method

__all__ = [
    "select",
    "with_common",
    "check_prior",
    "NoiseState",
    "LocalUpdate",
    "local_update",
    "Detection",
    "make_detector",
    "detector_feature_kinds",
    "load_method_model",
    "StateTest",
]


def check_prior(method: Method, allowed: tuple[str, ...] = ("local", "global")) -> None:
    """One-line error unless ``method.prior`` is one the architecture implements."""
    if method.prior not in allowed:
        raise ValueError(
            f"methods[{method.name}].prior: {method.prior!r} is not available "
            f"with architecture {method.architecture!r} (expected one of "
            f"{list(allowed)})"
        )


def with_common(
    prior: tuple[np.ndarray, np.ndarray], xc: np.ndarray, Pc: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A local prior ``(x, P)`` with its common block replaced by ``(xc, Pc)``.

    Private states keep their prior; their cross-covariance with the common block
    is set to zero.  This is the prior of a residual test against a fused
    reference (spec §3.1 with ``prior = "global"``).
    """
    nc = xc.shape[-1]
    x, P = prior
    if x.shape[-1] == nc:
        return xc, Pc
    x_g = np.concatenate([xc, x[:, nc:]], 1)
    P_g = P.copy()
    P_g[:, :nc, :nc] = Pc
    P_g[:, :nc, nc:] = 0.0
    P_g[:, nc:, :nc] = 0.0
    return x_g, P_g


def select(mask: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` where ``mask`` (B,) else ``b``, broadcasting over trailing axes."""
    if mask.all():
        return a
    if not mask.any():
        return b
    m = np.asarray(mask).reshape(mask.shape + (1,) * (a.ndim - mask.ndim))
    return np.where(m, a, b)


class NoiseState(NamedTuple):
    """Inverse-gamma posterior of a VB local filter (spec §7), (B, m) each."""

    alpha: np.ndarray
    beta: np.ndarray


class LocalUpdate(NamedTuple):
    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray  # (B,) 0 where not updated
    R: np.ndarray  # (B, m, m) noise used (adapted under VB)
    noise: NoiseState | None


def vb_variant(method: Method) -> str | None:
    """``"sarkka"``, ``"literal"`` or None from the method's ``adaptive_noise``."""
    return {"none": None, "vb": "sarkka", "vb-literal": "literal"}[method.adaptive_noise]


def vb_enabled(method: Method, sensors) -> list[bool]:
    """Per sensor: does its local filter adapt R (``adaptive_noise`` and ``vb_sensors``)."""
    on = method.adaptive_noise != "none"
    return [on and (not method.vb_sensors or s.name in method.vb_sensors) for s in sensors]


def initial_noise(R: np.ndarray, batch: int, alpha0: float = 1.0) -> NoiseState:
    """VB prior with ``β₀/α₀`` equal to the nominal diagonal R (spec §7.2 [A])."""
    m = R.shape[0]
    alpha = np.full((batch, m), alpha0)
    return NoiseState(alpha, alpha * np.diag(R)[None, :])


def local_update(
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    use: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    noise: NoiseState | None,
    *,
    variant: str | None = None,
    rho: float = 0.99,
    iterations: int = 3,
) -> LocalUpdate:
    """Masked Kalman (or VB) update of one local filter.

    Parameters
    ----------
    x, P : (B, n), (B, n, n) prior.
    z : (B, m) measurement; entries of runs with ``use`` False are ignored.
    use : (B,) bool, runs that take the measurement.
    H, R : (m, n), (m, m) model; R is the nominal noise.
    noise : VB state, or None for a fixed-R filter.
    """
    z0 = np.where(use[:, None], z, 0.0)
    if variant is None:
        up = kf.update(x, P, z0, H, R)
        Rused = np.broadcast_to(R, (x.shape[0],) + R.shape)
        new_noise = None
    else:
        a, b = vbk.vb_predict(noise.alpha, noise.beta, rho)
        up, a_post, b_post, R_post = vbk.vb_update(
            x, P, z0, H, a, b, iterations=iterations, variant=variant
        )
        # no measurement: the noise posterior is only forgotten (spec §7.2 predict)
        new_noise = NoiseState(select(use, a_post, a), select(use, b_post, b))
        # the noise the posterior was computed with (what a CKF needs to reproduce it)
        Rused = select(use, R_post, vbk.noise_estimate(a, b))
    return LocalUpdate(
        select(use, up.x, x), select(use, up.P, P), np.where(use, up.nis, 0.0), Rused, new_noise
    )


def predicted_noise(noise: NoiseState | None, R: np.ndarray, rho: float) -> np.ndarray:
    """Noise the next update starts from: R, or ``R̂ = ρβ/(ρα + ½)`` under VB (spec §7.2)."""
    if noise is None:
        return R
    return vbk.noise_estimate(rho * noise.alpha + 0.5, rho * noise.beta)


def valid_measurement(z: np.ndarray, available: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(usable, nan) masks (B,): scheduled and finite; scheduled but NaN/inf (counted)."""
    finite = np.isfinite(z).all(-1)
    return available & finite, available & ~finite


class Detection(NamedTuple):
    """Per-epoch detector result for the N local filters, (B, N) each."""

    output: DetectorOutput
    state: DetectorState


def make_detector(method: Method, system=None) -> ChiSquareDetector | RBFDetector | None:
    """The method's detector (chi-square or RBF network), None without a test.

    An RBF detector loads ``method.model`` and checks it against ``system``
    (states, sensors, system hash); a bad or foreign file raises
    :class:`~ftnav.io.model_file.ModelFileError` naming the method.
    """
    if method.detector in ("residual-chi2", "state-chi2"):
        return ChiSquareDetector(
            method.false_alarm_probability, method.window, method.n_on, method.n_off
        )
    if method.detector == "rbf":
        model = load_method_model(
            RBFModel, method, system, "detector 'rbf'", "ftnav train-detector"
        )
        return RBFDetector(model, method.threshold, method.n_on, method.n_off)
    return None


def load_method_model(cls, method: Method, system, what: str, trainer: str):
    """``cls.load(method.model)`` checked against ``system``; errors name the method's field.

    ``cls`` is :class:`~ftnav.fdi.rbf.RBFModel` or
    :class:`~ftnav.fusion.neural.NeuronModel`; ``what`` and ``trainer`` word the
    error when no file is given.
    """
    from ftnav.io.model_file import ModelFileError

    field = f"methods[{method.name}].model"
    if method.model is None:
        raise ValueError(f"{field}: {what} needs a trained model file ({trainer})")
    compat = None if system is None else system.compatibility()
    try:
        return cls.load(method.model, compat)
    except ModelFileError as e:
        raise ModelFileError(method.model, e.reason, field=field) from None


def detector_feature_kinds(
    detector, method: Method, extra: tuple[str, ...] | None = None
) -> tuple[tuple[str, ...] | None, str]:
    """Feature kinds a filter must compute and the prior its innovations use.

    The RBF detector's kinds and trained prior, or ``extra`` with the method's
    ``prior`` (training data collection); ``(None, prior)`` when no features are needed.
    """
    if isinstance(detector, RBFDetector):
        return tuple(extra) if extra else detector.features, detector.model.prior
    return (tuple(extra) if extra else None), method.prior


class StateTest:
    """Pure propagators of the state chi-square test, one per local (spec §3.2).

    The propagator ``x̂ˢ = Φ x̂ˢ``, ``Pˢ = Φ Pˢ Φᵀ + Q`` restarts from the local
    posterior every ``reset`` epochs; the first 3 epochs after a restart are not
    tested because ``Pˢ − P`` is ill-conditioned then.
    """

    SKIP = 3

    def __init__(self, reset: int):
        self.reset = int(reset)

    def statistic(self, k, x, P, xs, Ps):
        """(statistic, dof, tested) at step k for posterior (x, P), propagator (xs, Ps)."""
        age = (k - 1) % self.reset + 1
        lam, dof = state_statistic(x, P, xs, Ps)
        tested = np.full(lam.shape, age > self.SKIP)
        return lam, dof, tested

    def restart(self, k, x, P, xs, Ps):
        """Restart the propagator from the posterior at the end of a period."""
        if k % self.reset == 0:
            return x, P
        return xs, Ps


class StepOutput(NamedTuple):
    """What every fusion filter reports per epoch.

    Attributes
    ----------
    x : (B, n_c) fused estimate of the common states.
    P : (B, n_c, n_c) its covariance.
    beta : (B, N) sharing coefficients in effect (federated only) or None.
    detection : detector output (B, N) per local filter / sensor, or None.
    R_hat : per sensor (B, m_i) diagonal of the noise used (adapted under VB).
    nan : (B, N) bool, scheduled measurements that were NaN/inf (treated as missing).
    features : (B, F) learned-detector features of the epoch (spec §4.1), or None.
    """

    x: np.ndarray
    P: np.ndarray
    beta: np.ndarray | None
    detection: DetectorOutput | None
    R_hat: tuple[np.ndarray, ...]
    nan: np.ndarray
    features: np.ndarray | None = None


def detect(
    method: Method,
    detector: ChiSquareDetector | None,
    state: DetectorState | None,
    statistic: np.ndarray,
    dof: np.ndarray,
    tested: np.ndarray,
    oracle: np.ndarray,
    features: np.ndarray | None = None,
) -> tuple[DetectorState | None, DetectorOutput | None]:
    """Run the method's detector for one epoch; ``oracle`` (N,) or (B, N): true fault flags.

    A chi-square detector thresholds ``statistic``; an RBF detector evaluates its
    network on ``features`` (B, F) (spec §4) and ignores the statistic.
    """
    if isinstance(detector, RBFDetector):
        return detector.step(state, features, tested)
    if detector is not None:
        return detector.step(state, statistic, dof, tested)
    if method.detector == "oracle":
        flag = np.broadcast_to(np.asarray(oracle, dtype=bool), statistic.shape).copy()
        return state, DetectorOutput(
            np.zeros_like(statistic), np.full_like(statistic, np.inf), flag, flag
        )
    return state, None


def residual_statistic(x, P, z, use, H, R):
    """NIS of a prior (B, n), (B, n, n) against z (B, m); 0 where not used."""
    z0 = np.where(use[:, None], z, 0.0)
    return np.where(use, kf.prior_nis(x, P, z0, H, R), 0.0)
