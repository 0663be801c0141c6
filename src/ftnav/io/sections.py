"""Sections shared by linear and integrated scenario files: methods, figures, evaluation.

``[[methods]]`` (the fusion methods to compare), ``[[figures]]`` (the figures a run
draws) and ``[evaluation]`` (metric settings) read the same in both kinds of file;
the builders turn them into the frozen :mod:`ftnav.model.scenario` containers,
every problem a one-line :class:`~ftnav.io.common.ScenarioError`.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, get_args, get_origin

from pydantic import BaseModel, Field
from pydantic_core import PydanticCustomError

from ftnav.fusion.config import (
    NOTHING_LEARNED,
    Learned,
    MethodBase,
    VbNoise,
)
from ftnav.fusion.registry import ARCHITECTURES, MethodConfig
from ftnav.fusion.registry import check as check_method
from ftnav.io.common import (
    STRICT,
    Name,
    ScenarioError,
    fail,
    file_name_problem,
    format_loc,
    number,
    unique,
)
from ftnav.io.learned import learned_for
from ftnav.io.model_file import ModelFileError
from ftnav.model.scenario import (
    MAX_FIGURE_METHODS,
    Evaluation,
    FigureCondition,
    FigureKind,
    FigureSpec,
)
from ftnav.model.system import LinearSystem

__all__ = [
    "EvaluationFile",
    "FigureFile",
    "MethodConfig",
    "build_figures",
    "explain_method_key",
    "resolve_methods",
]


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
    flight: Literal["first", "second"] = Field(
        default="first",
        description="integrated: the scenario's flight, or its test_profile (second)",
    )


class EvaluationFile(BaseModel):
    """``[evaluation]``: metric settings."""

    model_config = STRICT

    skip_initial: float = number(
        "initial convergence period left out of metrics (s)", default=0.0, ge=0
    )
    grace: float = number("post-fault grace period (s)", default=10.0, ge=0)
    watch_window_s: float = number(
        "the sliding window of each aid's NIS mean the method watches (s)", default=60.0, gt=0
    )
    watch_probability: float = number(
        "probability outside the NIS band of a consistent filter", default=0.01, gt=0, lt=1
    )
    sigma_bound_m: float | None = Field(
        default=None,
        gt=0,
        allow_inf_nan=False,
        description=(
            "the bound on the fused horizontal position σ (m) the method is flagged past "
            "(integrated scenarios and recordings; default 100 there, none on a linear model)"
        ),
    )
    min_availability: float = number(
        "an aid with a measurement at (or used at) less than this fraction of its epochs is "
        "reported",
        default=0.5,
        ge=0,
        le=1,
    )

    def settings(self, sigma_bound_m: float | None = None) -> Evaluation:
        """The validated settings; ``sigma_bound_m`` is the default bound of the model."""
        bound = self.sigma_bound_m if self.sigma_bound_m is not None else sigma_bound_m
        return Evaluation(
            float(self.skip_initial),
            float(self.grace),
            float(self.watch_window_s),
            float(self.watch_probability),
            bound,
            float(self.min_availability),
        )


def explain_method_key(key: str, model: type[BaseModel]) -> str | None:
    """Why ``key`` is refused in a method's table: a setting of another architecture (or
    of another mode), of the detector, of the noise model; None when it is unknown."""
    for table in ("detector", "noise"):  # a table of one detector or noise kind
        members = _members(MethodBase.model_fields[table].annotation)
        if model in members:
            others = [_kind(m) for m in members if key in m.model_fields]
            if not others:
                return None
            return (
                f"not a setting of the {_kind(model)!r} {table} (a setting of {', '.join(others)})"
            )
    if not (isinstance(model, type) and issubclass(model, MethodBase)):
        return None
    arch = model.model_fields["architecture"].default
    others = [n for n, e in ARCHITECTURES.items() if key in e.config.model_fields]
    if others:
        return f"not a setting of the {arch} architecture (a setting of {', '.join(others)})"
    for table in ("detector", "noise"):
        annotation = MethodBase.model_fields[table].annotation
        kinds = [m for m in _members(annotation) if key in m.model_fields and key != "kind"]
        if kinds:
            return (
                f"a setting of the {table}: write {table} = "
                f"{{kind = {_kind(kinds[0])!r}, {key} = ...}}"
            )
    return None


def _kind(model: type[BaseModel]) -> str:
    """The ``kind`` tag of a detector or noise model."""
    return str(get_args(model.model_fields["kind"].annotation)[0])


def _members(annotation: Any) -> list[type[BaseModel]]:
    while get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    return [m for m in get_args(annotation) if isinstance(m, type) and issubclass(m, BaseModel)]


def resolve_methods(
    methods: Sequence[MethodBase],
    system: LinearSystem,
    base: Path | None,
    origin: str,
    models: bool = True,
    indices: Sequence[int] | None = None,
) -> tuple[tuple[str, Learned], ...]:
    """Check every method against the system and load its trained models (once).

    Method names must be unique and usable as file names (the outputs are named after
    them: :func:`~ftnav.io.common.file_name_problem`); a check that needs the system
    (sensor names, sizes, private states) or a trained model (its file, its states)
    fails with one line ``methods[i].<setting>: <reason>``.  ``models=False`` loads no
    model file (the training commands, whose scenario may name the file they are about
    to write).
    ``indices``: the methods' positions in the file, when ``methods`` is a selection.
    """
    learned, seen = [], set()
    where = range(len(methods)) if indices is None else indices
    for i, me in zip(where, methods, strict=True):
        problem = file_name_problem(me.name)  # outputs are named after methods
        if problem is not None:
            raise ScenarioError(f"methods[{i}].name", problem, origin)
        if me.name in seen:
            raise ScenarioError(f"methods[{i}].name", f"duplicate method name {me.name!r}", origin)
        seen.add(me.name)
        try:
            got = learned_for(me, i, system, base) if models else NOTHING_LEARNED
        except ModelFileError as exc:  # the scenario's error: it names the method's field
            raise ScenarioError(exc.field, exc.reason, origin) from None
        try:
            check_method(system, me, got)
        except PydanticCustomError as exc:
            path = format_loc(("methods", i, *(exc.context or {}).get("path", ())))
            raise ScenarioError(path, exc.message(), origin) from None
        if got is not NOTHING_LEARNED:
            learned.append((me.name, got))
    return tuple(learned)


_FILE_STEM = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
#: Figure names the run writes itself.
_RESERVED_FIGURES = ("sharing", "fault_flags")


def _build_figure(
    fg: FigureFile,
    i: int,
    states: Sequence[str],
    methods: Sequence[MethodBase],
    sensors: Sequence[str],
    kinds: Sequence[str] = ("errors",),
    position_states: Sequence[str] = (),
    second_flight: bool = False,
) -> FigureSpec:
    """Check one ``[[figures]]`` entry against the scenario's states, methods and sensors.

    ``states`` may be drawn by ``errors`` figures, ``position_states`` by ``local-fused``
    ones; ``kinds`` are the figure kinds the scenario's kind supports.
    """
    at = ("figures", i)
    if fg.flight == "second" and not second_flight:
        raise fail("the scenario has no second flight (test_profile)", *at, "flight")
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
            noise = by_name[name].noise
            if not isinstance(noise, VbNoise) or (noise.sensors and fg.sensor not in noise.sensors):
                raise fail(
                    f"method {name!r} does not estimate the noise of {fg.sensor!r}",
                    *at,
                    "methods",
                    j,
                )
    elif fg.sensor:
        raise fail("only used with kind = 'vb-noise'", *at, "sensor")
    return FigureSpec(
        fg.name,
        fg.title,
        tuple(fg.methods),
        tuple(fg.states),
        fg.kind,
        fg.condition,
        fg.sensor,
        fg.flight,
    )


def build_figures(files: Sequence[FigureFile], **context: Any) -> tuple[FigureSpec, ...]:
    """Every ``[[figures]]`` entry (:func:`_build_figure`), names unique."""
    seen: set[str] = set()
    for i, fg in enumerate(files):
        if fg.name in seen:
            raise fail(f"duplicate figure name {fg.name!r}", "figures", i, "name")
        seen.add(fg.name)
    return tuple(_build_figure(fg, i, **context) for i, fg in enumerate(files))
