"""Measurement differencing of a first-order Markov measurement error (Bryson & Henrikson).

Oracles: the algebraic identity ``z* − H* x_k = w_{k−1} + n_k − ψ n_{k−1}`` (exact when
the process noise is zero), with and without a correction removed from the state between
the epochs (closed-loop feedback); the closed form of the differenced GNSS noise
``σ_b²(1 − ψ²) + (1 + ψ²) σ_n²`` with ``ψ = e^{−dt/τ}``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core import kalman as kf
from ftnav.sensors import Gnss


@pytest.mark.parametrize("with_shift", [False, True])
def test_differenced_measurement_leaves_only_the_driving_and_white_noise(with_shift):
    rng = np.random.default_rng(3)
    B, n, m = 5, 7, 4
    Phi = np.eye(n) + 0.2 * rng.standard_normal((B, n, n))
    H_prev, H = rng.standard_normal((B, m, n)), rng.standard_normal((B, m, n))
    psi = rng.uniform(0.5, 0.999, m)
    x_prev = rng.standard_normal((B, n)) * 10.0
    s = rng.standard_normal((B, n)) if with_shift else np.zeros((B, n))
    b_prev, w = rng.standard_normal((B, m)) * 25.0, rng.standard_normal((B, m))
    n_prev, n_now = rng.standard_normal((B, m)), rng.standard_normal((B, m))
    z_prev = kf.mv(H_prev, x_prev) + b_prev + n_prev
    x = kf.mv(Phi, x_prev - s)  # the correction s is removed, then the state propagates
    z = kf.mv(H, x) + psi * b_prev + w + n_now
    z_star, H_star = kf.differenced_measurement(
        z, H, z_prev, H_prev, Phi, psi, s if with_shift else None
    )
    np.testing.assert_allclose(
        z_star - kf.mv(H_star, x), w + n_now - psi * n_prev, rtol=1e-9, atol=1e-9
    )


def test_differenced_gnss_noise_and_factor_closed_form():
    g = Gnss(
        pos_markov_sigma_m=(25.0, 20.0, 30.0),
        pos_markov_tau_s=(100.0, 50.0, 200.0),
        vel_markov_sigma_m_s=0.05,
        vel_markov_tau_s=100.0,
        pos_white_sigma_m=1.0,
        vel_white_sigma_m_s=0.02,
        markov="difference",
        dt=1.0,
    )
    psi = np.exp(-1.0 / np.array([100.0, 50.0, 200.0, 100.0, 100.0, 100.0]))
    np.testing.assert_allclose(g.difference_factor, psi, rtol=1e-15)
    sb = np.array([25.0, 20.0, 30.0, 0.05, 0.05, 0.05])
    sn = np.array([1.0, 1.0, 1.0, 0.02, 0.02, 0.02])
    np.testing.assert_allclose(
        np.diag(g.R), sb**2 * (1 - psi**2) + (1 + psi**2) * sn**2, rtol=1e-13
    )
    assert g.private is None and Gnss(markov="augment").difference_factor is None
    assert Gnss().difference_factor is None
