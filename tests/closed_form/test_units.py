"""Datasheet unit helpers against hand-computed numbers (spec §8.3, §8.4).

Oracles: the definitions 1° = π/180 rad, 1 h = 3600 s, √(1 h) = 60 √s,
g₀ = 9.80665 m/s² (standard gravity, CGPM 1901), 1 ft = 0.3048 m,
1 kn = 1852 m/h; spec §8.3 for the S1 Table 1 numbers and q = 2σ²/τ.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ftnav.model.imu import IMU_PRESETS, ImuErrors, imu_preset
from ftnav.nav import units as u

D = math.pi / 180.0
G0 = 9.80665


@pytest.mark.parametrize(
    ("func", "x", "expected"),
    [
        (u.deg_per_h, 1.0, math.pi / 180.0 / 3600.0),
        (u.deg_per_h, 0.1, 4.84813681109536e-07),  # 0.1·π/648000
        (u.deg_per_s, 1.0, math.pi / 180.0),
        (u.deg_per_sqrt_h, 0.01, 0.01 * math.pi / 180.0 / 60.0),
        (u.deg_per_h_per_sqrt_hz, 60.0, math.pi / 180.0 / 60.0),  # 60 °/h/√Hz = 1 °/√h
        (u.standard_g, 1e-4, 9.80665e-4),
        (u.milli_g, 1.0, 9.80665e-3),
        (u.micro_g, 100.0, 9.80665e-4),
        (u.micro_g_per_sqrt_hz, 50.0, 50 * 9.80665e-6),
        (u.m_per_s_per_sqrt_h, 0.06, 0.001),
        (u.ppm, 250.0, 2.5e-4),
        (u.percent, 0.25, 2.5e-3),
        (u.arcsec, 300.0, 300.0 * math.pi / 648000.0),
        (u.arcsec, 30.0, 1.454441043328608e-04),  # S1 initial δL, ≈ 925 m on the meridian
        (u.arcmin, 60.0, math.pi / 180.0),
        (u.m_per_h, 1000.0, 0.2777777777777778),  # S1 Doppler Markov σ, spec §8.3
        (u.hours, 2.0, 7200.0),
    ],
)
def test_conversion_to_si(func, x, expected):
    assert func(x) == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize(
    ("to_si", "from_si"),
    [
        (u.deg_per_h, u.to_deg_per_h),
        (u.deg_per_s, u.to_deg_per_s),
        (u.deg_per_sqrt_h, u.to_deg_per_sqrt_h),
        (u.milli_g, u.to_milli_g),
        (u.micro_g, u.to_micro_g),
        (u.m_per_s_per_sqrt_h, u.to_m_per_s_per_sqrt_h),
        (u.ppm, u.to_ppm),
        (u.arcsec, u.to_arcsec),
        (u.arcmin, u.to_arcmin),
        (u.m_per_h, u.to_m_per_h),
    ],
)
def test_inverse_converters_round_trip_arrays(to_si, from_si):
    x = np.array([[-3.0, 0.0, 0.1], [1e-6, 42.0, 7e3]])
    y = from_si(to_si(x))
    assert isinstance(y, np.ndarray) and y.shape == x.shape
    np.testing.assert_allclose(y, x, rtol=1e-14, atol=0.0)


def test_standard_gravity_is_the_unit_g_not_local_gravity():
    assert u.STANDARD_GRAVITY == 9.80665
    assert u.milli_g(1.0) == u.standard_g(1e-3)


def test_white_noise_psd_sigma():
    # q = 4e-6 unit²·s sampled at dt = 0.01 s: σ = √(4e-6/0.01) = 0.02
    assert u.psd_to_sigma(4e-6, 0.01) == pytest.approx(0.02, rel=1e-15)
    assert u.sigma_to_psd(0.02, 0.01) == pytest.approx(4e-6, rel=1e-15)
    psd = np.array([0.0, 1e-12, 3.5, 2e4])
    np.testing.assert_allclose(u.sigma_to_psd(u.psd_to_sigma(psd, 0.005), 0.005), psd, rtol=1e-14)
    # ARW N (rad/√s) is √q: the rate noise sampled at dt has σ = N/√dt
    arw = u.deg_per_sqrt_h(0.01)
    assert u.psd_to_sigma(arw**2, 0.01) == pytest.approx(arw / 0.1, rel=1e-14)


def test_markov_q_is_two_sigma_squared_over_tau():
    assert u.markov_q(2.0, 4.0) == 2.0
    # S1 gyro Markov: σ = 0.1 °/h, T_g = 7200 s (spec §8.3)
    s = 0.1 * D / 3600.0
    assert u.markov_q(u.deg_per_h(0.1), 7200.0) == pytest.approx(2 * s * s / 7200.0, rel=1e-14)
    np.testing.assert_allclose(u.markov_q([1.0, 3.0], [2.0, 9.0]), [1.0, 2.0], rtol=1e-15)


@pytest.mark.parametrize(
    ("text", "family", "expected"),
    [
        ("0.1 deg/h", "angular_rate", 0.1 * D / 3600),
        ("0.1°/hr", "angular_rate", 0.1 * D / 3600),
        ("-10 deg/h", "angular_rate", -10 * D / 3600),
        ("2e-3 rad/s", "angular_rate", 2e-3),
        ("1 deg/s", "angular_rate", D),
        ("0.01 deg/sqrt(h)", "angle_random_walk", 0.01 * D / 60),
        ("0.01 °/√h", "angle_random_walk", 0.01 * D / 60),
        ("0.01 deg/rt(hr)", "angle_random_walk", 0.01 * D / 60),
        ("0.6 deg/h/sqrt(Hz)", "angle_random_walk", 0.01 * D / 60),
        ("3e-6 rad/sqrt(s)", "angle_random_walk", 3e-6),
        ("100 ug", "acceleration", 100 * 9.80665e-6),
        ("100 µg", "acceleration", 100 * 9.80665e-6),
        ("1e-4 g", "acceleration", 9.80665e-4),
        ("1 mg", "acceleration", 9.80665e-3),
        ("0.5 m/s^2", "acceleration", 0.5),
        ("0.5 m/s²", "acceleration", 0.5),
        ("0.06 m/s/sqrt(h)", "velocity_random_walk", 0.001),
        ("50 ug/sqrt(Hz)", "velocity_random_walk", 50 * 9.80665e-6),
        ("0.06 ft/s/sqrt(h)", "velocity_random_walk", 0.001 * 0.3048),
        ("0.25 %", "dimensionless", 0.0025),
        ("250 ppm", "dimensionless", 2.5e-4),
        ("0.003", "dimensionless", 0.003),
        ("300 arcsec", "angle", 300 * D / 3600),
        ('300"', "angle", 300 * D / 3600),
        ("10 arcmin", "angle", 10 * D / 60),
        ("0.5 mrad", "angle", 5e-4),
        ("2 deg", "angle", 2 * D),
        ("7200 s", "time", 7200.0),
        ("2 h", "time", 7200.0),
        ("30 min", "time", 1800.0),
        ("25 m", "length", 25.0),
        ("1.5 km", "length", 1500.0),
        ("1000 m/h", "velocity", 1000 / 3600),
        ("0.05 m/s", "velocity", 0.05),
        ("36 km/h", "velocity", 10.0),
        ("1 kn", "velocity", 1852 / 3600),
        ("0", "angle_random_walk", 0.0),
        (0, "acceleration", 0.0),
    ],
)
def test_parse_quantity_each_family(text, family, expected):
    assert u.parse_quantity(text, family, "x") == pytest.approx(expected, rel=1e-14, abs=0.0)


def test_parse_quantity_matches_converters():
    assert u.parse_quantity("0.1 deg/h", "angular_rate", "f") == u.deg_per_h(0.1)
    assert u.parse_quantity("100 ug", "acceleration", "f") == u.micro_g(100.0)


def test_seed001_preset_is_s1_table_1():
    """Spec §8.3: 0.1 °/h constant and Markov drift, T_g 7200 s, ARW 0.01 °/√h, 1e-4 g, 1800 s."""
    p = imu_preset("seed001")
    ones = np.ones(3)
    np.testing.assert_allclose(p.gyro_bias_sd, 0.1 * D / 3600 * ones, rtol=1e-15)
    np.testing.assert_allclose(p.gyro_markov_sd, 0.1 * D / 3600 * ones, rtol=1e-15)
    np.testing.assert_array_equal(p.gyro_markov_tau, 7200.0 * ones)
    # q_g = (0.01·π/180/60)² rad²/s (spec §8.3 [A])
    np.testing.assert_allclose(p.gyro_arw**2, (0.01 * D / 60) ** 2 * ones, rtol=1e-14)
    np.testing.assert_allclose(p.accel_markov_sd, 1e-4 * G0 * ones, rtol=1e-15)
    np.testing.assert_array_equal(p.accel_markov_tau, 1800.0 * ones)
    for name in (
        "gyro_bias",
        "gyro_scale_sd",
        "gyro_misalignment_sd",
        "accel_bias",
        "accel_bias_sd",
        "accel_vrw",
        "accel_scale_sd",
        "accel_misalignment_sd",
    ):
        np.testing.assert_array_equal(getattr(p, name), np.zeros(3), err_msg=name)
    assert p == ImuErrors.from_datasheet(
        {
            "gyro_bias_sd": "0.1 deg/h",
            "gyro_markov_sd": "0.1 deg/h",
            "gyro_markov_tau": "2 h",
            "gyro_arw": "0.01 deg/sqrt(h)",
            "accel_markov_sd": "1e-4 g",
            "accel_markov_tau": "1800 s",
        }
    )


def test_ideal_preset_is_zero_and_presets_are_read_only():
    p = IMU_PRESETS["ideal"]
    for name in ("gyro_bias_sd", "gyro_markov_sd", "gyro_arw", "accel_markov_sd", "accel_vrw"):
        np.testing.assert_array_equal(getattr(p, name), np.zeros(3))
    with pytest.raises(ValueError, match="read-only"):
        IMU_PRESETS["seed001"].gyro_arw[0] = 1.0


def test_from_datasheet_per_axis_and_base():
    e = ImuErrors.from_datasheet(
        {"gyro_bias": ["1 deg/h", "-2 deg/h", "0"], "accel_vrw": "0.06 m/s/sqrt(h)"},
        base=imu_preset("seed001"),
    )
    np.testing.assert_allclose(e.gyro_bias, [D / 3600, -2 * D / 3600, 0.0], rtol=1e-15)
    np.testing.assert_allclose(e.accel_vrw, [1e-3] * 3, rtol=1e-14)
    np.testing.assert_array_equal(e.gyro_markov_tau, [7200.0] * 3)
