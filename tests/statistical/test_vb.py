"""Variational-Bayes adaptive measurement noise (spec §7.4 a-f).

Statistical problem for (b)-(e): two independent random walks
``x_k = x_{k−1} + w``, ``w ~ N(0, 0.05 I)``, both measured directly
(``H = I``) with true ``R = diag(4, 0.25)``; the VB prior is deliberately wrong
(``β₀/α₀ = 1``, ``α₀ = 1``), ρ = 0.99, so the effective memory is
``1/(1 − ρ) = 100`` epochs.

Bounds.  The estimate over epochs 500-1000 averages ~5 memory lengths of 20
runs, i.e. ~100 nearly independent windows of ~100 squared residuals each; the
relative standard error of ``R̂`` per window is ≈ ``√(2/100)`` = 14%, so the
mean of 100 windows has a ≈1.4% standard error.  The ±10% bound of (b) is
therefore ~7 standard errors wide: it can only fail through a bias, which is
what it is meant to catch.  The literal variant's bias (§7.3) is
``E[β-increment] = R + 2 H P⁻ Hᵀ`` instead of ``R``: with the steady-state prior
variance ``P⁻ = (q + √(q² + 4qR))/2`` (q = 0.05) that is +24% and +111% for the
two components, so "> 20%" holds with margin on both.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core import kalman as kf
from ftnav.core import vb
from ftnav.engine import navigation_model
from ftnav.engine.driver import run as run_engine
from ftnav.fusion import registry
from ftnav.model.scenario import Scenario
from ftnav.model.system import LinearModel, Sensor
from ftnav.sim.linear import simulate

R_TRUE = np.array([4.0, 0.25])
Q_WALK = 0.05
RHO = 0.99


def random_walk_vb(*, variant="sarkka", iterations=3, steps=1000, runs=20, step_at=None, seed=0):
    """VB-KF on the 2-state random walk; returns R̂ = β/α of every epoch, (runs, steps, 2).

    ``step_at``: the noise variance is multiplied by 9 from that epoch on (0-based).
    """
    rng = np.random.default_rng(seed)
    n = 2
    truth = rng.standard_normal((runs, n))
    x, P = np.zeros((runs, n)), np.broadcast_to(np.eye(n), (runs, n, n)).copy()
    alpha, beta = np.ones((runs, n)), np.ones((runs, n))
    F, Q, H = np.eye(n), Q_WALK * np.eye(n), np.eye(n)
    R_hat = np.empty((runs, steps, n))
    for k in range(steps):
        truth = truth + np.sqrt(Q_WALK) * rng.standard_normal((runs, n))
        var = R_TRUE * (9.0 if step_at is not None and k >= step_at else 1.0)
        z = truth + np.sqrt(var) * rng.standard_normal((runs, n))
        x, P = kf.predict(x, P, F, Q)
        alpha, beta = vb.vb_predict(alpha, beta, RHO)
        up, alpha, beta, _ = vb.vb_update(
            x, P, z, H, alpha, beta, iterations=iterations, variant=variant
        )
        x, P = up.x, up.P
        R_hat[:, k] = beta / alpha
    return R_hat


@pytest.fixture(scope="module")
def stationary():
    return random_walk_vb()


def test_large_prior_count_and_no_forgetting_is_the_standard_kf():
    """§7.4 (a): ρ = 1, α₀ = 1e12, β₀ = α₀ R -> the plain KF within 1e-9 relative, over
    200 steps of a 4-state / 2-measurement problem with a full (non-diagonal) P.

    Data follow the model, so each step adds ≈ R/2 to β and ½ to α and R̂ stays within
    ~1e-11 of R; inconsistent data (residuals ≫ √R) would drift R̂ by ~1e-9 in 200 steps.
    """
    rng = np.random.default_rng(1)
    n, m, B = 4, 2, 3
    F = 0.95 * np.linalg.qr(rng.standard_normal((n, n)))[0]  # stable: |x| stays O(1)
    Q = 0.1 * np.eye(n)
    H = rng.standard_normal((m, n))
    R_diag = np.array([0.5, 2.0])
    R = np.diag(R_diag)
    x_v = x_k = np.zeros((B, n))
    P_v = P_k = np.broadcast_to(5.0 * np.eye(n), (B, n, n)).copy()
    alpha = np.full((B, m), 1e12)
    beta = alpha * R_diag
    truth = rng.standard_normal((B, n)) * np.sqrt(5.0)
    for _ in range(200):
        truth = truth @ F.T + rng.standard_normal((B, n)) * np.sqrt(0.1)
        z = truth @ H.T + rng.standard_normal((B, m)) * np.sqrt(R_diag)
        x_k, P_k = kf.predict(x_k, P_k, F, Q)
        up_k = kf.update(x_k, P_k, z, H, R)
        x_k, P_k = up_k.x, up_k.P
        x_v, P_v = kf.predict(x_v, P_v, F, Q)
        alpha, beta = vb.vb_predict(alpha, beta, 1.0)
        up_v, alpha, beta, R_used = vb.vb_update(x_v, P_v, z, H, alpha, beta)
        x_v, P_v = up_v.x, up_v.P
        np.testing.assert_allclose(x_v, x_k, rtol=1e-9, atol=1e-9 * np.abs(x_k).max())
        np.testing.assert_allclose(P_v, P_k, rtol=1e-9, atol=1e-9 * np.abs(P_k).max())
        np.testing.assert_allclose(up_v.nis, up_k.nis, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(R_used, np.broadcast_to(R, R_used.shape), rtol=1e-9, atol=1e-12)


def test_stationary_noise_is_estimated_within_ten_percent(stationary):
    """§7.4 (b): mean R̂ over epochs 500-1000 within ±10% of truth, per component."""
    mean = stationary[:, 500:].mean((0, 1))
    np.testing.assert_allclose(mean, R_TRUE, rtol=0.10)
    # the per-run spread supports the docstring's ~1.4% standard error claim
    se = stationary[:, 500:].mean(1).std(0, ddof=1) / np.sqrt(stationary.shape[0]) / R_TRUE
    assert (se < 0.10 / 3).all()


def test_variance_step_is_tracked_within_three_memory_lengths():
    """§7.4 (c): after a ×9 variance step the run-averaged R̂ reaches 80% of the new value
    within 3/(1 − ρ) = 300 epochs (and it started below 80%)."""
    step = 500
    R_hat = random_walk_vb(step_at=step, runs=10, seed=3).mean(0)  # (steps, 2)
    target = 0.8 * 9.0 * R_TRUE
    assert (R_hat[step - 1] < target).all()
    horizon = int(round(3.0 / (1.0 - RHO)))
    reached = (R_hat[step : step + horizon] >= target).any(0)
    assert reached.all(), R_hat[step + horizon - 1]


def test_more_iterations_change_little(stationary):
    """§7.4 (d): 3 -> 10 fixed-point iterations changes R̂ by < 1% at every epoch of every
    run in the evaluation window of (b), epochs 500-1000 (same data: same seed).

    Measured: max 0.34% there.  During the start-up transient from the wrong prior the
    difference is larger (max 3.2% over epochs 100-200, 1.6% over 200-300), so the
    bound is a steady-state property.
    """
    ten = random_walk_vb(iterations=10)
    rel = np.abs(ten / stationary - 1.0)
    assert rel[:, 500:].max() < 0.01
    assert rel[:, 100:].mean() < 0.01


def test_literal_variant_over_estimates(stationary):
    """§7.4 (e): S2's printed eq. 30 (prior residual, no iteration) is biased by > +20%."""
    literal = random_walk_vb(variant="literal")[:, 500:].mean((0, 1))
    assert (literal > 1.2 * R_TRUE).all(), literal
    assert (literal > 1.2 * stationary[:, 500:].mean((0, 1))).all()


# ---------------------------------------------------------------------------
# (f) distributed filter with VB locals = CKF with the logged R̂
# ---------------------------------------------------------------------------


def _scenario(steps):
    rng = np.random.default_rng(17)
    n = 3
    F = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 0.9]])
    Q = np.diag([0.05, 0.02, 0.01])
    model = LinearModel(("p", "v", "a"), F, Q, np.zeros(n), np.diag([10.0, 4.0, 1.0]), Q)
    specs = [
        (np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), np.diag([2.0, 0.5]), np.diag([8.0, 0.3])),
        (np.array([[1.0, 0.0, 0.0]]), np.eye(1), np.eye(1) * 3.0),
        (rng.standard_normal((2, n)), np.diag([1.0, 1.0]), np.diag([1.0, 1.0])),
    ]
    sensors = tuple(
        Sensor(f"z{i}", H, R, R_true, every=1 + (i == 2)) for i, (H, R, R_true) in enumerate(specs)
    )
    return Scenario(name="vb", dt=1.0, steps=steps, model=model, sensors=sensors)


def _ckf_with_logged_noise(sc, sim, R_hat):
    """Plain centralized KF (kernel calls only) with sensor i's R replaced by the logged
    diagonal R̂_i at every epoch; skips unscheduled measurements."""
    B, K = sim.truth.states.shape[:2]
    x = np.broadcast_to(sc.model.x0, (B, sc.model.n)).copy()
    P = np.broadcast_to(sc.model.P0, (B, sc.model.n, sc.model.n)).copy()
    xs, Ps = [], []
    for k in range(K):
        x, P = kf.predict(x, P, sc.model.F, sc.model.Q)
        for i, s in enumerate(sc.sensors):
            if not sim.stream.available[0, k, i]:
                continue
            R = np.einsum("bi,ij->bij", R_hat[i][:, k], np.eye(s.dim))
            up = kf.update(x, P, sim.stream.z[i][:, k], s.H, R)
            x, P = up.x, up.P
        xs.append(x)
        Ps.append(P)
    return np.stack(xs, 1), np.stack(Ps, 1)


@pytest.mark.parametrize("increment", ["direct", "difference"])
@pytest.mark.parametrize("local_scale", [(1.0, 1.0), (4.0, 3.0)], ids=["same", "Qx4,P0x3"])
def test_distributed_vb_equals_ckf_with_logged_noise(increment, local_scale):
    """§6.4 / §7.4 (f): the fused result equals a CKF run with R = blkdiag(R̂_i), R̂_i the
    noise each VB local used at that epoch (``Trace.R_hat``), within 1e-9."""
    sc = _scenario(300)
    sim = simulate(sc, 3, seed=8)
    system = sc.system()
    q, p = local_scale
    filt = registry.build(
        system,
        registry.method_config("distributed", name="vb", noise="vb", increment=increment),
        local_Q_scale=[q] * 3,
        local_P0_scale=[p] * 3,
    )
    res = run_engine(navigation_model(sc, system), sim.stream, {"vb": filt}, sc.steps)["vb"]
    # the noise really adapted (otherwise the test would not need the logged R̂)
    assert np.abs(res.R_hat[0][:, -1] / np.diag(sc.sensors[0].R) - 1.0).max() > 0.2
    x_ref, P_ref = _ckf_with_logged_noise(sc, sim, res.R_hat)
    scale = max(1.0, float(np.abs(x_ref).max()))
    np.testing.assert_allclose(res.x, x_ref, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(
        res.P_diag,
        np.diagonal(P_ref, axis1=-2, axis2=-1),
        rtol=1e-9,
        atol=1e-9 * max(1.0, float(np.abs(P_ref).max())),
    )
