"""``ftnav trajectory`` on a small profile: files, columns, consistency, IMU errors, seeds."""

from __future__ import annotations

import numpy as np

from ftnav.cli import main
from ftnav.io.trajectory_files import IMU_COLUMNS, TRUTH_COLUMNS, read_imu_csv

PROFILE = """
name = "short"
imu_rate_hz = 100.0
[start]
lat_deg = 32.0
lon_deg = 118.0
h_m = 500.0
speed_m_s = 80.0
heading_deg = 45.0
[[segments]]
duration_s = 4.0
[[segments]]
duration_s = 2.0
roll_rate_deg_s = 10.0
[[segments]]
duration_s = 4.0
yaw_rate_deg_s = "coordinated"
"""


def _run(tmp_path, name, *extra):
    f = tmp_path / "short.toml"
    f.write_text(PROFILE)
    out = tmp_path / name
    assert main(["trajectory", str(f), "--out", str(out), *extra]) == 0
    return out


def test_trajectory_writes_truth_imu_and_figure(tmp_path, capsys):
    out = _run(tmp_path, "ideal")
    assert "short: 10 s at 100 Hz" in capsys.readouterr().out
    header = (out / "truth.csv").read_text().splitlines()[0].split(",")
    assert tuple(header) == TRUTH_COLUMNS
    truth = np.loadtxt(out / "truth.csv", delimiter=",", skiprows=1)
    t, dtheta, dv = read_imu_csv(out / "imu.csv")
    assert truth.shape == (1001, 10) and dtheta.shape == (1000, 3)
    np.testing.assert_allclose(t, truth[1:, 0])
    assert truth[0, 9] == 45.0 and truth[-1, 9] > 45.0  # right bank turns clockwise
    assert abs(truth[-1, 7] - 20.0) < 1e-6  # roll reached 20 deg
    # level flight: the increments read gravity upward
    np.testing.assert_allclose(dv[:100, 2].mean() / 0.01, 9.79, atol=0.01)
    assert (out / "trajectory.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "imu.csv").read_text().splitlines()[0] == ",".join(IMU_COLUMNS)


def test_imu_preset_corrupts_deterministically(tmp_path):
    ideal = read_imu_csv(_run(tmp_path, "ideal", "--no-figure") / "imu.csv")
    a = read_imu_csv(
        _run(tmp_path, "a", "--no-figure", "--imu", "seed001", "--seed", "3") / "imu.csv"
    )
    b = read_imu_csv(
        _run(tmp_path, "b", "--no-figure", "--imu", "seed001", "--seed", "3") / "imu.csv"
    )
    c = read_imu_csv(
        _run(tmp_path, "c", "--no-figure", "--imu", "seed001", "--seed", "4") / "imu.csv"
    )
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[1], c[1])
    d = a[1] - ideal[1]
    # ARW 0.01 deg/sqrt(h) at 100 Hz: about 2.9e-7 rad per sample, plus 0.1 deg/h drifts
    assert 1e-7 < d.std() < 1e-6


def test_unknown_imu_preset_exits_2_naming_the_option(tmp_path, capsys):
    """Named as the option the user gave (it said ``imu.preset``, a scenario file's key)."""
    f = tmp_path / "short.toml"
    f.write_text(PROFILE)
    assert main(["trajectory", str(f), "--out", str(tmp_path / "x"), "--imu", "nope"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("ftnav: error: --imu: unknown preset 'nope'") and "\n" not in err
