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
fit.

A sweep of method settings (every key under ``methods.``, alone or with fault keys)
keeps the model, the aids and the noise too: the points run as one campaign of the
*union* of their methods (:func:`shared_methods`), a method that two points have alike
(every method the sweep does not touch) run once, each swept method once per value,
on one simulation of the runs per fault setting (a key under ``evaluation.``, the
grace after a fault or the convergence time, changes no run at all: its points share
every run and differ in their scoring only).  A false-alarm sweep of one detector
over five values among five methods costs nine methods' filters rather than
twenty-five, and one simulation rather than five; each point's metrics equal those of
its own campaign bit for bit (``tests/equivalence/test_sweep_batched.py``: every method
is its own rows of the batch, whatever runs beside it).  Any other key (a noise scale,
the steps) changes the model: those points run one after another, each batched over
its runs and spread over the local workers like ``ftnav run``.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from ftnav.eval.evaluate import MethodMetrics, evaluate
from ftnav.eval.intervals import CONFIDENCE, Interval
from ftnav.eval.montecarlo import ScenarioResult, run_points
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
    "SharedMethods",
    "faults_only",
    "parse_set",
    "run_sweep",
    "shared_methods",
    "shares_model",
    "sweep_work",
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


def _same(value: Any) -> str:
    """A value's identity for the repeat check: numbers by their value (10 and 10.0)."""
    if isinstance(value, int | float) and not isinstance(value, bool):
        return repr(float(value))
    return repr(value)


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
    if len(set(map(_same, values))) != len(values):  # 10 and 10.0 alike
        raise SweepError(f"{where}: a value is given twice")
    parts = key.split(".")
    if parts[-1] == "name" and parts[0] in ("methods", "sensors", "aids"):
        raise SweepError(
            f"{where}: a name labels the results (every point's methods and sensors must "
            "be the same names); sweep its settings instead"
        )
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
    Dask cluster at ``scheduler`` when given; ``progress`` is fed
    :func:`sweep_work`'s units."""
    first = points[0][1]
    options: dict[str, Any] = {"scheduler": scheduler}
    if workers is not None:
        options["workers"] = workers
    scenarios = [sc for _, sc in points]
    if len(scenarios) > 1 and shares_model(axes):
        # points that differ in their faults and methods only run together
        metrics = _run_shared(points, axes, runs, seed, workers, progress, options)
    else:
        metrics = []
        for sc in scenarios:
            for result in run_points([sc], runs, seed, progress=progress, **options):
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
    """Whether every swept key is a fault's setting."""
    return all(a.key.split(".")[0] == "faults" for a in axes)


#: the tables whose settings leave the model, the aids and the noise as they are
SHARED_TABLES = ("faults", "methods", "evaluation")


def shares_model(axes: Sequence[SweepAxis]) -> bool:
    """Whether every swept key is a fault's, a method's or the evaluation's setting: the
    points then share the model, the aids and the noise, and run together (module
    docstring)."""
    return all(a.key.split(".")[0] in SHARED_TABLES for a in axes)


@dataclass(frozen=True, slots=True)
class SharedMethods:
    """The methods of several points run as one campaign (:func:`shared_methods`).

    Attributes
    ----------
    methods : the union: each distinct method configuration once, in order of first
        appearance (the first point's under their own names, a later point's method
        that differs from every one before it as ``NAME@k``, k its point).
    learned : the union's trained models, under the union's names.
    names : per point, its method names -> their names in the union.
    """

    methods: tuple[Any, ...]
    learned: tuple[tuple[str, Any], ...]
    names: tuple[dict[str, str], ...]


def shared_methods(scenarios: Sequence[Scenario | InsScenario]) -> SharedMethods:
    """The union of the points' methods (:class:`SharedMethods`).  Two methods are the
    same when their whole configurations are, name included (a trained model comes from
    the file its configuration names, read against the same system: the same)."""
    union: list[Any] = []
    learned: list[tuple[str, Any]] = []
    names: list[dict[str, str]] = []
    taken = {m.name for sc in scenarios for m in sc.methods}
    for k, sc in enumerate(scenarios):
        alias: dict[str, str] = {}
        for m in sc.methods:
            same = next((u for u in union if u == m), None)
            if same is None:
                name = m.name if k == 0 else f"{m.name}@{k}"
                while k and name in taken:  # a file's own name never collides
                    name += "'"
                taken.add(name)
                same = m if name == m.name else m.model_copy(update={"name": name})
                union.append(same)
                model = sc.learned_for(m.name)
                if model is not None:
                    learned.append((name, model))
            alias[m.name] = same.name
        names.append(alias)
    return SharedMethods(tuple(union), tuple(learned), tuple(names))


def _fault_values(axes: Sequence[SweepAxis], values: tuple[Any, ...]) -> tuple[Any, ...]:
    """A point's values of the fault keys: the same for points with the same faults."""
    return tuple(repr(v) for a, v in zip(axes, values, strict=True) if a.key.startswith("faults."))


def _variants(
    points: Sequence[tuple[tuple[Any, ...], Scenario | InsScenario]],
    axes: Sequence[SweepAxis],
) -> tuple[SharedMethods, list[Scenario | InsScenario], list[int]]:
    """The union of the methods, one scenario per distinct fault setting (with the
    union's methods) and each point's index among them."""
    scenarios = [sc for _, sc in points]
    shared = shared_methods(scenarios)
    variants: list[Scenario | InsScenario] = []
    seen: dict[tuple[Any, ...], int] = {}
    index = []
    for values, sc in points:
        key = _fault_values(axes, values)
        if key not in seen:
            seen[key] = len(variants)
            variants.append(
                replace(
                    scenarios[0], faults=sc.faults, methods=shared.methods, learned=shared.learned
                )
            )
        index.append(seen[key])
    return shared, variants, index


def sweep_work(
    points: Sequence[tuple[tuple[Any, ...], Scenario | InsScenario]], axes: Sequence[SweepAxis]
) -> int:
    """The units of work :func:`run_sweep` reports to its ``progress`` for one batch of
    runs: epochs × methods stepped, summed over what runs (the union of the methods for
    each distinct fault setting when the points share the model)."""
    if len(points) > 1 and shares_model(axes):
        shared, variants, _ = _variants(points, axes)
        return len(variants) * len(shared.methods) * points[0][1].steps
    return sum(len(sc.methods) * sc.steps for _, sc in points)


def _run_shared(
    points: Sequence[tuple[tuple[Any, ...], Scenario | InsScenario]],
    axes: Sequence[SweepAxis],
    runs: int,
    seed: int,
    workers: int | None,
    progress: Callable[[int], None] | None,
    options: dict[str, Any],
) -> list[dict[str, MethodMetrics]]:
    """Every point's metrics, its methods run among the union of all points' on one
    simulation per fault setting (module docstring)."""
    shared, variants, index = _variants(points, axes)
    size = _points_per_batch(variants[0], runs, len(variants), workers)
    results: list[ScenarioResult] = []
    for i in range(0, len(variants), size):
        group = variants[i : i + size]
        scaled = None if progress is None else _scaled(progress, len(group))
        results += run_points(group, runs, seed, progress=scaled, **options)
    metrics = []
    for (_, sc), alias, v in zip(points, shared.names, index, strict=True):
        r = results[v]
        ff = {n: r.fault_free[u] for n, u in alias.items() if u in r.fault_free}
        own = {n: r.results[u] for n, u in alias.items()}
        metrics.append(evaluate(r._replace(scenario=sc, results=own, fault_free=ff)))
    return metrics


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


def _coordinate(values: Sequence[Any]) -> list[Any]:
    """A swept key's values as a coordinate: as they are when every one is a scalar,
    else each as its text (an array value, e.g. ``faults.0.magnitude=[10, 0]``, is no
    1-D coordinate)."""
    if all(isinstance(v, int | float | str) for v in values):
        return list(values)
    return [json.dumps(v) if isinstance(v, list | dict) else str(v) for v in values]


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
                    det[k][(*at, j, n)] = _bounds(getattr(d, k))
    dims = [a.label for a in sweep.axes]
    coords: dict[str, Any] = {a.label: _coordinate(a.values) for a in sweep.axes}
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
