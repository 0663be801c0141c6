"""Writing run outputs: ``metrics.json`` and ``estimates.nc`` (open formats only)."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ftnav.engine.driver import Diverged, check_output
from ftnav.eval.evaluate import split_unit
from ftnav.eval.montecarlo import ScenarioResult
from ftnav.sim.linear import LinearTruth

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "write_metrics",
    "estimates_dataset",
    "write_estimates",
    "state_units",
    "METHOD_DIM",
    "flag_attrs",
]


def _clean(obj: object, path: tuple[str, ...] = ()) -> object:
    """JSON-safe copy: tuples to lists, NaN (not applicable) to null, numpy scalars to
    Python; an infinite number of a method is its divergence (:class:`Diverged`)."""
    if isinstance(obj, dict):
        return {str(k): _clean(v, (*path, str(k))) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v, (*path, str(i))) for i, v in enumerate(obj)]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and math.isinf(obj) and path[:1] == ("methods",):
        method = path[1] if len(path) > 1 else "?"
        raise Diverged(method, None, None, f"{'.'.join(path[2:])} is {obj} (not written)")
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_metrics(doc: dict[str, Any], path: Path) -> Path:
    """Write the metrics document as strict JSON (no NaN literals: null, "not
    applicable"); an infinite metric of a method raises :class:`Diverged` instead."""
    path = Path(path)
    path.write_text(json.dumps(_clean(doc), indent=2, allow_nan=False) + "\n", encoding="utf-8")
    return path


#: Dimension of the methods in ``estimates.nc``; ``method`` would collide with the
#: ``method`` keyword of xarray's ``.sel`` (nearest-neighbour lookup).
METHOD_DIM = "method_name"


def flag_attrs(long_name: str) -> dict[str, str | np.ndarray]:
    """netCDF attributes of a fault-flag variable (−1: the method has no detector)."""
    return {
        "units": "1",
        "long_name": long_name,
        "flag_values": np.array([-1, 0, 1], dtype=np.int8),
        "flag_meanings": "method_has_no_detector not_flagged flagged",
    }


def state_units(states: Sequence[str]) -> list[str]:
    """Unit of each state, from its name (``pos_E_m`` → ``m``); linear states: "state units".

    A linear scenario does not say in which units its states are: their unit is written
    as ``"state units"``.
    """
    return [split_unit(s)[1] or "state units" for s in states]


def estimates_dataset(result: ScenarioResult, fault_free: bool = False) -> xr.Dataset:
    """xarray Dataset of per-epoch estimates (dims method_name, run, time, state, sensor).

    Variables: ``error`` and ``P_diag`` (method_name, run, time, state), the error of the
    reported states (estimate − truth; an integrated run's navigation output error,
    computed − true) and its variance; a linear scenario also has ``x_hat`` (the fused
    estimate) and ``truth`` (run, time, state); ``fault_flag`` (method_name, run, time,
    sensor) as int8 for methods with a detector (``-1`` for methods without one);
    ``beta`` (method_name, run, time, sensor) for federated methods (NaN otherwise).
    A NaN or inf estimate or error, or a negative variance, raises
    :class:`~ftnav.engine.driver.Diverged` (it is never written).
    Every variable and coordinate has ``units`` and ``long_name`` attributes; the
    coordinate ``state_units`` (along ``state``) gives each state's unit.  Select a
    method with ``ds.error.sel(method_name="ckf")``.
    """
    import xarray as xr

    sc = result.scenario
    res = result.fault_free if fault_free else result.results
    names = list(res)
    for name in names:  # no NaN estimate, no negative variance is ever written
        check_output(name, (res[name].error, res[name].estimate), (res[name].P_diag,), sc.times)
    first = res[names[0]]
    B, K, n = first.error.shape
    N = len(sc.sensor_names)
    flag = np.full((len(names), B, K, N), -1, dtype=np.int8)
    beta = np.full((len(names), B, K, N), np.nan)
    for j, name in enumerate(names):
        r = res[name]
        if r.flag is not None:
            flag[j] = r.flag
        if r.beta is not None:
            beta[j] = r.beta
    states = list(sc.metric_states)
    units = state_units(states)
    known = any(u != "state units" for u in units)
    x_units = (
        "see state_units (one unit per state)"
        if known
        else "state units (the scenario does not give them)"
    )
    p_units = "square of state_units (per state)" if known else "state units squared"
    integrated = getattr(sc, "kind", "linear") == "integrated"
    M = METHOD_DIM
    variables: dict[str, tuple[tuple[str, ...], np.ndarray, dict[str, str]]] = {
        "error": (
            (M, "run", "time", "state"),
            np.stack([res[m].error for m in names]),
            {
                "units": x_units,
                "long_name": "navigation output error of each method (computed - true)"
                if integrated
                else "estimation error of each method (fused estimate - truth)",
            },
        ),
        "P_diag": (
            (M, "run", "time", "state"),
            np.stack([res[m].P_diag for m in names]),
            {"units": p_units, "long_name": "variance of each state of the fused estimate"},
        ),
    }
    if not integrated:
        x_hat = []
        for m in names:
            estimate = res[m].estimate
            assert estimate is not None  # a linear model's methods keep their estimate
            x_hat.append(estimate)
        variables["x_hat"] = (
            (M, "run", "time", "state"),
            np.stack(x_hat),
            {"units": x_units, "long_name": "fused state estimate of each method"},
        )
        if isinstance(result.truth, LinearTruth):  # a linear scenario's truth, if kept
            variables["truth"] = (
                ("run", "time", "state"),
                result.truth.states[..., :n],
                {"units": x_units, "long_name": "true state"},
            )
    ds = xr.Dataset(
        {
            **variables,
            "fault_flag": (
                (M, "run", "time", "sensor"),
                flag,
                flag_attrs("fault flag after hysteresis"),
            ),
            "beta": (
                (M, "run", "time", "sensor"),
                beta,
                {
                    "units": "1",
                    "long_name": "federated sharing coefficient of each "
                    "local filter (NaN: method without sharing)",
                },
            ),
        },
        coords={
            M: (M, names, {"units": "none", "long_name": "fusion method (scenario name)"}),
            "run": ("run", np.arange(B), {"units": "1", "long_name": "Monte Carlo run index"}),
            "time": (
                "time",
                sc.times,
                {"units": "s", "long_name": "epoch time t_k = k dt since the start"},
            ),
            "state": ("state", states, {"units": "none", "long_name": "state name"}),
            "state_units": ("state", units, {"units": "none", "long_name": "unit of each state"}),
            "sensor": (
                "sensor",
                list(sc.sensor_names),
                {"units": "none", "long_name": "aiding sensor name"},
            ),
        },
        attrs={
            "scenario": sc.name,
            "runs": result.runs,
            "seed": result.seed,
            "condition": "fault-free" if fault_free else "with faults",
            "fault_flag": "1 flagged, 0 not flagged, -1 method has no detector",
        },
    )
    return ds


def write_estimates(result: ScenarioResult, out_dir: Path) -> list[Path]:
    """Write ``estimates.nc`` (and ``estimates_fault_free.nc`` when there is a twin run)."""
    out_dir = Path(out_dir)
    paths = []
    for ff, name in ((False, "estimates.nc"), (True, "estimates_fault_free.nc")):
        if ff and not result.fault_free:
            continue
        path = out_dir / name
        estimates_dataset(result, ff).to_netcdf(path, engine="scipy")
        paths.append(path)
    return paths
