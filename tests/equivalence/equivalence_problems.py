"""Random linear test problems and a step-by-step filter driver for the equivalence tests.

Not a test module: imported by ``test_*.py`` in this folder (pytest puts the
folder on ``sys.path``).  :func:`drive` forms each epoch with the engine's linear model
(:class:`ftnav.engine.linear.LinearModel`) and steps one filter on it, keeping the full
fused covariance (the engine's trace keeps only its diagonal).
"""

from __future__ import annotations

from dataclasses import fields, is_dataclass
from typing import NamedTuple

import numpy as np

from ftnav.engine.linear import LinearModel as EngineModel
from ftnav.fusion.centralized import CentralizedFilter
from ftnav.fusion.registry import method_config
from ftnav.model.scenario import Fault, Scenario
from ftnav.model.system import LinearModel, LinearSystem, Sensor, TimeVarying
from ftnav.sim.linear import Simulated, simulate

#: the plain centralized Kalman filter (no detector, fixed noise): the oracle
CKF = method_config("centralized", name="ckf")


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
    return Scenario(
        name="random", dt=1.0, steps=steps, model=model, sensors=tuple(sensors), faults=faults
    )


def centralized(system: LinearSystem) -> CentralizedFilter:
    """The plain centralized Kalman filter on ``system`` (the oracle of this folder)."""
    return CentralizedFilter(system, CKF)


class Trajectory(NamedTuple):
    """Fused outputs of one filter over all epochs: x (B, K, n_c), P (B, K, n_c, n_c)."""

    x: np.ndarray
    P: np.ndarray
    outputs: list
    states: list


def drive(
    filt,
    sim: Simulated,
    available: np.ndarray | None = None,
    labels: np.ndarray | None = None,
    keep_states: bool = False,
    transitions: TimeVarying | None = None,
) -> Trajectory:
    """Run ``filt`` epoch by epoch over ``sim``'s stream (optionally with a replaced
    schedule or fault labels; ``transitions``: a time-varying model's ``(Φ_k, Q_k)``)."""
    stream = sim.stream
    if available is not None:
        stream = stream._replace(available=available)
    if labels is not None:
        stream = stream._replace(labels=labels)
    model = EngineModel(filt.system, transitions)
    state = filt.init(stream.batch)
    xs, Ps, outs, states = [], [], [], []
    for k in range(1, stream.epochs + 1):
        _, epoch = model.epoch(None, stream, k, 1)
        state, out = filt.step(state, epoch)
        xs.append(out.x)
        Ps.append(out.P)
        outs.append(out)
        if keep_states:
            states.append(state)
    return Trajectory(np.stack(xs, 1), np.stack(Ps, 1), outs, states)


def centralized_skipping(
    system: LinearSystem, sim: Simulated, sensor: int, first: int, last: int
) -> Trajectory:
    """Plain centralized KF that ignores ``sensor`` on steps ``first..last`` (inclusive)."""
    available = sim.stream.available.copy()
    available[:, first - 1 : last, sensor] = False
    return drive(centralized(system), sim, available, np.zeros_like(sim.stream.labels))


def assert_same(traj: Trajectory, ref: Trajectory, rtol: float = 1e-9) -> None:
    """``traj`` equals ``ref`` within ``rtol`` relative to the reference's scale."""
    x_scale = max(1.0, float(np.abs(ref.x).max()))
    P_scale = max(1.0, float(np.abs(ref.P).max()))
    np.testing.assert_allclose(traj.x, ref.x, rtol=rtol, atol=rtol * x_scale)
    np.testing.assert_allclose(traj.P, ref.P, rtol=rtol, atol=rtol * P_scale)


def simulate_problem(scenario: Scenario, runs: int = 3, seed: int = 11) -> Simulated:
    return simulate(scenario, runs, seed)


def assert_identical(a, b) -> None:
    """Two result tuples (e.g. :class:`~ftnav.eval.montecarlo.MethodResult`) equal bit for
    bit, field by field (None in both, or equal arrays, or tuples of equal arrays)."""
    names = [f.name for f in fields(a)] if is_dataclass(a) else list(a._fields)
    for field in names:
        u, v = getattr(a, field), getattr(b, field)
        if u is None or v is None:
            assert u is None and v is None, field
        elif isinstance(u, tuple):
            for p, q in zip(u, v, strict=True):
                np.testing.assert_array_equal(p, q, err_msg=field)
        else:
            np.testing.assert_array_equal(u, v, err_msg=field)
