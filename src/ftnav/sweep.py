"""Parameter sweeps: a Monte Carlo campaign at every point of a grid of scenario settings.

``ftnav sweep SCENARIO --set KEY=V1,V2,... [--set ...] --runs N`` (issue 23): ``KEY`` is a
dotted path into the scenario file as written (TOML tables and arrays of tables; an
integer part indexes an array: ``faults.0.magnitude``,
``methods.2.detector.false_alarm_probability``).  ``KEY=V1,V2`` sets the values (TOML
scalars: ``60``, ``0.5``, ``"chi2"``); ``KEY*=F1,F2`` multiplies the file's number or
array by each factor (a noise scale: ``sensors.1.R*=0.5,1,2``).
A scalar set where the file holds a one-element array replaces its element
(``faults.0.magnitude=30`` on ``magnitude = [60.0]``).

Each point of the cartesian grid is the whole scenario re-validated (an invalid point is a
one-line error naming the ``--set`` key and the point) and run as a full campaign with the
same root seed, so the points differ only by the swept settings (common random numbers:
a difference between two points is not blurred by different noise).  Every metric is kept
with its 95 % interval (:mod:`ftnav.eval.intervals`) in one :class:`xarray.Dataset`
(:func:`sweep_dataset`): the swept keys are dimensions, then ``method``, ``state`` or
``sensor``, and ``bound`` (``value``, ``lo``, ``hi``).

A sweep of fault settings only (every key under ``faults.``: sizes, times, kinds) keeps
the model, the methods and the noise of every point, so its points run together
(:func:`ftnav.eval.montecarlo.run_points`): one batch of every point's runs and one
fault-free twin shared by all, stepped as one campaign of ``(P + 1)·runs`` runs; each
point's metrics equal those of its own campaign bit for bit
(``tests/equivalence/test_sweep_batched.py``), and the per-epoch cost of a linear
model is paid once, not P times (``benchmarks/bench_sweep.py``).  As many points go in
one batch as the memory estimate of :mod:`ftnav.eval.resources` lets their results
fit.  Any other key (a method's setting, a noise scale) changes the filters or the
model: those points run one after another, each batched over its runs and spread over
the local workers like ``ftnav run``.
"""

from __future__ import annotations

import copy
import itertools
import math
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ftnav.eval.evaluate import MethodMetrics, evaluate
from ftnav.eval.intervals import CONFIDENCE, Interval
from ftnav.eval.montecarlo import run_points
from ftnav.eval.resources import available_memory_bytes, max_runs_within
from ftnav.io.common import ScenarioError, read_toml
from ftnav.io.ins_scenario_file import parse_ins_scenario
from ftnav.io.scenario_file import parse_scenario
from ftnav.model.scenario import InsScenario, Scenario
from ftnav.version import __version__

__all__ = [
    "SweepAxis",
    "SweepError",
    "SweepResult",
    "faults_only",
    "parse_set",
    "run_sweep",
    "sweep_dataset",
]

#: Detection metrics kept per method and sensor (the names of ``DetectionStats``).
DETECTION = ("rate", "event_rate", "false_alarm_rate", "mean_delay_s", "median_delay_s")


class SweepError(ValueError):
    """A ``--set`` the scenario cannot take: one line naming the key (CLI exit 2)."""


@dataclass(frozen=True, slots=True)
class SweepAxis:
    """One swept setting: its dotted ``key``, the ``values`` (or factors, ``scale``)."""

    key: str
    values: tuple[Any, ...]
    scale: bool = False

    @property
    def label(self) -> str:
        """The dimension's name: the key, with ``*`` for a scale."""
        return f"{self.key}*" if self.scale else self.key


def _scalar(text: str, where: str) -> Any:
    try:
        value = tomllib.loads(f"v = {text.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = text.strip()  # a bare word is a string (e.g. a detector kind)
    if isinstance(value, float) and not math.isfinite(value):
        raise SweepError(f"{where}: {text.strip()!r} is not a finite number")
    return value


def parse_set(text: str) -> SweepAxis:
    """``KEY=V1,V2,...`` or ``KEY*=F1,F2,...`` (module docstring)."""
    key, sep, rest = text.partition("=")
    scale = key.endswith("*")
    key = key.removesuffix("*").strip()
    where = f"--set {text}"
    if not sep or not key or not rest.strip():
        raise SweepError(f"{where}: expected KEY=V1,V2,... or KEY*=F1,F2,...")
    values = tuple(_scalar(v, where) for v in rest.split(","))
    if scale and not all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        raise SweepError(f"{where}: a scale (KEY*=...) takes numbers")
    if len(set(map(repr, values))) != len(values):
        raise SweepError(f"{where}: a value is given twice")
    return SweepAxis(key, values, scale)


def _set(doc: dict[str, Any], axis: SweepAxis, value: Any) -> None:
    """Set ``axis.key`` of the parsed file ``doc`` in place (module docstring)."""
    parts = axis.key.split(".")
    where = f"--set {axis.label}"
    node: Any = doc
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise SweepError(
                    f"{where}: {'.'.join(parts[: i + 1])}: the file has {len(node)} entries "
                    f"there (0-based index expected)"
                )
            index: int | str = int(part)
        elif isinstance(node, dict):
            if part not in node:
                known = ", ".join(sorted(node)) or "none"
                raise SweepError(
                    f"{where}: {'.'.join(parts[: i + 1])} is not in the file (keys there: {known})"
                )
            index = part
        else:
            raise SweepError(f"{where}: {'.'.join(parts[:i])} is a value, not a table or array")
        if not last:
            node = node[index]  # type: ignore[index]
            continue
        old = node[index]  # type: ignore[index]
        node[index] = _new_value(old, value, axis.scale, where)  # type: ignore[index]


def _new_value(old: Any, value: Any, scale: bool, where: str) -> Any:
    if scale:
        if isinstance(old, bool) or not isinstance(old, int | float | list):
            raise SweepError(f"{where}: the file's value {old!r} is not a number or array")
        return np.multiply(np.asarray(old, float), value).tolist()
    if isinstance(old, list) and len(old) == 1 and not isinstance(value, list):
        return [value]
    return value


def _scenario(doc: dict[str, Any], origin: str, base: Path) -> Scenario | InsScenario:
    if doc.get("kind") == "integrated":
        return parse_ins_scenario(doc, origin, base)
    return parse_scenario(doc, origin, base)


@dataclass(frozen=True, slots=True)
class SweepResult:
    """A sweep: the axes, each grid point's settings and metrics (row-major over axes)."""

    scenario: str
    axes: tuple[SweepAxis, ...]
    points: tuple[tuple[Any, ...], ...]
    metrics: tuple[dict[str, MethodMetrics], ...]
    states: tuple[str, ...]
    sensors: tuple[str, ...]
    runs: int
    seed: int


def grid(source: str | Path, axes: Sequence[SweepAxis]) -> list[tuple[tuple[Any, ...], Any]]:
    """Every point's values and validated scenario, before anything runs (a bad point is
    refused with the key and values that make it bad)."""
    path = Path(source)
    doc = read_toml(path)
    out = []
    for values in itertools.product(*(a.values for a in axes)):
        point = copy.deepcopy(doc)
        for a, v in zip(axes, values, strict=True):
            _set(point, a, v)
        try:
            sc = _scenario(point, str(path), path.parent)
        except ScenarioError as exc:
            at = ", ".join(f"{a.label}={v}" for a, v in zip(axes, values, strict=True))
            raise SweepError(f"at {at}: {exc}") from None
        out.append((values, sc))
    return out


def run_sweep(
    points: Sequence[tuple[tuple[Any, ...], Scenario | InsScenario]],
    axes: Sequence[SweepAxis],
    runs: int,
    seed: int,
    workers: int | None = None,
    progress: Callable[[int], None] | None = None,
    scheduler: str | None = None,
) -> SweepResult:
    """Run the campaign of every grid point of :func:`grid` (module docstring), on the
    Dask cluster at ``scheduler`` when given."""
    metrics = []
    first = points[0][1]
    options: dict[str, Any] = {"scheduler": scheduler}
    if workers is not None:
        options["workers"] = workers
    scenarios = [sc for _, sc in points]
    # points that differ in their faults only run together; any other sweep one by one
    together = len(scenarios) > 1 and faults_only(axes)
    size = _points_per_batch(first, runs, len(scenarios), workers) if together else 1
    for i in range(0, len(scenarios), size):
        group = scenarios[i : i + size]
        scaled = None if progress is None else _scaled(progress, len(group))
        for result in run_points(group, runs, seed, progress=scaled, **options):
            metrics.append(evaluate(result))
    return SweepResult(
        first.name,
        tuple(axes),
        tuple(v for v, _ in points),
        tuple(metrics),
        tuple(next(iter(metrics[0].values())).rmse),
        tuple(first.sensor_names),
        runs,
        seed,
    )


def faults_only(axes: Sequence[SweepAxis]) -> bool:
    """Whether every swept key is a fault's setting (the points then run together)."""
    return all(a.key.split(".")[0] == "faults" for a in axes)


def _points_per_batch(
    sc: Scenario | InsScenario, runs: int, points: int, workers: int | None
) -> int:
    """How many points' campaigns of ``runs`` runs fit in memory at once (all, when the
    available memory is unknown; at least one)."""
    available = available_memory_bytes()
    if available is None:
        return points
    options = {} if workers is None else {"workers": workers}
    fit = max_runs_within(sc, available, **options)
    return max(1, min(points, fit // max(1, runs)))


def _scaled(progress: Callable[[int], None], points: int) -> Callable[[int], None]:
    """The progress of ``points`` points stepped together: each epoch counts for each."""
    return progress if points == 1 else lambda n: progress(n * points)


def _bounds(i: Interval | None, value: float | None = None) -> list[float]:
    if i is None:
        v = math.nan if value is None else float(value)
        return [v, math.nan, math.nan]
    return [i.value, i.lo, i.hi]


def sweep_dataset(sweep: SweepResult) -> xr.Dataset:
    """The sweep as one Dataset (module docstring); NaN where a metric is undefined (a
    method without a detector, a point without a fault window)."""
    shape = [len(a.values) for a in sweep.axes]
    methods = list(sweep.metrics[0])
    M, S, N = len(methods), len(sweep.states), len(sweep.sensors)
    rmse = np.full((*shape, M, S, 3), np.nan)
    anees = np.full((*shape, M, 3), np.nan)
    anees_ff = np.full((*shape, M, 3), np.nan)
    det = {k: np.full((*shape, M, N, 3), np.nan) for k in DETECTION}
    for flat, m in enumerate(sweep.metrics):
        at = np.unravel_index(flat, shape)
        for j, name in enumerate(methods):
            mm = m[name]
            ci = mm.intervals
            for s, state in enumerate(sweep.states):
                rmse[(*at, j, s)] = _bounds(ci.rmse.get(state) if ci else None, mm.rmse[state])
            anees[(*at, j)] = _bounds(ci.anees if ci else None, mm.anees)
            if ci and ci.fault_free_anees is not None:
                anees_ff[(*at, j)] = _bounds(ci.fault_free_anees)
            for n, sensor in enumerate(sweep.sensors):
                d = (ci.detection or {}).get(sensor) if ci else None
                if d is None:
                    continue
                for k in DETECTION:
                    det[k][(*at, j, n)] = _bounds(d[k])
    dims = [a.label for a in sweep.axes]
    coords: dict[str, Any] = {a.label: list(a.values) for a in sweep.axes}
    coords |= {
        "method": methods,
        "state": list(sweep.states),
        "sensor": list(sweep.sensors),
        "bound": ["value", "lo", "hi"],
    }
    data = {
        "rmse": ([*dims, "method", "state", "bound"], rmse),
        "anees": ([*dims, "method", "bound"], anees),
        "fault_free_anees": ([*dims, "method", "bound"], anees_ff),
    }
    data |= {f"detection_{k}": ([*dims, "method", "sensor", "bound"], v) for k, v in det.items()}
    return xr.Dataset(
        data,
        coords=coords,
        attrs={
            "scenario": sweep.scenario,
            "runs": sweep.runs,
            "seed": sweep.seed,
            "confidence": CONFIDENCE,
            "ftnav_version": __version__,
            "intervals": "rmse, anees: Student t over runs; detection rates: Wilson with the "
            "runs as clusters; delays: bootstrap over runs (ftnav.eval.intervals)",
        },
    )
