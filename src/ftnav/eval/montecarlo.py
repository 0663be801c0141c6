"""Monte Carlo runner: simulate once, run every method over all runs in lock-step.

The time loop is a Python loop over epochs; every operation inside is batched
over the B runs (no loop over runs).  Per-run random streams come from one root
seed (:func:`ftnav.sim.linear.run_generator`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ftnav.eval.metrics import nees
from ftnav.fusion.centralized import CentralizedFilter
from ftnav.fusion.distributed import DistributedFilter
from ftnav.fusion.federated import FederatedFilter
from ftnav.fusion.neural import NeuralFusion
from ftnav.model.scenario import Method, Scenario
from ftnav.model.system import LinearSystem
from ftnav.parallel import run_tasks, split_even
from ftnav.sim.linear import Simulation, concat_simulations, simulate

__all__ = [
    "MethodResult",
    "ScenarioResult",
    "build_filter",
    "run_filter",
    "run_scenario",
    "concat_simulations",
    "split_result",
]


class MethodResult(NamedTuple):
    """Per-epoch outputs of one method over B runs and K epochs.

    Attributes
    ----------
    x : (B, K, n_c) fused estimate.   P_diag : (B, K, n_c) its variances.
    nees : (B, K) NEES of the fused common state against truth.
    beta : (B, K, N) sharing coefficients, or None (not federated).
    statistic, threshold : (B, K, N) detector statistic and threshold, or None.
    raw_flag, flag : (B, K, N) detector flags before/after hysteresis, or None.
    R_hat : per sensor (B, K, m_i) diagonal noise used (adapted under VB).
    nan_count : (B, N) scheduled measurements that were NaN/inf (treated as missing).
    features : (B, K, F) learned-detector features (spec §4.1), or None.
    """

    x: np.ndarray
    P_diag: np.ndarray
    nees: np.ndarray
    beta: np.ndarray | None
    statistic: np.ndarray | None
    threshold: np.ndarray | None
    raw_flag: np.ndarray | None
    flag: np.ndarray | None
    R_hat: tuple[np.ndarray, ...]
    nan_count: np.ndarray
    features: np.ndarray | None = None


class ScenarioResult(NamedTuple):
    """Everything ``ftnav run`` computes: data, and results with and without faults."""

    scenario: Scenario
    runs: int
    seed: int
    simulation: Simulation
    results: dict[str, MethodResult]
    fault_free_simulation: Simulation | None
    fault_free: dict[str, MethodResult]


def build_filter(system: LinearSystem, method: Method, features: tuple[str, ...] | None = None):
    """The filter object for a method's architecture.

    ``features`` asks a federated or distributed filter to report the learned
    detector's input features every epoch (training data collection).
    """
    if method.architecture == "centralized":
        return CentralizedFilter(system, method)
    if method.architecture == "federated":
        return FederatedFilter(system, method, features=features)
    if method.architecture == "distributed":
        return DistributedFilter(system, method, features=features)
    if method.architecture == "neural":
        return NeuralFusion(system, method)
    raise ValueError(f"methods[{method.name}].architecture: unknown value {method.architecture!r}")


def run_filter(
    filt, sim: Simulation, n_common: int, progress: Callable[[int], None] | None = None
) -> MethodResult:
    """Run one filter over a simulation; returns per-epoch arrays."""
    B, K = sim.truth.shape[:2]
    N = len(sim.z)
    state = filt.init(B)
    x = np.empty((B, K, n_common))
    Pd = np.empty((B, K, n_common))
    ne = np.empty((B, K))
    beta = stat = thr = raw = flag = feats = None
    R_hat = [np.empty((B, K, z.shape[-1])) for z in sim.z]
    nan_count = np.zeros((B, N), dtype=int)
    for k in range(1, K + 1):
        zk = [z[:, k - 1] for z in sim.z]
        state, out = filt.step(state, k, zk, sim.available[:, k - 1], sim.oracle[k - 1])
        x[:, k - 1] = out.x
        Pd[:, k - 1] = np.diagonal(out.P, axis1=-2, axis2=-1)
        ne[:, k - 1] = nees(out.x - sim.truth[:, k - 1, :n_common], out.P)
        if out.beta is not None:
            if beta is None:
                beta = np.empty((B, K, N))
            beta[:, k - 1] = out.beta
        if out.detection is not None:
            if stat is None:
                stat, thr = np.empty((B, K, N)), np.empty((B, K, N))
                raw, flag = np.empty((B, K, N), bool), np.empty((B, K, N), bool)
            d = out.detection
            stat[:, k - 1], thr[:, k - 1] = d.statistic, d.threshold
            raw[:, k - 1], flag[:, k - 1] = d.raw, d.flag
        if out.features is not None:
            if feats is None:
                feats = np.empty((B, K, out.features.shape[-1]))
            feats[:, k - 1] = out.features
        for i, r in enumerate(out.R_hat):
            R_hat[i][:, k - 1] = r
        nan_count += out.nan
        if progress is not None:
            progress(1)
    return MethodResult(x, Pd, ne, beta, stat, thr, raw, flag, tuple(R_hat), nan_count, feats)


#: smallest ``methods × epochs`` worth worker processes (each costs ~2 s to start)
PARALLEL_MIN_WORK = 10_000


def run_scenario(
    scenario: Scenario,
    runs: int,
    seed: int,
    *,
    methods: tuple[Method, ...] | None = None,
    fault_free: bool = True,
    progress: Callable[[int], None] | None = None,
    workers: int = 1,
) -> ScenarioResult:
    """Simulate the scenario and run every method (and, if asked, the fault-free twin).

    The fault-free twin uses the same random streams with the faults removed
    (the paper's Fig. 3 condition), so in-window RMSE can be compared with and
    without the fault on identical noise.  Both simulations run as one batch of
    ``2·runs`` (runs are independent, so the results are those of two separate
    batches) and are split afterwards: half the per-epoch Python overhead.

    ``workers > 1`` runs groups of methods in that many processes
    (:mod:`ftnav.parallel`) when the job holds at least
    :data:`PARALLEL_MIN_WORK` method-epochs; each simulates the same runs from the
    seed, so the results are identical to ``workers = 1``.
    """
    if runs < 1:
        raise ValueError(f"runs: must be >= 1, got {runs}")
    methods = scenario.methods if methods is None else methods
    system = LinearSystem.from_scenario(scenario)
    filters = {m.name: build_filter(system, m) for m in methods}  # validate before running
    sim = simulate(scenario, runs, seed)
    twin = fault_free and bool(scenario.faults)
    sim_ff = simulate(scenario.without_faults(), runs, seed) if twin else None
    groups = [tuple(methods)]
    if workers > 1 and len(methods) * scenario.steps >= PARALLEL_MIN_WORK:
        groups = [tuple(g) for g in split_even(methods, 3 * workers)]
    # in this process the task reuses the simulation; a worker simulates its own copy
    local = (sim, sim_ff) if len(groups) == 1 else None
    parts = run_tasks(
        _method_group, [(scenario, runs, seed, g, twin, local) for g in groups], workers, progress
    )
    results, ff = {}, {}
    for group, (res, res_ff) in zip(groups, parts, strict=True):
        results.update((m.name, r) for m, r in zip(group, res, strict=True))
        ff.update((m.name, r) for m, r in zip(group, res_ff, strict=False))
    results = {name: results[name] for name in filters}  # the scenario's order
    ff = {name: ff[name] for name in filters} if twin else {}
    return ScenarioResult(scenario, runs, seed, sim, results, sim_ff, ff)


def _method_group(
    task, progress: Callable[[int], None] | None = None
) -> tuple[list[MethodResult], list[MethodResult]]:
    """One task of :func:`run_scenario`: a group of methods over every run."""
    scenario, runs, seed, methods, twin, local = task
    system = LinearSystem.from_scenario(scenario)
    nc = system.n_common
    sim, sim_ff = (
        local
        if local is not None
        else (
            simulate(scenario, runs, seed),
            simulate(scenario.without_faults(), runs, seed) if twin else None,
        )
    )
    if not twin:
        return [run_filter(build_filter(system, m), sim, nc, progress) for m in methods], []
    both = concat_simulations(sim, sim_ff)
    split = [
        split_result(run_filter(build_filter(system, m), both, nc, progress), runs) for m in methods
    ]
    return [r[0] for r in split], [r[1] for r in split]


def split_result(r: MethodResult, runs: int) -> tuple[MethodResult, MethodResult]:
    """Split a :class:`MethodResult` of a concatenated batch after ``runs`` runs."""

    def part(sl):
        return MethodResult(
            *(
                tuple(a[sl] for a in v) if isinstance(v, tuple) else None if v is None else v[sl]
                for v in r
            )
        )

    return part(slice(None, runs)), part(slice(runs, None))
