"""The same log in another format gives the same solution (issue 22): equivalence oracles.

The built-in drive's first 90 s, rewritten in the test into each format a recording
reads, is processed like the built-in (the same settings, the centralized filter) and
must give its solution to 1 mm:

* KF-GINS text (i2Nav-WHU/KF-GINS): the IMU as increments in forward-right-down axes,
  the GNSS as positions and σ N, E, D on GPS seconds of week (no velocity: both runs
  start from a given attitude and velocity, without the GNSS velocity aid);
* RTKLIB ``.pos`` with GPS week and seconds of week, with ECEF positions, velocities and
  covariances, and as an e/n/u-baseline from a ``% ref pos`` base (no velocity);

and a CSV truth written from NaveGo's ``ref.mat`` loads as the ``.mat`` itself.  The
readers' own forms (d m s, UTC, a base in ECEF) are checked on the ``.pos`` alone.
"""

from __future__ import annotations

import math
import tomllib
from decimal import Decimal
from pathlib import Path

import numpy as np
import pymap3d
import pytest
import tomli_w
from recording_runs import drive_copy, traces_of

from ftnav.io.recording_file import load_recording
from ftnav.io.recording_readers import (
    GPS_EPOCH_UNIX_S,
    WEEK_S,
    enu_rotation,
    read_navego_truth,
    read_rtklib_pos,
)
from ftnav.nav.attitude import dcm_to_euler
from ftnav.nav.units import parse_quantity
from ftnav.recordings import navego_dir, recording_path

DRIVE = recording_path("rtklib-drive").parent / "data" / "rtklibexplorer" / "drive_0708"
POS, IMU = DRIVE / "gnss_1934_sf.pos", DRIVE / "imu_1934_gpst.csv"
DURATION_S = 75.0
#: the drive's stamps are GPST as Unix seconds; KF-GINS's are seconds of this GPS week
WEEK = (1752003261 - GPS_EPOCH_UNIX_S) // WEEK_S
WEEK_START = GPS_EPOCH_UNIX_S + WEEK * WEEK_S


def _pos_parts() -> tuple[list[str], list[str], list[list[str]]]:
    """The ``.pos`` as its '%' lines, its columns and its data lines split in fields."""
    lines = POS.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("%")]
    return head, head[-1][1:].split(), [ln.split() for ln in lines if not ln.startswith("%")]


def _sow(date: str, clock: str) -> str:
    """GPS seconds of week of a ``.pos`` calendar time, exactly as a decimal."""
    whole, _, frac = clock.partition(".")
    day = np.datetime64(f"{date.replace('/', '-')}T{whole}").astype("datetime64[s]")
    return str(Decimal(int(day.astype(np.int64)) - WEEK_START) + Decimal(f"0.{frac or 0}"))


def _r(x: float) -> str:
    return repr(float(x))


def _sqvar(c: np.ndarray) -> np.ndarray:
    """RTKLIB's signed square root of a covariance."""
    return np.sign(c) * np.sqrt(np.abs(c))


# --- the drive rewritten --------------------------------------------------------------


def _pos_week(folder: Path) -> Path:
    """The ``.pos`` with GPS week and seconds of week instead of the calendar time."""
    head, _, rows = _pos_parts()
    out = [*head, *(" ".join([str(WEEK), _sow(f[0], f[1]), *f[2:]]) for f in rows)]
    (folder / "week.pos").write_text("\n".join(out) + "\n")
    return folder / "week.pos"


def _enu_covariances(cols: list[str], rows: list[list[str]], names: tuple[str, ...]):
    """(K, 3, 3) ENU covariances of the σ columns ``names`` (N, E, U, NE, EU, UN)."""
    v = np.array([[float(f[cols.index(n) + 1]) for n in names] for f in rows])
    sn, se, su, ne, eu, un = v.T
    C = np.zeros((len(rows), 3, 3))
    C[:, 0, 0], C[:, 1, 1], C[:, 2, 2] = se**2, sn**2, su**2
    C[:, 0, 1] = C[:, 1, 0] = ne * np.abs(ne)
    C[:, 0, 2] = C[:, 2, 0] = eu * np.abs(eu)
    C[:, 1, 2] = C[:, 2, 1] = un * np.abs(un)
    return C


def _covariance_cells(C: np.ndarray) -> list[str]:
    """RTKLIB's six σ columns of a covariance: σ of the axes, then the signed square roots
    of the covariances (0, 1), (1, 2), (2, 0)."""
    sd = [_r(math.sqrt(C[i, i])) for i in range(3)]
    return sd + [_r(_sqvar(C[i, j])) for i, j in ((0, 1), (1, 2), (2, 0))]


def _pos_ecef(folder: Path) -> Path:
    """The ``.pos`` as RTKLIB's x/y/z-ecef with velocity: positions, velocities and their
    full covariances in ECEF."""
    _, cols, rows = _pos_parts()
    pos = read_rtklib_pos(POS)
    x, y, z = pymap3d.geodetic2ecef(pos.lat_deg, pos.lon_deg, pos.height_m)
    R = enu_rotation(pos.lat_deg, pos.lon_deg)
    P = _enu_covariances(
        cols, rows, ("sdn(m)", "sde(m)", "sdu(m)", "sdne(m)", "sdeu(m)", "sdun(m)")
    )
    V = _enu_covariances(cols, rows, ("sdvn", "sdve", "sdvu", "sdvne", "sdveu", "sdvun"))
    v = np.einsum("kji,kj->ki", R, pos.v_neu[:, [1, 0, 2]])  # Rᵀ v_ENU
    head = (
        "%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)"
        "   sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio    vx(m/s)    vy(m/s)"
        "    vz(m/s)      sdvx     sdvy     sdvz    sdvxy    sdvyz    sdvzx"
    )
    out = ["% (x/y/z-ecef=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)"]
    out.append(head)
    for k, f in enumerate(rows):
        cell = {n: f[cols.index(n) + 1] for n in ("Q", "ns", "age(s)", "ratio")}
        cells = [f[0], f[1], _r(x[k]), _r(y[k]), _r(z[k]), cell["Q"], cell["ns"]]
        cells += _covariance_cells(R[k].T @ P[k] @ R[k]) + [cell["age(s)"], cell["ratio"]]
        cells += [_r(c) for c in v[k]] + _covariance_cells(R[k].T @ V[k] @ R[k])
        out.append(" ".join(cells))
    (folder / "ecef.pos").write_text("\n".join(out) + "\n")
    return folder / "ecef.pos"


BASE_LLH = (40.0, -105.1, 1600.0)  # a base 11 km south of the drive


def _pos_enu(folder: Path, ref: str = "llh") -> Path:
    """The ``.pos`` as RTKLIB's e/n/u-baseline from a base named in ``% ref pos``
    (``ref``: as lat lon h or as ECEF x y z), position covariances in the base's ENU."""
    _, cols, rows = _pos_parts()
    pos = read_rtklib_pos(POS)
    e, n, u = pymap3d.geodetic2enu(pos.lat_deg, pos.lon_deg, pos.height_m, *BASE_LLH)
    R = enu_rotation(pos.lat_deg, pos.lon_deg)
    Rb = enu_rotation(np.array(BASE_LLH[0]), np.array(BASE_LLH[1]))
    P = _enu_covariances(
        cols, rows, ("sdn(m)", "sde(m)", "sdu(m)", "sdne(m)", "sdeu(m)", "sdun(m)")
    )
    if ref == "llh":
        line = "% ref pos   :  " + "  ".join(_r(c) for c in BASE_LLH)
    else:
        line = "% ref pos   :  " + "  ".join(_r(c) for c in pymap3d.geodetic2ecef(*BASE_LLH))
    out = [
        "% program   : RTKPOST ver.2.4.3 (written by the test)",
        line,
        "%",
        "% (e/n/u-baseline=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)",
        "%  GPST                  e-baseline(m)  n-baseline(m)  u-baseline(m)   Q  ns   sde(m)"
        "   sdn(m)   sdu(m)  sden(m)  sdnu(m)  sdue(m) age(s)  ratio",
    ]
    for k, f in enumerate(rows):
        cell = {n: f[cols.index(n) + 1] for n in ("Q", "ns", "age(s)", "ratio")}
        B = Rb @ R[k].T @ P[k] @ R[k] @ Rb.T  # rover ENU -> ECEF -> base ENU
        cells = [f[0], f[1], _r(e[k]), _r(n[k]), _r(u[k]), cell["Q"], cell["ns"]]
        cells += _covariance_cells(B) + [cell["age(s)"], cell["ratio"]]
        out.append(" ".join(cells))
    (folder / "enu.pos").write_text("\n".join(out) + "\n")
    return folder / "enu.pos"


def _kfgins(folder: Path, imu_offset_s: float) -> tuple[Path, Path]:
    """The drive as KF-GINS text: the IMU as increments over each interval in
    forward-right-down axes (the built-in's sensor axes are x back, y right, z up:
    FRD = [−x, y, −z]), the RTK fixes (Q = 1) with σ N, E, D; GPS seconds of week.

    The built-in reader drops the IMU's stale repeats (every value as the row before) and
    repeated stamps, the next sample's rate then holding over both intervals; a log of
    increments has no repeats, so they are left out here and the next increment spans
    both intervals.  Each interval is the one the reader computes from the stamps it
    reads (seconds of week plus ``imu_offset_s``)."""
    lines = IMU.read_text().splitlines()[1:]
    raw = np.array([ln.split(",") for ln in lines], dtype=float)
    keep = np.ones(len(raw), bool)
    keep[1:] = ~(np.all(raw[1:, 1:7] == raw[:-1, 1:7], 1) | (raw[1:, 0] == raw[:-1, 0]))
    sow = [
        str(Decimal(ln.split(",", 1)[0]) - WEEK_START)
        for ln, k in zip(lines, keep, strict=True)
        if k
    ]
    raw = raw[keep]
    t = np.array([float(s) for s in sow]) * 1.0 + imu_offset_s
    dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
    accel = raw[:, 1:4] * parse_quantity("1 g", "acceleration", "g") * [-1.0, 1.0, -1.0]
    gyro = raw[:, 4:7] * parse_quantity("1 deg/s", "angular_rate", "deg/s") * [-1.0, 1.0, -1.0]
    dth, dv = gyro * dt[:, None], accel * dt[:, None]
    imu = [" ".join([s, *(_r(c) for c in (*a, *b))]) for s, a, b in zip(sow, dth, dv, strict=True)]
    (folder / "imu.txt").write_text("\n".join(["# KF-GINS IMU (written by the test)", *imu]) + "\n")
    _, cols, rows = _pos_parts()
    gnss = []
    for f in rows:
        if float(f[cols.index("Q") + 1]) != 1.0:
            continue
        c = [f[cols.index(n) + 1] for n in ("latitude(deg)", "longitude(deg)", "height(m)")]
        s = [f[cols.index(n) + 1] for n in ("sdn(m)", "sde(m)", "sdu(m)")]
        gnss.append("    ".join([_sow(f[0], f[1]), *c, *s]) + " ")
    (folder / "gnss.txt").write_text("\n".join(gnss) + "\n")
    return folder / "imu.txt", folder / "gnss.txt"


# --- processing -----------------------------------------------------------------------


def _short(doc: dict) -> None:
    doc["filter"]["duration_s"] = DURATION_S
    doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]


@pytest.fixture(scope="module")
def start() -> dict:
    """The built-in's static alignment, for runs that start from a given attitude."""
    loaded = load_recording(recording_path("rtklib-drive"), warn=False, methods=["ckf"])
    return {"attitude_deg": [float(a) for a in np.degrees(loaded.alignment.euler)]}


def _given(start: dict):
    """The drive without GNSS velocities: the velocity aid off, started from the
    built-in's attitude at rest."""

    def edit(doc: dict) -> None:
        _short(doc)
        doc["aids"] = [a for a in doc["aids"] if a.get("name") != "gnss-vel"]
        doc["alignment"] = {
            "mode": "given",
            "attitude_deg": start["attitude_deg"],
            "velocity_mps": [0.0, 0.0, 0.0],
            "attitude_sigma_deg": [1.0, 1.0, 10.0],
        }

    return edit


def _solution(path: Path) -> dict[str, np.ndarray]:
    loaded = load_recording(path, warn=False)
    rec = loaded.recording
    sol = traces_of(loaded)["ckf"].solution
    assert sol is not None
    return {"t": rec.t_start + rec.times, "p": sol.p[0], "v": sol.v[0], "q": sol.q[0]}


def _assert_same(a: dict, b: dict) -> None:
    """The same epochs and the same solution: position and velocity to 1 mm (m/s)."""
    assert a["t"].shape == b["t"].shape
    np.testing.assert_allclose(a["t"], b["t"], rtol=0, atol=1e-6)
    L = a["p"][:, 0]
    d = a["p"] - b["p"]
    metres = np.stack([d[:, 0] * 6.37e6, d[:, 1] * 6.37e6 * np.cos(L), d[:, 2]], -1)
    assert np.abs(metres).max() < 1e-3, np.abs(metres).max()
    assert np.abs(a["v"] - b["v"]).max() < 1e-3
    assert np.abs(a["q"] - b["q"]).max() < 1e-6


@pytest.fixture(scope="module")
def builtin(tmp_path_factory) -> dict:
    path = drive_copy(tmp_path_factory.mktemp("builtin") / "rec.toml", _short)
    return _solution(path)


@pytest.fixture(scope="module")
def builtin_given(tmp_path_factory, start) -> dict:
    path = drive_copy(tmp_path_factory.mktemp("given") / "rec.toml", _given(start))
    return _solution(path)


@pytest.mark.parametrize("form", ["week", "ecef"])
def test_a_pos_in_week_seconds_or_ecef_gives_the_builtin_solution(tmp_path, builtin, form):
    """Both GNSS aids (positions, velocities) read the rewritten file; the alignment is
    the built-in's static one (it reads the GNSS course)."""
    pos = _pos_week(tmp_path) if form == "week" else _pos_ecef(tmp_path)

    def edit(doc: dict) -> None:
        _short(doc)
        for a in doc["aids"]:
            if a["type"] == "gnss":
                a["file"] = str(pos)

    _assert_same(_solution(drive_copy(tmp_path / "rec.toml", edit)), builtin)


def test_an_enu_baseline_pos_gives_the_builtin_solution(tmp_path, builtin_given, start):
    pos = _pos_enu(tmp_path)

    def edit(doc: dict) -> None:
        _given(start)(doc)
        doc["aids"][0]["file"] = str(pos)

    _assert_same(_solution(drive_copy(tmp_path / "rec.toml", edit)), builtin_given)


def test_kfgins_text_gives_the_builtin_solution(tmp_path, builtin_given, start):
    """The preset's default axes (forward-right-down) and increments; the time offsets put
    the seconds of week on the built-in's time base (GPST as Unix seconds)."""
    offset = float(WEEK_START) - 0.20  # the built-in's imu.time_offset_s
    imu, gnss = _kfgins(tmp_path, offset)

    def edit(doc: dict) -> None:
        _given(start)(doc)
        old = doc["imu"]
        doc["imu"] = {
            "file": str(imu),
            "format": "kfgins-text",
            "time_offset_s": offset,
            "misalignment_deg": old["misalignment_deg"],
            "errors": old["errors"],
        }
        g = doc["aids"][0]
        g.update(file=str(gnss), format="kfgins-text", time_offset_s=float(WEEK_START))

    path = drive_copy(tmp_path / "rec.toml", edit)
    loaded = load_recording(path, warn=False)
    assert loaded.recording.aids[0].sensor.rows == "position"
    _assert_same(_solution(path), builtin_given)


# --- the .pos forms on the reader alone ------------------------------------------------


def _pos_differences(a, b, atol_m: float = 1e-6) -> list[str]:
    """The fields of two read ``.pos`` files that differ beyond ``atol_m`` (time and
    quality exactly; σ to 1e-9 m); empty when they are the same fixes."""
    if a.t.shape != b.t.shape:
        return [f"shape {a.t.shape} != {b.t.shape}"]
    tol = {
        "lat_deg": atol_m / 111e3,
        "lon_deg": atol_m / 85e3,
        "height_m": atol_m,
        "sigma_neu": 1e-9,
    }
    out = [f for f in ("t", "quality") if not np.array_equal(getattr(a, f), getattr(b, f))]
    return out + [
        f
        for f, atol in tol.items()
        if not np.allclose(getattr(a, f), getattr(b, f), 0, atol, equal_nan=True)
    ]


def test_pos_time_forms_and_systems_read_as_one_gpst(tmp_path):
    """GPS week and seconds, UTC (GPST − 18 s in 2025) and JST (UTC + 9 h) all read as
    the calendar GPST, to the bit."""
    ref = read_rtklib_pos(POS)
    assert not _pos_differences(read_rtklib_pos(_pos_week(tmp_path)), ref, 0.0)
    head, _, rows = _pos_parts()
    for system, shift in (("UTC", -18), ("JST", 9 * 3600 - 18)):
        out = [*head[:-1], head[-1].replace("GPST", system)]
        for f in rows:
            day = np.datetime64(f"{f[0].replace('/', '-')}T{f[1]}") + np.timedelta64(shift, "s")
            date, clock = str(day).split("T")
            out.append(" ".join([date.replace("-", "/"), clock, *f[2:]]))
        (tmp_path / f"{system}.pos").write_text("\n".join(out) + "\n")
        assert not _pos_differences(read_rtklib_pos(tmp_path / f"{system}.pos"), ref, 0.0)


def test_pos_position_forms_read_as_the_llh(tmp_path):
    """ECEF (with its velocity), an ENU baseline from a base given as lat/lon/h or as
    ECEF, and lat/lon in d m s: the same fixes, σ and velocities."""
    ref = read_rtklib_pos(POS)
    ecef = read_rtklib_pos(_pos_ecef(tmp_path))
    assert not _pos_differences(ecef, ref, 1e-6)
    np.testing.assert_allclose(ecef.v_neu, ref.v_neu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ecef.sigma_v_neu, ref.sigma_v_neu, rtol=0, atol=1e-9)
    for base in ("llh", "ecef"):
        enu = read_rtklib_pos(_pos_enu(tmp_path, base))
        assert not _pos_differences(enu, ref, 1e-6)
        assert np.isnan(enu.v_neu).all()
    head, _, rows = _pos_parts()
    out = [*head[:-1], head[-1].replace("latitude(deg)", "latitude(d'\")")]
    out[-1] = out[-1].replace("longitude(deg)", "longitude(d'\")")
    for f in rows:
        dms = []
        for deg in (float(f[2]), float(f[3])):
            a = abs(deg)
            d, m = math.floor(a), math.floor((a - math.floor(a)) * 60)
            s = (a - d - m / 60) * 3600
            dms += [("-" if deg < 0 else "") + f"{d:d}", f"{m:02d}", repr(s)]
        out.append(" ".join([f[0], f[1], *dms, *f[4:]]))
    (tmp_path / "dms.pos").write_text("\n".join(out) + "\n")
    assert not _pos_differences(read_rtklib_pos(tmp_path / "dms.pos"), ref, 1e-6)


# --- a CSV truth ------------------------------------------------------------------------

NAVEGO = navego_dir()


@pytest.mark.skipif(
    not all((NAVEGO / f).is_file() for f in ("imu2.mat", "gnss.mat", "ref.mat")),
    reason=f"NaveGo data absent from {NAVEGO} (or set FTNAV_NAVEGO_DIR)",
)
def test_a_csv_truth_loads_as_the_navego_mat(tmp_path):
    """NaveGo's ``ref.mat`` written as a CSV (deg, NED velocity, roll/pitch/yaw deg as in
    ``solution.csv``) gives the same truth at the filter epochs, and the same IMU biases
    fitted against it."""
    tr = read_navego_truth(NAVEGO / "ref.mat")
    theta, gamma, psi = dcm_to_euler(tr.C).T
    rows = ["t,lat_deg,lon_deg,h_m,vn,ve,vd,roll_deg,pitch_deg,yaw_deg"]
    lat, lon = np.degrees(tr.p[:, 0]), np.degrees(tr.p[:, 1])
    att = np.degrees(np.stack([gamma, theta, -psi], -1))
    for k in range(tr.t.size):
        v = (tr.v[k, 1], tr.v[k, 0], -tr.v[k, 2])
        rows.append(",".join(_r(x) for x in (tr.t[k], lat[k], lon[k], tr.p[k, 2], *v, *att[k])))
    (tmp_path / "truth.csv").write_text("\n".join(rows) + "\n")
    src = recording_path("navego-adis16488")
    doc = tomllib.loads(src.read_text())
    for key in ("imu", "reference"):
        doc[key]["file"] = str(NAVEGO / Path(doc[key]["file"]).name)
    doc["aids"][0]["file"] = str(NAVEGO / "gnss.mat")
    doc["filter"]["duration_s"] = 60.0
    doc["methods"] = doc["methods"][:1]
    (tmp_path / "mat.toml").write_text(tomli_w.dumps(doc))
    doc["reference"] = {
        "source": "truth",
        "file": str(tmp_path / "truth.csv"),
        "format": "csv",
        "time": {"columns": ["t"], "unit": "s"},
        "lat": {"columns": ["lat_deg"], "unit": "deg"},
        "lon": {"columns": ["lon_deg"], "unit": "deg"},
        "height": {"columns": ["h_m"], "unit": "m"},
        "velocity": {"columns": ["vn", "ve", "vd"], "unit": "m/s", "frame": "NED"},
        "attitude": {"columns": ["roll_deg", "pitch_deg", "yaw_deg"], "unit": "deg"},
    }
    (tmp_path / "csv.toml").write_text(tomli_w.dumps(doc))
    a = load_recording(tmp_path / "mat.toml", warn=False).truth
    b = load_recording(tmp_path / "csv.toml", warn=False).truth
    assert a is not None and b is not None
    np.testing.assert_array_equal(a.index, b.index)
    np.testing.assert_allclose(b.p[:, :2], a.p[:, :2], rtol=0, atol=1e-14)
    for name in ("v", "C", "gyro_bias", "accel_bias"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), rtol=0, atol=1e-9)
    np.testing.assert_allclose(b.p[:, 2], a.p[:, 2], rtol=0, atol=1e-9)
