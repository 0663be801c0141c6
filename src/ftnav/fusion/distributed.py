"""Exact distributed form of the centralized Kalman filter (paper 002 eq. 24; spec §6).

Every local filter runs a full KF on the augmented state with its own sensor, its own
Q and P0; the fusion centre propagates the global estimate and adds the local
information increments:

    Y⁺ = Y⁻ + Σ ΔY_i,  y⁺ = y⁻ + Σ Δy_i.

``increment="direct"`` transmits ``ΔY_i = Hᵢᵀ R̂ᵢ⁻¹ Hᵢ``, ``Δy_i = Hᵢᵀ R̂ᵢ⁻¹ z_i``
(default, spec §6.2 numerics); ``"difference"`` the paper's ``(P⁺)⁻¹ − (P⁻)⁻¹``,
``(P⁺)⁻¹x⁺ − (P⁻)⁻¹x⁻``.  A flagged local filter does the time update only, so its
increment is zero (isolation, spec §6.3); a missing measurement (multi-rate, outage,
NaN) likewise.

``mode="rescale"`` (Carlson's rescale mode as reconstructed in spec §1.5 [R], enabled
only with ``reconstructed=True``) is this filter with each local's information scaled
by ``γ = rescale_factor`` after every fusion, which keeps the locals responsive while
the centre, fed increments only, stays exact.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, ClassVar, Literal, NamedTuple

import numpy as np
from pydantic import Field, model_validator

from ftnav.core import kalman as kf
from ftnav.core.kalman import Gaussian
from ftnav.core.linalg import spd_solve
from ftnav.fdi.chi2 import DetectorState
from ftnav.fusion.config import NOTHING_LEARNED, Learned, MethodBase, Separation, config_error
from ftnav.fusion.detection import Detection, epoch_features, features_needed
from ftnav.fusion.guard import Guard, GuardState
from ftnav.fusion.locals import (
    LocalBank,
    LocalUpdate,
    Measurements,
    NoiseState,
    gated,
    learned_beside,
    measurements,
)
from ftnav.fusion.protocol import StepOutput, minus, select
from ftnav.model.system import Epoch, LinearSystem

__all__ = ["DistributedConfig", "DistributedFilter", "DistributedState", "check"]


class DistributedConfig(MethodBase):
    """``architecture = "distributed"``: the exact distributed centralized filter (spec §6).

    ``increment`` is what each local transmits; ``mode = "rescale"`` Carlson's rescale
    mode as the spec reconstructs it (needs ``reconstructed = true``) with its
    ``rescale_factor``.  A flagged local filter always does the time update only.
    """

    PRIORS: ClassVar[tuple[str, ...]] = ("local", "global")

    architecture: Literal["distributed"] = "distributed"
    mode: Literal["exact", "rescale"] = "exact"
    increment: Literal["direct", "difference"] = "direct"
    reconstructed: bool = False
    rescale_factor: Annotated[float, Field(ge=0.0, lt=1.0, allow_inf_nan=False)] = 0.5

    @model_validator(mode="after")
    def _check(self) -> DistributedConfig:
        self.check_pieces()
        if self.mode == "rescale" and not self.reconstructed:
            raise config_error(
                "'rescale' is a reconstruction (spec §1.5); set reconstructed = true to use it",
                "mode",
            )
        for key in ("reconstructed", "rescale_factor"):
            if key in self.model_fields_set and self.mode != "rescale":
                raise config_error("only read with mode = 'rescale'", key)
        return self


def check(config: DistributedConfig, system: LinearSystem, learned: Learned) -> None:
    """Boundary checks that need the system."""
    config.check_sensors(system.sensors)


class DistributedState(NamedTuple):
    x: tuple[np.ndarray, ...]  # local posteriors (B, n_aug)
    P: tuple[np.ndarray, ...]
    xg: np.ndarray  # fusion centre (B, n_aug)
    Pg: np.ndarray
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None
    propagator: tuple[kf.Gaussian, ...] | None
    guard: GuardState | None = None


class DistributedFilter:
    """Distributed fusion equal to the centralized KF (spec §6).

    Parameters
    ----------
    system : linear system.
    config : the method's settings.
    learned : the trained RBF model of an ``rbf`` detector.
    local_Q_scale, local_P0_scale : (N,) factors on each local filter's Q and P0
        (spec §6.2: they do not affect exactness in the linear case).
    features : feature kinds (spec §4.1) to compute every epoch even without an
        RBF detector (training data collection); ``feature_prior`` the prior their
        innovations are whitened against (default: the test's reference).
    dt : the filter period (s): the guard's windows.
    """

    def __init__(
        self,
        system: LinearSystem,
        config: DistributedConfig,
        learned: Learned = NOTHING_LEARNED,
        local_Q_scale: Sequence[float] | None = None,
        local_P0_scale: Sequence[float] | None = None,
        features: tuple[str, ...] | None = None,
        feature_prior: str | None = None,
        dt: float = 1.0,
    ):
        self.system = system
        self.config = config
        self.N = N = system.n_sensors
        self.bank = LocalBank(system, config.noise, augmented=True)
        g = config.guard_settings
        # the guard tracks every aid's pull on the centre (an information sum: the CKF)
        self.guard = None
        if g is not None:
            sd = config.detector if isinstance(config.detector, Separation) else None
            self.guard = Guard.fused(g, system.sensors, system.n_aug, dt, sd)
        self.q_scale = np.ones(N) if local_Q_scale is None else np.asarray(local_Q_scale, float)
        self.p_scale = np.ones(N) if local_P0_scale is None else np.asarray(local_P0_scale, float)
        self.detection = Detection(config.detector, learned.detector, system.sensors)
        self.features = features_needed(
            self.detection, features, feature_prior or self.detection.prior
        )
        self.gamma = config.rescale_factor if config.mode == "rescale" else 1.0

    @property
    def n_filters(self) -> int:
        return self.N

    def init(self, batch: int) -> DistributedState:
        x0, P0 = self.system.augmented_initial()
        B = batch
        xs = tuple(np.broadcast_to(x0, (B,) + x0.shape).copy() for _ in range(self.N))
        Ps = tuple(np.broadcast_to(P0 * c, (B,) + P0.shape).copy() for c in self.p_scale)
        prop = (
            tuple(kf.Gaussian(x, P) for x, P in zip(xs, Ps, strict=True))
            if self.detection.state_test
            else None
        )
        return DistributedState(
            xs,
            Ps,
            xs[0].copy(),
            np.broadcast_to(P0, (B,) + P0.shape).copy(),
            self.bank.initial_noise(B),
            self.detection.init(B, self.N),
            prop,
            None if self.guard is None else self.guard.init(B),
        )

    def step(self, state: DistributedState, epoch: Epoch) -> tuple[DistributedState, StepOutput]:
        """Advance one epoch (spec §6.1 steps 1-3)."""
        N, bank = self.N, self.bank
        F, Q = self.system.augmented_transition(lin=epoch.lin)
        Hs = bank.H(epoch.lin)
        prior_g = kf.predict(state.xg, state.Pg, F, Q)
        meas0 = measurements(epoch, self.system.sensors)
        meas = gated(  # pseudo-measurements against the centre's prior
            meas0,
            self.system.sensors,
            lambda i: bank.residual(
                i, prior_g, epoch.z[i], meas0.usable[:, i], Hs[i], state.noise[i]
            ),
        )
        priors = [kf.predict(state.x[i], state.P[i], F, Q * self.q_scale[i]) for i in range(N)]
        props = (
            []
            if state.propagator is None
            else [kf.predict(*state.propagator[i], F, Q * self.q_scale[i]) for i in range(N)]
        )
        stat, dof, tested, posts, innov = self._statistic(
            state, epoch, meas, priors, props, prior_g, Hs
        )
        feats = None
        if self.features is not None:
            # features see each local posterior before the isolation decision (spec §4.1)
            if posts is None:
                posts = [
                    bank.update(i, priors[i], epoch.z[i], meas.usable[:, i], Hs[i], state.noise[i])
                    for i in range(N)
                ]
            feats = epoch_features(
                self.features,
                bank,
                priors,
                [Gaussian(u.x, u.P) for u in posts],
                prior_g,
                epoch,
                meas.usable,
                state.noise,
                Hs,
            )
        det_state, det_out = self.detection.step(
            state.detector, stat, dof, tested, epoch.labels, feats, innov
        )
        guarded = None
        R_now = [bank.noise_now(i, state.noise[i]) for i in range(N)]
        if self.guard is not None:
            assert state.guard is not None
            guarded = self.guard.begin(
                state.guard,
                [prior_g],
                [F],
                epoch.z,
                Hs,
                R_now,
                meas.usable,
                det_out,
                repeated=epoch.repeated,
            )
            det_out = guarded.detection
        use = meas.usable if det_out is None else meas.usable & ~det_out.flag
        # a flagged VB local keeps adapting its R̂ on its measurement while its state only
        # time-updates: else R̂ stays at its pre-anomaly value, the residual test against
        # it never passes again, and an aid whose noise grew is never re-admitted
        # (measured on seed002, docs/claims.md); but not on an output repeated bit for
        # bit, which has no noise to learn (seed002's receiver frozen 100 s: its R̂ grew
        # to a 7.8 km σ, and the receiver back was barely used for 1000 s)
        adapt = meas.usable if epoch.repeated is None else use | (meas.usable & ~epoch.repeated)
        back = np.zeros_like(use)
        if guarded is not None:
            # with the guard, a held local learns no offset: not while its hold keeps a
            # jump (seed002's 20 m GNSS step held for the patience taught it a 9 m σ,
            # kept for 300 s after the step: 2.51 m after it against ckf's 1.45), unless
            # the guard calls its measurement a noise (its increments show one); a hold
            # without a jump (an alarm in a turn on the real drive) learns as before (it
            # learning nothing held the drive's GNSS 6.9 % of the time, 0.085 m against
            # 0.045); and not at the epoch it is let back, where its prior is the coast's
            # (docs/integrity.md §1.12)
            back = (guarded.before.hold | guarded.flags) & ~guarded.after.hold
            learn = meas.usable & (guarded.output.noisy | (guarded.after.jumps == 0))
            out = meas.usable & ~use
            elsewhere = (out.sum(axis=1, keepdims=True) - out) > 0
            learn &= ~elsewhere
            if epoch.repeated is not None:
                learn &= ~epoch.repeated
            adapt = (use & ~back & ~elsewhere) | learn
        updates = [
            bank.update(i, priors[i], epoch.z[i], use[:, i], Hs[i], state.noise[i], adapt[:, i])
            for i in range(N)
        ]
        for i in range(N):
            if bank.vb_on[i]:  # where its own prior is no reference for its noise (integrity §1.17)
                updates[i] = learned_beside(
                    bank, i, priors[i], prior_g, epoch.z[i], use[:, i], Hs[i],
                    state.noise[i], adapt[:, i], updates[i],
                )  # fmt: skip
        xg, Pg = self._fuse(prior_g, priors, updates, use, epoch.z, Hs)
        prop = None
        test = self.detection.state_test
        Ps = [u.P / self.gamma if self.gamma != 1.0 else u.P for u in updates]
        xs = [u.x for u in updates]
        guard_state = None
        if guarded is not None:
            assert self.guard is not None
            guard_state, (amend,) = self.guard.finish(
                guarded, [prior_g], epoch.z, Hs, R_now, meas.usable
            )
            xg = select(amend.where, xg - amend.dx, xg)
            Pg = select(amend.where, Pg + amend.dP, Pg)
            out_g = guarded.output
            # a rolled-back local restarts from the amended centre (a deferred rollback:
            # when the aid's agreement applies it), and so does a local let back in: its
            # state only time-updated while held, so its residual, what its VB learns
            # from, would carry the whole hold's offset (the estimate took the jump, the
            # local did not)
            back |= out_g.rollback | (out_g.undone & guarded.before.deferred)
            for i in range(N):
                xs[i], Ps[i] = select(back[:, i], xg, xs[i]), select(back[:, i], Pg, Ps[i])
        if test is not None:
            prop = tuple(
                kf.Gaussian(*test.restart(epoch.k, xs[i], Ps[i], *props[i])) for i in range(N)
            )
        nc = self.system.n_common
        R_hat = tuple(np.diagonal(u.R, axis1=-2, axis2=-1) for u in updates)
        watch = np.stack(  # every finite measurement against the centre's prediction
            [
                bank.residual(i, prior_g, epoch.z[i], meas0.usable[:, i], Hs[i], state.noise[i])
                for i in range(N)
            ],
            1,
        )
        out = StepOutput(
            xg[:, :nc],
            Pg[:, :nc, :nc],
            None,
            det_out,
            R_hat,
            meas.nan,
            feats,
            None if guarded is None else guarded.output,
            watch,
            use,
            meas0.usable,
        )
        return DistributedState(
            tuple(xs),
            tuple(Ps),
            xg,
            Pg,
            tuple(u.noise for u in updates),
            det_state,
            prop,
            guard_state,
        ), out

    def _statistic(
        self,
        state: DistributedState,
        epoch: Epoch,
        meas: Measurements,
        priors: Sequence[Gaussian],
        props: Sequence[Gaussian],
        prior_g: Gaussian,
        Hs: Sequence[np.ndarray],
    ) -> tuple[
        np.ndarray, np.ndarray, np.ndarray, list[LocalUpdate] | None, list[np.ndarray] | None
    ]:
        """(statistic, dof, tested, posteriors or None, whitened innovations or None)."""
        N, bank = self.N, self.bank
        base = [prior_g if self.detection.prior == "global" else priors[i] for i in range(N)]
        innov = None
        if self.detection.whitened:  # the sequential tests (spec §3.3)
            innov = [
                bank.whitened(i, base[i], epoch.z[i], meas.usable[:, i], Hs[i], state.noise[i])
                for i in range(N)
            ]
            stat = np.stack([(w**2).sum(-1) for w in innov], 1)
        elif self.detection.residual:  # no other detector reads the residual statistic
            stat = np.stack(
                [
                    bank.residual(i, base[i], epoch.z[i], meas.usable[:, i], Hs[i], state.noise[i])
                    for i in range(N)
                ],
                1,
            )
        else:
            stat = np.zeros(meas.usable.shape)
        test = self.detection.state_test
        if test is None:
            return stat, meas.dof, meas.usable, None, innov
        # the state test compares this epoch's posterior with the propagator
        posts: list[LocalUpdate] = [
            bank.update(i, priors[i], epoch.z[i], meas.usable[:, i], Hs[i], state.noise[i])
            for i in range(N)
        ]
        res = [test.statistic(epoch.k, posts[i].x, posts[i].P, *props[i]) for i in range(N)]
        stat, dof, tested = (np.stack([r[j] for r in res], 1) for j in range(3))
        return stat, dof, tested, posts, None

    def _fuse(
        self,
        prior_g: Gaussian,
        priors: Sequence[Gaussian],
        updates: Sequence[LocalUpdate],
        use: np.ndarray,
        z: Sequence[np.ndarray],
        Hs: Sequence[np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray]:
        """``Y⁺ = Y⁻ + Σ ΔY_i``, ``y⁺ = y⁻ + Σ Δy_i`` over the used measurements."""
        yg, Yg = kf.to_information(*prior_g)
        for i, up in enumerate(updates):
            if self.config.increment == "direct":
                HtRinv = kf.mT(spd_solve(up.R, Hs[i]))  # (R⁻¹ H)ᵀ, R SPD
                dY = HtRinv @ Hs[i]
                dy = kf.mv(HtRinv, np.where(use[:, i, None], z[i], 0.0))
            else:
                y_po, Y_po = kf.to_information(up.x, up.P)
                y_pr, Y_pr = kf.to_information(*priors[i])
                dY, dy = Y_po - Y_pr, y_po - y_pr
            Yg = Yg + np.where(use[:, i, None, None], dY, 0.0)
            yg = yg + np.where(use[:, i, None], dy, 0.0)
        return kf.from_information(yg, Yg)

    def shift(self, state: DistributedState, delta: np.ndarray) -> DistributedState:
        prop = (
            None
            if state.propagator is None
            else tuple(kf.Gaussian(minus(g.x, delta), g.P) for g in state.propagator)
        )
        return state._replace(
            x=tuple(minus(x, delta) for x in state.x), xg=minus(state.xg, delta), propagator=prop
        )

    def local_estimates(self, state: DistributedState, n: int) -> np.ndarray:
        return np.stack([x[:, :n] for x in state.x], 1)
