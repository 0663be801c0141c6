"""Training and held-out evaluation of the neuron fusion centre (spec §5.3-§5.4).

Pipeline (:func:`train_fusion`):

1. Configurations (spec §5.4): ``healthy`` (no flag) and one per sensor
   (that sensor's local filter flagged).  Paper 001's "SINS faulty"
   configuration needs an inertial system and comes with the INS scenarios.
2. Training data: independent local filters (no sharing) run over a
   :class:`~ftnav.sim.fault_family.FaultFamily`.  Configuration ``healthy``
   takes every epoch of the fault-free runs after the initial convergence;
   configuration ``<sensor>`` takes the epochs inside that sensor's fault
   windows, so LMS learns to down-weight the faulty input.
3. Per (configuration, state) neuron the inputs are centred by their mean
   ``ū`` (spec §5.3 conditioning): ``ũ_i = u_i − ū``, target ``t̃ = t − ū``.
   Every configuration is subsampled to the same M samples and all neurons
   train in one batch of :func:`ftnav.core.lms.lms_train`.
4. Held-out runs (whole runs, :data:`~ftnav.sim.fault_family.HOLDOUT_OFFSET`):
   RMSE per configuration and state of the neuron fusion (configuration from
   the true fault windows, and from the residual chi-square flags), of every
   local filter and of the centralized filter, on the same data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ftnav.core.lms import lms_train
from ftnav.engine.driver import run
from ftnav.engine.linear import LinearModel
from ftnav.fusion import registry
from ftnav.fusion.config import Learned, OracleDetector, ResidualChi2
from ftnav.fusion.neural import NeuralConfig, NeuralFusion
from ftnav.fusion.neural_model import FREE_INPUT, NeuronModel
from ftnav.io.learned import compatibility
from ftnav.model.scenario import Scenario
from ftnav.sim.fault_family import (
    HOLDOUT_OFFSET,
    FaultFamily,
    fault_variants,
    simulate_variants,
    window_masks,
)

__all__ = ["check_training", "FusionTraining", "FusionReport", "train_fusion", "fusion_table"]

_WINDOW_STREAM = 0x4E46
_SAMPLE_STREAM = 0x4E53


def _default_family() -> FaultFamily:
    return FaultFamily(
        step_sizes=(5.0, 10.0, 20.0), ramp_sizes=(20.0,), noise_scales=(5.0,), fault_free=4
    )


@dataclass(frozen=True, slots=True)
class FusionTraining:
    """Settings of :func:`train_fusion` (defaults from spec §5.3).

    Attributes
    ----------
    runs, holdout_runs : runs per fault variant.   seed : root seed.
    family : faults that generate each configuration's data.
    free_input : add the free propagation as an input (paper 001's SINS input).
    projection, step, mu, epochs, tol : LMS settings (:func:`ftnav.core.lms.lms_train`).
    max_samples : samples per neuron (all configurations use the same number).
    skip_fraction : initial fraction of each run left out (filter convergence).
    chi2_pfa, chi2_prior : false-alarm probability and prior of the selection test on
        held-out runs (``"global"``: against the predicted fused estimate).
    """

    runs: int = 4
    holdout_runs: int = 2
    seed: int = 1
    family: FaultFamily = field(default_factory=_default_family)
    free_input: bool = False
    projection: str = "simplex"
    step: str = "lms"
    mu: float = 0.1
    epochs: int = 200
    tol: float = 1e-6
    max_samples: int = 20000
    skip_fraction: float = 0.05
    chi2_pfa: float = 1e-3
    chi2_prior: str = "global"

    def __post_init__(self):
        for name in ("runs", "holdout_runs", "max_samples"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: must be >= 1, got {getattr(self, name)}")
        if not 0 <= self.skip_fraction < 1:
            raise ValueError(f"skip_fraction: must be in [0, 1), got {self.skip_fraction}")


@dataclass(frozen=True)
class FusionReport:
    """Held-out RMSE per configuration.

    ``rmse[source][configuration]`` maps state name → RMSE, for the sources
    ``neural-oracle`` (configuration from the true windows), ``neural-chi2``
    (from the chi-square flags), ``centralized`` and every local filter.
    """

    rmse: dict[str, dict[str, dict[str, float]]]
    configurations: tuple[str, ...]
    states: tuple[str, ...]
    samples_per_neuron: int
    lms_epochs: int
    min_weight: float
    max_sum_error: float


def _epoch_masks(scenario: Scenario, variants, runs: int, skip: float):
    """Per configuration, a (B, K) mask of the epochs that belong to it."""
    converged = scenario.times >= skip * scenario.steps * scenario.dt
    windows = window_masks(scenario, variants, runs)  # (B, K, N)
    fault_free = np.repeat([v.sensor is None for v in variants], runs)
    masks = {"healthy": fault_free[:, None] & converged}
    for i, name in enumerate(scenario.sensor_names):
        masks[name] = windows[..., i] & converged
    return masks


def _training_epochs(scenario: Scenario, variants, s: FusionTraining):
    """The epochs of each configuration and the samples per neuron (known before any
    simulation); too few for the inputs raise ``ValueError`` naming ``runs``."""
    masks = _epoch_masks(scenario, variants, s.runs, s.skip_fraction)
    M = min(s.max_samples, *(int(m.sum()) for m in masks.values()))
    n_in = len(scenario.sensor_names) + int(s.free_input)
    if M <= n_in:
        raise ValueError(
            f"runs: too few training epochs ({M}) for {n_in} inputs; "
            "raise runs or the fault windows"
        )
    return masks, M


def check_training(scenario: Scenario, settings: FusionTraining = FusionTraining()) -> None:
    """Raise the ``ValueError`` :func:`train_fusion` would, before anything is computed."""
    rng = np.random.default_rng(np.random.SeedSequence(settings.seed, spawn_key=(_WINDOW_STREAM,)))
    _training_epochs(scenario, fault_variants(scenario, settings.family, rng), settings)


def _estimates(system, stream, steps, filt, progress) -> np.ndarray:
    """(B, K, n_c) fused estimates of one filter over the stream."""
    return run(LinearModel(system), stream, {"m": filt}, steps, progress)["m"].x


def _inputs(system, stream, steps, free_input, progress):
    """Stacked local estimates (B, K, N_in, n_c) of independent local filters."""
    collect = NeuralFusion(
        system, NeuralConfig(name="collect"), collect=True, free_input=free_input
    )
    trace = run(LinearModel(system), stream, {"collect": collect}, steps, progress)["collect"]
    B, K, _ = trace.features.shape
    return trace.features.reshape(B, K, -1, system.n_common)


def train_fusion(
    scenario: Scenario,
    settings: FusionTraining = FusionTraining(),
    progress: Callable[[int], None] | None = None,
) -> tuple[NeuronModel, FusionReport]:
    """Train the neuron banks for ``scenario``'s system (spec §5.3-§5.4).

    Returns
    -------
    model : the trained banks (save with :func:`ftnav.io.learned.save_neuron_model`).
    report : held-out RMSE per configuration beside the local and centralized filters.
    """
    s = settings
    system = scenario.system()
    nc, N = system.n_common, system.n_sensors
    rng = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(_WINDOW_STREAM,)))
    variants = fault_variants(scenario, s.family, rng)
    masks, M = _training_epochs(scenario, variants, s)
    configs = tuple(masks)
    sim, _ = simulate_variants(scenario, variants, s.runs, s.seed)
    U = _inputs(system, sim.stream, scenario.steps, s.free_input, progress)  # (B, K, N_in, nc)
    truth = sim.truth.states[..., :nc]
    pick = np.random.default_rng(np.random.SeedSequence(s.seed, spawn_key=(_SAMPLE_STREAM,)))
    Us, ts = [], []
    for c in configs:
        idx = np.flatnonzero(masks[c].ravel())
        idx = np.sort(pick.choice(idx, M, replace=False))
        u = U.reshape(-1, *U.shape[2:])[idx]  # (M, N_in, nc)
        t = truth.reshape(-1, nc)[idx]  # (M, nc)
        ubar = u.mean(1)  # (M, nc) centring (spec §5.3)
        Us.append(np.moveaxis(u - ubar[:, None, :], 2, 0))  # (nc, M, N_in)
        ts.append((t - ubar).T)  # (nc, M)
    lms = lms_train(
        np.concatenate(Us),
        np.concatenate(ts),
        projection=s.projection,
        step=s.step,
        mu=s.mu,
        epochs=s.epochs,
        tol=s.tol,
        rng=pick,
    )
    C = len(configs)
    weights = lms.weights.reshape(C, nc, -1)
    patterns = np.zeros((C, N), dtype=bool)
    for j, c in enumerate(configs[1:], start=1):
        patterns[j, scenario.sensor_names.index(c)] = True
    inputs = scenario.sensor_names + ((FREE_INPUT,) if s.free_input else ())
    provenance = {
        "scenario": scenario.name,
        "runs_per_variant": s.runs,
        "seed": s.seed,
        "variants": [v.label for v in variants],
        "samples_per_neuron": M,
        "lms": {
            "projection": s.projection,
            "step": s.step,
            "mu": s.mu,
            "epochs": s.epochs,
            "epochs_run": int(lms.epochs_run),
            "converged": bool(lms.converged),
            "tol": s.tol,
        },
        "family": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(s.family).items()},
    }
    model = NeuronModel(
        configs,
        patterns,
        inputs,
        tuple(system.model.states),
        weights,
        np.sqrt(lms.mse).reshape(C, nc),
        compatibility(system),
        provenance,
    )
    rmse = _held_out(scenario, system, model, variants, s, progress)
    report = FusionReport(
        rmse,
        configs,
        tuple(system.model.states),
        M,
        int(lms.epochs_run),
        float(lms.min_weight.min()),
        float(lms.max_sum_error.max()),
    )
    return replace(model, training={**provenance, "held_out_rmse": rmse}), report


def _held_out(scenario, system, model, variants, s: FusionTraining, progress) -> dict:
    """Held-out RMSE ``[source][configuration][state]`` (see :class:`FusionReport`)."""
    sim, _ = simulate_variants(scenario, variants, s.holdout_runs, s.seed, HOLDOUT_OFFSET)
    nc, K = system.n_common, scenario.steps
    masks = _epoch_masks(scenario, variants, s.holdout_runs, s.skip_fraction)
    U = _inputs(system, sim.stream, K, model.free_input, progress)
    truth = sim.truth.states[..., :nc]
    est = {name: U[:, :, i] for i, name in enumerate(model.inputs)}
    chi2 = ResidualChi2(
        kind="residual-chi2", false_alarm_probability=s.chi2_pfa, n_off=3, prior=s.chi2_prior
    )
    for src, filt in (
        (
            "neural-oracle",
            NeuralFusion(
                system,
                NeuralConfig(name="neural", detector=OracleDetector(kind="oracle")),
                Learned(fusion=model),
            ),
        ),
        (
            "neural-chi2",
            NeuralFusion(system, NeuralConfig(name="neural", detector=chi2), Learned(fusion=model)),
        ),
        ("centralized", registry.build(system, registry.method_config("centralized", name="ckf"))),
    ):
        est[src] = _estimates(system, sim.stream, K, filt, progress)
    rmse = {}
    states = tuple(system.model.states)
    for src, x in est.items():
        err2 = (x - truth) ** 2
        rmse[src] = {
            c: {st: float(np.sqrt(err2[mask][:, j].mean())) for j, st in enumerate(states)}
            for c, mask in masks.items()
        }
    order = ["neural-oracle", "neural-chi2", "centralized", *model.inputs]
    return {k: rmse[k] for k in order}


def fusion_table(model: NeuronModel, report: FusionReport) -> str:
    """Plain-text table: held-out RMSE per configuration and the learned weights."""
    lines = []
    for j, st in enumerate(report.states):
        head = f"RMSE of {st} on held-out runs, per configuration"
        cols = "".join(f"{c:>12s}" for c in report.configurations)
        lines += [head, f"{'source':16s}{cols}"]
        for src, by in report.rmse.items():
            lines.append(
                f"{src:16s}" + "".join(f"{by[c][st]:12.3g}" for c in report.configurations)
            )
        lines.append("weights (" + ", ".join(model.inputs) + "):")
        for c, w in zip(model.configurations, model.weights[:, j], strict=True):
            lines.append(f"  {c:14s} " + " ".join(f"{v:.3f}" for v in w))
        lines.append("")
    lines.append(
        f"LMS: {report.samples_per_neuron} samples per neuron, {report.lms_epochs} "
        f"epochs; constraints over every update: min w = {report.min_weight:.3g}, "
        f"max |sum w - 1| = {report.max_sum_error:.2g}"
    )
    return "\n".join(lines)
