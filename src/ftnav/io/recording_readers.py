"""Readers of recorded sensor files: delimited text (a comma, or whitespace as KF-GINS
writes), RTKLIB ``.pos`` solutions in every time and position form RTKLIB writes
(:func:`read_rtklib_pos`), NaveGo ``.mat``.

Every problem is refused with one line ``<file>:<line>: <what>`` (a
:class:`~ftnav.io.common.ScenarioError` whose path is the file and line), or handled
and counted:

* a first or last line with fewer fields than the others (a log cut mid-line) is
  dropped and counted; such a line anywhere else is refused;
* a field that is not a number (Python's ``float`` would take ``1_0`` as 10: an
  underscore is refused), NaN or infinite is refused with its line and column name;
* a ``.pos`` file is held to the CSV reader's rules: σ ≥ 0, ``Q`` an integer flag 1-6,
  ``ns`` an integer ≥ 0, a time of the file's form (calendar, or GPS week and seconds of
  week below 604 800) and system (GPST, UTC, JST), a base (``% ref pos``) for an ENU
  baseline; latitude within ±90°, longitude within ±180° and height within
  [:data:`HEIGHT_MIN_M`, :data:`HEIGHT_MAX_M`] in every GNSS reader, after converting
  ECEF and ENU (:func:`check_position`);
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
import re
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Literal, NamedTuple, overload

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
    "WHITESPACE",
    "check_position",
    "dcm_from_roll_pitch_yaw",
    "enu_rotation",
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
    lat_deg: np.ndarray,
    lon_deg: np.ndarray,
    height_m: np.ndarray,
    where: Callable[[int, str], tuple[str, str]],
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


#: the ``delimiter`` that splits at any run of spaces and tabs (KF-GINS text files);
#: lines starting with ``#`` or ``%`` are then comments
WHITESPACE = "whitespace"


def _split(line: str, delimiter: str) -> list[str]:
    return line.split() if delimiter == WHITESPACE else line.split(delimiter)


def read_csv(
    path: Path, header: bool, delimiter: str, what: str, names: Sequence[str] = ()
) -> Table:
    """A delimited file of numbers (module docstring); ``delimiter`` :data:`WHITESPACE`
    splits at any run of spaces and tabs and skips comment lines (``#``, ``%``).
    Without a header the columns are named ``names`` (a preset's), then by their
    0-based index."""
    lines = _lines(path, what)
    comment = ("#", "%") if delimiter == WHITESPACE else ()
    rows = [
        (i + 1, ln)
        for i, ln in enumerate(lines)
        if ln.strip() and not (comment and ln.lstrip().startswith(comment))
    ]
    if header:
        if not rows:
            raise ScenarioError(str(path), f"{what}: empty file (no header line)")
        names = tuple(c.strip() for c in _split(rows[0][1], delimiter))
        rows = rows[1:]
    if not rows:
        raise ScenarioError(str(path), f"{what}: no data rows")
    split = [(n, _split(ln, delimiter)) for n, ln in rows]
    width = len(names) if header else max(len(f) for _, f in split[1:-1] or split)
    if not header:
        names = tuple(names[j] if j < len(names) else str(j) for j in range(width))
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
    return Table(tuple(names), values, np.array([n for n, _ in split]), dropped)


class PosFile(NamedTuple):
    """An RTKLIB solution: time (s, GPST as Unix seconds), ``lat``/``lon`` (deg), height
    (m), quality flag, σ N, E, U (m), velocity N, E, U (m/s) and its σ (m/s; NaN when
    absent), whatever form the file was written in (:func:`read_rtklib_pos`)."""

    t: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    height_m: np.ndarray
    quality: np.ndarray
    sigma_neu: np.ndarray
    v_neu: np.ndarray
    lines: np.ndarray
    sigma_v_neu: np.ndarray


#: GPST counted as Unix seconds (ftnav's time base for RTKLIB files): the GPS epoch
#: 1980-01-06 00:00:00 is 315 964 800 s, a GPS week 604 800 s
GPS_EPOCH_UNIX_S, WEEK_S = 315964800, 604800

#: GPS − UTC (s) from each UTC date on: the leap seconds since the GPS epoch (IERS
#: Bulletin C; none announced after 2017-01-01), the table RTKLIB carries
_LEAP_SECONDS = (
    ((1981, 7, 1), 1),
    ((1982, 7, 1), 2),
    ((1983, 7, 1), 3),
    ((1985, 7, 1), 4),
    ((1988, 1, 1), 5),
    ((1990, 1, 1), 6),
    ((1991, 1, 1), 7),
    ((1992, 7, 1), 8),
    ((1993, 7, 1), 9),
    ((1994, 7, 1), 10),
    ((1996, 1, 1), 11),
    ((1997, 7, 1), 12),
    ((1999, 1, 1), 13),
    ((2006, 1, 1), 14),
    ((2009, 1, 1), 15),
    ((2012, 7, 1), 16),
    ((2015, 7, 1), 17),
    ((2017, 1, 1), 18),
)
_LEAP_AT = np.array([datetime(*d, tzinfo=UTC).timestamp() for d, _ in _LEAP_SECONDS])
_LEAP_N = np.array([0.0] + [float(n) for _, n in _LEAP_SECONDS])

#: RTKLIB's time systems (``out-timesys``) and their offset to UTC (s)
_POS_TIME_SYSTEMS = {"GPST": None, "UTC": 0.0, "JST": 9 * 3600.0}

_DMS_LAT, _DMS_LON = "latitude(d'\")", "longitude(d'\")"
#: the first position column of each ``out-solformat`` (``out-degform`` for d m s)
_POS_FORMS = {
    "latitude(deg)": "llh",
    _DMS_LAT: "llh-dms",
    "x-ecef(m)": "xyz",
    "e-baseline(m)": "enu",
}
_POS_REQUIRED = {
    "llh": ("latitude(deg)", "longitude(deg)", "height(m)", "Q", "sdn(m)", "sde(m)", "sdu(m)"),
    "llh-dms": (_DMS_LAT, _DMS_LON, "height(m)", "Q", "sdn(m)", "sde(m)", "sdu(m)"),
    "xyz": ("x-ecef(m)", "y-ecef(m)", "z-ecef(m)", "Q", "sdx(m)", "sdy(m)", "sdz(m)"),
    "enu": ("e-baseline(m)", "n-baseline(m)", "u-baseline(m)", "Q", "sde(m)", "sdn(m)", "sdu(m)"),
}
#: the signed square roots of the covariances (RTKLIB's ``sqvar``) of each form's
#: position, in the order (01, 12, 20) of its three axes
_POS_OFF_DIAGONAL = {
    "xyz": ("sdxy(m)", "sdyz(m)", "sdzx(m)"),
    "enu": ("sden(m)", "sdnu(m)", "sdue(m)"),
}
_POS_VELOCITY = {"llh": ("vn(m/s)", "ve(m/s)", "vu(m/s)"), "xyz": ("vx(m/s)", "vy(m/s)", "vz(m/s)")}
_POS_VELOCITY_SIGMA = {
    "llh": ("sdvn", "sdve", "sdvu"),
    "xyz": ("sdvx", "sdvy", "sdvz", "sdvxy", "sdvyz", "sdvzx"),
}

_DATE = re.compile(r"(\d{4})/(\d{1,2})/(\d{1,2})")
_CLOCK = re.compile(r"(\d{1,2}):(\d{1,2}):(\d{1,2})(?:\.(\d*))?")
_WEEK = re.compile(r"\d{1,5}")
_SECONDS = re.compile(r"(\d{1,6})(?:\.(\d*))?")


def _exact(whole: int, fraction: str) -> float:
    """``whole.fraction`` s rounded once to a float (as ``datetime.timestamp`` does), so
    one time written as a calendar date or as GPS week and seconds is one float."""
    scale: int = 10 ** len(fraction)
    return (whole * scale + int(fraction or "0")) / scale


def _pos_time(first: str, second: str, calendar: bool, label: str, path: Path, line: int) -> float:
    """A ``.pos`` time as Unix seconds of its own time system: ``YYYY/MM/DD hh:mm:ss.sss``
    (``calendar``) or GPS week and seconds of week (RTKLIB's ``out-timeform``)."""
    if calendar:
        d, c = _DATE.fullmatch(first), _CLOCK.fullmatch(second)
        try:
            if d is None or c is None:
                raise ValueError
            year, month, day = (int(x) for x in d.groups())
            hour, minute, sec = (int(x) for x in c.groups()[:3])
            whole = int(datetime(year, month, day, hour, minute, sec, tzinfo=UTC).timestamp())
        except ValueError:
            raise ScenarioError(
                f"{path}:{line}",
                f"column {label}: not a 'YYYY/MM/DD hh:mm:ss.sss' time ({first} {second})",
            ) from None
        return _exact(whole, c.group(4) or "")
    s = _SECONDS.fullmatch(second)
    if _WEEK.fullmatch(first) is None or s is None:
        raise ScenarioError(
            f"{path}:{line}",
            f"column {label}: not a GPS week and seconds of week ('{first} {second}'; the "
            "file's first epoch has that form)",
        )
    if int(s.group(1)) >= WEEK_S:
        raise ScenarioError(
            f"{path}:{line}", f"column {label}: {second} seconds of week is not below {WEEK_S}"
        )
    return _exact(GPS_EPOCH_UNIX_S + int(first) * WEEK_S + int(s.group(1)), s.group(2) or "")


def _to_gpst(t: np.ndarray, system: str) -> np.ndarray:
    """Unix seconds of UTC or JST (RTKLIB: UTC + 9 h) as GPST: plus the leap seconds."""
    offset = _POS_TIME_SYSTEMS[system]
    if offset is None:
        return t
    utc = t - offset
    gpst: np.ndarray = utc + _LEAP_N[np.searchsorted(_LEAP_AT, utc, side="right")]
    return gpst


def enu_rotation(lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    """(…, 3, 3) ``R`` with ``x_ENU = R x_ECEF`` at geodetic ``lat``, ``lon`` (deg)."""
    L, lam = np.radians(lat_deg), np.radians(lon_deg)
    sL, cL, sl, cl = np.sin(L), np.cos(L), np.sin(lam), np.cos(lam)
    z = np.zeros_like(sL)
    return np.stack(
        [
            np.stack([-sl, cl, z], -1),
            np.stack([-sL * cl, -sL * sl, cL], -1),
            np.stack([cL * cl, cL * sl, sL], -1),
        ],
        -2,
    )


def _covariance(sd: np.ndarray, off: np.ndarray) -> np.ndarray:
    """(K, 3, 3) from σ (K, 3) and RTKLIB's signed square roots of the covariances
    (K, 3) of the axis pairs (0, 1), (1, 2), (2, 0)."""
    C = np.zeros(sd.shape[:1] + (3, 3))
    C[:, [0, 1, 2], [0, 1, 2]] = sd**2
    for k, (i, j) in enumerate(((0, 1), (1, 2), (2, 0))):
        C[:, i, j] = C[:, j, i] = off[:, k] * np.abs(off[:, k])
    return C


def _dms(d: np.ndarray, m: np.ndarray, s: np.ndarray, negative: np.ndarray) -> np.ndarray:
    """Degrees from RTKLIB's ``d m s`` (the sign on the degrees, ``-0`` included)."""
    deg: np.ndarray = np.where(negative, -1.0, 1.0) * (np.abs(d) + m / 60.0 + s / 3600.0)
    return deg


def _ref_pos(text: str, path: Path, line: int) -> tuple[float, float, float]:
    """The base position of a ``% ref pos :`` line as ``lat``, ``lon`` (deg), height:
    written as lat lon h, as lat and lon in d m s and h, or as ECEF x y z (m)."""
    fields = text.replace(",", " ").split()
    values = [_number(f, path, line, "ref pos") for f in fields]
    if len(values) == 7:
        a = np.array(values[:6]).reshape(2, 3)
        neg = np.array([fields[0].startswith("-"), fields[3].startswith("-")])
        lat, lon, h = (*_dms(a[:, 0], a[:, 1], a[:, 2], neg), values[6])
    elif len(values) == 3 and math.hypot(*values) > 1e6:  # ECEF: ~6.4e6 m from the centre
        import pymap3d

        lat, lon, h = pymap3d.ecef2geodetic(*values)
    elif len(values) == 3:
        lat, lon, h = values
    else:
        raise ScenarioError(
            f"{path}:{line}",
            f"ref pos: {len(values)} numbers; expected lat lon height (deg, m), lat and lon "
            "as d m s and height, or x y z ECEF (m)",
        )
    llh = (float(lat), float(lon), float(h))
    check_position(
        np.array([llh[0]]),
        np.array([llh[1]]),
        np.array([llh[2]]),
        lambda r, name: (f"{path}:{line}", "ref pos"),
    )
    return llh


def read_rtklib_pos(path: Path, what: str = "gnss") -> PosFile:
    """An RTKLIB ``.pos`` solution in any form RTKLIB writes (module docstring).

    The last ``%`` line naming the columns sets the form: the time system (``GPST``;
    ``UTC`` and ``JST`` are moved to GPST by the leap seconds), the position as
    ``latitude(deg)``/``latitude(d'")`` lat/lon/height, ``x-ecef(m)`` ECEF (with ``vx``…
    when present) or ``e-baseline(m)`` ENU from the base of the ``% ref pos :`` line.
    The time form comes from the first epoch: ``YYYY/MM/DD hh:mm:ss.sss`` or GPS week and
    seconds of week.  ECEF and ENU are converted to geodetic (:mod:`pymap3d`) and their
    covariance (full when the ``sdxy``… columns are there) rotated to the local ENU."""
    lines = _lines(path, what)
    header: Sequence[str] | None = None
    ref: tuple[int, str] | None = None
    data: list[tuple[int, list[str]]] = []
    for i, ln in enumerate(lines):
        if ln.startswith("%"):
            if any(label in ln for label in _POS_FORMS):
                header = ln[1:].split()
            elif ln[1:].lstrip().startswith("ref pos"):
                ref = (i + 1, ln.partition(":")[2])
            continue
        if ln.strip():
            data.append((i + 1, ln.split()))
    if header is None:
        raise ScenarioError(
            str(path),
            f"{what}: no '%' header line naming the columns (GPST latitude(deg) longitude(deg) "
            "height(m) Q ..., or x-ecef(m) ..., or e-baseline(m) ...): write the solution "
            "with RTKLIB's header on",
        )
    label = header[0]
    if label not in _POS_TIME_SYSTEMS:
        raise ScenarioError(
            str(path), f"{what}: time column {label!r}, expected 'GPST', 'UTC' or 'JST'"
        )
    form = _POS_FORMS.get(header[1]) if len(header) > 1 else None
    if form is None:
        raise ScenarioError(
            str(path),
            f"{what}: the column after the time is {' '.join(header[1:2])!r}, expected one "
            f"of {', '.join(_POS_FORMS)} (RTKLIB's llh, xyz or enu solution)",
        )
    names: list[str] = []
    for name in header[1:]:  # RTKLIB writes d m s as three fields under one name
        names += [name, f"{name} min", f"{name} sec"] if name in (_DMS_LAT, _DMS_LON) else [name]
    missing = [c for c in _POS_REQUIRED[form] if c not in names]
    if missing:
        raise ScenarioError(str(path), f"{what}: the header has no column {missing[0]!r}")
    base = None
    if form == "enu":
        if ref is None:
            raise ScenarioError(
                str(path),
                f"{what}: an e/n/u-baseline solution without the base position: no '% ref "
                "pos :' header line (write the solution with RTKLIB's header and options on, "
                "or as lat/lon/height)",
            )
        base = _ref_pos(ref[1], path, ref[0])
    if not data:
        raise ScenarioError(str(path), f"{what}: no solution epochs")
    col = {name: j for j, name in enumerate(names)}
    width = len(names) + 2  # the time takes two fields in either form
    for end in (0, -1):
        if data and len(data[end][1]) < width:
            data.pop(end)
    if not data:
        raise ScenarioError(str(path), f"{what}: no complete solution epochs")
    calendar = "/" in data[0][1][0]
    signs = [j + 2 for j, name in enumerate(names) if name in (_DMS_LAT, _DMS_LON)]
    out = np.empty((len(data), width - 2))
    t = np.empty(len(data))
    negative = np.zeros((len(data), len(signs)), bool)
    for r, (n, fields) in enumerate(data):
        if len(fields) != width:  # more: two epochs run together on one line
            raise ScenarioError(
                f"{path}:{n}",
                f"expected {width} fields (the header's columns), got {len(fields)}",
            )
        t[r] = _pos_time(fields[0], fields[1], calendar, label, path, n)
        try:
            if any("_" in f for f in fields):  # float() reads 1_0 as 10
                raise ValueError
            out[r] = [float(f) for f in fields[2:width]]
        except ValueError:  # find the culprit for the message
            for j, name in enumerate(names):
                _number(fields[j + 2], path, n, name)
            raise
        negative[r] = [fields[j].startswith("-") for j in signs]
    bad = ~np.isfinite(out)
    if bad.any():
        r, j = np.argwhere(bad)[0]
        raise ScenarioError(f"{path}:{data[r][0]}", f"column {names[j]}: not finite")

    def c(name: str) -> np.ndarray:
        return out[:, col[name]]

    lines_of = np.array([n for n, _ in data])

    def refuse(rows: np.ndarray, column: str, reason: str, value: np.ndarray | None = None) -> None:
        if rows.any():
            r = int(np.flatnonzero(rows)[0])
            shown = c(column) if value is None else value
            raise ScenarioError(
                f"{path}:{lines_of[r]}", f"column {column}: {reason} ({shown[r]:g})"
            )

    kind = "xyz" if form == "xyz" else "llh"
    for name in (*_POS_REQUIRED[form][4:], *_POS_VELOCITY_SIGMA[kind][:3]):
        if name in col:
            refuse(c(name) < 0, name, "a σ must be >= 0")
    q = c("Q")
    refuse((q != np.round(q)) | (q < 1) | (q > 6), "Q", "not an RTKLIB solution flag 1-6")
    if "ns" in col:
        ns = c("ns")
        refuse((ns != np.round(ns)) | (ns < 0), "ns", "not a satellite count")
    first = _POS_REQUIRED[form][:3]
    if form == "llh-dms":
        for name in (_DMS_LAT, _DMS_LON):
            for part, unit in (("min", "minutes"), ("sec", "seconds")):
                x = c(f"{name} {part}")
                refuse((x < 0) | (x >= 60), f"{name} {part}", f"{unit} not in [0, 60)")
        lat = _dms(c(_DMS_LAT), c(f"{_DMS_LAT} min"), c(f"{_DMS_LAT} sec"), negative[:, 0])
        lon = _dms(c(_DMS_LON), c(f"{_DMS_LON} min"), c(f"{_DMS_LON} sec"), negative[:, 1])
        llh = (lat, lon, c("height(m)"))
    elif form == "llh":
        llh = (c("latitude(deg)"), c("longitude(deg)"), c("height(m)"))
    else:
        import pymap3d

        xyz = np.stack([c(n) for n in first], -1)
        if form == "enu":
            assert base is not None
            geodetic = pymap3d.enu2geodetic(*xyz.T, *base)
        else:
            geodetic = pymap3d.ecef2geodetic(*xyz.T)
        lat, lon, h = (np.asarray(a, float) for a in geodetic)
        llh = (lat, lon, h)
    where = {"lat": first[0], "lon": first[1], "height": first[2]}
    if form in ("xyz", "enu"):
        where = dict.fromkeys(where, ", ".join(first))
    check_position(*llh, lambda r, name: (f"{path}:{lines_of[r]}", f"column {where[name]}"))

    def offdiag(names3: Sequence[str]) -> np.ndarray:
        if all(n in col for n in names3):
            return np.stack([c(n) for n in names3], -1)
        return np.zeros((len(data), 3))

    if form in ("llh", "llh-dms"):
        sigma_neu = np.stack([c("sdn(m)"), c("sde(m)"), c("sdu(m)")], -1)
    else:
        sd = np.stack([c(n) for n in _POS_REQUIRED[form][4:]], -1)
        C = _covariance(sd, offdiag(_POS_OFF_DIAGONAL[form]))
        R = enu_rotation(llh[0], llh[1])
        if form == "enu":  # the baseline's axes are the base's
            assert base is not None
            R = R @ enu_rotation(np.array(base[0]), np.array(base[1])).T
        var = np.einsum("kij,kjl,kil->ki", R, C, R)
        wrong = np.flatnonzero((var < -1e-8).any(1))  # beyond the rounding of 0.1 mm
        if wrong.size:
            r = int(wrong[0])
            raise ScenarioError(
                f"{path}:{lines_of[r]}",
                f"columns {', '.join(_POS_REQUIRED[form][4:] + _POS_OFF_DIAGONAL[form])}: not "
                f"a covariance (a variance of {var[r].min():.3g} m² in E, N, U)",
            )
        sigma_neu = np.sqrt(np.maximum(var, 0.0))[:, [1, 0, 2]]

    v = np.full((len(data), 3), np.nan)
    sv = np.full((len(data), 3), np.nan)
    if form != "enu" and all(n in col for n in _POS_VELOCITY[kind]):
        v = np.stack([c(n) for n in _POS_VELOCITY[kind]], -1)
    if form != "enu" and all(n in col for n in _POS_VELOCITY_SIGMA[kind][:3]):
        sv = np.stack([c(n) for n in _POS_VELOCITY_SIGMA[kind][:3]], -1)
    if form == "xyz":  # ECEF velocity and its covariance to the local ENU
        R = enu_rotation(llh[0], llh[1])
        v = np.einsum("kij,kj->ki", R, v)[:, [1, 0, 2]]
        if np.isfinite(sv).all():
            Cv = _covariance(sv, offdiag(_POS_VELOCITY_SIGMA["xyz"][3:]))
            var = np.einsum("kij,kjl,kil->ki", R, Cv, R)
            sv = np.sqrt(np.maximum(var, 0.0))[:, [1, 0, 2]]
    return PosFile(
        t=_to_gpst(t, label),
        lat_deg=llh[0],
        lon_deg=llh[1],
        height_m=llh[2],
        quality=q.astype(int),
        sigma_neu=sigma_neu,
        v_neu=v,
        lines=lines_of,
        sigma_v_neu=sv,
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


@overload
def _mat_field(
    s: Any, path: Path, name: str, shape: tuple[int | None, ...], required: Literal[True] = True
) -> np.ndarray: ...


@overload
def _mat_field(
    s: Any, path: Path, name: str, shape: tuple[int | None, ...], required: bool
) -> np.ndarray | None: ...


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
    if t.size < 2:
        raise ScenarioError(str(path), f"field t: {t.size} sample(s)")
    return t


def _euler_from_navego(rpy: np.ndarray) -> np.ndarray:
    """ftnav ``[θ, γ, ψ]`` from NaveGo's ``[roll, pitch, yaw]`` (module docstring)."""
    rpy = np.asarray(rpy, float)
    return np.stack([rpy[..., 1], rpy[..., 0], -rpy[..., 2]], -1)


def dcm_from_roll_pitch_yaw(rpy: np.ndarray) -> np.ndarray:
    """(…, 3, 3) ftnav's ``C_b^n`` from ``[roll, pitch, yaw]`` (…, 3) rad: the ZYX Euler
    angles of a forward-right-down body in NED (NaveGo's, KF-GINS's; yaw the heading
    clockwise from North), which are also the ``roll_deg``, ``pitch_deg``, ``yaw_deg``
    of ftnav's ``solution.csv`` (module docstring)."""
    return euler_to_dcm(_euler_from_navego(rpy))


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
    _same_length(path, t.size, **cols)
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
    _same_length(path, t.size, vel=vel, **cols)
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
        _same_length(path, t.size, **rpy)
        C = dcm_from_roll_pitch_yaw(np.stack([rpy["roll"], rpy["pitch"], rpy["yaw"]], -1))
    p = np.stack([cols["lat"], cols["lon"], cols["h"]], -1)
    return NavegoTruth(t, p, vel @ M, C)
