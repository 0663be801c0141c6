"""Exact distributed form of the centralized Kalman filter (paper 002 eq. 24; spec §6).

Every local filter runs a full KF on the augmented state with its own sensor,
its own Q and P0; the fusion centre propagates the global estimate and adds the
local information increments:

    Y⁺ = Y⁻ + Σ ΔY_i,  y⁺ = y⁻ + Σ Δy_i.

``increment="direct"`` transmits ``ΔY_i = Hᵢᵀ R̂ᵢ⁻¹ Hᵢ``, ``Δy_i = Hᵢᵀ R̂ᵢ⁻¹ z_i``
(default, spec §6.2 numerics); ``"difference"`` the paper's
``(P⁺)⁻¹ − (P⁻)⁻¹``, ``(P⁺)⁻¹x⁺ − (P⁻)⁻¹x⁻``.  A flagged local filter does the
time update only, so its increment is zero (isolation, spec §6.3); a missing
measurement (multi-rate, outage, NaN) likewise.

``mode="rescale"`` (Carlson's rescale mode as reconstructed in spec §1.5 [R],
enabled only with ``reconstructed=True``) is this filter with each local's
information scaled by ``γ = rescale_factor`` after every fusion, which keeps
the locals responsive while the centre, fed increments only, stays exact.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.core.linalg import spd_solve
from ftnav.fdi.chi2 import DetectorState
from ftnav.fdi.features import detector_features, whitened_innovation
from ftnav.fusion.local import (
    NoiseState,
    StateTest,
    StepOutput,
    check_prior,
    detect,
    detector_feature_kinds,
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

__all__ = ["DistributedFilter", "DistributedState"]


class DistributedState(NamedTuple):
    x: tuple[np.ndarray, ...]  # local posteriors (B, n_aug)
    P: tuple[np.ndarray, ...]
    xg: np.ndarray  # fusion centre (B, n_aug)
    Pg: np.ndarray
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None
    propagator: tuple[kf.Gaussian, ...] | None


class DistributedFilter:
    """Distributed fusion equal to the centralized KF (spec §6).

    Parameters
    ----------
    system : linear system.
    method : settings (``increment``, detector settings, ``prior``,
        ``adaptive_noise``, ``mode="rescale"`` with ``rescale_factor``).
    local_Q_scale, local_P0_scale : (N,) factors on each local filter's Q and P0
        (spec §6.2: they do not affect exactness in the linear case).
    features : feature kinds (spec §4.1) to compute every epoch even without an
        RBF detector (training data collection).
    """

    def __init__(
        self,
        system: LinearSystem,
        method: Method,
        local_Q_scale=None,
        local_P0_scale=None,
        features: tuple[str, ...] | None = None,
    ):
        name = f"methods[{method.name}]"
        if method.mode == "rescale" and not method.reconstructed:
            raise ValueError(
                f"{name}.mode: 'rescale' is a reconstruction (spec §1.5); "
                "set reconstructed = true to use it"
            )
        check_prior(method)
        self.system = system
        self.method = method
        N = system.n_sensors
        self.N = N
        self.H = [system.augmented_H(i) for i in range(N)]
        self.q_scale = np.ones(N) if local_Q_scale is None else np.asarray(local_Q_scale, float)
        self.p_scale = np.ones(N) if local_P0_scale is None else np.asarray(local_P0_scale, float)
        self.detector = make_detector(method, system)
        self.features, self.feature_prior = detector_feature_kinds(self.detector, method, features)
        self.state_test = (
            StateTest(method.state_test_reset) if method.detector == "state-chi2" else None
        )
        self.variant = vb_variant(method)
        self.vb_on = vb_enabled(method, system.sensors)
        self.gamma = method.rescale_factor if method.mode == "rescale" else 1.0

    @property
    def n_filters(self) -> int:
        return self.N

    def init(self, batch: int) -> DistributedState:
        x0, P0 = self.system.augmented_initial()
        B = batch
        xs = tuple(np.broadcast_to(x0, (B,) + x0.shape).copy() for _ in range(self.N))
        Ps = tuple(np.broadcast_to(P0 * c, (B,) + P0.shape).copy() for c in self.p_scale)
        noise = tuple(
            initial_noise(s.R, B) if on else None
            for s, on in zip(self.system.sensors, self.vb_on, strict=True)
        )
        det = self.detector.init(B, self.N) if self.detector else None
        prop = (
            tuple(kf.Gaussian(x, P) for x, P in zip(xs, Ps, strict=True))
            if self.state_test
            else None
        )
        return DistributedState(
            xs, Ps, xs[0].copy(), np.broadcast_to(P0, (B,) + P0.shape).copy(), noise, det, prop
        )

    def step(self, state: DistributedState, k: int, z, available, oracle, lin=None):
        """Advance one epoch (spec §6.1 steps 1-3); ``lin`` as in the centralized filter."""
        m, N = self.method, self.N
        F, Q = self.system.augmented_transition(k, lin=lin)
        Hs = self.H if lin is None else [self.system.augmented_H(i, lin) for i in range(N)]
        xg_pr, Pg_pr = kf.predict(state.xg, state.Pg, F, Q)
        usable, nan = zip(
            *(valid_measurement(z[i], available[:, i]) for i in range(N)), strict=True
        )
        usable, nan = np.stack(usable, 1), np.stack(nan, 1)
        priors, stat, props, innov = [], [], [], []
        for i, s in enumerate(self.system.sensors):
            prior = kf.predict(state.x[i], state.P[i], F, Q * self.q_scale[i])
            priors.append(prior)
            R = predicted_noise(state.noise[i], s.R, m.vb_rho)
            base = kf.Gaussian(xg_pr, Pg_pr) if m.prior == "global" else prior
            # the residual test's statistic (spec §3.1); no other detector reads it
            stat.append(
                residual_statistic(*base, z[i], usable[:, i], Hs[i], R)
                if m.detector == "residual-chi2"
                else np.zeros(usable.shape[0])
            )
            if self.features is not None:
                fb = kf.Gaussian(xg_pr, Pg_pr) if self.feature_prior == "global" else prior
                innov.append(whitened_innovation(*fb, z[i], usable[:, i], Hs[i], R))
            if self.state_test is not None:
                props.append(kf.predict(*state.propagator[i], F, Q * self.q_scale[i]))
        stat = np.stack(stat, 1)
        dof = np.array([s.dim for s in self.system.sensors])[None, :] * usable
        tested = usable
        posts = None
        if self.state_test is not None:
            # the state test compares this epoch's posterior with the propagator
            posts = [
                self._update(i, priors[i], z[i], usable[:, i], state.noise[i], Hs[i])
                for i in range(N)
            ]
            res = [
                self.state_test.statistic(k, posts[i].x, posts[i].P, *props[i]) for i in range(N)
            ]
            stat = np.stack([r[0] for r in res], 1)
            dof = np.stack([r[1] for r in res], 1)
            tested = np.stack([r[2] for r in res], 1)
        feats = None
        if self.features is not None:
            # features see each local posterior before the isolation decision (spec §4.1)
            if posts is None:
                posts = [
                    self._update(i, priors[i], z[i], usable[:, i], state.noise[i], Hs[i])
                    for i in range(N)
                ]
            nc = self.system.n_common
            feats = detector_features(
                self.features,
                np.stack([p.x[:, :nc] for p in posts], 1),
                np.stack([np.diagonal(p.P, axis1=-2, axis2=-1)[:, :nc] for p in posts], 1),
                xg_pr[:, :nc],
                innov,
            )
        det_state, det_out = detect(
            m, self.detector, state.detector, stat, dof, tested, oracle, feats
        )
        use = usable if det_out is None else usable & ~det_out.flag

        yg, Yg = kf.to_information(xg_pr, Pg_pr)
        xs, Ps, noise, R_hat = [], [], [], []
        for i in range(N):
            up = self._update(i, priors[i], z[i], use[:, i], state.noise[i], Hs[i])
            H = Hs[i]
            if m.increment == "direct":
                HtRinv = kf.mT(spd_solve(up.R, H))  # (R⁻¹ H)ᵀ, R SPD
                dY = HtRinv @ H
                dy = kf.mv(HtRinv, np.where(use[:, i, None], z[i], 0.0))
            else:
                y_po, Y_po = kf.to_information(up.x, up.P)
                y_pr, Y_pr = kf.to_information(*priors[i])
                dY, dy = Y_po - Y_pr, y_po - y_pr
            Yg = Yg + np.where(use[:, i, None, None], dY, 0.0)
            yg = yg + np.where(use[:, i, None], dy, 0.0)
            x_i, P_i = up.x, up.P
            if self.gamma != 1.0:
                P_i = P_i / self.gamma
            xs.append(x_i)
            Ps.append(P_i)
            noise.append(up.noise)
            R_hat.append(np.diagonal(up.R, axis1=-2, axis2=-1))
        xg, Pg = kf.from_information(yg, Yg)
        prop = None
        if self.state_test is not None:
            prop = tuple(
                kf.Gaussian(*self.state_test.restart(k, xs[i], Ps[i], *props[i])) for i in range(N)
            )
        nc = self.system.n_common
        out = StepOutput(xg[:, :nc], Pg[:, :nc, :nc], None, det_out, tuple(R_hat), nan, feats)
        return DistributedState(tuple(xs), tuple(Ps), xg, Pg, tuple(noise), det_state, prop), out

    def _update(self, i, prior, z, use, noise, H):
        s = self.system.sensors[i]
        return local_update(
            prior.x,
            prior.P,
            z,
            use,
            H,
            s.R,
            noise,
            variant=self.variant if self.vb_on[i] else None,
            rho=self.method.vb_rho,
            iterations=self.method.vb_iterations,
        )
