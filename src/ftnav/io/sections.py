"""Sections shared by linear and integrated scenario files: methods, figures, evaluation.

``[[methods]]`` (the fusion methods to compare), ``[[figures]]`` (the figures a run
draws) and ``[evaluation]`` (metric settings) read the same in both kinds of file;
the builders turn them into the frozen :mod:`ftnav.model.scenario` containers,
every problem a one-line :class:`~ftnav.io.common.ScenarioError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Annotated, Any

from pydantic import BaseModel, Field

from ftnav.io.common import SHARE_TOL, STRICT, Name, fail, number, unique
from ftnav.model.scenario import (
    MAX_FIGURE_METHODS,
    AdaptiveNoise,
    Architecture,
    CommonMode,
    Detector,
    FigureCondition,
    FigureKind,
    FigureSpec,
    Increment,
    Isolation,
    Method,
    Mode,
    Prior,
    Sensor,
    Sharing,
    TraceMode,
)

__all__ = ["EvaluationFile", "FigureFile", "MethodFile", "build_figures", "build_method"]

_M = Method.__dataclass_fields__


def _d(key: str) -> Any:
    """Default of a Method dataclass field."""
    return _M[key].default


class MethodFile(BaseModel):
    """``[[methods]]``: one fusion method; every key but ``name`` is optional."""

    model_config = STRICT

    name: Name = Field(description="unique method name")
    architecture: Architecture = Field(default=_d("architecture"))
    mode: Mode = Field(default=_d("mode"), description="information reset mode")
    reset_interval: int = Field(default=_d("reset_interval"), ge=1)
    sharing: Sharing = Field(default=_d("sharing"), description="information-sharing rule")
    betas: list[Annotated[float, Field(ge=0.0, allow_inf_nan=False)]] = Field(
        default=[], description="sharing = 'fixed' only: one factor per sensor"
    )
    master_share: float = number("master filter's share", default=_d("master_share"), ge=0, lt=1)
    trace_mode: TraceMode = Field(default=_d("trace_mode"))
    detector: Detector = Field(default=_d("detector"))
    false_alarm_probability: float = number(
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
    vb_rho: float = number("VB forgetting factor", default=_d("vb_rho"), gt=0, le=1)
    vb_iterations: int = Field(default=_d("vb_iterations"), ge=1)
    vb_sensors: list[Name] = Field(default=[], description="sensors with VB; empty = all")
    increment: Increment = Field(default=_d("increment"))
    reconstructed: bool = Field(default=_d("reconstructed"))
    rescale_factor: float = number(
        "information scale of the rescale mode", default=_d("rescale_factor"), ge=0, lt=1
    )
    model: str | None = Field(
        default=_d("model"),
        description="trained model file (detector 'rbf' or architecture 'neural'); a relative "
        "path is relative to the scenario file",
    )
    threshold: float | None = number(
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

    model_config = STRICT

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

    model_config = STRICT

    skip_initial: float = number(
        "initial convergence period left out of metrics (s)", default=0.0, ge=0
    )
    grace: float = number("post-fault grace period (s)", default=10.0, ge=0)


def build_method(me: MethodFile, sensors: Sequence[Sensor], i: int) -> Method:
    names = [s.name for s in sensors]
    if me.sharing == "fixed":
        if len(me.betas) != len(sensors):
            raise fail(
                f"expected {len(sensors)} values (one per sensor) with sharing = 'fixed', "
                f"got {len(me.betas)}",
                "methods",
                i,
                "betas",
            )
        total = math.fsum(me.betas) + me.master_share
        if abs(total - 1.0) > SHARE_TOL:
            raise fail(
                f"sum(betas) + master_share must equal 1, got {total!r}", "methods", i, "betas"
            )
    elif me.betas:
        raise fail(
            f"must be empty unless sharing = 'fixed' (sharing is {me.sharing!r})",
            "methods",
            i,
            "betas",
        )
    unique(me.vb_sensors, "sensor", "methods", i, "vb_sensors")
    for j, name in enumerate(me.vb_sensors):
        if name not in names:
            raise fail(
                f"unknown sensor {name!r} (known: {', '.join(names)})",
                "methods",
                i,
                "vb_sensors",
                j,
            )
    needs_model = me.detector == "rbf" or me.architecture == "neural"
    if needs_model and me.model is None:
        what = "detector 'rbf'" if me.detector == "rbf" else "architecture 'neural'"
        raise fail(f"{what} needs a trained model file", "methods", i, "model")
    if me.model is not None and not needs_model:
        raise fail(
            "only used with detector = 'rbf' or architecture = 'neural'", "methods", i, "model"
        )
    if me.common_mode_quorum is not None:
        if me.common_mode != "keep":
            raise fail(
                f"only used with common_mode = 'keep' (common_mode is {me.common_mode!r})",
                "methods",
                i,
                "common_mode_quorum",
            )
        if me.common_mode_quorum > len(sensors):
            raise fail(
                f"must be <= the number of sensors ({len(sensors)})",
                "methods",
                i,
                "common_mode_quorum",
            )
    if me.prior == "intersection" and me.architecture != "neural":
        raise fail(
            "'intersection' (covariance intersection of the local priors) is only "
            "used with architecture = 'neural'",
            "methods",
            i,
            "prior",
        )
    if me.mode == "rescale" and not me.reconstructed:
        raise fail(
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
        raise fail(
            "must be a file name without extension (letters, digits, '_', '-', '.')", *at, "name"
        )
    if fg.name in _RESERVED_FIGURES:
        raise fail(f"{fg.name!r} is reserved (the run writes {fg.name}.png itself)", *at, "name")
    if fg.kind not in kinds:
        raise fail(
            f"kind {fg.kind!r} needs an integrated scenario (here: {', '.join(kinds)})", *at, "kind"
        )
    if len(fg.methods) > MAX_FIGURE_METHODS:
        raise fail(
            f"at most {MAX_FIGURE_METHODS} methods per figure (one line each per "
            f"axes), got {len(fg.methods)}; split them over several figures",
            *at,
            "methods",
        )
    by_name = {m.name: m for m in methods}
    unique(fg.methods, "method", *at, "methods")
    for j, name in enumerate(fg.methods):
        if name not in by_name:
            raise fail(f"unknown method {name!r} (known: {', '.join(by_name)})", *at, "methods", j)
    allowed = {"errors": states, "local-fused": position_states, "vb-noise": ()}[fg.kind]
    unique(fg.states, "state", *at, "states")
    for j, name in enumerate(fg.states):
        if name not in allowed:
            reason = (
                "not used with kind 'vb-noise' (its panels are the aid's measurement components)"
                if fg.kind == "vb-noise"
                else f"unknown state {name!r} (known: {', '.join(allowed)})"
            )
            raise fail(reason, *at, "states", j)
    if fg.kind == "vb-noise":
        if fg.sensor not in sensors:
            raise fail(
                f"required with kind 'vb-noise': one of {', '.join(sensors)}"
                if not fg.sensor
                else f"unknown sensor {fg.sensor!r} (known: {', '.join(sensors)})",
                *at,
                "sensor",
            )
        for j, name in enumerate(fg.methods):
            me = by_name[name]
            if me.adaptive_noise == "none" or (me.vb_sensors and fg.sensor not in me.vb_sensors):
                raise fail(
                    f"method {name!r} does not estimate the noise of {fg.sensor!r}",
                    *at,
                    "methods",
                    j,
                )
    elif fg.sensor:
        raise fail("only used with kind = 'vb-noise'", *at, "sensor")
    return FigureSpec(
        fg.name, fg.title, tuple(fg.methods), tuple(fg.states), fg.kind, fg.condition, fg.sensor
    )


def build_figures(files: Sequence[FigureFile], **context: Any) -> tuple[FigureSpec, ...]:
    """Every ``[[figures]]`` entry (:func:`_build_figure`), names unique."""
    seen: set[str] = set()
    for i, fg in enumerate(files):
        if fg.name in seen:
            raise fail(f"duplicate figure name {fg.name!r}", "figures", i, "name")
        seen.add(fg.name)
    return tuple(_build_figure(fg, i, **context) for i, fg in enumerate(files))
