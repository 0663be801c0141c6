"""The NaveGo ``.mat`` layout and the CSV GNSS layout: malformed input refused in one line
naming the file and field (exit 2, nothing written); a CSV made from the drive's ``.pos``
gives the same solution as the ``.pos`` itself (equivalence oracle).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
from recording_runs import traces_of

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.recording_file import load_recording
from ftnav.io.recording_readers import read_rtklib_pos
from ftnav.recordings import recording_path

NAVEGO = """
kind = "recording"
name = "mini-navego"

[imu]
file = "imu.mat"
format = "navego-mat"

[imu.errors]
gyro_arw = "0.3 deg/sqrt(h)"
accel_vrw = "0.029 m/s/sqrt(h)"
gyro_bias_sd = "0.2 deg/s"
accel_bias_sd = "16 mg"

[[aids]]
type = "gnss"
name = "gnss"
file = "gnss.mat"
format = "navego-mat"

[alignment]
mode = "given"
{alignment}

[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _imu(n=2001, **change):
    t = np.arange(n) * 0.005
    rng = np.random.default_rng(1)
    s = {
        "t": t,
        "fb": np.tile([0.0, 0.0, -9.79], (n, 1)) + rng.normal(0, 0.007, (n, 3)),
        "wb": rng.normal(0, 0.0012, (n, 3)),
        "ini_align": np.array([0.0, 0.0, -0.2618]),
        "ini_align_err": np.radians([0.5, 0.5, 1.0]),
    }
    s.update(change)
    return {k: v for k, v in s.items() if v is not None}


def _gnss(n=51, **change):
    s = {
        "t": np.arange(n) * 0.2,
        "lat": np.full(n, -0.573),
        "lon": np.full(n, -1.2007),
        "h": np.full(n, 700.0),
        "vel": np.zeros((n, 3)),
        "std": np.array([7.87e-7, 9.32e-7, 10.0]),
        "stdv": np.full(3, 0.0514),
    }
    s.update(change)
    return {k: v for k, v in s.items() if v is not None}


def _write(folder: Path, imu=None, gnss=None, alignment="") -> Path:
    sio.savemat(folder / "imu.mat", {"imu2": _imu() if imu is None else imu})
    sio.savemat(folder / "gnss.mat", {"gnss": _gnss() if gnss is None else gnss})
    path = folder / "rec.toml"
    path.write_text(NAVEGO.format(alignment=alignment))
    return path


def test_a_still_navego_log_starts_from_ini_align_and_the_gnss_sigma(tmp_path):
    loaded = load_recording(_write(tmp_path))
    al, rec = loaded.alignment, loaded.recording
    assert np.allclose(al.euler, [0.0, 0.0, 0.2618]) and np.all(al.gyro_bias == 0)
    # σ pitch, roll, yaw from ini_align_err [roll, pitch, yaw]; velocity, position: the fix's
    assert np.allclose(rec.initial_sigma[:6], np.r_[np.radians([0.5, 0.5, 1.0]), [0.0514] * 3])
    assert rec.initial_sigma[8] == 10.0
    assert loaded.truth is None


CASES = [
    ("missing-field", {"imu": _imu(fb=None)}, r"imu\.mat: field fb: missing$"),
    (
        "wrong-shape",
        {"imu": _imu(wb=np.zeros((2001, 2)))},
        r"imu\.mat: field wb: shape 2001 x 2, expected N x 3$",
    ),
    (
        "rows",
        {"imu": _imu(wb=np.zeros((2000, 3)))},
        r"imu\.mat: field wb: 2000 rows, expected 2001",
    ),
    (
        "not-finite",
        {"imu": _imu(fb=np.where(np.arange(2001)[:, None] == 7, np.nan, -9.79) * [0, 0, 1])},
        r"imu\.mat: field fb: not finite",
    ),
    (
        "time-backwards",
        {"imu": _imu(t=np.r_[np.arange(1000) * 0.005, np.arange(1001) * 0.005])},
        r"imu\.mat: field t: sample 1001: time goes backwards",
    ),
    ("gnss-missing-lat", {"gnss": _gnss(lat=None)}, r"gnss\.mat: field lat: missing$"),
    (
        "gnss-bad-std",
        {"gnss": _gnss(std=np.array([1e-6, 1e-6]))},
        r"gnss\.mat: field std: shape 2, expected 3$",
    ),
    (
        "no-ini-align",
        {"imu": _imu(ini_align=None)},
        r"^alignment\.attitude_deg: mode 'given' needs the initial",
    ),
    (
        "static-key-in-given",
        {"alignment": "static_s = 10.0"},
        r"^alignment\.static_s: a setting of mode 'static', not 'given'",
    ),
]


@pytest.mark.parametrize("case", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_navego_input_is_refused_in_one_line(case, tmp_path, capsys):
    change, pattern = case
    path = _write(tmp_path, **change)
    out = tmp_path / "o"
    assert main(["process", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    line = err.strip().removeprefix("ftnav: error: ")
    line = re.sub(rf"^{re.escape(str(path))}:\d+: ", "", line)  # a field: its file and line
    assert re.search(pattern, line), err
    assert not out.exists()


def test_not_a_mat_file_is_refused(tmp_path):
    path = _write(tmp_path)
    (tmp_path / "imu.mat").write_text("t,fb\n1,2\n")
    with pytest.raises(ScenarioError, match=r"imu\.mat: imu\.file: not a MATLAB \.mat file"):
        load_recording(path)


# --- CSV GNSS ------------------------------------------------------------------------

DRIVE = recording_path("rtklib-drive").parent / "data" / "rtklibexplorer" / "drive_0708"
IMU_ROWS, POS_ROWS = 7000, 300  # 70 s of IMU, 75 s of GNSS

MINI_DRIVE = """
kind = "recording"
name = "mini-drive"

[imu]
file = "{imu}"
time = {{ columns = ["t_gpst_unix_s"], unit = "s" }}
accel = {{ columns = ["acc_x_g", "acc_y_g", "acc_z_g"], unit = "g" }}
gyro = {{ columns = ["gyro_x_dps", "gyro_y_dps", "gyro_z_dps"], unit = "deg/s" }}
time_offset_s = -0.125
axes = ["+y", "-x", "+z"]
misalignment_deg = [-6.79, 0.0, -5.35]

[imu.errors]
gyro_arw = "0.0038 deg/s/sqrt(Hz)"
accel_vrw = "70 ug/sqrt(Hz)"
gyro_bias_sd = "0.05 deg/s"
accel_bias_sd = "20 mg"

[[aids]]
{aid}
lever_arm_m = [-0.05, 0.0, 0.0]
pos_white_sigma_m = 0.05
vel_white_sigma_m_s = 0.3

[[aids]]
type = "nhc"

[[methods]]
name = "ckf"
architecture = "centralized"
"""

POS_AID = """type = "gnss"
name = "gnss"
file = "gnss.pos"
"""

CSV_AID = """type = "gnss"
name = "gnss"
file = "gnss.csv"
format = "csv"
time = { columns = ["t"], unit = "s" }
lat = { columns = ["lat"], unit = "deg" }
lon = { columns = ["lon"], unit = "rad" }
height = { columns = ["h"], unit = "m" }
velocity = { columns = ["vn", "ve", "vd"], unit = "m/s", frame = "NED" }
sigma = { columns = ["sdn", "sde", "sdu"], unit = "m", frame = "NEU" }
quality_column = "Q"
"""


def _drive_with_csv_gnss(folder: Path, aid: str = CSV_AID) -> tuple[Path, Path]:
    """The first minute of the vendored drive twice: its GNSS as the ``.pos`` and as a CSV
    written from the same epochs (every value exact; lat in deg, lon in rad, NED)."""
    lines = (DRIVE / "gnss_1934_sf.pos").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("%")]
    (folder / "gnss.pos").write_text(
        "\n".join(head + [ln for ln in lines if not ln.startswith("%")][:POS_ROWS]) + "\n"
    )
    pos = read_rtklib_pos(folder / "gnss.pos")
    rows = ["t,lat,lon,h,vn,ve,vd,sdn,sde,sdu,Q"]
    for i in range(pos.t.size):
        vn, ve, vu = pos.v_neu[i]
        sn, se, su = pos.sigma_neu[i]
        lon = pos.lon_deg[i] * (np.pi / 180.0)
        values = [pos.t[i], pos.lat_deg[i], lon, pos.height_m[i], vn, ve, -vu, sn, se, su]
        rows.append(",".join(repr(float(x)) for x in values) + f",{pos.quality[i]}")
    (folder / "gnss.csv").write_text("\n".join(rows) + "\n")
    imu = (DRIVE / "imu_1934_gpst.csv").read_text().splitlines()[: IMU_ROWS + 1]
    (folder / "imu.csv").write_text("\n".join(imu) + "\n")
    paths = []
    for name, text in (("csv", aid), ("pos", POS_AID)):
        path = folder / f"{name}.toml"
        path.write_text(MINI_DRIVE.format(imu="imu.csv", aid=text))
        paths.append(path)
    return paths[0], paths[1]


def _solution(path: Path) -> np.ndarray:
    tr = traces_of(load_recording(path, methods=["ckf"]))["ckf"]
    return np.concatenate([tr.solution.p[0], tr.solution.v[0], tr.solution.q[0]], -1)


def test_a_csv_gnss_made_from_the_pos_gives_the_pos_solution(tmp_path):
    csv, pos = _drive_with_csv_gnss(tmp_path)
    a, b = _solution(csv), _solution(pos)
    assert a.shape == b.shape and a.shape[0] > 300
    assert np.abs(a - b).max() < 1e-9


CSV_CASES = [
    (
        "missing-column",
        ('["lat"]', '["latitude"]'),
        r"aids\[0\]\.lat\.columns: no column 'latitude'",
    ),
    ("unit-family", ('unit = "deg" }', 'unit = "m" }'), r"aids\[0\]\.lat\.unit: unit 'm' is not"),
    ("velocity-columns", ('["vn", "ve", "vd"]', '["vn", "ve"]'), r"aids\[0\]\.velocity\.columns"),
    ("frame", ('frame = "NED"', 'frame = "XYZ"'), r"aids\[0\]\.velocity\.frame"),
    (
        "csv-key-on-pos",
        ('format = "csv"', 'format = "rtklib-pos"'),
        r"aids\[0\]\.header|aids\[0\]\.time",
    ),
]


@pytest.mark.parametrize("case", [c[1:] for c in CSV_CASES], ids=[c[0] for c in CSV_CASES])
def test_malformed_csv_gnss_is_refused_in_one_line(case, tmp_path):
    (old, new), pattern = case
    csv, _ = _drive_with_csv_gnss(tmp_path, aid=CSV_AID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as exc:
        load_recording(csv)
    assert re.search(pattern, str(exc.value)) and "\n" not in str(exc.value), str(exc.value)
