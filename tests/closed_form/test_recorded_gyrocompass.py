"""Heading from the gyros where the IMU's grade allows (issue 15, point 3).

Closed form: a still, navigation-grade IMU synthesized from the Earth's rate and gravity
at a known heading, with a static GNSS solution, processed by ``ftnav process``: with
``heading = "auto"`` the alignment gyrocompasses (its predicted σ is below the limit)
and the heading is within 3σ of the true one; with a MEMS datasheet ``auto`` keeps the
GNSS course, which a still log cannot give (refused in one line).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime

import numpy as np
import pytest

from ftnav.cli import main
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.earth import gravity, omega_ie_n

LAT, LON, H = np.radians(40.1), np.radians(-105.1), 1600.0
HEADING_DEG = 37.0
T0 = 1752003258.5
POS_HEADER = (
    "%  GPST            latitude(deg) longitude(deg) height(m) Q  ns  sdn(m) sde(m) sdu(m) "
    "sdne(m) sdeu(m) sdun(m) age(s) ratio vn(m/s) ve(m/s) vu(m/s) sdvn sdve sdvu sdvne "
    "sdveu sdvun"
)

RECORDING = """
kind = "recording"
name = "still"

[imu]
file = "imu.csv"
time = {{ columns = ["t"], unit = "s" }}
accel = {{ columns = ["ax", "ay", "az"], unit = "m/s^2" }}
gyro = {{ columns = ["gx", "gy", "gz"], unit = "rad/s" }}

[imu.errors]
gyro_arw = "{arw}"
accel_vrw = "0.01 m/s/sqrt(h)"
gyro_bias_sd = "{bias}"
accel_bias_sd = "0.1 mg"

[[aids]]
type = "gnss"
file = "gnss.pos"

[alignment]
static_s = 30.0
heading = "auto"

[filter]
duration_s = 20.0

[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _write(folder, arw: str, bias: str, seed: int = 0):
    rng = np.random.default_rng(seed)
    t = T0 + 0.01 * np.arange(1, 6001)  # 60 s at 100 Hz
    C = euler_to_dcm(np.array([0.01, -0.02, np.radians(HEADING_DEG)]))
    f = C.T @ np.array([0.0, 0.0, float(gravity(LAT, H))])
    w = C.T @ omega_ie_n(LAT)
    bias_rad = np.radians(0.005 / 3600.0)  # a 0.005 deg/h gyro bias drawn below
    gyro = (
        w
        + bias_rad * rng.standard_normal(3)
        + np.radians(0.002 / 60) * 10 * rng.standard_normal((t.size, 3))
    )
    accel = f + 1e-4 * rng.standard_normal((t.size, 3))
    rows = ["t,ax,ay,az,gx,gy,gz"] + [
        ",".join(f"{x:.12g}" for x in (tk, *a, *g)) for tk, a, g in zip(t, accel, gyro, strict=True)
    ]
    (folder / "imu.csv").write_text("\n".join(rows) + "\n")
    lines = [POS_HEADER]
    for tk in T0 + 0.25 * np.arange(0, 260):
        stamp = datetime.fromtimestamp(tk, UTC).strftime("%Y/%m/%d %H:%M:%S.%f")[:-3]
        lines.append(
            f"{stamp} {np.degrees(LAT):.9f} {np.degrees(LON):.9f} {H:.4f} 1 20 0.01 0.01 0.01 "
            "0 0 0 0 0 0.000 0.000 0.000 0.05 0.05 0.05 0 0 0"
        )
    (folder / "gnss.pos").write_text("\n".join(lines) + "\n")
    path = folder / "still.toml"
    path.write_text(RECORDING.format(arw=arw, bias=bias))
    return path


def test_a_navigation_grade_imu_gyrocompasses_its_heading(tmp_path, capsys):
    path = _write(tmp_path, "0.002 deg/sqrt(h)", "0.01 deg/h")
    out = tmp_path / "out"
    assert main(["process", str(path), "--out", str(out), "--no-figures", "--quiet"]) == 0
    al = json.loads((out / "metrics.json").read_text())["alignment"]
    assert al["heading_from"] == "gyrocompass"
    sigma = al["heading_sigma_deg"]
    assert 0.0 < sigma < 1.0
    heading = al["heading_deg"]  # clockwise from North
    err = (heading - (-HEADING_DEG) % 360.0 + 180.0) % 360.0 - 180.0
    assert abs(err) <= 3 * sigma, (heading, sigma)


def test_a_mems_imu_keeps_the_gnss_course_which_a_still_log_cannot_give(tmp_path, capsys):
    path = _write(tmp_path, "0.3 deg/sqrt(h)", "0.05 deg/s")
    out = tmp_path / "out"
    assert main(["process", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "alignment.min_speed_mps" in err, err
    assert not out.exists()


@pytest.mark.parametrize("key", ["heading", "gyrocompass_max_sigma_deg"])
def test_gyrocompass_settings_belong_to_the_static_mode(tmp_path, capsys, key):
    path = _write(tmp_path, "0.002 deg/sqrt(h)", "0.01 deg/h")
    value = '"auto"' if key == "heading" else "1.0"
    text = path.read_text().replace(
        'static_s = 30.0\nheading = "auto"',
        f'mode = "given"\nattitude_deg = [0.0, 0.0, 0.0]\n{key} = {value}',
    )
    path.write_text(text)
    assert main(["process", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert f"alignment.{key}: a setting of mode 'static'" in capsys.readouterr().err
