"""Seeded statistics of the simulated aiding-sensor errors (spec §8.4, §9.7 e).

Bounds.  For a stationary AR(1) sequence ``b_{k+1} = ρ b_k + w`` (``ρ = e^{−dt/τ}``)
with known zero mean, the pooled ``σ̂² = mean(b²)`` over N samples (independent
runs/axes, each a long series) has ``var(σ̂²) ≈ (2σ⁴/N)(1 + ρ²)/(1 − ρ²)``, so
``SE(σ̂) ≈ σ √((1 + ρ²)/(2N(1 − ρ²)))``; we require ``|σ̂ − σ| < 5 SE``.  For white
noise (ρ = 0) and the per-run random constants this is ``σ/√(2N)``.

The sample autocorrelation at lag h = τ/dt, ``r = Σ b_k b_{k+h} / Σ b_k²``, has
Bartlett variance ``(1/N)[(1 + ρ²)(1 − ρ^{2h})/(1 − ρ²) − 2hρ^{2h}] ≈ 0.594 τ/(dt N)``;
over n series of 100τ each that is SE ≈ 0.077/√n.  Spec §9.7 e asks for
``|r − e⁻¹| < 0.05``: with n = 96 (GNSS) or 32 (DNS) series that is ≥ 3.7 SE.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.nav.attitude import euler_to_quat
from ftnav.sensors import (
    AidTruth,
    AnalyticTerrain,
    Barometer,
    Doppler,
    Gnss,
    StarTracker,
    Tan,
)

SEED = 20240


def straight_truth(K: int, dt: float = 1.0, speed: float = 100.0) -> AidTruth:
    """Level flight due north at 32°N, 118°E, 1000 m."""
    p = np.tile([np.radians(32.0), np.radians(118.0), 1000.0], (K, 1))
    v = np.tile([0.0, speed, 0.0], (K, 1))
    q = np.tile(euler_to_quat(np.zeros(3)), (K, 1))
    return AidTruth(dt * np.arange(K), p, v, q)


def sigma_se(sigma: float, rho: float, n: int) -> float:
    return sigma * np.sqrt((1.0 + rho**2) / (2.0 * n * (1.0 - rho**2)))


def acf(x: np.ndarray, lag: int) -> float:
    """Pooled zero-mean autocorrelation at ``lag`` over axis 1 of (runs, K, n)."""
    return float(np.sum(x[:, :-lag] * x[:, lag:]) / np.sum(x * x))


def check_markov(x: np.ndarray, sigma: float, tau: float, dt: float) -> None:
    rho = np.exp(-dt / tau)
    s = np.sqrt(np.mean(x**2))
    assert abs(s - sigma) < 5.0 * sigma_se(sigma, rho, x.size), (s, sigma)
    r = acf(x, int(round(tau / dt)))
    assert abs(r - np.exp(-1.0)) < 0.05, r


def test_gnss_markov_and_white_statistics():
    """GNSS position/velocity Gauss-Markov σ and τ (per axis σ), white σ; 16 runs × 100τ."""
    g = Gnss(
        pos_markov_sigma_m=(25.0, 10.0, 40.0),
        vel_markov_sigma_m_s=0.05,
        pos_markov_tau_s=100.0,
        vel_markov_tau_s=100.0,
        pos_white_sigma_m=1.0,
        vel_white_sigma_m_s=0.02,
    )
    err = g.simulate_errors(straight_truth(10_000), SEED, range(16), stream=0)
    assert err.coloured.shape == (16, 10_000, 6) and err.constants.shape == (16, 0)
    for axis, sigma in enumerate(g.pos_markov_sigma_m + g.vel_markov_sigma_m_s):
        x = err.coloured[:, :, axis : axis + 1]
        rho = np.exp(-1.0 / 100.0)
        assert abs(np.sqrt(np.mean(x**2)) - sigma) < 5.0 * sigma_se(sigma, rho, x.size)
    # τ pooled over the 6 axes after normalizing by σ (96 series)
    scaled = err.coloured / np.array(g.pos_markov_sigma_m + g.vel_markov_sigma_m_s)
    check_markov(scaled, 1.0, 100.0, 1.0)
    for sl, sigma in ((slice(0, 3), 1.0), (slice(3, 6), 0.02)):
        w = err.white[:, :, sl]
        assert abs(np.sqrt(np.mean(w**2)) - sigma) < 5.0 * sigma / np.sqrt(2 * w.size)
        assert abs(acf(w, 1)) < 5.0 / np.sqrt(w.size)


def test_dns_markov_and_scale_statistics():
    """Doppler δV_D (σ 0.278 m/s, τ 300 s) along track, white σ, δK random constants."""
    d = Doppler()
    err = d.simulate_errors(straight_truth(30_000), SEED, range(32), stream=3)
    assert np.all(err.coloured[..., 0] == 0.0)  # along track = north here
    check_markov(err.coloured[..., 1:], 0.278, 300.0, 1.0)
    w = err.white
    assert abs(np.sqrt(np.mean(w**2)) - 0.05) < 5.0 * 0.05 / np.sqrt(2 * w.size)
    dK = d.simulate_errors(straight_truth(1), SEED, range(4000), stream=3).constants
    assert dK.shape == (4000, 1)
    assert abs(np.sqrt(np.mean(dK**2)) - 0.0025) < 5.0 * 0.0025 / np.sqrt(2 * dK.size)
    # one δK per run, the same as in the long simulation
    np.testing.assert_array_equal(dK[:32], err.constants)


def test_baro_bias_statistics():
    """Barometer Markov bias σ and τ (an order-of-magnitude shorter check: τ = 50 s)."""
    b = Barometer(bias_sigma_m=10.0, bias_tau_s=50.0)
    err = b.simulate_errors(straight_truth(5_000), SEED, range(32), stream=5)
    check_markov(err.coloured, 10.0, 50.0, 1.0)


TERRAIN = AnalyticTerrain.random(np.random.default_rng(0), 32.0, 118.0)
SENSORS = {
    "gnss": Gnss(),
    "gnss-augment": Gnss(markov="augment"),
    "tan": Tan(TERRAIN),
    "dns": Doppler(),
    "cns": StarTracker(),
    "cns-euler": StarTracker(form="euler"),
    "ads": Barometer(bias_sigma_m=10.0),
}


@pytest.mark.parametrize("key", list(SENSORS))
def test_run_streams_do_not_depend_on_the_batch(key):
    """Runs range(3, 5) drawn alone equal rows 3, 4 of range(0, 5); streams differ."""
    sensor = SENSORS[key]
    truth = straight_truth(50)
    full = sensor.simulate_errors(truth, SEED, range(0, 5), stream=2)
    part = sensor.simulate_errors(truth, SEED, range(3, 5), stream=2)
    for a, b in zip(full, part, strict=True):
        np.testing.assert_array_equal(a[3:5], b)
    other = sensor.simulate_errors(truth, SEED, range(0, 5), stream=4)
    assert not np.array_equal(full.white, other.white)
    assert not np.array_equal(full.white[0], full.white[1])  # runs differ
