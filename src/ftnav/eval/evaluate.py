"""Turn a :class:`~ftnav.eval.montecarlo.ScenarioResult` into typed metrics (spec §11).

The JSON form (``metrics.json``) is a stable contract, documented in
``docs/architecture.md``: top-level ``scenario``, ``runs``, ``seed``,
``methods``; ``methods[name]`` holds ``rmse``, ``rmse_fault``, ``rmse_nofault``
(state name → float, mean over runs of the per-run RMSE), ``anees`` and, for a
method with a detector, ``detection[sensor]`` = {``rate``, ``false_alarm_rate``,
``mean_delay_s``, ...}.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from ftnav.eval.metrics import detection_stats, error_stats, nees_stats
from ftnav.eval.montecarlo import MethodResult, ScenarioResult

__all__ = ["MethodMetrics", "evaluate", "metrics_to_json"]


@dataclass(frozen=True, slots=True)
class MethodMetrics:
    """Metrics of one method; maps are keyed by state or sensor name."""

    architecture: str
    rmse: dict[str, float]
    rmse_fault: dict[str, float] | None
    rmse_nofault: dict[str, float] | None
    ensemble_rmse: dict[str, float]
    max_abs_error: dict[str, float]
    anees: float
    anees_band: tuple[float, float]
    nees_in_band_fraction: float
    detection: dict[str, dict[str, float]] | None
    fault_free: dict[str, dict[str, float] | None] | None
    max_rel_diff_to_centralized: float | None
    mean_beta: dict[str, float] | None
    nan_measurements: dict[str, int]


def _named(values: np.ndarray, names) -> dict[str, float]:
    return {n: float(v) for n, v in zip(names, values, strict=True)}


def _errors(res: MethodResult, truth: np.ndarray) -> np.ndarray:
    return res.x - truth[..., : res.x.shape[-1]]


def _max_rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    scale = max(1.0, float(np.abs(b).max()))
    return float(np.abs(a - b).max() / scale)


def evaluate(result: ScenarioResult) -> dict[str, MethodMetrics]:
    """Compute every metric of every method."""
    sc = result.scenario
    t = sc.times
    states = sc.model.states
    window = t >= sc.evaluation.skip_initial
    in_fault = sc.fault_mask() & window
    out_fault = ~sc.fault_mask() & window
    truth = result.simulation.truth
    methods = {m.name: m for m in sc.methods}
    central = next((n for n, m in methods.items() if m.architecture == "centralized"
                    and m.detector == "none" and m.adaptive_noise == "none"
                    and n in result.results), None)
    out: dict[str, MethodMetrics] = {}
    for name, res in result.results.items():
        err = _errors(res, truth)
        es = error_stats(err, window)
        ns = nees_stats(res.nees, len(states), window)
        detection = None
        if res.flag is not None:
            detection = {}
            for i, s in enumerate(sc.sensors):
                wins = [(f.start, f.end) for f in sc.faults
                        if f.sensor == s.name and f.kind != "outage"]
                d = detection_stats(res.flag[..., i], t, wins, sc.evaluation.grace)
                detection[s.name] = {k: (None if isinstance(v, float) and math.isnan(v)
                                         else float(v)) for k, v in d._asdict().items()}
        ff = None
        ff_res = result.fault_free.get(name)
        if ff_res is not None:
            ff_err = _errors(ff_res, result.fault_free_simulation.truth)
            ff = {
                "rmse": _named(error_stats(ff_err, window).rmse, states),
                "rmse_fault_window": _named(error_stats(ff_err, in_fault).rmse, states)
                if in_fault.any() else None,
            }
        rel = None
        if central is not None and name != central:
            ref_res = result.fault_free.get(central) if ff_res is not None else None
            if ref_res is not None:
                rel = _max_rel_diff(ff_res.x, ref_res.x)
            else:
                rel = _max_rel_diff(res.x, result.results[central].x)
        out[name] = MethodMetrics(
            architecture=methods[name].architecture if name in methods else "",
            rmse=_named(es.rmse, states),
            rmse_fault=_named(error_stats(err, in_fault).rmse, states) if in_fault.any()
            else None,
            rmse_nofault=_named(error_stats(err, out_fault).rmse, states) if out_fault.any()
            else None,
            ensemble_rmse=_named(es.ensemble_rmse, states),
            max_abs_error=_named(es.max_abs, states),
            anees=float(ns.anees),
            anees_band=(float(ns.band[0]), float(ns.band[1])),
            nees_in_band_fraction=float(ns.in_band_fraction),
            detection=detection,
            fault_free=ff,
            max_rel_diff_to_centralized=rel,
            mean_beta=_named(res.beta[:, window].mean((0, 1)), sc.sensor_names)
            if res.beta is not None else None,
            nan_measurements={s.name: int(res.nan_count[:, i].sum())
                              for i, s in enumerate(sc.sensors)},
        )
    return out


def metrics_to_json(result: ScenarioResult, metrics: dict[str, MethodMetrics],
                    claims: list[dict] | None = None) -> dict:
    """The ``metrics.json`` document (stable contract; ``None`` is written as null)."""
    from ftnav import __version__

    doc = {
        "scenario": result.scenario.name,
        "runs": result.runs,
        "seed": result.seed,
        "ftnav_version": __version__,
        "states": list(result.scenario.model.states),
        "sensors": list(result.scenario.sensor_names),
        "methods": {name: asdict(m) for name, m in metrics.items()},
    }
    if claims is not None:
        doc["claims"] = claims
    return doc
