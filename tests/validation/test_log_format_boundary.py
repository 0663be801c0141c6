"""The log formats of issue 22 at the boundary: a malformed line in each new format is
refused with exit status 2 and one line naming ``file:line`` and the column; a setting
that cannot hold is refused naming the key; a GNSS log with positions only, of a vehicle
moving from the start, runs from a given velocity.

The data are the vendored drive's, cut and rewritten in the test (``test_log_formats``
writes the same formats whole).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from recording_runs import traces_of

# the writers of the formats live with the equivalence oracles that use them whole
sys.path.insert(0, str(Path(__file__).parents[1] / "equivalence"))
from test_log_formats import (  # noqa: E402
    DRIVE,
    WEEK_START,
    _pos_ecef,
    _pos_enu,
    _pos_parts,
    _pos_week,
    _sow,
)

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.recording_file import load_recording

IMU_ROWS = 5600  # 56 s of the drive's IMU (the first minute: still, then moving)

KFGINS = """
kind = "recording"
name = "kfgins"

[imu]
file = "imu.txt"
format = "kfgins-text"
time_offset_s = {imu_offset}
misalignment_deg = [-6.79, 0.0, -5.35]
{imu_extra}

[imu.errors]
gyro_arw = "0.0038 deg/s/sqrt(Hz)"
accel_vrw = "70 ug/sqrt(Hz)"
gyro_bias_sd = "0.05 deg/s"
accel_bias_sd = "20 mg"

[[aids]]
type = "gnss"
name = "gnss"
file = "{gnss}"
format = "{gnss_format}"
time_offset_s = {gnss_offset}
lever_arm_m = [-0.05, 0.0, 0.0]
pos_white_sigma_m = 0.05
{gnss_extra}

[[aids]]
type = "nhc"

[alignment]
{alignment}

[[methods]]
name = "ckf"
architecture = "centralized"
"""

GIVEN = 'mode = "given"\nattitude_deg = [0.0, 0.0, 4.2]'
#: a ``.pos`` is on GPST as Unix seconds: the IMU's seconds of week moved there
POS_BASE = {"imu_offset": WEEK_START - 0.20}


def _imu_text(first: int = 0, rows: int = IMU_ROWS) -> list[str]:
    """The drive's IMU as KF-GINS increments (FRD; seconds of week; 100 Hz intervals)."""
    lines = (DRIVE / "imu_1934_gpst.csv").read_text().splitlines()[1 + first : 1 + first + rows]
    out = []
    for ln in lines:
        t, ax, ay, az, gx, gy, gz = ln.split(",")[:7]
        dth = np.radians([-float(gx), float(gy), -float(gz)]) * 0.01
        dv = np.array([-float(ax), float(ay), -float(az)]) * 9.80665 * 0.01
        out.append(" ".join([f"{float(t) - WEEK_START:.4f}", *(f"{x:.9e}" for x in (*dth, *dv))]))
    return out


def _gnss_text(t_from: float = 0.0) -> list[str]:
    """The drive's RTK fixes as KF-GINS GNSS text from ``t_from`` (seconds of week)."""
    _, cols, rows = _pos_parts()
    out = []
    for f in rows:
        sow = _sow(f[0], f[1])
        if float(f[cols.index("Q") + 1]) != 1.0 or float(sow) < t_from:
            continue
        c = [f[cols.index(n) + 1] for n in ("latitude(deg)", "longitude(deg)", "height(m)")]
        out.append("  ".join([sow, *c, "0.010", "0.010", "0.020"]))
    return out


def _write(
    folder: Path,
    imu: list[str] | None = None,
    gnss: list[str] | None = None,
    *,
    gnss_file: str = "gnss.txt",
    gnss_format: str = "kfgins-text",
    gnss_offset: float = 0.0,
    imu_offset: float = -0.20,
    imu_extra: str = "",
    gnss_extra: str = "",
    alignment: str = GIVEN + "\nvelocity_mps = [0.0, 0.0, 0.0]",
) -> Path:
    (folder / "imu.txt").write_text("\n".join(_imu_text() if imu is None else imu) + "\n")
    if gnss_format == "kfgins-text":
        (folder / gnss_file).write_text("\n".join(_gnss_text() if gnss is None else gnss) + "\n")
    path = folder / "rec.toml"
    path.write_text(
        KFGINS.format(
            imu_offset=repr(imu_offset),
            gnss=gnss_file,
            gnss_format=gnss_format,
            gnss_offset=repr(gnss_offset),
            imu_extra=imu_extra,
            gnss_extra=gnss_extra,
            alignment=alignment,
        )
    )
    return path


def _refused(path: Path, capsys) -> str:
    out = path.parent / "out"
    assert main(["process", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()
    # a field of the recording file comes after the file and its line
    line = err.strip().removeprefix("ftnav: error: ")
    where = re.match(rf"{re.escape(str(path))}:\d+: ", line)
    return line if where is None else line[where.end() :]


def _with(lines: list[str], row: int, column: int, text: str) -> list[str]:
    """``lines`` with field ``column`` (0-based) of line ``row`` (0-based) replaced."""
    fields = lines[row].split()
    fields[column] = text
    return [*lines[:row], " ".join(fields), *lines[row + 1 :]]


def test_the_base_processes(tmp_path):
    loaded = load_recording(_write(tmp_path), warn=False)
    assert loaded.recording.aids[0].sensor.rows == "position"
    assert loaded.alignment.heading_from == "given"


# --- a malformed line in each format ------------------------------------------------


def _pos_line(path: Path, row: int) -> int:
    """The 1-based line of data row ``row`` (0-based) of a ``.pos``."""
    lines = path.read_text().splitlines()
    data = [i for i, ln in enumerate(lines) if not ln.startswith("%")]
    return data[row] + 1


def _pos_field(path: Path, row: int, column: int, text: str) -> int:
    lines = path.read_text().splitlines()
    n = _pos_line(path, row)
    fields = lines[n - 1].split()
    fields[column] = text
    lines[n - 1] = " ".join(fields)
    path.write_text("\n".join(lines) + "\n")
    return n


@pytest.mark.parametrize(
    ("case", "pattern"),
    [
        ("imu-number", r"imu\.txt:41: column dtheta_y_rad: not a number \('0\.1x'\)"),
        ("imu-nan", r"imu\.txt:41: column dv_z_mps: not finite"),
        ("imu-short", r"imu\.txt:41: expected 7 fields, got 5"),
        ("imu-width", r"imu\.txt: imu\.file: 6 columns; a KF-GINS IMU file has 7"),
        ("gnss-lat", r"gnss\.txt:12: column lat_deg: latitude 95 deg is outside \[-90, 90\]"),
        ("gnss-sigma", r"gnss\.txt:12: column sigma_e_m: σ must be > 0"),
        ("gnss-number", r"gnss\.txt:12: column height_m: not a number \('1_0'\)"),
        ("gnss-width", r"gnss\.txt: aids\[0\]\.file: 13 columns; a KF-GINS GNSS file has 7"),
    ],
)
def test_a_malformed_kfgins_line_is_refused_with_file_line_and_column(
    tmp_path, capsys, case, pattern
):
    imu, gnss = _imu_text(), _gnss_text()
    if case == "imu-number":
        imu = _with(imu, 40, 2, "0.1x")
    elif case == "imu-nan":
        imu = _with(imu, 40, 6, "nan")
    elif case == "imu-short":
        imu[40] = " ".join(imu[40].split()[:5])
    elif case == "imu-width":
        imu = [" ".join(ln.split()[:6]) for ln in imu]
    elif case == "gnss-lat":
        gnss = _with(gnss, 11, 1, "95.0")
    elif case == "gnss-sigma":
        gnss = _with(gnss, 11, 5, "0.000")
    elif case == "gnss-number":
        gnss = _with(gnss, 11, 3, "1_0")
    else:
        gnss = [ln + " 0 0 0 0.1 0.1 0.1" for ln in gnss]
    err = _refused(_write(tmp_path, imu, gnss), capsys)
    assert re.search(pattern, err), err


def test_a_whitespace_csv_skips_comments_and_refuses_a_bad_field(tmp_path, capsys):
    """The generic reader with ``delimiter = "whitespace"``: runs of spaces and tabs,
    ``#`` and ``%`` lines skipped, a bad field named by the header's column."""
    imu = ["# a comment", "% another", "t gx gy gz ax ay az"]
    imu += [ln.replace(" ", "\t  ", 2) for ln in _imu_text()]
    csv = (
        'header = true\ndelimiter = "whitespace"\n'
        'time = { columns = ["t"], unit = "s" }\n'
        'gyro = { columns = ["gx", "gy", "gz"], unit = "rad" }\n'
        'accel = { columns = ["ax", "ay", "az"], unit = "m/s" }\naxes = ["+y", "+x", "-z"]'
    )
    path = _write(tmp_path, imu, imu_extra=csv)
    path.write_text(path.read_text().replace('format = "kfgins-text"\n', 'format = "csv"\n', 1))
    loaded = load_recording(path, warn=False)
    assert loaded.recording.steps > 100
    (tmp_path / "imu.txt").write_text("\n".join(_with(imu, 10, 4, "abc")) + "\n")
    err = _refused(path, capsys)
    assert re.search(r"imu\.txt:11: column ax: not a number \('abc'\)", err), err


@pytest.mark.parametrize(
    ("form", "column", "text", "pattern"),
    [
        ("week", 0, "20x5", r"column GPST: not a GPS week and seconds of week \('20x5 "),
        ("week", 1, "604800.0", r"column GPST: 604800\.0 seconds of week is not below 604800"),
        ("week", 2, "abc", r"column latitude\(deg\): not a number \('abc'\)"),
        ("ecef", 3, "1_0", r"column y-ecef\(m\): not a number \('1_0'\)"),
        ("ecef", 2, "0.0", r"column x-ecef\(m\), y-ecef\(m\), z-ecef\(m\): height "),
        ("ecef", 7, "-0.1", r"column sdx\(m\): a σ must be >= 0"),
        ("enu", 4, "inf", r"column u-baseline\(m\): not finite"),
        ("enu", 5, "7", r"column Q: not an RTKLIB solution flag 1-6"),
    ],
)
def test_a_malformed_pos_line_is_refused_with_file_line_and_column(
    tmp_path, capsys, form, column, text, pattern
):
    """The GPS week and seconds, ECEF and ENU forms of RTKLIB's ``.pos``."""
    pos = {"week": _pos_week, "ecef": _pos_ecef, "enu": _pos_enu}[form](tmp_path)
    line = _pos_field(pos, 20, column, text)
    path = _write(tmp_path, gnss_file=pos.name, gnss_format="rtklib-pos", **POS_BASE)
    err = _refused(path, capsys)
    assert re.search(rf"{pos.name}:{line}: {pattern}", err), err


def test_an_enu_pos_without_its_base_is_refused_naming_the_ref_pos_line(tmp_path, capsys):
    pos = _pos_enu(tmp_path)
    pos.write_text("".join(ln for ln in pos.read_text().splitlines(True) if "ref pos" not in ln))
    path = _write(tmp_path, gnss_file=pos.name, gnss_format="rtklib-pos", **POS_BASE)
    err = _refused(path, capsys)
    assert re.search(r"enu\.pos: aids\[0\]\.file: an e/n/u-baseline solution without", err)
    assert "'% ref pos :'" in err, err


def test_a_pos_time_system_other_than_rtklibs_is_refused(tmp_path):
    """GPST, UTC and JST are read (``test_log_formats``); another is refused."""
    pos = _pos_week(tmp_path)
    pos.write_text(pos.read_text().replace("%  GPST", "%  TAI ", 1))
    path = _write(tmp_path, gnss_file=pos.name, gnss_format="rtklib-pos", **POS_BASE)
    with pytest.raises(ScenarioError, match=r"time column 'TAI', expected 'GPST', 'UTC' or 'JST'"):
        load_recording(path, warn=False)


def test_a_malformed_truth_csv_line_is_refused(tmp_path, capsys):
    """A CSV truth: a bad attitude field by file, line and column; a missing column map
    by its key."""
    rows = ["t,lat,lon,h,vn,ve,vd,roll,pitch,yaw"]
    for ln in _gnss_text()[:400]:
        f = ln.split()
        rows.append(",".join([repr(float(f[0]) + WEEK_START), f[1], f[2], f[3], "0,0,0,0,0,4"]))
    rows[30] = rows[30].rsplit(",", 1)[0] + ",4°"
    (tmp_path / "truth.csv").write_text("\n".join(rows) + "\n")
    truth = (
        '\n[reference]\nsource = "truth"\nfile = "truth.csv"\nformat = "csv"\n'
        'time = { columns = ["t"], unit = "s" }\nlat = { columns = ["lat"], unit = "deg" }\n'
        'lon = { columns = ["lon"], unit = "deg" }\nheight = { columns = ["h"], unit = "m" }\n'
        'velocity = { columns = ["vn", "ve", "vd"], unit = "m/s", frame = "NED" }\n'
        'attitude = { columns = ["roll", "pitch", "yaw"], unit = "deg" }\n'
    )
    path = _write(tmp_path, gnss_offset=float(WEEK_START), **POS_BASE)
    path.write_text(path.read_text() + truth)
    err = _refused(path, capsys)
    assert re.search(r"truth\.csv:31: column yaw: not a number \('4°'\)", err), err
    path.write_text(path.read_text().replace('attitude = { columns = ["roll"', "# ", 1))
    assert _refused(path, capsys).startswith("reference.attitude: missing required key"), err


@pytest.mark.parametrize(
    ("edit", "alignment", "field"),
    [
        (
            ('format = "kfgins-text"\n', 'format = "kfgins-text"\ndelimiter = ","\n'),
            None,
            "imu.delimiter",
        ),
        (
            ("pos_white_sigma_m = 0.05", 'pos_white_sigma_m = 0.05\nrows = "velocity"'),
            None,
            "aids[0].rows",
        ),
        (None, 'mode = "static"\nvelocity_mps = [1.0, 0.0, 0.0]', "alignment.velocity_mps"),
        (
            None,
            GIVEN + "\nvelocity_mps = [0.0, 0.0, 0.0]\nposition_deg_m = [95.0, 0.0, 0.0]",
            "alignment.position_deg_m",
        ),
    ],
)
def test_a_setting_that_cannot_hold_is_refused_naming_its_key(
    tmp_path, capsys, edit, alignment, field
):
    """A CSV key on the KF-GINS preset, velocity rows from a file without velocity, a
    given-only setting on a static start, a start position off the Earth."""
    path = _write(tmp_path) if alignment is None else _write(tmp_path, alignment=alignment)
    if edit is not None:
        text = path.read_text()
        assert edit[0] in text
        path.write_text(text.replace(*edit, 1))
    assert _refused(path, capsys).startswith(f"{field}: "), field


# --- a moving start from a position-only log --------------------------------------------


def test_a_position_only_log_moving_from_the_start_runs_from_a_given_velocity(tmp_path, capsys):
    """The drive from 60 s on (moving at 8.7 m/s), its fixes without velocity: refused
    without ``velocity_mps`` (the refusal names it), processed with the receiver's
    velocity there, the course as heading and pitch and roll 0: 0.2 m RMS from the fixes
    over the minute (bounded at 0.5 m; the built-in, aligned at rest, 0.07 m)."""
    _, cols, rows = _pos_parts()
    sow = np.array([float(_sow(f[0], f[1])) for f in rows])
    v_neu = np.array(
        [[float(f[cols.index(n) + 1]) for n in ("vn(m/s)", "ve(m/s)", "vu(m/s)")] for f in rows]
    )
    imu = _imu_text(first=6000, rows=6000)
    t0 = float(imu[0].split()[0]) - 0.20  # the IMU's first stamp after its offset
    k = int(np.flatnonzero(sow >= t0)[0])  # the start fix
    assert np.hypot(*v_neu[k, :2]) > 2.0
    heading = float(np.degrees(np.arctan2(-v_neu[k, 1], v_neu[k, 0])))  # ψ: counter-clockwise
    path = _write(
        tmp_path,
        imu,
        _gnss_text(sow[k]),
        alignment=f'mode = "given"\nattitude_deg = [0.0, 0.0, {heading!r}]',
    )
    err = _refused(path, capsys)
    assert err.startswith("alignment.velocity_mps: the start velocity is unknown"), err
    assert "set velocity_mps = [E, N, U]" in err
    v = [float(v_neu[k, 1]), float(v_neu[k, 0]), float(v_neu[k, 2])]
    path.write_text(path.read_text().replace("attitude_deg", f"velocity_mps = {v!r}\nattitude_deg"))
    loaded = load_recording(path, warn=False)
    assert loaded.alignment.t == pytest.approx(sow[k], abs=1e-6)
    np.testing.assert_array_equal(loaded.alignment.v, v)
    sol = traces_of(loaded)["ckf"].solution
    assert sol is not None and np.isfinite(sol.p).all() and np.isfinite(sol.v).all()
    p = sol.p[0, loaded.reference_index]
    d = p - loaded.reference_p
    north, east = d[:, 0] * 6.37e6, d[:, 1] * 6.37e6 * np.cos(p[:, 0])
    assert np.sqrt(np.mean(north**2 + east**2)) < 0.5
    assert loaded.recording.steps * loaded.recording.dt > 50.0


def test_the_schema_names_the_new_settings(capsys):
    assert main(["schema", "--recording"]) == 0
    text = capsys.readouterr().out
    schema = json.loads(text)
    for word in ("kfgins-text", "whitespace", "velocity_mps", "position_deg_m", "AttitudeColumns"):
        assert word in text, word
    assert schema["title"] == "ftnav recording"
