"""Integrated-navigation scenario files (``kind = "integrated"``), validated with pydantic.

Same conventions as :mod:`ftnav.io.scenario_file`: TOML in, frozen
:class:`~ftnav.model.ins_scenario.InsScenario` out, every problem a one-line
:class:`~ftnav.io.scenario_file.ScenarioError` ``<field path>: <reason>``.  The
format is documented in ``docs/scenario-format.md`` ("Integrated navigation").
Units are in the key names; sensor parameters are the fields of the sensor classes
of :mod:`ftnav.sensors` and are validated by them.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, WithJsonSchema, create_model

from ftnav.io.common import (
    MAX_NOISE_FACTOR,
    STRICT,
    FileName,
    ScenarioError,
    format_loc,
    to_scenario_error,
)
from ftnav.io.profile_file import resolve_profile
from ftnav.io.sections import (
    EvaluationFile,
    FigureFile,
    MethodConfig,
    build_figures,
    explain_method_key,
    resolve_methods,
)
from ftnav.model.flight import Profile
from ftnav.model.imu import DATASHEET_KEYS, IMU_PRESETS, RANGES, ImuErrors, imu_preset
from ftnav.model.scenario import (
    METRIC_STATES,
    POSITION_NORMS,
    SINS,
    AidSpec,
    Fault,
    InsScenario,
)
from ftnav.nav.error_model import ErrorModelParams
from ftnav.sensors.ads import Barometer
from ftnav.sensors.base import AidingSensor
from ftnav.sensors.cns import StarTracker
from ftnav.sensors.dns import Doppler
from ftnav.sensors.gnss import Gnss
from ftnav.sensors.tan import Tan
from ftnav.sensors.terrain import AnalyticTerrain, GridDem, Terrain
from ftnav.types import ArrayLike

__all__ = [
    "parse_ins_scenario",
    "AID_TYPES",
    "check_aid",
    "sensor_from_table",
    "filter_model",
    "FilterModel",
    "ScenarioWarning",
    "imu_errors",
    "initial_sigma",
]

_DEG = np.pi / 180.0
_ARCSEC = _DEG / 3600.0
_DEG_H = _DEG / 3600.0
_G = 9.80665


#: every aid type of ``[[aids]]``: a new aid is its module in ftnav.sensors plus one line here
AID_CLASSES: dict[str, type] = {
    "gnss": Gnss,
    "tan": Tan,
    "dns": Doppler,
    "cns": StarTracker,
    "ads": Barometer,
}
AID_TYPES = tuple(AID_CLASSES)


class TerrainFile(BaseModel):
    """``[terrain]``: the surface TAN flies over (analytic, or a DEM grid file)."""

    model_config = STRICT
    kind: Literal["analytic", "grid"] = "analytic"
    seed: int = Field(default=7, ge=0, description="analytic: random waves from this seed")
    h0_m: float = -300.0
    amplitude_range_m: list[float] = Field(default=[10.0, 80.0], min_length=2, max_length=2)
    wavelength_range_m: list[float] = Field(default=[500.0, 5000.0], min_length=2, max_length=2)
    waves: int = Field(default=6, ge=1)
    path: str | None = Field(default=None, description="grid: .npz DEM file")
    slope: Literal["central", "plane_fit"] = "central"


class AidFile(BaseModel):
    """``[[aids]]``: type, schedule and the sensor's own parameters."""

    model_config = ConfigDict(extra="allow", strict=True, allow_inf_nan=False)
    type: Literal[AID_TYPES]  # type: ignore[valid-type]
    name: FileName | None = None
    every: int = Field(default=1, ge=1)
    offset: int = Field(default=0, ge=0)


class InsFaultFile(BaseModel):
    model_config = STRICT
    sensor: str
    kind: Literal["bias", "ramp", "noise-scale", "noise-ramp", "outage", "stuck", "gyro-bias"]
    start: float = Field(ge=0.0)
    end: float
    magnitude: list[float] | None = None
    magnitude_deg_h: list[float] | None = Field(
        default=None, description="gyro-bias: step in deg/h"
    )


_Quantity = str | float | int | list[str | float | int]

#: an IMU datasheet table: ``base`` (a preset the table starts from) and the datasheet
#: keys of :meth:`ImuErrors.from_datasheet`, each ``"<number> <unit>"`` or three of them
#: (its fields are built at run time: pydantic's field definitions, typed ``Any``)
_IMU_TABLE_FIELDS: dict[str, Any] = {
    "base": (
        Literal[tuple(IMU_PRESETS)] | None,
        Field(default=None, description="preset whose values the keys not given take"),
    ),
    **{
        key: (_Quantity | None, Field(default=None, description="'<number> <unit>' or three"))
        for key in DATASHEET_KEYS
    },
}
ImuTableFile = create_model("ImuTableFile", __config__=STRICT, **_IMU_TABLE_FIELDS)

#: an IMU: a preset name or a datasheet table (validated by :func:`imu_errors`, so that an
#: error names ``imu.<key>``; the JSON schema shows both forms)
ImuSpec = Annotated[
    str | dict[str, Any],
    WithJsonSchema(
        {"anyOf": [{"enum": list(IMU_PRESETS), "type": "string"}, ImuTableFile.model_json_schema()]}
    ),
]


def imu_errors(spec: str | Mapping[str, Any], field: str, origin: str) -> ImuErrors:
    """The :class:`ImuErrors` of a preset name or a datasheet table; errors name the key."""
    if isinstance(spec, str):
        if spec not in IMU_PRESETS:
            raise _err(
                field,
                f"unknown preset {spec!r}; valid: {', '.join(IMU_PRESETS)}, or a datasheet table",
                origin,
            )
        return imu_preset(spec)
    try:
        table = ImuTableFile.model_validate(dict(spec)).model_dump(exclude_none=True)
    except ValidationError as exc:
        inner = to_scenario_error(exc, origin)
        raise _err(f"{field}.{inner.path}", inner.reason, origin) from None
    base = table.pop("base", None)
    try:
        imu = ImuErrors.from_datasheet(
            table, base=None if base is None else imu_preset(base), field=field
        )
    except ValueError as exc:
        msg = " ".join(str(exc).split())
        path, _, reason = msg.partition(": ")
        raise _err(path, reason, origin) from None
    for key, why in imu.unusual():
        if key in table:
            warnings.warn(f"{origin}: {field}.{key}: {why}", ScenarioWarning, stacklevel=3)
    return imu


def _sigma(high: float) -> Any:
    """A σ of the initial errors: ``0 <= σ <= high``."""
    return Annotated[float, Field(ge=0.0, le=high)]


class InitialFile(BaseModel):
    """``[filter.initial]``: σ of the initial INS errors (S1 Table 1 defaults).

    Bounded where the error model stops being one: attitude and horizontal position
    36 000 arcsec (10°, the small-angle model), velocity 1 000 m/s, height 10 km.
    """

    model_config = STRICT
    attitude_arcsec: list[_sigma(36000.0)] = Field(  # type: ignore[valid-type]
        default=[300.0, 300.0, 600.0], min_length=3, max_length=3
    )
    velocity_m_s: list[_sigma(1000.0)] = Field(  # type: ignore[valid-type]
        default=[0.6, 0.6, 0.6], min_length=3, max_length=3
    )
    latlon_arcsec: list[_sigma(36000.0)] = Field(  # type: ignore[valid-type]
        default=[30.0, 30.0], min_length=2, max_length=2
    )
    height_m: float = Field(default=5.0, ge=0.0, le=1e4)


class FilterFile(BaseModel):
    model_config = STRICT
    dt: float = Field(default=1.0, gt=0.0, description="filter period, s")
    duration_s: float = Field(gt=0.0)
    correction: Literal["feedback", "output"] = "feedback"
    discretization: Literal["series", "van-loan"] = "series"
    states: Literal[18, 15, 21] = 18
    bias_frame: Literal["body", "nav"] = "body"
    bias_compensation: bool = Field(
        default=False,
        description=(
            "feedback, bias_frame body: the estimated IMU biases are fed back and "
            "subtracted from the increments before the strapdown (off: the papers feed "
            "back the navigation errors only)"
        ),
    )
    initial: InitialFile = Field(default_factory=InitialFile)
    imu: ImuSpec | None = Field(
        default=None,
        description=(
            "the IMU the filters assume (preset or datasheet table); default the true IMU"
        ),
    )


class InsScenarioFile(BaseModel):
    model_config = ConfigDict(
        extra="forbid", strict=True, allow_inf_nan=False, title="ftnav integrated scenario"
    )
    kind: Literal["integrated"]
    name: FileName
    description: str = ""
    profile: str
    test_profile: str | None = None
    imu: ImuSpec = "seed001"
    filter: FilterFile
    terrain: TerrainFile | None = None
    aids: list[AidFile] = Field(min_length=1)
    faults: list[InsFaultFile] = Field(default_factory=list)
    methods: list[MethodConfig] = Field(default_factory=list)
    evaluation: EvaluationFile = Field(default_factory=EvaluationFile)
    figures: list[FigureFile] = Field(default_factory=list)


#: the bound on the horizontal position σ an integrated model is watched against (m)
DEFAULT_SIGMA_BOUND_M = 100.0


class ScenarioWarning(UserWarning):
    """A scenario that runs, with a modelling choice its author should know about."""


def _err(path: str, reason: str, origin: str) -> ScenarioError:
    return ScenarioError(path, reason, origin)


class FilterModel(NamedTuple):
    """The filters' SINS error model derived from an IMU description (spec §8.3).

    Attributes
    ----------
    params : the error model (noise PSDs, Markov σ and τ, bias random walks).
    bias_sigma : (n − 9,) σ of the initial bias states in state units.
    notes : one line per IMU error the model cannot represent exactly, with what the
        model does instead (the scenario warns with them).
    """

    params: ErrorModelParams
    bias_sigma: np.ndarray
    notes: tuple[str, ...]


def _deg_h(x: ArrayLike) -> str:
    return f"{np.max(np.asarray(x)) / _DEG_H:.3g} deg/h"


def _ug(x: ArrayLike) -> str:
    ug = np.max(np.asarray(x)) / _G * 1e6
    return f"{ug / 1e3:.3g} mg" if ug >= 1e3 else f"{ug:.3g} ug"


def filter_model(
    imu: ImuErrors, states: int = 18, bias_frame: Literal["body", "nav"] = "body"
) -> FilterModel:
    """The default filter model of an IMU: every error term the IMU declares, represented.

    White noise: the angle and velocity random walks give the PSDs ``q_g = ARW²``,
    ``q_v = VRW²``.  Biases (constant σ = hypot(fixed value, σ of the random constant)):

    * 18 states (spec §8.3): ε_b is the gyro constant drift, ε_r the gyro Markov drift
      (σ_g, T_g) and ∇ the accelerometer Markov bias (σ_a, T_a).  The model has no
      accelerometer constant bias: one the IMU declares is folded into ∇, a Markov
      state of σ = hypot(σ_c, σ_a) and correlation time T_a (the stationary variance
      of the sum; the model lets it decorrelate, which is conservative).
    * 15 states: ε and ∇ are random constants of σ = hypot(constant, Markov σ) driven
      by random walks of PSD ``2σ²/T`` of the Markov part, the rate at which a
      first-order Markov process of σ, T wanders over times short against T (the
      random walk's variance grows without bound over longer times: conservative).
    * 21 states: the 15, and the gyro and accelerometer scale factors as random
      constants of σ ``gyro_scale_sd``, ``accel_scale_sd`` (KF-GINS's model).

    Misalignment errors have no state in any model, nor scale factors in the 15- and
    18-state models; they are named in ``notes`` (their effect grows with the angular
    rate and specific force).
    """
    notes = []
    scale = states == 21
    g_const = np.hypot(imu.gyro_bias_sd, imu.gyro_bias)
    # accelerometer scale factor and misalignment under the ~1 g specific force of flight:
    # axis i reads s_i f_i + Σ_j M_ij f_j, of variance at most g² max(σ_s,i, σ_m,i)²
    # whatever the attitude; it moves as the attitude and manoeuvres turn f_b
    a_sf = np.zeros(3) if scale else np.asarray(imu.accel_scale_sd)
    a_equiv = _G * np.maximum(a_sf, imu.accel_misalignment_sd)
    a_const = np.hypot(imu.accel_bias_sd, imu.accel_bias)
    a_markov = np.hypot(imu.accel_markov_sd, a_equiv)
    if np.any(a_equiv > 0):
        notes.append(
            f"no state for the accelerometer {'' if scale else 'scale factor and '}"
            f"misalignment: under "
            f"the ~1 g specific force they act as a bias of up to {_ug(a_equiv)} that "
            f"changes with the attitude, added to the accelerometer Markov term "
            f"(τ {np.max(imu.accel_markov_tau):g} s)"
        )
    if (not scale and np.any(np.asarray(imu.gyro_scale_sd) > 0)) or np.any(
        np.asarray(imu.gyro_misalignment_sd) > 0
    ):
        what = "misalignment" if scale else "scale factor and misalignment"
        notes.append(
            f"no state for the gyro {what}: its drift, proportional to the angular "
            "rate, is unmodelled (small at cruise, up to σ·rate in turns)"
        )
    if states == 18:
        accel_sigma = np.hypot(a_const, a_markov)
        if np.any(a_const > 0):
            notes.append(
                f"the 18-state model has no accelerometer constant-bias state: the "
                f"constant bias (σ {_ug(a_const)}) is folded into the Markov bias ∇ "
                f"(σ {_ug(accel_sigma)}, τ {np.max(imu.accel_markov_tau):g} s); "
                f"states = 15 models it as a random constant"
            )
        params = ErrorModelParams(
            gyro_psd=tuple(np.asarray(imu.gyro_arw) ** 2),
            gyro_markov_sigma=tuple(np.asarray(imu.gyro_markov_sd)),
            gyro_markov_tau=tuple(np.asarray(imu.gyro_markov_tau)),
            accel_markov_sigma=tuple(accel_sigma),
            accel_markov_tau=tuple(np.asarray(imu.accel_markov_tau)),
            accel_psd=tuple(np.asarray(imu.accel_vrw) ** 2),
            bias_frame=bias_frame,
            states=18,
        )
        bias = np.concatenate([g_const, imu.gyro_markov_sd, accel_sigma])
    else:
        g_rw = 2.0 * np.asarray(imu.gyro_markov_sd) ** 2 / np.asarray(imu.gyro_markov_tau)
        a_rw = 2.0 * a_markov**2 / np.asarray(imu.accel_markov_tau)
        if np.any(np.asarray(imu.gyro_markov_sd) > 0) or np.any(a_markov > 0):
            notes.append(
                "the 15-state model has no Markov states: the Markov terms are "
                "random walks of PSD 2σ²/τ on the bias states (conservative over "
                "times longer than τ); states = 18 models them"
            )
        params = ErrorModelParams(
            gyro_psd=tuple(np.asarray(imu.gyro_arw) ** 2),
            accel_psd=tuple(np.asarray(imu.accel_vrw) ** 2),
            gyro_bias_rw_psd=tuple(g_rw),
            accel_bias_rw_psd=tuple(a_rw),
            bias_frame=bias_frame,
            states=21 if scale else 15,
        )
        bias = np.concatenate([np.hypot(g_const, imu.gyro_markov_sd), np.hypot(a_const, a_markov)])
        if scale:
            bias = np.concatenate([bias, imu.gyro_scale_sd, imu.accel_scale_sd])
    return FilterModel(params, bias, tuple(notes))


def initial_sigma(init: InitialFile, bias_sigma: np.ndarray) -> np.ndarray:
    """(n,) σ of the initial errors: navigation from ``[filter.initial]``, then the biases."""
    nav = np.concatenate(
        [
            np.asarray(init.attitude_arcsec) * _ARCSEC,
            np.asarray(init.velocity_m_s),
            np.asarray(init.latlon_arcsec) * _ARCSEC,
            [init.height_m],
        ]
    )
    # a zero σ would make P0 singular; keep a tiny floor (the state is then known)
    sigma: np.ndarray = np.maximum(np.concatenate([nav, bias_sigma]), 1e-12)
    return sigma


def _terrain(
    t: TerrainFile, origin_lat: float, origin_lon: float, base: Path, origin: str
) -> Terrain:
    if t.kind == "grid":
        if not t.path:
            raise _err("terrain.path", "required with kind = 'grid'", origin)
        path = Path(t.path) if Path(t.path).is_absolute() else base / t.path
        try:
            return GridDem.from_npz(path, slope=t.slope)
        except (OSError, ValueError) as exc:
            raise _err("terrain.path", str(exc), origin) from None
    rng = np.random.default_rng(t.seed)
    return AnalyticTerrain.random(
        rng,
        origin_lat_deg=origin_lat,
        origin_lon_deg=origin_lon,
        n_waves=t.waves,
        h0_m=t.h0_m,
        amplitude_range_m=(t.amplitude_range_m[0], t.amplitude_range_m[1]),
        wavelength_range_m=(t.wavelength_range_m[0], t.wavelength_range_m[1]),
    )


class _AidRange(NamedTuple):
    """Plausibility of an aid parameter of one unit (by its name's suffix): |x| at most
    ``high``; a σ also either 0 or at least ``sigma_low``, and warned above ``usual``."""

    unit: str
    high: float
    sigma_low: float
    usual: float


#: unit suffix of an aid parameter's name -> plausible range; docs/scenario-format.md
AID_RANGES: dict[str, _AidRange] = {
    "_m_s": _AidRange("m/s", 1e4, 1e-5, 100.0),  # faster than orbit: no aid
    "_m": _AidRange("m", 1e7, 1e-4, 1e4),  # the size of the Earth
    "_arcsec": _AidRange("arcsec", 1.296e6, 1e-3, 3600.0),  # a full turn
    "_s": _AidRange("s", 1e9, 0.0, np.inf),  # correlation times: 30 years
    "": _AidRange("", 1.0, 0.0, 0.1),  # dimensionless σ (a scale factor): 100 %
}


def _aid_range(key: str) -> _AidRange | None:
    """The range of a numeric aid parameter, None for one that is not a quantity."""
    if key == "min_slope":
        return AID_RANGES[""]._replace(usual=np.inf)
    for suffix in ("_m_s", "_m", "_arcsec", "_s"):
        if key.endswith(suffix):
            return AID_RANGES[suffix]
    return AID_RANGES[""] if "sigma" in key else None


def check_aid(sensor: AidingSensor, given: Mapping[str, Any], path: str, origin: str) -> None:
    """Refuse implausible parameters (:data:`AID_RANGES`), warn of unusual σ, and refuse
    an aid whose assumed measurement noise R is not positive definite (a σ of 0)."""
    for key in given:
        r = _aid_range(key)
        value = getattr(sensor, key, None)
        if r is None or value is None or isinstance(value, bool | str):
            continue
        a = np.abs(np.asarray(value, dtype=float))
        unit = f" {r.unit}" if r.unit else ""
        if a.max() > r.high:
            raise _err(
                f"{path}.{key}",
                f"implausibly large ({a.max():.3g}{unit}; at most {r.high:.3g}{unit})",
                origin,
            )
        if "sigma" not in key and key.endswith("_tau_s") and a.min() < 1e-3:
            raise _err(
                f"{path}.{key}", f"implausibly small ({a.min():.3g} s; at least 0.001 s)", origin
            )
        if "sigma" in key:
            tiny = (a > 0) & (a < r.sigma_low)
            if tiny.any():
                raise _err(
                    f"{path}.{key}",
                    f"implausibly small σ ({a[tiny].min():.3g}{unit}; 0 or at least "
                    f"{r.sigma_low:g}{unit}: the filters lose it to rounding)",
                    origin,
                )
            if a.max() > r.usual:
                warnings.warn(
                    f"{origin}: {path}.{key}: σ {a.max():.3g}{unit} is beyond any real "
                    f"aid (above {r.usual:g}{unit}): a unit mistake?",
                    ScenarioWarning,
                    stacklevel=3,
                )
    R = np.asarray(sensor.R, dtype=float)
    sd = np.sqrt(np.clip(np.diagonal(R), 0.0, None))
    try:
        np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        rows = [c for c, v in zip(sensor.components, sd, strict=True) if not v > 0]
        raise _err(
            path,
            f"the measurement noise the filters assume is not positive definite (σ of "
            f"{', '.join(rows) or 'a combination of rows'} is 0): give the white-noise "
            "σ (or the assumed σ) a value > 0",
            origin,
        ) from None


def sensor_from_table(
    kind: str,
    params: Mapping[str, Any],
    path: str,
    origin: str,
    terrain: Terrain | None = None,
    dt: float = 1.0,
) -> AidingSensor:
    """Build one sensor (of the class :data:`AID_CLASSES` names) from its TOML table;
    errors name ``path.<field>``."""
    cls = AID_CLASSES[kind]
    fields = {f.name for f in dataclasses.fields(cls)}
    kw = dict(params)
    for key in kw:
        if key not in fields or key in ("terrain",):
            raise _err(
                f"{path}.{key}",
                f"unknown parameter of a {kind} sensor (known: "
                f"{', '.join(sorted(fields - {'terrain'}))})",
                origin,
            )
    for key, value in kw.items():
        if isinstance(value, list):
            kw[key] = tuple(value)
    if kind == "tan":
        kw["terrain"] = terrain
    kw.setdefault("dt", dt)
    try:
        sensor: AidingSensor = cls(**kw)
    except (TypeError, ValueError) as exc:
        msg = " ".join(str(exc).split())
        m = re.match(r"^[\w.]*?(\w+): (.*)$", msg)
        if m and m.group(1) in fields:
            raise _err(f"{path}.{m.group(1)}", m.group(2), origin) from None
        raise _err(path, msg, origin) from None
    return sensor


#: a bias or ramp fault this many times its aid's σ is warned about (a unit slip: 2 rad
#: for 2 deg is 40 000 times a star tracker's 10″)
LARGE_FAULT_SIGMAS = 1e3


def _offset_range(component: str) -> tuple[str, float]:
    """Unit and largest |offset| of a fault on a measurement row (by the row's name):
    velocities 1e4 m/s, angles π rad (star tracker), lengths 1e7 m (the Earth's size)."""
    if component.startswith("vel"):
        return "m/s", 1e4
    if component.startswith("phi") or component in ("pitch", "roll", "yaw"):
        return "rad", float(np.pi)
    return "m", 1e7


def parse_ins_scenario(
    data: Mapping[str, Any],
    origin: str = "<scenario>",
    base: Path | None = None,
    models: bool = True,
) -> InsScenario:
    """Validate an integrated scenario dictionary and build the frozen objects.

    ``base`` is the folder relative paths (profiles, DEMs, model files) are relative to;
    ``models=False`` loads no trained model (see :func:`ftnav.io.sections.resolve_methods`).
    """
    base = base or Path(".")
    try:
        f = InsScenarioFile.model_validate(dict(data))
    except ValidationError as exc:
        raise to_scenario_error(exc, origin, InsScenarioFile, explain_method_key) from None

    def profile(key: str, value: str) -> Profile:
        try:
            cand = base / value
            return resolve_profile(str(cand) if cand.exists() else value)
        except (ValueError, OSError) as exc:
            raise _err(key, " ".join(str(exc).split()), origin) from None

    prof = profile("profile", f.profile)
    test_prof = profile("test_profile", f.test_profile) if f.test_profile else None
    imu = imu_errors(f.imu, "imu", origin)
    assumed = imu if f.filter.imu is None else imu_errors(f.filter.imu, "filter.imu", origin)
    fl = f.filter
    steps = int(round(fl.duration_s / fl.dt))
    if steps < 1:
        raise _err(
            "filter.dt",
            f"{fl.dt:g} s is longer than the flight (filter.duration_s {fl.duration_s:g} s): "
            "no filter epoch",
            origin,
        )
    spe = fl.dt / prof.dt
    if abs(spe - round(spe)) > 1e-9 or round(spe) % 2:
        raise _err("filter.dt", f"must be an even number of IMU periods ({prof.dt} s)", origin)
    if steps * fl.dt > prof.duration + 1e-9:
        raise _err("filter.duration_s", f"longer than the profile ({prof.duration} s)", origin)
    lat0, lon0 = (float(np.degrees(a)) for a in prof.start.position[:2])
    terrain = None
    tan = [i for i, a in enumerate(f.aids) if a.type == "tan"]
    if tan:
        if f.terrain is None:
            raise _err(
                "terrain",
                f"required by the TAN aid aids[{tan[0]}]: the surface it "
                f"flies over (kind = 'analytic' or 'grid', docs/scenario-format.md)",
                origin,
            )
        terrain = _terrain(f.terrain, lat0, lon0, base, origin)
    aids, names = [], []
    for i, a in enumerate(f.aids):
        extra = dict(a.model_extra or {})
        name = a.name or a.type
        if name in names or name == SINS:
            raise _err(f"aids[{i}].name", f"duplicate or reserved name {name!r}", origin)
        names.append(name)
        # errors are simulated and private states propagated at every filter epoch; the
        # schedule (every, offset) only masks the epochs without output
        s = sensor_from_table(a.type, {"name": name, **extra}, f"aids[{i}]", origin, terrain, fl.dt)
        check_aid(s, extra, f"aids[{i}]", origin)
        try:
            aids.append(AidSpec(s, a.every, a.offset))
        except ValueError as exc:
            raise _err(f"aids[{i}].every", str(exc).split(": ", 1)[1], origin) from None
    faults = []
    for i, x in enumerate(f.faults):
        p = f"faults[{i}]"
        if x.sensor != SINS and x.sensor not in names:
            raise _err(
                f"{p}.sensor",
                f"unknown sensor {x.sensor!r} (known: {', '.join([*names, SINS])})",
                origin,
            )
        if not x.end > x.start:
            raise _err(f"{p}.end", "must be greater than start", origin)
        if not x.start < steps * fl.dt:
            raise _err(
                f"{p}.start",
                f"{x.start:g} s is not before the end of the flight "
                f"({steps * fl.dt:g} s, filter.duration_s): the fault would never act",
                origin,
            )
        if x.end > steps * fl.dt + 1e-9:
            warnings.warn(
                f"{origin}: {p}.end: {x.end:g} s is after the end of the flight "
                f"({steps * fl.dt:g} s, filter.duration_s): the fault is cut there",
                ScenarioWarning,
                stacklevel=2,
            )
        if (x.kind == "gyro-bias") != (x.sensor == SINS):
            raise _err(
                f"{p}.kind",
                "'gyro-bias' is the only fault of the SINS and applies only to it",
                origin,
            )
        if x.kind == "gyro-bias":
            if x.magnitude_deg_h is None or len(x.magnitude_deg_h) != 3:
                raise _err(f"{p}.magnitude_deg_h", "three values (deg/h) required", origin)
            mag = np.asarray(x.magnitude_deg_h, float) * _DEG_H
        else:
            m = aids[names.index(x.sensor)].dim
            if x.kind in ("noise-scale", "noise-ramp"):
                if x.magnitude is None or len(x.magnitude) != 1 or not x.magnitude[0] > 0:
                    raise _err(f"{p}.magnitude", "one positive noise-std factor required", origin)
                mag = np.asarray(x.magnitude, float)
            elif x.kind in ("bias", "ramp"):
                if x.magnitude is None or len(x.magnitude) != m:
                    raise _err(
                        f"{p}.magnitude",
                        f"expected {m} values "
                        f"({', '.join(aids[names.index(x.sensor)].sensor.components)})",
                        origin,
                    )
                mag = np.asarray(x.magnitude, float)
            else:
                mag = np.zeros(0)
        if not np.all(np.isfinite(mag)):
            raise _err(f"{p}.magnitude", "must be finite", origin)
        if x.kind == "gyro-bias" and np.abs(mag).max() > RANGES["angular_rate"].high:
            raise _err(
                f"{p}.magnitude_deg_h",
                f"implausibly large (at most {RANGES['angular_rate'].high / _DEG_H:g} deg/h)",
                origin,
            )
        if x.kind in ("noise-scale", "noise-ramp") and mag[0] > MAX_NOISE_FACTOR:
            raise _err(f"{p}.magnitude", f"must be at most {MAX_NOISE_FACTOR:g}", origin)
        if x.kind in ("bias", "ramp"):
            sensor = aids[names.index(x.sensor)].sensor
            sigma = np.sqrt(np.diag(sensor.R))
            for j, (c, v) in enumerate(zip(sensor.components, mag, strict=True)):
                unit, high = _offset_range(c)
                if abs(v) > high:
                    raise _err(
                        f"{p}.magnitude[{j}]",
                        f"implausibly large offset of {c} ({v:.3g} {unit}; at most "
                        f"{high:.3g} {unit})",
                        origin,
                    )
                if sigma[j] > 0 and abs(v) > LARGE_FAULT_SIGMAS * sigma[j]:
                    warnings.warn(
                        f"{origin}: {p}.magnitude[{j}]: {v:.3g} {unit} is "
                        f"{abs(v) / sigma[j]:.3g} times the σ of {c} ({sigma[j]:.3g} {unit}): "
                        "any test sees it at once; is the unit right (rad, not deg)?",
                        ScenarioWarning,
                        stacklevel=2,
                    )
        faults.append(Fault(x.sensor, x.kind, float(x.start), float(x.end), mag))
    methods = list(f.methods)
    ev = f.evaluation
    if not ev.skip_initial < steps * fl.dt:
        raise _err("evaluation.skip_initial", "must be less than the duration", origin)
    try:
        figures = build_figures(
            f.figures,
            states=METRIC_STATES + POSITION_NORMS,
            methods=methods,
            sensors=names,
            kinds=("errors", "local-fused", "vb-noise"),
            position_states=METRIC_STATES[:3],
            second_flight=f.test_profile is not None,
        )
    except Exception as exc:  # pydantic custom error outside validation
        ctx = getattr(exc, "context", None) or {}
        raise _err(format_loc(ctx.get("path", ())) or "figures", str(exc), origin) from None
    if fl.bias_compensation and (fl.bias_frame != "body" or fl.correction != "feedback"):
        raise _err(
            "filter.bias_compensation",
            "needs correction 'feedback' and bias_frame 'body' (the biases are fed back "
            "and subtracted in the body frame)",
            origin,
        )
    if fl.states == 21 and fl.bias_frame != "body":
        raise _err(
            "filter.states",
            "21 needs bias_frame 'body' (a scale factor acts on a body axis)",
            origin,
        )
    model = filter_model(assumed, fl.states, fl.bias_frame)
    field = "imu" if f.filter.imu is None else "filter.imu"
    for note in model.notes:
        warnings.warn(f"{origin}: {field}: {note}", ScenarioWarning, stacklevel=2)
    sc = InsScenario(
        name=f.name,
        profile=prof,
        imu=imu,
        error_model=model.params,
        initial_sigma=initial_sigma(fl.initial, model.bias_sigma),
        model_notes=model.notes,
        dt=float(fl.dt),
        steps=steps,
        aids=tuple(aids),
        faults=tuple(faults),
        methods=tuple(methods),
        evaluation=ev.settings(DEFAULT_SIGMA_BOUND_M),
        correction=fl.correction,
        bias_compensation=fl.bias_compensation,
        discretization=fl.discretization,
        description=f.description,
        test_profile=test_prof,
        figures=figures,
    )
    return replace(sc, learned=resolve_methods(sc.methods, sc.system(), base, origin, models))
