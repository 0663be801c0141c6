"""Integrated-navigation scenario files (``kind = "integrated"``), validated with pydantic.

Same conventions as :mod:`ftnav.io.scenario_file`: TOML in, frozen
:class:`~ftnav.sim.ins_scenario.InsScenario` out, every problem a one-line
:class:`~ftnav.io.scenario_file.ScenarioError` ``<field path>: <reason>``.  The
format is documented in ``docs/scenario-format.md`` ("Integrated navigation").
Units are in the key names; sensor parameters are the fields of the sensor classes
of :mod:`ftnav.sensors` and are validated by them.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ftnav.io.scenario_file import (
    EvaluationFile,
    FigureFile,
    MethodFile,
    ScenarioError,
    _build_figures,
    _build_method,
    _format_loc,
    _to_scenario_error,
)
from ftnav.nav.error_model import ErrorModelParams
from ftnav.sim.imu import ImuErrors, imu_preset
from ftnav.sim.ins_scenario import (
    METRIC_STATES,
    POSITION_NORMS,
    SINS,
    AidSpec,
    InsFault,
    InsScenario,
)
from ftnav.sim.scenario import Evaluation

__all__ = ["parse_ins_scenario", "AID_TYPES", "sensor_from_table", "matched_error_model",
           "initial_sigma"]

_STRICT = ConfigDict(extra="forbid", strict=True)
_DEG = np.pi / 180.0
_ARCSEC = _DEG / 3600.0
_DEG_H = _DEG / 3600.0
_G = 9.80665


_AID_CLASSES = {"gnss": ("gnss", "Gnss"), "tan": ("tan", "Tan"), "dns": ("dns", "Doppler"),
                "cns": ("cns", "StarTracker"), "ads": ("ads", "Barometer")}
AID_TYPES = tuple(_AID_CLASSES)


def _aid_class(kind: str) -> type:
    import importlib

    module, cls = _AID_CLASSES[kind]
    return getattr(importlib.import_module(f"ftnav.sensors.{module}"), cls)




class TerrainFile(BaseModel):
    """``[terrain]``: the surface TAN flies over (analytic, or a DEM grid file)."""

    model_config = _STRICT
    kind: Literal["analytic", "grid"] = "analytic"
    seed: int = Field(default=7, ge=0, description="analytic: random waves from this seed")
    h0_m: float = -300.0
    amplitude_range_m: list[float] = Field(default=[10.0, 80.0], min_length=2, max_length=2)
    wavelength_range_m: list[float] = Field(default=[500.0, 5000.0], min_length=2,
                                            max_length=2)
    waves: int = Field(default=6, ge=1)
    path: str | None = Field(default=None, description="grid: .npz DEM file")
    slope: Literal["central", "plane_fit"] = "central"


class AidFile(BaseModel):
    """``[[aids]]``: type, schedule and the sensor's own parameters."""

    model_config = ConfigDict(extra="allow", strict=True)
    type: Literal["gnss", "tan", "dns", "cns", "ads"]
    name: str | None = None
    every: int = Field(default=1, ge=1)
    offset: int = Field(default=0, ge=0)


class InsFaultFile(BaseModel):
    model_config = _STRICT
    sensor: str
    kind: Literal["bias", "ramp", "noise-scale", "noise-ramp", "outage", "stuck",
                  "gyro-bias"]
    start: float = Field(ge=0.0)
    end: float
    magnitude: list[float] | None = None
    magnitude_deg_h: list[float] | None = Field(default=None,
                                                description="gyro-bias: step in deg/h")


class InitialFile(BaseModel):
    """``[filter.initial]``: σ of the initial INS errors (S1 Table 1 defaults)."""

    model_config = _STRICT
    attitude_arcsec: list[float] = Field(default=[300.0, 300.0, 600.0], min_length=3,
                                         max_length=3)
    velocity_m_s: list[float] = Field(default=[0.6, 0.6, 0.6], min_length=3, max_length=3)
    latlon_arcsec: list[float] = Field(default=[30.0, 30.0], min_length=2, max_length=2)
    height_m: float = Field(default=5.0, ge=0.0)


class FilterFile(BaseModel):
    model_config = _STRICT
    dt: float = Field(default=1.0, gt=0.0, description="filter period, s")
    duration_s: float = Field(gt=0.0)
    correction: Literal["feedback", "output"] = "feedback"
    discretization: Literal["series", "van-loan"] = "series"
    states: Literal[18, 15] = 18
    bias_frame: Literal["body", "nav"] = "body"
    initial: InitialFile = Field(default_factory=InitialFile)


class InsScenarioFile(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, title="ftnav integrated scenario")
    kind: Literal["integrated"]
    name: str
    description: str = ""
    profile: str
    test_profile: str | None = None
    imu: str | dict[str, Any] = "seed001"
    filter: FilterFile
    terrain: TerrainFile | None = None
    aids: list[AidFile] = Field(min_length=1)
    faults: list[InsFaultFile] = Field(default_factory=list)
    methods: list[MethodFile] = Field(default_factory=list)
    evaluation: EvaluationFile = Field(default_factory=EvaluationFile)
    figures: list[FigureFile] = Field(default_factory=list)


def _err(path: str, reason: str, origin: str) -> ScenarioError:
    return ScenarioError(path, reason, origin)


def matched_error_model(imu: ImuErrors, states: int = 18, bias_frame: str = "body"
                        ) -> ErrorModelParams:
    """The filters' error model matched to the true IMU errors (spec §8.3)."""
    return ErrorModelParams(
        gyro_psd=tuple(np.asarray(imu.gyro_arw) ** 2),
        gyro_markov_sigma=tuple(imu.gyro_markov_sd), gyro_markov_tau=tuple(imu.gyro_markov_tau),
        accel_markov_sigma=tuple(imu.accel_markov_sd),
        accel_markov_tau=tuple(imu.accel_markov_tau),
        accel_psd=tuple(np.asarray(imu.accel_vrw) ** 2), bias_frame=bias_frame, states=states)


def initial_sigma(init: InitialFile, imu: ImuErrors, lat_rad: float, states: int = 18
                  ) -> np.ndarray:
    """(n,) σ of the initial errors: navigation from ``[filter.initial]``, biases from the IMU.

    The bias states start at their a-priori σ (random-constant drift, Markov σ).
    """
    nav = np.concatenate([np.asarray(init.attitude_arcsec) * _ARCSEC,
                          np.asarray(init.velocity_m_s),
                          np.asarray(init.latlon_arcsec) * _ARCSEC, [init.height_m]])
    gb = np.hypot(np.asarray(imu.gyro_bias_sd), np.asarray(imu.gyro_bias))
    if states == 18:
        rest = np.concatenate([gb, imu.gyro_markov_sd, imu.accel_markov_sd])
    else:
        ab = np.hypot(np.asarray(imu.accel_bias_sd), np.asarray(imu.accel_markov_sd))
        rest = np.concatenate([np.hypot(gb, imu.gyro_markov_sd), ab])
    # a zero σ would make P0 singular; keep a tiny floor (the state is then known)
    return np.maximum(np.concatenate([nav, rest]), 1e-12)


def _terrain(t: TerrainFile | None, origin_lat: float, origin_lon: float, base: Path,
             origin: str):
    from ftnav.sensors.terrain import AnalyticTerrain, GridDem

    t = t or TerrainFile()
    if t.kind == "grid":
        if not t.path:
            raise _err("terrain.path", "required with kind = 'grid'", origin)
        path = Path(t.path) if Path(t.path).is_absolute() else base / t.path
        try:
            return GridDem.from_npz(path, slope=t.slope)
        except (OSError, ValueError) as exc:
            raise _err("terrain.path", str(exc), origin) from None
    rng = np.random.default_rng(t.seed)
    return AnalyticTerrain.random(rng, origin_lat_deg=origin_lat, origin_lon_deg=origin_lon,
                                  n_waves=t.waves, h0_m=t.h0_m,
                                  amplitude_range_m=tuple(t.amplitude_range_m),
                                  wavelength_range_m=tuple(t.wavelength_range_m))


def sensor_from_table(kind: str, params: Mapping[str, Any], path: str, origin: str,
                      terrain=None, dt: float = 1.0):
    """Build one sensor from its TOML table; errors name ``path.<field>``."""
    cls = _aid_class(kind)
    fields = {f.name for f in dataclasses.fields(cls)}
    kw = dict(params)
    for key in kw:
        if key not in fields or key in ("terrain",):
            raise _err(f"{path}.{key}", f"unknown parameter of a {kind} sensor (known: "
                       f"{', '.join(sorted(fields - {'terrain'}))})", origin)
    for key, value in kw.items():
        if isinstance(value, list):
            kw[key] = tuple(value)
    if kind == "tan":
        kw["terrain"] = terrain
    kw.setdefault("dt", dt)
    try:
        return cls(**kw)
    except (TypeError, ValueError) as exc:
        msg = " ".join(str(exc).split())
        m = re.match(r"^[\w.]*?(\w+): (.*)$", msg)
        if m and m.group(1) in fields:
            raise _err(f"{path}.{m.group(1)}", m.group(2), origin) from None
        raise _err(path, msg, origin) from None


def parse_ins_scenario(data: Mapping[str, Any], origin: str = "<scenario>",
                       base: Path | None = None) -> InsScenario:
    """Validate an integrated scenario dictionary and build the frozen objects."""
    from ftnav.io.profile_file import resolve_profile

    base = base or Path(".")
    try:
        f = InsScenarioFile.model_validate(dict(data))
    except ValidationError as exc:
        raise _to_scenario_error(exc, origin) from None

    def profile(key: str, value: str):
        try:
            cand = base / value
            return resolve_profile(str(cand) if cand.exists() else value)
        except (ValueError, OSError) as exc:
            raise _err(key, " ".join(str(exc).split()), origin) from None

    prof = profile("profile", f.profile)
    test_prof = profile("test_profile", f.test_profile) if f.test_profile else None
    try:
        imu = imu_preset(f.imu) if isinstance(f.imu, str) else ImuErrors.from_datasheet(**f.imu)
    except (TypeError, ValueError) as exc:
        raise _err("imu", " ".join(str(exc).split()), origin) from None
    fl = f.filter
    steps = int(round(fl.duration_s / fl.dt))
    spe = fl.dt / prof.dt
    if abs(spe - round(spe)) > 1e-9 or round(spe) % 2:
        raise _err("filter.dt", f"must be an even number of IMU periods ({prof.dt} s)", origin)
    if steps * fl.dt > prof.duration + 1e-9:
        raise _err("filter.duration_s", f"longer than the profile ({prof.duration} s)", origin)
    lat0, lon0 = (float(np.degrees(a)) for a in prof.start.position[:2])
    terrain = None
    if any(a.type == "tan" for a in f.aids):
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
        s = sensor_from_table(a.type, {"name": name, **extra}, f"aids[{i}]", origin, terrain,
                              fl.dt)
        try:
            aids.append(AidSpec(s, a.every, a.offset))
        except ValueError as exc:
            raise _err(f"aids[{i}].every", str(exc).split(": ", 1)[1], origin) from None
    faults = []
    for i, x in enumerate(f.faults):
        p = f"faults[{i}]"
        if x.sensor != SINS and x.sensor not in names:
            raise _err(f"{p}.sensor", f"unknown sensor {x.sensor!r} (known: "
                       f"{', '.join([*names, SINS])})", origin)
        if not x.end > x.start:
            raise _err(f"{p}.end", "must be greater than start", origin)
        if (x.kind == "gyro-bias") != (x.sensor == SINS):
            raise _err(f"{p}.kind", "'gyro-bias' is the only fault of the SINS and applies "
                       "only to it", origin)
        if x.kind == "gyro-bias":
            if x.magnitude_deg_h is None or len(x.magnitude_deg_h) != 3:
                raise _err(f"{p}.magnitude_deg_h", "three values (deg/h) required", origin)
            mag = np.asarray(x.magnitude_deg_h, float) * _DEG_H
        else:
            m = aids[names.index(x.sensor)].dim
            if x.kind in ("noise-scale", "noise-ramp"):
                if x.magnitude is None or len(x.magnitude) != 1 or not x.magnitude[0] > 0:
                    raise _err(f"{p}.magnitude", "one positive noise-std factor required",
                               origin)
                mag = np.asarray(x.magnitude, float)
            elif x.kind in ("bias", "ramp"):
                if x.magnitude is None or len(x.magnitude) != m:
                    raise _err(f"{p}.magnitude", f"expected {m} values "
                               f"({', '.join(aids[names.index(x.sensor)].sensor.components)})",
                               origin)
                mag = np.asarray(x.magnitude, float)
            else:
                mag = np.zeros(0)
        if not np.all(np.isfinite(mag)):
            raise _err(f"{p}.magnitude", "must be finite", origin)
        faults.append(InsFault(x.sensor, x.kind, float(x.start), float(x.end), mag))
    methods, seen = [], set()
    for i, me in enumerate(f.methods):
        if me.name in seen:
            raise _err(f"methods[{i}].name", f"duplicate method name {me.name!r}", origin)
        seen.add(me.name)
        try:
            methods.append(_build_method(me, aids, i))
        except Exception as exc:  # pydantic custom error outside validation
            ctx = getattr(exc, "context", None) or {}
            path = _format_loc(ctx.get("path", ()))
            raise _err(path or f"methods[{i}]", str(exc), origin) from None
    ev = f.evaluation
    if not ev.skip_initial < steps * fl.dt:
        raise _err("evaluation.skip_initial", "must be less than the duration", origin)
    try:
        figures = _build_figures(f.figures, states=METRIC_STATES + POSITION_NORMS,
                                 methods=methods, sensors=names,
                                 kinds=("errors", "local-fused", "vb-noise"),
                                 position_states=METRIC_STATES[:3])
    except Exception as exc:  # pydantic custom error outside validation
        ctx = getattr(exc, "context", None) or {}
        raise _err(_format_loc(ctx.get("path", ())) or "figures", str(exc), origin) from None
    sigma = initial_sigma(fl.initial, imu, np.radians(lat0), fl.states)
    return InsScenario(
        name=f.name, profile=prof, imu=imu,
        error_model=matched_error_model(imu, fl.states, fl.bias_frame),
        initial_sigma=sigma, dt=float(fl.dt), steps=steps, aids=tuple(aids),
        faults=tuple(faults), methods=tuple(methods),
        evaluation=Evaluation(float(ev.skip_initial), float(ev.grace)),
        correction=fl.correction, discretization=fl.discretization,
        description=f.description, test_profile=test_prof, figures=figures)

