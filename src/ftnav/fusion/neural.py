"""Neuron fusion centre of paper 001 (spec §5): banks of linear neurons per fault configuration.

Each aid has an independent local Kalman filter (no information sharing, no
reset: paper 001 §3).  The fusion centre combines the N_in local estimates of
every common state s with one linear neuron per (state, configuration),

    x̂_F[s] = Σ_i w_i^{(s,c)} x̂_i[s],   w ≥ 0,  Σ_i w_i = 1   (spec §5.2, S1 eqs. 11-15),

where the weights were learned offline by constrained Widrow-Hoff learning
(:func:`ftnav.core.lms.lms_train`, :mod:`ftnav.fusion.neural_training`).  The
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

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.fdi.chi2 import DetectorState
from ftnav.fusion.local import (
    StepOutput,
    detect,
    load_method_model,
    local_update,
    make_detector,
    residual_statistic,
    select,
    valid_measurement,
    with_common,
)
from ftnav.model.scenario import Method
from ftnav.model.system import LinearSystem

__all__ = [
    "NeuronModel",
    "NeuralFusion",
    "NeuralState",
    "select_weights",
    "MODEL_KIND",
    "FREE_INPUT",
]

#: ``kind`` of a neuron fusion model file.
MODEL_KIND = "neuron-fusion"
#: Name of the free-propagation input.
FREE_INPUT = "free"


@dataclass(frozen=True)
class NeuronModel:
    """Trained banks of neurons (spec §5.2-§5.4).

    Attributes
    ----------
    configurations : (C,) names, the first is the healthy one.
    patterns : (C, N) bool, the local filters flagged in each configuration
        (the selection key of spec §5.4).
    inputs : (N_in,) input names: the sensors' local filters, then optionally
        :data:`FREE_INPUT`.
    states : (n_c,) fused state names.
    weights : (C, n_c, N_in) neuron weights, each row on the simplex.
    rmse : (C, n_c) training RMSE of each neuron.
    compatibility, training : see :class:`ftnav.fdi.rbf.RBFModel`.
    """

    configurations: tuple[str, ...]
    patterns: np.ndarray
    inputs: tuple[str, ...]
    states: tuple[str, ...]
    weights: np.ndarray
    rmse: np.ndarray
    compatibility: dict
    training: dict

    def __post_init__(self):
        C, N = self.patterns.shape
        if self.weights.shape != (C, len(self.states), len(self.inputs)):
            raise ValueError(
                f"weights: expected {(C, len(self.states), len(self.inputs))}, "
                f"got {self.weights.shape}"
            )
        if len(self.configurations) != C or self.patterns[0].any():
            raise ValueError("configurations: the first must be the healthy one (no flag)")
        if (self.weights < 0).any() or np.abs(self.weights.sum(-1) - 1.0).max() > 1e-9:
            raise ValueError("weights: every neuron's weights must be >= 0 and sum to 1")
        if len({tuple(p) for p in self.patterns}) != C:
            raise ValueError("patterns: two configurations have the same flag pattern")

    @property
    def free_input(self) -> bool:
        return FREE_INPUT in self.inputs

    def save(self, path: str | Path) -> Path:
        """Write the open-format model file (npz arrays + JSON metadata, no pickle)."""
        from ftnav.io.model_file import save_model

        settings = {
            "configurations": list(self.configurations),
            "inputs": list(self.inputs),
            "states": list(self.states),
            "training": self.training,
        }
        return save_model(
            path,
            MODEL_KIND,
            {"patterns": self.patterns, "weights": self.weights, "rmse": self.rmse},
            compatibility=self.compatibility,
            settings=settings,
        )

    @classmethod
    def load(cls, path: str | Path, compatibility: Mapping | None = None) -> NeuronModel:
        """Read and check a model file; a bad or foreign file raises ``ModelFileError``."""
        from ftnav.io.model_file import ModelFileError, load_model

        mf = load_model(path, MODEL_KIND, compatibility=compatibility)
        s = mf.settings
        try:
            return cls(
                tuple(s["configurations"]),
                np.array(mf.arrays["patterns"], dtype=bool),
                tuple(s["inputs"]),
                tuple(s["states"]),
                np.array(mf.arrays["weights"]),
                np.array(mf.arrays["rmse"]),
                dict(mf.compatibility),
                dict(s.get("training", {})),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise ModelFileError(path, f"inconsistent neuron fusion settings ({e})") from None


def select_weights(model: NeuronModel, flags: np.ndarray, uncovered: str) -> np.ndarray:
    """Weights (B, n_c, N_in) for the detector flags (B, N) (spec §5.4 selection).

    ``uncovered`` is ``"renormalize"`` or a configuration name (see module doc).
    """
    flags = np.asarray(flags, dtype=bool)
    match = (flags[:, None, :] == model.patterns[None]).all(-1)  # (B, C)
    covered = match.any(1)
    W = model.weights[np.argmax(match, 1)]
    if covered.all():
        return W
    if uncovered == "renormalize":
        keep = np.ones((flags.shape[0], len(model.inputs)))
        keep[:, : flags.shape[1]] = ~flags
        W0 = model.weights[0][None] * keep[:, None, :]
        total = W0.sum(-1, keepdims=True)
        fallback = np.where(total > 0, W0 / np.where(total > 0, total, 1.0), model.weights[0])
    else:
        fallback = np.broadcast_to(model.weights[model.configurations.index(uncovered)], W.shape)
    return np.where(covered[:, None, None], W, fallback)


class NeuralState(NamedTuple):
    """Local posteriors, the free propagation and the last fused estimate."""

    x: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    free: kf.Gaussian
    xf: np.ndarray
    Pf: np.ndarray
    detector: DetectorState | None


class NeuralFusion:
    """Independent local filters and the neuron fusion centre (spec §5, paper 001 §3).

    Parameters
    ----------
    system : the linear system.
    method : ``architecture = "neural"``; ``model`` (file), ``detector``
        (``residual-chi2``, ``oracle`` or ``none``) and its settings, ``prior``
        (``local``, ``global`` or ``intersection``: the reference of the
        residual test, module doc), ``uncovered``.
    model : an in-memory model instead of ``method.model``.
    collect : training-data mode: no model needed (equal weights), the stacked
        inputs (B, N_in·n_c) are reported in ``StepOutput.features``.
    free_input : with ``collect``, include the free propagation as an input.
    untrained : fusion without a model: ``"uniform"`` (equal weights) or
        ``"inverse-variance"`` (per state, weights ∝ 1/σ² over the unflagged inputs,
        the optimum for independent errors).  Closed-loop collection needs the latter:
        its fused estimate is fed back to the SINS.
    """

    def __init__(
        self,
        system: LinearSystem,
        method: Method,
        model: NeuronModel | None = None,
        collect: bool = False,
        free_input: bool = False,
        untrained: str = "uniform",
    ):
        name = f"methods[{method.name}]"
        if method.detector in ("rbf", "state-chi2"):
            raise ValueError(
                f"{name}.detector: the neural architecture selects its "
                "configuration from 'residual-chi2' (or 'oracle', 'none')"
            )
        self.system = system
        self.method = method
        self.N = system.n_sensors
        self.nc = system.n_common
        self.collect = collect
        if model is None and not collect:
            model = load_method_model(
                NeuronModel, method, system, "architecture 'neural'", "ftnav train-fusion"
            )
        if model is not None:
            if model.states != tuple(system.model.states):
                raise ValueError(f"{name}.model: trained for states {list(model.states)}")
            if method.uncovered != "renormalize" and method.uncovered not in model.configurations:
                raise ValueError(
                    f"{name}.uncovered: expected 'renormalize' or one of "
                    f"{list(model.configurations)}, got {method.uncovered!r}"
                )
        self.model = model
        self.untrained = untrained
        self.free_input = model.free_input if model is not None else bool(free_input)
        self.n_inputs = self.N + int(self.free_input)
        self.locals = [system.local(i) for i in range(self.N)]
        self.detector = make_detector(method, system)

    @property
    def n_filters(self) -> int:
        return self.N

    def init(self, batch: int) -> NeuralState:
        B, nc = batch, self.nc
        xs = tuple(np.broadcast_to(lm.x0, (B, lm.n)).copy() for lm in self.locals)
        Ps = tuple(np.broadcast_to(lm.P0, (B,) + lm.P0.shape).copy() for lm in self.locals)
        x0, P0 = self.system.model.x0, self.system.model.P0
        free = kf.Gaussian(
            np.broadcast_to(x0, (B, nc)).copy(), np.broadcast_to(P0, (B, nc, nc)).copy()
        )
        det = self.detector.init(B, self.N) if self.detector else None
        return NeuralState(xs, Ps, free, free.x.copy(), free.P.copy(), det)

    def step(self, state: NeuralState, k: int, z, available, oracle, lin=None):
        """Advance one epoch: local filters, detection, configuration, neuron fusion.

        ``lin`` as in :meth:`ftnav.fusion.federated.FederatedFilter.step`.
        """
        m, nc, N = self.method, self.nc, self.N
        F, Q = self.system.transition(k, lin)
        usable, nan = zip(
            *(valid_measurement(z[i], available[:, i]) for i in range(N)), strict=True
        )
        usable, nan = np.stack(usable, 1), np.stack(nan, 1)
        xs, Ps, stat, R_hat, priors, Hs = [], [], [], [], [], []
        for i, (lm, s) in enumerate(zip(self.locals, self.system.sensors, strict=True)):
            Fi, Qi = self.system.local_transition(i, k, lin=lin)
            H = lm.H if lin is None else lin.H[i]
            x_pr, P_pr = kf.predict(state.x[i], state.P[i], Fi, Qi)
            priors.append((x_pr, P_pr))
            Hs.append(H)
            up = local_update(x_pr, P_pr, z[i], usable[:, i], H, s.R, None)
            xs.append(up.x)
            Ps.append(up.P)
            R_hat.append(np.broadcast_to(np.diag(s.R), (up.x.shape[0], s.dim)))
            stat.append(up.nis)
        if m.prior != "local":
            if m.prior == "global":  # the predicted neuron output and its bound
                ref = kf.predict(state.xf, state.Pf, F, Q)
            else:  # covariance intersection of the local priors (module doc)
                ref = kf.intersect(
                    np.stack([p[0][:, :nc] for p in priors], 1),
                    np.stack([p[1][:, :nc, :nc] for p in priors], 1),
                )
            stat = [
                residual_statistic(*with_common(priors[i], *ref), z[i], usable[:, i], Hs[i], s.R)
                for i, s in enumerate(self.system.sensors)
            ]
        stat = np.stack(stat, 1)
        dof = np.array([s.dim for s in self.system.sensors])[None, :] * usable
        det_state, det_out = detect(m, self.detector, state.detector, stat, dof, usable, oracle)
        flags = np.zeros((stat.shape[0], N), dtype=bool) if det_out is None else det_out.flag
        if m.isolation == "time-update":  # a flagged local filter discards its measurement
            xs = [select(flags[:, i], priors[i][0], xs[i]) for i in range(N)]
            Ps = [select(flags[:, i], priors[i][1], Ps[i]) for i in range(N)]

        free = kf.Gaussian(*kf.predict(state.free.x, state.free.P, F, Q))
        u = [x[:, :nc] for x in xs]
        sd = [np.sqrt(np.diagonal(P, axis1=-2, axis2=-1)[:, :nc]) for P in Ps]
        if self.free_input:
            u.append(free.x)
            sd.append(np.sqrt(np.diagonal(free.P, axis1=-2, axis2=-1)))
        u, sd = np.stack(u, -1), np.stack(sd, -1)  # (B, n_c, N_in)
        if self.model is None and self.untrained == "inverse-variance":
            keep = np.ones(u.shape[0::2], bool)  # (B, N_in)
            keep[:, :N] = ~flags
            keep[~keep.any(1)] = True  # every input flagged: use them all
            W = np.where(keep[:, None, :], 1.0 / np.maximum(sd, 1e-300) ** 2, 0.0)
            W = W / W.sum(-1, keepdims=True)
        elif self.model is None:
            W = np.full(u.shape, 1.0 / self.n_inputs)
        else:
            W = select_weights(self.model, flags, m.uncovered)
        xf = (W * u).sum(-1)
        Pf = np.zeros(xf.shape + (nc,))
        Pf[:, np.arange(nc), np.arange(nc)] = (W * sd).sum(-1) ** 2
        feats = np.swapaxes(u, 1, 2).reshape(u.shape[0], -1) if self.collect else None
        out = StepOutput(xf, Pf, None, det_out, tuple(R_hat), nan, feats)
        return NeuralState(tuple(xs), tuple(Ps), free, xf, Pf, det_state), out
