"""Random linear test problems and a step-by-step filter driver for the equivalence tests.

Not a test module: imported by ``test_*.py`` in this folder (pytest puts the
folder on ``sys.path``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.fusion.centralized import CentralizedFilter
from ftnav.model.scenario import Fault, Scenario
from ftnav.model.system import LinearModel, Sensor
from ftnav.model.system import LinearSystem
from ftnav.sim.linear import Simulation, simulate


def random_spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    """Well-conditioned random SPD matrix ``scale·(A Aᵀ/n + 0.1 I)``."""
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + 0.1 * np.eye(n))


def random_scenario(
    rng: np.random.Generator,
    n: int,
    dims: list[int],
    steps: int,
    *,
    Q: np.ndarray | None = None,
    every: list[int] | None = None,
    faults: tuple[Fault, ...] = (),
) -> Scenario:
    """Stable random model (``F = 0.98·orthogonal + 0.02·noise``) with SPD Q, P0, R_i.

    Sensor i is named ``z{i}``; ``every`` sets multi-rate schedules.
    """
    ortho, _ = np.linalg.qr(rng.standard_normal((n, n)))
    F = 0.98 * ortho + 0.02 * rng.standard_normal((n, n))
    Q = random_spd(rng, n, 0.1) if Q is None else Q
    P0 = random_spd(rng, n, 10.0)
    model = LinearModel(tuple(f"s{j}" for j in range(n)), F, Q, rng.standard_normal(n), P0, Q)
    every = every or [1] * len(dims)
    sensors = []
    for i, (m, e) in enumerate(zip(dims, every, strict=True)):
        R = random_spd(rng, m)
        sensors.append(Sensor(f"z{i}", rng.standard_normal((m, n)), R, R, every=e))
    return Scenario("random", 1.0, steps, model, tuple(sensors), faults)


class Trajectory(NamedTuple):
    """Fused outputs of one filter over all epochs: x (B, K, n_c), P (B, K, n_c, n_c)."""

    x: np.ndarray
    P: np.ndarray
    outputs: list
    states: list


def drive(
    filt,
    sim: Simulation,
    available: np.ndarray | None = None,
    oracle: np.ndarray | None = None,
    keep_states: bool = False,
) -> Trajectory:
    """Run ``filt`` epoch by epoch over ``sim`` (optionally with a replaced schedule/oracle)."""
    available = sim.available if available is None else available
    oracle = sim.oracle if oracle is None else oracle
    B, K = sim.truth.shape[:2]
    state = filt.init(B)
    xs, Ps, outs, states = [], [], [], []
    for k in range(1, K + 1):
        state, out = filt.step(
            state, k, [z[:, k - 1] for z in sim.z], available[:, k - 1], oracle[k - 1]
        )
        xs.append(out.x)
        Ps.append(out.P)
        outs.append(out)
        if keep_states:
            states.append(state)
    return Trajectory(np.stack(xs, 1), np.stack(Ps, 1), outs, states)


def centralized_skipping(
    system: LinearSystem, sim: Simulation, sensor: int, first: int, last: int
) -> Trajectory:
    """Plain centralized KF that ignores ``sensor`` on steps ``first..last`` (inclusive)."""
    available = sim.available.copy()
    available[:, first - 1 : last, sensor] = False
    return drive(CentralizedFilter(system), sim, available, np.zeros_like(sim.oracle))


def assert_same(traj: Trajectory, ref: Trajectory, rtol: float = 1e-9) -> None:
    """``traj`` equals ``ref`` within ``rtol`` relative to the reference's scale."""
    x_scale = max(1.0, float(np.abs(ref.x).max()))
    P_scale = max(1.0, float(np.abs(ref.P).max()))
    np.testing.assert_allclose(traj.x, ref.x, rtol=rtol, atol=rtol * x_scale)
    np.testing.assert_allclose(traj.P, ref.P, rtol=rtol, atol=rtol * P_scale)


def simulate_problem(scenario: Scenario, runs: int = 3, seed: int = 11) -> Simulation:
    return simulate(scenario, runs, seed)


def assert_identical(a, b) -> None:
    """Two result tuples (e.g. :class:`~ftnav.eval.montecarlo.MethodResult`) equal bit for
    bit, field by field (None in both, or equal arrays, or tuples of equal arrays)."""
    for field, u, v in zip(a._fields, a, b, strict=True):
        if u is None or v is None:
            assert u is None and v is None, field
        elif isinstance(u, tuple):
            for p, q in zip(u, v, strict=True):
                np.testing.assert_array_equal(p, q, err_msg=field)
        else:
            np.testing.assert_array_equal(u, v, err_msg=field)
