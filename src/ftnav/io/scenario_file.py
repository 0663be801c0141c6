"""Scenario files: TOML on disk, validated with pydantic, frozen dataclasses inside.

This is the only place where scenario dictionaries exist.  :func:`load_scenario`
reads a TOML file, :func:`parse_scenario` validates an already-parsed dictionary,
and both return the plain frozen :class:`ftnav.model.scenario.Scenario` whose
matrices are float64 ``numpy`` arrays of checked shape (read-only).
:func:`scenario_to_dict` is the inverse (plain lists, floats, ints, strings), so
a scenario can be dumped and hashed; :func:`scenario_json_schema` describes the
format.  The reference is ``docs/scenario-format.md``.

Every problem is reported as a :class:`ScenarioError` whose message is a single
line ``<field path>: <reason>``, e.g. ``sensors[1].R: not positive definite``.
"""

from __future__ import annotations

import json
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    model_validator,
)

from ftnav.core.discretize import van_loan
from ftnav.io.common import (
    MAX_NOISE_FACTOR,
    MAX_OFFSET,
    PSD_RTOL,
    STRICT,
    SYM_RTOL,
    FileName,
    Matrix,
    Name,
    ScenarioError,
    Vector,
    covariance_problem,
    fail,
    number,
    read_toml,
    to_scenario_error,
    unique,
    with_line,
)
from ftnav.io.ins_scenario_file import (
    LARGE_FAULT_SIGMAS,
    InsScenarioFile,
    ScenarioWarning,
    parse_ins_scenario,
)
from ftnav.io.sections import (
    EvaluationFile,
    FigureFile,
    MethodConfig,
    build_figures,
    explain_method_key,
    resolve_methods,
)
from ftnav.model.scenario import Fault, InsScenario, Scenario
from ftnav.model.system import LinearModel, PrivateStates, Sensor
from ftnav.scenarios import builtin_names, builtin_path

__all__ = [
    "ScenarioError",
    "load_scenario",
    "parse_scenario",
    "scenario_json_schema",
    "scenario_to_dict",
]

# ------------------------------------------------------------------ file models


class PrivateFile(BaseModel):
    """``[sensors.private]``: states carried only by this sensor's local filter."""

    model_config = STRICT

    states: list[Name] = Field(min_length=1, description="names of the p private states")
    F: Matrix = Field(description="p x p transition block")
    Q: Matrix = Field(description="p x p process noise, symmetric positive semi-definite")
    x0: Vector = Field(description="p initial mean")
    P0: Matrix = Field(description="p x p initial covariance, symmetric positive definite")
    H: Matrix = Field(description="m x p measurement columns acting on the private states")


class SensorFile(BaseModel):
    """``[[sensors]]``: one aiding sensor z = H x + v, v ~ N(0, R)."""

    model_config = STRICT

    name: Name = Field(description="unique sensor name")
    H: Matrix = Field(description="m x n measurement matrix (m >= 1)")
    R: Matrix = Field(description="m x m noise covariance assumed by the filters (SPD)")
    R_true: Matrix | None = Field(
        default=None, description="m x m noise covariance of the simulator (SPD); default R"
    )
    every: int = Field(default=1, ge=1, description="measure every this many steps")
    offset: int = Field(default=0, ge=0, description="step offset of the measurement schedule")
    private: PrivateFile | None = Field(default=None, description="sensor-specific states")


class ModelFile(BaseModel):
    """``[model]``: common-state model x_{k+1} = F x_k + w_k, w ~ N(0, Q).

    Either discrete (``F``, ``Q``) or continuous (``F_c``, ``Q_c``: dx/dt = F_c x + w(t)
    with white noise of spectral density ``Q_c``, discretized over ``dt`` by Van Loan).
    """

    model_config = STRICT

    states: list[Name] = Field(min_length=1, description="unique names of the n states")
    F: Matrix | None = Field(default=None, description="n x n transition matrix (or F_c)")
    Q: Matrix | None = Field(
        default=None, description="n x n process noise assumed by the filters (SPD; or Q_c)"
    )
    F_c: Matrix | None = Field(
        default=None, description="n x n continuous-time system matrix, instead of F"
    )
    Q_c: Matrix | None = Field(
        default=None,
        description="n x n spectral density of the continuous process noise "
        "(PSD, units²/s), instead of Q; the filters' Q is its Van Loan discretization",
    )
    x0: Vector = Field(description="n initial mean")
    P0: Matrix = Field(description="n x n initial covariance (SPD)")
    Q_true: Matrix | None = Field(
        default=None, description="n x n process noise of the simulator (PSD); default Q"
    )
    Q_c_true: Matrix | None = Field(
        default=None,
        description="with F_c: n x n spectral density of the simulator's "
        "process noise (PSD), instead of Q_true; default Q_c",
    )


class FaultFile(BaseModel):
    """``[[faults]]``: a fault on one sensor over start <= t < end seconds."""

    model_config = STRICT

    sensor: Name = Field(description="name of the faulty sensor")
    kind: Literal["bias", "ramp", "noise-scale", "outage", "stuck"] = Field(
        description="bias | ramp | noise-scale | outage | stuck"
    )
    start: float = number("window start in seconds", ge=0.0)
    end: float = number("window end in seconds (> start)")
    magnitude: Vector | None = Field(
        default=None,
        description="m values: offset (bias), final offset (ramp), std factor (noise-scale); "
        "optional for outage and stuck",
    )


class ScenarioFile(BaseModel):
    """A ftnav scenario file (TOML)."""

    model_config = ConfigDict(
        extra="forbid", strict=True, allow_inf_nan=False, title="ftnav scenario"
    )

    name: FileName = Field(description="scenario name (the default output folder's name)")
    description: str = Field(default="", description="free text")
    dt: float = number("seconds per step", gt=0)
    steps: int = Field(ge=1, description="number of steps k = 1..steps, t_k = k*dt")
    model: ModelFile
    sensors: list[SensorFile] = Field(min_length=1)
    faults: list[FaultFile] = Field(default=[])
    methods: list[MethodConfig] = Field(min_length=1)
    evaluation: EvaluationFile = Field(default_factory=EvaluationFile)
    figures: list[FigureFile] = Field(default=[])

    _built: Scenario | None = PrivateAttr(default=None)

    @model_validator(mode="after")
    def _cross_check(self) -> ScenarioFile:
        self._built = _build(self)
        return self


# ------------------------------------------------------------ cross-field checks


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _vector(values: list[float], n: int, source: str, *path: str | int) -> np.ndarray:
    if len(values) != n:
        raise fail(
            f"expected {n} value{'' if n == 1 else 's'} (from {source}), got {len(values)}", *path
        )
    return _frozen(np.array(values, dtype=np.float64).reshape(n))


def _matrix(
    rows: list[list[float]],
    shape: tuple[int, int],
    source: str,
    *path: str | int,
    spd: bool = False,
    psd: bool = False,
) -> np.ndarray:
    got = (len(rows), len(rows[0]) if rows else 0)
    if got != shape:
        raise fail(
            f"expected a {shape[0]}x{shape[1]} matrix (from {source}), got {got[0]}x{got[1]}",
            *path,
        )
    a = np.array(rows, dtype=np.float64).reshape(shape)
    if spd or psd:
        scale = float(np.max(np.abs(a))) if a.size else 0.0
        if float(np.max(np.abs(a - a.T), initial=0.0)) > SYM_RTOL * scale:
            raise fail("not symmetric", *path)
        a = 0.5 * (a + a.T)
        if spd:
            try:
                np.linalg.cholesky(a)
            except np.linalg.LinAlgError:
                raise fail("not positive definite", *path) from None
        else:
            eig = np.linalg.eigvalsh(a)
            if eig.size and eig[0] < -PSD_RTOL * max(float(np.max(np.abs(eig))), 1e-300):
                raise fail(f"not positive semi-definite (eigenvalue {eig[0]:.3g})", *path)
        problem = covariance_problem(a, definite=spd)
        if problem is not None:
            raise fail(problem, *path)
    return _frozen(a)


def _mean(x0: np.ndarray, *path: str | int) -> np.ndarray:
    """An initial mean within ±MAX_OFFSET state units (its square must not overflow)."""
    if x0.size and float(np.abs(x0).max()) > MAX_OFFSET:
        raise fail(
            f"implausibly large value {np.abs(x0).max():.3g} (at most {MAX_OFFSET:g} state units)",
            *path,
        )
    return x0


def _model_form(m: ModelFile) -> bool:
    """True for a continuous-time model (F_c, Q_c); checks that the keys are not mixed."""
    continuous = m.F_c is not None or m.Q_c is not None
    given = [k for k in ("F", "Q", "F_c", "Q_c", "Q_true", "Q_c_true") if getattr(m, k) is not None]
    if continuous:
        for key in ("F", "Q"):
            if key in given:
                raise fail(
                    f"not used with F_c and Q_c (a continuous-time model: F and Q "
                    f"come from them by Van Loan); give either {key} or "
                    f"{key[0]}_c",
                    "model",
                    key,
                )
        for key in ("F_c", "Q_c"):
            if key not in given:
                raise fail(
                    f"missing required key ({'F_c' if key == 'Q_c' else 'Q_c'} "
                    "makes a continuous-time model)",
                    "model",
                    key,
                )
        if "Q_true" in given and "Q_c_true" in given:
            raise fail(
                "give either Q_true (discrete) or Q_c_true (spectral density)", "model", "Q_c_true"
            )
    else:
        for key in ("F", "Q"):
            if key not in given:
                raise fail(
                    "missing required key (or F_c and Q_c for a continuous-time model)",
                    "model",
                    key,
                )
        if "Q_c_true" in given:
            raise fail("only used with F_c and Q_c (a continuous-time model)", "model", "Q_c_true")
    return continuous


def _discretized(
    F_c: np.ndarray, Q_c: np.ndarray, dt: float, key: str, spd: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Van Loan's discretization (spec §8.4) of (F_c, Q_c) over dt, Q checked."""
    with np.errstate(all="ignore"):  # an overflow is reported below, as one line
        F, Q = van_loan(F_c, Q_c, dt)
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(Q))):
        raise fail(
            f"the discretization over dt = {dt!r} s overflows (F_c too large)", "model", "F_c"
        )
    if spd:
        try:
            np.linalg.cholesky(Q)
        except np.linalg.LinAlgError:
            raise fail(
                f"its discrete Q over dt = {dt!r} s is not positive definite (the "
                "noise does not reach every state)",
                "model",
                key,
            ) from None
    return _frozen(np.array(F)), _frozen(np.array(Q))


def _build_model(m: ModelFile, dt: float) -> LinearModel:
    unique(m.states, "state name", "model", "states")
    n = len(m.states)
    src = "model.states"
    continuous = _model_form(m)
    if continuous:
        assert m.F_c is not None and m.Q_c is not None  # _model_form refuses one alone
        F_c = _matrix(m.F_c, (n, n), src, "model", "F_c")
        Q_c = _matrix(m.Q_c, (n, n), src, "model", "Q_c", psd=True)
        F, Q = _discretized(F_c, Q_c, dt, "Q_c", spd=True)
    else:
        assert m.F is not None and m.Q is not None  # _model_form refuses a missing one
        F = _matrix(m.F, (n, n), src, "model", "F")
        Q = _matrix(m.Q, (n, n), src, "model", "Q", spd=True)
    x0 = _mean(_vector(m.x0, n, src, "model", "x0"), "model", "x0")
    P0 = _matrix(m.P0, (n, n), src, "model", "P0", spd=True)
    if m.Q_c_true is not None:
        Q_c_true = _matrix(m.Q_c_true, (n, n), src, "model", "Q_c_true", psd=True)
        Q_true = _discretized(F_c, Q_c_true, dt, "Q_c_true", spd=False)[1]
    elif m.Q_true is not None:
        Q_true = _matrix(m.Q_true, (n, n), src, "model", "Q_true", psd=True)
    else:
        Q_true = Q
    return LinearModel(tuple(m.states), F, Q, x0, P0, Q_true)


def _build_private(p: PrivateFile, model_states: Sequence[str], m: int, i: int) -> PrivateStates:
    at = ("sensors", i, "private")
    unique(p.states, "state name", *at, "states")
    for j, name in enumerate(p.states):
        if name in model_states:
            raise fail(f"{name!r} is already a state of model.states", *at, "states", j)
    k = len(p.states)
    src = f"sensors[{i}].private.states"
    F = _matrix(p.F, (k, k), src, *at, "F")
    Q = _matrix(p.Q, (k, k), src, *at, "Q", psd=True)
    x0 = _mean(_vector(p.x0, k, src, *at, "x0"), *at, "x0")
    P0 = _matrix(p.P0, (k, k), src, *at, "P0", spd=True)
    H = _matrix(p.H, (m, k), f"sensors[{i}].H rows and {src}", *at, "H")
    return PrivateStates(tuple(p.states), F, Q, x0, P0, H)


def _build_sensor(s: SensorFile, model: LinearModel, i: int) -> Sensor:
    n = model.n
    m = len(s.H)
    if m == 0:
        raise fail("expected at least one row", "sensors", i, "H")
    cols = len(s.H[0])
    if cols != n:
        raise fail(f"expected {n} columns (from model.states), got {m}x{cols}", "sensors", i, "H")
    H = _matrix(s.H, (m, n), "model.states", "sensors", i, "H")
    src = f"sensors[{i}].H rows"
    R = _matrix(s.R, (m, m), src, "sensors", i, "R", spd=True)
    R_true = (
        R if s.R_true is None else _matrix(s.R_true, (m, m), src, "sensors", i, "R_true", spd=True)
    )
    private = None if s.private is None else _build_private(s.private, model.states, m, i)
    return Sensor(s.name, H, R, R_true, s.every, s.offset, private)


def _build_fault(f: FaultFile, sensors: Sequence[Sensor], i: int, duration: float) -> Fault:
    names = [s.name for s in sensors]
    if f.sensor not in names:
        raise fail(
            f"unknown sensor {f.sensor!r} (known: {', '.join(names)})", "faults", i, "sensor"
        )
    if not f.end > f.start:
        raise fail(f"must be greater than start ({f.start!r})", "faults", i, "end")
    if not f.start < duration:
        raise fail(
            f"{f.start:g} s is not before the end of the run ({duration:g} s, dt*steps): "
            "the fault would never act",
            "faults",
            i,
            "start",
        )
    if f.end > duration + 1e-9:
        warnings.warn(
            f"faults[{i}].end: {f.end:g} s is after the end of the run ({duration:g} s, "
            "dt*steps): the fault is cut there",
            ScenarioWarning,
            stacklevel=2,
        )
    j = names.index(f.sensor)
    m = sensors[j].dim
    if f.magnitude is None:
        if f.kind not in ("outage", "stuck"):
            raise fail(f"required for kind {f.kind!r}", "faults", i, "magnitude")
        magnitude = _frozen(np.zeros(m))
    else:
        magnitude = _vector(f.magnitude, m, f"sensors[{j}].H rows", "faults", i, "magnitude")
    if f.kind == "noise-scale" and not np.all(magnitude > 0):
        raise fail("noise-scale factors must all be > 0", "faults", i, "magnitude")
    if f.kind == "noise-scale" and np.any(magnitude > MAX_NOISE_FACTOR):
        raise fail(
            f"noise-scale factors must be at most {MAX_NOISE_FACTOR:g}, got {magnitude.max():g}",
            "faults",
            i,
            "magnitude",
        )
    sigma = np.sqrt(np.diag(sensors[j].R))
    if f.kind in ("bias", "ramp") and np.any(np.abs(magnitude) > LARGE_FAULT_SIGMAS * sigma):
        k = int(np.argmax(np.abs(magnitude) / sigma))
        warnings.warn(
            f"faults[{i}].magnitude: {magnitude[k]:.3g} is {abs(magnitude[k]) / sigma[k]:.3g} "
            f"times the σ of {f.sensor}'s row {k} ({sigma[k]:.3g}, from R): any test sees it "
            "at once; is the unit right?",
            ScenarioWarning,
            stacklevel=3,
        )
    if np.any(np.abs(magnitude) > MAX_OFFSET):
        raise fail(
            f"implausibly large offset {np.abs(magnitude).max():.3g} (at most "
            f"{MAX_OFFSET:g} state units, like a σ)",
            "faults",
            i,
            "magnitude",
        )
    return Fault(f.sensor, f.kind, float(f.start), float(f.end), magnitude)


def _warn_idle(sensors: Sequence[Sensor], faults: Sequence[Fault], dt: float, steps: int) -> None:
    """Warn of a sensor that never measures in the run (``every`` or ``offset`` past its
    steps) and of a fault whose window holds none of its sensor's measurements (between
    two of them, or on a sensor that never measures): legal, but nothing is tested there,
    and the fault was scored as a miss.  Only the window's own epochs are looked at (a
    run of 10¹⁰ steps is refused later, by its memory, not here)."""
    names = [s.name for s in sensors]
    for i, s in enumerate(sensors):
        first = s.offset if s.offset >= 1 else s.every  # Sensor.available's first step
        if first > steps:
            warnings.warn(
                f"sensors[{i}].every: {s.name} measures every {s.every} steps from step "
                f"{s.offset}, never within the run's {steps} steps: it aids nothing",
                ScenarioWarning,
                stacklevel=3,
            )
    for i, f in enumerate(faults):
        s = sensors[names.index(f.sensor)]
        lo, hi = max(1, math.floor(f.start / dt)), min(steps, math.ceil(f.end / dt))
        if hi - lo > IDLE_CHECK_MAX:
            continue  # a window that long holds a measurement of any sensor that measures
        k = np.arange(lo, hi + 1)
        t = dt * k  # the epochs' times as Scenario.times computes them
        due = ((k - s.offset) % s.every == 0) & (k >= s.offset)
        if not (due & (t >= f.start) & (t < f.end)).any():
            warnings.warn(
                f"faults[{i}]: no measurement of {f.sensor} falls in [{f.start:g}, {f.end:g}) s "
                f"(it measures every {s.every * dt:g} s; epochs at k·dt, dt = {dt:g} s): the "
                "fault never acts",
                ScenarioWarning,
                stacklevel=3,
            )


#: a fault window of more epochs than this is not looked at for its measurements
IDLE_CHECK_MAX = 10**6


def _build(f: ScenarioFile) -> Scenario:
    model = _build_model(f.model, float(f.dt))
    sensors = []
    seen: set[str] = set()
    for i, s in enumerate(f.sensors):
        if s.name in seen:
            raise fail(f"duplicate sensor name {s.name!r}", "sensors", i, "name")
        seen.add(s.name)
        sensors.append(_build_sensor(s, model, i))
    duration = f.dt * f.steps
    faults = tuple(_build_fault(x, sensors, i, duration) for i, x in enumerate(f.faults))
    _warn_idle(sensors, faults, float(f.dt), f.steps)
    methods = list(f.methods)
    ev = f.evaluation
    if not ev.skip_initial < duration:
        raise fail(f"must be less than dt*steps ({duration!r} s)", "evaluation", "skip_initial")
    figures = build_figures(
        f.figures, states=model.states, methods=methods, sensors=[s.name for s in sensors]
    )
    return Scenario(
        name=f.name,
        dt=float(f.dt),
        steps=f.steps,
        model=model,
        sensors=tuple(sensors),
        faults=faults,
        methods=tuple(methods),
        evaluation=ev.settings(),
        description=f.description,
        figures=figures,
    )


# ------------------------------------------------------------------- public API


def parse_scenario(
    data: Mapping[str, Any],
    origin: str = "<scenario>",
    base: Path | None = None,
    models: bool = True,
) -> Scenario:
    """Validate an already-parsed scenario dictionary and build the frozen objects.

    Parameters
    ----------
    data : the TOML document as a dictionary (lists for arrays, no tuples).
    origin : where ``data`` came from; kept on the error as ``origin`` and used
        as the path of errors about the document as a whole.
    base : the folder relative model paths are relative to (default: the working one).
    models : load the trained models the methods name (False for the training commands,
        whose scenario may name the file they are about to write).

    Raises
    ------
    ScenarioError : the first problem found, as one line ``<field path>: <reason>``.
    """
    if isinstance(data, Mapping) and not isinstance(data, dict):
        data = dict(data)
    try:
        spec = ScenarioFile.model_validate(data)
    except ValidationError as exc:
        raise to_scenario_error(exc, origin, ScenarioFile, explain_method_key) from None
    sc = spec._built
    assert sc is not None
    return replace(sc, learned=resolve_methods(sc.methods, sc.system(), base, origin, models))


def load_scenario(source: str | Path, models: bool = True) -> Scenario | InsScenario:
    """Read, validate and build the scenario in the TOML file ``source``, or a built-in
    scenario given by its name (:func:`ftnav.scenarios.builtin_names`).

    ``models=False`` checks the methods but loads no trained model file.

    Raises
    ------
    ScenarioError : unreadable file, TOML syntax error (message names the file),
        or an invalid scenario (message ``<field path>: <reason>``).
    """
    if not isinstance(source, str | os.PathLike):
        raise ScenarioError(
            "scenario", f"expected a built-in scenario's name or a file's path, got {source!r}"
        )
    if isinstance(source, str) and source in builtin_names() and not Path(source).exists():
        source = builtin_path(source)
    data = read_toml(source)
    try:
        if data.get("kind") == "integrated":
            sc: Scenario | InsScenario = parse_ins_scenario(
                data, str(source), Path(source).parent, models
            )
        else:
            sc = parse_scenario(data, str(source), Path(source).parent, models)
    except ScenarioError as e:  # the line of the file that sets the field
        raise with_line(e, source) from None
    return replace(sc, builtin=builtin_of(Path(source)))


def builtin_of(path: Path) -> str | None:
    """The built-in scenario whose file ``path`` is, byte for byte, or None."""
    try:
        text = path.read_bytes()
    except OSError:
        return None
    for name in builtin_names():
        if builtin_path(name).read_bytes() == text:
            return name
    return None


def scenario_json_schema() -> dict[str, Any]:
    """JSON schema of scenario files, linear and integrated (what ``ftnav schema`` prints).

    ``oneOf`` two objects: a linear scenario (``$defs.ScenarioFile``, no ``kind`` key)
    or an integrated one (``$defs.InsScenarioFile`` of :mod:`ftnav.io.ins_scenario_file`,
    ``kind = "integrated"``).  Both forbid unknown keys, so a file matches exactly one.
    Every table of either is under ``$defs`` (``ModelFile``, ``MethodFile``, ...).
    """
    from pydantic import TypeAdapter

    union = TypeAdapter(ScenarioFile | InsScenarioFile).json_schema()
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "ftnav scenario file",
        "description": "A linear scenario (model, sensors, faults, methods) or, with "
        'kind = "integrated", an integrated-navigation scenario (flight, IMU, aids, '
        "faults, methods); docs/scenario-format.md",
        "oneOf": union["anyOf"],
        "$defs": union["$defs"],
    }


def _rows(a: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(a, dtype=np.float64)]


def _vals(a: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(a, dtype=np.float64).ravel()]


def scenario_to_dict(sc: Scenario) -> dict[str, Any]:
    """The scenario as a plain, TOML/JSON-serialisable dictionary (inverse of parsing).

    Every optional key is written out explicitly (``Q_true``, ``R_true``,
    ``[evaluation]``), except an unset optional one (TOML has no null), and each
    method's settings that differ from their defaults (a setting its architecture or
    mode does not read is refused, so the defaults are not written), so
    ``parse_scenario(scenario_to_dict(sc))`` rebuilds ``sc`` and
    ``json.dumps(..., sort_keys=True)`` gives a stable hash input.
    """
    m = sc.model
    if m.F is None or m.Q is None or m.Q_true is None:
        raise ValueError("model: no F, Q or Q_true to write (a model linearized per epoch)")
    sensors = []
    for s in sc.sensors:
        if s.H is None:
            raise ValueError(f"sensor {s.name!r}: no H to write (linearized per epoch)")
        d: dict[str, Any] = {
            "name": s.name,
            "H": _rows(s.H),
            "R": _rows(s.R),
            "R_true": _rows(s.R_true),
            "every": int(s.every),
            "offset": int(s.offset),
        }
        if s.private is not None:
            p = s.private
            d["private"] = {
                "states": list(p.names),
                "F": _rows(p.F),
                "Q": _rows(p.Q),
                "x0": _vals(p.x0),
                "P0": _rows(p.P0),
                "H": _rows(p.H),
            }
        sensors.append(d)
    # the settings that differ from their defaults (nested detector and noise as tables)
    methods = [
        {"name": me.name, "architecture": me.architecture}
        | json.loads(me.model_dump_json(exclude_none=True, exclude_defaults=True))
        for me in sc.methods
    ]
    return {
        "name": sc.name,
        "description": sc.description,
        "dt": float(sc.dt),
        "steps": int(sc.steps),
        "model": {
            "states": list(m.states),
            "F": _rows(m.F),
            "Q": _rows(m.Q),
            "x0": _vals(m.x0),
            "P0": _rows(m.P0),
            "Q_true": _rows(m.Q_true),
        },
        "sensors": sensors,
        "faults": [
            {
                "sensor": f.sensor,
                "kind": f.kind,
                "start": float(f.start),
                "end": float(f.end),
                "magnitude": _vals(f.magnitude),
            }
            for f in sc.faults
        ],
        "methods": methods,
        "evaluation": {k: v for k, v in asdict(sc.evaluation).items() if v is not None},
        "figures": [
            {
                "name": g.name,
                "title": g.title,
                "kind": g.kind,
                "methods": list(g.methods),
                "states": list(g.states),
                "condition": g.condition,
                "sensor": g.sensor,
            }
            for g in sc.figures
        ],
    }
