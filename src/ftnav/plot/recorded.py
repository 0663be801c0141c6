"""Figures of a processed recording: the track over the reference, and the errors.

* ``track.png`` — each method's horizontal track (East, North metres from the start)
  over the reference fixes, the GNSS outages and the injected fault windows marked on
  the reference;
* ``errors.png`` — per method, the horizontal and the vertical error against the
  reference over time with the filter's ±3σ, outages and faults shaded.

Built as plain :class:`~matplotlib.figure.Figure` objects (no pyplot state).
"""

from __future__ import annotations

import pathlib
from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from ftnav.engine.driver import Trace
from ftnav.eval.recorded import horizontal_errors
from ftnav.io.recording_file import LoadedRecording
from ftnav.nav.earth import radii

__all__ = ["save_recording_figures"]


def _windows(loaded: LoadedRecording) -> list[tuple[float, float, str]]:
    rec = loaded.recording
    out = [(s, e, "outage") for s, e in loaded.outages[0]]
    return out + [(f.start, f.end, f"{f.kind} on {f.sensor}") for f in rec.faults]


def _enu(p: np.ndarray, origin: np.ndarray) -> np.ndarray:
    RM, RN = radii(origin[0], origin[2])
    return np.stack(
        [(p[:, 1] - origin[1]) * RN * np.cos(origin[0]), (p[:, 0] - origin[0]) * RM], -1
    )


def track_figure(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Figure:
    """Horizontal tracks over the reference (module docstring)."""
    rec = loaded.recording
    fig = Figure(figsize=(7.5, 7.0), layout="constrained")
    ax = fig.add_subplot()
    origin = loaded.reference_p[0]
    ref = _enu(loaded.reference_p, origin)
    ax.plot(ref[:, 0], ref[:, 1], ".", color="0.6", ms=2, label="reference")
    t_ref = rec.times[loaded.reference_index]
    for s, e, _ in _windows(loaded):
        w = (t_ref >= s) & (t_ref < e)
        ax.plot(ref[w, 0], ref[w, 1], ".", ms=3, color="tab:red", label=None)
    for name, tr in traces.items():
        assert tr.solution is not None
        xy = _enu(tr.solution.p[0], origin)
        ax.plot(xy[:, 0], xy[:, 1], lw=0.9, label=name)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    ax.set_title(f"{rec.name}: track (red: reference inside outages and faults)")
    ax.legend(loc="best", fontsize=8)
    return fig


def errors_figure(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Figure:
    """Horizontal and vertical errors against the reference with ±3σ (module docstring)."""
    rec = loaded.recording
    n = len(traces)
    fig = Figure(figsize=(9.0, 2.6 * n + 0.6), layout="constrained")
    axes = fig.subplots(n, 2, squeeze=False, sharex=True)
    idx = loaded.reference_index
    t = rec.times[idx]
    for row, (name, tr) in zip(axes, traces.items(), strict=True):
        assert tr.solution is not None
        err = horizontal_errors(tr.solution.p[0, idx], loaded.reference_p)
        p = tr.solution.p[0, idx]
        RM, RN = radii(p[:, 0], p[:, 2])
        var = tr.P_diag[0, idx]
        s_h = np.sqrt(var[:, 6] * RM**2 + var[:, 7] * (RN * np.cos(p[:, 0])) ** 2)
        s_u = np.sqrt(var[:, 8])
        for ax, e, s, label in (
            (row[0], np.hypot(err[:, 0], err[:, 1]), s_h, "horizontal"),
            (row[1], err[:, 2], s_u, "up"),
        ):
            ax.plot(t, e, lw=0.8, label=f"{name} {label} error")
            ax.plot(t, 3 * s, color="0.4", lw=0.6, ls="--", label="±3σ")
            if label == "up":
                ax.plot(t, -3 * s, color="0.4", lw=0.6, ls="--")
            for s0, e0, _ in _windows(loaded):
                ax.axvspan(s0, e0, color="tab:red", alpha=0.12, lw=0)
            ax.set_ylabel(f"{label} (m)")
            ax.legend(loc="upper left", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel(f"time after {rec.t_start:.3f} s (s)")
    fig.suptitle(f"{rec.name}: errors against the reference (shaded: outages, faults)")
    return fig


def save_recording_figures(
    loaded: LoadedRecording, traces: Mapping[str, Trace], folder: pathlib.Path
) -> list[pathlib.Path]:
    """Write ``track.png`` and ``errors.png`` into ``folder``; their paths."""
    out = []
    for name, fig in (
        ("track.png", track_figure(loaded, traces)),
        ("errors.png", errors_figure(loaded, traces)),
    ):
        path = folder / name
        fig.savefig(path, dpi=110)
        out.append(path)
    return out
