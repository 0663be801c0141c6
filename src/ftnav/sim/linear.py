"""Truth and measurement simulation of a linear scenario, with fault injection.

Truth: ``x_0 ~ N(x0, P0)``, ``x_k = F x_{k−1} + w``, ``w ~ N(0, Q_true)`` on the
augmented state (common + private sensor states).  Ideal measurements
``H x_k``, then noise ``v ~ N(0, R_true)`` and faults (spec §9.6) are applied
in that order, so truth and corruption stay apart.

Randomness (style §5): run ``i`` draws from
``Generator(SeedSequence(seed, spawn_key=(i,)))``, the same stream that
``SeedSequence(seed).spawn(n)[i]`` gives, so run i is identical alone or in a
batch.  The only Python loop over runs is this draw of each run's noise.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.model.faults import fault_effect, hold_stuck
from ftnav.model.scenario import Scenario
from ftnav.model.streams import MeasurementStream
from ftnav.model.system import LinearSystem, TimeVarying

__all__ = ["LinearTruth", "Simulated", "run_generator", "simulate"]


class LinearTruth(NamedTuple):
    """The truth of B simulated runs of a linear scenario.

    Attributes
    ----------
    states : (B, K, n_aug) true augmented state at t_1..t_K.
    noise_free : per sensor (B, K, m_i) ideal measurements H x (for analysis).
    """

    states: np.ndarray
    noise_free: tuple[np.ndarray, ...]


class Simulated(NamedTuple):
    """A simulator's output: the stream the engine consumes and, apart, the truth."""

    stream: MeasurementStream
    truth: LinearTruth


def run_generator(seed: int, run: int) -> np.random.Generator:
    """Random stream of Monte Carlo run ``run`` under root ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run,)))


def _cholesky_psd(A: np.ndarray) -> np.ndarray:
    """Factor L with L Lᵀ = A for a positive semi-definite A (eigen-decomposition)."""
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def simulate(
    scenario: Scenario,
    runs: int,
    seed: int,
    first_run: int = 0,
    transitions: TimeVarying | None = None,
) -> Simulated:
    """Simulate ``runs`` Monte Carlo runs (indices ``first_run ..``) of a scenario.

    ``transitions`` gives a time-varying model's per-epoch common ``(Φ_k, Q_k)`` (the
    simulator draws ``Q_k`` as the true process noise); the private states and the
    sensors are the scenario's.
    """
    system = LinearSystem(scenario.model, scenario.sensors)
    K, B, N = scenario.steps, runs, len(scenario.sensors)
    n = system.n_aug
    dims = [s.dim for s in scenario.sensors]
    x0, P0 = system.augmented_initial()
    # one draw per run: initial state, process noise, measurement noise
    size = n + K * n + K * sum(dims)
    draws = np.stack([run_generator(seed, first_run + b).standard_normal(size) for b in range(B)])
    # einsum keeps a fixed summation order per element, so run i is bit-identical
    # whatever the batch size (BLAS blocking would depend on it)
    x = x0 + np.einsum("ij,bj->bi", _cholesky_psd(P0), draws[:, :n])
    w = draws[:, n : n + K * n].reshape(B, K, n)
    v_all = draws[:, n + K * n :].reshape(B, K, sum(dims))

    truth = np.empty((B, K, n))
    F_aug, Q_aug = system.augmented_transition(true=True)
    for k in range(1, K + 1):
        F, Q = F_aug, Q_aug
        if transitions is not None:
            F, Q = F.copy(), Q.copy()
            nc = system.n_common
            F[:nc, :nc], Q[:nc, :nc] = transitions.Phi[k - 1], transitions.Q[k - 1]
        x = np.einsum("ij,bj->bi", F, x) + np.einsum("ij,bj->bi", _cholesky_psd(Q), w[:, k - 1])
        truth[:, k - 1] = x

    t = scenario.times
    z, ideal = [], []
    available = np.empty((B, K, N), dtype=bool)
    labels = np.zeros((K, N), dtype=bool)
    start = 0
    for i, s in enumerate(scenario.sensors):
        H = system.augmented_H(i)
        zi_ideal = np.einsum("ij,bkj->bki", H, truth)
        noise = np.einsum(
            "ij,bkj->bki", np.linalg.cholesky(s.R_true), v_all[:, :, start : start + s.dim]
        )
        start += s.dim
        effect = fault_effect(scenario.faults, s.name, t, s.dim)
        zi = hold_stuck(zi_ideal + noise * effect.scale[None] + effect.offset[None], effect)
        z.append(zi)
        ideal.append(zi_ideal)
        available[:, :, i] = s.available(K)[None, :] & ~effect.outage[None, :]
        labels[:, i] = effect.label
    return Simulated(
        MeasurementStream(tuple(z), available, labels), LinearTruth(truth, tuple(ideal))
    )
