"""Scenario files: TOML on disk, validated with pydantic, frozen dataclasses inside.

This is the only place where scenario dictionaries exist.  :func:`load_scenario`
reads a TOML file, :func:`parse_scenario` validates an already-parsed dictionary,
and both return the plain frozen :class:`ftnav.sim.scenario.Scenario` whose
matrices are float64 ``numpy`` arrays of checked shape (read-only).
:func:`scenario_to_dict` is the inverse (plain lists, floats, ints, strings), so
a scenario can be dumped and hashed; :func:`scenario_json_schema` describes the
format.  The reference is ``docs/scenario-format.md``.

Every problem is reported as a :class:`ScenarioError` whose message is a single
line ``<field path>: <reason>``, e.g. ``sensors[1].R: not positive definite``.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    model_validator,
)
from pydantic_core import PydanticCustomError

from ftnav.sim.scenario import (
    MAX_FIGURE_METHODS,
    AdaptiveNoise,
    Architecture,
    CommonMode,
    Detector,
    Evaluation,
    Fault,
    FaultKind,
    FigureCondition,
    FigureKind,
    FigureSpec,
    Increment,
    Isolation,
    LinearModel,
    Method,
    Mode,
    Prior,
    PrivateStates,
    Scenario,
    Sensor,
    Sharing,
    TraceMode,
)

__all__ = [
    "ScenarioError",
    "load_scenario",
    "parse_scenario",
    "scenario_json_schema",
    "scenario_to_dict",
]

#: Relative tolerance of the symmetry test: max|A - Aᵀ| <= SYM_RTOL · max|A|.
SYM_RTOL = 1e-9
#: Tolerance of ``sum(betas) + master_share == 1``.
SHARE_TOL = 1e-9
#: Relative tolerance of the positive-semi-definite test on the smallest eigenvalue.
PSD_RTOL = 1e-10

_CHECK = "ftnav_check"  # pydantic error type of the checks below


# --------------------------------------------------------------------------- errors


class ScenarioError(ValueError):
    """An invalid scenario: the message is one line ``<field path>: <reason>``.

    Attributes
    ----------
    path : dotted field path (``methods[2].sharing``), or the file name for
        problems reading the file.
    reason : what is wrong, one line.
    origin : where the data came from (file name or ``"<scenario>"``).
    """

    def __init__(self, path: str, reason: str, origin: str = "<scenario>") -> None:
        self.path = _one_line(path)
        self.reason = _one_line(reason)
        self.origin = origin
        super().__init__(f"{self.path}: {self.reason}")

    def __reduce__(self):  # keep picklable despite the custom signature
        return (type(self), (self.path, self.reason, self.origin))


def _one_line(text: str) -> str:
    """Collapse every line break (``\\n``, ``\\r``, U+2028, ...) to one space."""
    return " ".join(str(text).splitlines()).strip() if text else str(text)


def _fail(reason: str, *path: str | int) -> PydanticCustomError:
    """A validation error at ``path`` (relative to the validator's own location)."""
    return PydanticCustomError(_CHECK, "{reason}", {"reason": reason, "path": tuple(path)})


def _format_loc(loc: Sequence[str | int]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


_TOML_TYPES = {
    bool: "boolean",
    int: "integer",
    float: "float",
    str: "string",
    list: "array",
    tuple: "array",
    dict: "table",
}


def _show(value: Any) -> str:
    """Short one-line description of an offending input: ``string 'abc'``."""
    kind = _TOML_TYPES.get(type(value), type(value).__name__)
    if isinstance(value, list | tuple | dict):
        return kind
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{kind} {text}"


def _reason(err: Mapping[str, Any]) -> str:
    """One-line reason for one pydantic error."""
    kind = err["type"]
    ctx = err.get("ctx") or {}
    value = err.get("input")
    if kind == _CHECK:
        return str(ctx["reason"])
    if kind == "extra_forbidden":
        return "unknown key"
    if kind == "missing":
        return "missing required key"
    if kind == "literal_error":
        choices = re.findall(r"'((?:[^'\\]|\\.)*)'", str(ctx.get("expected", "")))
        shown = repr(value) if isinstance(value, str) else _show(value)
        return f"unknown value {shown} (expected one of: {', '.join(choices)})"
    if kind in ("float_type", "float_parsing"):
        return f"expected a number, got {_show(value)}"
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return f"expected an integer, got {_show(value)}"
    if kind in ("bool_type", "bool_parsing"):
        return f"expected true or false, got {_show(value)}"
    if kind == "string_type":
        return f"expected a string, got {_show(value)}"
    if kind in ("list_type", "tuple_type"):
        return f"expected an array, got {_show(value)}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"expected a table, got {_show(value)}"
    if kind == "finite_number":
        return f"is NaN or inf ({value!r})"
    bounds = {
        "greater_than": ("gt", ">"),
        "greater_than_equal": ("ge", ">="),
        "less_than": ("lt", "<"),
        "less_than_equal": ("le", "<="),
    }
    if kind in bounds:
        key, op = bounds[kind]
        return f"must be {op} {ctx.get(key)}, got {value!r}"
    if kind == "too_short":
        need = ctx.get("min_length", 1)
        return f"must have at least {need} {'entry' if need == 1 else 'entries'}"
    if kind == "string_too_short":
        return "must not be empty"
    return str(err.get("msg", kind))


def _to_scenario_error(exc: ValidationError, origin: str) -> ScenarioError:
    err = exc.errors(include_url=False)[0]
    loc = tuple(err.get("loc", ()))
    if err["type"] == _CHECK:
        loc = loc + tuple(err["ctx"]["path"])
    path = _format_loc(loc) or origin
    return ScenarioError(path, _reason(err), origin)


# ------------------------------------------------------------- field-level types


def _finite_vector(values: list[float]) -> list[float]:
    if not all(math.isfinite(v) for v in values):
        raise _fail("contains NaN or inf")
    return values


def _finite_matrix(rows: list[list[float]]) -> list[list[float]]:
    if rows and any(len(r) != len(rows[0]) for r in rows):
        lengths = ", ".join(str(len(r)) for r in rows)
        raise _fail(f"rows have different lengths ({lengths})")
    if not all(math.isfinite(v) for r in rows for v in r):
        raise _fail("contains NaN or inf")
    return rows


def _name(text: str) -> str:
    if not text.strip():
        raise _fail("must be a non-empty name")
    return text


Vector = Annotated[list[float], AfterValidator(_finite_vector)]
Matrix = Annotated[list[list[float]], AfterValidator(_finite_matrix)]
Name = Annotated[str, AfterValidator(_name)]


def _num(description: str, **bounds: float) -> Any:
    """A finite float field with optional bounds."""
    return Field(description=description, allow_inf_nan=False, **bounds)


_STRICT = ConfigDict(extra="forbid", strict=True)


# ------------------------------------------------------------------ file models


class PrivateFile(BaseModel):
    """``[sensors.private]``: states carried only by this sensor's local filter."""

    model_config = _STRICT

    states: list[Name] = Field(min_length=1, description="names of the p private states")
    F: Matrix = Field(description="p x p transition block")
    Q: Matrix = Field(description="p x p process noise, symmetric positive semi-definite")
    x0: Vector = Field(description="p initial mean")
    P0: Matrix = Field(description="p x p initial covariance, symmetric positive definite")
    H: Matrix = Field(description="m x p measurement columns acting on the private states")


class SensorFile(BaseModel):
    """``[[sensors]]``: one aiding sensor z = H x + v, v ~ N(0, R)."""

    model_config = _STRICT

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

    model_config = _STRICT

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

    model_config = _STRICT

    sensor: Name = Field(description="name of the faulty sensor")
    kind: FaultKind = Field(description="bias | ramp | noise-scale | outage | stuck")
    start: float = _num("window start in seconds", ge=0.0)
    end: float = _num("window end in seconds (> start)")
    magnitude: Vector | None = Field(
        default=None,
        description="m values: offset (bias), final offset (ramp), std factor (noise-scale); "
        "optional for outage and stuck",
    )


_M = Method.__dataclass_fields__


def _d(key: str) -> Any:
    """Default of a Method dataclass field."""
    return _M[key].default


class MethodFile(BaseModel):
    """``[[methods]]``: one fusion method; every key but ``name`` is optional."""

    model_config = _STRICT

    name: Name = Field(description="unique method name")
    architecture: Architecture = Field(default=_d("architecture"))
    mode: Mode = Field(default=_d("mode"), description="information reset mode")
    reset_interval: int = Field(default=_d("reset_interval"), ge=1)
    sharing: Sharing = Field(default=_d("sharing"), description="information-sharing rule")
    betas: list[Annotated[float, Field(ge=0.0, allow_inf_nan=False)]] = Field(
        default=[], description="sharing = 'fixed' only: one factor per sensor"
    )
    master_share: float = _num("master filter's share", default=_d("master_share"), ge=0, lt=1)
    trace_mode: TraceMode = Field(default=_d("trace_mode"))
    detector: Detector = Field(default=_d("detector"))
    false_alarm_probability: float = _num(
        "false-alarm probability of the chi-square test",
        default=_d("false_alarm_probability"),
        gt=0,
        lt=1,
    )
    window: int = Field(default=_d("window"), ge=1, description="chi-square test window (steps)")
    prior: Prior = Field(default=_d("prior"))
    n_on: int = Field(default=_d("n_on"), ge=1, description="alarms in a row to isolate")
    n_off: int = Field(default=_d("n_off"), ge=1, description="passes in a row to readmit")
    state_test_reset: int = Field(default=_d("state_test_reset"), ge=5)
    adaptive_noise: AdaptiveNoise = Field(default=_d("adaptive_noise"))
    vb_rho: float = _num("VB forgetting factor", default=_d("vb_rho"), gt=0, le=1)
    vb_iterations: int = Field(default=_d("vb_iterations"), ge=1)
    vb_sensors: list[Name] = Field(default=[], description="sensors with VB; empty = all")
    increment: Increment = Field(default=_d("increment"))
    reconstructed: bool = Field(default=_d("reconstructed"))
    rescale_factor: float = _num(
        "information scale of the rescale mode", default=_d("rescale_factor"), ge=0, lt=1
    )
    model: str | None = Field(
        default=_d("model"),
        description="trained model file (detector 'rbf' or architecture 'neural'); a relative "
        "path is relative to the scenario file",
    )
    threshold: float | None = _num(
        "RBF decision threshold (default: the model's)", default=_d("threshold"), gt=0, lt=1
    )
    uncovered: Name = Field(
        default=_d("uncovered"),
        description="neural: flag pattern no configuration covers -> 'renormalize' or a "
        "configuration name",
    )
    isolation: Isolation = Field(
        default=_d("isolation"),
        description="federated, neural: a flagged local filter runs 'standalone' on its own "
        "measurements (spec §1.8) or does the 'time-update' only (spec §6.3)",
    )
    common_mode: CommonMode = Field(
        default=_d("common_mode"),
        description="federated: when every aid is flagged at once, 'isolate' them all or "
        "'keep' them (the shared SINS failed, not the aids)",
    )
    common_mode_quorum: int | None = Field(
        default=_d("common_mode_quorum"),
        ge=2,
        description="federated, common_mode 'keep': keep every aid when at least this many "
        "are flagged at the same epoch (default: all of them)",
    )


class FigureFile(BaseModel):
    """``[[figures]]``: one figure of the run (optional; without any, the default figures)."""

    model_config = _STRICT

    name: Name = Field(description="file name without extension: the run writes <name>.png")
    title: str = Field(default="", description="title (default: the scenario's description)")
    kind: FigureKind = Field(
        default="errors",
        description="errors: estimation error per state; local-fused (integrated): local and "
        "fused position errors; vb-noise (integrated): VB noise sigma of one aid",
    )
    methods: list[Name] = Field(
        min_length=1,
        description=f"methods compared, at most {MAX_FIGURE_METHODS} (one line each per axes)",
    )
    states: list[Name] = Field(default=[], description="one panel per state; empty = all")
    condition: FigureCondition = Field(
        default="faults", description="faults: the run with the faults; fault-free: its twin"
    )
    sensor: str = Field(default="", description="vb-noise: the aid whose noise is drawn")


class EvaluationFile(BaseModel):
    """``[evaluation]``: metric settings."""

    model_config = _STRICT

    skip_initial: float = _num(
        "initial convergence period left out of metrics (s)", default=0.0, ge=0
    )
    grace: float = _num("post-fault grace period (s)", default=10.0, ge=0)


class ScenarioFile(BaseModel):
    """A ftnav scenario file (TOML)."""

    model_config = ConfigDict(extra="forbid", strict=True, title="ftnav scenario")

    name: Name = Field(description="scenario name")
    description: str = Field(default="", description="free text")
    dt: float = _num("seconds per step", gt=0)
    steps: int = Field(ge=1, description="number of steps k = 1..steps, t_k = k*dt")
    model: ModelFile
    sensors: list[SensorFile] = Field(min_length=1)
    faults: list[FaultFile] = Field(default=[])
    methods: list[MethodFile] = Field(min_length=1)
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
        raise _fail(
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
        raise _fail(
            f"expected a {shape[0]}x{shape[1]} matrix (from {source}), got {got[0]}x{got[1]}",
            *path,
        )
    a = np.array(rows, dtype=np.float64).reshape(shape)
    if spd or psd:
        scale = float(np.max(np.abs(a))) if a.size else 0.0
        if float(np.max(np.abs(a - a.T), initial=0.0)) > SYM_RTOL * scale:
            raise _fail("not symmetric", *path)
        a = 0.5 * (a + a.T)
        if spd:
            try:
                np.linalg.cholesky(a)
            except np.linalg.LinAlgError:
                raise _fail("not positive definite", *path) from None
        else:
            eig = np.linalg.eigvalsh(a)
            if eig.size and eig[0] < -PSD_RTOL * max(float(np.max(np.abs(eig))), 1e-300):
                raise _fail(f"not positive semi-definite (eigenvalue {eig[0]:.3g})", *path)
    return _frozen(a)


def _unique(names: Sequence[str], what: str, *path: str | int) -> None:
    seen: set[str] = set()
    for i, name in enumerate(names):
        if name in seen:
            raise _fail(f"duplicate {what} {name!r}", *path, i)
        seen.add(name)


def _model_form(m: ModelFile) -> bool:
    """True for a continuous-time model (F_c, Q_c); checks that the keys are not mixed."""
    continuous = m.F_c is not None or m.Q_c is not None
    given = [k for k in ("F", "Q", "F_c", "Q_c", "Q_true", "Q_c_true") if getattr(m, k) is not None]
    if continuous:
        for key in ("F", "Q"):
            if key in given:
                raise _fail(
                    f"not used with F_c and Q_c (a continuous-time model: F and Q "
                    f"come from them by Van Loan); give either {key} or "
                    f"{key[0]}_c",
                    "model",
                    key,
                )
        for key in ("F_c", "Q_c"):
            if key not in given:
                raise _fail(
                    f"missing required key ({'F_c' if key == 'Q_c' else 'Q_c'} "
                    "makes a continuous-time model)",
                    "model",
                    key,
                )
        if "Q_true" in given and "Q_c_true" in given:
            raise _fail(
                "give either Q_true (discrete) or Q_c_true (spectral density)", "model", "Q_c_true"
            )
    else:
        for key in ("F", "Q"):
            if key not in given:
                raise _fail(
                    "missing required key (or F_c and Q_c for a continuous-time model)",
                    "model",
                    key,
                )
        if "Q_c_true" in given:
            raise _fail("only used with F_c and Q_c (a continuous-time model)", "model", "Q_c_true")
    return continuous


def _discretized(
    F_c: np.ndarray, Q_c: np.ndarray, dt: float, key: str, spd: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Van Loan's discretization (spec §8.4) of (F_c, Q_c) over dt, Q checked."""
    from ftnav.core.discretize import van_loan

    with np.errstate(all="ignore"):  # an overflow is reported below, as one line
        F, Q = van_loan(F_c, Q_c, dt)
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(Q))):
        raise _fail(
            f"the discretization over dt = {dt!r} s overflows (F_c too large)", "model", "F_c"
        )
    if spd:
        try:
            np.linalg.cholesky(Q)
        except np.linalg.LinAlgError:
            raise _fail(
                f"its discrete Q over dt = {dt!r} s is not positive definite (the "
                "noise does not reach every state)",
                "model",
                key,
            ) from None
    return _frozen(np.array(F)), _frozen(np.array(Q))


def _build_model(m: ModelFile, dt: float) -> LinearModel:
    _unique(m.states, "state name", "model", "states")
    n = len(m.states)
    src = "model.states"
    continuous = _model_form(m)
    if continuous:
        F_c = _matrix(m.F_c, (n, n), src, "model", "F_c")
        Q_c = _matrix(m.Q_c, (n, n), src, "model", "Q_c", psd=True)
        F, Q = _discretized(F_c, Q_c, dt, "Q_c", spd=True)
    else:
        F = _matrix(m.F, (n, n), src, "model", "F")
        Q = _matrix(m.Q, (n, n), src, "model", "Q", spd=True)
    x0 = _vector(m.x0, n, src, "model", "x0")
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
    _unique(p.states, "state name", *at, "states")
    for j, name in enumerate(p.states):
        if name in model_states:
            raise _fail(f"{name!r} is already a state of model.states", *at, "states", j)
    k = len(p.states)
    src = f"sensors[{i}].private.states"
    F = _matrix(p.F, (k, k), src, *at, "F")
    Q = _matrix(p.Q, (k, k), src, *at, "Q", psd=True)
    x0 = _vector(p.x0, k, src, *at, "x0")
    P0 = _matrix(p.P0, (k, k), src, *at, "P0", spd=True)
    H = _matrix(p.H, (m, k), f"sensors[{i}].H rows and {src}", *at, "H")
    return PrivateStates(tuple(p.states), F, Q, x0, P0, H)


def _build_sensor(s: SensorFile, model: LinearModel, i: int) -> Sensor:
    n = model.n
    m = len(s.H)
    if m == 0:
        raise _fail("expected at least one row", "sensors", i, "H")
    cols = len(s.H[0])
    if cols != n:
        raise _fail(f"expected {n} columns (from model.states), got {m}x{cols}", "sensors", i, "H")
    H = _matrix(s.H, (m, n), "model.states", "sensors", i, "H")
    src = f"sensors[{i}].H rows"
    R = _matrix(s.R, (m, m), src, "sensors", i, "R", spd=True)
    R_true = (
        R if s.R_true is None else _matrix(s.R_true, (m, m), src, "sensors", i, "R_true", spd=True)
    )
    private = None if s.private is None else _build_private(s.private, model.states, m, i)
    return Sensor(s.name, H, R, R_true, s.every, s.offset, private)


def _build_fault(f: FaultFile, sensors: Sequence[Sensor], i: int) -> Fault:
    names = [s.name for s in sensors]
    if f.sensor not in names:
        raise _fail(
            f"unknown sensor {f.sensor!r} (known: {', '.join(names)})", "faults", i, "sensor"
        )
    if not f.end > f.start:
        raise _fail(f"must be greater than start ({f.start!r})", "faults", i, "end")
    j = names.index(f.sensor)
    m = sensors[j].dim
    if f.magnitude is None:
        if f.kind not in ("outage", "stuck"):
            raise _fail(f"required for kind {f.kind!r}", "faults", i, "magnitude")
        magnitude = _frozen(np.zeros(m))
    else:
        magnitude = _vector(f.magnitude, m, f"sensors[{j}].H rows", "faults", i, "magnitude")
    if f.kind == "noise-scale" and not np.all(magnitude > 0):
        raise _fail("noise-scale factors must all be > 0", "faults", i, "magnitude")
    return Fault(f.sensor, f.kind, float(f.start), float(f.end), magnitude)


def _build_method(me: MethodFile, sensors: Sequence[Sensor], i: int) -> Method:
    names = [s.name for s in sensors]
    if me.sharing == "fixed":
        if len(me.betas) != len(sensors):
            raise _fail(
                f"expected {len(sensors)} values (one per sensor) with sharing = 'fixed', "
                f"got {len(me.betas)}",
                "methods",
                i,
                "betas",
            )
        total = math.fsum(me.betas) + me.master_share
        if abs(total - 1.0) > SHARE_TOL:
            raise _fail(
                f"sum(betas) + master_share must equal 1, got {total!r}", "methods", i, "betas"
            )
    elif me.betas:
        raise _fail(
            f"must be empty unless sharing = 'fixed' (sharing is {me.sharing!r})",
            "methods",
            i,
            "betas",
        )
    _unique(me.vb_sensors, "sensor", "methods", i, "vb_sensors")
    for j, name in enumerate(me.vb_sensors):
        if name not in names:
            raise _fail(
                f"unknown sensor {name!r} (known: {', '.join(names)})",
                "methods",
                i,
                "vb_sensors",
                j,
            )
    needs_model = me.detector == "rbf" or me.architecture == "neural"
    if needs_model and me.model is None:
        what = "detector 'rbf'" if me.detector == "rbf" else "architecture 'neural'"
        raise _fail(f"{what} needs a trained model file", "methods", i, "model")
    if me.model is not None and not needs_model:
        raise _fail(
            "only used with detector = 'rbf' or architecture = 'neural'", "methods", i, "model"
        )
    if me.common_mode_quorum is not None:
        if me.common_mode != "keep":
            raise _fail(
                f"only used with common_mode = 'keep' (common_mode is {me.common_mode!r})",
                "methods",
                i,
                "common_mode_quorum",
            )
        if me.common_mode_quorum > len(sensors):
            raise _fail(
                f"must be <= the number of sensors ({len(sensors)})",
                "methods",
                i,
                "common_mode_quorum",
            )
    if me.prior == "intersection" and me.architecture != "neural":
        raise _fail(
            "'intersection' (covariance intersection of the local priors) is only "
            "used with architecture = 'neural'",
            "methods",
            i,
            "prior",
        )
    if me.mode == "rescale" and not me.reconstructed:
        raise _fail(
            "'rescale' is a reconstruction (spec §1.5); set reconstructed = true to use it",
            "methods",
            i,
            "mode",
        )
    return Method(
        name=me.name,
        architecture=me.architecture,
        mode=me.mode,
        reset_interval=me.reset_interval,
        sharing=me.sharing,
        betas=tuple(float(b) for b in me.betas),
        master_share=float(me.master_share),
        trace_mode=me.trace_mode,
        detector=me.detector,
        false_alarm_probability=float(me.false_alarm_probability),
        window=me.window,
        prior=me.prior,
        n_on=me.n_on,
        n_off=me.n_off,
        state_test_reset=me.state_test_reset,
        adaptive_noise=me.adaptive_noise,
        vb_rho=float(me.vb_rho),
        vb_iterations=me.vb_iterations,
        vb_sensors=tuple(me.vb_sensors),
        increment=me.increment,
        reconstructed=me.reconstructed,
        rescale_factor=float(me.rescale_factor),
        model=me.model,
        threshold=None if me.threshold is None else float(me.threshold),
        uncovered=me.uncovered,
        isolation=me.isolation,
        common_mode=me.common_mode,
        common_mode_quorum=me.common_mode_quorum,
    )


_FILE_STEM = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
#: Figure names the run writes itself.
_RESERVED_FIGURES = ("sharing", "fault_flags")


def _build_figure(
    fg: FigureFile,
    i: int,
    states: Sequence[str],
    methods: Sequence[Method],
    sensors: Sequence[str],
    kinds: Sequence[str] = ("errors",),
    position_states: Sequence[str] = (),
) -> FigureSpec:
    """Check one ``[[figures]]`` entry against the scenario's states, methods and sensors.

    ``states`` may be drawn by ``errors`` figures, ``position_states`` by ``local-fused``
    ones; ``kinds`` are the figure kinds the scenario's kind supports.
    """
    at = ("figures", i)
    if not _FILE_STEM.fullmatch(fg.name):
        raise _fail(
            "must be a file name without extension (letters, digits, '_', '-', '.')", *at, "name"
        )
    if fg.name in _RESERVED_FIGURES:
        raise _fail(f"{fg.name!r} is reserved (the run writes {fg.name}.png itself)", *at, "name")
    if fg.kind not in kinds:
        raise _fail(
            f"kind {fg.kind!r} needs an integrated scenario (here: {', '.join(kinds)})", *at, "kind"
        )
    if len(fg.methods) > MAX_FIGURE_METHODS:
        raise _fail(
            f"at most {MAX_FIGURE_METHODS} methods per figure (one line each per "
            f"axes), got {len(fg.methods)}; split them over several figures",
            *at,
            "methods",
        )
    by_name = {m.name: m for m in methods}
    _unique(fg.methods, "method", *at, "methods")
    for j, name in enumerate(fg.methods):
        if name not in by_name:
            raise _fail(f"unknown method {name!r} (known: {', '.join(by_name)})", *at, "methods", j)
    allowed = {"errors": states, "local-fused": position_states, "vb-noise": ()}[fg.kind]
    _unique(fg.states, "state", *at, "states")
    for j, name in enumerate(fg.states):
        if name not in allowed:
            reason = (
                "not used with kind 'vb-noise' (its panels are the aid's measurement components)"
                if fg.kind == "vb-noise"
                else f"unknown state {name!r} (known: {', '.join(allowed)})"
            )
            raise _fail(reason, *at, "states", j)
    if fg.kind == "vb-noise":
        if fg.sensor not in sensors:
            raise _fail(
                f"required with kind 'vb-noise': one of {', '.join(sensors)}"
                if not fg.sensor
                else f"unknown sensor {fg.sensor!r} (known: {', '.join(sensors)})",
                *at,
                "sensor",
            )
        for j, name in enumerate(fg.methods):
            me = by_name[name]
            if me.adaptive_noise == "none" or (me.vb_sensors and fg.sensor not in me.vb_sensors):
                raise _fail(
                    f"method {name!r} does not estimate the noise of {fg.sensor!r}",
                    *at,
                    "methods",
                    j,
                )
    elif fg.sensor:
        raise _fail("only used with kind = 'vb-noise'", *at, "sensor")
    return FigureSpec(
        fg.name, fg.title, tuple(fg.methods), tuple(fg.states), fg.kind, fg.condition, fg.sensor
    )


def _build_figures(files: Sequence[FigureFile], **context: Any) -> tuple[FigureSpec, ...]:
    """Every ``[[figures]]`` entry (:func:`_build_figure`), names unique."""
    seen: set[str] = set()
    for i, fg in enumerate(files):
        if fg.name in seen:
            raise _fail(f"duplicate figure name {fg.name!r}", "figures", i, "name")
        seen.add(fg.name)
    return tuple(_build_figure(fg, i, **context) for i, fg in enumerate(files))


def _build(f: ScenarioFile) -> Scenario:
    model = _build_model(f.model, float(f.dt))
    sensors = []
    seen: set[str] = set()
    for i, s in enumerate(f.sensors):
        if s.name in seen:
            raise _fail(f"duplicate sensor name {s.name!r}", "sensors", i, "name")
        seen.add(s.name)
        sensors.append(_build_sensor(s, model, i))
    faults = tuple(_build_fault(x, sensors, i) for i, x in enumerate(f.faults))
    methods = []
    seen = set()
    for i, me in enumerate(f.methods):
        if me.name in seen:
            raise _fail(f"duplicate method name {me.name!r}", "methods", i, "name")
        seen.add(me.name)
        methods.append(_build_method(me, sensors, i))
    duration = f.dt * f.steps
    ev = f.evaluation
    if not ev.skip_initial < duration:
        raise _fail(f"must be less than dt*steps ({duration!r} s)", "evaluation", "skip_initial")
    figures = _build_figures(
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
        evaluation=Evaluation(float(ev.skip_initial), float(ev.grace)),
        description=f.description,
        figures=figures,
    )


# ------------------------------------------------------------------- public API


def parse_scenario(data: Mapping[str, Any], origin: str = "<scenario>") -> Scenario:
    """Validate an already-parsed scenario dictionary and build the frozen objects.

    Parameters
    ----------
    data : the TOML document as a dictionary (lists for arrays, no tuples).
    origin : where ``data`` came from; kept on the error as ``origin`` and used
        as the path of errors about the document as a whole.

    Raises
    ------
    ScenarioError : the first problem found, as one line ``<field path>: <reason>``.
    """
    if isinstance(data, Mapping) and not isinstance(data, dict):
        data = dict(data)
    try:
        spec = ScenarioFile.model_validate(data)
    except ValidationError as exc:
        raise _to_scenario_error(exc, origin) from None
    assert spec._built is not None
    return spec._built


def read_toml(source: str | Path) -> dict[str, Any]:
    """Read a TOML file; every problem is a one-line :class:`ScenarioError` naming the file."""
    path = Path(source)
    name = str(source)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ScenarioError(name, "file not found", name) from None
    except IsADirectoryError:
        raise ScenarioError(name, "is a directory, not a TOML file", name) from None
    except OSError as exc:
        raise ScenarioError(name, f"cannot read file ({exc.strerror or exc})", name) from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(name, f"not valid UTF-8 text (byte {exc.start})", name) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = _one_line(str(exc))
        where = re.fullmatch(r"(.*?)\s*\(at line (\d+), column (\d+)\)", msg)
        if where:
            reason = f"TOML syntax error at line {where[2]}, column {where[3]}: {where[1]}"
        else:
            reason = f"TOML syntax error: {msg}"
        raise ScenarioError(name, reason, name) from None


def load_scenario(source: str | Path) -> Scenario:
    """Read, validate and build the scenario in the TOML file ``source``.

    Raises
    ------
    ScenarioError : unreadable file, TOML syntax error (message names the file),
        or an invalid scenario (message ``<field path>: <reason>``).
    """
    data = read_toml(source)
    if data.get("kind") == "integrated":
        from ftnav.io.ins_scenario_file import parse_ins_scenario

        sc = parse_ins_scenario(data, origin=str(source), base=Path(source).parent)
    else:
        sc = parse_scenario(data, origin=str(source))
    return resolve_model_paths(sc, Path(source).parent)


def resolve_model_paths(sc: Scenario, base: Path) -> Scenario:
    """Make the methods' relative ``model`` paths relative to ``base`` (the file's folder)."""
    methods = tuple(
        replace(m, model=str(base / m.model)) if m.model and not Path(m.model).is_absolute() else m
        for m in sc.methods
    )
    return replace(sc, methods=methods)


def scenario_json_schema() -> dict[str, Any]:
    """JSON schema of scenario files, linear and integrated (what ``ftnav schema`` prints).

    ``oneOf`` two objects: a linear scenario (``$defs.ScenarioFile``, no ``kind`` key)
    or an integrated one (``$defs.InsScenarioFile`` of :mod:`ftnav.io.ins_scenario_file`,
    ``kind = "integrated"``).  Both forbid unknown keys, so a file matches exactly one.
    Every table of either is under ``$defs`` (``ModelFile``, ``MethodFile``, ...).
    """
    from pydantic import TypeAdapter

    from ftnav.io.ins_scenario_file import InsScenarioFile

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

    Every optional key is written out explicitly (``Q_true``, ``R_true``, all
    method keys, ``[evaluation]``), except a method's ``model`` when it is unset
    (TOML has no null), so ``parse_scenario(scenario_to_dict(sc))`` rebuilds
    ``sc`` and ``json.dumps(..., sort_keys=True)`` gives a stable hash input.
    """
    m = sc.model
    sensors = []
    for s in sc.sensors:
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
    methods = []
    for me in sc.methods:
        d = {}
        for key in Method.__dataclass_fields__:
            value = getattr(me, key)
            if isinstance(value, tuple):
                value = list(value)
            if key == "betas":
                value = [float(v) for v in value]
            if value is None:
                continue
            d[key] = value
        methods.append(d)
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
        "evaluation": {
            "skip_initial": float(sc.evaluation.skip_initial),
            "grace": float(sc.evaluation.grace),
        },
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
