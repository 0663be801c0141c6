"""Training the neuron fusion centre on an integrated-navigation scenario (paper 001 §3-§4).

Configurations (spec §5.4, paper 001 §3.3): ``healthy``, one per aid (that aid's local
filter flagged) and ``sins`` (every aid flagged at once: the SINS that all local filters
share has failed) -- the paper's five for SINS/GPS/TAN/DNS.

Training data (:func:`train_ins_fusion`): for each configuration the scenario is flown
closed loop with that element faulty from ``fault_start`` to the end (the magnitude of
the scenario's first fault of that element; without one, the configuration is
skipped).  The collecting filter is the neural architecture's own independent local
filters, fused by inverse variances over the unflagged inputs with the true fault
flags (``oracle``), with the correction the trained method uses in operation:
``"output"`` (paper 001 §3: the SINS runs free, each local filter corrects its own copy
of its output and measures its aid there) or ``"feedback"`` (the fused estimate fed
back).  Targets are the true error states of the SINS the locals estimate (its
navigation errors before any correction, the IMU's true biases).

The training runs draw their random streams from run numbers
``TRAIN_RUN_OFFSET + r`` (r = 0 … runs − 1) of the root seed: disjoint from the runs
``ftnav run`` evaluates (0 … runs − 1), so no evaluation run was seen in training.  The
neurons of each (configuration, state) pair are trained by projected LMS on centred
inputs (spec §5.3), as :func:`ftnav.training.fusion.train_fusion` does for
linear scenarios (step below).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ftnav.core.lms import lms_train
from ftnav.engine import navigation_model
from ftnav.engine.driver import iterate
from ftnav.fusion.config import OracleDetector
from ftnav.fusion.neural import NeuralConfig, NeuralFusion
from ftnav.fusion.neural_model import NeuronModel
from ftnav.io.learned import compatibility
from ftnav.model.scenario import SINS, Fault, InsScenario
from ftnav.nav.mechanization import navigation_errors
from ftnav.sim.ins import InsTruth, simulate_ins

__all__ = ["train_ins_fusion", "ins_configurations"]

_SAMPLE_STREAM = 0x4E49
#: first run number of the training runs (module docstring: disjoint from evaluation)
TRAIN_RUN_OFFSET = 1_000_000


def ins_configurations(sc: InsScenario) -> list[tuple[str, np.ndarray, Fault | None]]:
    """(name, flag pattern (N,), training fault) of every configuration with a fault to learn."""
    N = len(sc.aids)
    out = [("healthy", np.zeros(N, bool), None)]
    for i, name in enumerate(sc.sensor_names):
        f = next((f for f in sc.faults if f.sensor == name and f.kind in ("bias", "ramp")), None)
        if f is not None:
            pattern = np.zeros(N, bool)
            pattern[i] = True
            out.append((name, pattern, f))
    f = next((f for f in sc.faults if f.sensor == SINS), None)
    if f is not None:
        out.append((SINS, np.ones(N, bool), f))
    return out


def check_ins_training(sc: InsScenario, fault_start: float = 150.0, skip: float = 60.0) -> None:
    """Refuse a flight too short to train on (ValueError naming ``filter.duration_s``):
    each configuration's samples start ``skip`` s after its fault, injected from
    ``fault_start`` s (a 120 s flight had none and ended in the LMS's own message)."""
    duration = sc.steps * sc.dt
    if duration <= fault_start + skip:
        raise ValueError(
            f"filter.duration_s: the flight lasts {duration:g} s; training the neuron "
            f"centre needs it past {fault_start + skip:g} s (each configuration's fault "
            f"from {fault_start:g} s, its samples from {skip:g} s after)"
        )


def train_ins_fusion(
    sc: InsScenario,
    runs: int = 4,
    seed: int = 1,
    *,
    fault_start: float = 150.0,
    skip: float = 60.0,
    max_samples: int = 4000,
    mu: float = 1.0,
    epochs: int = 500,
    progress: Callable[[int], None] | None = None,
    samples: dict | None = None,
    correction: str | None = None,
    run_offset: int = TRAIN_RUN_OFFSET,
) -> NeuronModel:
    """Train the neuron banks of the scenario's integrated system (module docstring).

    LMS step ``η = μ / tr R`` (``step="lms"``) with μ = 1 and 500 decaying epochs: the
    local estimates' errors differ by orders of magnitude (GPS ~20 m, Doppler ~500 m),
    and the per-sample normalized step (``"nlms"``, μ = 0.1, 200 epochs) then stalled far
    from the constrained least-squares optimum (healthy δL weights 0.17 / 0.83 / 0.00
    for GPS / TAN / DNS against the optimum 0.94 / 0.03 / 0.02).  ``samples``, if given,
    receives the centred, scaled training arrays ``U`` (J, M, N_in) and ``t`` (J, M).
    ``correction``: the trained method's (default: the scenario's); ``run_offset``: the
    first run number of the training runs (module docstring).
    """
    check_ins_training(sc, fault_start, skip)
    correction = correction or sc.correction
    system = sc.system()
    model_ = navigation_model(sc, system)
    nc = system.n_common
    collect_method = NeuralConfig(
        name="collect", detector=OracleDetector(kind="oracle"), correction=correction
    )
    training_runs = range(run_offset, run_offset + runs)
    configs = ins_configurations(sc)
    end = sc.steps * sc.dt
    pick = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_SAMPLE_STREAM,)))
    Us, ts, names, patterns = [], [], [], []
    for name, pattern, fault in configs:
        faults = () if fault is None else (replace(fault, start=fault_start, end=end + 1.0),)
        variant = replace(sc, faults=faults)
        sim = simulate_ins(variant, training_runs, seed)
        filt = NeuralFusion(system, collect_method, collect=True, untrained="inverse-variance")
        truth = np.empty((runs, sc.steps, nc))
        feats = np.empty((runs, sc.steps, system.n_sensors * nc))
        for r in iterate(model_, sim.stream, {"collect": filt}, sc.steps, progress):
            truth[:, r.k - 1] = true_states(sim.truth, r.nav, r.k, nc)
            feats[:, r.k - 1] = r.outputs[0].features
        res_features = feats
        U = res_features.reshape(runs, sc.steps, -1, nc)  # (B, K, N_in, nc)
        t = sc.times
        window = t >= (skip if fault is None else fault_start + skip)
        u = U[:, window].reshape(-1, *U.shape[2:])
        tt = truth[:, window].reshape(-1, nc)
        M = min(max_samples, u.shape[0])
        idx = np.sort(pick.choice(u.shape[0], M, replace=False))
        u, tt = u[idx], tt[idx]
        ubar = u.mean(1)
        Us.append(np.moveaxis(u - ubar[:, None, :], 2, 0))  # (nc, M, N_in)
        ts.append((tt - ubar).T)
        names.append(name)
        patterns.append(pattern)
    M = min(x.shape[1] for x in Us)
    Us = [x[:, :M] for x in Us]
    ts = [x[:, :M] for x in ts]
    # scale each neuron's inputs to unit size: the states mix radians and metres
    U_all, t_all = np.concatenate(Us), np.concatenate(ts)
    scale = np.sqrt((U_all**2).mean((1, 2), keepdims=True)) + 1e-300
    U_all, t_all = U_all / scale, t_all / scale[..., 0]
    if samples is not None:
        samples.update(U=U_all, t=t_all)
    lms = lms_train(U_all, t_all, projection="simplex", step="lms", mu=mu, epochs=epochs, rng=pick)
    C = len(names)
    weights = lms.weights.reshape(C, nc, -1)
    rmse = np.sqrt(lms.mse).reshape(C, nc) * scale[:, 0, 0].reshape(C, nc)
    provenance = {
        "scenario": sc.name,
        "profile": sc.profile.name,
        "runs": runs,
        "run_numbers": [run_offset, run_offset + runs - 1],
        "seed": seed,
        "correction": correction,
        "fault_start_s": fault_start,
        "samples_per_neuron": M,
        "collect": (
            "output correction, each local at its own SINS copy"
            if correction == "output"
            else "closed loop (feedback)"
        )
        + ", inverse-variance fusion with oracle flags",
        "lms": {
            "projection": "simplex",
            "step": "lms",
            "mu": mu,
            "epochs": epochs,
            "epochs_run": int(lms.epochs_run),
            "converged": bool(lms.converged),
        },
    }
    return NeuronModel(
        tuple(names),
        np.array(patterns),
        tuple(sc.sensor_names),
        tuple(system.model.states),
        weights,
        rmse,
        compatibility(system),
        provenance,
    )


def true_states(truth: InsTruth, nav, k: int, n: int) -> np.ndarray:
    """(B, n) the true error state at epoch k: the navigation errors of the SINS (its first
    B rows) before the correction, then the IMU's true biases as the error model's states
    hold them (18 states: ε_b, ε_r, ∇ = constant + Markov accelerometer bias; 15 states:
    ε and ∇ each constant + Markov)."""
    tr, it = truth.epochs, truth.imu
    B = it.gyro_bias.shape[0]
    e = navigation_errors(nav.q[:B], nav.v[:B], nav.p[:B], tr.q[k - 1], tr.v[k - 1], tr.p[k - 1])
    accel = it.accel_bias + it.accel_markov[:, k - 1]
    gyro = (
        [it.gyro_bias, it.gyro_markov[:, k - 1]]
        if n == 18
        else [it.gyro_bias + it.gyro_markov[:, k - 1]]
    )
    return np.concatenate([e, *gyro, accel], -1)
