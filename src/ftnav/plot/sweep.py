"""Figures of a parameter sweep (:mod:`ftnav.sweep`): each metric against each swept key,
one line per method with its 95 % interval as a band; and for a key of a method's
setting (a detector's false-alarm probability, its window) the ROC it traces: the
detection probability against the false-alarm rate, one point per value, with both
intervals.

With several swept keys, the figure of one key holds the others at their first value
(the title says which).  The detection figures show each sensor that some method's
detector is scored on (a fault of that sensor at some point of the grid).
"""

from __future__ import annotations

import pathlib
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

__all__ = ["roc_figure", "save_sweep_figures", "swept", "sweep_figure"]

#: (variable, y label) of the figures, in order.
_METRICS = (
    ("detection_rate", "detection probability per epoch"),
    ("detection_false_alarm_rate", "false alarms per clean epoch"),
    ("detection_mean_delay_s", "mean detection delay [s]"),
    ("rmse", "RMSE"),
    ("anees", "ANEES"),
)


def swept(ds: xr.Dataset) -> list[str]:
    """The swept keys: the dimensions before ``method``."""
    return [str(d) for d in ds["anees"].dims if d not in ("method", "bound")]


def _state(ds: xr.Dataset) -> str:
    states = [str(s) for s in ds["state"].values]
    return "pos_horizontal_m" if "pos_horizontal_m" in states else states[0]


def sweep_figure(ds: xr.Dataset, key: str, variable: str, ylabel: str) -> Figure | None:
    """``variable`` against the swept ``key``, per method (and sensor), with bands; None
    when no method has a value of it anywhere."""
    da = ds[variable]
    others = {d: 0 for d in swept(ds) if d != key and d in da.dims}
    da = da.isel(others)
    if "state" in da.dims:
        state = _state(ds)
        da = da.sel(state=state)
        ylabel = f"{ylabel} of {state}"
    series: list[tuple[str, Any]] = []
    for m in ds["method"].values:
        one = da.sel({"method": m})
        if "sensor" in one.dims:
            for s in ds["sensor"].values:
                line = one.sel(sensor=s)
                if np.isfinite(line.sel(bound="value")).any():
                    series.append((f"{m} ({s})", line))
        elif np.isfinite(one.sel(bound="value")).any():
            series.append((str(m), one))
    if not series:
        return None
    x = ds[key].values
    numeric = np.issubdtype(np.asarray(x).dtype, np.number)
    pos = x if numeric else np.arange(len(x))
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.add_subplot()
    for label, line in series:
        v = line.sel(bound="value").values
        lo, hi = line.sel(bound="lo").values, line.sel(bound="hi").values
        (h,) = ax.plot(pos, v, marker="o", label=label)
        ok = np.isfinite(lo) & np.isfinite(hi)
        if ok.any():
            ax.fill_between(pos[ok], lo[ok], hi[ok], color=h.get_color(), alpha=0.2, lw=0)
    if not numeric:
        ax.set_xticks(pos, [str(v) for v in x])
    _finish(ax, ds, others, key, ylabel, f"{ds.attrs.get('runs', '')} runs per point, 95 % bands")
    return fig


def _finish(ax: Any, ds: xr.Dataset, others: dict[str, int], x: str, y: str, what: str) -> None:
    """Axis labels, the title (the scenario, ``what``, the keys held), grid and legend."""
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    held = ", ".join(f"{d}={ds[d].values[0]}" for d in others)
    title = f"{ds.attrs.get('scenario', '')}: {what}"
    ax.set_title(title + (f"\n({held})" if held else ""), fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)


def roc_figure(ds: xr.Dataset, key: str) -> Figure | None:
    """The detection probability against the false-alarm rate as ``key`` varies, per
    method and sensor whose pair moves with it (95 % intervals as error bars, each point
    labelled with its value of ``key``); None when no pair moves."""
    pd, fa = ds["detection_rate"], ds["detection_false_alarm_rate"]
    others = {d: 0 for d in swept(ds) if d != key}
    pd, fa = pd.isel(others), fa.isel(others)
    values = ds[key].values
    series = []
    for m in ds["method"].values:
        for s in ds["sensor"].values:
            y, x = pd.sel({"method": m, "sensor": s}), fa.sel({"method": m, "sensor": s})
            yv, xv = y.sel(bound="value").values, x.sel(bound="value").values
            ok = np.isfinite(xv) & np.isfinite(yv)
            if ok.sum() < 2 or (np.ptp(xv[ok]) == 0 and np.ptp(yv[ok]) == 0):
                continue
            series.append((f"{m} ({s})", x, y, ok))
    if not series:
        return None
    fig = Figure(figsize=(6.4, 4.6), layout="constrained")
    ax = fig.add_subplot()
    positive = []
    for label, x, y, ok in series:
        (xv, xerr), (yv, yerr) = _bars(x, ok), _bars(y, ok)
        order = np.argsort(xv)
        ax.errorbar(
            xv[order],
            yv[order],
            xerr=xerr[:, order],
            yerr=yerr[:, order],
            marker="o",
            capsize=2,
            label=label,
        )
        for xi, yi, v in zip(xv, yv, values[ok], strict=True):
            ax.annotate(
                f"{v:g}" if isinstance(v, float) else str(v),
                (xi, yi),
                fontsize=6,
                xytext=(3, -9),
                textcoords="offset points",
            )
        positive += [float(v) for v in xv if v > 0]
    if positive and max(positive) > 20 * min(positive):
        ax.set_xscale("symlog", linthresh=min(positive))
    x_label, y_label = "false alarms per clean epoch", "detection probability per epoch"
    _finish(ax, ds, others, x_label, y_label, f"ROC over {key}, 95 % intervals")
    return fig


def _bars(da: xr.DataArray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The values of ``da`` where ``ok`` and their (2, n) error bars to ``lo`` and ``hi``
    (0 where a bound is missing)."""
    v = da.sel(bound="value").values[ok]
    lo, hi = da.sel(bound="lo").values[ok], da.sel(bound="hi").values[ok]
    return v, np.nan_to_num(np.abs(np.stack([v - lo, hi - v])))


def save_sweep_figures(ds: xr.Dataset, folder: pathlib.Path) -> list[pathlib.Path]:
    """Every figure of the sweep as ``sweep_<metric>_<key>.png`` in ``folder``, and for a
    key of a method's setting its ROC as ``sweep_roc_<key>.png``."""
    out = []
    for key in swept(ds):
        for variable, ylabel in _METRICS:
            fig = sweep_figure(ds, key, variable, ylabel)
            if fig is None:
                continue
            name = f"sweep_{variable.removeprefix('detection_')}_{_safe(key)}.png"
            fig.savefig(folder / name, dpi=110)
            out.append(folder / name)
        roc = roc_figure(ds, key) if key.startswith("methods.") else None
        if roc is not None:
            name = f"sweep_roc_{_safe(key)}.png"
            roc.savefig(folder / name, dpi=110)
            out.append(folder / name)
    return out


def _safe(key: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in key)
