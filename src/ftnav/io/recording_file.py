"""Recording files (``docs/recording-format.md``): a recorded log, validated at the boundary.

A recording file (TOML) names the IMU file and its layout, the mounting of the IMU,
the aids (a GNSS solution file, vehicle constraints), the reference to score against,
the alignment, the filter and the methods (the same method tables as scenarios).
:func:`load_recording` reads and validates it and every file it names, and builds the
engine's :class:`~ftnav.model.scenario.Recording` and stream (:mod:`ftnav.recorded`).
Every problem is one line ``<field or file:line>: <reason>``
(:class:`~ftnav.io.common.ScenarioError`).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from ftnav.eval.resources import available_memory_bytes, format_bytes
from ftnav.fusion.config import config_error
from ftnav.io.common import (
    STRICT,
    ScenarioError,
    format_loc,
    read_toml,
    to_scenario_error,
    with_line,
)
from ftnav.io.ins_scenario_file import (
    DEFAULT_SIGMA_BOUND_M,
    ImuSpec,
    ScenarioWarning,
    filter_model,
    imu_errors,
    sensor_from_table,
)
from ftnav.io.recording_readers import (
    WHITESPACE,
    NavegoImu,
    NavegoTruth,
    Table,
    check_position,
    dcm_from_roll_pitch_yaw,
    read_csv,
    read_navego_gnss,
    read_navego_imu,
    read_navego_truth,
    read_rtklib_pos,
)
from ftnav.io.sections import (
    EvaluationFile,
    MethodConfig,
    explain_method_key,
    resolve_methods,
)
from ftnav.model.imu import ImuErrors
from ftnav.model.scenario import SINS, AidSpec, Fault, Recording
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.earth import gravity
from ftnav.nav.units import parse_quantity
from ftnav.recorded.aids import RECORDING_AIDS, AidContext, ColumnReader, PreparedAid
from ftnav.recorded.imu import (
    ImuCleaning,
    ImuLog,
    TimeGoesBack,
    clean,
    noise_density,
)
from ftnav.recorded.plausibility import (
    Verdict,
    course_rate_gain,
    gyro_gain_verdict,
    holds,
    position_rate_verdict,
    specific_force_verdict,
    static_motion_verdict,
    static_rate_verdict,
)
from ftnav.recorded.stream import (
    RECORDING_FAULT_KINDS,
    Alignment,
    GnssLog,
    align,
    given,
    gnss_raw,
    gyrocompass_sigma,
    imu_with_faults,
    interleave,
    on_grid,
    outage_schedule,
    recording_stream,
    retime_velocity,
    with_outages,
)
from ftnav.recorded.truth import Truth, imu_bias_against_truth
from ftnav.recordings import recording_names, recording_path
from ftnav.sensors.gnss import Gnss

__all__ = [
    "LoadedRecording",
    "ParsedRecording",
    "RecordingFile",
    "load_recording",
    "parse_recording",
    "recording_aids",
    "recording_json_schema",
]

_DEG = math.pi / 180.0
_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


class ColumnsFile(BaseModel):
    """Columns of one quantity and their unit."""

    model_config = STRICT
    columns: list[str | int] = Field(min_length=1, max_length=3)
    unit: str


class FrameColumns(ColumnsFile):
    """Three columns of a vector quantity, their unit and the order of their axes."""

    frame: Literal["ENU", "NED", "NEU"] = "ENU"


_IMU_CSV_KEYS = ("header", "delimiter", "time", "gyro", "accel")
_DELIMITER = (
    "csv: the field separator, or 'whitespace' (any run of spaces and tabs; lines starting "
    "with # or % are comments)"
)


class ImuFile(BaseModel):
    """``[imu]``: the IMU log and its layout, its mounting, its errors (datasheet)."""

    model_config = STRICT
    file: str
    format: Literal["csv", "navego-mat", "kfgins-text"] = Field(
        default="csv",
        description=(
            "csv: a delimited text file with a column map; navego-mat: NaveGo's imu.mat; "
            "kfgins-text: KF-GINS's text (GPS seconds of week, Δθ x y z rad, Δv x y z m/s)"
        ),
    )
    header: bool = True
    delimiter: str = Field(default=",", description=_DELIMITER)
    time: ColumnsFile | None = Field(default=None, description="csv: required")
    gyro: ColumnsFile | None = Field(default=None, description="csv: required")
    accel: ColumnsFile | None = Field(default=None, description="csv: required")
    time_offset_s: float = Field(default=0.0, allow_inf_nan=False)
    axes: list[Literal[_AXES]] = Field(  # type: ignore[valid-type]
        default=["+x", "+y", "+z"],
        min_length=3,
        max_length=3,
        description=(
            "the sensor axis along body x (right), y (forward) and z (up) (kfgins-text: "
            "default ['+y', '+x', '-z'], its forward-right-down axes)"
        ),
    )
    misalignment_deg: list[float] = Field(
        default=[0.0, 0.0, 0.0],
        min_length=3,
        max_length=3,
        description=(
            "the IMU's attitude in the vehicle body frame after the axes, [pitch, roll, yaw] "
            "deg (ftnav's Euler convention: yaw positive counter-clockwise)"
        ),
    )
    errors: ImuSpec = Field(description="the IMU's errors: a preset or a datasheet table")


_GNSS_CSV_KEYS = (
    "header",
    "delimiter",
    "time",
    "lat",
    "lon",
    "height",
    "velocity",
    "sigma",
    "quality_column",
)


#: every aid type of ``[[aids]]``: the GNSS receiver, read here, and the plug-ins of
#: :data:`ftnav.recorded.aids.RECORDING_AIDS` (their settings models validate the rest)
AID_TYPES = ("gnss", *RECORDING_AIDS)


class AidTable(BaseModel):
    """``[[aids]]``: ``type``, and for ``gnss`` its file; the sensor's parameters (a
    plug-in aid's keys: its settings model, ``$defs`` ``aid-<type>`` of the schema)."""

    model_config = ConfigDict(extra="allow", strict=True)
    type: Literal[AID_TYPES]  # type: ignore[valid-type]
    name: str | None = None
    file: str | None = None
    format: Literal["rtklib-pos", "navego-mat", "csv", "kfgins-text"] = Field(
        default="rtklib-pos",
        description=(
            "rtklib-pos: an RTKLIB solution (any time and position form); navego-mat: "
            "NaveGo's gnss.mat; csv: a delimited text file with a column map; kfgins-text: "
            "KF-GINS's GNSS text (GPS seconds of week, lat, lon deg, height m, σ N E D m)"
        ),
    )
    header: bool = Field(default=True, description="csv")
    delimiter: str = Field(default=",", description=_DELIMITER)
    time: ColumnsFile | None = Field(default=None, description="csv: required")
    lat: ColumnsFile | None = Field(default=None, description="csv: required, deg or rad")
    lon: ColumnsFile | None = Field(default=None, description="csv: required, deg or rad")
    height: ColumnsFile | None = Field(default=None, description="csv: required, m")
    velocity: FrameColumns | None = Field(default=None, description="csv: optional")
    sigma: FrameColumns | None = Field(
        default=None, description="csv: optional position σ (m), 3 columns"
    )
    quality_column: str | int | None = Field(
        default=None, description="csv: optional solution flag (default: every row 1)"
    )
    quality: list[int] = Field(default=[1], min_length=1)
    time_offset_s: float = Field(default=0.0, allow_inf_nan=False)
    velocity_time_offset_s: float = Field(
        default=0.0,
        allow_inf_nan=False,
        ge=-1.0,
        le=1.0,
        description=(
            "gnss: the velocities' own time offset against the positions (a velocity "
            "stamped t describes t + offset; RTKLIB's lag theirs by 0.10-0.15 s: -0.125)"
        ),
    )


class AttitudeColumns(ColumnsFile):
    """Roll, pitch, yaw columns (deg or rad): the ZYX Euler angles of a forward-right-down
    body in NED (NaveGo's and KF-GINS's; yaw the heading clockwise from North), the same
    as ``roll_deg``, ``pitch_deg``, ``yaw_deg`` of ftnav's ``solution.csv``."""

    columns: list[str | int] = Field(min_length=3, max_length=3, description="roll, pitch, yaw")


_TRUTH_CSV_KEYS = ("header", "delimiter", "time", "lat", "lon", "height", "velocity", "attitude")


class ReferenceFile(BaseModel):
    """``[reference]``: what to score against: the GNSS file's best epochs, or a full
    truth (position, velocity, attitude) from a file."""

    model_config = STRICT
    source: Literal["gnss", "truth"] = "gnss"
    quality: list[int] = Field(default=[1], min_length=1, description="source gnss")
    file: str | None = Field(default=None, description="source truth: required")
    format: Literal["navego-mat", "csv"] = Field(default="navego-mat", description="source truth")
    header: bool = Field(default=True, description="truth csv")
    delimiter: str = Field(default=",", description=_DELIMITER)
    time: ColumnsFile | None = Field(default=None, description="truth csv: required")
    lat: ColumnsFile | None = Field(default=None, description="truth csv: required, deg or rad")
    lon: ColumnsFile | None = Field(default=None, description="truth csv: required, deg or rad")
    height: ColumnsFile | None = Field(default=None, description="truth csv: required, m")
    velocity: FrameColumns | None = Field(default=None, description="truth csv: required")
    attitude: AttitudeColumns | None = Field(default=None, description="truth csv: required")


class AlignmentFile(BaseModel):
    """``[alignment]``: static levelling and the GNSS-course heading (``mode = "static"``),
    or a given attitude for a vehicle moving from the start (``mode = "given"``)."""

    model_config = STRICT
    mode: Literal["static", "given"] = "static"
    static_s: float = Field(default=30.0, gt=0, description="static")
    heading: Literal["auto", "gnss-course", "gyrocompass"] = Field(
        default="auto",
        description=(
            "static: the heading from the GNSS course once moving, or by gyrocompassing "
            "the static window; auto: gyrocompassing where the IMU's grade allows "
            "(predicted σ at most gyrocompass_max_sigma_deg)"
        ),
    )
    gyrocompass_max_sigma_deg: float = Field(default=1.0, gt=0, description="static, auto")
    min_speed_mps: float = Field(default=1.0, gt=0, description="static")
    noise: Literal["max", "datasheet"] = Field(
        default="max",
        description=(
            "static: the filter's gyro and accelerometer white noise, per axis the larger "
            "of the datasheet's and the static window's (Allan deviation at 1 s: engine "
            "vibration), or the datasheet's alone"
        ),
    )
    attitude_deg: list[float] | None = Field(
        default=None,
        min_length=3,
        max_length=3,
        description="given: [pitch, roll, yaw] deg (default: the IMU file's ini_align)",
    )
    attitude_sigma_deg: list[Annotated[float, Field(gt=0, le=180, allow_inf_nan=False)]] = Field(
        default=[1.0, 1.0, 10.0],
        min_length=3,
        max_length=3,
        description="σ pitch, roll, yaw (given: default the IMU file's ini_align_err)",
    )
    velocity_sigma_mps: float | None = Field(
        default=None, gt=0, description="default: static 0.1, given the GNSS aid's σ"
    )
    position_sigma_m: float | None = Field(
        default=None, gt=0, description="default: static 0.1, given the GNSS aid's σ E, N, U"
    )
    velocity_mps: list[float] | None = Field(
        default=None,
        min_length=3,
        max_length=3,
        description=(
            "given: the velocity [E, N, U] m/s at the start (the first GNSS fix in the IMU "
            "log; default: that fix's, required when the file has no velocity)"
        ),
    )
    position_deg_m: list[float] | None = Field(
        default=None,
        min_length=3,
        max_length=3,
        description="given: the position [lat deg, lon deg, height m] at the start "
        "(default: the first GNSS fix's)",
    )


class RecordingFilterFile(BaseModel):
    model_config = STRICT
    states: Literal[15, 18, 21] = Field(
        default=15,
        description=(
            "error states: 15 (biases as random constants or walks), 18 (spec §8.3: "
            "Markov biases) or 21 (the 15 and the gyro and accelerometer scale factors, "
            "KF-GINS's model; their σ from imu.errors gyro_scale / accel_scale)"
        ),
    )
    correction: Literal["feedback", "output"] = "feedback"
    bias_compensation: bool = Field(
        default=True,
        description=(
            "feedback: the estimated IMU biases are fed back and subtracted from the "
            "increments before the strapdown (as KF-GINS and pyins do)"
        ),
    )
    imu_rate_hz: float | None = Field(default=None, gt=0, description="default: the log's")
    rate_hz: float = Field(
        default=10.0,
        gt=0,
        description="least filter (and solution) rate: the GNSS period is split into epochs",
    )
    duration_s: float | None = Field(default=None, gt=0, description="default: to the end")


class RecordingFile(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, title="ftnav recording")
    kind: Literal["recording"]
    name: str
    description: str = ""
    imu: ImuFile
    aids: list[AidTable] = Field(min_length=1)
    reference: ReferenceFile = Field(default_factory=ReferenceFile)
    alignment: AlignmentFile = Field(default_factory=AlignmentFile)
    filter: RecordingFilterFile = Field(default_factory=RecordingFilterFile)
    evaluation: EvaluationFile = Field(default_factory=EvaluationFile)
    methods: list[MethodConfig] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique_aid_names(self) -> RecordingFile:
        """Aids are told apart by name (``--aids``, ``--fault``, the outputs); an aid
        without ``name`` is named by its type."""
        seen: dict[str, int] = {}
        for i, a in enumerate(self.aids):
            name = a.name or a.type
            if name in seen:
                raise config_error(
                    f"duplicate aid name {name!r} (aids[{seen[name]}] has it; an aid without "
                    "a name is named by its type)",
                    "aids",
                    i,
                    "name",
                )
            seen[name] = i
        return self

    @model_validator(mode="after")
    def _detectors_for_real_noise(self) -> RecordingFile:
        """The detectors that cannot hold their false-alarm rate on real noise are
        refused for recordings (issue 20; measured on the vendored drive): a windowed
        χ² and the CUSUM sum innovations a real receiver correlates over seconds (window
        8: 47-72 % of the epochs flagged, 3 084 m; CUSUM at arl0 1e4: 415 alarms/h, ~100
        times its setting), and the state χ² compares local estimates whose correlation
        the test ignores (19-77 % flagged)."""
        for i, m in enumerate(self.methods):
            d = getattr(m, "detector", None)
            kind = getattr(d, "kind", None)
            if kind == "state-chi2":
                raise config_error(
                    "the state chi-square test cannot run on real noise: it flags 19-77 % "
                    "of a fault-free real drive's epochs (use residual-chi2, glr or cusum)",
                    "methods",
                    i,
                    "detector",
                )
            if kind == "cusum":
                raise config_error(
                    "the CUSUM cannot run on real noise: it accumulates innovations a "
                    "receiver correlates over seconds and alarms about 100 times more often "
                    "than its arl0 on a fault-free real drive (415 alarms/h against 4.3); "
                    "use glr, which learns that correlation",
                    "methods",
                    i,
                    "detector",
                )
            if kind == "residual-chi2" and getattr(d, "window", 1) > 1:
                raise config_error(
                    "a windowed chi-square test cannot run on real noise: a receiver's "
                    "errors are correlated over seconds and window 8 flags 47-72 % of a "
                    "fault-free real drive's epochs (use window = 1, or glr, which learns "
                    "that correlation)",
                    "methods",
                    i,
                    "detector",
                    "window",
                )
        return self


class LoadedRecording(NamedTuple):
    """Everything ``ftnav process`` runs and scores.

    Attributes
    ----------
    recording : the engine's description.  stream : the engine's input (one run).
    reference_index, reference_p : epochs (0-based) and positions of the reference.
    alignment : the initial solution.  counts : what the readers handled (for output).
    outages : per run of the batch, the primary GNSS's outages, s relative to
        ``recording.t_start`` (interleaved schedules, :func:`ftnav.recorded.stream.interleave`).
    truth : a full truth (``[reference] source = "truth"``), or None.
    warnings : one line each, what the recording's data suggest is wrong but legal.
    reference_lever_arm : (3,) m, the point the reference measures from the IMU, body
        frame (x right, y forward, z up): a GNSS reference's antenna (its aid's
        ``lever_arm_m``), zeros for a truth at the IMU.
    """

    recording: Recording
    stream: Any
    reference_index: np.ndarray
    reference_p: np.ndarray
    alignment: Alignment
    counts: dict[str, Any]
    outages: tuple[tuple[tuple[float, float], ...], ...]
    truth: Truth | None = None
    warnings: tuple[str, ...] = ()
    reference_lever_arm: np.ndarray = np.zeros(3)


_ENV = re.compile(r"\$\{(\w+)(?::-([^}]*))?\}")


def _data_path(raw: str, base: Path, field: str, origin: str) -> Path:
    """A data file's path: relative to the recording file; ``${NAME:-default}`` is the
    environment variable NAME, or ``default`` when NAME is unset or empty (the NaveGo
    built-ins read ``${FTNAV_NAVEGO_DIR:-<the shared data folder>}``).  A file missing
    behind such a path is refused with where to put it."""
    names: list[str] = []

    def sub(m: re.Match[str]) -> str:
        names.append(m.group(1))
        value = os.environ.get(m.group(1))
        if value:
            return value
        if m.group(2) is None:
            raise ScenarioError(field, f"environment variable {m.group(1)} is not set", origin)
        return m.group(2)

    path = base / _ENV.sub(sub, raw)
    if names and not path.is_file():
        where = path.parent.resolve()
        raise ScenarioError(
            field,
            f"{path.resolve()}: file not found; put the data files in {where} or set "
            f"{' or '.join(names)} to the folder holding them",
            origin,
        )
    return path


def _factor(unit: str, families: Sequence[str], field: str, origin: str) -> tuple[float, str]:
    for family in families:
        try:
            return parse_quantity(f"1 {unit}", family, field), family  # type: ignore[arg-type]
        except ValueError:
            continue
    raise ScenarioError(field, f"unit {unit!r} is not one of the {' or '.join(families)}", origin)


def _column(table: Any, ref: str | int, field: str, origin: str) -> int:
    if isinstance(ref, int):
        if not 0 <= ref < len(table.columns):
            n = len(table.columns)
            raise ScenarioError(field, f"column {ref} (0-based): the file has {n}", origin)
        return ref
    if ref not in table.columns:
        raise ScenarioError(
            field, f"no column {ref!r} in the file (columns: {', '.join(table.columns)})", origin
        )
    return int(table.columns.index(ref))


def _axes_matrix(axes: Sequence[str]) -> np.ndarray:
    """(3, 3) ``M`` with ``body = M · sensor``."""
    M = np.zeros((3, 3))
    for row, a in enumerate(axes):
        M[row, "xyz".index(a[1])] = 1.0 if a[0] == "+" else -1.0
    return M


def _mounting(f: ImuFile, origin: str, axes: Sequence[str] | None = None) -> np.ndarray:
    """(3, 3) ``M`` with ``body = M · sensor`` from ``axes`` (default ``f.axes``) and
    ``misalignment_deg``."""
    axes = f.axes if axes is None else axes
    M = _axes_matrix(axes)
    if np.linalg.det(M) < 0.5:
        raise ScenarioError("imu.axes", f"{list(axes)} is not a right-handed axis set", origin)
    if not np.all(np.abs(f.misalignment_deg) <= 90.0):
        raise ScenarioError(
            "imu.misalignment_deg", f"{f.misalignment_deg}: each angle within ±90 deg", origin
        )
    return np.asarray(euler_to_dcm(np.radians(f.misalignment_deg)) @ M, float)


#: the largest rate (rad/s, 5 730 °/s) and specific force (m/s², 102 g) a recording may
#: hold, per axis: beyond the range of navigation IMUs (MEMS ±2 000 °/s and ±16 g,
#: tactical ±50 g), so a larger value is a corrupt field or a unit slip
GYRO_MAX_RAD_S, ACCEL_MAX_M_S2 = 100.0, 1000.0


def _imu_range(gyro: np.ndarray, accel: np.ndarray, where: Any, origin: str) -> None:
    """Refuse the first sample beyond :data:`GYRO_MAX_RAD_S` or :data:`ACCEL_MAX_M_S2`;
    ``where(row, kind)`` is ``(path, what)`` of that sample."""
    for kind, a, bound, unit in (
        ("gyro", gyro, GYRO_MAX_RAD_S, "rad/s"),
        ("accel", accel, ACCEL_MAX_M_S2, "m/s²"),
    ):
        big = np.abs(a).max(1)  # NaN: an increment over no time, dropped by the cleaning
        bad = np.flatnonzero(big > bound)
        if bad.size:
            r = int(bad[0])
            path, what = where(r, kind)
            raise ScenarioError(
                path,
                f"{what}: {big[r]:.3g} {unit} after the unit, beyond the ±{bound:g} {unit} of "
                "any navigation IMU (a corrupt value or a unit slip?)",
                origin,
            )


def _cleaned(
    t: np.ndarray, gyro: np.ndarray, accel: np.ndarray, where: Any, origin: str
) -> tuple[ImuLog, ImuCleaning]:
    """:func:`clean`; a stamp going back is refused naming ``where(row, reason)``."""
    try:
        return clean(ImuLog(t, gyro, accel))
    except TimeGoesBack as exc:
        field, reason = where(exc.row, exc.reason)
        raise ScenarioError(field, reason, origin) from None


def _read_navego_imu(
    f: ImuFile, base: Path, origin: str
) -> tuple[ImuLog, ImuCleaning, int, NavegoImu]:
    """The NaveGo layout: already in SI and (after the reader) in ftnav's body axes; the
    ``axes`` and ``misalignment_deg`` then apply as to a CSV log."""
    for key in _IMU_CSV_KEYS:
        if key in f.model_fields_set:
            raise ScenarioError(f"imu.{key}", "a setting of format 'csv', not 'navego-mat'", origin)
    path = _data_path(f.file, base, "imu.file", origin)
    nav = read_navego_imu(path, "imu.file")
    field = {"gyro": "wb", "accel": "fb"}
    _imu_range(
        nav.gyro,
        nav.accel,
        lambda row, kind: (str(path), f"field {field[kind]}: sample {row + 1}"),
        origin,
    )
    M = _mounting(f, origin)
    log, info = _cleaned(
        nav.t + f.time_offset_s,
        nav.gyro @ M.T,
        nav.accel @ M.T,
        lambda row, reason: (str(path), f"field t: sample {row + 1}: {reason}"),
        origin,
    )
    nav = nav._replace(
        gyro_bias_nominal=None if nav.gyro_bias_nominal is None else M @ nav.gyro_bias_nominal,
        accel_bias_nominal=None if nav.accel_bias_nominal is None else M @ nav.accel_bias_nominal,
    )
    return log, info, 0, nav


class _ImuLayout(NamedTuple):
    """Where an IMU table holds what: the columns (0-based), each quantity's unit as a
    factor to SI and its family (a rate or an increment), the axes."""

    time: int
    gyro: list[int]
    accel: list[int]
    time_factor: float
    gyro_factor: float
    gyro_family: str
    accel_factor: float
    accel_family: str
    axes: Sequence[str]


def _csv_imu(f: ImuFile, base: Path, origin: str) -> tuple[Table, Path, _ImuLayout]:
    """The ``csv`` layout of ``[imu]``: its table, path and layout."""
    for key in ("time", "gyro", "accel"):
        if getattr(f, key) is None:
            raise ScenarioError(f"imu.{key}", "missing required key (format 'csv')", origin)
    assert f.time is not None and f.gyro is not None and f.accel is not None
    path = _data_path(f.file, base, "imu.file", origin)
    table = read_csv(path, f.header, f.delimiter, "imu.file")
    t_fac, _ = _factor(f.time.unit, ("time",), "imu.time.unit", origin)
    g_fac, g_fam = _factor(f.gyro.unit, ("angular_rate", "angle"), "imu.gyro.unit", origin)
    a_fac, a_fam = _factor(f.accel.unit, ("acceleration", "velocity"), "imu.accel.unit", origin)
    for key, cols in (("gyro", f.gyro), ("accel", f.accel)):
        if len(cols.columns) != 3:
            got = len(cols.columns)
            raise ScenarioError(f"imu.{key}.columns", f"expected 3 columns, got {got}", origin)
    if len(f.time.columns) != 1:
        raise ScenarioError("imu.time.columns", "expected 1 column")
    tc = _column(table, f.time.columns[0], "imu.time.columns", origin)
    gc = [_column(table, c, "imu.gyro.columns", origin) for c in f.gyro.columns]
    ac = [_column(table, c, "imu.accel.columns", origin) for c in f.accel.columns]
    return table, path, _ImuLayout(tc, gc, ac, t_fac, g_fac, g_fam, a_fac, a_fam, f.axes)


#: KF-GINS's IMU text (i2Nav-WHU/KF-GINS README): GPS seconds of week, the increments
#: Δθ (rad) and Δv (m/s) over the interval ending there, forward-right-down; an eighth
#: column (an odometer) is not read
KFGINS_IMU_COLUMNS = (
    "gps_seconds_of_week",
    "dtheta_x_rad",
    "dtheta_y_rad",
    "dtheta_z_rad",
    "dv_x_mps",
    "dv_y_mps",
    "dv_z_mps",
    "odometer",
)
#: ftnav's body x (right), y (forward), z (up) from forward-right-down axes
KFGINS_AXES = ("+y", "+x", "-z")


def _kfgins_imu(f: ImuFile, base: Path, origin: str) -> tuple[Table, Path, _ImuLayout]:
    """The ``kfgins-text`` preset of ``[imu]``: its table, path and layout (increments in
    rad and m/s; the axes forward-right-down unless ``axes`` is given)."""
    for key in _IMU_CSV_KEYS:
        if key in f.model_fields_set:
            raise ScenarioError(
                f"imu.{key}", "a setting of format 'csv', not 'kfgins-text'", origin
            )
    path = _data_path(f.file, base, "imu.file", origin)
    table = read_csv(path, False, WHITESPACE, "imu.file", KFGINS_IMU_COLUMNS)
    if table.values.shape[1] not in (7, 8):
        raise ScenarioError(
            str(path),
            f"imu.file: {table.values.shape[1]} columns; a KF-GINS IMU file has 7 (GPS seconds "
            "of week, dθ x y z rad, dv x y z m/s) or 8 (and an odometer)",
            origin,
        )
    axes = f.axes if "axes" in f.model_fields_set else list(KFGINS_AXES)
    return (
        table,
        path,
        _ImuLayout(0, [1, 2, 3], [4, 5, 6], 1.0, 1.0, "angle", 1.0, "velocity", axes),
    )


def _read_imu(
    f: ImuFile, base: Path, origin: str
) -> tuple[ImuLog, ImuCleaning, int, NavegoImu | None]:
    if f.format == "navego-mat":
        return _read_navego_imu(f, base, origin)
    if f.format == "kfgins-text":
        table, path, layout = _kfgins_imu(f, base, origin)
    else:
        table, path, layout = _csv_imu(f, base, origin)
    tc, gc, ac, t_fac, g_fac, g_fam, a_fac, a_fam, axes = layout
    t = table.values[:, tc] * t_fac + f.time_offset_s
    M = _mounting(f, origin, axes)
    gyro = table.values[:, gc] * g_fac @ M.T
    accel = table.values[:, ac] * a_fac @ M.T
    if g_fam == "angle" or a_fam == "velocity":  # increments: rates over each interval
        dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
        dt = np.where(dt > 0, dt, np.nan)
        gyro = gyro / dt[:, None] if g_fam == "angle" else gyro
        accel = accel / dt[:, None] if a_fam == "velocity" else accel
    names = {"gyro": [table.columns[j] for j in gc], "accel": [table.columns[j] for j in ac]}
    _imu_range(
        gyro,
        accel,
        lambda row, kind: (
            f"{path}:{table.lines[row]}",
            f"columns {', '.join(str(c) for c in names[kind])}",
        ),
        origin,
    )
    log, info = _cleaned(
        t,
        gyro,
        accel,
        lambda row, reason: (f"{path}:{table.lines[row]}", f"column time: {reason}"),
        origin,
    )
    return log, info, table.dropped_partial, None


_TO_ENU = {  # column order -> ENU: index and sign
    "ENU": ([0, 1, 2], np.array([1.0, 1.0, 1.0])),
    "NED": ([1, 0, 2], np.array([1.0, 1.0, -1.0])),
    "NEU": ([1, 0, 2], np.array([1.0, 1.0, 1.0])),
}


def _columns(
    table: Table, cols: ColumnsFile, n: int, families: Sequence[str], field: str, origin: str
) -> tuple[np.ndarray, float]:
    """The ``n`` columns ``cols`` names in ``table`` (rows, n) and their unit's factor to
    SI (one of ``families``); ``field`` is the key's path."""
    if len(cols.columns) != n:
        got = len(cols.columns)
        raise ScenarioError(f"{field}.columns", f"expected {n}, got {got}", origin)
    fac, _ = _factor(cols.unit, families, f"{field}.unit", origin)
    idx = [_column(table, c, f"{field}.columns", origin) for c in cols.columns]
    return table.values[:, idx], fac


def _gnss_csv(a: AidTable, path: Path, field: str, origin: str) -> _GnssRead:
    """A GNSS solution as a delimited text file with a column map (``docs/recording-format.md``)."""
    for key in ("time", "lat", "lon", "height"):
        if getattr(a, key) is None:
            raise ScenarioError(f"{field}.{key}", "missing required key (format 'csv')", origin)
    table = read_csv(path, a.header, a.delimiter, f"{field}.file")

    def columns(key: str, n: int, families: Sequence[str]) -> tuple[np.ndarray, float]:
        return _columns(table, getattr(a, key), n, families, f"{field}.{key}", origin)

    t, t_fac = columns("time", 1, ("time",))
    lat, lat_fac = columns("lat", 1, ("angle",))
    lon, lon_fac = columns("lon", 1, ("angle",))
    h, h_fac = columns("height", 1, ("length",))
    p = np.concatenate([lat * lat_fac, lon * lon_fac, h * h_fac], 1)
    column = {k: getattr(a, k).columns[0] for k in ("lat", "lon", "height")}
    check_position(
        np.degrees(p[:, 0]),
        np.degrees(p[:, 1]),
        p[:, 2],
        lambda r, k: (f"{path}:{table.lines[r]}", f"column {column[k]}"),
    )
    v = np.full((t.shape[0], 3), np.nan)
    if a.velocity is not None:
        raw, fac = columns("velocity", 3, ("velocity",))
        order, sign = _TO_ENU[a.velocity.frame]
        v = raw[:, order] * sign * fac
    defaults: dict[str, Any] = {}
    per_epoch = np.full((t.shape[0], 6), np.nan)
    if a.sigma is not None:
        raw, fac = columns("sigma", 3, ("length",))
        sig = raw[:, _TO_ENU[a.sigma.frame][0]] * fac
        if np.any(sig <= 0):
            r = int(np.flatnonzero((sig <= 0).any(1))[0])
            raise ScenarioError(f"{path}:{table.lines[r]}", "column sigma: σ must be > 0")
        defaults["pos_white_sigma_m"] = tuple(float(x) for x in np.median(sig, 0))
        per_epoch[:, :3] = sig
    quality = np.ones(t.shape[0], int)
    if a.quality_column is not None:
        q = table.values[:, _column(table, a.quality_column, f"{field}.quality_column", origin)]
        if np.any(q != np.round(q)):
            r = int(np.flatnonzero(q != np.round(q))[0])
            raise ScenarioError(f"{path}:{table.lines[r]}", "column quality: not an integer flag")
        quality = q.astype(int)
    log = GnssLog(t=t[:, 0] * t_fac + a.time_offset_s, p=p, v=v, quality=quality, sigma=per_epoch)
    return log, defaults, table.lines


def _read_gnss(a: AidTable, base: Path, field: str, origin: str) -> tuple[GnssLog, dict[str, Any]]:
    """Every epoch of the aid's solution file (selection by quality comes later), and the
    GNSS sensor's parameter defaults the file gives (its σ)."""
    if a.file is None:
        raise ScenarioError(f"{field}.file", "missing required key (the GNSS solution file)")
    if a.format != "csv":
        for key in _GNSS_CSV_KEYS:
            if key in (a.model_fields_set or ()):
                raise ScenarioError(
                    f"{field}.{key}", f"a setting of format 'csv', not {a.format!r}", origin
                )
    path = _data_path(a.file, base, f"{field}.file", origin)
    log, defaults, lines = _read_gnss_format(a, path, field, origin)
    _refuse_repeated(log, path, lines)
    if not np.isfinite(log.v).any():  # a velocity row would leave every epoch out
        rows = (a.model_extra or {}).get("rows")
        if rows in ("position-velocity", "velocity"):
            raise ScenarioError(
                f"{field}.rows",
                f"{rows!r}, but the file has no velocity: the aid measures position only "
                "(rows = 'position', the default for such a file)",
                origin,
            )
        defaults["rows"] = "position"
    return log, defaults


#: what a GNSS reader gives: the epochs, the aid's defaults the file sets, and each
#: epoch's line in the file (None: a binary file, its rows counted from 1)
_GnssRead = tuple[GnssLog, dict[str, Any], np.ndarray | None]


def _refuse_repeated(log: GnssLog, path: Path, lines: np.ndarray | None) -> None:
    """Refuse an epoch whose time stamp repeats another's with other values: which of
    the two is the solution cannot be told (an exact repeat is dropped later, counted)."""
    order = np.argsort(log.t, kind="stable")
    same = np.flatnonzero(log.t[order][1:] == log.t[order][:-1])
    if not same.size:
        return
    rows = [log.p, log.v, log.quality[:, None]] + ([] if log.sigma is None else [log.sigma])
    values = np.concatenate([np.asarray(r, float) for r in rows], 1)
    line = (lambda r: int(lines[r])) if lines is not None else (lambda r: r + 1)
    kind = "line" if lines is not None else "row"
    for j in same:
        a, b = sorted((int(order[j]), int(order[j + 1])))
        if not np.array_equal(values[a], values[b], equal_nan=True):
            raise ScenarioError(
                f"{path}:{line(b)}",
                f"time stamp {log.t[b]:.3f} s repeats {kind} {line(a)}'s with another "
                "solution: which one is right cannot be told; remove one",
            )


def _read_gnss_format(a: AidTable, path: Path, field: str, origin: str) -> _GnssRead:
    """:func:`_read_gnss` of the aid's ``format``."""
    if a.format == "csv":
        return _gnss_csv(a, path, field, origin)
    if a.format == "kfgins-text":
        return _gnss_kfgins(a, path, field, origin)
    if a.format == "navego-mat":
        g = read_navego_gnss(path, f"{field}.file")
        defaults: dict[str, Any] = {}
        if g.sigma_p is not None:
            defaults["pos_white_sigma_m"] = tuple(float(x) for x in g.sigma_p)
        if g.sigma_v is not None:
            defaults["vel_white_sigma_m_s"] = tuple(float(x) for x in g.sigma_v)
        quality = np.ones(g.t.size, int)
        return GnssLog(t=g.t + a.time_offset_s, p=g.p, v=g.v, quality=quality), defaults, None
    pos = read_rtklib_pos(path, f"{field}.file")
    p = np.stack([pos.lat_deg * _DEG, pos.lon_deg * _DEG, pos.height_m], -1)
    sigma = np.concatenate([pos.sigma_neu[:, [1, 0, 2]], pos.sigma_v_neu[:, [1, 0, 2]]], -1)
    log = GnssLog(
        t=pos.t + a.time_offset_s,
        p=p,
        v=pos.v_neu[:, [1, 0, 2]],
        quality=pos.quality,
        sigma=sigma,
    )
    return log, {}, pos.lines


#: KF-GINS's GNSS text (i2Nav-WHU/KF-GINS README): GPS seconds of week, latitude and
#: longitude (deg), ellipsoidal height (m), σ North, East, Down (m)
KFGINS_GNSS_COLUMNS = (
    "gps_seconds_of_week",
    "lat_deg",
    "lon_deg",
    "height_m",
    "sigma_n_m",
    "sigma_e_m",
    "sigma_d_m",
)


def _gnss_kfgins(a: AidTable, path: Path, field: str, origin: str) -> _GnssRead:
    """The ``kfgins-text`` preset of a GNSS aid: positions and their σ, no velocity; every
    epoch quality 1; the σ the aid's default (their median) and per epoch."""
    table = read_csv(path, False, WHITESPACE, f"{field}.file", KFGINS_GNSS_COLUMNS)
    x = table.values
    if x.shape[1] != len(KFGINS_GNSS_COLUMNS):
        raise ScenarioError(
            str(path),
            f"{field}.file: {x.shape[1]} columns; a KF-GINS GNSS file has 7 (GPS seconds of "
            "week, lat lon deg, height m, σ N E D m): another layout is format 'csv' with "
            "delimiter 'whitespace'",
            origin,
        )
    check_position(
        x[:, 1],
        x[:, 2],
        x[:, 3],
        lambda r, k: (f"{path}:{table.lines[r]}", f"column {k}_{'m' if k == 'height' else 'deg'}"),
    )
    bad = np.argwhere(x[:, 4:7] <= 0)
    if bad.size:
        r, j = bad[0]
        raise ScenarioError(
            f"{path}:{table.lines[r]}", f"column {KFGINS_GNSS_COLUMNS[4 + j]}: σ must be > 0"
        )
    sigma = np.full((x.shape[0], 6), np.nan)
    sigma[:, :3] = x[:, [5, 4, 6]]  # E, N, U from N, E, D
    log = GnssLog(
        t=x[:, 0] + a.time_offset_s,
        p=np.stack([x[:, 1] * _DEG, x[:, 2] * _DEG, x[:, 3]], -1),
        v=np.full((x.shape[0], 3), np.nan),
        quality=np.ones(x.shape[0], int),
        sigma=sigma,
    )
    defaults = {"pos_white_sigma_m": tuple(float(s) for s in np.median(sigma[:, :3], 0))}
    return log, defaults, table.lines


def _some_quality(log: GnssLog, quality: Sequence[int], field: str, origin: str) -> None:
    """Refuse a quality filter that keeps no epoch of the file (it names the file's)."""
    if not np.isin(log.quality, quality).any():
        found = ", ".join(f"{q:g}: {int((log.quality == q).sum())}" for q in np.unique(log.quality))
        raise ScenarioError(
            field,
            f"no epoch of the GNSS file has quality {list(quality)} (its epochs: {found})",
            origin,
        )


def _select(log: GnssLog, keep: np.ndarray) -> GnssLog:
    """The epochs ``keep`` of every per-epoch field."""
    n = log.t.shape[0]
    return log._replace(
        **{
            k: x[keep]
            for k, x in zip(log._fields, log, strict=True)
            if isinstance(x, np.ndarray) and x.ndim >= 1 and x.shape[0] == n
        }
    )


_GNSS_DEFAULTS: dict[str, Any] = {  # a receiver's solution: its errors are white to the filter
    "markov": "white",
    "pos_markov_sigma_m": 0.0,
    "vel_markov_sigma_m_s": 0.0,
    "pos_white_sigma_m": 0.05,
    "vel_white_sigma_m_s": 0.1,
}
_NOT_SENSOR = (
    "type",
    "name",
    "file",
    "format",
    "quality",
    "time_offset_s",
    "velocity_time_offset_s",
)


def _gnss_log(a: AidTable, base: Path, field: str, origin: str) -> tuple[GnssLog, dict[str, Any]]:
    """:func:`_read_gnss` with the velocities moved onto the position stamps
    (``velocity_time_offset_s``, :func:`ftnav.recorded.stream.retime_velocity`)."""
    log, defaults = _read_gnss(a, base, field, origin)
    return retime_velocity(log, a.velocity_time_offset_s), defaults


#: an antenna farther from the IMU than this is warned about (m: a car, a truck's cab)
LEVER_ARM_WARN_M = 10.0
#: and refused beyond this (m: longer than any vehicle; a lever arm in mm?)
LEVER_ARM_MAX_M = 100.0
#: a GNSS σ (m, m/s) beyond these aids nothing (a unit slip or a placeholder)
POS_SIGMA_MAX_M, VEL_SIGMA_MAX_M_S = 1e4, 100.0
#: a .pos whose median σ exceeds the assumed default by this factor is warned about
SIGMA_DEFAULT_WARN = 4.0


def _gnss_checks(
    a: AidTable,
    sensor: Any,
    params: dict[str, Any],
    from_file: dict[str, Any],
    sel: GnssLog,
    field: str,
    origin: str,
) -> list[str]:
    """The GNSS aid's lever arm and σ: refused when impossible, a one-line warning each
    when suspicious.  A CSV or NaveGo file without its σ needs them in the recording:
    no receiver's σ can be assumed (an RTK fix is 1 cm, a single point 5 m)."""
    notes = []
    arm = float(np.linalg.norm(sensor.lever_arm_m))
    if arm > LEVER_ARM_MAX_M:
        raise ScenarioError(
            f"{field}.lever_arm_m",
            f"the antenna {arm:.3g} m from the IMU: more than the {LEVER_ARM_MAX_M:g} m of "
            "any vehicle (metres, body frame right, forward, up)",
            origin,
        )
    if arm > LEVER_ARM_WARN_M:
        notes.append(
            f"{origin}: {field}.lever_arm_m: the antenna is {arm:.3g} m from the IMU, more "
            f"than {LEVER_ARM_WARN_M:g} m (metres, body frame right, forward, up)"
        )
    given = set(params)
    for kind, rows, bound, unit in (
        ("pos", slice(0, 3), POS_SIGMA_MAX_M, "m"),
        ("vel", slice(3, 6), VEL_SIGMA_MAX_M_S, "m/s"),
    ):
        white = "pos_white_sigma_m" if kind == "pos" else "vel_white_sigma_m_s"
        override = "pos_sigma_m" if kind == "pos" else "vel_sigma_m_s"
        names = [c for c in sensor.components if c.startswith(kind)]
        if not names:
            continue
        key = override if override in given else white
        var = np.diag(sensor.R)[[sensor.components.index(c) for c in names]]
        if np.any(var <= 0):
            raise ScenarioError(
                f"{field}.{key}",
                f"σ 0 ({', '.join(n for n, v in zip(names, var, strict=True) if v <= 0)}) "
                "makes the filter take the fixes as exact: give the receiver's σ (> 0)",
                origin,
            )
        if np.sqrt(var.max()) > bound:
            raise ScenarioError(
                f"{field}.{key}",
                f"σ {np.sqrt(var.max()):.3g} {unit}: beyond {bound:g} {unit} a fix aids "
                "nothing (is the unit right?)",
                origin,
            )
        explicit = given & {white, override, white.replace("white", "markov")}
        if explicit or white in from_file:
            continue
        if a.format != "rtklib-pos":
            if kind == "vel" and not np.isfinite(sel.v).any():
                continue  # no velocity in the file: the rows count as missing
            source = "sigma columns" if a.format == "csv" else ("std" if kind == "pos" else "stdv")
            raise ScenarioError(
                f"{field}.{white}",
                f"missing: the file has no {kind}ition σ ({source}) and no receiver's σ can "
                f"be assumed (an RTK fix: 0.01-0.05 m, a single point: 5 m); set {white}"
                if kind == "pos"
                else f"missing: the file has no velocity σ ({source}) and no receiver's σ "
                f"can be assumed; set {white}",
                origin,
            )
        sig = sel.sigma[:, rows] if sel.sigma is not None else np.full((0, 3), np.nan)
        sig = sig[np.isfinite(sig) & (sig > 0)]
        default = _GNSS_DEFAULTS[white]
        if sig.size and float(np.median(sig)) > SIGMA_DEFAULT_WARN * default:
            notes.append(
                f"{origin}: {field}.{white}: not set, the filter assumes {default:g} {unit} "
                f"(an RTK fix) while the file's σ are {float(np.median(sig)):.3g} {unit} "
                f"(median): set {white}"
            )
    return notes


def _gnss_moves(a: AidTable, sel: GnssLog, field: str, origin: str) -> list[str]:
    """The file's positions against its own velocities (:func:`~ftnav.recorded.
    plausibility.position_rate_verdict`): an angle unit slip refused, another gain
    warned about."""
    _, moves = position_rate_verdict(sel.t, sel.p, sel.v)
    if moves.level == "ok":
        return []
    csv = a.format == "csv"
    if moves.level == "refusal":
        raise ScenarioError(f"{field}.lat.unit" if csv else f"{field}.file", moves.reason, origin)
    where = f"{field}.lat.unit, {field}.velocity.unit" if csv else f"{field}.file"
    return [f"{origin}: {where}: {moves.reason}"]


#: ``filter.imu_rate_hz`` at most this many times the log's own rate
IMU_RATE_MAX_FACTOR = 10.0
#: bytes per IMU increment of the stream while it is built (the grid, the cumulative
#: integrals interpolated onto it and their differences, the stream's Δθ and Δv)
_BYTES_PER_INCREMENT = 256


def _grid(
    gnss: GnssLog, imu: ImuLog, start: float, f: RecordingFile, origin: str = ""
) -> tuple[float, int, int, int]:
    """Filter period (the GNSS period split into ``sub`` epochs to reach ``rate_hz``),
    epochs, IMU increments per epoch (even, for the two-sample algorithm), ``sub``.

    Refused: an ``imu_rate_hz`` above :data:`IMU_RATE_MAX_FACTOR` times the log's, and
    increments that would not fit in the memory available."""
    period = float(np.round(np.median(np.diff(np.sort(gnss.t))), 3))
    sub = max(1, math.ceil(period * f.filter.rate_hz - 1e-9))
    dt = period / sub
    t_end = min(float(imu.t[-1]), float(gnss.t.max()))
    if f.filter.duration_s is not None:
        t_end = min(t_end, start + f.filter.duration_s)
    steps = int(math.floor((t_end - start) / dt + 1e-9))
    if steps < 2:
        raise ScenarioError("filter.duration_s", f"{steps} filter epoch(s) after the alignment")
    own = 1.0 / float(np.median(np.diff(imu.t)))
    rate = f.filter.imu_rate_hz or own
    if rate > IMU_RATE_MAX_FACTOR * own:
        raise ScenarioError(
            "filter.imu_rate_hz",
            f"{rate:g} Hz is more than {IMU_RATE_MAX_FACTOR:g} times the log's {own:.4g} Hz: "
            "integration steps finer than the samples add nothing",
            origin,
        )
    spe = int(math.ceil(dt * rate - 1e-6))
    spe += spe % 2
    need = steps * spe * _BYTES_PER_INCREMENT
    avail = available_memory_bytes()
    if avail is not None and need > avail:
        raise ScenarioError(
            "filter.imu_rate_hz",
            f"{steps * spe} IMU increments need about {format_bytes(need)}, more than the "
            f"{format_bytes(avail)} available (a lower imu_rate_hz or filter.duration_s)",
            origin,
        )
    return dt, steps, spe, sub


def _outages(
    outage: tuple[float, float, float], start: float, last: float
) -> list[tuple[float, float]]:
    """The outage schedule (:func:`ftnav.recorded.stream.outage_schedule`, s after the
    first GNSS epoch) without the outages that end before the filter starts at ``start``;
    refused when none is left."""
    length, every, first = outage
    try:
        sched = outage_schedule(length, every, first, last=last)
    except ValueError as exc:
        raise ScenarioError("--outage-length", str(exc).partition(": ")[2] or str(exc)) from None
    sched = [(s, e) for s, e in sched if e > start]
    if not sched:
        raise ScenarioError(
            "--outage-start",
            f"no outage of {length:g} s every {every:g} s from {first:g} s fits in the "
            f"processed span [{start:.1f}, {last:.1f}] s (s after the first GNSS epoch; "
            "every outage ends 30 s before the span's end)",
        )
    return sched


def _initial_sigma(
    attitude: np.ndarray,
    velocity: np.ndarray,
    position_enu: np.ndarray,
    bias_sigma: np.ndarray,
    p: np.ndarray,
) -> np.ndarray:
    """σ of the initial errors: attitude (rad), velocity (m/s), position E, N, U (m) as
    ``δL, δλ, δh``, then the biases."""
    R = 6378137.0 + p[2]
    pos = np.asarray(position_enu, float) * np.ones(3)
    nav = np.r_[
        np.asarray(attitude, float),
        np.asarray(velocity, float) * np.ones(3),
        [pos[1] / R, pos[0] / (R * math.cos(p[0]))],
        [pos[2]],
    ]
    return np.asarray(np.maximum(np.r_[nav, bias_sigma], 1e-12), float)


def _gyrocompass_sigma(
    a: AlignmentFile, log: ImuLog, gnss: GnssLog, imu_err: ImuErrors | None
) -> float:
    """The predicted σ (rad) of a gyrocompass heading over the static window from the
    IMU's datasheet (its horizontal gyros' constant and Markov bias σ and ARW)."""
    if imu_err is None:
        return float("inf")
    b = np.broadcast_to(np.asarray(imu_err.gyro_bias_sd, float), (3,))
    m = np.broadcast_to(np.asarray(imu_err.gyro_markov_sd, float), (3,))
    arw = float(np.max(np.broadcast_to(np.asarray(imu_err.gyro_arw, float), (3,))[:2]))
    bias = float(np.max(np.hypot(b, m)[:2]))
    lat = float(gnss.p[0, 0]) if gnss.t.size else 0.0
    return gyrocompass_sigma(lat, bias, arw, a.static_s)


def _static_noise(
    f: RecordingFile, log: ImuLog, imu_err: ImuErrors, origin: str
) -> tuple[ImuErrors, dict[str, Any] | None, str | None]:
    """The IMU errors with the static window's white noise where it exceeds the
    datasheet's (``[alignment] noise = "max"``, :func:`ftnav.recorded.imu.noise_density`),
    what was measured (for ``metrics.json``) and a one-line warning when that is more
    than twice the datasheet's and the file does not say ``noise`` (or None)."""
    a = f.alignment
    if a.mode != "static" or a.noise == "datasheet":
        return imu_err, None, None
    try:  # clusters of 1 s, shorter in a window of less than 4 s
        gyro, accel = noise_density(log, log.t[0] + a.static_s, min(1.0, a.static_s / 4))
    except ValueError as exc:
        path, _, reason = str(exc).partition(": ")
        raise ScenarioError(path, reason, origin) from None
    arw = np.maximum(imu_err.gyro_arw, gyro)
    vrw = np.maximum(imu_err.accel_vrw, accel)
    r_g = float(np.max(gyro / np.maximum(imu_err.gyro_arw, 1e-300)))
    r_a = float(np.max(accel / np.maximum(imu_err.accel_vrw, 1e-300)))
    message = None
    if max(r_g, r_a) > 2.0 and "noise" not in a.model_fields_set:
        message = (
            f"{origin}: alignment.noise: the static window's white noise is up to "
            f"{r_g:.3g} times the datasheet's for the gyros ({np.max(gyro) * 180 / np.pi:.3g} "
            f"deg/s/sqrt(Hz)) and {r_a:.3g} times for the accelerometers "
            f"({np.max(accel) / 9.80665e-6:.3g} ug/sqrt(Hz)): vibration; the filter uses the "
            f"larger per axis (set noise = 'max' to say so, 'datasheet' for the datasheet's)"
        )
    note = {
        "gyro_deg_s_rt_hz": (gyro * 180 / np.pi).tolist(),
        "accel_ug_rt_hz": (accel / 9.80665e-6).tolist(),
        "used_gyro_deg_s_rt_hz": (arw * 180 / np.pi).tolist(),
        "used_accel_ug_rt_hz": (vrw / 9.80665e-6).tolist(),
    }
    return replace(imu_err, gyro_arw=arw, accel_vrw=vrw), note, message


def _start(
    f: RecordingFile,
    log: ImuLog,
    gnss: GnssLog,
    nav: NavegoImu | None,
    origin: str,
    imu_err: ImuErrors | None = None,
) -> tuple[Alignment, np.ndarray]:
    """The initial solution and the σ of its attitude (rad) (``[alignment]``)."""
    a = f.alignment
    span = float(log.t[-1] - log.t[0])
    if a.mode == "static" and a.static_s >= span:
        raise ScenarioError(
            "alignment.static_s",
            f"{a.static_s:g} s of standing still, but the IMU log is {span:.1f} s long",
            origin,
        )
    if a.mode == "static":
        for key in ("attitude_deg", "velocity_mps", "position_deg_m"):
            if getattr(a, key) is not None:
                raise ScenarioError(
                    f"alignment.{key}", "a setting of mode 'given', not 'static'", origin
                )
        sigma_gc = _gyrocompass_sigma(a, log, gnss, imu_err)
        use_gc = a.heading == "gyrocompass" or (
            a.heading == "auto" and sigma_gc <= a.gyrocompass_max_sigma_deg * _DEG
        )
        try:
            al = align(log, gnss, a.static_s, a.min_speed_mps, sigma_gc if use_gc else None)
        except ValueError as exc:
            path, _, reason = str(exc).partition(": ")
            raise ScenarioError(path, reason, origin) from None
        sigma = np.asarray(a.attitude_sigma_deg) * _DEG
        if use_gc and "attitude_sigma_deg" not in a.model_fields_set:
            sigma[2] = sigma_gc
        return al, sigma
    for key in ("static_s", "min_speed_mps", "heading", "gyrocompass_max_sigma_deg", "noise"):
        if key in a.model_fields_set:
            raise ScenarioError(
                f"alignment.{key}", "a setting of mode 'static', not 'given'", origin
            )
    if a.attitude_deg is not None:
        euler = np.asarray(a.attitude_deg) * _DEG
    elif nav is not None and nav.euler is not None:
        euler = nav.euler
    else:
        raise ScenarioError(
            "alignment.attitude_deg",
            "mode 'given' needs the initial [pitch, roll, yaw] (or an IMU file with ini_align)",
            origin,
        )
    if "attitude_sigma_deg" in a.model_fields_set or nav is None or nav.euler_sigma is None:
        sigma = np.asarray(a.attitude_sigma_deg) * _DEG
    else:
        sigma = nav.euler_sigma
    if np.any(sigma <= 0):
        raise ScenarioError("alignment.attitude_sigma_deg", "every σ must be > 0", origin)
    # the start is the first fix in the IMU log: its velocity and position unless given
    v_file = gnss.v
    v = np.nan_to_num(v_file) if a.velocity_mps is None else np.asarray(a.velocity_mps, float)
    try:
        al = given(log, gnss._replace(v=np.broadcast_to(v, v_file.shape)), euler)
    except ValueError as exc:
        path, _, reason = str(exc).partition(": ")
        raise ScenarioError(path, reason, origin) from None
    k = int(np.flatnonzero(gnss.t == al.t)[0])
    if a.velocity_mps is None and not np.isfinite(v_file[k]).all():
        which = "has no velocity" if np.isnan(v_file).all() else "has none at that epoch"
        raise ScenarioError(
            "alignment.velocity_mps",
            f"the start velocity is unknown: the first GNSS fix in the IMU log (t = "
            f"{al.t:.3f} s) has no velocity (the file {which}); set velocity_mps = [E, N, U] "
            "m/s, the vehicle's velocity then",
            origin,
        )
    if a.position_deg_m is not None:
        lat, lon, h = (np.array([x]) for x in a.position_deg_m)
        check_position(lat, lon, h, lambda r, name: ("alignment.position_deg_m", name))
        al = al._replace(p=np.array([lat[0] * _DEG, lon[0] * _DEG, h[0]]))
    return al, sigma


def _aids(
    f: RecordingFile,
    base: Path,
    origin: str,
    primary: tuple[int, GnssLog, dict[str, Any]],
    log: ImuLog,
    grid: tuple[float, float, int, int],
    faults: Sequence[Fault],
) -> tuple[
    list[AidSpec], list[tuple[np.ndarray, np.ndarray, np.ndarray]], dict[str, Any], list[str]
]:
    """Every aid's sensor model and its epochs on the filter grid (outages are cut from the
    stream afterwards, :func:`ftnav.recorded.stream.with_outages`), and the warnings about
    them (:func:`_gnss_checks`)."""
    t0, dt, steps, sub = grid
    times = t0 + dt * np.arange(1, steps + 1)
    # the primary GNSS's epochs: where a constraint applies (recorded.aids.AidContext)
    primary_epochs = np.arange(sub - 1, steps, sub)
    specs, streams, counts, notes = [], [], {}, []
    moved: set[str | None] = set()
    for i, a in enumerate(f.aids):
        name, field = a.name or a.type, f"aids[{i}]"
        params = {k: v for k, v in (a.model_extra or {}).items() if k not in _NOT_SENSOR}
        if a.type == "gnss":
            g, from_file = primary[1:] if i == primary[0] else _gnss_log(a, base, field, origin)
            _some_quality(g, a.quality, f"{field}.quality", origin)
            sel = _select(g, np.isin(g.quality, a.quality))
            sensor = sensor_from_table(
                "gnss",
                {**_GNSS_DEFAULTS, **from_file, **params, "name": name},
                field,
                origin,
                dt=dt,
            )
            assert isinstance(sensor, Gnss)  # the table's type is gnss
            notes += _gnss_checks(a, sensor, params, from_file, sel, field, origin)
            if a.file not in moved:  # once a file (a receiver's two aids share one)
                moved.add(a.file)
                notes += _gnss_moves(a, sel, field, origin)
            raw, labels = gnss_raw(sel, faults, name, _assumed_sigma(sensor, sel))
            # the values a position (velocity) aid does not measure are no part of its
            # epochs: a file without velocity does not leave every epoch out
            other = {"position": slice(3, 6), "velocity": slice(0, 3)}.get(sensor.rows)
            if other is not None:
                raw[:, other] = np.nan_to_num(raw[:, other], nan=0.0)
            if sensor.per_epoch_sigma:  # the file's σ after the values (sensors.gnss)
                # a missing σ is 0: the row keeps the sensor's R (NaN would mean "no epoch")
                sig = sel.sigma if sel.sigma is not None else np.zeros((sel.t.size, 6))
                raw = np.concatenate([raw, np.nan_to_num(sig, nan=0.0)], -1)
            place = on_grid(sel.t, t0, dt, steps)
            streams.append((place.index, raw[place.kept], labels[place.kept]))
            counts[name] = {
                "epochs": int(g.t.size),
                "quality_selected": int(sel.t.size),
                "off_grid_dropped": place.off_grid,
                "duplicated_dropped": place.duplicated,
                "unsorted": place.unsorted,
                "applied": int(np.isfinite(raw[place.kept]).all(-1).sum()),
            }
        else:
            reader = _column_reader(base, field, origin)
            ctx = AidContext(name, dt, times, primary_epochs, log, reader)
            ready = _plugin_aid(a, name, field, origin, ctx)
            sensor = ready.sensor
            streams.append((ready.index, ready.raw, ready.labels))
            if ready.counts:
                counts[name] = dict(ready.counts)
        specs.append(AidSpec(sensor))
    return specs, streams, counts, notes


def _assumed_sigma(sensor: Gnss, log: GnssLog) -> np.ndarray:
    """(K, 6) the σ the filter assumes for each of the receiver's six values (E, N, U m,
    m/s): the epoch's own σ where the aid reads it from the file, else its R."""
    sigma = np.broadcast_to(sensor.sigma_all, (log.t.size, 6)).copy()
    if sensor.per_epoch_sigma and log.sigma is not None:
        own = np.isfinite(log.sigma) & (log.sigma > 0)
        sigma[own] = log.sigma[own]
    return sigma


def _column_reader(base: Path, field: str, origin: str) -> ColumnReader:
    """``read_columns(file, columns, header, delimiter)`` for a plug-in aid's own log: the
    strict delimited-text reader (errors name file:line and ``aids[i].file``)."""

    def read_columns(
        file: str, columns: Sequence[str | int], header: bool = True, delimiter: str = ","
    ) -> np.ndarray:
        path = _data_path(file, base, f"{field}.file", origin)
        table = read_csv(path, header, delimiter, f"{field}.file")
        idx = [_column(table, c, f"{field}.columns", origin) for c in columns]
        return np.asarray(table.values[:, idx], float)

    return read_columns


def _plugin_aid(a: AidTable, name: str, field: str, origin: str, ctx: AidContext) -> PreparedAid:
    """A plug-in aid (:data:`ftnav.recorded.aids.RECORDING_AIDS`): its keys validated by
    its own settings model (errors name ``aids[i].<key>``), then prepared."""
    plugin = RECORDING_AIDS[a.type]
    known = plugin.settings.model_fields
    keys = dict(a.model_extra or {})
    for key in sorted((a.model_fields_set & set(AidTable.model_fields)) - {"type", "name"}):
        if key not in known:  # a key of the GNSS receiver's table
            raise ScenarioError(f"{field}.{key}", f"a setting of gnss, not of {a.type}", origin)
        keys[key] = getattr(a, key)
    for key in keys:
        if key not in known:
            owners = [t for t, p in RECORDING_AIDS.items() if key in p.settings.model_fields]
            why = (
                f"a setting of {', '.join(owners)}, not of {a.type}"
                if owners
                else f"unknown parameter of a {a.type} aid (known: {', '.join(known)})"
            )
            raise ScenarioError(f"{field}.{key}", why, origin)
    try:
        settings = plugin.settings.model_validate(keys)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise ScenarioError(f"{field}.{format_loc(err['loc'])}", err["msg"], origin) from None
    try:
        return plugin.prepare(settings, ctx)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(field, " ".join(str(exc).split()), origin) from None


class ParsedRecording(NamedTuple):
    """A recording file read and validated (once: :func:`parse_recording`); its data
    files are not read yet.  ``path`` names it in errors and anchors its data paths."""

    path: Path
    file: RecordingFile


def parse_recording(source: str | Path | ParsedRecording) -> ParsedRecording:
    """Read and validate a recording file (TOML; errors name the file and the field), or
    a built-in recording given by its name (:func:`ftnav.recordings.recording_names`)."""
    if isinstance(source, ParsedRecording):
        return source
    if isinstance(source, str) and source in recording_names() and not Path(source).exists():
        source = recording_path(source)
    try:
        f = RecordingFile.model_validate(read_toml(source))
    except ValidationError as exc:
        err = to_scenario_error(exc, str(source), RecordingFile, explain_method_key)
        raise with_line(err, source) from None
    return ParsedRecording(Path(source), f)


def _validated(source: str | Path | ParsedRecording) -> RecordingFile:
    return parse_recording(source).file


def recording_aids(source: str | Path | ParsedRecording) -> dict[str, str]:
    """The aids a recording file names, ``{name: type}`` (its data files are not read);
    a GNSS aid that measures velocity only has the type ``"gnss-velocity"``."""
    return {
        a.name or a.type: (
            "gnss-velocity" if (a.model_extra or {}).get("rows") == "velocity" else a.type
        )
        for a in _validated(source).aids
    }


def _keep_aids(f: RecordingFile, aids: Sequence[str] | None) -> RecordingFile:
    if aids is None:
        return f
    known = [a.name or a.type for a in f.aids]
    for nm in aids:
        if nm not in known:
            raise ScenarioError("--aids", f"no aid {nm!r} (known: {', '.join(known)})")
    return f.model_copy(update={"aids": [a for a in f.aids if (a.name or a.type) in aids]})


def _check_gnss_epochs(gnss: GnssLog, log: ImuLog, first: int, origin: str) -> None:
    """The primary GNSS has a period (the filter's, :func:`_grid`: two epochs at distinct
    times at least, and most epochs not repeating a stamp), and its log overlaps the
    IMU's."""
    distinct = np.unique(gnss.t)
    if distinct.size < 2:
        raise ScenarioError(
            f"aids[{first}].file",
            f"{distinct.size} distinct epoch time(s): the primary GNSS's period is the "
            "filter's, which needs two epochs at least",
            origin,
        )
    if not np.round(np.median(np.diff(np.sort(gnss.t))), 3) > 0:
        raise ScenarioError(
            f"aids[{first}].file",
            "the median time between GNSS epochs rounds to 0 ms (most epochs repeat a "
            "time stamp): the filter's period cannot come from it",
            origin,
        )
    a, b, c, d = float(log.t[0]), float(log.t[-1]), float(distinct[0]), float(distinct[-1])
    if min(b, d) <= max(a, c):
        raise ScenarioError(
            "imu/gnss",
            f"the logs do not overlap: IMU [{a:.3f}, {b:.3f}] s, GNSS [{c:.3f}, {d:.3f}] s "
            "(one time base? imu.time_offset_s and the aid's time_offset_s shift them)",
            origin,
        )


def _unit_factors(f: ImuFile, origin: str) -> tuple[float, float]:
    """The declared gyro unit in rad/s and accelerometer unit in m/s², 0 for increments
    (NaveGo: SI by format; KF-GINS: increments by format)."""
    if f.format == "kfgins-text":
        return 0.0, 0.0
    if f.format == "navego-mat" or f.gyro is None or f.accel is None:
        return 1.0, 1.0
    g_fac, g_fam = _factor(f.gyro.unit, ("angular_rate", "angle"), "imu.gyro.unit", origin)
    a_fac, a_fam = _factor(f.accel.unit, ("acceleration", "velocity"), "imu.accel.unit", origin)
    return (g_fac if g_fam == "angular_rate" else 0.0), (a_fac if a_fam == "acceleration" else 0.0)


def _plausible_imu(
    f: RecordingFile, log: ImuLog, gnss: GnssLog, imu_err: ImuErrors, origin: str
) -> list[str]:
    """The IMU's units against gravity and the GNSS course (:mod:`ftnav.recorded.
    plausibility`): a refusal raised, the warnings returned (one line each)."""
    g_fac, a_fac = _unit_factors(f.imu, origin)
    csv = f.imu.format == "csv"
    a = f.alignment
    g = float(gravity(float(gnss.p[0, 0]), float(gnss.p[0, 2])))
    accel_sd = float(
        np.max(np.hypot(np.asarray(imu_err.accel_bias_sd), np.asarray(imu_err.accel_markov_sd)))
    )
    static = a.mode == "static"
    w = log.t < log.t[0] + a.static_s if static else np.ones(log.t.size, bool)
    checks: list[tuple[str, Verdict]] = []
    if static and log.t[0] + a.static_s <= log.t[-1]:  # longer: refused as such later
        moving = static_motion_verdict(gnss.t, gnss.v, log.t[0], a.static_s, a.min_speed_mps)
        checks.append(("alignment.static_s", moving))
    if static and w.sum() >= 10:
        f_norm = float(np.linalg.norm(log.accel[w].mean(0)))
        where = f"over the static {a.static_s:g} s"
    else:
        f_norm = float(np.median(np.linalg.norm(log.accel, axis=1)))
        where = "(median over the log)"
    path = "imu.accel.unit" if csv else "imu.file"
    checks.append((path, specific_force_verdict(f_norm, g, a_fac, accel_sd, where)))
    path = "imu.gyro.unit" if csv else "imu.file"
    fit = course_rate_gain(log, gnss.t, gnss.v, a.min_speed_mps)
    course = gyro_gain_verdict(fit, g_fac)
    if static and w.sum() >= 10:
        bias = np.hypot(np.asarray(imu_err.gyro_bias_sd), np.asarray(imu_err.gyro_markov_sd))
        w_norm = float(np.linalg.norm(log.gyro[w].mean(0)))
        bias3 = float(np.linalg.norm(np.broadcast_to(bias, (3,))))
        v = static_rate_verdict(w_norm, g_fac, bias3, a.static_s)
        if v.level == "refusal" and fit is not None and holds(fit) and 0.5 <= fit.k <= 2.0:
            # the GNSS course confirms the unit: the window is not still
            path, v = (
                "alignment.static_s",
                Verdict(
                    "refusal",
                    f"the IMU turns over the static {a.static_s:g} s (mean rate {w_norm:.3g} "
                    "rad/s, the unit confirmed by the GNSS course): the window must be still",
                ),
            )
        checks.append((path, v))
        path = "imu.gyro.unit" if csv else "imu.file"
    checks.append((path, course))
    notes = []
    for field, v in checks:
        if v.level == "refusal":
            raise ScenarioError(field, v.reason, origin)
        if v.level == "warning":
            notes.append(f"{origin}: {field}: {v.reason}")
    return notes


def load_recording(
    source: str | Path | ParsedRecording,
    *,
    outage: tuple[float, float, float] | None = None,
    faults: Sequence[Fault] = (),
    methods: Sequence[str] | None = None,
    aids: Sequence[str] | None = None,
    warn: bool = True,
) -> LoadedRecording:
    """Read and validate a recording file and its data files; build what the engine runs.

    Parameters
    ----------
    source : the recording file, or the file already parsed (:func:`parse_recording`:
        it is not read again).
    outage : ``(length, every, start)`` s of a GNSS outage schedule after the first
        GNSS epoch, clipped to leave 30 s at the end
        (:func:`ftnav.recorded.stream.outage_schedule`); None: GNSS on.
    faults : injected into the recorded aids, ``start``/``end`` on the recording's
        time base.
    methods : the names of the methods to run (default: every method of the file).
    aids : the names of the aids to use (default: every aid of the file).
    warn : issue the recording's warnings (:attr:`LoadedRecording.warnings`) as
        :class:`~ftnav.io.ins_scenario_file.ScenarioWarning` once it is all valid (the
        command line issues them after its own checks).
    """
    parsed = parse_recording(source)
    try:
        return _load(parsed, outage, faults, methods, aids, warn)
    except ScenarioError as e:  # the line of the recording file that sets the field
        raise with_line(e, parsed.path) from None


def _load(
    parsed: ParsedRecording,
    outage: tuple[float, float, float] | None,
    faults: Sequence[Fault],
    methods: Sequence[str] | None,
    aids: Sequence[str] | None,
    warn: bool,
) -> LoadedRecording:
    """:func:`load_recording` of a parsed file."""
    origin, base = str(parsed.path), parsed.path.parent
    for i, x in enumerate(faults):
        if x.kind not in RECORDING_FAULT_KINDS:
            raise ScenarioError(
                f"faults[{i}].kind",
                f"{x.kind!r} has no recorded form (recordings: {', '.join(RECORDING_FAULT_KINDS)})",
            )
        if (x.kind == "gyro-bias") != (x.sensor == SINS):
            raise ScenarioError(
                f"faults[{i}].kind",
                "'gyro-bias' is the only fault of the SINS and applies only to it",
            )
    f = _keep_aids(parsed.file, aids)
    imu_err = imu_errors(f.imu.errors, "imu.errors", origin)
    log, cleaning, partial, nav = _read_imu(f.imu, base, origin)
    first = next((i for i, a in enumerate(f.aids) if a.type == "gnss"), None)
    if first is None:
        raise ScenarioError("aids", "a recording needs a gnss aid (its epochs are the filter's)")
    gnss_all, gnss_defaults = _gnss_log(f.aids[first], base, f"aids[{first}]", origin)
    _check_gnss_epochs(gnss_all, log, first, origin)
    _some_quality(gnss_all, f.aids[first].quality, f"aids[{first}].quality", origin)
    gnss = _select(gnss_all, np.isin(gnss_all.quality, f.aids[first].quality))
    imu_notes = _plausible_imu(f, log, gnss_all, imu_err, origin)
    al, attitude_sigma = _start(f, log, gnss, nav, origin, imu_err)
    imu_err, noise_note, noise_warning = _static_noise(f, log, imu_err, origin)
    raw_log = log
    # the static window's bias out; the SINS's injected faults in (after the alignment)
    log = imu_with_faults(log._replace(gyro=log.gyro - al.gyro_bias), faults)
    dt, steps, spe, sub = _grid(gnss_all, log, al.t, f, origin)
    t_origin = float(gnss_all.t.min())
    sched: list[tuple[float, float]] = []
    if outage is not None:
        # the last GNSS epoch processed (filter.duration_s may end the run before the log)
        last = min(float(gnss_all.t.max()), al.t + steps * dt) - t_origin
        sched = _outages(outage, al.t - t_origin, last)
        sched = [(s + t_origin, e + t_origin) for s, e in sched]
    chosen = list(f.methods)
    if methods is not None:
        known = [m.name for m in chosen]
        for nm in methods:
            if nm not in known:
                raise ScenarioError("--methods", f"no method {nm!r} (known: {', '.join(known)})")
        chosen = [m for m in chosen if m.name in methods]
    specs, streams, counts, aid_notes = _aids(
        f, base, origin, (first, gnss_all, gnss_defaults), log, (al.t, dt, steps, sub), faults
    )
    fm = filter_model(imu_err, f.filter.states)
    a = f.alignment
    if a.mode == "given":  # the first fix's own σ
        g0 = specs[first].sensor
        vel_sigma = np.hypot(g0.vel_white_sigma_m_s, g0.vel_markov_sigma_m_s)
        pos_sigma = np.hypot(g0.pos_white_sigma_m, g0.pos_markov_sigma_m)
    else:
        vel_sigma, pos_sigma = np.array(0.1), np.array(0.1)
    if a.velocity_sigma_mps is not None:
        vel_sigma = np.array(a.velocity_sigma_mps)
    if a.position_sigma_m is not None:
        pos_sigma = np.array(a.position_sigma_m)
    rel = tuple(Fault(x.sensor, x.kind, x.start - al.t, x.end - al.t, x.magnitude) for x in faults)
    rec = Recording(
        name=f.name,
        description=f.description,
        dt=dt,
        steps=steps,
        faults=rel,
        methods=tuple(chosen),
        evaluation=f.evaluation.settings(DEFAULT_SIGMA_BOUND_M),
        t_start=al.t,
        t_origin=t_origin,
        samples_per_epoch=spe,
        error_model=fm.params,
        initial_sigma=_initial_sigma(attitude_sigma, vel_sigma, pos_sigma, fm.bias_sigma, al.p),
        aids=tuple(specs),
        correction=f.filter.correction,
        bias_compensation=f.filter.bias_compensation and f.filter.correction == "feedback",
    )
    # every method of the file is checked, the chosen ones' models loaded; errors name the
    # file's methods[i], whatever --methods chose.  A method that adapts the noise of an
    # aid --aids left out is checked only if chosen, and then refused naming --aids.
    system = rec.system()
    left_out = {a.name or a.type for a in parsed.file.aids} - set(rec.sensor_names)
    checked = []
    for i, m in enumerate(f.methods):
        gone = [s for s in getattr(m.noise, "sensors", ()) if s in left_out]
        if gone and m in chosen:
            raise ScenarioError(
                "--aids",
                f"method {m.name!r} adapts the noise of {gone[0]!r}, which the aids chosen "
                f"leave out (methods[{i}].noise.sensors): keep the aid or choose other "
                "methods",
            )
        if not gone:
            checked.append(i)
    resolve_methods([f.methods[i] for i in checked], system, base, origin, False, checked)
    at = [i for i, m in enumerate(f.methods) if m in chosen]
    rec = replace(rec, learned=resolve_methods(chosen, system, base, origin, indices=at))
    truth = None
    if f.reference.source == "truth":
        truth = _truth(f.reference, base, origin, raw_log, al, (dt, steps), nav)
        ref_index, ref_p = truth.index, truth.p
    else:
        for key in ("file", "format", *_TRUTH_CSV_KEYS):
            if key in f.reference.model_fields_set:
                raise ScenarioError(
                    f"reference.{key}", "a setting of source 'truth', not 'gnss'", origin
                )
        _some_quality(gnss_all, f.reference.quality, "reference.quality", origin)
        ref = _select(gnss_all, np.isin(gnss_all.quality, f.reference.quality))
        place = on_grid(ref.t, al.t, dt, steps)
        ref_index, ref_p = place.index, ref.p[place.kept]
    stream = recording_stream(log, al, dt, steps, spe, streams)
    runs = (
        [[(s - al.t, e - al.t) for s, e in g] for g in interleave(sched, outage[1])]
        if (outage is not None)
        else [[]]
    )
    if outage is not None:
        receivers = [i for i, a in enumerate(f.aids) if a.type == "gnss"]
        stream = with_outages(stream, receivers, rec.times, runs)
    counts["imu"] = {
        "rows": cleaning.rows,
        "partial_lines_dropped": partial,
        "repeated_rows_dropped": cleaning.repeated_rows,
        "repeated_stamps_dropped": cleaning.repeated_stamps,
        "max_gap_s": cleaning.max_gap_s,
        "samples_per_epoch": spe,
    }
    counts["model_notes"] = list(fm.notes)
    gap_note = _imu_gaps(raw_log, dt, origin, f.imu.file)
    if noise_note is not None:
        counts["imu"]["static_noise"] = noise_note
    outages_rel = tuple(tuple(g) for g in runs)
    notes = tuple(imu_notes) + tuple(aid_notes) + (() if gap_note is None else (gap_note,))
    notes += () if noise_warning is None else (noise_warning,)
    if warn:  # once everything is valid: a refusal comes alone
        for note in notes:
            warnings.warn(note, ScenarioWarning, stacklevel=2)
    arm = np.zeros(3) if truth is not None else np.array(specs[first].sensor.lever_arm_m, float)
    return LoadedRecording(
        rec, stream, ref_index, ref_p, al, counts, outages_rel, truth, notes, arm
    )


#: an IMU gap longer than this many filter epochs (and than 0.1 s) is said: the
#: strapdown holds the sample after a gap over all of it
GAP_EPOCHS = 2.0


def _imu_gaps(log: ImuLog, dt: float, origin: str, file: str) -> str | None:
    """A warning for the gaps of the IMU log longer than :data:`GAP_EPOCHS` epochs."""
    d = np.diff(log.t)
    limit = max(GAP_EPOCHS * dt, 0.1)
    big = np.flatnonzero(d > limit)
    if big.size == 0:
        return None
    worst = int(big[np.argmax(d[big])])
    return (
        f"{origin}: imu.file: {big.size} gap(s) of more than {limit:.3g} s in {file} "
        f"({d[big].sum():.1f} s in all; the longest {d[worst]:.1f} s from "
        f"{log.t[worst]:.3f} s): the strapdown holds the sample after a gap over all of "
        "it, so the solution drifts there"
    )


def _truth(
    r: ReferenceFile,
    base: Path,
    origin: str,
    log: ImuLog,
    al: Alignment,
    grid: tuple[float, int],
    nav: NavegoImu | None,
) -> Truth:
    """The truth file at the filter epochs, and the IMU biases it reveals in ``log`` (the
    log before the alignment removed anything; :mod:`ftnav.recorded.truth`)."""
    if "quality" in r.model_fields_set:
        raise ScenarioError("reference.quality", "a setting of source 'gnss', not 'truth'", origin)
    if r.file is None:
        raise ScenarioError("reference.file", "missing required key (source 'truth')", origin)
    path = _data_path(r.file, base, "reference.file", origin)
    if r.format == "csv":
        tr = _truth_csv(r, path, origin)
    else:
        for key in _TRUTH_CSV_KEYS:
            if key in r.model_fields_set:
                raise ScenarioError(
                    f"reference.{key}", "a setting of format 'csv', not 'navego-mat'", origin
                )
        tr = read_navego_truth(path, "reference.file")
    dt, steps = grid
    k = np.rint((tr.t - al.t) / dt).astype(np.int64)
    on = (np.abs(tr.t - (al.t + k * dt)) <= 1e-6) & (k >= 1) & (k <= steps)
    first = np.unique(k[on], return_index=True)[1]  # one truth sample per epoch
    on[np.flatnonzero(on)[np.setdiff1d(np.arange(on.sum()), first)]] = False
    if not on.any():
        raise ScenarioError(
            "reference.file", f"{path}: no truth sample at the filter epochs (every {dt:g} s)"
        )
    try:
        gb, ab = imu_bias_against_truth(log, tr.t, tr.p, tr.v, tr.C)
    except ValueError as exc:
        raise ScenarioError("reference.file", f"{path}: {exc}", origin) from None
    return Truth(
        index=k[on] - 1,
        p=tr.p[on],
        v=tr.v[on],
        C=tr.C[on],
        gyro_bias=gb,
        accel_bias=ab,
        gyro_bias_nominal=None if nav is None else nav.gyro_bias_nominal,
        accel_bias_nominal=None if nav is None else nav.accel_bias_nominal,
        removed_gyro_bias=np.asarray(al.gyro_bias, float),
    )


def _truth_csv(r: ReferenceFile, path: Path, origin: str) -> NavegoTruth:
    """A truth as a delimited text file with a column map: what :func:`read_navego_truth`
    gives for NaveGo's ``ref.mat`` (the attitude :class:`AttitudeColumns`)."""
    for key in _TRUTH_CSV_KEYS[2:]:
        if getattr(r, key) is None:
            raise ScenarioError(f"reference.{key}", "missing required key (format 'csv')", origin)
    table = read_csv(path, r.header, r.delimiter, "reference.file")
    if table.values.shape[0] < 2:
        raise ScenarioError(str(path), f"reference.file: {table.values.shape[0]} sample(s)")

    def columns(key: str, n: int, families: Sequence[str]) -> np.ndarray:
        values, fac = _columns(table, getattr(r, key), n, families, f"reference.{key}", origin)
        return values * fac

    t = columns("time", 1, ("time",))[:, 0]
    p = np.concatenate(
        [
            columns("lat", 1, ("angle",)),
            columns("lon", 1, ("angle",)),
            columns("height", 1, ("length",)),
        ],
        1,
    )
    named = {k: getattr(r, k).columns[0] for k in ("lat", "lon", "height")}
    check_position(
        np.degrees(p[:, 0]),
        np.degrees(p[:, 1]),
        p[:, 2],
        lambda row, k: (f"{path}:{table.lines[row]}", f"column {named[k]}"),
    )
    assert r.velocity is not None
    order, sign = _TO_ENU[r.velocity.frame]
    v = columns("velocity", 3, ("velocity",))[:, order] * sign
    C = dcm_from_roll_pitch_yaw(columns("attitude", 3, ("angle",)))
    return NavegoTruth(t, p, v, C)


def recording_json_schema() -> dict[str, Any]:
    """JSON schema of recording files (``ftnav schema``), with every plug-in aid's settings
    under ``$defs`` as ``aid-<type>``."""
    schema = RecordingFile.model_json_schema()
    defs = schema.setdefault("$defs", {})
    for kind, plugin in RECORDING_AIDS.items():
        sub = plugin.settings.model_json_schema()
        defs.update(sub.pop("$defs", {}))
        sub["description"] = (sub.get("description") or "").strip()
        defs[f"aid-{kind}"] = sub
    return schema
