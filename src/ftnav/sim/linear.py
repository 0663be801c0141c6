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

from ftnav.model.scenario import Scenario
from ftnav.model.system import LinearSystem

__all__ = ["Simulation", "concat_simulations", "run_generator", "simulate"]


class Simulation(NamedTuple):
    """Simulated data for B runs and K steps.

    Attributes
    ----------
    truth : (B, K, n_aug) true augmented state at t_1..t_K.
    z : per sensor (B, K, m_i) measurements (garbage where not available).
    available : (B, K, N) bool, a measurement exists (schedule and outages).
    oracle : (K, N) bool, true detectable fault windows per sensor (or (K, B, N)
        per run, for a batch that concatenates simulations).
    noise_free : per sensor (B, K, m_i) ideal measurements H x (for analysis).
    """

    truth: np.ndarray
    z: tuple[np.ndarray, ...]
    available: np.ndarray
    oracle: np.ndarray
    noise_free: tuple[np.ndarray, ...]


def run_generator(seed: int, run: int) -> np.random.Generator:
    """Random stream of Monte Carlo run ``run`` under root ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(run,)))


def _cholesky_psd(A: np.ndarray) -> np.ndarray:
    """Factor L with L Lᵀ = A for a positive semi-definite A (eigen-decomposition)."""
    w, V = np.linalg.eigh(0.5 * (A + A.T))
    return V * np.sqrt(np.clip(w, 0.0, None))


def simulate(
    scenario: Scenario, runs: int, seed: int, first_run: int = 0, system: LinearSystem | None = None
) -> Simulation:
    """Simulate ``runs`` Monte Carlo runs (indices ``first_run ..``) of a scenario.

    ``system`` replaces the scenario's constant model, e.g. by a
    :class:`~ftnav.model.system.TimeVaryingSystem` (same sensors and faults).
    """
    system = LinearSystem.from_scenario(scenario) if system is None else system
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
    for k in range(1, K + 1):
        F, Q = system.augmented_transition(k, true=True)
        x = np.einsum("ij,bj->bi", F, x) + np.einsum("ij,bj->bi", _cholesky_psd(Q), w[:, k - 1])
        truth[:, k - 1] = x

    t = scenario.times
    z, ideal = [], []
    available = np.empty((B, K, N), dtype=bool)
    oracle = np.zeros((K, N), dtype=bool)
    start = 0
    for i, s in enumerate(scenario.sensors):
        H = system.augmented_H(i)
        zi_ideal = np.einsum("ij,bkj->bki", H, truth)
        noise = np.einsum(
            "ij,bkj->bki", np.linalg.cholesky(s.R_true), v_all[:, :, start : start + s.dim]
        )
        start += s.dim
        avail = np.broadcast_to(s.available(K), (B, K)).copy()
        for f in scenario.faults:
            if f.sensor != s.name:
                continue
            win = (t >= f.start) & (t < f.end)
            if f.kind == "noise-scale":
                noise = np.where(win[None, :, None], noise * f.magnitude, noise)
        zi = zi_ideal + noise
        for f in scenario.faults:
            if f.sensor != s.name:
                continue
            win = (t >= f.start) & (t < f.end)
            if not win.any():
                continue
            if f.kind == "bias":
                zi = zi + win[None, :, None] * f.magnitude
            elif f.kind == "ramp":
                frac = np.clip((t - f.start) / (f.end - f.start), 0.0, 1.0) * win
                zi = zi + frac[None, :, None] * f.magnitude
            elif f.kind == "outage":
                avail &= ~win[None, :]
            elif f.kind == "stuck":
                k0 = int(np.argmax(win))
                held = zi[:, max(k0 - 1, 0)].copy()
                zi = np.where(win[None, :, None], held[:, None, :], zi)
            if f.kind != "outage":
                oracle[:, i] |= win
        z.append(zi)
        ideal.append(zi_ideal)
        available[:, :, i] = avail
    return Simulation(truth, tuple(z), available, oracle, tuple(ideal))


def concat_simulations(*sims: Simulation) -> Simulation:
    """One simulation with the runs of each argument in turn.

    The oracle becomes per run, ``(K, B_1 + B_2 + ..., N)``.
    """

    def per_run(s):
        return np.broadcast_to(
            s.oracle[:, None, :] if s.oracle.ndim == 2 else s.oracle,
            (s.oracle.shape[0], s.truth.shape[0], s.oracle.shape[-1]),
        )

    return Simulation(
        np.concatenate([s.truth for s in sims]),
        tuple(np.concatenate(p) for p in zip(*(s.z for s in sims), strict=True)),
        np.concatenate([s.available for s in sims]),
        np.concatenate([per_run(s) for s in sims], axis=1),
        tuple(np.concatenate(p) for p in zip(*(s.noise_free for s in sims), strict=True)),
    )
