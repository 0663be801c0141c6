"""Carlson federated Kalman filter with adaptive information sharing (spec §1-§2).

Modes (spec §1.5); ``zero-reset`` is its own filter (:mod:`ftnav.fusion.zero_reset`):

* ``fusion-reset`` (FR): fuse every epoch; every ``reset_interval`` epochs reset
  each healthy local filter to ``x̂_g``, ``P_g/β_i`` and the master to
  ``P_g/β_m``; local filters propagate with ``Q/β_i``.  Equals the centralized
  filter when the reset interval is 1 (spec §1.6).
* ``no-reset`` (NR): the initial sharing only; locals stay independent.

Fault factors ``r_i`` (spec §1.8): a filter flagged at epoch k is fused with its
prior (time update only) at k, gets ``β_i = 0`` from the sharing at the end of
k and runs standalone (``Q_i = Q``) on its own measurements; a recovery flagged
at epoch k re-admits it at the next sharing, so it is fused again from k+1
(with reset interval 1).  ``no-reset`` re-admits a recovered filter at once.

The guard (:mod:`ftnav.fusion.guard`) decides the isolation from the detector's flags:
with fusion-reset it tracks every aid's pull on the fused estimate (which the locals
are reset to), with no-reset each local's pull by its own aid, and rolls a newly
isolated aid's recent pull back from that estimate.

``no-reset`` with ``isolation = "time-update"``: a flagged local filter discards its
measurements, so its estimate is its last healthy one propagated (spec §6.3); nothing
of the fault enters it and, the locals staying independent, it stays in the fusion with
its share (``Q/β_i``) instead of being dropped.  The fused solution keeps the
information it had before the fault (e.g. the TAN height while TAN is isolated) rather
than falling back on the remaining aids alone.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, NamedTuple

import numpy as np
from pydantic import Field, model_validator

from ftnav.core import kalman as kf
from ftnav.core.kalman import Gaussian
from ftnav.core.sharing import information_content, sharing_coefficients
from ftnav.fdi.chi2 import DetectorOutput, DetectorState
from ftnav.fusion.config import (
    NOTHING_LEARNED,
    Count,
    Learned,
    MethodBase,
    ResidualChi2,
    Tuple,
    config_error,
)
from ftnav.fusion.detection import Detection, epoch_features, features_needed
from ftnav.fusion.guard import Amend, Guard, GuardState, devices_of
from ftnav.fusion.isolation import IsolationPolicy
from ftnav.fusion.locals import (
    LocalBank,
    LocalUpdate,
    Measurements,
    NoiseState,
    gated,
    measurements,
    restart_apart,
)
from ftnav.fusion.protocol import StepOutput, minus, select, with_common
from ftnav.model.system import Epoch, LinearSystem

__all__ = ["FederatedConfig", "FederatedFilter", "FederatedState", "MIN_SHARE", "check"]

#: Smallest positive sharing coefficient: a local reset with P_g/β for β below it
#: loses accuracy roughly as (machine epsilon)/β.
MIN_SHARE = 1e-6
#: Tolerance of ``sum(betas) + master_share == 1``.
SHARE_TOL = 1e-9

Sharing = Literal[
    "equal", "fixed", "information", "trace", "eigen-trace", "frobenius", "inverse-trace"
]

#: the settings each mode reads (beyond name, architecture, detector and noise)
MODE_SETTINGS: dict[str, tuple[str, ...]] = {
    "fusion-reset": (
        "mode",
        "reset_interval",
        "sharing",
        "betas",
        "master_share",
        "trace_mode",
        "isolation",
        "common_mode",
        "common_mode_quorum",
    ),
    "no-reset": (
        "mode",
        "sharing",
        "betas",
        "master_share",
        "trace_mode",
        "isolation",
        "common_mode",
        "common_mode_quorum",
    ),
    "zero-reset": ("mode", "reset_interval", "common_mode", "common_mode_quorum"),
}


class FederatedConfig(MethodBase):
    """``architecture = "federated"``: local filters sharing information (spec §1-§2).

    ``sharing`` is the rule of spec §2 (``betas``: the user's coefficients with
    ``fixed``); ``trace_mode`` whether the trace rules scale the covariances by the
    initial σ; ``master_share`` the master filter's β_m; ``isolation`` and
    ``common_mode`` what a flag does (:mod:`ftnav.fusion.isolation`).
    """

    architecture: Literal["federated"] = "federated"
    mode: Literal["fusion-reset", "no-reset", "zero-reset"] = "fusion-reset"
    reset_interval: Count = 1
    sharing: Sharing = "equal"
    betas: Tuple[Annotated[float, Field(ge=0.0, allow_inf_nan=False)]] = ()
    master_share: Annotated[float, Field(ge=0.0, lt=1.0, allow_inf_nan=False)] = 0.0
    trace_mode: Literal["scaled", "raw"] = "scaled"
    isolation: Literal["standalone", "time-update"] = "standalone"
    common_mode: Literal["isolate", "keep"] = "isolate"
    common_mode_quorum: Annotated[int, Field(ge=2)] | None = None

    @model_validator(mode="after")
    def _check(self) -> FederatedConfig:
        allowed = MODE_SETTINGS[self.mode]
        for key in sorted(self.model_fields_set - {"architecture", *MethodBase.model_fields}):
            if key not in allowed:
                raise config_error(f"not a setting of the {self.mode} mode", key)
        self.check_pieces()
        if self.sharing == "fixed":
            total = math.fsum(self.betas) + self.master_share
            if abs(total - 1.0) > SHARE_TOL:
                raise config_error(
                    f"sum(betas) + master_share must equal 1, got {total!r}", "betas"
                )
        elif self.betas:
            raise config_error(
                f"only read with sharing = 'fixed' (sharing is {self.sharing!r})", "betas"
            )
        if "trace_mode" in self.model_fields_set and self.sharing in ("equal", "fixed"):
            raise config_error(f"not read by the {self.sharing!r} sharing rule", "trace_mode")
        if self.common_mode_quorum is not None and self.common_mode != "keep":
            raise config_error(
                f"only read with common_mode = 'keep' (common_mode is {self.common_mode!r})",
                "common_mode_quorum",
            )
        return self

    @property
    def DETECTORS(self) -> tuple[str, ...]:  # type: ignore[override]  # noqa: N802
        if self.mode == "zero-reset":  # the locals have no prior, no propagator
            return ("none", "oracle", "residual-chi2", "cusum", "glr", "separation")
        if self.mode == "no-reset":  # no fused estimate the aids share: no separation
            return tuple(d for d in MethodBase.DETECTORS if d != "separation")
        return MethodBase.DETECTORS

    @property
    def NOISE(self) -> tuple[str, ...]:  # type: ignore[override]  # noqa: N802
        return ("none",) if self.mode == "zero-reset" else MethodBase.NOISE


def check(config: FederatedConfig, system: LinearSystem, learned: Learned) -> None:
    """Boundary checks that need the system (sensors, private states)."""
    config.check_sensors(system.sensors)
    N = system.n_sensors
    if config.sharing == "fixed" and len(config.betas) != N:
        raise config_error(
            f"expected {N} values (one per sensor) with sharing = 'fixed', got {len(config.betas)}",
            "betas",
        )
    if config.common_mode_quorum is not None and config.common_mode_quorum > N:
        raise config_error(f"must be <= the number of sensors ({N})", "common_mode_quorum")
    if config.mode == "zero-reset" and system.has_private:
        raise config_error(
            "zero-reset needs full-state local filters (a sensor has private states)", "mode"
        )
    if config.sharing == "information" and system.linearized:
        raise config_error(
            "the information rule needs constant measurement matrices; an "
            "integrated scenario linearizes them every epoch",
            "sharing",
        )
    if (
        isinstance(config.detector, ResidualChi2)
        and config.mode == "zero-reset"
        and "prior" in config.detector.model_fields_set
        and config.detector.prior != "global"
    ):
        raise config_error(
            "zero-reset tests against the fused prior (its local filters "
            "hold information, not a prior)",
            "detector",
            "prior",
        )


class FederatedState(NamedTuple):
    """Full state of the federated filter (nothing hidden in the object).

    ``x``/``P`` hold each local filter's posterior after the sharing.  ``share`` is
    the β each local was last reset with (its Q scaling), ``active`` whether it is
    fused next epoch.
    """

    x: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    master: kf.Gaussian | None
    xg: np.ndarray
    Pg: np.ndarray
    share: np.ndarray
    active: np.ndarray
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None
    propagator: tuple[kf.Gaussian, ...] | None
    guard: GuardState | None = None


class _Locals(NamedTuple):
    """One epoch of the local filters: priors, posteriors, and what the test reads."""

    priors: list[Gaussian]
    updates: list[LocalUpdate]
    props: list[Gaussian]
    Hs: list[np.ndarray]
    Fs: list[np.ndarray]

    @property
    def posts(self) -> list[Gaussian]:
        return [Gaussian(u.x, u.P) for u in self.updates]


#: the guard's inputs: priors and transitions per group, z, H and R per aid
_GuardInputs = tuple[
    list[Gaussian], list[np.ndarray], tuple[np.ndarray, ...], list[np.ndarray], list[np.ndarray]
]


def _constant(H: np.ndarray | None) -> np.ndarray:
    assert H is not None  # a constant system's sensors carry their H
    return H


class FederatedFilter:
    """Federated filter (fusion-reset or no-reset) with the spec §2 sharing rules.

    Parameters
    ----------
    system : linear system (local filters carry ``[x_c; x_si]``).
    config : the method's settings (mode fusion-reset or no-reset).
    learned : the trained RBF model of an ``rbf`` detector.
    features : feature kinds (spec §4.1) to compute every epoch even without an
        RBF detector (training data collection); ``feature_prior`` the prior their
        innovations are whitened against (default: the test's reference); reported in
        ``StepOutput.features``.
    """

    def __init__(
        self,
        system: LinearSystem,
        config: FederatedConfig,
        learned: Learned = NOTHING_LEARNED,
        features: tuple[str, ...] | None = None,
        feature_prior: str | None = None,
        dt: float = 1.0,
    ):
        self.system = system
        self.config = config
        self.N = N = system.n_sensors
        self.nc = system.n_common
        self.bank = LocalBank(system, config.noise)
        dims = [s.dim for s in system.sensors]
        self.detection = Detection(config.detector, learned.detector, system.sensors)
        self.global_prior = self.detection.prior == "global" and (
            self.detection.residual or self.detection.whitened
        )
        g = config.guard_settings
        self.guard: Guard | None = None
        #: the guard tracks each local (no-reset) or the fused estimate (fusion-reset)
        self.local_guard = config.mode == "no-reset"
        sd = self.detection.separation
        if g is not None:
            if self.local_guard:  # independent locals: tested against the fused prior
                sizes = [self.bank.models[i].n for i in range(N)]
                groups = [(i,) for i in range(N)]
                self.guard = Guard(
                    g,
                    groups,
                    sizes,
                    dims,
                    dt,
                    rollback=False,
                    devices=devices_of(system.sensors),
                    common=self.nc,
                )
            else:
                self.guard = Guard.fused(g, system.sensors, self.nc, dt, sd)
        self.features = features_needed(
            self.detection, features, feature_prior or self.detection.prior
        )
        self.policy = IsolationPolicy(
            config.isolation, config.common_mode, config.common_mode_quorum, self.N
        )
        self.scale = None if config.trace_mode == "raw" else 1.0 / np.sqrt(np.diag(system.model.P0))
        self.info = (
            None
            if system.linearized
            else information_content(
                [_constant(s.H) for s in system.sensors], [s.R for s in system.sensors], self.scale
            )
        )
        self.beta_m = float(config.master_share)

    @property
    def n_filters(self) -> int:
        return self.N

    def _sharing(self, P_common: np.ndarray, r: np.ndarray) -> np.ndarray:
        """β of the rule, a positive share raised to at least :data:`MIN_SHARE`.

        The adaptive rules can drive a healthy filter's β geometrically to 0 (e.g.
        inverse-trace when sensors observe different subspaces); ``P_g/β`` then
        overflows.  Raising it to the floor (the others renormalized, Σβ + β_m = 1)
        keeps its measurements in the fusion; a zero β (fault, fixed 0) stays 0.
        """
        c = self.config
        beta = sharing_coefficients(
            c.sharing,
            P_common,
            r,
            master_share=self.beta_m,
            betas=np.asarray(c.betas),
            info=self.info,
            scale=self.scale,
        )
        tiny = (beta > 0) & (beta < MIN_SHARE)
        if not tiny.any():
            return beta
        rest = np.where(tiny, 0.0, beta)
        budget = 1.0 - self.beta_m - MIN_SHARE * tiny.sum(-1, keepdims=True)
        # a run whose shares are all zero (every filter faulty) keeps them at zero
        total = rest.sum(-1, keepdims=True)
        return np.where(tiny, MIN_SHARE, rest * (budget / np.where(total > 0, total, 1.0)))

    def init(self, batch: int) -> FederatedState:
        B, nc = batch, self.nc
        x0c, P0c = self.system.model.x0, self.system.model.P0
        share = self._sharing(np.broadcast_to(P0c, (B, self.N, nc, nc)), np.ones((B, self.N)))
        xs, Ps = [], []
        for i, lm in enumerate(self.bank.models):
            P = np.broadcast_to(lm.P0, (B,) + lm.P0.shape).copy()
            P[:, :nc, :nc] = P0c / np.where(share[:, i] > 0, share[:, i], 1.0)[:, None, None]
            xs.append(np.broadcast_to(lm.x0, (B, lm.n)).copy())
            Ps.append(P)
        master = None
        if self.beta_m > 0:
            master = kf.Gaussian(
                np.broadcast_to(x0c, (B, nc)).copy(),
                np.broadcast_to(P0c / self.beta_m, (B, nc, nc)).copy(),
            )
        prop = (
            tuple(kf.Gaussian(x, P) for x, P in zip(xs, Ps, strict=True))
            if self.detection.state_test
            else None
        )
        return FederatedState(
            tuple(xs),
            tuple(Ps),
            master,
            np.broadcast_to(x0c, (B, nc)).copy(),
            np.broadcast_to(P0c, (B, nc, nc)).copy(),
            share,
            share > 0,
            self.bank.initial_noise(B),
            self.detection.init(B, self.N),
            prop,
            None if self.guard is None else self.guard.init(B),
        )

    # ------------------------------------------------------------------------------
    def step(self, state: FederatedState, epoch: Epoch) -> tuple[FederatedState, StepOutput]:
        """Advance one epoch (spec §1.3): predict, update, test, fuse, share."""
        F, Q = self.system.transition(epoch.lin)
        # the fused prior: needed by global-prior tests and when every local is isolated
        # the fused prior: the method's prediction, which it watches every aid against
        prior_g = kf.predict(state.xg, state.Pg, F, Q)
        meas0 = measurements(epoch, self.system.sensors)
        loc, meas = self._locals(state, epoch, meas0, None if self.local_guard else prior_g)
        feats = None
        if self.features is not None:
            assert prior_g is not None  # need_prior holds whenever features are computed
            feats = epoch_features(
                self.features,
                self.bank,
                loc.priors,
                loc.posts,
                prior_g,
                epoch,
                meas.usable,
                state.noise,
                loc.Hs,
            )
        det_state, det_out, flag = self._detect(state, epoch, meas, loc, prior_g, feats)
        guarded = guard_state = gin = None
        fusing = state  # the locals fused this epoch: state.active (below)
        if self.guard is not None:
            assert state.guard is not None
            gin = self._guard_inputs(state, epoch, loc, prior_g, F)
            guarded = self.guard.begin(
                state.guard,
                *gin,
                meas.usable,
                det_out,
                keep=self.policy.flags,
                repeated=epoch.repeated,
            )
            det_out, flag = guarded.detection, guarded.flags
            if self.local_guard:  # each local takes its own aid's rollback
                guard_state, amends = self.guard.finish(guarded, *_without_F(gin), meas.usable)
                loc = _amended(loc, amends, gin[0], state.share, self.nc)
                # a local let back in restarts from the reference its aid passed against
                # where its own estimate is far from it (locals.restart_apart): a local
                # that kept measuring a frozen aid was let back in 4 km off and every aid
                # failed against the fused output it pulled (docs/integrity.md §1.14)
                back = guarded.before.hold & ~guarded.after.hold
                priors, updates = list(loc.priors), list(loc.updates)
                for i, a in enumerate(amends):
                    again = back[:, i] & ~a.where
                    if not again.any():
                        continue
                    priors[i], updates[i] = restart_apart(
                        self.bank,
                        i,
                        priors[i],
                        updates[i],
                        _shared_base(gin[0][i], state.share[:, i], self.nc),
                        self.nc,
                        again,
                        self.guard.config.false_alarm_probability,
                        epoch.z[i],
                        meas.usable[:, i],
                        loc.Hs[i],
                        state.noise[i],
                    )
                loc = loc._replace(priors=priors, updates=updates)
                # a local re-admitted relaxed is fused at once: with every aid held the
                # fused estimate only coasts, and an aid let back in is tested again
                # next epoch against that coast (seed000, its dominant sensor frozen:
                # every aid held for 350 s while the locals agreed; §1.14)
                relaxed = np.stack([a.where for a in amends], 1)
                if relaxed.any():
                    fusing = state._replace(active=state.active | relaxed)
        xg, Pg, master = self._fuse(fusing, loc, flag, prior_g, F, Q)
        if guarded is not None and not self.local_guard:  # the fused estimate takes it
            assert self.guard is not None and gin is not None
            guard_state, (amend,) = self.guard.finish(guarded, *_without_F(gin), meas.usable)
            xg = select(amend.where, xg - amend.dx, xg)
            Pg = select(amend.where, Pg + amend.dP, Pg)
        new = self._share(state, epoch.k, loc, flag, xg, Pg, master)
        beta_report = np.where(new.active, new.share, 0.0)
        R_hat = tuple(np.diagonal(u.R, axis1=-2, axis2=-1) for u in loc.updates)
        watch = np.stack(  # every finite measurement against the fused prediction
            [
                self.bank.residual(
                    i,
                    with_common(loc.priors[i], *prior_g),
                    epoch.z[i],
                    meas0.usable[:, i],
                    loc.Hs[i],
                    state.noise[i],
                )
                for i in range(self.N)
            ],
            1,
        )
        out = StepOutput(
            xg,
            Pg,
            beta_report,
            det_out,
            R_hat,
            meas.nan,
            feats,
            None if guarded is None else guarded.output,
            watch,
            meas.usable & ~flag,
            meas0.usable,
        )
        new = new._replace(
            noise=tuple(u.noise for u in loc.updates), detector=det_state, guard=guard_state
        )
        return new, out

    def _guard_inputs(
        self,
        state: FederatedState,
        epoch: Epoch,
        loc: _Locals,
        prior_g: Gaussian | None,
        F: np.ndarray,
    ) -> _GuardInputs:
        """The guard's priors and transitions per group, the measurements, H and R per aid.

        No-reset: each local's prior with its common block the fused prior (the
        reference its aid is tested against; the guard does not roll the locals back).
        Fusion-reset: the fused prior; an aid's private states are folded into its noise,
        ``R + H_p P_p H_pᵀ`` (the fused estimate holds the common states only).
        """
        R_now = [self.bank.noise_now(i, state.noise[i]) for i in range(self.N)]
        assert prior_g is not None
        if self.local_guard:
            ref = [with_common(p, *prior_g) for p in loc.priors]
            return ref, list(loc.Fs), epoch.z, list(loc.Hs), R_now
        nc = self.nc
        Hc, Reff = [], []
        for i in range(self.N):
            H = loc.Hs[i]
            Hc.append(H[..., :nc])
            if H.shape[-1] > nc:
                Hp = H[..., nc:]
                Pp = loc.priors[i][1][:, nc:, nc:]
                Reff.append(R_now[i] + Hp @ Pp @ kf.mT(Hp))
            else:
                Reff.append(R_now[i])
        return [prior_g], [F], epoch.z, Hc, Reff

    def _locals(
        self,
        state: FederatedState,
        epoch: Epoch,
        meas: Measurements,
        prior_g: Gaussian | None,
    ) -> tuple[_Locals, Measurements]:
        """Predict (with ``Q/β_i`` while sharing) and update every local filter, the gated
        pseudo-measurements left out (against the fused prior with fusion-reset, each
        local's own with no-reset); the measurements after the gates."""
        Hs = self.bank.H(epoch.lin)
        priors, updates, props, Fs = [], [], [], []
        for i in range(self.N):
            sharing = state.active[:, i] & (state.share[:, i] > 0)
            scale = np.where(sharing, 1.0 / np.where(sharing, state.share[:, i], 1.0), 1.0)
            Fi, Qi = self.system.local_transition(i, scale, epoch.lin)
            Fs.append(Fi)
            priors.append(kf.predict(state.x[i], state.P[i], Fi, Qi))

        def reference(i: int) -> np.ndarray:
            base = priors[i] if prior_g is None else with_common(priors[i], *prior_g)
            return self.bank.residual(i, base, epoch.z[i], meas.usable[:, i], Hs[i], state.noise[i])

        meas = gated(meas, self.system.sensors, reference)
        usable = meas.usable
        for i in range(self.N):
            prior = priors[i]
            updates.append(
                self.bank.update(i, prior, epoch.z[i], usable[:, i], Hs[i], state.noise[i])
            )
            if state.propagator is not None:
                props.append(kf.predict(*state.propagator[i], Fi, Qi))
        return _Locals(priors, updates, props, Hs, Fs), meas

    def _detect(
        self,
        state: FederatedState,
        epoch: Epoch,
        meas: Measurements,
        loc: _Locals,
        prior_g: Gaussian | None,
        feats: np.ndarray | None,
    ) -> tuple[DetectorState | None, DetectorOutput | None, np.ndarray]:
        """The epoch's test statistic, the detector, the common-mode rule."""
        B, N = meas.usable.shape
        innov = None
        if self.detection.whitened:  # the sequential tests read whitened innovations
            innov = [
                self.bank.whitened(
                    i,
                    with_common(loc.priors[i], *prior_g)
                    if self.global_prior and prior_g is not None
                    else loc.priors[i],
                    epoch.z[i],
                    meas.usable[:, i],
                    loc.Hs[i],
                    state.noise[i],
                )
                for i in range(N)
            ]
            stat = np.stack([(w**2).sum(-1) for w in innov], 1)
        elif not self.detection.residual:  # no other detector reads the statistic
            stat = np.zeros((B, N))
        elif self.global_prior:
            assert prior_g is not None
            stat = np.stack(
                [
                    self.bank.residual(
                        i,
                        with_common(loc.priors[i], *prior_g),
                        epoch.z[i],
                        meas.usable[:, i],
                        loc.Hs[i],
                        state.noise[i],
                    )
                    for i in range(N)
                ],
                1,
            )
        else:
            stat = np.stack([u.nis for u in loc.updates], 1)
        dof, tested = meas.dof, meas.usable
        test = self.detection.state_test
        if test is not None:
            res = [test.statistic(epoch.k, *loc.posts[i], *loc.props[i]) for i in range(N)]
            stat, dof, tested = (np.stack([r[j] for r in res], 1) for j in range(3))
        det_state, det_out = self.detection.step(
            state.detector, stat, dof, tested, epoch.labels, feats, innov
        )
        flag = np.zeros((B, N), dtype=bool) if det_out is None else det_out.flag
        return det_state, det_out, self.policy.flags(flag)

    def _fuse(
        self,
        state: FederatedState,
        loc: _Locals,
        flag: np.ndarray,
        prior_g: Gaussian | None,
        F: np.ndarray,
        Q: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, Gaussian | None]:
        """Information fusion over the active set and the master (spec §1.3 step 3)."""
        nc, N = self.nc, self.N
        newly = np.asarray(
            state.active & flag, dtype=bool
        )  # flagged now: fused with its prior this epoch
        xc = np.stack(
            [select(newly[:, i], loc.priors[i][0], loc.updates[i].x)[:, :nc] for i in range(N)], 1
        )
        Pc = np.stack(
            [
                select(newly[:, i], loc.priors[i][1], loc.updates[i].P)[:, :nc, :nc]
                for i in range(N)
            ],
            1,
        )
        master = y0 = Y0 = None
        if state.master is not None:
            master = kf.predict(state.master.x, state.master.P, F, Q / self.beta_m)
            y0, Y0 = kf.to_information(*master)
        any_source = np.asarray(state.active.any(1) | (state.master is not None), dtype=bool)
        if not any_source.all():  # every local isolated: output the global prior
            Y0 = np.where(any_source[:, None, None], 0.0 if Y0 is None else Y0, np.eye(nc))
        xf, Pf = kf.fuse(xc, Pc, state.active.astype(float), y0, Y0)
        if any_source.all():
            return xf, Pf, master
        assert prior_g is not None
        return select(any_source, xf, prior_g[0]), select(any_source, Pf, prior_g[1]), master

    def _share(
        self,
        state: FederatedState,
        k: int,
        loc: _Locals,
        flag: np.ndarray,
        xg: np.ndarray,
        Pg: np.ndarray,
        master: kf.Gaussian | None,
    ) -> FederatedState:
        """Sharing and reset (spec §1.2, §1.5, §1.8): the locals' state for the next epoch."""
        c, N = self.config, self.N
        r = ~flag
        no_reset = c.mode == "no-reset"
        reset_epoch = not no_reset and k % c.reset_interval == 0
        active_next = r.copy() if (reset_epoch or no_reset) else state.active & r
        if no_reset:
            # time-update isolation leaves a flagged local uncontaminated: keep fusing it
            active_next = (
                (state.share > 0) if self.policy.time_update else active_next & (state.share > 0)
            )
        xs, Ps = self.policy.discard(flag, loc.priors, loc.posts)
        share, new_master = state.share, master
        if reset_epoch:
            P_common = np.stack([u.P[:, : self.nc, : self.nc] for u in loc.updates], 1)
            share = self._sharing(P_common, r.astype(float))
            active_next &= share > 0  # a zero share is not reset (P_g/0) nor fused
            for i in range(N):
                xs[i], Ps[i] = self._reset(xs[i], Ps[i], xg, Pg, share[:, i], active_next[:, i])
            if state.master is not None:
                new_master = kf.Gaussian(xg.copy(), Pg / self.beta_m)
        prop = None
        test = self.detection.state_test
        if test is not None:
            prop = tuple(
                kf.Gaussian(*test.restart(k, xs[i], Ps[i], *loc.props[i])) for i in range(N)
            )
        return state._replace(
            x=tuple(xs),
            P=tuple(Ps),
            master=new_master,
            xg=xg,
            Pg=Pg,
            share=share,
            active=active_next,
            propagator=prop,
        )

    def _reset(
        self,
        x: np.ndarray,
        P: np.ndarray,
        xg: np.ndarray,
        Pg: np.ndarray,
        beta: np.ndarray,
        where: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Reset common block to ``x̂_g``, ``P_g/β`` (spec §1.2); cross block per §1.7."""
        nc = self.nc
        b = np.where(where, beta, 1.0)[:, None, None]
        P_new_cc = Pg / b
        x_new = x.copy()
        x_new[:, :nc] = xg
        P_new = P.copy()
        if P.shape[-1] > nc:
            L_old = np.linalg.cholesky(P[:, :nc, :nc])
            L_new = np.linalg.cholesky(P_new_cc)
            P_cs: np.ndarray = L_new @ np.linalg.solve(L_old, P[:, :nc, nc:])
            P_new[:, :nc, nc:] = P_cs
            P_new[:, nc:, :nc] = kf.mT(P_cs)
        P_new[:, :nc, :nc] = P_new_cc
        return select(where, x_new, x), select(where, P_new, P)

    # ------------------------------------------------------------------------------
    def shift(self, state: FederatedState, delta: np.ndarray) -> FederatedState:
        master = (
            None
            if state.master is None
            else kf.Gaussian(minus(state.master.x, delta), state.master.P)
        )
        prop = (
            None
            if state.propagator is None
            else tuple(kf.Gaussian(minus(g.x, delta), g.P) for g in state.propagator)
        )
        return state._replace(
            x=tuple(minus(x, delta) for x in state.x),
            master=master,
            xg=minus(state.xg, delta),
            propagator=prop,
        )

    def local_estimates(self, state: FederatedState, n: int) -> np.ndarray:
        return np.stack([x[:, :n] for x in state.x], 1)


def _without_F(
    gin: _GuardInputs,
) -> tuple[list[Gaussian], tuple[np.ndarray, ...], list[np.ndarray], list[np.ndarray]]:
    """The guard inputs :meth:`~ftnav.fusion.guard.Guard.finish` reads (no transitions)."""
    priors, _, z, H, R = gin
    return priors, z, H, R


def _shared_base(base: Gaussian, share: np.ndarray, nc: int) -> Gaussian:
    """A local's restart from ``base``: its common block's covariance divided by its share
    β_i (``share``, (B,); 1 where not sharing), as a fusion reset restarts every local (spec
    §1.5), so that the fused estimate does not count the reference's information once
    more for each local restarted from it."""
    beta = np.where(share > 0, share, 1.0)
    scale = np.ones(base.P.shape[:2])
    scale[:, :nc] = 1.0 / np.sqrt(beta)[:, None]
    return Gaussian(base.x, scale[:, :, None] * base.P * scale[:, None, :])


def _amended(
    loc: _Locals,
    amends: tuple[Amend, ...],
    bases: list[Gaussian],
    share: np.ndarray,
    nc: int,
) -> _Locals:
    """Each local after its guard's amend (no-reset guard: a relaxed re-admission's
    update and inflation, made on the reference its aid was tested against, ``bases``).

    The local restarts from that reference, as a fusion reset restarts every local
    (spec §1.5): its common block's covariance divided by its share β_i (``share``,
    (B, N)), so that the fused estimate does not count the reference's information once
    more for each local restarted from it.  Its own coast may lie far from where the
    aid's innovation was measured (an isolated aid beside another one's fault: the
    reference followed that fault).  The amend (``x − dx``, ``P + dP`` of the reference)
    is the relaxed update itself: the local's prior and its posterior are both that
    (docs/integrity.md §1.14)."""
    priors, updates = list(loc.priors), list(loc.updates)
    for i, a in enumerate(amends):
        if not a.where.any():
            continue
        x, P = priors[i]
        xb, P_new = _shared_base(Gaussian(bases[i].x, bases[i].P + a.dP), share[:, i], nc)
        priors[i] = Gaussian(select(a.where, xb - a.dx, x), select(a.where, P_new, P))
        # the amend is the relaxed update of the reference (its prior), not of the
        # local's own update, which with standalone isolation has taken the aid once
        # already (the two together left a covariance with a negative variance)
        u = updates[i]
        updates[i] = u._replace(
            x=select(a.where, priors[i].x, u.x), P=select(a.where, priors[i].P, u.P)
        )
    return loc._replace(priors=priors, updates=updates)
