"""Readers of recorded sensor files: IMU CSV and RTKLIB ``.pos`` solutions.

Every problem is refused with one line ``<file>:<line>: <what>`` (a
:class:`~ftnav.io.common.ScenarioError` whose path is the file and line), or handled
and counted:

* a first or last line with fewer fields than the others (a log cut mid-line) is
  dropped and counted; such a line anywhere else is refused;
* a field that is not a number is refused with its line and column name;
* IMU time stamps that go backwards are refused; repeated stamps and stale rows are
  dropped later and counted (:func:`ftnav.recorded.imu.clean`);
* ``.pos`` epochs out of order or duplicated are sorted or dropped and counted
  (:func:`ftnav.recorded.stream.on_grid`).
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ftnav.io.common import ScenarioError

__all__ = ["Table", "read_csv", "read_rtklib_pos", "PosFile"]


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


def _lines(path: Path, what: str) -> list[str]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(str(path), f"{what}: file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(str(path), f"{what}: cannot read ({exc})") from None
    return text.splitlines()


def _number(text: str, path: Path, line: int, column: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ScenarioError(
            f"{path}:{line}", f"column {column}: not a number ({text.strip()[:30]!r})"
        ) from None


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
    try:
        values = np.array([f for _, f in split], dtype=float)
    except ValueError:  # find the culprit for the message
        for n, fields in split:
            for name, text in zip(names, fields, strict=True):
                _number(text, path, n, name)
        raise
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ScenarioError(f"{path}:{split[r][0]}", f"column {names[c]}: not finite")
    return Table(names, values, np.array([n for n, _ in split]), dropped)


class PosFile(NamedTuple):
    """An RTKLIB solution: time (s, GPST as Unix seconds), ``lat``/``lon`` (deg), height
    (m), quality flag, σ N, E, U (m) and velocity N, E, U (m/s; NaN when absent)."""

    t: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    height_m: np.ndarray
    quality: np.ndarray
    sigma_neu: np.ndarray
    v_neu: np.ndarray
    lines: np.ndarray


_POS_REQUIRED = ("latitude(deg)", "longitude(deg)", "height(m)", "Q", "sdn(m)", "sde(m)", "sdu(m)")
_POS_VELOCITY = ("vn(m/s)", "ve(m/s)", "vu(m/s)")


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
        for j, name in enumerate(header[1:]):
            out[r, j] = _number(fields[j + 2], path, n, name)

    def c(name: str) -> np.ndarray:
        return out[:, col[name] - 1]

    v = (
        np.stack([c(n) for n in _POS_VELOCITY], -1)
        if all(n in col for n in _POS_VELOCITY)
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
        np.array([n for n, _ in data]),
    )
