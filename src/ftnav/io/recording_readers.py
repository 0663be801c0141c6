"""Readers of recorded sensor files: IMU CSV, RTKLIB ``.pos`` solutions, NaveGo ``.mat``.

Every problem is refused with one line ``<file>:<line>: <what>`` (a
:class:`~ftnav.io.common.ScenarioError` whose path is the file and line), or handled
and counted:

* a first or last line with fewer fields than the others (a log cut mid-line) is
  dropped and counted; such a line anywhere else is refused;
* a field that is not a number (Python's ``float`` would take ``1_0`` as 10: an
  underscore is refused), NaN or infinite is refused with its line and column name;
* a ``.pos`` file is held to the CSV reader's rules: σ ≥ 0, ``Q`` an integer flag 1-6,
  ``ns`` an integer ≥ 0; latitude within ±90°, longitude within ±180° and height
  within [:data:`HEIGHT_MIN_M`, :data:`HEIGHT_MAX_M`] in every GNSS reader
  (:func:`check_position`);
* a FIFO, a device, a folder or a file above the input limit is refused before it is
  read (:func:`ftnav.io.common.read_input`); a UTF-8 byte-order mark is dropped;
* IMU time stamps that go backwards are refused; repeated stamps and stale rows are
  dropped later and counted (:func:`ftnav.recorded.imu.clean`);
* ``.pos`` epochs out of order or duplicated are sorted or dropped and counted
  (:func:`ftnav.recorded.stream.on_grid`);
* a NaveGo ``.mat`` struct (:func:`read_navego_imu`, :func:`read_navego_gnss`,
  :func:`read_navego_truth`) missing a field, with a field of the wrong shape or with
  a non-finite value is refused with one line ``<file>: field <name>: <what>``; a
  MATLAB v7.3 (HDF5) file is refused (``scipy`` reads v5: save with ``-v7``).

NaveGo's frames (R. Gonzalez et al., "NaveGo", JCEAI 17(2), 2015): body x forward,
y right, z down; navigation NED; attitude roll, pitch, yaw (ZYX).  ftnav's
(``docs/conventions.md``): body x right, y forward, z up; navigation ENU; Euler
``[θ pitch, γ roll, ψ yaw]`` with ``C_b^n = R_z(ψ) R_x(θ) R_y(γ)`` and ψ
counter-clockwise.  Both swaps are the one symmetric matrix :data:`FRD_TO_RFU`
(``[y, x, −z]``), so ``C_b^n(ftnav) = M C_b^n(NaveGo) M``: pitch and roll keep their
values and ψ = −yaw (checked against the reference's DCM in
``tests/reference/test_recorded_navego.py``).
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from scipy.io import loadmat
from scipy.io.matlab import MatReadError

from ftnav.io.common import ScenarioError, read_input, read_text
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.earth import radii

__all__ = [
    "FRD_TO_RFU",
    "NavegoGnss",
    "NavegoImu",
    "NavegoTruth",
    "PosFile",
    "Table",
    "check_position",
    "read_csv",
    "read_navego_gnss",
    "read_navego_imu",
    "read_navego_truth",
    "read_rtklib_pos",
]


class Table(NamedTuple):
    """Numeric columns of a delimited text file.

    Attributes
    ----------
    columns : column names (the header's, or ``"0"``, ``"1"``, … without one).
    values : (rows, columns) float.  lines : (rows,) 1-based line numbers.
    dropped_partial : first/last lines dropped for having too few fields.
    """

    columns: tuple[str, ...]
    values: np.ndarray
    lines: np.ndarray
    dropped_partial: int


#: Lowest and highest ellipsoidal height (m) of a GNSS fix: the Dead Sea shore (−430 m)
#: plus the lowest geoid undulation (−106 m) with a margin; the edge of space (100 km)
HEIGHT_MIN_M, HEIGHT_MAX_M = -1000.0, 100e3


def _lines(path: Path, what: str) -> list[str]:
    return read_text(path, what).splitlines()


def _number(text: str, path: Path, line: int, column: str) -> float:
    """A finite number as written (``float`` also takes ``1_0``, ``nan``, ``inf``)."""
    try:
        if "_" in text:
            raise ValueError
        value = float(text)
    except ValueError:
        raise ScenarioError(
            f"{path}:{line}", f"column {column}: not a number ({text.strip()[:30]!r})"
        ) from None
    if not math.isfinite(value):
        raise ScenarioError(f"{path}:{line}", f"column {column}: not finite ({text.strip()!r})")
    return value


def check_position(
    lat_deg: np.ndarray, lon_deg: np.ndarray, height_m: np.ndarray, where: Any
) -> None:
    """Refuse the first fix off the Earth: ``|lat| > 90°``, ``|lon| > 180°`` or a height
    outside [:data:`HEIGHT_MIN_M`, :data:`HEIGHT_MAX_M`]; ``where(row, column)`` names the
    place (``(path, reason prefix)``)."""
    for name, a, lo, hi, unit in (
        ("lat", lat_deg, -90.0, 90.0, "deg"),
        ("lon", lon_deg, -180.0, 180.0, "deg"),
        ("height", height_m, HEIGHT_MIN_M, HEIGHT_MAX_M, "m"),
    ):
        bad = np.flatnonzero(~((a >= lo) & (a <= hi)))
        if bad.size:
            r = int(bad[0])
            path, column = where(r, name)
            what = {"lat": "latitude", "lon": "longitude", "height": "height"}[name]
            raise ScenarioError(
                path, f"{column}: {what} {a[r]:.6g} {unit} is outside [{lo:g}, {hi:g}] {unit}"
            )


def _first_bad(split: list[tuple[int, list[str]]], names: Sequence[str], path: Path) -> None:
    """Refuse the first field of ``split`` that is not a number as written."""
    for n, fields in split:
        for name, text in zip(names, fields, strict=True):
            _number(text, path, n, name)


def read_csv(path: Path, header: bool, delimiter: str, what: str) -> Table:
    """A delimited file of numbers (module docstring)."""
    lines = _lines(path, what)
    rows = [(i + 1, ln) for i, ln in enumerate(lines) if ln.strip()]
    if header:
        if not rows:
            raise ScenarioError(str(path), f"{what}: empty file (no header line)")
        names = tuple(c.strip() for c in rows[0][1].split(delimiter))
        rows = rows[1:]
    if not rows:
        raise ScenarioError(str(path), f"{what}: no data rows")
    split = [(n, ln.split(delimiter)) for n, ln in rows]
    width = len(names) if header else max(len(f) for _, f in split[1:-1] or split)
    if not header:
        names = tuple(str(j) for j in range(width))
    dropped = 0
    for end in (0, -1):
        if split and len(split[end][1]) < width:
            split.pop(end)
            dropped += 1
    if not split:
        raise ScenarioError(str(path), f"{what}: no complete data rows")
    for n, fields in split:
        if len(fields) != width:
            raise ScenarioError(f"{path}:{n}", f"expected {width} fields, got {len(fields)}")
    if any("_" in ln for _, ln in rows):  # float() reads 1_0 as 10
        _first_bad(split, names, path)
    try:
        values = np.array([f for _, f in split], dtype=float)
    except ValueError:  # find the culprit for the message
        _first_bad(split, names, path)
        raise
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ScenarioError(f"{path}:{split[r][0]}", f"column {names[c]}: not finite")
    return Table(names, values, np.array([n for n, _ in split]), dropped)


class PosFile(NamedTuple):
    """An RTKLIB solution: time (s, GPST as Unix seconds), ``lat``/``lon`` (deg), height
    (m), quality flag, σ N, E, U (m), velocity N, E, U (m/s) and its σ (m/s; NaN when
    absent)."""

    t: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    height_m: np.ndarray
    quality: np.ndarray
    sigma_neu: np.ndarray
    v_neu: np.ndarray
    lines: np.ndarray
    sigma_v_neu: np.ndarray | None = None


_POS_REQUIRED = ("latitude(deg)", "longitude(deg)", "height(m)", "Q", "sdn(m)", "sde(m)", "sdu(m)")
_POS_VELOCITY = ("vn(m/s)", "ve(m/s)", "vu(m/s)")
_POS_VELOCITY_SIGMA = ("sdvn", "sdve", "sdvu")


def _pos_time(date: str, time: str, path: Path, line: int) -> float:
    try:
        stamp = datetime.strptime(f"{date} {time}", "%Y/%m/%d %H:%M:%S.%f")
    except ValueError:
        raise ScenarioError(
            f"{path}:{line}", f"column GPST: not a 'YYYY/MM/DD hh:mm:ss.sss' time ({date} {time})"
        ) from None
    return stamp.replace(tzinfo=UTC).timestamp()


def read_rtklib_pos(path: Path, what: str = "gnss") -> PosFile:
    """An RTKLIB ``.pos`` file in ``YYYY/MM/DD hh:mm:ss.sss`` GPST with lat/lon/height
    (module docstring).  The last ``%`` line before the data must name the columns."""
    lines = _lines(path, what)
    header: Sequence[str] | None = None
    data: list[tuple[int, list[str]]] = []
    for i, ln in enumerate(lines):
        if ln.startswith("%"):
            if "latitude(deg)" in ln:
                header = ln[1:].split()
            continue
        if ln.strip():
            data.append((i + 1, ln.split()))
    if header is None:
        raise ScenarioError(
            str(path),
            f"{what}: no '%' header line naming the columns (GPST latitude(deg) longitude(deg) "
            "height(m) Q ...): write the solution with RTKLIB's header on and lat/lon/height",
        )
    if header[0] != "GPST":
        raise ScenarioError(str(path), f"{what}: time column {header[0]!r}, expected 'GPST'")
    missing = [c for c in _POS_REQUIRED if c not in header]
    if missing:
        raise ScenarioError(str(path), f"{what}: the header has no column {missing[0]!r}")
    if not data:
        raise ScenarioError(str(path), f"{what}: no solution epochs")
    col = {name: j + 1 for j, name in enumerate(header[1:])}  # the date and time take two
    width = len(header) + 1
    for end in (0, -1):
        if data and len(data[end][1]) < width:
            data.pop(end)
    out = np.empty((len(data), width - 2))
    t = np.empty(len(data))
    for r, (n, fields) in enumerate(data):
        if len(fields) < width:
            raise ScenarioError(f"{path}:{n}", f"expected {width} fields, got {len(fields)}")
        t[r] = _pos_time(fields[0], fields[1], path, n)
        try:
            if any("_" in f for f in fields):  # float() reads 1_0 as 10
                raise ValueError
            out[r] = [float(f) for f in fields[2:width]]
        except ValueError:  # find the culprit for the message
            for j, name in enumerate(header[1:]):
                _number(fields[j + 2], path, n, name)
            raise
    bad = ~np.isfinite(out)
    if bad.any():
        r, j = np.argwhere(bad)[0]
        raise ScenarioError(f"{path}:{data[r][0]}", f"column {header[1 + j]}: not finite")

    def c(name: str) -> np.ndarray:
        return out[:, col[name] - 1]

    lines = np.array([n for n, _ in data])

    def refuse(rows: np.ndarray, column: str, reason: str) -> None:
        if rows.any():
            r = int(np.flatnonzero(rows)[0])
            raise ScenarioError(
                f"{path}:{lines[r]}", f"column {column}: {reason} ({c(column)[r]:g})"
            )

    for name in (*_POS_REQUIRED[4:], *_POS_VELOCITY_SIGMA):
        if name in col:
            refuse(c(name) < 0, name, "a σ must be >= 0")
    q = c("Q")
    refuse((q != np.round(q)) | (q < 1) | (q > 6), "Q", "not an RTKLIB solution flag 1-6")
    if "ns" in col:
        ns = c("ns")
        refuse((ns != np.round(ns)) | (ns < 0), "ns", "not a satellite count")
    names = {"lat": "latitude(deg)", "lon": "longitude(deg)", "height": "height(m)"}
    check_position(
        c("latitude(deg)"),
        c("longitude(deg)"),
        c("height(m)"),
        lambda r, name: (f"{path}:{lines[r]}", f"column {names[name]}"),
    )

    v = (
        np.stack([c(n) for n in _POS_VELOCITY], -1)
        if all(n in col for n in _POS_VELOCITY)
        else np.full((len(data), 3), np.nan)
    )
    sv = (
        np.stack([c(n) for n in _POS_VELOCITY_SIGMA], -1)
        if all(n in col for n in _POS_VELOCITY_SIGMA)
        else np.full((len(data), 3), np.nan)
    )
    return PosFile(
        t,
        c("latitude(deg)"),
        c("longitude(deg)"),
        c("height(m)"),
        c("Q").astype(int),
        np.stack([c("sdn(m)"), c("sde(m)"), c("sdu(m)")], -1),
        v,
        lines,
        sv,
    )


# --- NaveGo .mat (module docstring) -------------------------------------------------

#: body FRD → RFU and navigation NED → ENU (both ``[y, x, −z]``; symmetric, its own inverse)
FRD_TO_RFU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _mat_struct(path: Path, what: str) -> tuple[Any, str]:
    """The one struct of a MATLAB v5 file (``scipy.io.loadmat``) and its variable name."""
    raw = read_input(path, what)
    if raw.startswith(b"MATLAB 7.3") or raw[512:520] == b"\x89HDF\r\n\x1a\n":
        raise ScenarioError(
            str(path), f"{what}: MATLAB v7.3 (HDF5) files are not supported: save with -v7"
        )
    try:
        data = loadmat(io.BytesIO(raw), squeeze_me=True, struct_as_record=False)
    except (OSError, ValueError, TypeError, EOFError, MatReadError) as exc:
        reason = " ".join(str(exc).split())[:120]
        raise ScenarioError(str(path), f"{what}: not a MATLAB .mat file ({reason})") from None
    names = [k for k in data if not k.startswith("__")]
    structs = [k for k in names if hasattr(data[k], "_fieldnames")]
    if len(structs) != 1:
        raise ScenarioError(
            str(path),
            f"{what}: expected one struct (NaveGo layout), found {len(structs)} "
            f"(variables: {', '.join(names) or 'none'})",
        )
    return data[structs[0]], structs[0]


def _mat_field(
    s: Any, path: Path, name: str, shape: tuple[int | None, ...], required: bool = True
) -> np.ndarray | None:
    """Field ``name`` of a struct as float, of ``shape`` (None: any length); checked."""
    if name not in s._fieldnames:
        if not required:
            return None
        raise ScenarioError(str(path), f"field {name}: missing")
    try:
        a = np.asarray(getattr(s, name), dtype=float)
    except (TypeError, ValueError):
        raise ScenarioError(str(path), f"field {name}: not numeric") from None
    if a.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(a.shape, shape, strict=True)
    ):
        dims = " x ".join("N" if d is None else str(d) for d in shape) or "a scalar"
        got = " x ".join(str(d) for d in a.shape) or "a scalar"
        raise ScenarioError(str(path), f"field {name}: shape {got}, expected {dims}")
    if not np.isfinite(a).all():
        raise ScenarioError(str(path), f"field {name}: not finite (NaN or inf)")
    return a


def _same_length(path: Path, n: int, **arrays: np.ndarray) -> None:
    for name, a in arrays.items():
        if a.shape[0] != n:
            raise ScenarioError(
                str(path), f"field {name}: {a.shape[0]} rows, expected {n} (as many as t)"
            )


def _times(s: Any, path: Path) -> np.ndarray:
    t = _mat_field(s, path, "t", (None,))
    assert t is not None
    if t.size < 2:
        raise ScenarioError(str(path), f"field t: {t.size} sample(s)")
    return t


def _euler_from_navego(rpy: np.ndarray) -> np.ndarray:
    """ftnav ``[θ, γ, ψ]`` from NaveGo's ``[roll, pitch, yaw]`` (module docstring)."""
    rpy = np.asarray(rpy, float)
    return np.stack([rpy[..., 1], rpy[..., 0], -rpy[..., 2]], -1)


class NavegoImu(NamedTuple):
    """A NaveGo IMU struct in ftnav's frames.

    Attributes
    ----------
    t : (N,) s.  gyro : (N, 3) rad/s, accel : (N, 3) m/s², body x right, y forward, z up.
    euler : (3,) ``[θ, γ, ψ]`` rad of ``ini_align`` (the true initial attitude), or None.
    euler_sigma : (3,) σ pitch, roll, yaw (rad) of ``ini_align_err``, or None.
    gyro_bias_nominal, accel_bias_nominal : (3,) ``gb_sta``, ``ab_sta`` in ftnav's body
        axes (the z axis changes sign), or None.
    """

    t: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    euler: np.ndarray | None
    euler_sigma: np.ndarray | None
    gyro_bias_nominal: np.ndarray | None
    accel_bias_nominal: np.ndarray | None


def read_navego_imu(path: Path, what: str = "imu") -> NavegoImu:
    """A NaveGo IMU struct (``imu1.mat``): ``t``, ``fb``, ``wb`` and the optional
    ``ini_align``, ``ini_align_err``, ``gb_sta``, ``ab_sta`` (module docstring)."""
    s, _ = _mat_struct(path, what)
    t = _times(s, path)
    fb = _mat_field(s, path, "fb", (None, 3))
    wb = _mat_field(s, path, "wb", (None, 3))
    assert fb is not None and wb is not None
    _same_length(path, t.size, fb=fb, wb=wb)
    ini = _mat_field(s, path, "ini_align", (3,), required=False)
    ini_err = _mat_field(s, path, "ini_align_err", (3,), required=False)
    if ini_err is not None and np.any(ini_err <= 0):
        raise ScenarioError(str(path), "field ini_align_err: every σ must be > 0")
    nominal = [_mat_field(s, path, k, (3,), required=False) for k in ("gb_sta", "ab_sta")]
    M = FRD_TO_RFU
    return NavegoImu(
        t,
        wb @ M,
        fb @ M,
        None if ini is None else _euler_from_navego(ini),
        None if ini_err is None else ini_err[[1, 0, 2]],
        *(None if b is None else b @ M for b in nominal),
    )


class NavegoGnss(NamedTuple):
    """A NaveGo GNSS struct in ftnav's frames.

    Attributes
    ----------
    t : (K,) s.  p : (K, 3) ``[L, λ, h]`` rad, rad, m.  v : (K, 3) ENU m/s (NaN: none).
    sigma_p : (3,) E, N, U position σ (m) from ``std`` (lat/lon rad, h m), or None.
    sigma_v : (3,) E, N, U velocity σ (m/s) from ``stdv``, or None.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    sigma_p: np.ndarray | None
    sigma_v: np.ndarray | None


def read_navego_gnss(path: Path, what: str = "gnss") -> NavegoGnss:
    """A NaveGo GNSS struct (``gnss.mat``): ``t``, ``lat``, ``lon`` (rad), ``h`` (m), the
    optional ``vel`` (N, 3) NED m/s, ``std`` and ``stdv`` (module docstring)."""
    s, _ = _mat_struct(path, what)
    t = _times(s, path)
    cols = {k: _mat_field(s, path, k, (None,)) for k in ("lat", "lon", "h")}
    _same_length(path, t.size, **cols)  # type: ignore[arg-type]
    p = np.stack([cols["lat"], cols["lon"], cols["h"]], -1)
    field = {"lat": "lat", "lon": "lon", "height": "h"}
    check_position(
        np.degrees(p[:, 0]),
        np.degrees(p[:, 1]),
        p[:, 2],
        lambda r, name: (str(path), f"field {field[name]}: sample {r + 1}"),
    )
    vel = _mat_field(s, path, "vel", (None, 3), required=False)
    if vel is None:
        v = np.full((t.size, 3), np.nan)
    else:
        _same_length(path, t.size, vel=vel)
        v = vel @ FRD_TO_RFU
    std = _mat_field(s, path, "std", (3,), required=False)
    stdv = _mat_field(s, path, "stdv", (3,), required=False)
    sigma_p = sigma_v = None
    for name, a in (("std", std), ("stdv", stdv)):
        if a is not None and np.any(a <= 0):
            raise ScenarioError(str(path), f"field {name}: every σ must be > 0")
    if std is not None:
        RM, RN = radii(float(np.mean(p[:, 0])), float(np.mean(p[:, 2])))
        sigma_p = np.array([std[1] * RN * np.cos(np.mean(p[:, 0])), std[0] * RM, std[2]])
    if stdv is not None:
        sigma_v = stdv[[1, 0, 2]]
    return NavegoGnss(t, p, v, sigma_p, sigma_v)


class NavegoTruth(NamedTuple):
    """A NaveGo reference struct in ftnav's frames.

    Attributes
    ----------
    t : (N,) s.  p : (N, 3) ``[L, λ, h]``.  v : (N, 3) ENU m/s.
    C : (N, 3, 3) ``C_b^n`` (body x right, y forward, z up; ENU).
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    C: np.ndarray


def read_navego_truth(path: Path, what: str = "reference") -> NavegoTruth:
    """A NaveGo reference struct (``ref.mat``): ``t``, ``lat``, ``lon``, ``h``, ``vel``
    NED, and the attitude as ``DCMnb_m`` (N, 9) (each row ``C_n^b`` flattened column-major)
    or, without it, ``roll``, ``pitch``, ``yaw`` (module docstring)."""
    s, _ = _mat_struct(path, what)
    t = _times(s, path)
    cols = {k: _mat_field(s, path, k, (None,)) for k in ("lat", "lon", "h")}
    vel = _mat_field(s, path, "vel", (None, 3))
    assert vel is not None
    _same_length(path, t.size, vel=vel, **cols)  # type: ignore[arg-type]
    dcm = _mat_field(s, path, "DCMnb_m", (None, 9), required="roll" not in s._fieldnames)
    M = FRD_TO_RFU
    if dcm is not None:
        _same_length(path, t.size, DCMnb_m=dcm)
        C_nb = dcm.reshape(-1, 3, 3).transpose(0, 2, 1)  # column-major rows
        C = M @ C_nb.transpose(0, 2, 1) @ M
        err = np.abs(C @ C.transpose(0, 2, 1) - np.eye(3)).max()
        if err > 1e-6:
            raise ScenarioError(str(path), f"field DCMnb_m: not a rotation (|C Cᵀ − I| {err:.2g})")
    else:
        rpy = {k: _mat_field(s, path, k, (None,)) for k in ("roll", "pitch", "yaw")}
        _same_length(path, t.size, **rpy)  # type: ignore[arg-type]
        C = euler_to_dcm(_euler_from_navego(np.stack([rpy["roll"], rpy["pitch"], rpy["yaw"]], -1)))
    p = np.stack([cols["lat"], cols["lon"], cols["h"]], -1)
    return NavegoTruth(t, p, vel @ M, C)
