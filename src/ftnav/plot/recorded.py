"""Figures of a processed recording: the track, the errors, the detectors per aid.

* ``track.png`` — each method's horizontal track (East, North metres from the first
  reference fix) over the reference fixes, the reference inside GNSS outages (red) and
  inside injected fault windows (purple) marked;
* ``errors.png`` — per method (rows), the horizontal error against the reference (log
  scale) and the vertical one, at the point the reference measures (the antenna), as
  the scores, each with the filter's 3σ, outages and faults shaded;
* ``innovations.png`` — per aid (rows), for every method with a fault detector, the
  detector statistic normalized by its threshold (log scale, the threshold at 1) at the
  epochs the aid measured, its flags marked, outages and faults shaded.  The engine
  does not record innovations nor the NIS of methods without a detector: when no method
  has one, the figure shows instead the σ of the measurement noise used per aid row
  (√ of the R̂ diagonal, adapted under VB) and says so in its title.

When the outage schedule is split into interleaved runs (``LoadedRecording.outages``),
every epoch is drawn from the run whose outage covers it (run 0 elsewhere), so each
outage's drift shows in one curve.  Built as plain :class:`~matplotlib.figure.Figure`
objects (no pyplot state).
"""

from __future__ import annotations

import pathlib
from collections.abc import Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ftnav.engine.driver import Trace
from ftnav.eval.recorded import errors_at
from ftnav.io.recording_file import LoadedRecording
from ftnav.io.solution_file import measurement_rows
from ftnav.nav.earth import enu_metres, radii

__all__ = ["errors_figure", "innovations_figure", "save_recording_figures", "track_figure"]

_OUTAGE, _FAULT = "tab:red", "tab:purple"
#: method colours: tab10 without the red and purple of the outage and fault marks
_PALETTE = ("C0", "C1", "C2", "C5", "C6", "C8", "C9", "C7")


def _colors(traces: Mapping[str, Trace]) -> dict[str, str]:
    return {nm: _PALETTE[j % len(_PALETTE)] for j, nm in enumerate(traces)}


def _windows(loaded: LoadedRecording) -> list[tuple[float, float, str]]:
    """Every run's outages and the faults, clipped to the processed span (s after
    ``t_start``)."""
    rec = loaded.recording
    end = float(rec.times[-1])
    out = [(s, e, "outage") for run in loaded.outages for s, e in run]
    out += [(f.start, f.end, f"{f.kind} on {f.sensor}") for f in rec.faults]
    return [(max(s, 0.0), min(e, end), k) for s, e, k in out if s < end and e > 0.0]


def _runs(loaded: LoadedRecording) -> np.ndarray:
    """(K,) the run each epoch is drawn from: the one whose outage covers it, else 0."""
    t = loaded.recording.times
    pick = np.zeros(len(t), int)
    for g, run in enumerate(loaded.outages):
        for s, e in run:
            pick[(t >= s) & (t < e)] = g
    return pick


def _pick(a: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """``a`` (B, K, …) → (K, …): epoch k of run ``runs[k]``."""
    runs = np.minimum(runs, a.shape[0] - 1)
    return a[runs, np.arange(a.shape[1])]


def _shade(ax, loaded: LoadedRecording) -> None:
    for s0, e0, kind in _windows(loaded):
        ax.axvspan(s0, e0, color=_OUTAGE if kind == "outage" else _FAULT, alpha=0.13, lw=0)


def _time_axis(ax, loaded: LoadedRecording) -> None:
    rec = loaded.recording
    ax.set_xlim(0.0, float(rec.times[-1]))
    ax.set_xlabel(f"time (s after {rec.t_start:.3f} s, the recording's time base)")


def _enu(p: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """(K, 2) East, North metres of positions ``p`` from ``origin`` (the track's plane)."""
    return enu_metres(p, np.broadcast_to(origin, p.shape))[:, :2]


def _finish_panel(ax: Axes, loaded: LoadedRecording, empty: str | None) -> None:
    """An aid's panel: ``empty`` said in its middle (None: it has data), the outage and
    fault windows shaded, the grid, the legend outside on the right."""
    if empty is not None:
        ax.text(0.5, 0.35, empty, transform=ax.transAxes, ha="center", color="0.35")
    _shade(ax, loaded)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=7)


def _note(loaded: LoadedRecording) -> str:
    n = len(loaded.outages)
    return f"\n(outages from {n} interleaved runs, each drawn from its run)" if n > 1 else ""


def track_figure(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Figure:
    """Horizontal tracks over the reference (module docstring)."""
    rec = loaded.recording
    runs = _runs(loaded)
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    ax = fig.add_subplot()
    origin = loaded.reference_p[0]
    ref = _enu(loaded.reference_p, origin)
    ax.plot(ref[:, 0], ref[:, 1], ".", color="0.55", ms=2, label="reference fixes", zorder=1)
    t_ref = rec.times[loaded.reference_index]
    marked = {"outage": False, "fault": False}
    for s, e, kind in _windows(loaded):
        key = "outage" if kind == "outage" else "fault"
        w = (t_ref >= s) & (t_ref < e)
        ax.plot(
            ref[w, 0],
            ref[w, 1],
            ".",
            ms=4,
            color=_OUTAGE if key == "outage" else _FAULT,
            label=None if marked[key] else f"reference in GNSS {key}s",
            zorder=3,
        )
        marked[key] = True
    colors = _colors(traces)
    for name, tr in traces.items():
        assert tr.solution is not None
        xy = _enu(_pick(tr.solution.p, runs), origin)
        ax.plot(xy[:, 0], xy[:, 1], lw=1.0, color=colors[name], label=name, zorder=2)
    ax.plot(0.0, 0.0, "k^", ms=6, label="first reference fix", zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    ax.grid(alpha=0.3)
    ax.set_title(f"{rec.name}: horizontal track over the reference{_note(loaded)}", fontsize=10)
    ax.legend(loc="best", fontsize=8, framealpha=0.85)
    return fig


def errors_figure(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Figure:
    """Horizontal and vertical errors against the reference with 3σ (module docstring)."""
    rec = loaded.recording
    n = len(traces)
    fig = Figure(figsize=(10.0, 2.5 * n + 0.9), layout="constrained")
    axes = fig.subplots(n, 2, squeeze=False, sharex=True)
    idx = loaded.reference_index
    t = rec.times[idx]
    runs = _runs(loaded)[idx]
    for row, (name, tr) in zip(axes, traces.items(), strict=True):
        assert tr.solution is not None
        p = _pick(tr.solution.p[:, idx], runs)
        # at the point the reference measures (the antenna), as the scores
        q = _pick(tr.solution.q[:, idx], runs)
        err = errors_at(p, q, loaded.reference_p, loaded.reference_lever_arm)
        RM, RN = radii(p[:, 0], p[:, 2])
        var = np.maximum(_pick(tr.P_diag[:, idx], runs), 0.0)
        s_h = np.sqrt(var[:, 6] * RM**2 + var[:, 7] * (RN * np.cos(p[:, 0])) ** 2)
        s_u = np.sqrt(var[:, 8])
        e_h = np.hypot(err[:, 0], err[:, 1])
        ax = row[0]
        ax.plot(t, np.maximum(e_h, 1e-4), lw=0.8, color="C0", label="horizontal error")
        ax.plot(t, 3 * s_h, color="0.3", lw=0.7, ls="--", label="3σ (filter)")
        ax.set_yscale("log")
        ax.set_ylabel(f"{name}\nhorizontal (m)")
        ax = row[1]
        ax.plot(t, err[:, 2], lw=0.8, color="C1", label="up error")
        ax.plot(t, 3 * s_u, color="0.3", lw=0.7, ls="--", label="±3σ (filter)")
        ax.plot(t, -3 * s_u, color="0.3", lw=0.7, ls="--")
        # the initial σ would flatten the rest: limits from the errors and the settled σ
        finite = np.isfinite(err[:, 2])
        lim = max(
            np.abs(err[finite, 2]).max(initial=0.0),
            3 * np.percentile(s_u, 90) if len(s_u) else 0.0,
            0.05,
        )
        ax.set_ylim(-1.15 * lim, 1.15 * lim)
        ax.set_ylabel(f"{name}\nup (m)")
        for ax in row:
            _shade(ax, loaded)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        _time_axis(ax, loaded)
    handles = [h for ax in axes[0] for h in ax.get_legend_handles_labels()[0]][:4]
    labels = [lb for ax in axes[0] for lb in ax.get_legend_handles_labels()[1]][:4]
    fig.legend(handles, labels, loc="outside lower center", ncols=4, fontsize=8)
    fig.suptitle(
        f"{rec.name}: error against the reference (shaded: red GNSS outages, purple "
        f"faults){_note(loaded)}",
        fontsize=10,
    )
    return fig


def innovations_figure(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Figure:
    """Per aid, the detectors' normalized statistics and flags, or the R̂ σ (module
    docstring)."""
    rec = loaded.recording
    t = rec.times
    runs = _runs(loaded)
    aids = rec.sensor_names
    avail = [_pick(np.asarray(a.available, bool), runs) for a in loaded.stream.aids]
    detectors = {
        nm: tr for nm, tr in traces.items() if tr.statistic is not None and tr.threshold is not None
    }
    fig = Figure(figsize=(10.0, 2.3 * len(aids) + 0.9), layout="constrained")
    axes = fig.subplots(len(aids), 1, squeeze=False, sharex=True)[:, 0]
    colors = _colors(traces)
    if detectors:
        for i, (ax, aid) in enumerate(zip(axes, aids, strict=True)):
            drawn = False
            for nm, tr in detectors.items():
                assert tr.statistic is not None and tr.threshold is not None
                thr = _pick(tr.threshold[..., i], runs)
                tested = avail[i] & np.isfinite(thr) & (thr > 0)
                if not tested.any():
                    continue
                drawn = True
                stat = _pick(tr.statistic[..., i], runs)
                ratio = np.maximum(stat[tested] / thr[tested], 1e-4)
                ax.plot(t[tested], ratio, ".", ms=2.5, color=colors[nm], label=nm)
                if tr.flag is not None:
                    f = _pick(tr.flag[..., i], runs)[tested]
                    if f.any():
                        ax.plot(
                            t[tested][f],
                            ratio[f],
                            "x",
                            ms=5,
                            mew=0.9,
                            color="k",
                            label=f"{nm} flagged ({int(f.sum())} epochs)",
                        )
            ax.axhline(1.0, color="k", lw=0.8, ls="--", label="threshold")
            ax.set_yscale("log")
            ax.set_ylabel(f"{aid}\nstatistic / threshold")
            _finish_panel(ax, loaded, None if drawn else f"{aid}: never measured, nothing tested")
        title = (
            f"{rec.name}: fault detector statistic per aid over its threshold, at the epochs "
            "the aid measured\n(shaded: red GNSS outages, purple faults)"
        )
    else:
        rows = measurement_rows(loaded)
        styles = ("-", "--", ":", "-.")
        for i, (ax, aid) in enumerate(zip(axes, aids, strict=True)):
            mine = [(j, c, u) for j, (a, c, u) in enumerate(rows) if a == aid]
            offset = mine[0][0]
            for jc, (j, c, _) in enumerate(mine):
                for k, (nm, tr) in enumerate(traces.items()):
                    r = _pick(tr.R_hat[i][..., j - offset], runs)[avail[i]]
                    ax.plot(
                        t[avail[i]],
                        np.sqrt(np.maximum(r, 0.0)),
                        lw=1.0,
                        color=_PALETTE[jc % len(_PALETTE)],
                        ls=styles[k % len(styles)],
                        label=f"{nm} {c}" if len(traces) > 1 else c,
                    )
            units = ", ".join(sorted({u for _, _, u in mine}))
            ax.set_ylabel(f"{aid}\nσ of R̂ ({units})")
            if avail[i].any():
                ax.set_yscale("log")
            _finish_panel(ax, loaded, None if avail[i].any() else f"{aid}: never measured")
        title = (
            f"{rec.name}: no method has a fault detector and the NIS is not recorded; shown: "
            "the σ of the measurement noise used\nper aid row at the epochs the aid measured "
            "(shaded: red GNSS outages, purple faults)"
        )
    _time_axis(axes[-1], loaded)
    fig.suptitle(title + _note(loaded).replace("\n", " "), fontsize=10)
    return fig


def save_recording_figures(
    loaded: LoadedRecording, traces: Mapping[str, Trace], folder: pathlib.Path
) -> list[pathlib.Path]:
    """Write ``track.png``, ``errors.png`` and ``innovations.png`` into ``folder``; their
    paths."""
    out = []
    for name, make in (
        ("track.png", track_figure),
        ("errors.png", errors_figure),
        ("innovations.png", innovations_figure),
    ):
        path = folder / name
        make(loaded, traces).savefig(path, dpi=110)
        out.append(path)
    return out
