"""Turn a :class:`~ftnav.eval.montecarlo.ScenarioResult` into typed metrics (spec §11).

The JSON form (``metrics.json``) is a stable contract, documented in
``docs/architecture.md``: top-level ``scenario``, ``runs``, ``seed``,
``methods``; ``methods[name]`` holds ``rmse``, ``rmse_fault``, ``rmse_nofault``
(state name → float, mean over runs of the per-run RMSE), ``anees`` and, for a
method with a detector, ``detection[sensor]`` = {``rate``, ``false_alarm_rate``,
``mean_delay_s``, ...}.

When the states include ``pos_E_m``, ``pos_N_m`` and ``pos_U_m`` (integrated runs), every
per-state map (``rmse``, ``rmse_fault``, ``rmse_nofault``, ``ensemble_rmse``,
``max_abs_error`` and the fault-free ``rmse``, ``rmse_fault_window``) also holds
``pos_horizontal_m`` and ``pos_3d_m``: the same statistic of the horizontal
``sqrt(e_E² + e_N²)`` and 3-D position error (:data:`~ftnav.model.ins_scenario.POSITION_NORMS`),
e.g. the mean over runs of each run's horizontal RMS error.

``methods[name].intervals`` holds the 95 % confidence interval of every metric above
that is an average over runs (:class:`MetricIntervals`; the method per kind in
:mod:`ftnav.eval.intervals`): each ``{value, lo, hi, runs, method}``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ftnav.eval.integrity import MethodWatch, WatchSettings, watch
from ftnav.eval.intervals import (
    Interval,
    bootstrap_interval,
    mean_interval,
    rate_interval,
    rms_interval,
)
from ftnav.eval.metrics import (
    DetectionEvents,
    DetectionStats,
    detection_events,
    error_stats,
    nees_stats,
    position_norms,
    summarize_detection,
)
from ftnav.eval.montecarlo import MethodResult, ScenarioResult
from ftnav.model.scenario import METRIC_STATES, POSITION_NORMS, Evaluation
from ftnav.version import __version__

__all__ = [
    "DetectionIntervals",
    "DetectionMetrics",
    "FaultFreeMetrics",
    "MethodMetrics",
    "MetricIntervals",
    "evaluate",
    "metrics_frame",
    "metrics_to_json",
    "readmitted_fraction",
    "split_unit",
]

#: Unit suffixes of state and metric names (longest first) and the units they name.
_UNIT_SUFFIXES = (
    ("_m_s2", "m/s²"),
    ("_m_s", "m/s"),
    ("_arcmin", "arcmin"),
    ("_arcsec", "arcsec"),
    ("_deg", "deg"),
    ("_rad", "rad"),
    ("_m", "m"),
)


def split_unit(name: str) -> tuple[str, str | None]:
    """A state or metric name and the unit it ends in: ``vel_N_m_s`` → ``("vel_N", "m/s")``.

    Names without a unit suffix (the states of a linear scenario, e.g. ``s``) give
    ``(name, None)``: their units are those of the scenario, which the file does not name.
    """
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            return name[: -len(suffix)], unit
    return name, None


@dataclass(frozen=True, slots=True)
class FaultFreeMetrics:
    """A method's metrics on the fault-free twin (``methods[name].fault_free``)."""

    rmse: dict[str, float]
    rmse_fault_window: dict[str, float] | None
    anees: float
    nees_in_band_fraction: float
    nis: dict[str, float] | None


def _number(v: float) -> float | None:
    """A metric's value, None where it is undefined (NaN: written as null)."""
    return None if math.isnan(v) else float(v)


@dataclass(frozen=True, slots=True)
class DetectionMetrics:
    """One detector on one sensor over the runs: the fields of
    :class:`~ftnav.eval.metrics.DetectionStats` (the same names in a recording's scores),
    None where undefined (no fault epochs, nothing detected; ``events``, the fault events
    times the runs, an integer), and ``readmitted``: the
    fraction of (run, fault) events whose aid is re-admitted after the fault's end
    (None without a fault window that ends inside the run)."""

    rate: float | None
    event_rate: float | None
    missed_rate: float | None
    false_alarm_rate: float | None
    false_alarms_per_hour: float | None
    mean_delay_s: float | None
    median_delay_s: float | None
    p95_delay_s: float | None
    mean_recovery_s: float | None
    events: int
    readmitted: float | None

    @classmethod
    def of(cls, d: DetectionStats, readmitted: float | None) -> DetectionMetrics:
        """From the pooled statistics and the re-admitted fraction."""
        return cls(
            rate=_number(d.rate),
            event_rate=_number(d.event_rate),
            missed_rate=_number(d.missed_rate),
            false_alarm_rate=_number(d.false_alarm_rate),
            false_alarms_per_hour=_number(d.false_alarms_per_hour),
            mean_delay_s=_number(d.mean_delay_s),
            median_delay_s=_number(d.median_delay_s),
            p95_delay_s=_number(d.p95_delay_s),
            mean_recovery_s=_number(d.mean_recovery_s),
            events=int(d.events),  # an integer, as in a recording's scores (was a float)
            readmitted=readmitted,
        )


@dataclass(frozen=True, slots=True)
class DetectionIntervals:
    """95 % intervals of one detector's metrics on one sensor: the rates (Wilson with the
    runs as clusters), the delays (bootstrap over runs), the mean recovery (t)."""

    rate: Interval
    event_rate: Interval
    false_alarm_rate: Interval
    mean_delay_s: Interval
    median_delay_s: Interval
    p95_delay_s: Interval
    mean_recovery_s: Interval


@dataclass(frozen=True, slots=True)
class MetricIntervals:
    """95 % confidence intervals of a method's metrics over its runs
    (:mod:`ftnav.eval.intervals`).

    Attributes
    ----------
    rmse, rmse_fault, rmse_nofault : state (and position norm) → interval of the mean
        over runs of the per-run RMSE (Student-t over runs); None where the metric is.
    ensemble_rmse : state → interval of the ensemble RMS (t on the per-run mean squares).
    anees : interval of the ANEES (t over the per-run mean NEES).
    detection : sensor → :class:`DetectionIntervals`, or None (no detector).
    fault_free_rmse, fault_free_anees : the same on the fault-free twin, or None.
    """

    rmse: dict[str, Interval]
    rmse_fault: dict[str, Interval] | None
    rmse_nofault: dict[str, Interval] | None
    ensemble_rmse: dict[str, Interval]
    anees: Interval
    detection: dict[str, DetectionIntervals] | None
    fault_free_rmse: dict[str, Interval] | None
    fault_free_anees: Interval | None


@dataclass(frozen=True, slots=True)
class MethodMetrics:
    """Metrics of one method; maps are keyed by state (and position norm) or sensor name."""

    architecture: str
    rmse: dict[str, float]
    rmse_fault: dict[str, float] | None
    rmse_nofault: dict[str, float] | None
    ensemble_rmse: dict[str, float]
    max_abs_error: dict[str, float]
    anees: float
    anees_band: tuple[float, float]
    nees_in_band_fraction: float
    detection: dict[str, DetectionMetrics] | None
    fault_free: FaultFreeMetrics | None
    max_rel_diff_to_centralized: float | None
    mean_beta: dict[str, float] | None
    nan_measurements: dict[str, int]
    nis: dict[str, float] | None = None
    integrity: MethodWatch | None = None
    intervals: MetricIntervals | None = None


def _named(values: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    return {n: float(v) for n, v in zip(names, values, strict=True)}


def _norms(err: np.ndarray, states: Sequence[str]) -> np.ndarray | None:
    """(B, K, 2) horizontal and 3-D position error, or None without ENU position states."""
    enu = METRIC_STATES[:3]
    if not all(s in states for s in enu):
        return None
    return position_norms(err[..., [list(states).index(s) for s in enu]])


def _with_norms(
    values: np.ndarray, states: Sequence[str], norm_values: np.ndarray | None
) -> dict[str, float]:
    """State name → value, followed by the position norms' values when there are any."""
    out = _named(values, states)
    if norm_values is not None:
        out.update(_named(norm_values, POSITION_NORMS))
    return out


def _rmse(
    err: np.ndarray, norms: np.ndarray | None, states: Sequence[str], mask: np.ndarray
) -> dict[str, float]:
    """State name (and position norm) → mean over runs of the per-run RMSE over ``mask``."""
    return _with_norms(
        error_stats(err, mask).rmse,
        states,
        None if norms is None else error_stats(norms, mask).rmse,
    )


def _per_run(
    err: np.ndarray, norms: np.ndarray | None, states: Sequence[str], mask: np.ndarray
) -> tuple[dict[str, Interval], dict[str, Interval]]:
    """State (and position norm) → interval of the mean per-run RMSE, and of the
    ensemble RMS, over ``mask``."""
    columns = err if norms is None else np.concatenate([err, norms], -1)
    names = list(states) + ([] if norms is None else list(POSITION_NORMS))
    ms = (columns[:, mask] ** 2).mean(1)  # (B, n) per-run mean squares
    rmse = {n: mean_interval(np.sqrt(ms[:, j])) for j, n in enumerate(names)}
    ensemble = {n: rms_interval(ms[:, j]) for j, n in enumerate(names)}
    return rmse, ensemble


def _anees_interval(nees: np.ndarray, window: np.ndarray) -> Interval:
    return mean_interval(nees[:, window].mean(1)) if window.any() else mean_interval(np.empty(0))


def detection_intervals(ev: DetectionEvents) -> DetectionIntervals:
    """The intervals of one detector's :class:`~ftnav.eval.metrics.DetectionStats`."""
    B, E = ev.delays.shape
    detected = np.isfinite(ev.delays)
    delays = [d[np.isfinite(d)] for d in ev.delays]
    return DetectionIntervals(
        rate=rate_interval(ev.fault_alarms, np.full(B, ev.fault_epochs)),
        event_rate=rate_interval(detected.sum(1), np.full(B, E)),
        false_alarm_rate=rate_interval(ev.clean_alarms, np.full(B, ev.clean_epochs)),
        mean_delay_s=bootstrap_interval(delays),
        median_delay_s=bootstrap_interval(delays, 0.5),
        p95_delay_s=bootstrap_interval(delays, 0.95),
        mean_recovery_s=mean_interval(_finite_mean(ev.recoveries)),
    )


def _finite_mean(x: np.ndarray) -> np.ndarray:
    """(B,) mean over the finite values of each run's row of ``x`` (NaN where none)."""
    ok = np.isfinite(x)
    n = ok.sum(1)
    total = np.where(ok, x, 0.0).sum(1)
    out: np.ndarray = np.divide(total, n, out=np.full(x.shape[0], np.nan), where=n > 0)
    return out


def _compared(res: MethodResult) -> np.ndarray:
    """What is compared with the centralized filter: a linear model's fused estimate, an
    integrated run's output error (the same truth is subtracted from both)."""
    return res.error if res.estimate is None else res.estimate


def _max_rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    scale = max(1.0, float(np.abs(b).max()))
    return float(np.abs(a - b).max() / scale)


def watch_settings(evaluation: Evaluation) -> WatchSettings:
    """The watch's settings of a scenario's :class:`~ftnav.model.scenario.Evaluation`."""
    return WatchSettings(
        evaluation.watch_window_s,
        evaluation.watch_probability,
        evaluation.sigma_bound_m,
        evaluation.min_availability,
        evaluation.skip_initial,
    )


def adapts(method: Any, sensors: Any) -> list[bool]:
    """Per sensor, whether the method adapts its noise (VB on it)."""
    noise = getattr(method, "noise", None)
    if noise is None or noise.kind == "none":
        return [False] * len(sensors)
    listed = tuple(getattr(noise, "sensors", ()))
    return [not listed or s in listed for s in sensors]


def watched(name: str, res: MethodResult, scenario: Any) -> MethodWatch | None:
    """The watch of one method's runs (:func:`ftnav.eval.integrity.watch`), or None when
    the result holds no watch data."""
    if res.nis is None or res.available is None or res.used is None:
        return None
    sc = scenario
    states = list(sc.metric_states)
    sigma_h = None
    if "pos_E_m" in states and "pos_N_m" in states:
        var = res.P_diag[..., states.index("pos_E_m")] + res.P_diag[..., states.index("pos_N_m")]
        sigma_h = np.sqrt(var)
    due = res.scheduled if res.scheduled is not None else res.available
    return watch(
        name,
        sc.times,
        sc.sensor_names,
        [s.dim for s in sc.system().sensors],
        res.nis,
        res.available,
        res.used,
        due,
        res.guard,
        sigma_h,
        watch_settings(sc.evaluation),
        adapts(next((m for m in sc.methods if m.name == name), None), sc.sensor_names),
    )


def _mean_nis(w: MethodWatch | None) -> dict[str, float] | None:
    return None if w is None else {a.name: a.mean_nis for a in w.aids}


def readmitted_fraction(
    flag: np.ndarray, t: np.ndarray, windows: list[tuple[float, float]]
) -> float | None:
    """Fraction of (run, fault) events whose aid is re-admitted (its flag clears) after the
    fault's end, before the run ends; None without a fault window."""
    ends = [e for s, e in windows if (t >= s).any() and e <= t[-1]]
    if not ends:
        return None
    back = [(~flag[:, t >= e]).any(1) for e in ends]
    return float(np.mean(back))


def evaluate(result: ScenarioResult) -> dict[str, MethodMetrics]:
    """Compute every metric of every method."""
    sc = result.scenario
    t = sc.times
    states = sc.metric_states
    window = t >= sc.evaluation.skip_initial
    in_fault = sc.fault_mask() & window
    out_fault = ~sc.fault_mask() & window
    methods = {m.name: m for m in sc.methods}
    central = next(
        (
            n
            for n, m in methods.items()
            if m.architecture == "centralized"
            and m.detector.kind == "none"
            and m.noise.kind == "none"
            and n in result.results
        ),
        None,
    )
    out: dict[str, MethodMetrics] = {}
    for name, res in result.results.items():
        err = res.error
        norms = _norms(err, states)
        es = error_stats(err, window)
        es_norms = None if norms is None else error_stats(norms, window)
        ns = nees_stats(res.nees, len(states), window)
        detection: dict[str, DetectionMetrics] | None = None
        det_ci: dict[str, DetectionIntervals] | None = None
        if res.flag is not None:
            detection, det_ci = {}, {}
            for i, sensor in enumerate(sc.sensor_names):
                wins = [
                    (f.start, f.end) for f in sc.faults if f.sensor == sensor and f.kind != "outage"
                ]
                ev = detection_events(res.flag[..., i], t, wins, sc.evaluation.grace)
                det_ci[sensor] = detection_intervals(ev)
                detection[sensor] = DetectionMetrics.of(
                    summarize_detection(ev), readmitted_fraction(res.flag[..., i], t, wins)
                )
        ff: FaultFreeMetrics | None = None
        ff_ci: tuple[dict[str, Interval], Interval] | None = None
        ff_res = result.fault_free.get(name)
        if ff_res is not None:
            ff_err = ff_res.error
            ff_norms = _norms(ff_err, states)
            ff_ns = nees_stats(ff_res.nees, len(states), window)
            ff = FaultFreeMetrics(
                rmse=_rmse(ff_err, ff_norms, states, window),
                rmse_fault_window=_rmse(ff_err, ff_norms, states, in_fault)
                if in_fault.any()
                else None,
                anees=float(ff_ns.anees),
                nees_in_band_fraction=float(ff_ns.in_band_fraction),
                nis=_mean_nis(watched(name, ff_res, sc)),
            )
            ff_ci = (
                _per_run(ff_err, ff_norms, states, window)[0],
                _anees_interval(ff_res.nees, window),
            )
        w = watched(name, res, sc)
        rel = None
        if central is not None and name != central:
            ref_res = result.fault_free.get(central) if ff_res is not None else None
            if ff_res is not None and ref_res is not None:
                rel = _max_rel_diff(_compared(ff_res), _compared(ref_res))
            else:
                rel = _max_rel_diff(_compared(res), _compared(result.results[central]))
        rmse_ci, ensemble_ci = _per_run(err, norms, states, window)
        intervals = MetricIntervals(
            rmse=rmse_ci,
            rmse_fault=_per_run(err, norms, states, in_fault)[0] if in_fault.any() else None,
            rmse_nofault=_per_run(err, norms, states, out_fault)[0] if out_fault.any() else None,
            ensemble_rmse=ensemble_ci,
            anees=_anees_interval(res.nees, window),
            detection=det_ci,
            fault_free_rmse=None if ff_ci is None else ff_ci[0],
            fault_free_anees=None if ff_ci is None else ff_ci[1],
        )
        out[name] = MethodMetrics(
            architecture=methods[name].architecture if name in methods else "",
            rmse=_with_norms(es.rmse, states, es_norms and es_norms.rmse),
            rmse_fault=_rmse(err, norms, states, in_fault) if in_fault.any() else None,
            rmse_nofault=_rmse(err, norms, states, out_fault) if out_fault.any() else None,
            ensemble_rmse=_with_norms(
                es.ensemble_rmse, states, es_norms and es_norms.ensemble_rmse
            ),
            max_abs_error=_with_norms(es.max_abs, states, es_norms and es_norms.max_abs),
            anees=float(ns.anees),
            anees_band=(float(ns.band[0]), float(ns.band[1])),
            nees_in_band_fraction=float(ns.in_band_fraction),
            detection=detection,
            fault_free=ff,
            max_rel_diff_to_centralized=rel,
            mean_beta=_named(res.beta[:, window].mean((0, 1)), sc.sensor_names)
            if res.beta is not None
            else None,
            nan_measurements={
                s: int(res.nan_count[:, i].sum()) for i, s in enumerate(sc.sensor_names)
            },
            nis=_mean_nis(w),
            integrity=w,
            intervals=intervals,
        )
    return out


def _method_json(m: MethodMetrics) -> dict[str, Any]:
    """One method's JSON form: its fields, the watch in its own JSON form."""
    doc = asdict(m)
    doc["integrity"] = None if m.integrity is None else m.integrity.as_dict()
    return doc


def _with_bounds(row: dict[str, Any], key: str, value: Any, ci: Interval | None) -> None:
    """``row[key]`` = ``value``, and ``key_lo`` / ``key_hi`` from its interval (if any)."""
    row[key] = value
    if ci is not None:
        row[f"{key}_lo"], row[f"{key}_hi"] = ci.lo, ci.hi


def _maps(
    row: dict[str, Any],
    prefix: str,
    values: dict[str, float] | None,
    cis: dict[str, Interval] | None,
) -> None:
    for name, v in (values or {}).items():
        _with_bounds(row, f"{prefix}.{name}", v, (cis or {}).get(name))


def metrics_frame(metrics: dict[str, MethodMetrics]) -> Any:
    """A :class:`pandas.DataFrame` of the metrics, one row per method (a campaign's
    counterpart of a recording's ``scores_frame``).

    Columns: ``architecture``; ``anees``, ``nees_in_band_fraction``,
    ``max_rel_diff_to_centralized``; ``rmse.<state>``, ``rmse_fault.<state>``,
    ``rmse_nofault.<state>``, ``ensemble_rmse.<state>`` (and the position norms);
    ``fault_free.anees`` and ``fault_free.rmse.<state>`` with a fault-free twin;
    ``detection.<sensor>.<field>`` (:class:`DetectionMetrics`) for a method with a
    detector.  A value with a 95 % interval has ``<column>_lo`` and ``<column>_hi``
    beside it; a column a method does not have is NaN in its row.
    """
    import pandas as pd

    rows: dict[str, dict[str, Any]] = {}
    for name, m in metrics.items():
        ci = m.intervals
        row: dict[str, Any] = {"architecture": m.architecture}
        _with_bounds(row, "anees", m.anees, None if ci is None else ci.anees)
        row["nees_in_band_fraction"] = m.nees_in_band_fraction
        row["max_rel_diff_to_centralized"] = m.max_rel_diff_to_centralized
        _maps(row, "rmse", m.rmse, None if ci is None else ci.rmse)
        _maps(row, "rmse_fault", m.rmse_fault, None if ci is None else ci.rmse_fault)
        _maps(row, "rmse_nofault", m.rmse_nofault, None if ci is None else ci.rmse_nofault)
        _maps(row, "ensemble_rmse", m.ensemble_rmse, None if ci is None else ci.ensemble_rmse)
        if m.fault_free is not None:
            ff = m.fault_free
            ff_ci = None if ci is None else ci.fault_free_anees
            _with_bounds(row, "fault_free.anees", ff.anees, ff_ci)
            _maps(row, "fault_free.rmse", ff.rmse, None if ci is None else ci.fault_free_rmse)
        for sensor, d in (m.detection or {}).items():
            dci = None if ci is None or ci.detection is None else ci.detection.get(sensor)
            for field, value in asdict(d).items():
                bound = getattr(dci, field, None) if dci is not None else None
                _with_bounds(row, f"detection.{sensor}.{field}", value, bound)
        rows[name] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def metrics_to_json(
    result: ScenarioResult,
    metrics: dict[str, MethodMetrics],
    claims: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The ``metrics.json`` document (stable contract; ``None`` is written as null)."""
    doc = {
        "scenario": result.scenario.name,
        "runs": result.runs,
        "seed": result.seed,
        "ftnav_version": __version__,
        "states": list(result.scenario.metric_states),
        "sensors": list(result.scenario.sensor_names),
        "methods": {name: _method_json(m) for name, m in metrics.items()},
    }
    if claims is not None:
        doc["claims"] = claims
    return doc
