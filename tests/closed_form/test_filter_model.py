"""The default filter model of an IMU, term by term (closed forms of ``filter_model``)."""

from __future__ import annotations

import numpy as np

from ftnav.io.ins_scenario_file import filter_model
from ftnav.model.imu import ImuErrors, imu_preset
from ftnav.nav.units import deg_per_h, deg_per_sqrt_h, milli_g, standard_g

G = 9.80665


def test_table_1_gives_the_18_state_model_term_for_term():
    imu = imu_preset("seed001")
    m = filter_model(imu, 18)
    p = m.params
    np.testing.assert_allclose(p.gyro_psd, deg_per_sqrt_h(0.01) ** 2)
    np.testing.assert_allclose(p.gyro_markov_sigma, deg_per_h(0.1))
    np.testing.assert_allclose(p.gyro_markov_tau, 7200.0)
    np.testing.assert_allclose(p.accel_markov_sigma, standard_g(1e-4))
    np.testing.assert_allclose(p.accel_markov_tau, 1800.0)
    np.testing.assert_allclose(p.accel_psd, 0.0)
    # P0 of ε_b, ε_r, ∇: the constant drift, the Markov σ of each
    np.testing.assert_allclose(
        m.bias_sigma, np.repeat([deg_per_h(0.1), deg_per_h(0.1), standard_g(1e-4)], 3)
    )
    assert m.notes == ()


def test_15_states_random_constants_plus_random_walks_of_the_markov_terms():
    imu = imu_preset("seed001")
    m = filter_model(imu, 15)
    sg, tg, sa, ta = deg_per_h(0.1), 7200.0, standard_g(1e-4), 1800.0
    np.testing.assert_allclose(m.params.gyro_bias_rw_psd, 2 * sg**2 / tg)
    np.testing.assert_allclose(m.params.accel_bias_rw_psd, 2 * sa**2 / ta)
    np.testing.assert_allclose(m.bias_sigma[:3], np.hypot(deg_per_h(0.1), sg))
    np.testing.assert_allclose(m.bias_sigma[3:], sa)
    assert len(m.notes) == 1 and "random walks of PSD 2σ²/τ" in m.notes[0]


def test_accelerometer_constant_bias_and_scale_errors_are_represented():
    imu = ImuErrors(
        accel_bias_sd=milli_g(1.0),
        accel_bias=milli_g(0.5),
        accel_scale_sd=300e-6,
        accel_misalignment_sd=0.5e-3,
        accel_markov_sd=0.0,
        accel_markov_tau=600.0,
    )
    const = np.hypot(milli_g(1.0), milli_g(0.5))
    equiv = G * 0.5e-3  # g·max(σ_scale, σ_misalignment)
    m18 = filter_model(imu, 18)
    np.testing.assert_allclose(m18.params.accel_markov_sigma, np.hypot(const, equiv))
    np.testing.assert_allclose(m18.bias_sigma[6:], np.hypot(const, equiv))
    m15 = filter_model(imu, 15)
    np.testing.assert_allclose(m15.bias_sigma[3:], np.hypot(const, equiv))
    np.testing.assert_allclose(m15.params.accel_bias_rw_psd, 2 * equiv**2 / 600.0)
    assert any("scale factor and misalignment" in n for n in m18.notes)
    assert any("no accelerometer constant-bias state" in n for n in m18.notes)
    assert not any("constant-bias" in n for n in m15.notes)
