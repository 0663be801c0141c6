"""Neuron fusion centre of paper 001 (spec §5): banks of linear neurons per fault configuration.

Each aid has an independent local Kalman filter (no information sharing, no
reset: paper 001 §3).  The fusion centre combines the N_in local estimates of
every common state s with one linear neuron per (state, configuration),

    x̂_F[s] = Σ_i w_i^{(s,c)} x̂_i[s],   w ≥ 0,  Σ_i w_i = 1   (spec §5.2, S1 eqs. 11-15),

where the weights were learned offline by constrained Widrow-Hoff learning
(:func:`ftnav.core.lms.lms_train`, :mod:`ftnav.training.fusion`).  The
configuration c is selected every epoch from the detector's flags (spec §5.4):
no flag → the healthy bank; a flag pattern that matches a trained configuration
→ that bank; any other pattern → the ``uncovered`` rule: ``"renormalize"``
(the healthy bank with the flagged inputs' weights zeroed and the rest scaled
to sum 1) or the name of a configuration (paper 001: two flags → "SINS faulty").

Inputs are the local filters' posteriors and, optionally, the ``free``
solution: the model propagated from ``x0`` without measurements (the
free-inertial SINS solution of paper 001's fourth input).

The fused covariance is not produced by the neuron; ftnav reports the bound
``P_F[s,s] = (Σ_i w_i σ_i[s])²`` (σ_i the local standard deviations), which
holds for any correlation between the local errors because w ≥ 0
(Cauchy-Schwarz), with zero cross terms.  NEES computed with it is
conservative by construction.

The χ² flags that pick the bank test each aid's residual (spec §3.1) against a
``prior``:

* ``local``: the local filter's own prior, as in paper 001.  A flagged local
  coasts (``isolation = "time-update"``); a SINS/TAN filter has no velocity aid,
  its coasted horizontal error grows, and through the terrain slopes its prior
  drifts towards a biased clearance until the test passes and the bias is
  absorbed; once the aid recovers it is flagged against its own biased estimate
  for ever (measured on seed001, ``docs/claims.md``).
* ``global``: the predicted neuron output with the bound above, far larger than
  its error, so the test has little power.
* ``intersection`` (ftnav's choice for seed001): the covariance intersection of
  the local priors' common states with equal weights,
  ``P⁻¹ = Σ P_i⁻¹ / N`` (:func:`ftnav.core.kalman.intersect`), consistent for any
  correlation between the local errors, and holding every local's information:
  the TAN filter's height, the GPS filter's position, the Doppler filter's
  velocity.  A flagged local's coasted prior stays in it (as the no-reset
  federated filter keeps it, spec §6.3), diluted by the others.  Private states
  keep the local's prior.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, Literal, NamedTuple

import numpy as np
from pydantic import Field, model_validator

from ftnav.core import kalman as kf
from ftnav.core.kalman import Gaussian
from ftnav.fdi.chi2 import DetectorState
from ftnav.fusion.config import NOTHING_LEARNED, Learned, MethodBase, config_error
from ftnav.fusion.detection import Detection
from ftnav.fusion.guard import Guard, GuardState
from ftnav.fusion.isolation import IsolationPolicy
from ftnav.fusion.locals import LocalBank, LocalUpdate, gated, measurements, restart_apart
from ftnav.fusion.neural_model import NeuronModel, select_weights
from ftnav.fusion.protocol import StepOutput, minus, select, with_common
from ftnav.model.system import Epoch, LinearSystem

__all__ = ["NeuralConfig", "NeuralFusion", "NeuralState", "check", "converged_only"]


class NeuralConfig(MethodBase):
    """``architecture = "neural"``: independent local filters and the neuron centre (§5).

    ``model`` is the trained banks (``ftnav train-fusion``); ``uncovered`` the rule for a
    flag pattern no configuration covers; ``isolation`` what a flagged local does.
    """

    DETECTORS: ClassVar[tuple[str, ...]] = (
        "none",
        "oracle",
        "residual-chi2",
        "cusum",
        "glr",
    )
    NOISE: ClassVar[tuple[str, ...]] = ("none",)
    PRIORS: ClassVar[tuple[str, ...]] = ("local", "global", "intersection")

    architecture: Literal["neural"] = "neural"
    model: str | None = Field(
        default=None,
        description=(
            "trained neuron banks (ftnav train-fusion), relative to the scenario file; "
            "required to run (the trainer builds the centre without one)"
        ),
    )
    uncovered: str = Field(
        default="renormalize",
        min_length=1,
        description=(
            "a flag pattern no configuration covers: 'renormalize' or a configuration name"
        ),
    )
    isolation: Literal["standalone", "time-update"] = "standalone"
    convergence_ratio: float | None = Field(
        default=None,
        gt=1.0,
        allow_inf_nan=False,
        description=(
            "ftnav's option beside the paper's fixed weights: an input whose σ of a state "
            "exceeds this multiple of the smallest input σ of that state (not converged, "
            "or far less accurate) is left out of that state's neuron, the weights "
            "renormalized over the rest (module docstring)"
        ),
    )

    absent_after: int | None = Field(
        default=None,
        ge=1,
        description=(
            "epochs: an aid without a usable measurement for longer, once it has "
            "measured, picks the bank as a flagged one does (its local only coasts: an "
            "outage of a sensor that always measures).  Off by default: banks trained "
            "with aids silent by design (ZUPT when moving, a terrain aid off its map) "
            "already weigh those silences (docs/integrity.md §1.14)"
        ),
    )

    @model_validator(mode="after")
    def _check(self) -> NeuralConfig:
        self.check_pieces()
        return self

    @property
    def model_file(self) -> str | None:
        return self.model


def check(config: NeuralConfig, system: LinearSystem, learned: Learned) -> None:
    """Boundary checks against the system and the trained banks."""
    config.check_sensors(system.sensors)
    model = learned.fusion
    if model is None:
        return
    if model.states != tuple(system.model.states):
        raise config_error(f"trained for states {list(model.states)}", "model")
    if config.uncovered != "renormalize" and config.uncovered not in model.configurations:
        raise config_error(
            f"expected 'renormalize' or one of {list(model.configurations)}, "
            f"got {config.uncovered!r}",
            "uncovered",
        )


def converged_only(W: np.ndarray, SD: np.ndarray, ratio: float) -> np.ndarray:
    """(B, n_c, N_in) the weights ``W`` with every input whose σ exceeds ``ratio`` × the
    smallest σ of its state set to 0 and the rest renormalized to sum 1 (a state whose
    kept inputs all have weight 0 gets equal weights over them).  ``SD`` (B, n_c, N_in)
    are the inputs' σ (module docstring, ``convergence_ratio``)."""
    keep = SD <= ratio * SD.min(-1, keepdims=True)
    Wk = np.where(keep, W, 0.0)
    total = Wk.sum(-1, keepdims=True)
    equal = keep / keep.sum(-1, keepdims=True)
    return np.where(total > 0, Wk / np.where(total > 0, total, 1.0), equal)


class NeuralState(NamedTuple):
    """Local posteriors, the free propagation and the last fused estimate."""

    x: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    free: kf.Gaussian
    xf: np.ndarray
    Pf: np.ndarray
    detector: DetectorState | None
    guard: GuardState | None = None
    #: (B, N) epochs since each aid's last usable measurement (0: this epoch; -1: none
    #: yet), kept with ``absent_after`` only
    since: np.ndarray | None = None


class NeuralFusion:
    """Independent local filters and the neuron fusion centre (spec §5, paper 001 §3).

    Parameters
    ----------
    system : the linear system.
    config : ``architecture = "neural"`` settings.
    learned : its trained banks (``learned.fusion``); None in training-data mode.
    collect : training-data mode: no model needed, the stacked inputs
        (B, N_in·n_c) are reported in ``StepOutput.features``.
    free_input : with ``collect``, include the free propagation as an input.
    untrained : fusion without a model: ``"uniform"`` (equal weights) or
        ``"inverse-variance"`` (per state, weights ∝ 1/σ² over the unflagged inputs,
        the optimum for independent errors).  Closed-loop collection needs the latter:
        its fused estimate is fed back to the SINS.
    dt : the filter period (s): the guard's windows.
    """

    #: with output correction each local filter measures its aid at its own copy of the
    #: SINS output (paper 001 §3, "输出校正"; :mod:`ftnav.engine.ins` step 5)
    local_copies: ClassVar[bool] = True

    def __init__(
        self,
        system: LinearSystem,
        config: NeuralConfig,
        learned: Learned = NOTHING_LEARNED,
        collect: bool = False,
        free_input: bool = False,
        untrained: str = "uniform",
        dt: float = 1.0,
    ):
        self.system = system
        self.config = config
        self.N = system.n_sensors
        self.nc = system.n_common
        self.collect = collect
        self.model: NeuronModel | None = learned.fusion
        assert self.model is not None or collect, "the neuron centre needs its trained banks"
        self.untrained = untrained
        self.free_input = self.model.free_input if self.model is not None else bool(free_input)
        self.n_inputs = self.N + int(self.free_input)
        self.bank = LocalBank(system, config.noise)
        dims = [s.dim for s in system.sensors]
        self.detection = Detection(config.detector, sensors=system.sensors)
        self.policy = IsolationPolicy(config.isolation, n_filters=self.N)
        g = config.guard_settings
        # the locals are independent: each tracks its own aid's pull
        sizes = [m.n for m in self.bank.models]
        self.guard = None
        if g is not None:  # independent locals: tested against the detector's reference
            groups = [(i,) for i in range(self.N)]
            self.guard = Guard(g, groups, sizes, dims, dt, rollback=False)

    @property
    def n_filters(self) -> int:
        return self.N

    def init(self, batch: int) -> NeuralState:
        B, nc = batch, self.nc
        xs = tuple(np.broadcast_to(lm.x0, (B, lm.n)).copy() for lm in self.bank.models)
        Ps = tuple(np.broadcast_to(lm.P0, (B,) + lm.P0.shape).copy() for lm in self.bank.models)
        x0, P0 = self.system.model.x0, self.system.model.P0
        free = kf.Gaussian(
            np.broadcast_to(x0, (B, nc)).copy(), np.broadcast_to(P0, (B, nc, nc)).copy()
        )
        return NeuralState(
            xs,
            Ps,
            free,
            free.x.copy(),
            free.P.copy(),
            self.detection.init(B, self.N),
            None if self.guard is None else self.guard.init(B),
            None if self.config.absent_after is None else np.full((B, self.N), -1),
        )

    def step(self, state: NeuralState, epoch: Epoch) -> tuple[NeuralState, StepOutput]:
        """Advance one epoch: local filters, detection, configuration, neuron fusion."""
        N, bank = self.N, self.bank
        F, Q = self.system.transition(epoch.lin)
        meas0 = measurements(epoch, self.system.sensors)
        Hs = bank.H(epoch.lin)
        priors, updates, Fs = [], [], []
        for i in range(N):
            Fi, Qi = self.system.local_transition(i, lin=epoch.lin)
            Fs.append(Fi)
            priors.append(kf.predict(state.x[i], state.P[i], Fi, Qi))
        meas = gated(  # pseudo-measurements against each local's own prior
            meas0,
            self.system.sensors,
            lambda i: bank.residual(i, priors[i], epoch.z[i], meas0.usable[:, i], Hs[i], None),
        )
        for i in range(N):
            updates.append(bank.update(i, priors[i], epoch.z[i], meas.usable[:, i], Hs[i], None))
        stat, innov, bases = self._statistic(state, epoch, meas.usable, priors, updates, Hs, F, Q)
        det_state, det_out = self.detection.step(
            state.detector, stat, meas.dof, meas.usable, epoch.labels, None, innov
        )
        posts = [Gaussian(u.x, u.P) for u in updates]
        guard_state = guarded = None
        ref = kf.predict(state.xf, state.Pf, F, Q)  # the predicted neuron output, its bound
        if self.guard is not None:
            assert state.guard is not None
            R = [s.R for s in self.system.sensors]
            if self.detection.prior == "local":
                # paper 001's own-residual test: an isolated local coasts on its own SINS
                # and drifts with the fault (module docstring of the seed001 tests), so
                # the guard re-tests the aid against the neuron output's common states
                bases = [with_common(priors[i], *ref) for i in range(N)]
            guarded = self.guard.begin(
                state.guard,
                bases,
                Fs,
                epoch.z,
                Hs,
                R,
                meas.usable,
                det_out,
                repeated=epoch.repeated,
            )
            det_out = guarded.detection
            guard_state, amends = self.guard.finish(guarded, bases, epoch.z, Hs, R, meas.usable)
            for i, a in enumerate(amends):  # a relaxed re-admission's update, inflation:
                if a.where.any():  # the local restarts from the reference it was tested on
                    priors[i] = Gaussian(
                        select(a.where, bases[i].x - a.dx, priors[i].x),
                        select(a.where, bases[i].P + a.dP, priors[i].P),
                    )
                    # the amend is the relaxed update of the reference: the posterior
                    # too (the local's own update has taken the aid once already)
                    posts[i] = Gaussian(
                        select(a.where, priors[i].x, posts[i].x),
                        select(a.where, priors[i].P, posts[i].P),
                    )
            # a local let back in restarts from the reference its aid passed against
            # where its own estimate is far from it (locals.restart_apart)
            back = guarded.before.hold & ~guarded.after.hold
            for i, a in enumerate(amends):
                again = back[:, i] & ~a.where
                if not again.any():
                    continue
                lu = LocalUpdate(posts[i].x, posts[i].P, updates[i].nis, updates[i].R, None)
                priors[i], lu = restart_apart(
                    bank,
                    i,
                    priors[i],
                    lu,
                    bases[i],
                    self.nc,
                    again,
                    self.guard.config.false_alarm_probability,
                    epoch.z[i],
                    meas.usable[:, i],
                    Hs[i],
                    None,
                )
                posts[i] = Gaussian(lu.x, lu.P)
        flags = np.zeros((stat.shape[0], N), dtype=bool) if det_out is None else det_out.flag
        xs, Ps = self.policy.discard(flags, priors, posts)
        free = kf.Gaussian(*kf.predict(state.free.x, state.free.P, F, Q))
        # with absent_after, the bank of the aids whose locals are informed: a flagged
        # aid, or one silent for a while once it has measured (an outage of seed000's
        # dominant sensor put the healthy bank's output 78 m off, against 3 m for every
        # other method; before an aid's first measurement the bank is the one trained on
        # that start: seed001's TAN and DNS start 50-80 s in; §1.14)
        after, since, absent = self.config.absent_after, state.since, flags
        if after is not None:
            assert since is not None  # kept from init with the option
            since = np.where(meas.usable, 0, np.where(since < 0, -1, since + 1))
            absent = flags | (since > after)
        xf, Pf, u = self._fuse(xs, Ps, free, absent)
        feats = np.swapaxes(u, 1, 2).reshape(u.shape[0], -1) if self.collect else None
        B = stat.shape[0]
        R_hat = tuple(np.broadcast_to(np.diag(s.R), (B, s.dim)) for s in self.system.sensors)
        watch = np.stack(
            [
                bank.residual(
                    i, with_common(priors[i], *ref), epoch.z[i], meas0.usable[:, i], Hs[i], None
                )
                for i in range(N)
            ],
            1,
        )
        out = StepOutput(
            xf,
            Pf,
            None,
            det_out,
            R_hat,
            meas.nan,
            feats,
            None if guarded is None else guarded.output,
            watch,
            meas.usable & ~flags,
            meas0.usable,
        )
        return NeuralState(tuple(xs), tuple(Ps), free, xf, Pf, det_state, guard_state, since), out

    def _statistic(
        self,
        state: NeuralState,
        epoch: Epoch,
        usable: np.ndarray,
        priors: Sequence[Gaussian],
        updates: Sequence[LocalUpdate],
        Hs: Sequence[np.ndarray],
        F: np.ndarray,
        Q: np.ndarray,
    ) -> tuple[np.ndarray, list[np.ndarray] | None, list[Gaussian]]:
        """(B, N) residual statistic against the configured reference (module docstring),
        the whitened innovations the sequential tests read (else None), and each local's
        prior with that reference (what the guard tests against)."""
        nc, prior = self.nc, self.detection.prior
        if prior == "local" and not self.detection.whitened:
            return np.stack([u.nis for u in updates], 1), None, list(priors)
        ref: Gaussian | None = None
        if prior == "global":  # the predicted neuron output and its bound
            ref = kf.predict(state.xf, state.Pf, F, Q)
        elif prior == "intersection":  # covariance intersection of the local priors (module doc)
            ref = kf.intersect(
                np.stack([p[0][:, :nc] for p in priors], 1),
                np.stack([p[1][:, :nc, :nc] for p in priors], 1),
            )
        bases = [priors[i] if ref is None else with_common(priors[i], *ref) for i in range(self.N)]
        if self.detection.whitened:
            innov = [
                self.bank.whitened(i, bases[i], epoch.z[i], usable[:, i], Hs[i], None)
                for i in range(self.N)
            ]
            return np.stack([(w**2).sum(-1) for w in innov], 1), innov, bases
        return (
            np.stack(
                [
                    self.bank.residual(i, bases[i], epoch.z[i], usable[:, i], Hs[i], None)
                    for i in range(self.N)
                ],
                1,
            ),
            None,
            bases,
        )

    def _fuse(
        self,
        xs: Sequence[np.ndarray],
        Ps: Sequence[np.ndarray],
        free: Gaussian,
        flags: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The bank of the flag pattern applied to the inputs; the bound on its error."""
        nc, N = self.nc, self.N
        u = [x[:, :nc] for x in xs]
        sd = [np.sqrt(np.diagonal(P, axis1=-2, axis2=-1)[:, :nc]) for P in Ps]
        if self.free_input:
            u.append(free.x)
            sd.append(np.sqrt(np.diagonal(free.P, axis1=-2, axis2=-1)))
        U, SD = np.stack(u, -1), np.stack(sd, -1)  # (B, n_c, N_in)
        if self.model is None and self.untrained == "inverse-variance":
            keep = np.ones(U.shape[0::2], bool)  # (B, N_in)
            keep[:, :N] = ~flags
            keep[~keep.any(1)] = True  # every input flagged: use them all
            W = np.where(keep[:, None, :], 1.0 / np.maximum(SD, 1e-300) ** 2, 0.0)
            W = W / W.sum(-1, keepdims=True)
        elif self.model is None:
            W = np.full(U.shape, 1.0 / self.n_inputs)
        else:
            W = select_weights(self.model, flags, self.config.uncovered)
        if self.config.convergence_ratio is not None:
            W = converged_only(W, SD, self.config.convergence_ratio)
        xf = (W * U).sum(-1)
        Pf = np.zeros(xf.shape + (nc,))
        Pf[:, np.arange(nc), np.arange(nc)] = (W * SD).sum(-1) ** 2
        return xf, Pf, U

    def shift(self, state: NeuralState, delta: np.ndarray) -> NeuralState:
        return state._replace(
            x=tuple(minus(x, delta) for x in state.x),
            free=kf.Gaussian(minus(state.free.x, delta), state.free.P),
            xf=minus(state.xf, delta),
        )

    def local_estimates(self, state: NeuralState, n: int) -> np.ndarray:
        return np.stack([x[:, :n] for x in state.x], 1)
