"""IMU error input validation: every bad input raises one line that starts with the field."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ftnav.core.markov import gauss_markov
from ftnav.model.imu import ImuErrors, imu_preset
from ftnav.nav.units import markov_q, parse_quantity, psd_to_sigma, sigma_to_psd
from ftnav.sim.imu import simulate_imu_errors

NAN = float("nan")
INF = float("inf")


def raises_on(field: str):
    """``pytest.raises`` for a ValueError whose single-line message starts with ``field:``."""
    return pytest.raises(ValueError, match=r"\A" + re.escape(field) + r": [^\n]+\Z")


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        # wrong unit family (a noise in the wrong unit is the classic datasheet slip)
        ("gyro_bias_sd", "0.1 deg/sqrt(h)", "expected an angular rate"),
        ("gyro_arw", "0.01 deg/h", "expected an angle random walk"),
        ("gyro_markov_sd", "100 ug", "which is an acceleration"),
        ("accel_vrw", "100 ug", "expected a velocity random walk"),
        ("accel_bias_sd", "0.01 m/s/sqrt(h)", "expected an acceleration"),
        ("accel_markov_tau", "1800 m", "expected a time"),
        ("gyro_scale_sd", "0.1 deg", "expected a dimensionless ratio"),
        ("gyro_misalignment_sd", "250 ppm", "expected an angle"),
        # missing, unknown or unreadable units and numbers
        ("gyro_bias_sd", "0.1", "no unit"),
        ("gyro_bias_sd", 0.1, "no unit"),
        ("gyro_bias_sd", "0.1 deg/day", "unknown unit 'deg/day'"),
        ("gyro_bias_sd", "fast", "cannot read a number"),
        ("gyro_bias_sd", None, "as a string with a unit"),
        ("gyro_bias_sd", True, "as a string with a unit"),
        # impossible values
        ("gyro_bias_sd", "-0.1 deg/h", "must be >= 0"),
        ("accel_vrw", "-1 m/s/sqrt(h)", "must be >= 0"),
        ("gyro_markov_tau", "0 s", "must be > 0"),
        ("accel_markov_tau", "-5 min", "must be > 0"),
        ("gyro_arw", "nan deg/sqrt(h)", "finite"),
        ("accel_markov_sd", "inf ug", "finite"),
    ],
)
def test_from_datasheet_bad_values_name_the_field(key, value, needle):
    with raises_on(f"imu.{key}") as info:
        ImuErrors.from_datasheet({key: value})
    assert needle in str(info.value)


def test_wrong_family_message_reads_as_documented():
    with raises_on("imu.gyro_bias") as info:
        ImuErrors.from_datasheet({"gyro_bias": "0.1 deg/sqrt(h)"})
    assert str(info.value).startswith(
        "imu.gyro_bias: expected an angular rate (e.g. '0.1 deg/h'), got '0.1 deg/sqrt(h)'"
    )


def test_from_datasheet_unknown_key_is_named():
    with raises_on("imu.gyro_drift") as info:
        ImuErrors.from_datasheet({"gyro_bias_sd": "0.1 deg/h", "gyro_drift": "0.1 deg/h"})
    assert "unknown key" in str(info.value) and "gyro_bias_sd" in str(info.value)


def test_from_datasheet_per_axis_errors_name_the_element():
    with raises_on("imu.gyro_arw[1]"):
        ImuErrors.from_datasheet({"gyro_arw": ["0.01 deg/sqrt(h)", "0.01 deg/h", "0"]})
    with raises_on("imu.gyro_arw"):
        ImuErrors.from_datasheet({"gyro_arw": ["0.01 deg/sqrt(h)"] * 2})


def test_from_datasheet_uses_the_given_prefix():
    with raises_on("scenario.imu.accel_vrw"):
        ImuErrors.from_datasheet({"accel_vrw": "1 mg"}, field="scenario.imu")
    with raises_on("scenario.imu"):
        ImuErrors.from_datasheet(["gyro_arw"], field="scenario.imu")


@pytest.mark.parametrize(
    ("kwargs", "field", "needle"),
    [
        ({"gyro_bias_sd": -1e-6}, "imu.gyro_bias_sd", ">= 0"),
        ({"gyro_arw": [1e-6, -1e-6, 0.0]}, "imu.gyro_arw", ">= 0"),
        ({"accel_markov_tau": 0.0}, "imu.accel_markov_tau", "> 0"),
        ({"gyro_markov_tau": [1.0, -1.0, 1.0]}, "imu.gyro_markov_tau", "> 0"),
        ({"accel_bias": NAN}, "imu.accel_bias", "finite"),
        ({"gyro_markov_sd": INF}, "imu.gyro_markov_sd", "finite"),
        ({"accel_scale_sd": [1e-4, 1e-4]}, "imu.accel_scale_sd", "shape (2,)"),
        ({"gyro_misalignment_sd": np.zeros((3, 3))}, "imu.gyro_misalignment_sd", "shape (3, 3)"),
        ({"gyro_bias_sd": "0.1 deg/h"}, "imu.gyro_bias_sd", "from_datasheet"),
    ],
)
def test_constructor_bad_values_name_the_field(kwargs, field, needle):
    with raises_on(field) as info:
        ImuErrors(**kwargs)
    assert needle in str(info.value)


def test_unknown_preset_lists_valid_names():
    with raises_on("imu.preset") as info:
        imu_preset("navigation-grade")
    for name in ("ideal", "seed001", "tactical"):
        assert name in str(info.value)


def test_parse_quantity_bad_family_and_custom_field():
    with raises_on("aid.gnss.sigma"):
        parse_quantity("25 m", "distance", "aid.gnss.sigma")
    with raises_on("aid.gnss.tau"):
        parse_quantity("100 m", "time", "aid.gnss.tau", constraint="positive")


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: psd_to_sigma(-1.0, 0.01), "psd"),
        (lambda: psd_to_sigma(1.0, 0.0), "dt"),
        (lambda: sigma_to_psd(NAN, 0.01), "sigma"),
        (lambda: markov_q(1.0, 0.0), "tau"),
        (lambda: markov_q(-1.0, 10.0), "sigma"),
        (lambda: gauss_markov(np.zeros((5, 3)), 1.0, -1.0, 0.1), "tau"),
        (lambda: gauss_markov(np.zeros(5), 1.0, 1.0, 0.1), "white"),
    ],
)
def test_noise_helpers_reject_impossible_values(call, field):
    with raises_on(field):
        call()


Z = np.zeros((10, 3))


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"dtheta": np.zeros((10, 2))}, "dtheta"),
        ({"dtheta": np.zeros(3), "dv": np.zeros(3)}, "dtheta"),
        ({"dv": np.zeros((2, 10, 3))}, "dv"),
        ({"dt": 0.0}, "dt"),
        ({"dt": NAN}, "dt"),
        ({"errors": {"gyro_arw": "0.01 deg/sqrt(h)"}}, "errors"),
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"first_run": -2}, "first_run"),
        ({"runs": 0}, "runs"),
        ({"dtheta": np.zeros((2, 10, 3)), "dv": np.zeros((2, 10, 3)), "runs": 3}, "runs"),
    ],
)
def test_simulate_rejects_bad_arguments(kwargs, field):
    args = {"dtheta": Z, "dv": Z, "dt": 0.01, "errors": imu_preset("seed001"), "seed": 1}
    with raises_on(field):
        simulate_imu_errors(**(args | kwargs))
