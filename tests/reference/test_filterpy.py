"""Centralized filter against an independent implementation: FilterPy's ``KalmanFilter``.

FilterPy processes the stacked measurement ``z = [z_1; …; z_N]`` with
``H = [H_1; …; H_N]`` and ``R = blkdiag(R_i)`` in one update (Joseph form with an
explicit ``S⁻¹``); ftnav processes the sensors one after another (spec §6.1: equal
because R is block-diagonal).  Agreement to 1e-9 relative checks both.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import block_diag

from ftnav.fusion.centralized import CentralizedFilter
from ftnav.fusion.registry import method_config
from ftnav.model.scenario import Scenario
from ftnav.model.system import Epoch, LinearModel, Sensor
from ftnav.sim.linear import simulate

filterpy_kalman = pytest.importorskip("filterpy.kalman")

STEPS = 300


def random_spd(rng, n, scale=1.0):
    A = rng.standard_normal((n, n))
    return scale * (A @ A.T / n + 0.1 * np.eye(n))


@pytest.fixture(scope="module")
def scenario():
    rng = np.random.default_rng(2718)
    n, dims = 5, [2, 1, 3]
    ortho, _ = np.linalg.qr(rng.standard_normal((n, n)))
    F = 0.99 * ortho + 0.02 * rng.standard_normal((n, n))
    Q = random_spd(rng, n, 0.05)
    model = LinearModel(
        tuple(f"s{j}" for j in range(n)), F, Q, rng.standard_normal(n), random_spd(rng, n, 20.0), Q
    )
    sensors = []
    for i, m in enumerate(dims):
        R = random_spd(rng, m, 0.5)
        sensors.append(
            Sensor(f"z{i}", rng.standard_normal((m, n)), R, R, every=1 + (i == 2))
        )  # sensor 3 at half rate
    return Scenario(name="filterpy", dt=1.0, steps=STEPS, model=model, sensors=tuple(sensors))


def filterpy_run(sc: Scenario, z: list[np.ndarray], available: np.ndarray):
    """One run with FilterPy; (K, n) means and (K, n, n) covariances."""
    n = sc.model.n
    dims = [s.dim for s in sc.sensors]
    f = filterpy_kalman.KalmanFilter(dim_x=n, dim_z=sum(dims))
    f.x, f.P, f.F, f.Q = sc.model.x0.copy(), sc.model.P0.copy(), sc.model.F, sc.model.Q
    xs, Ps = [], []
    for k in range(STEPS):
        f.predict()
        use = [i for i in range(len(dims)) if available[k, i]]
        H = np.vstack([sc.sensors[i].H for i in use])
        R = block_diag(*[sc.sensors[i].R for i in use])
        f.update(np.concatenate([z[i][k] for i in use]), R=R, H=H)
        xs.append(np.asarray(f.x).copy())
        Ps.append(np.asarray(f.P).copy())
    return np.array(xs), np.array(Ps)


def ftnav_run(sc: Scenario, sim):
    filt = CentralizedFilter(sc.system(), method_config("centralized", name="ckf"))
    stream = sim.stream
    state = filt.init(stream.batch)
    xs, Ps = [], []
    for k in range(1, STEPS + 1):
        z = tuple(zi[:, k - 1] for zi in stream.z)
        epoch = Epoch(k, z, stream.available[:, k - 1], stream.labels[k - 1])
        state, out = filt.step(state, epoch)
        xs.append(out.x)
        Ps.append(out.P)
    return np.stack(xs, 1), np.stack(Ps, 1)


def test_centralized_equals_filterpy(scenario):
    sim = simulate(scenario, 1, seed=1)
    x, P = ftnav_run(scenario, sim)
    x_ref, P_ref = filterpy_run(scenario, [z[0] for z in sim.stream.z], sim.stream.available[0])
    np.testing.assert_allclose(x[0], x_ref, rtol=1e-9, atol=1e-9 * np.abs(x_ref).max())
    np.testing.assert_allclose(P[0], P_ref, rtol=1e-9, atol=1e-9 * np.abs(P_ref).max())


def test_batched_runs_equal_single_runs(scenario):
    """Run i of a batch of 3 equals run i simulated and filtered alone (style §5)."""
    B, seed = 3, 5
    sim = simulate(scenario, B, seed)
    x, P = ftnav_run(scenario, sim)
    for b in range(B):
        one = simulate(scenario, 1, seed, first_run=b)
        # same random stream; BLAS may round a 1-row and a 3-row product differently
        np.testing.assert_allclose(one.truth.states[0], sim.truth.states[b], rtol=1e-12, atol=1e-12)
        for z1, z in zip(one.stream.z, sim.stream.z, strict=True):
            np.testing.assert_allclose(z1[0], z[b], rtol=1e-12, atol=1e-12)
        x1, P1 = ftnav_run(scenario, one)
        np.testing.assert_allclose(x1[0], x[b], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(P1[0], P[b], rtol=1e-12, atol=1e-12)
        x_ref, P_ref = filterpy_run(scenario, [z[b] for z in sim.stream.z], sim.stream.available[b])
        np.testing.assert_allclose(x[b], x_ref, rtol=1e-9, atol=1e-9 * np.abs(x_ref).max())
        np.testing.assert_allclose(P[b], P_ref, rtol=1e-9, atol=1e-9 * np.abs(P_ref).max())
