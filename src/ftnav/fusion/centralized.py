"""Centralized Kalman filter over all sensors: the optimal reference (spec §1, §6).

Works on the augmented state (common + every sensor's private states).  Sensors are
processed sequentially, which equals the stacked update because R is block-diagonal
(spec §6.1).  With a residual test every sensor is tested against the common prior
first; a flagged sensor is skipped (isolation).  The guard (:mod:`ftnav.fusion.guard`)
tracks each sensor's pull on the filter's own estimate, decides the isolation and rolls
a newly isolated sensor's recent pull back after the update.
"""

from __future__ import annotations

from typing import ClassVar, Literal, NamedTuple

import numpy as np
from pydantic import model_validator

from ftnav.core import kalman as kf
from ftnav.core.kalman import Gaussian
from ftnav.fdi.chi2 import DetectorState
from ftnav.fdi.features import whitened_innovation
from ftnav.fusion.config import NOTHING_LEARNED, Learned, MethodBase, RbfDetector, config_error
from ftnav.fusion.detection import Detection
from ftnav.fusion.guard import Guard, GuardState
from ftnav.fusion.locals import LocalBank, NoiseState, gated, measurements
from ftnav.fusion.protocol import StepOutput, minus, select
from ftnav.model.system import Epoch, LinearSystem

__all__ = ["CentralizedConfig", "CentralizedFilter", "CentralizedState", "check"]


class CentralizedConfig(MethodBase):
    """``architecture = "centralized"``: one Kalman filter over every sensor.

    Its residual test uses the filter's own prior, so the test has no ``prior``.
    """

    DETECTORS: ClassVar[tuple[str, ...]] = (
        "none",
        "oracle",
        "residual-chi2",
        "cusum",
        "glr",
        "separation",
        "rbf",
    )
    PRIORS: ClassVar[tuple[str, ...]] = ("local",)

    architecture: Literal["centralized"] = "centralized"

    @model_validator(mode="after")
    def _check(self) -> CentralizedConfig:
        self.check_pieces()
        return self


class CentralizedState(NamedTuple):
    x: np.ndarray  # (B, n_aug)
    P: np.ndarray  # (B, n_aug, n_aug)
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None
    guard: GuardState | None = None


class CentralizedFilter:
    """Centralized KF (optionally with residual chi-square isolation and VB noise).

    Parameters
    ----------
    system : the linear system.
    config : the method's settings.
    learned : the trained RBF model of an ``rbf`` detector.
    dt : the filter period (s): the guard's windows.
    """

    def __init__(
        self,
        system: LinearSystem,
        config: CentralizedConfig,
        learned: Learned = NOTHING_LEARNED,
        dt: float = 1.0,
    ):
        self.system = system
        self.config = config
        self.detection = Detection(config.detector, learned.detector, system.sensors)
        self.bank = LocalBank(system, config.noise, augmented=True)
        g = config.guard_settings
        self.guard = (
            None
            if g is None
            else Guard.fused(g, system.sensors, system.n_aug, dt, self.detection.separation)
        )

    @property
    def n_filters(self) -> int:
        return self.system.n_sensors

    def init(self, batch: int) -> CentralizedState:
        x0, P0 = self.system.augmented_initial()
        return CentralizedState(
            np.broadcast_to(x0, (batch,) + x0.shape).copy(),
            np.broadcast_to(P0, (batch,) + P0.shape).copy(),
            self.bank.initial_noise(batch),
            self.detection.init(batch, self.n_filters),
            None if self.guard is None else self.guard.init(batch),
        )

    def step(self, state: CentralizedState, epoch: Epoch) -> tuple[CentralizedState, StepOutput]:
        """Advance one epoch; see :class:`~ftnav.fusion.protocol.StepOutput`."""
        N, bank = self.n_filters, self.bank
        F, Q = self.system.augmented_transition(lin=epoch.lin)
        Hs = bank.H(epoch.lin)
        x, P = kf.predict(state.x, state.P, F, Q)
        prior = Gaussian(x, P)
        meas0 = measurements(epoch, self.system.sensors)
        meas = gated(
            meas0,
            self.system.sensors,
            lambda i: bank.residual(
                i, prior, epoch.z[i], meas0.usable[:, i], Hs[i], state.noise[i]
            ),
        )
        usable = meas.usable
        R_now = [bank.noise_now(i, state.noise[i]) for i in range(N)]
        # every finite measurement against the prediction: what the method watches
        watch = np.stack(
            [
                bank.residual(i, prior, epoch.z[i], meas0.usable[:, i], Hs[i], state.noise[i])
                for i in range(N)
            ],
            1,
        )
        # the residual test's statistic (spec §3.1) or the whitened innovations (§3.3)
        innov = None
        if self.detection.whitened:
            innov = [
                bank.whitened(i, prior, epoch.z[i], usable[:, i], Hs[i], state.noise[i])
                for i in range(N)
            ]
            stat = np.stack([(w**2).sum(-1) for w in innov], 1)
        elif self.detection.residual:
            stat = np.stack(
                [
                    bank.residual(i, prior, epoch.z[i], usable[:, i], Hs[i], state.noise[i])
                    for i in range(N)
                ],
                1,
            )
        else:
            stat = np.zeros(usable.shape)
        feats = None
        if isinstance(self.config.detector, RbfDetector):
            feats = np.concatenate(
                [
                    whitened_innovation(x, P, epoch.z[i], usable[:, i], Hs[i], R_now[i])
                    for i in range(N)
                ],
                1,
            )
        det_state, det_out = self.detection.step(
            state.detector, stat, meas.dof, usable, epoch.labels, feats, innov
        )
        guarded = None
        if self.guard is not None:
            assert state.guard is not None
            guarded = self.guard.begin(
                state.guard,
                [prior],
                [F],
                epoch.z,
                Hs,
                R_now,
                usable,
                det_out,
                repeated=epoch.repeated,
            )
            det_out = guarded.detection
        use = usable if det_out is None else usable & ~det_out.flag
        noise, R_hat = [], []
        for i in range(N):
            up = bank.update(i, Gaussian(x, P), epoch.z[i], use[:, i], Hs[i], state.noise[i])
            x, P = up.x, up.P
            noise.append(up.noise)
            R_hat.append(np.diagonal(up.R, axis1=-2, axis2=-1))
        guard_state = None
        if guarded is not None:
            assert self.guard is not None
            guard_state, (amend,) = self.guard.finish(guarded, [prior], epoch.z, Hs, R_now, usable)
            x = select(amend.where, x - amend.dx, x)
            P = select(amend.where, P + amend.dP, P)
        nc = self.system.n_common
        out = StepOutput(
            x[:, :nc],
            P[:, :nc, :nc],
            None,
            det_out,
            tuple(R_hat),
            meas.nan,
            guard=None if guarded is None else guarded.output,
            nis=watch,
            used=use,
            available=meas0.usable,
        )
        return CentralizedState(x, P, tuple(noise), det_state, guard_state), out

    def shift(self, state: CentralizedState, delta: np.ndarray) -> CentralizedState:
        return state._replace(x=minus(state.x, delta))

    def local_estimates(self, state: CentralizedState, n: int) -> None:
        return None


def check(config: CentralizedConfig, system: LinearSystem, learned: Learned) -> None:
    """Boundary checks that need the system or the trained model."""
    config.check_sensors(system.sensors)
    model = learned.detector
    if model is not None and "state-difference" in model.features:
        raise config_error(
            "its features include local state differences; a centralized "
            "filter has no local filters",
            "detector",
            "model",
        )
