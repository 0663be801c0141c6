"""A stopping rule for campaigns: add runs until a metric's interval is narrow enough.

``ftnav run SCENARIO --until "METHOD.METRIC:rel=0.02" --max-runs N`` (issue 23 item 4).
``METRIC`` is a path into the method's intervals (:class:`~ftnav.eval.evaluate.MetricIntervals`):
``rmse.<state>``, ``rmse_fault.<state>``, ``ensemble_rmse.<state>``, ``anees``,
``detection.<sensor>.<rate|event_rate|false_alarm_rate|mean_delay_s|median_delay_s|
p95_delay_s|mean_recovery_s>``.  The target is the interval's half-width, relative to the
value (``rel=0.02``) or absolute (``abs=0.1``, in the metric's unit).

The campaign starts with ``--runs`` runs; after each part it estimates the runs the target
needs from the ``1/√runs`` shrinkage (:func:`~ftnav.eval.intervals.runs_needed`) and runs
the difference (at least a quarter of the runs so far, at most up to ``max_runs``).  The
parts are runs ``0, 1, ...`` of the same root seed, so the final result is the campaign of
that many runs run at once, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields, is_dataclass
from typing import Any

from ftnav.eval.evaluate import MethodMetrics, evaluate
from ftnav.eval.intervals import Interval, runs_needed
from ftnav.eval.montecarlo import ScenarioResult, join_results, run_scenario
from ftnav.model.scenario import POSITION_NORMS

__all__ = ["Stopped", "Target", "check_target", "metric_interval", "parse_target", "run_until"]

_DETECTION = (
    "rate",
    "event_rate",
    "false_alarm_rate",
    "mean_delay_s",
    "median_delay_s",
    "p95_delay_s",
    "mean_recovery_s",
)


@dataclass(frozen=True, slots=True)
class Target:
    """``method``'s metric at ``path`` to a half-width of ``value`` (``relative`` to the
    metric's value, else in its unit)."""

    text: str
    method: str
    path: tuple[str, ...]
    relative: bool
    value: float

    def half_width(self, interval: Interval) -> float:
        """The half-width the target asks of ``interval``."""
        return self.value * abs(interval.value) if self.relative else self.value

    def met(self, interval: Interval) -> bool:
        h = interval.half_width
        return math.isfinite(h) and h <= self.half_width(interval)


def parse_target(text: str, methods: list[str]) -> Target:
    """``METHOD.METRIC:rel=F`` or ``...:abs=F``; ValueError naming ``--until`` otherwise."""
    where = f"--until {text}"
    spec, sep, goal = text.partition(":")
    kind, eq, number = goal.partition("=")
    if not sep or not eq or kind not in ("rel", "abs"):
        raise ValueError(f"{where}: expected METHOD.METRIC:rel=F or METHOD.METRIC:abs=F")
    try:
        value = float(number)
    except ValueError:
        raise ValueError(f"{where}: {number!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{where}: the target must be a positive number")
    method = next(
        (m for m in sorted(methods, key=len, reverse=True) if spec.startswith(m + ".")), None
    )
    if method is None:
        raise ValueError(f"{where}: no method of the scenario starts it ({', '.join(methods)})")
    path = tuple(spec[len(method) + 1 :].split("."))
    if not path or path[0] not in (
        "rmse",
        "rmse_fault",
        "rmse_nofault",
        "ensemble_rmse",
        "anees",
        "detection",
    ):
        raise ValueError(
            f"{where}: the metric is rmse.<state>, rmse_fault.<state>, ensemble_rmse.<state>, "
            "anees or detection.<sensor>.<quantity>"
        )
    shapes = {"anees": 1, "detection": 3}
    if len(path) != shapes.get(path[0], 2) or (
        path[0] == "detection" and path[2] not in _DETECTION
    ):
        raise ValueError(f"{where}: {'.'.join(path)} is not a metric with an interval")
    return Target(text, method, path, kind == "rel", value)


def check_target(target: Target, scenario: Any) -> None:
    """Refuse, before anything runs, a target this scenario cannot measure: a state or
    sensor it does not have, detection of a method without a detector, a detection
    metric other than the false-alarm rate of a sensor without a fault."""
    where = f"--until {target.text}"
    head = target.path[0]
    if head == "detection":
        method = next(m for m in scenario.methods if m.name == target.method)
        if method.detector.kind == "none":
            raise ValueError(f"{where}: {target.method} has no detector")
        if target.path[1] not in scenario.sensor_names:
            names = ", ".join(scenario.sensor_names)
            raise ValueError(f"{where}: no sensor {target.path[1]!r} (sensors: {names})")
        clean = target.path[2:] in (("false_alarm_rate",), ("false_alarms_per_hour",))
        if not clean and not any(f.sensor == target.path[1] for f in scenario.faults):
            raise ValueError(
                f"{where}: {target.path[1]} has no fault in the scenario: only its false-alarm "
                "rate can be measured"
            )
    elif head != "anees":
        states = list(scenario.metric_states)
        if getattr(scenario, "kind", "linear") == "integrated":
            states += list(POSITION_NORMS)
        if target.path[1] not in states:
            raise ValueError(f"{where}: no state {target.path[1]!r} (states: {', '.join(states)})")


def metric_interval(metrics: dict[str, MethodMetrics], target: Target) -> Interval:
    """The interval ``target`` names in ``metrics``; ValueError when the run has none."""
    where = f"--until {target.text}"
    ci = metrics[target.method].intervals
    head, *rest = target.path
    node: Any = None if ci is None else getattr(ci, head)
    for key in rest:
        # a map (by state or sensor) or a typed container (a sensor's detection intervals)
        if isinstance(node, dict):
            keys = list(node)
        else:
            keys = [f.name for f in fields(node)] if is_dataclass(node) else []
        if key not in keys:
            known = ", ".join(keys) or "none"
            raise ValueError(f"{where}: no {key!r} in {head} of this run (there: {known})")
        node = node[key] if isinstance(node, dict) else getattr(node, key)
    if not isinstance(node, Interval):
        raise ValueError(f"{where}: {'.'.join(target.path)} has no interval in this run")
    return node


@dataclass(frozen=True, slots=True)
class Stopped:
    """How a campaign under a stopping rule ended."""

    result: ScenarioResult
    metrics: dict[str, MethodMetrics]
    interval: Interval
    reached: bool
    parts: int


def run_until(
    scenario: Any,
    seed: int,
    target: Target,
    first_runs: int,
    max_runs: int,
    *,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
    scheduler: str | None = None,
) -> Stopped:
    """Add runs until ``target`` is met or ``max_runs`` are done (module docstring)."""
    options: dict[str, Any] = {"progress": progress, "workers": workers, "scheduler": scheduler}
    parts = [run_scenario(scenario, min(first_runs, max_runs), seed, **options)]
    while True:
        result = join_results(parts)
        metrics = evaluate(result)
        interval = metric_interval(metrics, target)
        done = result.runs
        if target.met(interval) or done >= max_runs:
            return Stopped(result, metrics, interval, target.met(interval), len(parts))
        need = runs_needed(interval, target.half_width(interval)) or 2 * done
        more = min(max(need - done, math.ceil(done / 4)), max_runs - done)
        parts.append(run_scenario(scenario, more, seed, first_run=done, **options))
