"""Monte Carlo runs of a scenario: simulate, run the engine, score against the truth.

One runner for linear and integrated scenarios.  Each task simulates its runs (a
stream and, apart, the truth: :mod:`ftnav.sim`), steps every method through the engine
(:func:`ftnav.engine.driver.iterate`) and scores each epoch's output against the truth
as it comes (errors in the reported states, NEES, variances): the engine never sees
the truth, and no full covariance history is kept.

With faults, the fault-free twin draws the same random streams with the faults
removed (paper 000 Fig. 3 condition) and runs in the same batch (2·runs; runs are
independent, so the results are those of two separate batches): in-window errors can
be compared with and without the fault on identical noise, at half the per-epoch
Python overhead.  Per-run random streams come from one root seed, so run i is the
same alone, in a batch, or in another worker process (:mod:`ftnav.parallel`).

Scenarios that differ in their faults only (the points of a sweep over fault settings,
:mod:`ftnav.sweep`) run in one batch the same way (:func:`run_points`): each point's
runs, then one fault-free twin for all of them, ``(P + 1)·runs`` rows stepped together,
so a sweep of P fault sizes costs about one campaign of P + 1 times the runs, not P
campaigns; every point's results equal its own campaign's bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, fields, replace
from typing import Any, NamedTuple, cast

import numpy as np

from ftnav.engine import navigation_model
from ftnav.engine.driver import (
    EpochRecord,
    MethodOutputs,
    Recorder,
    check_output,
    iterate,
    method_feedback,
)
from ftnav.eval.batching import CHUNK_BYTES, PARALLEL_MIN_WORK, chunk_runs
from ftnav.eval.metrics import nees
from ftnav.eval.navigation import N_NAV, metric_errors, metric_variances
from ftnav.eval.resources import check_memory
from ftnav.fusion import registry
from ftnav.fusion.config import NOTHING_LEARNED
from ftnav.fusion.protocol import Architecture
from ftnav.model.scenario import InsScenario, Scenario
from ftnav.model.streams import concat_streams, scheduled
from ftnav.model.system import LinearSystem
from ftnav.nav.mechanization import navigation_errors
from ftnav.parallel import run_tasks, split_even
from ftnav.sim.ins import InsTruth, SimulatedIns, simulate_ins
from ftnav.sim.linear import LinearTruth, Simulated, simulate

__all__ = [
    "CHUNK_BYTES",
    "MethodResult",
    "RESULT_FIELDS",
    "PARALLEL_MIN_WORK",
    "ScenarioResult",
    "build_filters",
    "join_results",
    "chunk_runs",
    "run_points",
    "run_scenario",
    "simulate_runs",
    "split_results",
]


@dataclass(frozen=True, kw_only=True)
class MethodResult(MethodOutputs):
    """Per-epoch scores of one method over B runs and K epochs, against the truth: what
    the method says of itself (:class:`~ftnav.engine.driver.MethodOutputs`, shared with
    a recording's :class:`~ftnav.engine.driver.Trace`) and its errors.

    Attributes
    ----------
    error : (B, K, n) error of the reported states: the estimate − truth of a linear
        model's common states; an integrated run's output errors (computed − true:
        E/N/U m, m/s, φ arcmin, :data:`~ftnav.model.scenario.METRIC_STATES`).
    P_diag : (B, K, n) the filter's variances of the same states.
    nees : (B, K) NEES of the fused estimate (common states; integrated: the 9
        navigation states).
    local : (B, K, N, 3) integrated runs: each local filter's position error (E/N/U m),
        or None.
    estimate : (B, K, n) a linear model's fused estimate (None for an integrated run,
        whose estimates are error states).
    scheduled : (B, K, N) bool, the epochs each aid was due (the stream's schedule).
    """

    error: np.ndarray
    P_diag: np.ndarray
    nees: np.ndarray
    local: np.ndarray | None = None
    estimate: np.ndarray | None = None
    scheduled: np.ndarray | None = None


#: the fields of :class:`MethodResult`, in order (what a shard stores, what joins)
RESULT_FIELDS = tuple(f.name for f in fields(MethodResult))


class ScenarioResult(NamedTuple):
    """Everything ``ftnav run`` computes, with and without the faults.

    ``truth`` is the reference of the runs (a linear scenario's always; an integrated
    one's when everything ran as one batch); ``stream`` the simulated stream when
    everything ran as one batch in this process (else None).
    """

    scenario: Any
    runs: int
    seed: int
    results: dict[str, MethodResult]
    fault_free: dict[str, MethodResult]
    truth: LinearTruth | InsTruth | None = None
    stream: Any = None


def build_filters(
    scenario: Any, system: LinearSystem, methods: Sequence[Any], **kw: Any
) -> dict[str, Architecture[Any]]:
    """Every method's filter on ``system`` with its trained models (scenario.learned), at
    the scenario's filter period (the guard's windows are in seconds)."""
    kw.setdefault("dt", float(scenario.dt))
    return {
        m.name: registry.build(system, m, scenario.learned_for(m.name) or NOTHING_LEARNED, **kw)
        for m in methods
    }


def simulate_runs(scenario: Any, runs: range, seed: int) -> Simulated | SimulatedIns:
    """The stream and truth of runs ``runs`` of either kind of scenario."""
    if scenario.kind == "integrated":
        return simulate_ins(scenario, runs, seed)
    return simulate(scenario, len(runs), seed, first_run=runs.start)


# --------------------------------------------------------------------------- scoring
class _Scores:
    """One method's per-epoch scores, filled in place as the epochs come; the outputs
    that need no reference go to an engine :class:`~ftnav.engine.driver.Recorder`."""

    def __init__(self, B: int, K: int, n: int, n_sensors: int):
        self.error, self.P = np.empty((B, K, n)), np.empty((B, K, n))
        self.nees = np.empty((B, K))
        self.n_sensors = n_sensors
        self.rec = Recorder(B, K)

    def result(self) -> MethodResult:
        e = self.rec.arrays
        return MethodResult(
            **self.rec.method_outputs(self.n_sensors),
            error=self.error,
            P_diag=self.P,
            nees=self.nees,
            local=e.get("local"),
            estimate=e.get("estimate"),
        )


def _score_linear(
    records: Iterable[EpochRecord],
    truth: LinearTruth,
    names: list[str],
    B: int,
    K: int,
    nc: int,
    dims: Sequence[int],
) -> dict[str, MethodResult]:
    scores = {nm: _Scores(B, K, nc, len(dims)) for nm in names}
    for r in records:
        k = r.k
        for j, nm in enumerate(names):
            out, s = r.outputs[j], scores[nm]
            s.rec.put("estimate", k, out.x)
            s.error[:, k - 1] = out.x - truth.states[:, k - 1, :nc]
            s.P[:, k - 1] = np.diagonal(out.P, axis1=-2, axis2=-1)
            s.nees[:, k - 1] = nees(out.x - truth.states[:, k - 1, :nc], out.P)
            s.rec.outputs(k, out)
    return {nm: scores[nm].result() for nm in names}


def _score_ins(
    records: Iterable[EpochRecord],
    truth: InsTruth,
    names: list[str],
    B: int,
    K: int,
    dims: Sequence[int],
    feedback: bool | Sequence[bool],
) -> dict[str, MethodResult]:
    """Integrated runs' scores; ``feedback`` per method (or one for all): a fed-back
    method's output is its SINS after feedback, an output-corrected one's the SINS minus
    its estimate (spec §8.5)."""
    M = len(names)
    fb = [bool(feedback)] * M if isinstance(feedback, bool) else [bool(f) for f in feedback]
    parts = [slice(j * B, (j + 1) * B) for j in range(M)]
    scores = {nm: _Scores(B, K, N_NAV, len(dims)) for nm in names}
    tr = truth.epochs
    for r in records:
        assert r.nav is not None and r.solution is not None  # an integrated model's are set
        k = r.k
        q_t, v_t, p_t = tr.q[k - 1], tr.v[k - 1], tr.p[k - 1]
        e_true = navigation_errors(r.nav.q, r.nav.v, r.nav.p, q_t, v_t, p_t)
        d_all = np.concatenate([o.x[:, :N_NAV] for o in r.outputs], 0)
        P_all = np.concatenate([o.P[:, :N_NAV, :N_NAV] for o in r.outputs], 0)
        eps = nees(d_all - e_true, P_all)
        var = metric_variances(P_all, p_t)
        e_out = (
            metric_errors(
                navigation_errors(r.solution.q, r.solution.v, r.solution.p, q_t, v_t, p_t), p_t
            )
            if any(fb)
            else None
        )
        for j, nm in enumerate(names):
            p, s, out = parts[j], scores[nm], r.outputs[j]
            s.error[:, k - 1] = (
                e_out[p]
                if fb[j] and e_out is not None
                else metric_errors(e_true[p] - out.x[:, :N_NAV], p_t)
            )
            s.nees[:, k - 1], s.P[:, k - 1] = eps[p], var[p]
            local = r.local[j]
            if local is not None:
                s.rec.put("local", k, metric_errors(e_true[p][:, None, :] - local, p_t)[..., :3])
            s.rec.outputs(k, out)
    return {nm: scores[nm].result() for nm in names}


def score(
    scenario: Any,
    records: Any,
    truth: LinearTruth | InsTruth,
    names: list[str],
    stream: Any,
    model: Any,
    filters: Mapping[str, Any] | None = None,
) -> dict[str, MethodResult]:
    """Each method's :class:`MethodResult` from the engine's records and the truth.

    ``stream`` is the batch the engine consumed: its size and each aid's schedule
    (``MethodResult.scheduled``, the denominator of the availability watch).
    """
    dims = [s.dim for s in model.system.sensors]
    B = stream.batch
    if scenario.kind == "integrated":
        fb: bool | Sequence[bool] = model.feedback
        if filters is not None:
            own = method_feedback(model, [filters[nm] for nm in names])
            fb = fb if own is None else list(own)
        assert isinstance(truth, InsTruth)
        scored = _score_ins(records, truth, names, B, scenario.steps, dims, fb)
    else:
        assert isinstance(truth, LinearTruth)
        scored = _score_linear(
            records, truth, names, B, scenario.steps, model.system.n_common, dims
        )
    due = scheduled(stream, scenario.steps)
    return {nm: replace(r, scheduled=due) for nm, r in scored.items()}


# ---------------------------------------------------------------------------- runner
def run_scenario(
    scenario: Any,
    runs: int,
    seed: int,
    *,
    methods: Sequence[Any] | None = None,
    fault_free: bool = True,
    progress: Callable[[int], None] | None = None,
    workers: int = 1,
    check_spd: bool = True,
    chunk: int | None = None,
    first_run: int = 0,
    scheduler: str | None = None,
) -> ScenarioResult:
    """Simulate ``runs`` runs from ``seed`` and run every method (module docstring).

    ``scheduler``: the address of a ``dask.distributed`` scheduler (``tcp://HOST:PORT``)
    that runs the batches instead of local processes
    (:func:`ftnav.parallel.run_on_cluster`); the results are the same.

    ``first_run``: the runs are ``first_run, ..., first_run + runs - 1`` of the root seed
    (each run's noise depends on its index only, so a campaign in parts, joined by
    :func:`join_results`, equals the campaign run at once).

    Integrated runs go in batches of ``chunk`` runs (default :func:`chunk_runs`, which
    bounds the memory of the simulated IMU data).  ``workers > 1`` runs the batches (or
    groups of methods: every group of a linear scenario above :data:`PARALLEL_MIN_WORK`
    method-epochs, an integrated one when there are fewer batches than workers) in that
    many processes (:mod:`ftnav.parallel`); the results are the same.  Every fused
    covariance is checked at every epoch (``check_spd``) and every error and variance
    before it is scored: a method that diverges raises
    :class:`~ftnav.engine.driver.Diverged`, naming it, the epoch and its time.
    """
    (result,) = run_points(
        (scenario,),
        runs,
        seed,
        methods=methods,
        fault_free=fault_free,
        progress=progress,
        workers=workers,
        check_spd=check_spd,
        chunk=chunk,
        first_run=first_run,
        scheduler=scheduler,
    )
    return result


def _chosen_methods(scenario: Any, methods: Sequence[Any] | None) -> tuple[Any, ...]:
    """``methods`` as the scenario's method settings: None (all of them), or names of
    its methods, or method settings; refused by name when empty, a string, or unknown."""
    if methods is None:
        return tuple(scenario.methods)
    if isinstance(methods, str):
        raise ValueError(f"methods: expected a list of method names or settings, got {methods!r}")
    chosen = list(methods)
    if not chosen:
        raise ValueError("methods: an empty list chooses nothing (None: all of them)")
    by_name = {m.name: m for m in scenario.methods}
    out = []
    for m in chosen:
        if isinstance(m, str):
            if m not in by_name:
                raise ValueError(
                    f"methods: {m!r} is not a method of the scenario ({', '.join(by_name)})"
                )
            m = by_name[m]
        elif not hasattr(m, "architecture"):
            raise ValueError(f"methods: expected method names or settings, got {m!r}")
        out.append(m)
    names = [m.name for m in out]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"methods: {', '.join(map(repr, twice))} given twice")
    return tuple(out)


def _check_whole(name: str, value: Any, low: int) -> None:
    """An argument that must be an integer ``>= low`` (ValueError naming it)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
        raise ValueError(f"{name}: must be an integer >= {low}, got {value!r}")


def run_points(
    points: Sequence[Any],
    runs: int,
    seed: int,
    *,
    methods: Sequence[Any] | None = None,
    fault_free: bool = True,
    progress: Callable[[int], None] | None = None,
    workers: int = 1,
    check_spd: bool = True,
    chunk: int | None = None,
    first_run: int = 0,
    scheduler: str | None = None,
) -> list[ScenarioResult]:
    """:func:`run_scenario` of every scenario of ``points`` in one batch (module
    docstring); their results in order, each equal to its own :func:`run_scenario`'s.

    The points must differ in their faults only (the same model, methods, aids, steps
    and seed: the sweep of :mod:`ftnav.sweep` checks its keys): every row runs the first
    point's filters.  Each batch holds every point's runs and one fault-free twin (a
    point without faults gets none, as alone); ``chunk`` counts runs per point.

    Raises
    ------
    ValueError : ``"points: ..."`` when they do not share the kind, steps, time step and
        method names.
    """
    for name, value, low in (
        ("runs", runs, 1),
        ("seed", seed, 0),
        ("workers", workers, 1),
        ("first_run", first_run, 0),
    ):
        _check_whole(name, value, low)
    points = tuple(points)
    if not points:
        raise ValueError("points: none given")
    for p in points:
        if not isinstance(p, Scenario | InsScenario):
            raise ValueError(
                "scenario: expected a loaded scenario (ftnav.load_scenario(path_or_name)), "
                f"got {p!r}"
            )
    if chunk is not None:
        _check_whole("chunk", chunk, 1)
    scenario = points[0]
    if len(points) == 1:  # a campaign (a sweep's points have their own estimate)
        check_memory(scenario, runs, workers=workers, fault_free=fault_free, chunk=chunk)
    for other in points[1:]:
        if (other.kind, other.steps, other.dt, [m.name for m in other.methods]) != (
            scenario.kind,
            scenario.steps,
            scenario.dt,
            [m.name for m in scenario.methods],
        ):
            raise ValueError(
                "points: the scenarios must differ in their faults only (kind, steps, dt "
                "and methods differ)"
            )
    methods = _chosen_methods(scenario, methods)
    system = scenario.system()
    build_filters(scenario, system, methods)  # every method builds before anything runs
    twin = fault_free and any(bool(p.faults) for p in points)
    P = len(points)
    chunk = chunk_runs(scenario, twin, P) if chunk is None else int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk: must be >= 1, got {chunk}")
    integrated = scenario.kind == "integrated"
    if scheduler is not None:  # the cluster's workers share the batches
        workers = max(workers, 2)
    if workers > 1 and integrated:  # no more runs per batch than share the workers evenly
        chunk = min(chunk, -(-runs // workers))
    end = first_run + runs
    starts = range(first_run, end, chunk)
    groups = [methods]
    if workers > 1 and (
        len(starts) < workers
        if integrated
        else P * len(methods) * scenario.steps >= PARALLEL_MIN_WORK
    ):
        parts = -(-workers // len(starts)) if integrated else 3 * workers
        groups = [tuple(g) for g in split_even(methods, parts)]
    keep = len(starts) * len(groups) == 1  # the stream and truth stay in this process
    tasks = [
        (points, range(s, min(s + chunk, end)), seed, g, twin, check_spd, keep)
        for s in starts
        for g in groups
    ]
    # what each task reports: one unit per method and epoch (every point's runs at once)
    units = [scenario.steps * len(t[3]) for t in tasks]
    done = run_tasks(_task, tasks, workers, progress, scheduler, units)
    return [
        _merge([d[i] for d in done], len(groups), methods, p, runs, seed)
        for i, p in enumerate(points)
    ]


#: one task of :func:`run_points`: the points, a batch of runs, the root seed, a group of
#: methods, the fault-free twin, check_spd, keep the stream and truth
_Task = tuple[Sequence[Any], range, int, Sequence[Any], bool, bool, bool]


def _task(task: _Task, progress: Callable[[int], None] | None = None) -> tuple[ScenarioResult, ...]:
    """One task of :func:`run_points`: a group of methods over a batch of runs of every
    point (each point's runs, then the fault-free twin's, in one stream)."""
    points, rr, seed, methods, twin, check_spd, keep = task
    runs, sc = len(rr), points[0]
    system = sc.system()
    model = navigation_model(sc, system)
    filters = build_filters(sc, system, methods)
    sims = [simulate_runs(p, rr, seed) for p in points]
    streams = [s.stream for s in sims]
    truths = [s.truth for s in sims]
    if twin:
        streams.append(simulate_runs(sc.without_faults(), rr, seed).stream)
        truths.append(truths[0])  # the fault-free twin's truth is the faulty runs'
    stream = streams[0] if len(streams) == 1 else concat_streams(*streams)
    names = [m.name for m in methods]
    records = iterate(model, stream, filters, sc.steps, progress, check_spd, sc.times)
    truth = _stacked_truth(truths)
    scored = score(sc, records, truth, names, stream, model, filters)
    for name, res in scored.items():  # a NaN error or a negative variance is no result
        check_output(name, (res.error, res.estimate), (res.P_diag,), sc.times)
    parts = {name: split_results(res, runs, len(streams)) for name, res in scored.items()}
    out = []
    for i, (p, sim) in enumerate(zip(points, sims, strict=True)):
        results = {name: part[i] for name, part in parts.items()}
        ff = {name: part[-1] for name, part in parts.items()} if twin and p.faults else {}
        linear = isinstance(sim.truth, LinearTruth)  # small: kept whatever the batching
        out.append(
            ScenarioResult(
                p,
                runs,
                seed,
                results,
                ff,
                sim.truth if keep or linear else None,
                sim.stream if keep else None,
            )
        )
    return tuple(out)


def _stacked_truth(truths: Sequence[LinearTruth | InsTruth]) -> LinearTruth | InsTruth:
    """The truth of the batches of one stream, in its order (the points' runs and the
    fault-free twin's: faults change the measurements, not the truth)."""
    first = truths[0]
    if len(truths) == 1 or not isinstance(first, LinearTruth):
        return first  # the flight is shared by every run
    linear = cast("Sequence[LinearTruth]", truths)
    return LinearTruth(
        np.concatenate([t.states for t in linear]),
        tuple(np.concatenate(z) for z in zip(*(t.noise_free for t in linear), strict=True)),
    )


def _rebuilt(like: tuple[Any, ...], parts: list[Any]) -> tuple[Any, ...]:
    """``parts`` as a tuple of the type of ``like`` (a NamedTuple keeps its type)."""
    return type(like)(*parts) if hasattr(like, "_fields") else tuple(parts)


def split_results(r: MethodResult, runs: int, parts: int) -> list[MethodResult]:
    """A :class:`MethodResult` of ``parts`` concatenated batches of ``runs`` runs each."""
    return [_part(r, slice(i * runs, (i + 1) * runs)) for i in range(parts)]


def _part(r: MethodResult, sl: slice) -> MethodResult:
    """The runs ``sl`` of every per-run array of ``r``."""
    parts: dict[str, Any] = {}
    for f in RESULT_FIELDS:
        v = getattr(r, f)
        parts[f] = (
            _rebuilt(v, [a[sl] for a in v])
            if isinstance(v, tuple)
            else None
            if v is None
            else v[sl]
        )
    return MethodResult(**parts)


def join_results(parts: Sequence[ScenarioResult]) -> ScenarioResult:
    """One campaign from campaigns of consecutive runs of the same scenario and seed
    (:func:`run_scenario`'s ``first_run``), the runs in order."""
    first = parts[0]
    methods = [m for m in first.scenario.methods if m.name in first.results]
    total = sum(p.runs for p in parts)
    return _merge(list(parts), 1, methods, first.scenario, total, first.seed)


def _merge(
    done: list[ScenarioResult],
    n_groups: int,
    methods: Sequence[Any],
    scenario: Any,
    runs: int,
    seed: int,
) -> ScenarioResult:
    """One result from the tasks: groups of methods side by side, batches of runs joined."""
    order = [m.name for m in methods]
    chunks = [done[i : i + n_groups] for i in range(0, len(done), n_groups)]

    def union(dicts: list[dict[str, MethodResult]]) -> dict[str, MethodResult]:
        merged = {k: v for d in dicts for k, v in d.items()}
        return {k: merged[k] for k in order if k in merged}

    def cat(values: list[Any]) -> Any:
        first = values[0]
        if first is None:
            return None
        if isinstance(first, tuple):
            return _rebuilt(first, [cat(list(a)) for a in zip(*values, strict=True)])
        return np.concatenate(values, 0)

    per_chunk = [(union([p.results for p in c]), union([p.fault_free for p in c])) for c in chunks]
    if len(done) == 1:
        return done[0]

    def joined(which: int) -> dict[str, MethodResult]:
        return {
            nm: MethodResult(
                **{f: cat([getattr(c[which][nm], f) for c in per_chunk]) for f in RESULT_FIELDS}
            )
            for nm in per_chunk[0][which]
        }

    if len(per_chunk) == 1:  # groups of methods on the same runs: the same truth
        return ScenarioResult(scenario, runs, seed, *per_chunk[0], done[0].truth)
    truths = [c[0].truth for c in chunks]
    truth = None
    if all(isinstance(t, LinearTruth) for t in truths):
        truth = LinearTruth(*(cat(list(f)) for f in zip(*truths, strict=True)))
    return ScenarioResult(scenario, runs, seed, joined(0), joined(1), truth)
