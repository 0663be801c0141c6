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
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ftnav.io.common import ScenarioError, read_toml, to_scenario_error
from ftnav.io.ins_scenario_file import (
    ImuSpec,
    filter_model,
    imu_errors,
    sensor_from_table,
)
from ftnav.io.recording_readers import read_csv, read_rtklib_pos
from ftnav.io.sections import MethodConfig, explain_method_key, resolve_methods
from ftnav.model.scenario import AidSpec, Evaluation, Fault, Recording
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.units import parse_quantity
from ftnav.recorded.imu import ImuCleaning, ImuLog, TimeGoesBack, clean, stationary
from ftnav.recorded.stream import (
    Alignment,
    GnssLog,
    align,
    gnss_raw,
    interleave,
    on_grid,
    outage_schedule,
    recording_stream,
    with_outages,
)
from ftnav.sensors.vehicle import Nhc, Zupt

__all__ = [
    "LoadedRecording",
    "RecordingFile",
    "load_recording",
    "recording_aids",
    "recording_json_schema",
]

STRICT = ConfigDict(extra="forbid", strict=True)
_DEG = math.pi / 180.0
_AXES = ("+x", "-x", "+y", "-y", "+z", "-z")


class ColumnsFile(BaseModel):
    """Columns of one quantity and their unit."""

    model_config = STRICT
    columns: list[str | int] = Field(min_length=1, max_length=3)
    unit: str


class ImuFile(BaseModel):
    """``[imu]``: the IMU log and its layout, its mounting, its errors (datasheet)."""

    model_config = STRICT
    file: str
    format: Literal["csv"] = "csv"
    header: bool = True
    delimiter: str = ","
    time: ColumnsFile
    gyro: ColumnsFile
    accel: ColumnsFile
    time_offset_s: float = Field(default=0.0, allow_inf_nan=False)
    axes: list[Literal[_AXES]] = Field(  # type: ignore[valid-type]
        default=["+x", "+y", "+z"],
        min_length=3,
        max_length=3,
        description="the sensor axis along body x (right), y (forward) and z (up)",
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


class AidTable(BaseModel):
    """``[[aids]]``: ``type``, and for ``gnss`` its file; the sensor's parameters."""

    model_config = ConfigDict(extra="allow", strict=True)
    type: Literal["gnss", "nhc", "zupt"]
    name: str | None = None
    file: str | None = None
    format: Literal["rtklib-pos"] = "rtklib-pos"
    quality: list[int] = Field(default=[1], min_length=1)
    time_offset_s: float = Field(default=0.0, allow_inf_nan=False)
    window_s: float = Field(default=0.5, gt=0, description="zupt: stationarity window")
    accel_std_mps2: float = Field(default=0.25, gt=0, description="zupt: accel std threshold")
    gyro_std_dps: float = Field(default=0.25, gt=0, description="zupt: gyro std threshold")


class ReferenceFile(BaseModel):
    """``[reference]``: positions to score against (the GNSS file's best epochs)."""

    model_config = STRICT
    source: Literal["gnss"] = "gnss"
    quality: list[int] = Field(default=[1], min_length=1)


class AlignmentFile(BaseModel):
    """``[alignment]``: static levelling and the GNSS-course heading (``ftnav.recorded``)."""

    model_config = STRICT
    static_s: float = Field(default=30.0, gt=0)
    min_speed_mps: float = Field(default=1.0, gt=0)
    attitude_sigma_deg: list[float] = Field(default=[1.0, 1.0, 10.0], min_length=3, max_length=3)
    velocity_sigma_mps: float = Field(default=0.1, gt=0)
    position_sigma_m: float = Field(default=0.1, gt=0)


class RecordingFilterFile(BaseModel):
    model_config = STRICT
    states: Literal[15, 18] = 15
    correction: Literal["feedback", "output"] = "feedback"
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
    methods: list[MethodConfig] = Field(min_length=1)


class LoadedRecording(NamedTuple):
    """Everything ``ftnav process`` runs and scores.

    Attributes
    ----------
    recording : the engine's description.  stream : the engine's input (one run).
    reference_index, reference_p : epochs (0-based) and positions of the reference.
    alignment : the initial solution.  counts : what the readers handled (for output).
    outages : per run of the batch, the primary GNSS's outages, s relative to
        ``recording.t_start`` (interleaved schedules, :func:`ftnav.recorded.stream.interleave`).
    """

    recording: Recording
    stream: Any
    reference_index: np.ndarray
    reference_p: np.ndarray
    alignment: Alignment
    counts: dict[str, Any]
    outages: tuple[tuple[tuple[float, float], ...], ...]


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
    return table.columns.index(ref)


def _axes_matrix(axes: Sequence[str]) -> np.ndarray:
    """(3, 3) ``M`` with ``body = M · sensor``."""
    M = np.zeros((3, 3))
    for row, a in enumerate(axes):
        M[row, "xyz".index(a[1])] = 1.0 if a[0] == "+" else -1.0
    return M


def _read_imu(f: ImuFile, base: Path, origin: str) -> tuple[ImuLog, ImuCleaning, int]:
    path = base / f.file
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
    t = table.values[:, tc] * t_fac + f.time_offset_s
    M = _axes_matrix(f.axes)
    if np.linalg.det(M) < 0.5:
        raise ScenarioError("imu.axes", f"{f.axes} is not a right-handed axis set", origin)
    if not np.all(np.abs(f.misalignment_deg) <= 90.0):
        raise ScenarioError(
            "imu.misalignment_deg", f"{f.misalignment_deg}: each angle within ±90 deg", origin
        )
    M = euler_to_dcm(np.radians(f.misalignment_deg)) @ M
    gyro = table.values[:, gc] * g_fac @ M.T
    accel = table.values[:, ac] * a_fac @ M.T
    if g_fam == "angle" or a_fam == "velocity":  # increments: rates over each interval
        dt = np.diff(t, prepend=t[0] - np.median(np.diff(t)))
        dt = np.where(dt > 0, dt, np.nan)
        gyro = gyro / dt[:, None] if g_fam == "angle" else gyro
        accel = accel / dt[:, None] if a_fam == "velocity" else accel
    try:
        log, info = clean(ImuLog(t, gyro, accel))
    except TimeGoesBack as exc:
        raise ScenarioError(
            f"{path}:{table.lines[exc.row]}", f"column time: {exc.reason}", origin
        ) from None
    return log, info, table.dropped_partial


def _read_gnss(a: AidTable, base: Path, field: str, origin: str) -> GnssLog:
    """Every epoch of the aid's RTKLIB solution (selection by quality comes later)."""
    if a.file is None:
        raise ScenarioError(f"{field}.file", "missing required key (the GNSS solution file)")
    pos = read_rtklib_pos(base / a.file, f"{field}.file")
    p = np.stack([pos.lat_deg * _DEG, pos.lon_deg * _DEG, pos.height_m], -1)
    return GnssLog(pos.t + a.time_offset_s, p, pos.v_neu[:, [1, 0, 2]], pos.quality)


def _select(log: GnssLog, keep: np.ndarray) -> GnssLog:
    return GnssLog(log.t[keep], log.p[keep], log.v[keep], log.quality[keep])


_GNSS_DEFAULTS: dict[str, Any] = {  # a receiver's solution: its errors are white to the filter
    "markov": "white",
    "pos_markov_sigma_m": 0.0,
    "vel_markov_sigma_m_s": 0.0,
    "pos_white_sigma_m": 0.05,
    "vel_white_sigma_m_s": 0.1,
}
_NOT_SENSOR = ("type", "name", "file", "format", "quality", "time_offset_s")
_ZUPT_ONLY = ("window_s", "accel_std_mps2", "gyro_std_dps")


def _grid(
    gnss: GnssLog, imu: ImuLog, start: float, f: RecordingFile
) -> tuple[float, int, int, int]:
    """Filter period (the GNSS period split into ``sub`` epochs to reach ``rate_hz``),
    epochs, IMU increments per epoch (even, for the two-sample algorithm), ``sub``."""
    period = float(np.round(np.median(np.diff(np.sort(gnss.t))), 3))
    sub = max(1, math.ceil(period * f.filter.rate_hz - 1e-9))
    dt = period / sub
    t_end = min(float(imu.t[-1]), float(gnss.t.max()))
    if f.filter.duration_s is not None:
        t_end = min(t_end, start + f.filter.duration_s)
    steps = int(math.floor((t_end - start) / dt + 1e-9))
    if steps < 2:
        raise ScenarioError("filter.duration_s", f"{steps} filter epoch(s) after the alignment")
    rate = f.filter.imu_rate_hz or 1.0 / float(np.median(np.diff(imu.t)))
    spe = int(math.ceil(dt * rate - 1e-6))
    return dt, steps, spe + (spe % 2), sub


def _initial_sigma(a: AlignmentFile, bias_sigma: np.ndarray, p: np.ndarray) -> np.ndarray:
    R = 6378137.0 + p[2]
    nav = np.r_[
        np.asarray(a.attitude_sigma_deg) * _DEG,
        [a.velocity_sigma_mps] * 3,
        [a.position_sigma_m / R, a.position_sigma_m / (R * math.cos(p[0]))],
        [a.position_sigma_m],
    ]
    return np.maximum(np.r_[nav, bias_sigma], 1e-12)


def _outage_mask(t: np.ndarray, outages: Sequence[tuple[float, float]]) -> np.ndarray:
    m = np.zeros(t.shape, bool)
    for s, e in outages:
        m |= (t >= s) & (t < e)
    return m


def _aids(
    f: RecordingFile,
    base: Path,
    origin: str,
    primary: tuple[int, GnssLog],
    log: ImuLog,
    grid: tuple[float, float, int, int],
    faults: Sequence[Fault],
    outages: Sequence[tuple[float, float]] = (),
) -> tuple[list[AidSpec], list[tuple[np.ndarray, np.ndarray, np.ndarray]], dict[str, Any]]:
    """Every aid's sensor model and its epochs on the filter grid (absolute outages)."""
    t0, dt, steps, sub = grid
    times = t0 + dt * np.arange(1, steps + 1)
    specs, streams, counts = [], [], {}
    for i, a in enumerate(f.aids):
        name, field = a.name or a.type, f"aids[{i}]"
        params = {k: v for k, v in (a.model_extra or {}).items() if k not in _NOT_SENSOR}
        if a.type == "gnss":
            g = primary[1] if i == primary[0] else _read_gnss(a, base, field, origin)
            sel = _select(g, np.isin(g.quality, a.quality))
            sensor = sensor_from_table(
                "gnss", {**_GNSS_DEFAULTS, **params, "name": name}, field, origin, dt=dt
            )
            raw, labels = gnss_raw(sel, faults, name)
            raw[_outage_mask(sel.t, outages)] = np.nan
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
            extra = [k for k in _ZUPT_ONLY if k in (a.model_fields_set or ())]
            if a.type == "nhc" and extra:
                raise ScenarioError(f"{field}.{extra[0]}", "a setting of zupt, not of nhc", origin)
            cls = Nhc if a.type == "nhc" else Zupt
            try:
                sensor = cls(name=name, dt=dt, **params)
            except (TypeError, ValueError) as exc:
                raise ScenarioError(field, " ".join(str(exc).split()), origin) from None
            # at the primary GNSS's epochs: a constraint's error is correlated over its
            # period, applying it more often would overweight it
            index = np.arange(sub - 1, steps, sub)
            if a.type == "zupt":
                rest = stationary(
                    log, times[index], a.window_s, a.accel_std_mps2, a.gyro_std_dps * _DEG
                )
                index = index[rest]
                counts[name] = {"stationary_epochs": int(index.size)}
            streams.append((index, np.zeros((index.size, sensor.dim)), np.zeros(index.size, bool)))
        specs.append(AidSpec(sensor))
    return specs, streams, counts


def _validated(source: str | Path) -> RecordingFile:
    try:
        return RecordingFile.model_validate(read_toml(source))
    except ValidationError as exc:
        raise to_scenario_error(exc, str(source), RecordingFile, explain_method_key) from None


def recording_aids(source: str | Path) -> dict[str, str]:
    """The aids a recording file names, ``{name: type}`` (its data files are not read)."""
    return {a.name or a.type: a.type for a in _validated(source).aids}


def _keep_aids(f: RecordingFile, aids: Sequence[str] | None) -> RecordingFile:
    if aids is None:
        return f
    known = [a.name or a.type for a in f.aids]
    for nm in aids:
        if nm not in known:
            raise ScenarioError("--aids", f"no aid {nm!r} (known: {', '.join(known)})")
    return f.model_copy(update={"aids": [a for a in f.aids if (a.name or a.type) in aids]})


def load_recording(
    source: str | Path,
    *,
    outage: tuple[float, float, float] | None = None,
    faults: Sequence[Fault] = (),
    methods: Sequence[str] | None = None,
    aids: Sequence[str] | None = None,
) -> LoadedRecording:
    """Read and validate a recording file and its data files; build what the engine runs.

    Parameters
    ----------
    outage : ``(length, every, start)`` s of a GNSS outage schedule after the first
        GNSS epoch, clipped to leave 30 s at the end
        (:func:`ftnav.recorded.stream.outage_schedule`); None: GNSS on.
    faults : injected into the recorded aids, ``start``/``end`` on the recording's
        time base.
    methods : the names of the methods to run (default: every method of the file).
    aids : the names of the aids to use (default: every aid of the file).
    """
    origin, base = str(source), Path(source).parent
    f = _keep_aids(_validated(source), aids)
    imu_err = imu_errors(f.imu.errors, "imu.errors", origin)
    log, cleaning, partial = _read_imu(f.imu, base, origin)
    first = next((i for i, a in enumerate(f.aids) if a.type == "gnss"), None)
    if first is None:
        raise ScenarioError("aids", "a recording needs a gnss aid (its epochs are the filter's)")
    gnss_all = _read_gnss(f.aids[first], base, f"aids[{first}]", origin)
    gnss = _select(gnss_all, np.isin(gnss_all.quality, f.aids[first].quality))
    try:
        al = align(log, gnss, f.alignment.static_s, f.alignment.min_speed_mps)
    except ValueError as exc:
        path, _, reason = str(exc).partition(": ")
        raise ScenarioError(path, reason, origin) from None
    log = log._replace(gyro=log.gyro - al.gyro_bias)
    dt, steps, spe, sub = _grid(gnss_all, log, al.t, f)
    t_origin = float(gnss_all.t.min())
    sched: list[tuple[float, float]] = []
    if outage is not None:
        last = float(gnss_all.t.max()) - t_origin
        sched = [(s + t_origin, e + t_origin) for s, e in outage_schedule(*outage, last=last)]
    chosen = list(f.methods)
    if methods is not None:
        known = [m.name for m in chosen]
        for nm in methods:
            if nm not in known:
                raise ScenarioError("--methods", f"no method {nm!r} (known: {', '.join(known)})")
        chosen = [m for m in chosen if m.name in methods]
    specs, streams, counts = _aids(
        f, base, origin, (first, gnss_all), log, (al.t, dt, steps, sub), faults
    )
    fm = filter_model(imu_err, f.filter.states)
    rel = tuple(Fault(x.sensor, x.kind, x.start - al.t, x.end - al.t, x.magnitude) for x in faults)
    rec = Recording(
        name=f.name,
        description=f.description,
        dt=dt,
        steps=steps,
        faults=rel,
        methods=tuple(chosen),
        evaluation=Evaluation(),
        t_start=al.t,
        t_origin=t_origin,
        samples_per_epoch=spe,
        error_model=fm.params,
        initial_sigma=_initial_sigma(f.alignment, fm.bias_sigma, al.p),
        aids=tuple(specs),
        correction=f.filter.correction,
    )
    rec = replace(rec, learned=resolve_methods(rec.methods, rec.system(), base, origin))
    ref = _select(gnss_all, np.isin(gnss_all.quality, f.reference.quality))
    place = on_grid(ref.t, al.t, dt, steps)
    stream = recording_stream(log, al, dt, steps, spe, streams)
    runs = (
        [[(s - al.t, e - al.t) for s, e in g] for g in interleave(sched, outage[1])]
        if (outage is not None)
        else [[]]
    )
    if outage is not None:
        stream = with_outages(stream, first, rec.times, runs)
    counts["imu"] = {
        "rows": cleaning.rows,
        "partial_lines_dropped": partial,
        "repeated_rows_dropped": cleaning.repeated_rows,
        "repeated_stamps_dropped": cleaning.repeated_stamps,
        "max_gap_s": cleaning.max_gap_s,
        "samples_per_epoch": spe,
    }
    counts["model_notes"] = list(fm.notes)
    outages_rel = tuple(tuple(g) for g in runs)
    return LoadedRecording(rec, stream, place.index, ref.p[place.kept], al, counts, outages_rel)


def recording_json_schema() -> dict[str, Any]:
    """JSON schema of recording files (``ftnav schema``)."""
    return RecordingFile.model_json_schema()
