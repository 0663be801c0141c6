"""Closed-form checks of the error model's noise, structure and interface (spec §8.3-§8.4).

Oracles: the stationary variance σ² of a first-order Gauss-Markov process (continuous
and discrete Lyapunov equations); the scalar discretization ``e^{−T/τ}``,
``σ²(1 − e^{−2T/τ})``; a random walk's ``Q = q T``; ``G q Gᵀ`` of the gyro noise,
``C q_g Cᵀ``; the 15-state and nav-frame variants as sub-structures of the 18-state F;
per-run calls for the batched model object.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov, solve_discrete_lyapunov

from ftnav.core import kalman as kf
from ftnav.core.discretize import markov_discrete
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.error_model import (
    STATES_15,
    STATES_18,
    ErrorModelParams,
    NavState,
    continuous_model,
    discrete_model,
)

DEG, HOUR, G0 = np.pi / 180.0, 3600.0, 9.80665
SIG_G = np.array([0.1, 0.2, 0.15]) * DEG / HOUR
SIG_A = np.array([1e-4, 2e-4, 1.5e-4]) * G0
TAU_G, TAU_A = np.array([7200.0, 3600.0, 5000.0]), np.array([1800.0, 900.0, 1200.0])
PARAMS = ErrorModelParams(
    gyro_psd=(0.01 * DEG / 60.0) ** 2,
    gyro_markov_sigma=SIG_G,
    gyro_markov_tau=TAU_G,
    accel_markov_sigma=SIG_A,
    accel_markov_tau=TAU_A,
    accel_psd=1e-8,
)
MARKOV = slice(12, 18)


def nav_batch(B=4, seed=0):
    rng = np.random.default_rng(seed)
    C = euler_to_dcm(rng.uniform(-1, 1, (B, 3)) * np.array([0.3, 0.5, 3.0]))
    f_n = np.column_stack([rng.uniform(-2, 2, (B, 2)), np.full(B, 9.8)])
    return NavState(
        L=rng.uniform(-1, 1, B),
        lam=rng.uniform(-3, 3, B),
        h=rng.uniform(0, 9000, B),
        v_enu=rng.uniform(-250, 250, (B, 3)),
        f_b=np.einsum("bji,bj->bi", C, f_n),
        C_bn=C,
    )


@pytest.mark.parametrize("method", ["van-loan", "series"])
def test_markov_states_are_stationary_at_sigma(method):
    """Discrete Lyapunov ``P = Φ P Φᵀ + Q_k`` on the Markov block gives σ² (and the block
    equals :func:`markov_discrete`)."""
    Phi, Q = discrete_model(*nav_batch(), PARAMS, 1.0, method)
    sigma = np.concatenate([SIG_G, SIG_A])
    a, var = markov_discrete(sigma, np.concatenate([TAU_G, TAU_A]), 1.0)
    for b in range(Phi.shape[0]):
        Pm, Qm = Phi[b, MARKOV, MARKOV], Q[b, MARKOV, MARKOV]
        np.testing.assert_allclose(np.diag(Pm), a, rtol=1e-14)
        np.testing.assert_allclose(np.diag(Qm), var, rtol=1e-9)
        P_inf = solve_discrete_lyapunov(Pm, Qm)
        np.testing.assert_allclose(np.diag(P_inf), sigma**2, rtol=1e-8)
        off = P_inf - np.diag(np.diag(P_inf))
        assert np.abs(off).max() < 1e-9 * sigma.min() ** 2


def test_markov_states_continuous_lyapunov():
    """``F P + P Fᵀ + G q Gᵀ = 0`` on the Markov block gives σ² (q = 2σ²/T)."""
    m = continuous_model(*nav_batch(1), PARAMS)
    P = solve_continuous_lyapunov(m.F[0, MARKOV, MARKOV], -m.GQGt[0, MARKOV, MARKOV])
    np.testing.assert_allclose(
        P, np.diag(np.concatenate([SIG_G, SIG_A]) ** 2), rtol=1e-12, atol=1e-30
    )


def test_gyro_and_accel_white_noise_mapping():
    """φ block of GqGᵀ is ``C diag(q_g) Cᵀ``; δv block ``C diag(q_v) Cᵀ``; no cross terms."""
    p = ErrorModelParams(gyro_psd=[1e-12, 2e-12, 3e-12], accel_psd=[1e-6, 4e-6, 9e-6])
    nav = nav_batch(3)
    GQGt = continuous_model(*nav, p).GQGt
    C = nav.C_bn
    np.testing.assert_allclose(
        GQGt[:, :3, :3], C @ np.diag(p.gyro_psd) @ np.swapaxes(C, 1, 2), rtol=1e-12, atol=1e-25
    )
    np.testing.assert_allclose(
        GQGt[:, 3:6, 3:6], C @ np.diag(p.accel_psd) @ np.swapaxes(C, 1, 2), rtol=1e-12, atol=1e-19
    )
    assert np.all(GQGt[:, :3, 3:] == 0.0) and np.all(GQGt[:, 6:12] == 0.0)


def test_15_state_is_the_18_state_without_markov_drift():
    """15 states (PSINS etm): ε takes ε_b's place (−C into φ), ∇ feeds δv with +C, and
    both are random walks: zero rows of F, ``Q_k = q T`` on their blocks."""
    p15 = ErrorModelParams(
        gyro_psd=PARAMS.gyro_psd,
        accel_psd=PARAMS.accel_psd,
        gyro_bias_rw_psd=1e-18,
        accel_bias_rw_psd=[1e-12, 2e-12, 3e-12],
        states=15,
    )
    nav = nav_batch()
    F18 = continuous_model(*nav, PARAMS).F
    F15 = continuous_model(*nav, p15).F
    keep = np.r_[0:12, 15:18]
    assert F15.shape == (4, 15, 15) and p15.names == STATES_15 and PARAMS.names == STATES_18
    np.testing.assert_array_equal(F15[:, :, :12], F18[:, keep][:, :, :12])
    np.testing.assert_array_equal(F15[:, :9, 12:], F18[:, :9, 15:])
    assert np.all(F15[:, 9:] == 0.0)
    T = 2.0
    Phi, Q = discrete_model(*nav, p15, T)
    np.testing.assert_allclose(
        Q[:, 9:12, 9:12], np.broadcast_to(1e-18 * T * np.eye(3), (4, 3, 3)), rtol=1e-10, atol=1e-30
    )
    np.testing.assert_allclose(
        Q[:, 12:, 12:],
        np.broadcast_to(np.diag([1e-12, 2e-12, 3e-12]) * T, (4, 3, 3)),
        rtol=1e-10,
        atol=1e-24,
    )
    np.testing.assert_array_equal(Phi[:, 9:, 9:], np.broadcast_to(np.eye(6), (4, 6, 6)))


def test_nav_bias_frame_uses_identity():
    p_nav = ErrorModelParams(
        gyro_psd=1e-12, gyro_markov_sigma=1e-7, accel_markov_sigma=1e-3, bias_frame="nav"
    )
    nav = nav_batch(2)
    F, G, _ = continuous_model(*nav, p_nav)
    F_body = continuous_model(*nav, ErrorModelParams()).F
    eye = np.broadcast_to(np.eye(3), (2, 3, 3))
    np.testing.assert_array_equal(F[:, :3, 9:12], -eye)
    np.testing.assert_array_equal(F[:, :3, 12:15], -eye)
    np.testing.assert_array_equal(F[:, 3:6, 15:18], eye)
    np.testing.assert_array_equal(G[:, :3, :3], -eye)
    np.testing.assert_array_equal(F[:, :9, :9], F_body[:, :9, :9])


def test_batched_model_feeds_predict():
    """The batched :func:`discrete_model` equals per-run calls and its (B, n, n) output
    goes straight into :func:`ftnav.core.kalman.predict`."""
    nav = nav_batch(5)
    Phi, Q = discrete_model(*nav, PARAMS, 1.0)
    assert Phi.shape == Q.shape == (5, 18, 18) and PARAMS.n == 18
    for b in range(5):
        Phi_b, Q_b = discrete_model(*(a[b] for a in nav), PARAMS, 1.0)
        np.testing.assert_allclose(Phi[b], Phi_b, rtol=1e-13, atol=1e-17)
        np.testing.assert_allclose(Q[b], Q_b, rtol=1e-12, atol=1e-30)
    P0 = np.diag(np.r_[[1e-6] * 3, [0.36] * 3, [2e-11] * 2, 25.0, [2e-13] * 6, [1e-6] * 3])
    pr = kf.predict(np.zeros((5, 18)), np.broadcast_to(P0, (5, 18, 18)), Phi, Q)
    ref = Phi[2] @ P0 @ Phi[2].T + Q[2]
    d = 1.0 / np.sqrt(np.diag(ref))  # compare in correlation units: entries span 1e-30..1
    np.testing.assert_allclose(d[:, None] * pr.P[2] * d, d[:, None] * ref * d, atol=1e-12)
    # runs × local filters: two batch axes
    nav2 = NavState(*(np.stack([a, a]) for a in nav))
    assert continuous_model(*nav2, PARAMS).F.shape == (2, 5, 18, 18)


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="states"):
        ErrorModelParams(states=16)
    with pytest.raises(ValueError, match="bias_frame"):
        ErrorModelParams(bias_frame="ecef")
    with pytest.raises(ValueError, match="gyro_markov_tau"):
        ErrorModelParams(gyro_markov_tau=0.0)
    with pytest.raises(ValueError, match="gyro_psd"):
        ErrorModelParams(gyro_psd=-1.0)
    with pytest.raises(ValueError, match="accel_psd"):
        ErrorModelParams(accel_psd=[1.0, 2.0])
    with pytest.raises(ValueError, match="method"):
        discrete_model(*nav_batch(3), PARAMS, 1.0, method="euler")
    nav = nav_batch(3)
    with pytest.raises(ValueError, match="T must be"):
        discrete_model(*nav, PARAMS, 0.0)
    with pytest.raises(ValueError, match="order"):
        discrete_model(*nav, PARAMS, 1.0, method="series", order=0)
    with pytest.raises(ValueError, match="do not broadcast"):
        continuous_model(nav.L[:2], nav.lam, nav.h, nav.v_enu, nav.f_b, nav.C_bn, PARAMS)
    with pytest.raises(ValueError, match="C_bn"):
        continuous_model(nav.L, nav.lam, nav.h, nav.v_enu, nav.f_b, nav.C_bn[..., :2], PARAMS)
    with pytest.raises(ValueError, match="method"):
        discrete_model(*nav, PARAMS, 1.0, method="exact")
