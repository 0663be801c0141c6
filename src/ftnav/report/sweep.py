"""The Markdown report and terminal table of a parameter sweep (:mod:`ftnav.sweep`)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import xarray as xr

__all__ = ["sweep_report", "sweep_table"]


def _cell(values: np.ndarray, fmt: str) -> str:
    v, lo, hi = (float(x) for x in values)
    if not math.isfinite(v):
        return "-"
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return format(v, fmt)
    return f"{v:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]"


def _rows(ds: xr.Dataset) -> tuple[list[str], list[list[str]]]:
    dims = [str(d) for d in ds["anees"].dims if d not in ("method", "bound")]
    states = [str(s) for s in ds["state"].values]
    state = "pos_horizontal_m" if "pos_horizontal_m" in states else states[0]
    sensors = [
        str(s)
        for s in ds["sensor"].values
        if np.isfinite(ds["detection_rate"].sel(sensor=s, bound="value")).any()
    ]
    header = [*dims, "method", f"RMSE {state}", "ANEES"]
    header += [f"{s} Pd" for s in sensors] + [f"{s} false alarms" for s in sensors]
    rows = []
    for at in itertools.product(*(range(ds.sizes[d]) for d in dims)):
        point = ds.isel(dict(zip(dims, at, strict=True)))
        for m in ds["method"].values:
            one = point.sel({"method": m})
            row = [str(point[d].values) for d in dims] + [str(m)]
            row.append(_cell(one["rmse"].sel(state=state).values, ".3g"))
            row.append(_cell(one["anees"].values, ".3g"))
            row += [_cell(one["detection_rate"].sel(sensor=s).values, ".3f") for s in sensors]
            row += [
                _cell(one["detection_false_alarm_rate"].sel(sensor=s).values, ".1e")
                for s in sensors
            ]
            rows.append(row)
    return header, rows


def sweep_table(ds: xr.Dataset) -> str:
    """Fixed-width text: one row per grid point and method, values with 95 % intervals."""
    header, rows = _rows(ds)
    widths = [max(len(r[c]) for r in [header, *rows]) for c in range(len(header))]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)).rstrip()]
    lines.append("-" * len(lines[0]))
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    return "\n".join(lines)


def sweep_report(ds: xr.Dataset, command: str, figures: list[str]) -> str:
    """``report.md`` of a sweep: what ran, the table, the figures."""
    header, rows = _rows(ds)
    md = [
        f"# ftnav sweep: {ds.attrs.get('scenario', '')}",
        "",
        f"`{command}`",
        "",
        f"{ds.attrs.get('runs')} Monte Carlo runs per point, root seed {ds.attrs.get('seed')} "
        "at every point (the points differ only by the swept settings), ftnav "
        f"{ds.attrs.get('ftnav_version')}.  Each value with its 95 % interval [lo, hi] "
        f"({ds.attrs.get('intervals')}).  Every metric of every point: `sweep.nc`.",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
    ]
    md += ["| " + " | ".join(r) + " |" for r in rows]
    if figures:
        md += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(md) + "\n"
