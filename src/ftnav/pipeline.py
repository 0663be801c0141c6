"""A user's own log in one call: parse → prepare → run → score (issue 22).

:func:`process_recording` is the Python route to what ``ftnav process`` does::

    import ftnav

    result = ftnav.process_recording("rtklib-drive", methods=["ckf"])
    df = result.to_dataframe()          # one row per method and filter epoch

The steps, each in its own layer (``docs/architecture.md``):

1. **parse** (:mod:`ftnav.io.recording_file`): the recording file and its logs, checked
   once at the boundary;
2. **prepare** (:mod:`ftnav.recorded`, called by the loader): alignment, the epoch grid,
   the aids on it, outages and faults, the reference;
3. **run** (:func:`ftnav.engine.driver.run`): every method over the stream, all outage
   schedules as one batch;
4. **score** (:func:`ftnav.eval.recorded.score_recording`): against the reference, at the
   point it measures (the GNSS antenna: the lever arm applied), the posterior and the
   prediction, outages, detection, integrity;
5. optionally **smooth** (:func:`ftnav.engine.smoother.smooth`): the forward–backward
   (RTS) solution with its σ.

:func:`prepare_recording` and :meth:`Prepared.run` split the call where the command
line claims its output folder (between the checks and the computing).  Errors of the
arguments raise :class:`ProcessingError` (a ``ValueError`` naming the argument); errors
of the file raise :class:`ftnav.io.common.ScenarioError` naming the file and field.
"""

from __future__ import annotations

import math
import os
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NamedTuple, cast

import numpy as np

from ftnav.engine import navigation_model
from ftnav.engine.driver import Trace, run
from ftnav.engine.smoother import smooth, smoothed_trace
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import RecordedScores, Reference, reference_errors, score_recording
from ftnav.io.common import MAX_NOISE_FACTOR, ScenarioError
from ftnav.io.ins_scenario_file import ScenarioWarning
from ftnav.io.recording_file import (
    LoadedRecording,
    load_recording,
    parse_recording,
    recording_aids,
)
from ftnav.io.solution_file import SOLUTION_COLUMNS, solution_table, trace_dataset
from ftnav.model.imu import RANGES
from ftnav.model.scenario import SINS, Fault, FaultKind, Recording
from ftnav.model.streams import scheduled
from ftnav.recorded.stream import RECORDING_FAULT_KINDS
from ftnav.recordings import recording_names, recording_path
from ftnav.scenarios import builtin_names

__all__ = [
    "MAX_FAULT_M",
    "MAX_FAULT_M_S",
    "RECORDING_FAULTS",
    "Outages",
    "Prepared",
    "ProcessingError",
    "RecordingResult",
    "parse_fault",
    "prepare_recording",
    "process_recording",
    "reference_of",
    "resolve_recording",
]

#: fault kinds a recorded GNSS aid can be given
RECORDING_FAULTS = RECORDING_FAULT_KINDS
#: largest fault magnitude (m): a position offset of a GNSS fix beyond it is not a fault
#: of a receiver on Earth, and squared it overflows the filter's arithmetic
MAX_FAULT_M = 1e5
#: largest velocity fault (m/s) of an aid that measures velocity only: beyond it the
#: velocity is no receiver's on a vehicle a recording holds
MAX_FAULT_M_S = 1e3


class ProcessingError(ValueError):
    """An argument of :func:`process_recording` that cannot be processed; the message
    starts with the argument's name (the command line's option name from the CLI)."""


class Outages(NamedTuple):
    """GNSS outages of ``length`` s every ``every`` s from ``start`` s after the first GNSS
    epoch (a schedule longer than its spacing allows is run as interleaved runs)."""

    length: float
    every: float = 60.0
    start: float = 40.0


def resolve_recording(spec: str | Path) -> Path:
    """A built-in recording's name, or the path of a recording file."""
    if not isinstance(spec, str | os.PathLike):
        raise ProcessingError(
            "recording: expected a built-in recording's name, a recording file's path or a "
            f"LoadedRecording, got {spec!r}"
        )
    if isinstance(spec, str) and not spec.strip():  # Path("") is the current folder
        raise ProcessingError("recording: an empty name; give a built-in recording or a file")
    if isinstance(spec, str) and spec in recording_names():
        return recording_path(spec)
    path = Path(spec)
    if path.suffix == ".toml" or path.exists():
        return path
    simulated = (
        " (it is a built-in simulated scenario: run it with 'ftnav run')"
        if str(spec) in builtin_names()
        else ""
    )
    raise ProcessingError(
        f"recording: {str(spec)!r} is neither a built-in recording "
        f"({', '.join(recording_names())}) nor a recording file{simulated}"
    )


def parse_fault(text: str, aids: Mapping[str, str], field: str = "faults") -> Fault:
    """``SENSOR:KIND:START:END[:MAGNITUDE]`` as a fault of a recorded GNSS aid: START and
    END on the recording's time base (s), a bias or ramp MAGNITUDE in metres on the north
    position (m/s on the north velocity for an aid that measures velocity only: a ramp
    reaches it at END), a ``noise-scale`` MAGNITUDE the factor ≥ 1 on the noise σ of every row the
    aid measures (white noise added to the recording:
    :func:`ftnav.recorded.stream.gnss_raw`).  Or ``sins:gyro-bias:START:END:X,Y,Z``: a
    step of the recorded gyros' bias, deg/h about the body axes (x right, y forward, z
    up), as a scenario file's ``magnitude_deg_h``
    (:func:`ftnav.recorded.stream.imu_with_faults`).  ``aids`` maps the recording's aid
    names to their types (:func:`ftnav.io.recording_file.recording_aids`); errors name
    ``field``."""
    parts = text.split(":")
    if len(parts) not in (4, 5):
        raise ProcessingError(f"{field}: expected SENSOR:KIND:START:END[:MAGNITUDE], got {text!r}")
    sensor, kind = parts[0], parts[1]
    if sensor == SINS or kind == "gyro-bias":
        return _sins_fault(text, parts, field)
    if aids.get(sensor) not in ("gnss", "gnss-velocity"):
        gnss = [n for n, t in aids.items() if t.startswith("gnss")]
        raise ProcessingError(f"{field}: {sensor!r} is not a GNSS aid of the recording ({gnss})")
    if kind not in RECORDING_FAULTS:
        raise ProcessingError(f"{field}: kind {kind!r} (recordings: {', '.join(RECORDING_FAULTS)})")
    try:
        start, end = float(parts[2]), float(parts[3])
        mag = float(parts[4]) if len(parts) == 5 else 0.0
    except ValueError:
        raise ProcessingError(
            f"{field}: START, END and MAGNITUDE must be numbers ({text!r})"
        ) from None
    if not math.isfinite(mag):
        raise ProcessingError(f"{field}: MAGNITUDE must be finite ({text!r})")
    if not (math.isfinite(start) and math.isfinite(end)) or end <= start:
        raise ProcessingError(f"{field}: END must be after START, both finite ({text!r})")
    if kind in ("stuck", "outage") and len(parts) == 5:
        raise ProcessingError(f"{field}: a {kind} takes no MAGNITUDE ({text!r})")
    velocity = aids[sensor] == "gnss-velocity"
    unit = "m/s" if velocity else "m"
    if kind in ("bias", "ramp") and len(parts) != 5:
        raise ProcessingError(
            f"{field}: a {kind} needs a MAGNITUDE in {'m/s' if velocity else 'metres'} ({text!r})"
        )
    if kind == "noise-scale":
        if len(parts) != 5 or not 1.0 <= mag <= MAX_NOISE_FACTOR:
            raise ProcessingError(
                f"{field}: a noise-scale needs a MAGNITUDE, the factor on the noise σ, in "
                f"[1, {MAX_NOISE_FACTOR:g}] (a recording's noise can only grow) ({text!r})"
            )
        return Fault(sensor, "noise-scale", start, end, np.full(6, mag))
    bound = MAX_FAULT_M_S if velocity else MAX_FAULT_M
    if abs(mag) > bound:
        where = "faster than any vehicle" if velocity else "off the Earth"
        raise ProcessingError(
            f"{field}: MAGNITUDE {mag:g} {unit} is beyond ±{bound:g} {unit}, {where} ({text!r})"
        )
    checked = cast("FaultKind", kind)  # one of RECORDING_FAULTS (above)
    magnitude = np.zeros(6)
    magnitude[4 if velocity else 1] = mag  # E, N, U m, then m/s: the north row
    return Fault(sensor, checked, start, end, magnitude)


def check_fault(f: Fault, aids: Mapping[str, str], field: str = "faults") -> Fault:
    """A :class:`Fault` given as an object held to what :func:`parse_fault` accepts from
    text: its window, its kind for its sensor, its magnitude's shape (a GNSS aid's six
    rows E, N, U m then E, N, U m/s, or one number for all; the SINS's three body axes
    in rad/s) and bounds.  The fault as the recording takes it (magnitude as floats)."""
    where = f"{field}: Fault({f.sensor!r}, {f.kind!r}, ...)"
    sins = (f.sensor, f.kind) == (SINS, "gyro-bias")
    aid = f.sensor in aids and f.kind in RECORDING_FAULTS and f.kind != "gyro-bias"
    if not (sins or aid):
        return f  # no aid of the recording, or a kind it has not: refused once loaded
    try:
        start, end = float(f.start), float(f.end)
        mag = np.array(f.magnitude, dtype=float)
    except (TypeError, ValueError):
        raise ProcessingError(f"{where}: start, end and magnitude must be numbers") from None
    if not (math.isfinite(start) and math.isfinite(end)) or end <= start:
        raise ProcessingError(f"{where}: end must be after start, both finite")
    if not np.isfinite(mag).all():
        raise ProcessingError(f"{where}: the magnitude must be finite")
    if sins:
        if mag.shape != (3,):
            raise ProcessingError(
                f"{where}: a gyro-bias is three rates (rad/s about the body x, y, z), got "
                f"shape {mag.shape}"
            )
        limit = RANGES["angular_rate"]
        if np.abs(mag).max() > limit.high:
            raise ProcessingError(f"{where}: a gyro-bias beyond a gyro's range ({limit.text})")
        return Fault(SINS, "gyro-bias", start, end, mag)
    if aids.get(f.sensor) not in ("gnss", "gnss-velocity"):
        gnss = [n for n, t in aids.items() if t.startswith("gnss")]
        raise ProcessingError(f"{where}: {f.sensor!r} is not a GNSS aid of the recording ({gnss})")
    if mag.shape not in ((), (6,)):
        raise ProcessingError(
            f"{where}: a magnitude of shape {mag.shape}; a GNSS aid's is one number or six "
            "(E, N, U m, then E, N, U m/s)"
        )
    mag = np.broadcast_to(mag, (6,)).copy()
    if f.kind in ("stuck", "outage") and mag.any():
        raise ProcessingError(f"{where}: a {f.kind} takes no magnitude (give zeros)")
    if f.kind == "noise-scale" and not ((mag >= 1.0) & (mag <= MAX_NOISE_FACTOR)).all():
        raise ProcessingError(
            f"{where}: a noise-scale's factors must be in [1, {MAX_NOISE_FACTOR:g}] (a "
            "recording's noise can only grow)"
        )
    if f.kind in ("bias", "ramp") and (
        np.abs(mag[:3]).max() > MAX_FAULT_M or np.abs(mag[3:]).max() > MAX_FAULT_M_S
    ):
        raise ProcessingError(
            f"{where}: a magnitude beyond ±{MAX_FAULT_M:g} m or ±{MAX_FAULT_M_S:g} m/s (off the "
            "Earth, or faster than any vehicle)"
        )
    return Fault(f.sensor, f.kind, start, end, mag)


def _sins_fault(text: str, parts: list[str], field: str) -> Fault:
    """``sins:gyro-bias:START:END:X,Y,Z`` (deg/h) as a :class:`Fault` (rad/s)."""
    if parts[0] != SINS or parts[1] != "gyro-bias":
        raise ProcessingError(
            f"{field}: 'gyro-bias' is the only fault of the SINS and applies only to it: "
            f"sins:gyro-bias:START:END:X,Y,Z (deg/h) ({text!r})"
        )
    try:
        start, end = float(parts[2]), float(parts[3])
        rate = [float(x) for x in parts[4].split(",")] if len(parts) == 5 else []
    except ValueError:
        raise ProcessingError(f"{field}: START, END and X,Y,Z must be numbers ({text!r})") from None
    if len(rate) != 3:
        raise ProcessingError(
            f"{field}: a gyro-bias needs X,Y,Z, the step in deg/h about the body axes "
            f"(x right, y forward, z up) ({text!r})"
        )
    if not all(math.isfinite(x) for x in rate):
        raise ProcessingError(f"{field}: X,Y,Z must be finite ({text!r})")
    if not (math.isfinite(start) and math.isfinite(end)) or end <= start:
        raise ProcessingError(f"{field}: END must be after START, both finite ({text!r})")
    limit = RANGES["angular_rate"]
    mag = np.asarray(rate) / limit.per_si
    if np.abs(mag).max() > limit.high:
        raise ProcessingError(
            f"{field}: gyro-bias {max(abs(x) for x in rate):g} deg/h is beyond a gyro's "
            f"{limit.high * limit.per_si:g} deg/h ({limit.text}) ({text!r})"
        )
    return Fault(SINS, "gyro-bias", start, end, mag)


def _outages(outages: Outages | Sequence[float] | None, field: str) -> Outages | None:
    if outages is None:
        return None
    try:
        if isinstance(outages, str | bytes):  # "15" would be read as (1, 5)
            raise TypeError
        values = [float(x) for x in outages]
        if not 1 <= len(values) <= 3:
            raise ValueError
    except (TypeError, ValueError):
        raise ProcessingError(
            f"{field}: expected (length[, every[, start]]) in seconds, got {outages!r}"
        ) from None
    o = Outages(*values)
    if not all(math.isfinite(x) for x in o) or o.length <= 0 or o.every <= 0:
        raise ProcessingError(f"{field}: length and spacing must be positive seconds, got {o}")
    if o.start < 0:
        raise ProcessingError(
            f"{field}: the first outage starts {o.start:g} s after the first GNSS epoch: "
            "must be >= 0"
        )
    if o.length >= o.every:
        raise ProcessingError(
            f"{field}: {o.length:g} s outages every {o.every:g} s leave no GNSS fix: the "
            "length must be shorter than the spacing"
        )
    return o


def reference_of(loaded: LoadedRecording) -> Reference:
    """A recording's reference at the point it measures (its lever arm from the IMU)."""
    return Reference(loaded.reference_index, loaded.reference_p, loaded.reference_lever_arm)


@dataclass(frozen=True)
class RecordingResult:
    """One processed recording (:func:`process_recording`): the same for a built-in and
    a user's own log.

    Attributes
    ----------
    loaded : the parsed and prepared recording (stream, reference, alignment, counts).
    traces : per method, the engine's :class:`~ftnav.engine.driver.Trace` (a batch of one
        run per interleaved outage schedule).
    scores : per method, :func:`~ftnav.eval.recorded.score_recording`'s typed scores
        (:class:`~ftnav.eval.recorded.RecordedScores`; ``.smoothed`` with ``smooth=True``).
    smoothed : per method, the RTS-smoothed solution (``smooth=True``), else None.
    elapsed_s : wall time of the run (engine and smoother), s.
    warnings : the loader's warnings (suspicious but legal input), one line each.
    """

    loaded: LoadedRecording
    traces: dict[str, Trace]
    scores: dict[str, RecordedScores]
    smoothed: dict[str, Trace] | None
    elapsed_s: float
    warnings: tuple[str, ...]

    @property
    def recording(self) -> Recording:
        """The recording as the engine ran it (methods, aids, epochs)."""
        return self.loaded.recording

    @property
    def name(self) -> str:
        return self.loaded.recording.name

    @property
    def methods(self) -> tuple[str, ...]:
        return tuple(self.traces)

    @property
    def times(self) -> np.ndarray:
        """(K,) the filter epochs' times on the recording's own time base, s."""
        rec = self.loaded.recording
        return np.asarray(rec.t_start + rec.times)

    @property
    def runs(self) -> int:
        """Runs of the batch: one per interleaved outage schedule (1 without outages)."""
        return int(self.loaded.stream.batch)

    def solution(self, method: str, run: int = 0, smoothed: bool = False) -> np.ndarray:
        """(K, 13) rows of :data:`~ftnav.io.solution_file.SOLUTION_COLUMNS` of one method
        and run (``smoothed``: the RTS solution); a diverged solution raises
        :class:`~ftnav.engine.driver.Diverged`."""
        return solution_table(self._trace(method, run, smoothed), self.times, run, method)

    @property
    def reference(self) -> Reference:
        """The reference the scores use: its epochs, and the positions of the point it
        measures (the GNSS antenna, its lever arm from the IMU)."""
        return reference_of(self.loaded)

    def errors(self, method: str, run: int = 0, smoothed: bool = False) -> np.ndarray:
        """(K_r, 3) ENU metres of one method's solution minus the reference at its epochs
        (``times[reference.index]``), at the point the reference measures: what the
        scores are computed from (:func:`~ftnav.eval.recorded.reference_errors`)."""
        solution = self._trace(method, run, smoothed).solution
        assert solution is not None  # a recording's trace is integrated
        return reference_errors(solution, self.reference, run)

    def to_dataframe(self, run: int = 0, smoothed: bool = False) -> Any:
        """A :class:`pandas.DataFrame` of every method's solution, one row per method and
        filter epoch: ``method`` then the columns of ``solution.csv``
        (``docs/recording-format.md``)."""
        import pandas as pd

        frames = []
        for name in self._traces(smoothed):
            df = pd.DataFrame(self.solution(name, run, smoothed), columns=list(SOLUTION_COLUMNS))
            df.insert(0, "method", name)
            frames.append(df)
        return pd.concat(frames, ignore_index=True)

    def scores_frame(self) -> Any:
        """A :class:`pandas.DataFrame` of the scalar scores, one row per method: the
        top-level ones, the outage drift, with ``smooth=True`` the smoothed solution's
        (``smoothed_…``), against a full truth its horizontal RMSE and NEES
        (``truth_…``)."""
        import pandas as pd

        rows = {}
        for name, s in self.scores.items():
            row: dict[str, Any] = dict(s.scalars())
            if s.outages is not None:
                row["outage_rms_max_m"] = s.outages.rms_max_error_m
                row["outages"] = s.outages.count
            if s.smoothed is not None:
                row |= {f"smoothed_{k}": v for k, v in s.smoothed.scalars().items()}
                if s.smoothed.outages is not None:
                    row["smoothed_outage_rms_max_m"] = s.smoothed.outages.rms_max_error_m
            if s.truth is not None:
                row["truth_horizontal_m"] = s.truth.rmse.horizontal_m
                if s.truth.nees is not None:
                    row["truth_nees_mean"] = s.truth.nees.mean
                    row["truth_nees_fraction_inside"] = s.truth.nees.fraction_inside
            rows[name] = row
        return pd.DataFrame.from_dict(rows, orient="index")

    def to_xarray(self) -> Any:
        """The whole trace as an :class:`xarray.Dataset` (what ``trace.nc`` holds)."""
        return trace_dataset(self.loaded, self.traces)

    def _trace(self, method: str, run: int, smoothed: bool) -> Trace:
        """One method's trace, ``method`` and ``run`` refused by name when absent."""
        traces = self._traces(smoothed)
        if method not in traces:
            raise KeyError(f"method {method!r}: processed were {list(traces)}")
        if not 0 <= run < self.runs:
            raise IndexError(f"run {run}: the batch has {self.runs} run(s)")
        return traces[method]

    def _traces(self, smoothed: bool) -> dict[str, Trace]:
        if not smoothed:
            return self.traces
        if self.smoothed is None:
            raise ValueError("smoothed: the recording was processed without smooth=True")
        return self.smoothed


@dataclass(frozen=True)
class Prepared:
    """A recording parsed and prepared, its filters built: what :meth:`run` needs."""

    loaded: LoadedRecording
    filters: dict[str, Any]
    smooth: bool

    @property
    def recording(self) -> Recording:
        return self.loaded.recording

    @property
    def work(self) -> int:
        """Steps the engine reports through ``progress``: epochs × methods × runs."""
        rec = self.loaded.recording
        return int(len(rec.methods) * rec.steps * self.loaded.stream.batch)

    def run(self, progress: Callable[[int], None] | None = None) -> RecordingResult:
        """Run every method (engine), smooth on request, score."""
        loaded = self.loaded
        rec = loaded.recording
        runs = loaded.stream.batch
        t0 = time.perf_counter()
        traces = run(
            navigation_model(rec),
            loaded.stream,
            self.filters,
            rec.steps,
            None if progress is None else (lambda n: progress(n * runs)),
            nav_covariance=loaded.truth is not None,  # NEES against a full truth
            times=rec.t_start + rec.times,
            smoothing=self.smooth,
            prediction=True,
        )
        smoothed = None
        if self.smooth:
            smoothed = {nm: smoothed_trace(tr, smooth(tr)) for nm, tr in traces.items()}
        elapsed = time.perf_counter() - t0
        ref = reference_of(loaded)
        sched = scheduled(loaded.stream, rec.steps)
        scores = score_recording(
            rec, traces, ref, loaded.outages, truth=loaded.truth, scheduled=sched
        )
        if smoothed is not None:
            smooth_scores = score_recording(rec, smoothed, ref, loaded.outages, truth=loaded.truth)
            scores = {nm: replace(s, smoothed=smooth_scores[nm]) for nm, s in scores.items()}
        warnings = (*loaded.warnings, *_thin_scores(scores, len(ref.index)))
        return RecordingResult(loaded, traces, scores, smoothed, elapsed, warnings)


#: a score resting on fewer reference epochs than this (and this fraction of all) is
#: warned about: the outages and fault windows left it next to nothing
THIN_SCORE_EPOCHS, THIN_SCORE_FRACTION = 30, 0.1


def _thin_scores(scores: Mapping[str, RecordedScores], total: int) -> list[str]:
    """A warning per method whose GNSS-on score rests on a handful of reference epochs
    (a fault over the whole drive left one epoch, scored 0.000 m)."""
    out = []
    for name, s in scores.items():
        if s.reference_epochs < max(THIN_SCORE_EPOCHS, THIN_SCORE_FRACTION * total):
            out.append(
                f"methods[{name}]: scored on {s.reference_epochs} of the {total} reference "
                "epochs (the rest inside outages or fault windows): its RMS says little"
            )
    return out


def prepare_recording(
    recording: str | Path | LoadedRecording,
    *,
    methods: Sequence[str] | None = None,
    aids: Sequence[str] | None = None,
    outages: Outages | Sequence[float] | None = None,
    faults: Sequence[Fault | str] = (),
    smooth: bool = False,
    fields: Mapping[str, str] | None = None,
) -> Prepared:
    """Parse and prepare a recording (:func:`process_recording`'s arguments) without
    running it.  ``fields`` renames the arguments in error messages (the CLI's options)."""
    names = {f: f for f in ("faults", "outages", "methods", "aids")} | dict(fields or {})
    # an iterator is read once: as a list here (a generator of names was used up by the
    # check and then ran as an empty list)
    methods, aids = (c if c is None or isinstance(c, str) else list(c) for c in (methods, aids))
    if faults is not None and not isinstance(faults, str | Fault):
        faults = list(faults)
    for field, chosen in (("methods", methods), ("aids", aids)):
        _check_names(chosen, names[field])
    if isinstance(recording, LoadedRecording):
        if methods is not None or aids is not None or outages is not None or faults:
            raise ProcessingError(
                "recording: a loaded recording is processed as it was loaded; give the "
                "methods, aids, outages and faults to load_recording"
            )
        loaded = recording
        types: Mapping[str, str] = {}
    else:
        if isinstance(faults, str) or not all(isinstance(f, str | Fault) for f in faults):
            raise ProcessingError(
                f"{names['faults']}: expected a list of faults (each SENSOR:KIND:START:END"
                f"[:MAGNITUDE] or a Fault), got {faults!r}"
            )
        parsed = parse_recording(resolve_recording(recording))  # read and validated once
        types = recording_aids(parsed)
        fault_list = [
            parse_fault(f, types, names["faults"])
            if isinstance(f, str)
            else check_fault(f, types, names["faults"])
            for f in faults
        ]
        outage = _outages(outages, names["outages"])
        try:
            loaded = load_recording(
                parsed,
                outage=None if outage is None else (outage.length, outage.every, outage.start),
                faults=fault_list,
                methods=methods,  # lists or None (above)
                aids=aids,
                warn=False,
            )
        except ScenarioError as e:  # a choice of methods or aids: the caller's argument
            option = {"--methods": "methods", "--aids": "aids"}.get(e.path)
            if option is None:
                raise
            raise ProcessingError(f"{names[option]}: {e.reason}") from None
    rec = loaded.recording
    for f in rec.faults:
        if f.sensor != SINS and f.sensor not in rec.sensor_names:
            left_out = " (left out by the aids chosen)" if f.sensor in types else ""
            raise ProcessingError(
                f"{names['faults']}: {f.sensor!r} is not an aid processed{left_out}; the aids "
                f"processed are {', '.join(rec.sensor_names)}"
            )
        end = rec.times[-1] + rec.dt  # a window is [START, END): to the end is one past it
        if f.start < 0 or f.end > end + 1e-6:
            raise ProcessingError(
                f"{names['faults']}: [{f.start + rec.t_start:.3f}, {f.end + rec.t_start:.3f}) "
                f"s is not within the processed span [{rec.t_start:.3f}, "
                f"{rec.t_start + end:.3f}) s (the recording's time base): a fault starts and "
                f"ends inside it (to the end: END {rec.t_start + end:.3f}, one epoch past the "
                "last, whose fix a window [START, END) leaves out)"
            )
    if smooth:
        _check_smoothable(rec)
    filters = build_filters(rec, rec.system(), rec.methods)
    return Prepared(loaded, dict(filters), smooth)


def _check_names(chosen: list[str] | str | None, field: str) -> None:
    """A chosen list of methods or aids: None (all), else names, at least one, none twice."""
    if chosen is None:
        return
    if isinstance(chosen, str) or not all(isinstance(n, str) and n for n in chosen):
        raise ProcessingError(f"{field}: expected a list of names, got {chosen!r}")
    if not chosen:
        raise ProcessingError(f"{field}: an empty list chooses nothing (None: all of them)")
    repeated = sorted({n for n in chosen if chosen.count(n) > 1})
    if repeated:
        raise ProcessingError(f"{field}: {', '.join(map(repr, repeated))} given twice")


def _check_smoothable(rec: Recording) -> None:
    for a in rec.aids:
        if getattr(a.sensor, "difference_factor", None) is not None:
            raise ProcessingError(
                f"smooth: aid {a.name!r} is differenced (a Markov error with markov = "
                "'difference'), which the RTS smoother does not cover"
            )


def process_recording(
    recording: str | Path | LoadedRecording,
    *,
    methods: Sequence[str] | None = None,
    aids: Sequence[str] | None = None,
    outages: Outages | Sequence[float] | None = None,
    faults: Sequence[Fault | str] = (),
    smooth: bool = False,
    progress: Callable[[int], None] | None = None,
) -> RecordingResult:
    """Process a recorded log: every method over it, scored against its reference.

    Parameters
    ----------
    recording : a built-in recording's name (``ftnav list``), the path of a recording
        file (``docs/recording-format.md``), or a :class:`LoadedRecording`.
    methods, aids : names of the file's methods and aids to keep (default all).
    outages : GNSS outages ``(length, every, start)`` s (:class:`Outages`), or None.
    faults : faults injected into recorded GNSS aids (or the SINS), as
        :class:`~ftnav.model.scenario.Fault` or ``"SENSOR:KIND:START:END[:MAGNITUDE]"``
        (:func:`parse_fault`), both with START and END on the recording's time base.
    smooth : also run the RTS smoother (:attr:`RecordingResult.smoothed`, scores under
        ``scores[method].smoothed``).
    progress : called with the number of engine steps done (epochs × methods × runs).

    Suspicious but legal input (an IMU gap, a lever arm over 10 m, …) is issued as a
    :class:`~ftnav.io.ins_scenario_file.ScenarioWarning` and kept in
    :attr:`RecordingResult.warnings`.

    Returns
    -------
    RecordingResult : traces, scores, the solution as a DataFrame (``to_dataframe``).

    Raises
    ------
    ProcessingError : an argument that cannot be processed (named).
    ftnav.io.common.ScenarioError : the recording file or its logs (file:line, field).
    ftnav.engine.driver.Diverged : a method's solution diverged (never returned).
    """
    prepared = prepare_recording(
        recording, methods=methods, aids=aids, outages=outages, faults=faults, smooth=smooth
    )
    for note in prepared.loaded.warnings:  # suspicious but legal input: a Python warning
        warnings.warn(note, ScenarioWarning, stacklevel=2)
    return prepared.run(progress)
