"""The bank of local filters every distributed architecture runs (spec §1.3, §6.1, §7).

A *local filter* processes one sensor over ``[x_c; x_si]`` (common states, then the
sensor's private states).  :class:`LocalBank` holds the N local models and the noise
adaptation and does, for all N at once, what every architecture's epoch starts with:
the usable measurements of the epoch (scheduled and finite; NaN counted), the
measurement matrices, the prediction, the masked Kalman or variational-Bayes update,
and the residual statistics of spec §3.1.  The update is done for the whole batch
and then selected per run with a mask, so runs whose measurement is missing, NaN, or
isolated keep their prior.  Shapes: batch B, common states ``n_c``, local states
``n_i``, measurement ``m_i``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from scipy.stats import chi2

from ftnav.core import kalman as kf
from ftnav.core import vb as vbk
from ftnav.core.kalman import Gaussian
from ftnav.fdi.chi2 import chi2_threshold
from ftnav.fdi.features import whitened_innovation
from ftnav.fusion.config import Noise, VbNoise
from ftnav.fusion.protocol import select
from ftnav.model.system import Epoch, Linearization, LinearSystem, Sensor

__all__ = [
    "LocalBank",
    "LocalUpdate",
    "Measurements",
    "gated",
    "NoiseState",
    "initial_noise",
    "local_update",
    "measurements",
    "predicted_noise",
    "residual_statistic",
    "restart_apart",
    "learned_beside",
]


class NoiseState(NamedTuple):
    """Inverse-gamma posterior of a VB local filter (spec §7), (B, m) each."""

    alpha: np.ndarray
    beta: np.ndarray


class LocalUpdate(NamedTuple):
    """One local filter's update: posterior, NIS (0 where not updated), the noise used."""

    x: np.ndarray
    P: np.ndarray
    nis: np.ndarray  # (B,) 0 where not updated
    R: np.ndarray  # (B, m, m) noise used (adapted under VB)
    noise: NoiseState | None


class Measurements(NamedTuple):
    """The epoch preamble: which measurements are used, which were NaN, their dof.

    Attributes
    ----------
    usable : (B, N) bool, scheduled and finite.
    nan : (B, N) bool, scheduled but NaN/inf (treated as missing, counted).
    dof : (B, N) int, measurement dimension where usable, else 0.
    """

    usable: np.ndarray
    nan: np.ndarray
    dof: np.ndarray


def measurements(epoch: Epoch, sensors: Sequence[Sensor]) -> Measurements:
    """Usable, NaN and degrees-of-freedom masks of an epoch's measurements."""
    finite = np.stack([np.isfinite(z).all(-1) for z in epoch.z], 1)
    usable = epoch.available & finite
    dims = np.array([s.dim for s in sensors])[None, :]
    return Measurements(usable, epoch.available & ~finite, dims * usable)


def gated(
    meas: Measurements, sensors: Sequence[Sensor], nis: Callable[[int], np.ndarray]
) -> Measurements:
    """The measurements with every gated sensor's (:attr:`Sensor.gate`) left out where
    its innovation's χ² ``nis(i)`` (B,) against the method's reference fails the gate
    (a pseudo-measurement whose constraint does not hold: neither used nor tested)."""
    if not any(s.gate for s in sensors):
        return meas
    usable = meas.usable.copy()
    for i, s in enumerate(sensors):
        if s.gate and usable[:, i].any():
            usable[:, i] &= nis(i) <= chi2.isf(s.gate, s.dim)
    dims = np.array([s.dim for s in sensors])[None, :]
    return Measurements(usable, meas.nan, dims * usable)


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
    vb: VbNoise | None = None,
    adapt: np.ndarray | None = None,
) -> LocalUpdate:
    """Masked Kalman (or VB, spec §7.2) update of one local filter.

    Parameters
    ----------
    x, P : (B, n), (B, n, n) prior.
    z : (B, m) measurement; entries of runs with ``use`` False are ignored.
    use : (B,) bool, runs that take the measurement.
    H, R : (m, n) or (B, m, n), (m, m) model; R is the nominal noise.
    noise : VB state, or None for a fixed-R filter.
    vb : the VB settings when this filter adapts R.
    adapt : (B,) bool, runs whose VB noise estimate learns from the measurement
        (default ``use``).  An isolated filter whose state only time-updates can
        still adapt its R̂ (``adapt`` without ``use``); a run with ``use`` and not
        ``adapt`` takes the measurement with the predicted R̂ (``ρβ/ρα``), as a plain
        Kalman update, and its noise posterior is only forgotten.
    """
    adapt = use if adapt is None else adapt
    z0 = np.where((use | adapt)[:, None], z, 0.0)
    if vb is None or noise is None:
        up = kf.update(x, P, z0, H, R)
        Rused = np.broadcast_to(R, (x.shape[0],) + R.shape)
        new_noise = None
    else:
        a, b = vbk.vb_predict(noise.alpha, noise.beta, vb.rho)
        up, a_post, b_post, R_post = vbk.vb_update(
            x, P, z0, H, a, b, iterations=vb.iterations, variant=vb.variant
        )
        # no measurement: the noise posterior is only forgotten (spec §7.2 predict)
        new_noise = NoiseState(select(adapt, a_post, a), select(adapt, b_post, b))
        R_prior = vbk.noise_estimate(a, b)
        fixed = use & ~adapt
        if fixed.any():
            # used but not learned from: the plain update with the predicted R̂
            plain = kf.update(x, P, z0, H, R_prior)
            up = kf.Update(*(select(fixed, p, u) for p, u in zip(plain, up, strict=True)))
            R_post = select(fixed, R_prior, R_post)
        # the noise the posterior was computed with (what a CKF needs to reproduce it)
        Rused = select(use, R_post, R_prior)
    return LocalUpdate(
        select(use, up.x, x), select(use, up.P, P), np.where(use, up.nis, 0.0), Rused, new_noise
    )


def predicted_noise(noise: NoiseState | None, R: np.ndarray, rho: float) -> np.ndarray:
    """Noise the next update starts from: R, or ``R̂ = ρβ/(ρα + ½)`` under VB (spec §7.2)."""
    if noise is None:
        return R
    return vbk.noise_estimate(rho * noise.alpha + 0.5, rho * noise.beta)


#: a VB local's prediction departs from the centre's beyond chance at this probability
#: (χ²_m in its aid's rows against its own predicted covariance): :func:`learned_beside`
DEPART_PROBABILITY = 1e-3


def learned_beside(
    bank: LocalBank,
    i: int,
    prior: Gaussian,
    centre: Gaussian,
    z: np.ndarray,
    use: np.ndarray,
    H: np.ndarray,
    noise: NoiseState | None,
    adapt: np.ndarray,
    update: LocalUpdate,
) -> LocalUpdate:
    """A VB local's ``update`` where its own prior is no reference for its noise: its
    prediction of its aid departs from the fusion centre's beyond chance
    (:data:`DEPART_PROBABILITY`, against its own predicted covariance) while the aid
    agrees with the centre's at its declared noise.  There the local learns its R̂
    against the centre's prior and takes its measurement with that R̂ as a plain Kalman
    update (:func:`local_update`), so the centre is still the CKF with the R̂ used (spec
    §6.4).

    Why (docs/integrity.md §1.17): paper 002's local filter sees only its aid (spec
    §6.1), and the VB (spec §7) assumes its prior is right.  A fault the local cannot
    model (``seed002``'s GNSS local under a 10 °/h pitch-gyro step) grows its residuals;
    its VB learns them as noise, which lets its state drift further: σ̂ 1.5 m → 7 km,
    the centre 150–245 m off.  Learning against the centre at every epoch instead taught
    the GNSS a frozen star tracker's error (4 km); the agreement of the aid with the
    centre at its declared noise tells the two apart.  A noise increase moves neither the
    local's prediction nor the centre's, and is learned from the local's prior as the
    paper does (``seed002``'s built-in run is unchanged).

    Parameters
    ----------
    bank, i : the local filters and the VB local's index.
    prior, centre : the local's and the centre's predictions.
    z, use, H, noise, adapt : as :meth:`LocalBank.update`.
    update : the local's own update (:meth:`LocalBank.update` from ``prior``).
    """
    m = z.shape[-1]
    # the centre's prediction of the aid as a noiseless measurement of the local's prior
    q_d = kf.prior_nis(prior.x, prior.P, (H @ centre.x[..., None])[..., 0], H, np.zeros((m, m)))
    limit = float(chi2_threshold(m, DEPART_PROBABILITY))  # cached: a call per epoch
    beside = adapt & (q_d > limit)
    if beside.any():
        beside &= bank.residual(i, centre, z, adapt, H, None) <= limit
    if not beside.any() or noise is None:
        return update
    learned = bank.update(i, centre, z, adapt, H, noise, adapt).noise
    assert learned is not None
    rho = bank.rho
    fixed = NoiseState(learned.alpha / rho, learned.beta / rho)
    alt = bank.update(i, prior, z, use, H, fixed, np.zeros_like(use))
    assert alt.noise is not None and update.noise is not None
    return LocalUpdate(
        select(beside, alt.x, update.x),
        select(beside, alt.P, update.P),
        np.where(beside, alt.nis, update.nis),
        select(beside, alt.R, update.R),
        NoiseState(
            select(beside, alt.noise.alpha, update.noise.alpha),
            select(beside, alt.noise.beta, update.noise.beta),
        ),
    )


def restart_apart(
    bank: LocalBank,
    i: int,
    prior: Gaussian,
    update: LocalUpdate,
    base: Gaussian,
    nc: int,
    where: np.ndarray,
    probability: float,
    z: np.ndarray,
    use: np.ndarray,
    H: np.ndarray,
    noise: NoiseState | None,
) -> tuple[Gaussian, LocalUpdate]:
    """An independent local let back in (``where``, (B,)), restarted from ``base`` where
    its common states are far from it: its prior and update, else as they were.

    ``base`` is the local's prior with its common block (its first ``nc`` states) the
    reference its aid was just re-admitted against
    (:func:`ftnav.fusion.protocol.with_common`); "far" is ``dᵀ(P_c + P_c,base)⁻¹d`` on
    the common states beyond the χ²(``nc``) quantile of false-alarm ``probability`` (the
    guard's).  The aid's measurements passed against the reference; a local that kept
    measuring a frozen aid, or coasted while held, may not have: it would carry the
    fault's offset into the fusion (docs/integrity.md §1.14).  The restarted rows are
    updated from ``base`` with the epoch's measurement (the noise state, VB's, is the
    local's own).
    """
    if not where.any():
        return prior, update
    d = prior.x[:, :nc] - base.x[:, :nc]
    S = prior.P[:, :nc, :nc] + base.P[:, :nc, :nc]
    far = where & (
        np.einsum("bi,bi->b", d, np.linalg.solve(S, d[..., None])[..., 0])
        > chi2.isf(probability, nc)
    )
    if not far.any():
        return prior, update
    again = bank.update(i, base, z, use, H, noise)
    return Gaussian(select(far, base.x, prior.x), select(far, base.P, prior.P)), update._replace(
        x=select(far, again.x, update.x),
        P=select(far, again.P, update.P),
        nis=np.where(far, again.nis, update.nis),
    )


def residual_statistic(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, use: np.ndarray, H: np.ndarray, R: np.ndarray
) -> np.ndarray:
    """NIS of a prior (B, n), (B, n, n) against z (B, m) (spec §3.1); 0 where not used."""
    z0 = np.where(use[:, None], z, 0.0)
    return np.where(use, kf.prior_nis(x, P, z0, H, R), 0.0)


class LocalBank:
    """The N local filters of an architecture: models, noise adaptation, their epoch.

    Parameters
    ----------
    system : the system; local filter i carries ``[x_c; x_si]`` (``system.local(i)``).
    noise : the method's noise adaptation; a filter adapts R when VB is on and its
        sensor is listed (an empty list: every sensor).
    augmented : the locals run on the whole augmented state (the distributed filter)
        instead of ``[x_c; x_si]``.
    """

    def __init__(self, system: LinearSystem, noise: Noise, augmented: bool = False):
        self.system = system
        self.N = system.n_sensors
        self.nc = system.n_common
        self.augmented = augmented
        self.models = [system.local(i) for i in range(self.N)]
        self.vb = noise if isinstance(noise, VbNoise) else None
        self.vb_on = [
            self.vb is not None and (not self.vb.sensors or s.name in self.vb.sensors)
            for s in system.sensors
        ]
        self.H_const: list[np.ndarray] | None = None
        if not system.linearized:
            self.H_const = [self._constant_H(i, augmented) for i in range(self.N)]

    @property
    def sensors(self) -> tuple[Sensor, ...]:
        return self.system.sensors

    @property
    def rho(self) -> float:
        return 0.99 if self.vb is None else self.vb.rho

    def initial_noise(self, batch: int) -> tuple[NoiseState | None, ...]:
        """The VB prior of every adapting local filter (None for a fixed-R one)."""
        return tuple(
            initial_noise(s.R, batch) if on else None
            for s, on in zip(self.sensors, self.vb_on, strict=True)
        )

    def _constant_H(self, i: int, augmented: bool) -> np.ndarray:
        H = self.system.augmented_H(i) if augmented else self.system.local(i).H
        assert H is not None  # a constant system has constant H
        return H

    def H(self, lin: Linearization | None) -> list[np.ndarray]:
        """Every local filter's measurement matrix of the epoch."""
        if lin is None:
            assert self.H_const is not None
            return list(self.H_const)
        if self.augmented:
            return [self.system.augmented_H(i, lin) for i in range(self.N)]
        return list(lin.H)

    def update(
        self,
        i: int,
        prior: Gaussian,
        z: np.ndarray,
        use: np.ndarray,
        H: np.ndarray,
        noise: NoiseState | None,
        adapt: np.ndarray | None = None,
    ) -> LocalUpdate:
        """Local filter i's masked (VB) update from ``prior`` (``adapt``:
        :func:`local_update`)."""
        vb = self.vb if self.vb_on[i] else None
        return local_update(*prior, z, use, H, self.sensors[i].R, noise, vb, adapt)

    def noise_now(self, i: int, noise: NoiseState | None) -> np.ndarray:
        """The noise local filter i's next update starts from (R, or the VB estimate)."""
        return predicted_noise(noise, self.sensors[i].R, self.rho)

    def residual(
        self,
        i: int,
        prior: Gaussian,
        z: np.ndarray,
        use: np.ndarray,
        H: np.ndarray,
        noise: NoiseState | None,
    ) -> np.ndarray:
        """NIS of sensor i's measurement against ``prior`` (spec §3.1), 0 where unused."""
        return residual_statistic(*prior, z, use, H, self.noise_now(i, noise))

    def whitened(
        self,
        i: int,
        prior: Gaussian,
        z: np.ndarray,
        use: np.ndarray,
        H: np.ndarray,
        noise: NoiseState | None,
    ) -> np.ndarray:
        """(B, m) sensor i's innovation against ``prior`` whitened by its covariance
        (spec §3.3; zero where unused); its squared norm is :meth:`residual`."""
        return whitened_innovation(*prior, z, use, H, self.noise_now(i, noise))
