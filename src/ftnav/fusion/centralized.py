"""Centralized Kalman filter over all sensors: the optimal reference (spec §1, §6).

Works on the augmented state (common + every sensor's private states).  Sensors
are processed sequentially, which equals the stacked update because R is
block-diagonal (spec §6.1).  With a residual test every sensor is tested against
the common prior first; a flagged sensor is skipped (isolation).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.fdi.chi2 import DetectorState
from ftnav.fdi.features import whitened_innovation
from ftnav.fusion.local import (
    NoiseState,
    StepOutput,
    check_prior,
    detect,
    initial_noise,
    local_update,
    make_detector,
    predicted_noise,
    residual_statistic,
    valid_measurement,
    vb_enabled,
    vb_variant,
)
from ftnav.model.scenario import Method
from ftnav.model.system import LinearSystem

__all__ = ["CentralizedFilter", "CentralizedState"]


class CentralizedState(NamedTuple):
    x: np.ndarray  # (B, n_aug)
    P: np.ndarray  # (B, n_aug, n_aug)
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None


class CentralizedFilter:
    """Centralized KF (optionally with residual chi-square isolation and VB noise).

    Parameters
    ----------
    system : the linear system.
    method : settings; uses ``detector`` (none | residual-chi2 | oracle),
        ``false_alarm_probability``, ``window``, ``n_on``, ``n_off``,
        ``adaptive_noise``, ``vb_*``.
    """

    def __init__(self, system: LinearSystem, method: Method | None = None):
        method = method or Method(name="centralized", architecture="centralized")
        if method.detector == "state-chi2":
            raise ValueError(
                f"methods[{method.name}].detector: 'state-chi2' needs local filters "
                "(federated or distributed architecture)"
            )
        check_prior(method)
        self.system = system
        self.method = method
        self.detector = make_detector(method, system)
        if method.detector == "rbf" and "state-difference" in self.detector.features:
            raise ValueError(
                f"methods[{method.name}].model: its features include local "
                "state differences; a centralized filter has no local filters"
            )
        self.variant = vb_variant(method)
        self.H = [system.augmented_H(i) for i in range(system.n_sensors)]
        self.vb_on = vb_enabled(method, system.sensors)

    @property
    def n_filters(self) -> int:
        return self.system.n_sensors

    def init(self, batch: int) -> CentralizedState:
        x0, P0 = self.system.augmented_initial()
        noise = tuple(
            initial_noise(s.R, batch) if on else None
            for s, on in zip(self.system.sensors, self.vb_on, strict=True)
        )
        det = self.detector.init(batch, self.n_filters) if self.detector else None
        return CentralizedState(
            np.broadcast_to(x0, (batch,) + x0.shape).copy(),
            np.broadcast_to(P0, (batch,) + P0.shape).copy(),
            noise,
            det,
        )

    def step(self, state: CentralizedState, k: int, z, available, oracle, lin=None):
        """Advance one epoch; see :class:`~ftnav.fusion.local.StepOutput`.

        ``lin`` (:class:`~ftnav.model.system.Linearization`) supplies the epoch's
        per-run matrices of an error-state model linearized at the INS solution.
        """
        m = self.method
        F, Q = self.system.augmented_transition(k, lin=lin)
        Hs = (
            self.H
            if lin is None
            else [self.system.augmented_H(i, lin) for i in range(self.n_filters)]
        )
        x, P = kf.predict(state.x, state.P, F, Q)
        usable, nan = zip(
            *(valid_measurement(z[i], available[:, i]) for i in range(self.n_filters)), strict=True
        )
        usable, nan = np.stack(usable, 1), np.stack(nan, 1)
        R_now = [
            predicted_noise(state.noise[i], s.R, m.vb_rho)
            for i, s in enumerate(self.system.sensors)
        ]
        # the residual test's statistic (spec §3.1); no other detector reads it
        stat = (
            np.stack(
                [
                    residual_statistic(x, P, z[i], usable[:, i], Hs[i], R_now[i])
                    for i in range(self.n_filters)
                ],
                1,
            )
            if m.detector == "residual-chi2"
            else np.zeros(usable.shape)
        )
        dof = np.array([s.dim for s in self.system.sensors])[None, :] * usable
        feats = None
        if m.detector == "rbf":
            feats = np.concatenate(
                [
                    whitened_innovation(x, P, z[i], usable[:, i], Hs[i], R_now[i])
                    for i in range(self.n_filters)
                ],
                1,
            )
        det_state, det_out = detect(
            m, self.detector, state.detector, stat, dof, usable, oracle, feats
        )
        use = usable if det_out is None else usable & ~det_out.flag
        noise, R_hat = [], []
        for i, s in enumerate(self.system.sensors):
            up = local_update(
                x,
                P,
                z[i],
                use[:, i],
                Hs[i],
                s.R,
                state.noise[i],
                variant=self.variant if self.vb_on[i] else None,
                rho=m.vb_rho,
                iterations=m.vb_iterations,
            )
            x, P = up.x, up.P
            noise.append(up.noise)
            R_hat.append(np.diagonal(up.R, axis1=-2, axis2=-1))
        nc = self.system.n_common
        out = StepOutput(x[:, :nc], P[:, :nc, :nc], None, det_out, tuple(R_hat), nan)
        return CentralizedState(x, P, tuple(noise), det_state), out
