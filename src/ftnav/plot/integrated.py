"""Figures of the integrated-navigation experiments (papers 001 and 002).

* :func:`local_fused_figure`: paper 001 Fig. 4-5, latitude (North) and longitude
  (East) errors in metres of every local filter and of the fused estimate, with and
  without the faults (run 0 of the Monte Carlo batch, as the paper shows one flight).
* :func:`method_error_figure`: paper 002 Fig. 2-3, position (m), velocity (m/s) or
  attitude (arcmin) errors of several methods, RMS over the runs at every epoch.
* :func:`vb_noise_figure`: paper 002 Fig. 4-5, the VB estimate of the GNSS noise
  standard deviation against the true one.

Every function takes result objects and returns the figure (style §9).
"""

from __future__ import annotations

import pathlib
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ftnav.plot.figures import _shade_faults  # noqa: E402
from ftnav.sim.ins_data import fault_profiles  # noqa: E402

__all__ = ["local_fused_figure", "method_error_figure", "vb_noise_figure", "save_integrated"]

_GROUPS = {"position": (slice(0, 3), "m"), "velocity": (slice(3, 6), "m/s"),
           "attitude": (slice(6, 9), "arcmin")}
_AXES = ("East", "North", "Up")


def local_fused_figure(ir, method: str, fault_free: bool = False, run: int = 0):
    """Paper 001 Fig. 4 (``fault_free=True``) / Fig. 5: local and fused position errors."""
    sr = ir.result
    sc = sr.scenario
    res = (sr.fault_free if fault_free else sr.results)[method]
    loc = (ir.local_fault_free if fault_free else ir.local).get(method)
    t = sc.times
    fig, axs = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for ax, j, label in ((axs[0], 1, "latitude (North) error [m]"),
                         (axs[1], 0, "longitude (East) error [m]")):
        if loc is not None:
            for i, name in enumerate(sc.sensor_names):
                ax.plot(t, loc.pos[run, :, i, j], lw=0.8, label=f"SINS/{name} local")
        ax.plot(t, res.x[run, :, j], color="k", lw=1.3, label=f"fused ({method})")
        if not fault_free:
            _shade_faults(ax, sc)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axs[0].legend(fontsize=7, ncol=2)
    axs[1].set_xlabel("time [s]")
    what = "without faults" if fault_free else "with the injected faults (shaded)"
    fig.suptitle(f"{sc.name}: local and fused position errors, {what}, run {run}")
    fig.tight_layout()
    return fig


def method_error_figure(sr, methods: Sequence[str], quantity: str = "position",
                        fault_free: bool = False):
    """Paper 002 Fig. 2-3: RMS over runs of the output errors of each method."""
    sl, unit = _GROUPS[quantity]
    sc = sr.scenario
    pool = sr.fault_free if fault_free else sr.results
    t = sc.times
    fig, axs = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for j, ax in enumerate(axs):
        for name in methods:
            if name not in pool:
                continue
            e = pool[name].x[:, :, sl][:, :, j]
            ax.plot(t, np.sqrt(np.mean(e ** 2, 0)), lw=0.9, label=name)
        if not fault_free:
            _shade_faults(ax, sc)
        ax.set_ylabel(f"{_AXES[j]} [{unit}]")
        ax.set_yscale("log")
        ax.grid(alpha=0.3, which="both")
    axs[0].legend(fontsize=8)
    axs[-1].set_xlabel("time [s]")
    fig.suptitle(f"{sc.name}: {quantity} error, RMS over {sr.runs} runs "
                 f"(shaded: fault windows)")
    fig.tight_layout()
    return fig


def vb_noise_figure(sr, method: str, sensor: str = "gnss"):
    """Paper 002 Fig. 4-5: VB estimate of the noise σ of each measurement vs the truth."""
    sc = sr.scenario
    i = sc.sensor_names.index(sensor)
    aid = sc.aids[i].sensor
    R_hat = sr.results[method].R_hat[i]  # (B, K, m) variances
    t = sc.times
    _, scale = fault_profiles(sc.faults, sensor, t, aid.dim)
    white = None
    if hasattr(aid, "pos_white_sigma_m"):  # GNSS: true white σ per measurement row
        white = np.concatenate([np.broadcast_to(np.asarray(aid.pos_white_sigma_m, float), (3,)),
                                np.broadcast_to(np.asarray(aid.vel_white_sigma_m_s, float),
                                                (3,))])
    comps = aid.components
    fig, axs = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    for ax, rows, title in ((axs[0], [0, 1, 2], "position [m]"),
                            (axs[1], [3, 4, 5], "velocity [m/s]")):
        for j in rows:
            if j >= len(comps):
                continue
            ax.plot(t, np.sqrt(R_hat[:, :, j]).mean(0), lw=0.9, label=f"VB σ̂ {comps[j]}")
            if white is not None:
                ax.plot(t, white[j] * scale, "k--", lw=1.0,
                        label="true σ" if j == rows[0] else None)
        _shade_faults(ax, sc, sensor=sensor)
        ax.set_ylabel(title)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    axs[-1].set_xlabel("time [s]")
    fig.suptitle(f"{sc.name}: {method} VB estimate of the {sensor} noise σ (mean over runs)")
    fig.tight_layout()
    return fig


def save_integrated(ir, out_dir) -> list[pathlib.Path]:
    """Write the paper figures that apply to the scenario's methods; returns the paths."""
    out_dir = pathlib.Path(out_dir)
    sr = ir.result
    sc = sr.scenario
    names = list(sr.results)
    paths = []

    def save(fig, name):
        p = out_dir / name
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)

    for q in ("position", "velocity", "attitude"):
        save(method_error_figure(sr, names, q), f"errors_{q}.png")
    with_locals = [n for n in names if ir.local.get(n) is not None]
    for n in with_locals:
        save(local_fused_figure(ir, n, fault_free=False), f"local_fused_{n}.png")
        if sr.fault_free:
            save(local_fused_figure(ir, n, fault_free=True), f"local_fused_{n}_fault_free.png")
    for m in sc.methods:
        if m.adaptive_noise != "none" and m.name in sr.results:
            for s in (m.vb_sensors or sc.sensor_names):
                if s in sc.sensor_names and sc.aids[sc.sensor_names.index(s)].dim == 6:
                    save(vb_noise_figure(sr, m.name, s), f"vb_noise_{m.name}_{s}.png")
    return paths
