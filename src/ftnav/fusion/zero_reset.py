"""Zero-reset federated filter (spec §1.5, mode ``zero-reset``): information-form locals.

The master holds all the information; each local filter is an information filter over
the common state that accumulates its sensor's information ``Hᵀ R⁻¹ H``, ``Hᵀ R⁻¹ z``
and is zeroed after every fusion (every ``reset_interval`` epochs).  Its state is
information ``(y, Y)``, never a covariance, so it has its own state type.  The fused
estimate is ``Y_g = Y_m + Σ_active Y_i``; a flagged local filter contributes its
prior (time update only) at the epoch it is flagged and nothing while isolated.
The residual test uses the fused prior (the locals have no prior of their own).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.fdi.chi2 import DetectorState
from ftnav.fusion.config import NOTHING_LEARNED, Learned
from ftnav.fusion.detection import Detection
from ftnav.fusion.federated import FederatedConfig
from ftnav.fusion.guard import Guard, GuardState
from ftnav.fusion.isolation import IsolationPolicy
from ftnav.fusion.locals import LocalBank, gated, measurements
from ftnav.fusion.protocol import StepOutput, minus, select
from ftnav.model.system import Epoch, LinearSystem

__all__ = ["ZeroResetFilter", "ZeroResetState"]


#: an information vector and matrix ``(y, Y) = (P⁻¹ x, P⁻¹)`` (spec §1.6)
Information = tuple[np.ndarray, np.ndarray]


class ZeroResetState(NamedTuple):
    """Information ``(y, Y)`` of each local filter, the master, the fused estimate."""

    y: tuple[np.ndarray, ...]
    Y: tuple[np.ndarray, ...]
    master: kf.Gaussian
    xg: np.ndarray
    Pg: np.ndarray
    active: np.ndarray
    detector: DetectorState | None
    guard: GuardState | None = None


class ZeroResetFilter:
    """The zero-reset federated filter (module docstring); a :class:`FederatedConfig`."""

    def __init__(
        self,
        system: LinearSystem,
        config: FederatedConfig,
        learned: Learned = NOTHING_LEARNED,
        dt: float = 1.0,
    ):
        self.system = system
        self.config = config
        self.N = system.n_sensors
        self.nc = system.n_common
        self.bank = LocalBank(system, config.noise)
        self.detection = Detection(config.detector, learned.detector, system.sensors)
        g = config.guard_settings
        # the guard tracks every aid's pull on the fused estimate (the master's)
        self.guard = (
            None
            if g is None
            else Guard.fused(g, system.sensors, self.nc, dt, self.detection.separation)
        )
        self.policy = IsolationPolicy(
            "standalone", config.common_mode, config.common_mode_quorum, self.N
        )

    @property
    def n_filters(self) -> int:
        return self.N

    def init(self, batch: int) -> ZeroResetState:
        B, nc = batch, self.nc
        x0c, P0c = self.system.model.x0, self.system.model.P0
        zeros = tuple(np.zeros((B, nc)) for _ in range(self.N))
        return ZeroResetState(
            zeros,
            tuple(np.zeros((B, nc, nc)) for _ in range(self.N)),
            kf.Gaussian(
                np.broadcast_to(x0c, (B, nc)).copy(), np.broadcast_to(P0c, (B, nc, nc)).copy()
            ),
            np.broadcast_to(x0c, (B, nc)).copy(),
            np.broadcast_to(P0c, (B, nc, nc)).copy(),
            np.ones((B, self.N), dtype=bool),
            self.detection.init(B, self.N),
            None if self.guard is None else self.guard.init(B),
        )

    def step(self, state: ZeroResetState, epoch: Epoch) -> tuple[ZeroResetState, StepOutput]:
        """Advance one epoch: information predict and update, test, fuse, zero."""
        N = self.N
        F, Q = self.system.transition(epoch.lin)
        prior_g = kf.predict(state.xg, state.Pg, F, Q)
        Hs = self.bank.H(epoch.lin)
        meas0 = measurements(epoch, self.system.sensors)
        meas = gated(
            meas0,
            self.system.sensors,
            lambda i: self.bank.residual(i, prior_g, epoch.z[i], meas0.usable[:, i], Hs[i], None),
        )
        priors: list[Information] = []
        posts: list[Information] = []
        R_hat = []
        for i, s in enumerate(self.system.sensors):
            use = meas.usable[:, i]
            y, Y = kf.information_predict(state.y[i], state.Y[i], F, Q)
            HtRinv = kf.mT(np.linalg.solve(s.R, Hs[i]))
            Y_post = np.where(use[:, None, None], Y + HtRinv @ Hs[i], Y)
            y_post = np.where(
                use[:, None], y + kf.mv(HtRinv, np.where(use[:, None], epoch.z[i], 0.0)), y
            )
            priors.append((y, Y))
            posts.append((y_post, Y_post))
            R_hat.append(np.broadcast_to(np.diag(s.R), (state.xg.shape[0], s.dim)))
        innov = None
        if self.detection.whitened:  # the sequential tests, against the fused prior
            innov = [
                self.bank.whitened(i, prior_g, epoch.z[i], meas.usable[:, i], Hs[i], None)
                for i in range(N)
            ]
            stat = np.stack([(w**2).sum(-1) for w in innov], 1)
        elif self.detection.residual:
            stat = np.stack(
                [
                    self.bank.residual(i, prior_g, epoch.z[i], meas.usable[:, i], Hs[i], None)
                    for i in range(N)
                ],
                1,
            )
        else:
            stat = np.zeros(meas.usable.shape)
        det_state, det_out = self.detection.step(
            state.detector, stat, meas.dof, meas.usable, epoch.labels, None, innov
        )
        guarded = guard_state = None
        R = [s.R for s in self.system.sensors]
        if self.guard is not None:
            assert state.guard is not None
            guarded = self.guard.begin(
                state.guard,
                [prior_g],
                [F],
                epoch.z,
                Hs,
                R,
                meas.usable,
                det_out,
                keep=self.policy.flags,
                repeated=epoch.repeated,
            )
            det_out = guarded.detection
            flag = guarded.flags
        else:
            flag = np.zeros(meas.usable.shape, dtype=bool) if det_out is None else det_out.flag
            flag = self.policy.flags(flag)
        xg, Pg, master_pr = self._fuse(state, priors, posts, state.active & flag, F, Q)
        if guarded is not None:
            assert self.guard is not None
            guard_state, (amend,) = self.guard.finish(
                guarded, [prior_g], epoch.z, Hs, R, meas.usable
            )
            xg = select(amend.where, xg - amend.dx, xg)
            Pg = select(amend.where, Pg + amend.dP, Pg)
        reset_epoch = epoch.k % self.config.reset_interval == 0
        active_next = ~flag if reset_epoch else state.active & ~flag
        ys, Ys = [p[0] for p in posts], [p[1] for p in posts]
        master = master_pr
        if reset_epoch:
            ys, Ys = [np.zeros_like(y) for y in ys], [np.zeros_like(Y) for Y in Ys]
            master = kf.Gaussian(xg, Pg)
        watch = np.stack(  # every finite measurement against the fused prediction
            [
                self.bank.residual(i, prior_g, epoch.z[i], meas0.usable[:, i], Hs[i], None)
                for i in range(N)
            ],
            1,
        )
        out = StepOutput(
            xg,
            Pg,
            np.zeros(flag.shape),
            det_out,
            tuple(R_hat),
            meas.nan,
            guard=None if guarded is None else guarded.output,
            nis=watch,
            used=meas.usable & ~flag,
            available=meas0.usable,
        )
        return ZeroResetState(
            tuple(ys), tuple(Ys), master, xg, Pg, active_next, det_state, guard_state
        ), out

    def _fuse(
        self,
        state: ZeroResetState,
        priors: Sequence[Information],
        posts: Sequence[Information],
        newly: np.ndarray,
        F: np.ndarray,
        Q: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, kf.Gaussian]:
        """``Y_g = Y_m + Σ_active Y_i`` (a newly flagged local with its prior)."""
        master_pr = kf.predict(state.master.x, state.master.P, F, Q)
        ym, Ym = kf.to_information(*master_pr)
        Yg, yg = Ym.copy(), ym.copy()
        for i in range(self.N):
            y_i = select(newly[:, i], priors[i][0], posts[i][0])
            Y_i = select(newly[:, i], priors[i][1], posts[i][1])
            Yg += np.where(state.active[:, i, None, None], Y_i, 0.0)
            yg += np.where(state.active[:, i, None], y_i, 0.0)
        xg, Pg = kf.from_information(yg, Yg)
        return xg, Pg, kf.Gaussian(*master_pr)

    def shift(self, state: ZeroResetState, delta: np.ndarray) -> ZeroResetState:
        """Information shifts as ``y − Y δ``; the master and the fused estimate as ``x − δ``."""
        d = delta.shape[-1]
        ys = tuple(y - kf.mv(Y[..., :d], delta) for y, Y in zip(state.y, state.Y, strict=True))
        return state._replace(
            y=ys,
            master=kf.Gaussian(minus(state.master.x, delta), state.master.P),
            xg=minus(state.xg, delta),
        )

    def local_estimates(self, state: ZeroResetState, n: int) -> None:
        return None  # the locals hold information, not estimates
