"""Writing run outputs: ``metrics.json`` and ``estimates.nc`` (open formats only)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ftnav.eval.montecarlo import ScenarioResult

__all__ = ["write_metrics", "estimates_dataset", "write_estimates"]


def _clean(obj):
    """JSON-safe copy: tuples to lists, NaN/inf to null, numpy scalars to Python."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_metrics(doc: dict, path: Path) -> Path:
    """Write the metrics document as strict JSON (no NaN literals)."""
    path = Path(path)
    path.write_text(json.dumps(_clean(doc), indent=2, allow_nan=False) + "\n")
    return path


def estimates_dataset(result: ScenarioResult, fault_free: bool = False):
    """xarray Dataset of per-epoch estimates (dims method, run, time, state, sensor).

    Variables: ``x_hat`` and ``P_diag`` (method, run, time, state); ``truth``
    (run, time, state); ``fault_flag`` (method, run, time, sensor) as int8 for
    methods with a detector (``-1`` for methods without one); ``beta``
    (method, run, time, sensor) for federated methods (NaN otherwise).
    """
    import xarray as xr

    sc = result.scenario
    res = result.fault_free if fault_free else result.results
    sim = result.fault_free_simulation if fault_free else result.simulation
    names = list(res)
    first = res[names[0]]
    B, K, n = first.x.shape
    N = len(sc.sensors)
    flag = np.full((len(names), B, K, N), -1, dtype=np.int8)
    beta = np.full((len(names), B, K, N), np.nan)
    for j, name in enumerate(names):
        if res[name].flag is not None:
            flag[j] = res[name].flag
        if res[name].beta is not None:
            beta[j] = res[name].beta
    coords = {"method": names, "run": np.arange(B), "time": sc.times,
              "state": list(sc.model.states), "sensor": list(sc.sensor_names)}
    ds = xr.Dataset(
        {
            "x_hat": (("method", "run", "time", "state"), np.stack([res[m].x for m in names])),
            "P_diag": (("method", "run", "time", "state"),
                       np.stack([res[m].P_diag for m in names])),
            "truth": (("run", "time", "state"), sim.truth[..., :n]),
            "fault_flag": (("method", "run", "time", "sensor"), flag),
            "beta": (("method", "run", "time", "sensor"), beta),
        },
        coords=coords,
        attrs={"scenario": sc.name, "runs": result.runs, "seed": result.seed,
               "condition": "fault-free" if fault_free else "with faults",
               "fault_flag": "1 flagged, 0 not flagged, -1 method has no detector"},
    )
    ds["time"].attrs["units"] = "s"
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
