"""Closed-form checks of the discretization kernel (``ftnav.core.discretize``, spec §8.4).

Oracles: the double integrator worked by hand; the scalar Gauss-Markov process
(``e^{−T/τ}``, ``σ²(1 − e^{−2T/τ})``); Van Loan as the exact reference of the series
on the 18-state SINS model (spec §8.6 f); per-matrix calls for the batched ones.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core.discretize import markov_discrete, series, van_loan
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.error_model import ErrorModelParams, continuous_model

DEG, HOUR, G0 = np.pi / 180.0, 3600.0, 9.80665

#: S1 Table 1 noises (spec §8.3): ARW 0.01°/√h, gyro Markov 0.1°/h, 7200 s,
#: accelerometer Markov 1e-4 g, 1800 s
TABLE1 = ErrorModelParams(
    gyro_psd=(0.01 * DEG / 60.0) ** 2,
    gyro_markov_sigma=0.1 * DEG / HOUR,
    gyro_markov_tau=7200.0,
    accel_markov_sigma=1e-4 * G0,
    accel_markov_tau=1800.0,
)


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def cruise_model():
    """18-state (F, GqGᵀ) of an aircraft in cruise: 32°N, 5 km, 200 m/s heading 060°."""
    C = euler_to_dcm(np.array([2.0, -3.0, -60.0]) * DEG)
    v = np.array([200.0 * np.sin(60 * DEG), 200.0 * np.cos(60 * DEG), 0.0])
    f_b = C.T @ np.array([0.0, 0.0, 9.79])
    m = continuous_model(32 * DEG, 118 * DEG, 5000.0, v, f_b, C, TABLE1)
    return m.F, m.GQGt


@pytest.mark.parametrize("T", [0.01, 1.0, 7.5])
def test_van_loan_double_integrator(T):
    """F = [[0,1],[0,0]], white acceleration of PSD q: Φ = [[1,T],[0,1]],
    Q = q [[T³/3, T²/2], [T²/2, T]]."""
    q = 0.37
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    GQGt = np.array([[0.0, 0.0], [0.0, q]])
    Phi, Q = van_loan(F, GQGt, T)
    np.testing.assert_allclose(Phi, [[1.0, T], [0.0, 1.0]], rtol=0, atol=1e-12)
    Q_ref = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    np.testing.assert_allclose(Q, Q_ref, rtol=1e-12, atol=1e-12 * np.abs(Q_ref).max())


def test_series_double_integrator_is_exact_from_order_3():
    """The double integrator's series terminates: Φ is exact from order 1, Q from order 3;
    order 2 misses the T³/3 term."""
    T, q = 2.0, 0.5
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    GQGt = np.array([[0.0, 0.0], [0.0, q]])
    Q_ref = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    Phi, Q = series(F, GQGt, T, order=3)
    np.testing.assert_allclose(Phi, [[1.0, T], [0.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(Q, Q_ref, rtol=1e-14)
    _, Q2 = series(F, GQGt, T, order=2)
    assert Q2[0, 0] == 0.0


def test_series_against_van_loan_18_state():
    """Spec §8.6 (f): order 5 at T = 1 s gives Φ < 1e-10 and Q < 1e-4 relative
    (Frobenius) to Van Loan; orders 2 and 3 are clearly worse; at T = 0.1 s order 5
    is essentially exact."""
    F, GQGt = cruise_model()
    Phi_vl, Q_vl = van_loan(F, GQGt, 1.0)
    errs = {
        o: (rel(series(F, GQGt, 1.0, o)[0], Phi_vl), rel(series(F, GQGt, 1.0, o)[1], Q_vl))
        for o in (2, 3, 5)
    }
    assert errs[5][0] < 1e-10
    assert errs[5][1] < 1e-4
    assert errs[2][0] > 1e3 * errs[5][0] and errs[2][1] > 1e3 * errs[5][1]
    assert errs[2][1] > 0.1  # the first-order-ish Q misses the f^n×φ → δv noise terms
    assert errs[3][1] > 10 * errs[5][1]
    Phi_vl, Q_vl = van_loan(F, GQGt, 0.1)
    Phi_s, Q_s = series(F, GQGt, 0.1, 5)
    assert rel(Phi_s, Phi_vl) < 1e-14
    assert rel(Q_s, Q_vl) < 1e-8


def test_van_loan_phi_is_matrix_exponential():
    """Φ = e^{FT} (independent route: eigen-decomposition of a diagonalizable F)."""
    rng = np.random.default_rng(3)
    V = rng.standard_normal((4, 4))
    lam = np.array([-0.3, 0.1, -1.2, 0.5])
    F = V @ np.diag(lam) @ np.linalg.inv(V)
    Phi, Q = van_loan(F, np.eye(4), 0.7)
    np.testing.assert_allclose(
        Phi, V @ np.diag(np.exp(0.7 * lam)) @ np.linalg.inv(V), rtol=1e-11, atol=1e-12
    )
    np.testing.assert_array_equal(Q, Q.T)
    assert np.linalg.eigvalsh(Q).min() > 0.0


@pytest.mark.parametrize("fn", [van_loan, series])
def test_batched_equals_per_matrix(fn):
    """A (B, n, n) call equals B single calls; a shared GqGᵀ broadcasts; T per run."""
    rng = np.random.default_rng(7)
    F = 0.3 * rng.standard_normal((5, 6, 6))
    A = rng.standard_normal((6, 6))
    GQGt = A @ A.T
    T = np.array([0.1, 0.5, 1.0, 1.5, 2.0])
    Phi, Q = fn(F, GQGt, T)
    assert Phi.shape == Q.shape == (5, 6, 6)
    for b in range(5):
        Phi_b, Q_b = fn(F[b], GQGt, T[b])
        np.testing.assert_allclose(Phi[b], Phi_b, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(Q[b], Q_b, rtol=1e-13, atol=1e-14)
    # two batch axes (runs × local filters)
    Phi2, _ = fn(F.reshape(5, 1, 6, 6), np.broadcast_to(GQGt, (5, 3, 6, 6)), 1.0)
    assert Phi2.shape == (5, 3, 6, 6)
    np.testing.assert_allclose(Phi2[:, 2], fn(F, GQGt, 1.0)[0], rtol=1e-13, atol=1e-14)


def test_markov_discrete_closed_form():
    sigma, tau, T = np.array([0.5, 2.0]), np.array([100.0, 3.0]), 1.5
    a, var = markov_discrete(sigma, tau, T)
    np.testing.assert_allclose(a, np.exp(-T / tau), rtol=1e-15)
    np.testing.assert_allclose(var, sigma**2 * (1.0 - np.exp(-2.0 * T / tau)), rtol=1e-13)
    np.testing.assert_allclose(var / (1.0 - a**2), sigma**2, rtol=1e-13)  # stationary σ²
    a, var = markov_discrete(1.0, np.inf, 1.0)  # random constant
    assert a == 1.0 and var == 0.0


def test_markov_discrete_equals_van_loan_scalar():
    """The scalar Gauss-Markov F = −1/τ, q = 2σ²/τ discretized by Van Loan."""
    sigma, tau, T = 0.2, 50.0, 3.0
    Phi, Q = van_loan(np.array([[-1.0 / tau]]), np.array([[2.0 * sigma**2 / tau]]), T)
    a, var = markov_discrete(sigma, tau, T)
    assert Phi[0, 0] == pytest.approx(a, rel=1e-14)
    assert Q[0, 0] == pytest.approx(var, rel=1e-12)


def test_bad_inputs_raise():
    F = np.zeros((3, 3))
    with pytest.raises(ValueError, match="F must be"):
        van_loan(np.zeros((3, 2)), F, 1.0)
    with pytest.raises(ValueError, match="GQGt must be"):
        series(F, np.zeros((2, 2)), 1.0)
    with pytest.raises(ValueError, match="T must be"):
        van_loan(F, F, 0.0)
    with pytest.raises(ValueError, match="order"):
        series(F, F, 1.0, order=0)
    with pytest.raises(ValueError, match="tau"):
        markov_discrete(1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="T must be"):
        markov_discrete(1.0, 1.0, -1.0)
