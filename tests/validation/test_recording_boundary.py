"""Plausibility at the boundary of a recording (issue 21): every bad or suspicious input
is refused in one line naming the field or ``file:line`` (exit 2), or warned about in
one line when it is legal but suspicious; never a silent wrong answer, never an
internal error.

The base is the first minute of the vendored drive (``test_recording_input``); each
case breaks one thing.  By kind: the readers, boundary values, physical plausibility.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
from recording_runs import drive_copy
from test_recording_input import _imu_lines, _pos_lines, _refused, _write
from test_recording_navego_input import NAVEGO

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.recording_file import load_recording
from ftnav.recordings import recording_path

_FIELDS = _pos_lines()[-1].split()  # a data line: date, time, then the header's columns
_HEAD = [ln for ln in _pos_lines() if ln.startswith("%")]
_DATA = [ln for ln in _pos_lines() if not ln.startswith("%")]
_COLUMNS = _HEAD[-1][1:].split()


def _pos_with(row: int, column: str, text: str) -> list[str]:
    """The mini drive's ``.pos`` with ``column`` of data row ``row`` (0-based) replaced."""
    fields = _DATA[row].split()
    fields[_COLUMNS.index(column) + 1] = text  # the date and time take two fields
    return [*_HEAD, *_DATA[:row], " ".join(fields), *_DATA[row + 1 :]]


def _error(path: Path, **kw) -> str:
    with pytest.raises(ScenarioError) as exc:
        load_recording(path, warn=False, **kw)
    text = str(exc.value)
    assert "\n" not in text, text
    return text


def _edit(path: Path, old: str, new: str) -> Path:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))
    return path


# --- readers -------------------------------------------------------------------------

POS_LINE = len(_HEAD) + 6  # the 1-based line of data row 5


@pytest.mark.parametrize(
    ("column", "text", "pattern"),
    [
        ("latitude(deg)", "nan", r"column latitude\(deg\): not finite"),
        ("height(m)", "1_0", r"column height\(m\): not a number \('1_0'\)"),
        ("sdn(m)", "-0.01", r"column sdn\(m\): a σ must be >= 0"),
        ("sdvn", "-1", r"column sdvn: a σ must be >= 0"),
        ("Q", "1.5", r"column Q: not an RTKLIB solution flag 1-6"),
        ("Q", "7", r"column Q: not an RTKLIB solution flag 1-6"),
        ("ns", "-1", r"column ns: not a satellite count"),
        ("ratio", "inf", r"column ratio: not finite"),
        ("latitude(deg)", "95.0", r"column latitude\(deg\): latitude 95 deg is outside"),
        ("longitude(deg)", "-181.0", r"column longitude\(deg\): longitude -181 deg is outside"),
        ("height(m)", "1e9", r"column height\(m\): height 1e\+09 m is outside \[-1000, 100000\]"),
    ],
)
def test_a_pos_field_out_of_bounds_is_refused_with_file_and_line(tmp_path, column, text, pattern):
    """The ``.pos`` reader is as strict as the CSV reader (``float`` would read ``1_0``
    as 10 and ``nan`` as a latitude)."""
    err = _error(_write(tmp_path, pos=_pos_with(5, column, text)))
    assert re.search(rf"gnss\.pos:{POS_LINE}: {pattern}", err), err


def test_a_pos_sigma_of_zero_is_kept_as_missing(tmp_path):
    """RTKLIB prints a σ below 0.05 mm as 0: per epoch it means "keep the configured σ"."""
    (tmp_path / "base").mkdir()
    base = load_recording(_write(tmp_path / "base"), warn=False).recording
    rec = load_recording(_write(tmp_path, pos=_pos_with(5, "sdn(m)", "0.0000")), warn=False)
    assert rec.recording.steps == base.steps  # the epoch is kept
    assert rec.recording.aids[0].sensor.pos_white_sigma_m == (0.05, 0.05, 0.05)


@pytest.mark.parametrize(
    ("line", "text", "pattern"),
    [
        (50, "1752003262.3,1_0,0,1,0,0,0,0", r"imu\.csv:50: column acc_x_g: not a number"),
        (60, "1752003262.3,nan,0,1,0,0,0,0", r"imu\.csv:60: column acc_x_g: not finite"),
        (70, "1752003262.3,infinity,0,1,0,0,0,0", r"imu\.csv:70: column acc_x_g: not finite"),
        (
            101,
            "1752003262.26,0.1,0.0,1.0,1e300,0.0,0.0,0",
            r"imu\.csv:101: columns gyro_x_dps, gyro_y_dps, gyro_z_dps: 1\.\d+e\+298 rad/s",
        ),
        (
            102,
            "1752003262.27,2000,0.0,1.0,0.0,0.0,0.0,0",
            r"imu\.csv:102: columns acc_x_g, acc_y_g, acc_z_g: 1\.9\de\+04 m/s²",
        ),
    ],
)
def test_an_imu_value_that_is_no_number_or_no_imu_is_refused(tmp_path, line, text, pattern):
    imu = _imu_lines()
    imu[line - 1] = text
    err = _error(_write(tmp_path, imu=imu))
    assert re.search(pattern, err), err


def test_a_byte_order_mark_is_dropped(tmp_path):
    """Excel's "CSV UTF-8" starts with a BOM: the first column keeps its name."""
    imu = _imu_lines()
    path = _write(tmp_path, imu=["\ufeff" + imu[0], *imu[1:]])
    assert load_recording(path, warn=False).recording.steps > 100


@pytest.mark.parametrize("which", ["imu.csv", "gnss.pos"])
def test_a_folder_or_a_fifo_as_a_data_file_is_refused(tmp_path, which):
    path = _write(tmp_path)
    (tmp_path / which).unlink()
    (tmp_path / which).mkdir()
    assert re.search(rf"{re.escape(which)}: .*is a folder, not a file", _error(path))
    (tmp_path / which).rmdir()
    os.mkfifo(tmp_path / which)
    assert re.search(rf"{re.escape(which)}: .*is a FIFO", _error(path))


def test_dev_zero_as_the_imu_file_is_refused(tmp_path):
    path = _edit(_write(tmp_path), 'file = "imu.csv"', 'file = "/dev/zero"')
    assert re.search(r"/dev/zero: .*is a device, not a regular file", _error(path))


@pytest.mark.parametrize(
    ("rows", "pattern"),
    [
        ([_DATA[0]] * 50, r"aids\[0\]\.file: 1 distinct epoch time\(s\)"),
        ([_DATA[0]], r"aids\[0\]\.file: 1 distinct epoch time\(s\)"),
        (
            [_DATA[100]] * 50 + _DATA[100:103],
            r"aids\[0\]\.file: the median time between GNSS epochs rounds to 0",
        ),
    ],
    ids=["same-epoch", "one-epoch", "mostly-repeated"],
)
def test_a_gnss_file_without_a_period_is_refused(tmp_path, rows, pattern):
    assert re.search(pattern, _error(_write(tmp_path, pos=[*_HEAD, *rows])))


# --- NaveGo .mat ----------------------------------------------------------------------


def _navego(folder: Path, gnss: dict | None = None, fb: float = -9.79) -> Path:
    n, k = 2001, 51
    rng = np.random.default_rng(1)
    imu = {
        "t": np.arange(n) * 0.005,
        "fb": np.tile([0.0, 0.0, fb], (n, 1)) + rng.normal(0, 0.007, (n, 3)),
        "wb": rng.normal(0, 0.0012, (n, 3)),
        "ini_align": np.array([0.0, 0.0, -0.2618]),
        "ini_align_err": np.radians([0.5, 0.5, 1.0]),
    }
    g = {
        "t": np.arange(k) * 0.2,
        "lat": np.full(k, -0.573),
        "lon": np.full(k, -1.2007),
        "h": np.full(k, 700.0),
        "vel": np.zeros((k, 3)),
        "std": np.array([7.87e-7, 9.32e-7, 10.0]),
        "stdv": np.full(3, 0.0514),
    }
    g.update(gnss or {})
    sio.savemat(folder / "imu.mat", {"imu2": imu})
    sio.savemat(folder / "gnss.mat", {"gnss": {a: b for a, b in g.items() if b is not None}})
    path = folder / "rec.toml"
    path.write_text(NAVEGO.format(alignment=""))
    return path


def test_the_navego_base_loads_without_a_warning(tmp_path):
    assert load_recording(_navego(tmp_path), warn=False).warnings == ()


def test_a_matlab_v73_file_is_refused(tmp_path):
    path = _navego(tmp_path)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5"
    (tmp_path / "imu.mat").write_bytes(header.ljust(512, b" ") + b"\x89HDF\r\n\x1a\n" + bytes(64))
    err = _error(path)
    assert err.endswith(
        "imu.mat: imu.file: MATLAB v7.3 (HDF5) files are not supported: save with -v7"
    )


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        ({"lat": np.full(51, math.radians(95.0))}, r"field lat: sample 1: latitude 95 deg"),
        ({"lon": np.full(51, math.radians(200.0))}, r"field lon: sample 1: longitude 200 deg"),
        ({"h": np.full(51, -5000.0)}, r"field h: sample 1: height -5000 m is outside"),
        ({"std": None}, r"^aids\[0\]\.pos_white_sigma_m: missing: the file has no position σ"),
        ({"stdv": None}, r"^aids\[0\]\.vel_white_sigma_m_s: missing: the file has no velocity"),
    ],
)
def test_navego_gnss_off_the_earth_or_without_sigma_is_refused(tmp_path, change, pattern):
    assert re.search(pattern, _error(_navego(tmp_path, change)))


def test_a_navego_gnss_without_sigma_takes_the_recordings(tmp_path):
    path = _navego(tmp_path, {"std": None})
    _edit(
        path,
        'format = "navego-mat"\n\n[alignment]',
        'format = "navego-mat"\npos_white_sigma_m = 5.0\n\n[alignment]',
    )
    rec = load_recording(path, warn=False).recording
    assert rec.aids[0].sensor.pos_white_sigma_m == (5.0, 5.0, 5.0)


# --- boundary values -----------------------------------------------------------------


@pytest.mark.parametrize(
    ("old", "new", "pattern"),
    [
        (
            'gyro_bias_sd = "0.05 deg/s"',
            'gyro_bias_sd = "1e30 deg/s"',
            r"^imu\.errors\.gyro_bias_sd: 1\.75e\+28 rad/s, beyond the 1 rad/s",
        ),
        (
            'accel_vrw = "70 ug/sqrt(Hz)"',
            'accel_vrw = "5 m/s/sqrt(s)"',
            r"^imu\.errors\.accel_vrw: 5 m/s/sqrt\(s\), beyond",
        ),
        (
            "lever_arm_m = [-0.05, 0.0, 0.0]",
            "lever_arm_m = [1e9, 0.0, 0.0]",
            r"^aids\[0\]\.lever_arm_m: the antenna 1e\+09 m from the IMU: more than the 100 m",
        ),
        (
            "lever_arm_m",
            "pos_white_sigma_m = 0.0\nlever_arm_m",
            r"^aids\[0\]\.pos_white_sigma_m: σ 0 \(pos_E, pos_N, pos_U\) makes the filter",
        ),
        (
            "lever_arm_m",
            "pos_sigma_m = 1e6\nlever_arm_m",
            r"^aids\[0\]\.pos_sigma_m: σ 1e\+06 m: beyond 10000 m",
        ),
        (
            'type = "nhc"',
            'type = "nhc"\nname = "gnss"',
            r"^aids\[1\]\.name: duplicate aid name 'gnss' \(aids\[0\] has it",
        ),
        (
            "[[methods]]",
            "[filter]\nimu_rate_hz = 1e7\n\n[[methods]]",
            r"^filter\.imu_rate_hz: 1e\+07 Hz is more than 10 times the log's 100 Hz",
        ),
        (
            "time_offset_s = -0.125",
            "time_offset_s = -100000.0",
            r"^imu/gnss: the logs do not overlap: IMU \[1751903261\.\d+, 1751903317\.\d+\] s, "
            r"GNSS \[1752003258\.499, 1752003333\.249\] s",
        ),
    ],
)
def test_a_value_out_of_bounds_is_refused_naming_the_field(tmp_path, old, new, pattern):
    path = _edit(_write(tmp_path), old, new)
    assert re.search(pattern, _error(path))


def test_a_refusal_is_exit_2_in_one_line_and_writes_nothing(tmp_path, capsys):
    path = _write(tmp_path, lever_arm="[1e9, 0.0, 0.0]")
    err = _refused(["process", path, "--out", tmp_path / "o"], capsys)
    assert err.startswith("aids[0].lever_arm_m: "), err
    assert not (tmp_path / "o").exists()


def test_a_long_lever_arm_is_a_warning(tmp_path):
    loaded = load_recording(_write(tmp_path, lever_arm="[0.0, 20.0, 0.0]"), warn=False)
    assert any(
        "aids[0].lever_arm_m: the antenna is 20 m from the IMU" in w for w in loaded.warnings
    )


def test_an_arm_beside_velocity_rows_is_modelled_not_warned_about(tmp_path):
    """The velocity rows carry the arm's rotation ``C_b^n (ω_eb × l)`` since 2026-12-07
    (``sensors/gnss.py``; its Jacobian in ``tests/finite_difference``, its statistics in
    ``tests/statistical/test_lever_arm.py``): a 2.24 m arm is no warning now, as it was
    while the rows left the rotation out; only its length is judged."""
    loaded = load_recording(_write(tmp_path, lever_arm="[0.0, 2.0, 1.0]"), warn=False)
    assert not [w for w in loaded.warnings if "lever_arm_m" in w], loaded.warnings
    arms = [a.sensor.lever_arm_m for a in loaded.recording.aids if "vel_E" in a.sensor.components]
    assert arms == [(0.0, 2.0, 1.0)]


def test_an_outage_schedule_that_does_not_fit_is_refused_with_both_spans(tmp_path):
    err = _error(_write(tmp_path), outage=(15.0, 45.0, 500.0))
    assert re.search(
        r"^--outage-start: no outage of 15 s every 45 s from 500 s fits in the processed "
        r"span \[\d+\.\d, \d+\.\d\] s",
        err,
    ), err


def _csv_gnss(folder: Path, velocity: bool, sigma: bool, extra: str = "") -> Path:
    """The mini drive with its GNSS as a CSV (lat, lon deg; optional NED velocity, σ)."""
    rows = ["t,lat,lon,h,vn,ve,vd,sdn,sde,sdu"]
    for ln in _DATA:
        f = ln.split()
        t = np.datetime64(f"{f[0].replace('/', '-')}T{f[1]}").astype("datetime64[ms]")
        c = {n: f[i + 1] for i, n in enumerate(_COLUMNS[1:], start=1)}
        rows.append(
            f"{float(t.astype(np.int64)) / 1000.0!r},{c['latitude(deg)']},{c['longitude(deg)']},"
            f"{c['height(m)']},{c['vn(m/s)']},{c['ve(m/s)']},{-float(c['vu(m/s)'])!r},"
            f"{c['sdn(m)']},{c['sde(m)']},{c['sdu(m)']}"
        )
    path = _write(folder)
    (folder / "gnss.csv").write_text("\n".join(rows) + "\n")
    aid = (
        'file = "gnss.csv"\nformat = "csv"\ntime = { columns = ["t"], unit = "s" }\n'
        'lat = { columns = ["lat"], unit = "deg" }\nlon = { columns = ["lon"], unit = "deg" }\n'
        'height = { columns = ["h"], unit = "m" }\n'
        + (
            'velocity = { columns = ["vn", "ve", "vd"], unit = "m/s", frame = "NED" }\n'
            if velocity
            else ""
        )
        + (
            'sigma = { columns = ["sdn", "sde", "sdu"], unit = "m", frame = "NEU" }\n'
            if sigma
            else ""
        )
        + extra
    )
    return _edit(path, 'file = "gnss.pos"\n', aid)


def test_a_csv_gnss_without_sigma_needs_the_sigma_in_the_recording(tmp_path):
    """No receiver's σ can be assumed: 5 cm is an RTK fix's, a single point's is 5 m."""
    err = _error(_csv_gnss(tmp_path, velocity=True, sigma=False))
    assert err.startswith("aids[0].pos_white_sigma_m: missing: the file has no position σ"), err
    path = _csv_gnss(tmp_path, velocity=True, sigma=True)
    assert _error(path).startswith("aids[0].vel_white_sigma_m_s: missing: the file has no velocity")
    path = _csv_gnss(
        tmp_path,
        velocity=True,
        sigma=False,
        extra="pos_white_sigma_m = 0.05\nvel_white_sigma_m_s = 0.1\n",
    )
    load_recording(path, warn=False)


def test_a_csv_gnss_off_the_earth_is_refused_with_file_and_line(tmp_path):
    path = _csv_gnss(tmp_path, velocity=True, sigma=True, extra="vel_white_sigma_m_s = 0.1\n")
    lines = (tmp_path / "gnss.csv").read_text().splitlines()
    f = lines[4].split(",")
    f[2] = "-190.0"
    lines[4] = ",".join(f)
    (tmp_path / "gnss.csv").write_text("\n".join(lines) + "\n")
    assert re.search(
        r"gnss\.csv:5: column lon: longitude -190 deg is outside \[-180, 180\] deg", _error(path)
    )


def test_no_gnss_velocity_for_a_static_start_is_refused(tmp_path):
    """Gyrocompassing takes the heading from the gyros, but the start velocity is still
    the GNSS's: without velocity columns it is unknown (it was NaN)."""
    path = _csv_gnss(tmp_path, velocity=False, sigma=True)
    _edit(path, "[[methods]]", '[alignment]\nheading = "gyrocompass"\n\n[[methods]]')
    err = _error(path)
    assert err.startswith("alignment.heading: the start fix after the static window"), err
    assert "has no velocity: the initial velocity is unknown" in err
    path = _edit(path, 'heading = "gyrocompass"', 'heading = "gnss-course"')
    assert _error(path).startswith("alignment.heading: the GNSS has no velocity")


# --- physical plausibility -----------------------------------------------------------


def test_an_accelerometer_in_g_declared_m_s2_is_refused_naming_g(tmp_path):
    err = _error(_write(tmp_path, accel_unit="m/s^2"))
    assert re.search(
        r"^imu\.accel\.unit: the specific force over the static 30 s is 1\.01 m/s², 0\.103 "
        r"times the local gravity 9\.797 m/s²: is the unit g\?$",
        err,
    ), err


def test_an_accelerometer_in_m_s2_declared_mg_is_refused(tmp_path):
    err = _error(_write(tmp_path, accel_unit="mg"))
    assert err.startswith("imu.accel.unit: the specific force") and "is the unit" in err, err


def test_a_specific_force_a_few_percent_off_is_a_warning(tmp_path):
    """15 % off gravity at rest (beyond 5 % and 3 σ of the 20 mg bias): a scale-factor
    error, or a start that is not still."""
    imu = _imu_lines()
    rows = [imu[0]]
    for ln in imu[1:]:
        f = ln.split(",")
        f[1:4] = [repr(float(x) * 1.15) for x in f[1:4]]
        rows.append(",".join(f))
    loaded = load_recording(_write(tmp_path, imu=rows), warn=False)
    assert any(
        re.search(
            r"imu\.accel\.unit: the specific force over the static 30 s is 11\.4 m/s², 1\.17 times",
            w,
        )
        for w in loaded.warnings
    ), loaded.warnings


def test_a_gyro_in_deg_s_declared_rad_s_is_refused_at_rest(tmp_path):
    path = _edit(_write(tmp_path), 'unit = "deg/s"', 'unit = "rad/s"')
    err = _error(path)
    assert re.search(
        r"^imu\.gyro\.unit: the mean rate over the static 30 s is 0\.187 rad/s \(10\.7 deg/s\).*"
        r"is the unit deg/s\?$",
        err,
    ), err


def _given_drive(tmp_path: Path, gyro_unit: str, scale: float = 1.0) -> Path:
    """The whole vendored drive started from a given attitude (no static window to check
    the gyros against): only the GNSS course can tell their unit."""
    src = recording_path("rtklib-drive").parent
    imu_path = tmp_path / "imu.csv"
    if scale != 1.0:
        lines = (src / "data/rtklibexplorer/drive_0708/imu_1934_gpst.csv").read_text().splitlines()
        rows = [lines[0]]
        for ln in lines[1:]:
            f = ln.split(",")
            f[4:7] = [repr(float(x) * scale) for x in f[4:7]]
            rows.append(",".join(f))
        imu_path.write_text("\n".join(rows) + "\n")

    def edit(doc: dict) -> None:
        doc["imu"]["gyro"]["unit"] = gyro_unit
        if scale != 1.0:
            doc["imu"]["file"] = str(imu_path)
        doc["alignment"] = {"mode": "given", "attitude_deg": [0.0, 0.0, 0.0]}

    return drive_copy(tmp_path / "rec.toml", edit)


@pytest.mark.parametrize(
    ("unit", "scale", "named"),
    [("rad/s", 1.0, "deg/s"), ("deg/s", math.pi / 180.0, "rad/s")],
    ids=["deg-declared-rad", "rad-declared-deg"],
)
def test_a_gyro_unit_slip_is_refused_against_the_gnss_course(tmp_path, unit, scale, named):
    err = _error(_given_drive(tmp_path, unit, scale))
    assert re.search(
        rf"^imu\.gyro\.unit: the GNSS course turns \S+ times as fast as the gyros read about "
        rf"the vertical \(\d+ intervals of motion, \d+ deg of turns\): is the unit {named}\?$",
        err,
    ), err


def test_the_builtin_recordings_load_without_a_warning():
    """The checks fire on none of the built-ins (their data are plausible)."""
    for name in ("rtklib-drive", "rtklib-walk", "navego-adis16405", "navego-adis16488"):
        path = recording_path(name)
        doc = tomllib.loads(path.read_text())
        if doc["imu"]["file"].startswith("${") and not _navego_data(path, doc["imu"]["file"]):
            continue
        assert load_recording(path, warn=False).warnings == (), name


def _navego_data(path: Path, raw: str) -> bool:
    folder = os.environ.get("FTNAV_NAVEGO_DIR") or raw.split(":-", 1)[1].split("}", 1)[0]
    return (path.parent / folder / "imu2.mat").is_file()


def test_a_gap_in_the_imu_log_is_a_warning_with_its_length_and_time(tmp_path):
    """The strapdown holds the sample after a gap over all of it: said, with where."""
    lines = _imu_lines()
    t = [float(ln.split(",")[0]) for ln in lines[1:]]
    cut = [ln for ln, ti in zip(lines[1:], t, strict=True) if not (t[0] + 40 < ti < t[0] + 43)]
    loaded = load_recording(_write(tmp_path, imu=[lines[0], *cut]), warn=False)
    said = [w for w in loaded.warnings if "imu.file: 1 gap(s)" in w]
    assert len(said) == 1, loaded.warnings
    assert re.search(r"the longest 3\.0 s from 17520033\d\d\.\d{3} s", said[0]), said[0]


def test_the_base_has_no_gap_warning(tmp_path):
    loaded = load_recording(_write(tmp_path), warn=False)
    assert not any("gap(s)" in w for w in loaded.warnings), loaded.warnings


@pytest.mark.parametrize("sigma", ["[0.0, 1.0, 10.0]", "[1.0, -1.0, 10.0]", "[1.0, 1.0, 400.0]"])
def test_an_attitude_sigma_out_of_bounds_is_refused(tmp_path, sigma):
    path = _write(tmp_path)
    text = path.read_text()
    text = re.sub(r"attitude_sigma_deg = \[[^\]]*\]", f"attitude_sigma_deg = {sigma}", text)
    if "attitude_sigma_deg" not in text:
        assert "[alignment]" not in text
        text += f"\n[alignment]\nattitude_sigma_deg = {sigma}\n"
    path.write_text(text)
    assert _error(path).startswith("alignment.attitude_sigma_deg[")


def test_a_quality_filter_that_keeps_no_epoch_is_refused_with_the_files_flags(tmp_path):
    path = _write(tmp_path)
    _edit(path, "lever_arm_m", "quality = [5]\nlever_arm_m")
    assert re.search(
        r"^aids\[0\]\.quality: no epoch of the GNSS file has quality \[5\] \(its epochs: 1: \d+",
        _error(path),
    )


def test_a_static_window_longer_than_the_log_is_refused(tmp_path):
    path = _write(tmp_path)
    path.write_text(path.read_text() + "\n[alignment]\nstatic_s = 1e6\n")
    assert re.search(
        r"^alignment\.static_s: 1e\+06 s of standing still, but the IMU log is", _error(path)
    )


# --- found by trying what a user's own log does (2026-12-07) ---------------------------


def test_a_static_window_the_gnss_sees_moving_is_refused(tmp_path):
    """Levelled while accelerating and with the turns removed as a gyro bias, the start
    is wrong whatever the filter does after it (the base moves from about 36 s on)."""
    path = _write(tmp_path)
    load_recording(path, warn=False)  # the default window (30 s) is still
    path.write_text(path.read_text() + "\n[alignment]\nstatic_s = 50.0\n")
    assert re.search(
        r"^alignment\.static_s: the GNSS moves during the static 50 s: \d+ of its \d+ fixes "
        r"there at 1 m/s or faster \(up to [\d.]+ m/s, the first 3\d\.?\d* s into the window\)",
        _error(path),
    )


def test_an_imu_log_shifted_against_the_gnss_is_refused_at_the_static_window(tmp_path):
    """A time slip of the IMU's stamps (a minute) puts the moving fixes in its window."""
    path = _edit(_write(tmp_path), "time_offset_s = -0.125", "time_offset_s = 30.0")
    err = _error(path)
    assert err.startswith("alignment.static_s: the GNSS moves during the static"), err
    assert err.endswith("check the logs' time bases (imu.time_offset_s)"), err


def test_a_repeated_gnss_stamp_with_another_solution_is_refused_naming_both_lines(tmp_path):
    """Which of the two is the solution cannot be told; keeping the first (as before)
    gave 590 m on a 100 s drive when the first was the wrong one."""
    row = 200  # 50 s in: on the filter's grid (the start is the first moving fix)
    moved = _pos_with(row, "latitude(deg)", "40.19")[len(_HEAD) + row]
    pos = [*_HEAD, *_DATA[:row], moved, *_DATA[row:]]
    path = _write(tmp_path, pos=pos)
    line = len(_HEAD) + row + 2
    assert re.search(
        rf"gnss\.pos:{line}: time stamp [\d.]+ s repeats line {line - 1}'s with another "
        "solution: which one is right cannot be told; remove one",
        _error(path),
    )
    # an exact repeat is dropped and counted, as before
    path = _write(tmp_path, pos=[*_HEAD, *_DATA[: row + 1], _DATA[row], *_DATA[row + 1 :]])
    assert load_recording(path, warn=False).counts["gnss"]["duplicated_dropped"] == 1


def test_a_pos_line_with_more_fields_than_its_header_is_refused(tmp_path):
    """Two epochs run together on one line (a lost line break) lost the second."""
    pos = [*_HEAD, *_DATA[:5], _DATA[5] + " 1.0 2.0", *_DATA[6:]]
    err = _error(_write(tmp_path, pos=pos))
    width = len(_COLUMNS) + 1  # the header names the time once, the lines split it in two
    assert re.search(
        rf"gnss\.pos:{POS_LINE}: expected {width} fields \(the header's columns\), got "
        rf"{width + 2}",
        err,
    ), err


def test_a_csv_gnss_in_radians_declared_degrees_is_refused_naming_the_unit(tmp_path):
    """Its positions move about π/180 as far as its own velocities say (the east part
    by the cosines of two latitudes more); the track sat at 0.7° N, 1.8° W, 2.6 m RMS."""
    path = _csv_gnss(tmp_path, velocity=True, sigma=True, extra="vel_white_sigma_m_s = 0.1\n")
    rows = (tmp_path / "gnss.csv").read_text().splitlines()
    out = [rows[0]]
    for r in rows[1:]:
        f = r.split(",")
        f[1], f[2] = repr(math.radians(float(f[1]))), repr(math.radians(float(f[2])))
        out.append(",".join(f))
    (tmp_path / "gnss.csv").write_text("\n".join(out) + "\n")
    err = _error(path)
    assert re.search(
        r"^aids\[0\]\.lat\.unit: the positions move 0\.0\d+ times as far as the file's own "
        r"velocities say \(median over \d+ spans of 5 s\): is the latitude's and "
        r"longitude's unit rad\?",
        err,
    ), err


def test_a_gnss_velocity_in_km_h_declared_m_s_is_a_warning(tmp_path):
    path = _csv_gnss(tmp_path, velocity=True, sigma=True, extra="vel_white_sigma_m_s = 0.1\n")
    rows = (tmp_path / "gnss.csv").read_text().splitlines()
    out = [rows[0]]
    for r in rows[1:]:
        f = r.split(",")
        f[4:7] = [repr(3.6 * float(x)) for x in f[4:7]]
        out.append(",".join(f))
    (tmp_path / "gnss.csv").write_text("\n".join(out) + "\n")
    warnings = load_recording(path, warn=False).warnings
    moved = [w for w in warnings if "times as far as the file's own velocities" in w]
    assert len(moved) == 1, warnings
    assert re.search(
        r"aids\[0\]\.lat\.unit, aids\[0\]\.velocity\.unit: the positions move 0\.2\d+ times",
        moved[0],
    ), moved


def test_a_recording_field_is_refused_with_its_file_and_line(tmp_path, capsys):
    """The recording file's own line that sets the refused field, found by hand."""
    path = _write(tmp_path, lever_arm="[1e9, 0.0, 0.0]")
    line = 1 + next(i for i, t in enumerate(path.read_text().splitlines()) if "1e9" in t)
    assert main(["process", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ftnav: error: {path}:{line}: aids[0].lever_arm_m: "), err
