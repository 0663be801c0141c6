"""Figures of the integrated-navigation experiments (papers 001 and 002).

* :func:`method_error_figure`: paper 002 Fig. 2, 4: position (m), velocity (m/s) or
  attitude (arcmin) errors of a few methods, RMS over the runs at every epoch, one panel
  per state (:func:`ftnav.plot.figures.error_figure` without the run-0 column).
* :func:`local_fused_figure`: paper 001 Fig. 4-5, latitude (North) and longitude
  (East) errors in metres of every local filter of one method and of the fused
  estimate of up to :data:`~ftnav.model.scenario.MAX_FIGURE_METHODS` methods (run 0 of the
  Monte Carlo batch, as the paper shows one flight).
* :func:`vb_noise_figure`: paper 002 Fig. 3, 5, the VB estimate of an aid's noise
  standard deviation against the true one, one panel per measurement component.

:func:`save_integrated` draws the scenario's ``[[figures]]``, or :func:`default_figures`
when it has none.  Every function takes result objects and returns a
:class:`matplotlib.figure.Figure` (no ``pyplot`` state, style §9).
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from ftnav.eval.montecarlo import ScenarioResult
from ftnav.model.faults import fault_effect
from ftnav.model.scenario import METRIC_STATES, POSITION_NORMS, FigureSpec
from ftnav.plot.figures import (
    _check_count,
    _method_styles,
    _new_axes,
    _pool,
    _select,
    _sensor_colours,
    _shade_faults,
    _state_label,
    _titles,
    error_figure,
    method_groups,
)

__all__ = [
    "local_fused_figure",
    "method_error_figure",
    "vb_noise_figure",
    "default_figures",
    "draw_figure",
    "save_integrated",
]

#: The states of each quantity's figure; the position figure adds the horizontal error.
QUANTITIES = {
    "position": (*METRIC_STATES[0:3], POSITION_NORMS[0]),
    "velocity": METRIC_STATES[3:6],
    "attitude": METRIC_STATES[6:9],
}

_DPI = 110


def _names(methods: str | Sequence[str]) -> list[str]:
    return [methods] if isinstance(methods, str) else list(methods)


def method_error_figure(
    sr,
    methods: Sequence[str],
    quantity: str = "position",
    fault_free: bool = False,
    states: Sequence[str] | None = None,
    title: str | None = None,
) -> Figure:
    """Paper 002 Fig. 2, 4: RMS over runs of the output errors of a few methods.

    ``states`` default to the ``quantity``'s (:data:`QUANTITIES`); at most
    ``MAX_FIGURE_METHODS`` methods.
    """
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: expected one of {list(QUANTITIES)}, got {quantity!r}")
    return error_figure(
        sr,
        fault_free=fault_free,
        states=states or QUANTITIES[quantity],
        methods=methods,
        title=title,
        run0=False,
    )


def local_fused_figure(
    sr: ScenarioResult,
    method: str | Sequence[str],
    fault_free: bool = False,
    run: int = 0,
    states: Sequence[str] = ("pos_N_m", "pos_E_m"),
    title: str | None = None,
) -> Figure:
    """Paper 001 Fig. 4 (``fault_free=True``) / Fig. 5: local and fused position errors.

    Parameters
    ----------
    sr : ScenarioResult
        Output of :func:`ftnav.eval.montecarlo.run_scenario` on an integrated scenario.
    method : str or sequence of str
        The method whose local filters are drawn, or several (at most
        ``MAX_FIGURE_METHODS``): the locals of the first and the fused estimate of each.
    fault_free : bool
        Draw the fault-free twin.
    run : int
        The Monte Carlo run drawn.
    states : sequence of str
        Position states, one panel each (default North then East, as the paper).
    title : str, optional
        First title line (default: the scenario's description or name).
    """
    sc = sr.scenario
    names = _names(method)
    _check_count(names, "method")
    pool, injected, condition = _pool(sr, fault_free)
    names = _select(pool, names)
    loc = pool[names[0]].local
    for s in states:
        if s not in METRIC_STATES[:3]:
            raise ValueError(f"states: expected position states {METRIC_STATES[:3]}, got {s!r}")
    t = sc.times
    fig, axs = _new_axes(len(states), None, 1, figsize=(10.0, 2.8 * len(states) + 1.4))
    sensors = _sensor_colours(sc.sensor_names)
    # the first method's fused line black, the others in colours no local filter uses
    palette = matplotlib.colormaps["tab10"]
    colours = ["k"] + [palette((len(sensors) + k) % 10) for k in range(len(names) - 1)]
    fault_handles: list = []
    for ax, s in zip(axs, states, strict=True):
        j = METRIC_STATES.index(s)
        if loc is not None:
            for i, name in enumerate(sc.sensor_names):
                ax.plot(
                    t,
                    loc[run, :, i, j],
                    lw=0.8,
                    color=sensors[name],
                    alpha=0.8,
                    label=f"SINS/{name} local ({names[0]})",
                )
        for k, name in enumerate(names):
            ax.plot(
                t,
                pool[name].error[run, :, j],
                lw=1.6 if k == 0 else 1.1,
                color=colours[k],
                linestyle="-" if k == 0 else "--",
                label=f"fused ({name})",
            )
        fault_handles = _shade_faults(ax, sc, injected)
        ax.set_title(f"{_state_label(s)} error, run {run}", fontsize="medium")
        ax.set_ylabel("error [m]")
        # a diverging local would flatten the fused lines: a linear axis within a few
        # times the fused errors, logarithmic beyond (every line stays drawn)
        fused = max(float(np.nanmax(np.abs(pool[n].error[run, :, j]))) for n in names)
        if loc is not None and np.nanmax(np.abs(loc[run, :, :, j])) > 20.0 * fused > 0:
            ax.set_yscale("symlog", linthresh=2.0 * fused)
            ax.set_ylabel(f"error [m] (linear within ±{2.0 * fused:.3g} m)")
        ax.grid(alpha=0.3)
        ax.set_xlim(0.0, t[-1])
    axs[-1].set_xlabel("time [s]")
    what = "" if loc is not None else f" ({names[0]} has no local filters)"
    _titles(
        fig,
        sc,
        title,
        f"scenario '{sc.name}': local and fused position errors{what}, "
        f"{condition}; run {run} of {sr.runs}",
    )
    handles, labels = axs[0].get_legend_handles_labels()
    fig.legend(
        handles + fault_handles,
        labels + [h.get_label() for h in fault_handles],
        loc="outside right upper",
        fontsize="small",
        frameon=False,
    )
    return fig


def _true_sigma(aid, sc, sensor: str) -> np.ndarray | None:
    """(K, m) true white-noise σ of each measurement row, where the sensor model gives it."""
    if not hasattr(aid, "pos_white_sigma_m"):
        return None
    scale = fault_effect(sc.faults, sensor, sc.times, aid.dim).scale[:, 0]
    white = np.concatenate(
        [
            np.broadcast_to(np.asarray(aid.pos_white_sigma_m, float), (3,)),
            np.broadcast_to(np.asarray(aid.vel_white_sigma_m_s, float), (3,)),
        ]
    )
    return white[: aid.dim] * np.asarray(scale, float).reshape(-1, 1)


def vb_noise_figure(
    sr, method: str | Sequence[str], sensor: str = "gnss", title: str | None = None
) -> Figure:
    """Paper 002 Fig. 3, 5: VB estimate of the noise σ of each measurement vs the truth.

    One panel per measurement component of ``sensor``: the mean over runs of each
    method's ``sqrt(R̂)`` (at most ``MAX_FIGURE_METHODS`` methods) and, for GNSS, the
    true white-noise σ of the simulation (dashed).
    """
    sc = sr.scenario
    names = _names(method)
    _check_count(names, "method")
    names = _select(sr.results, names)
    if sensor not in sc.sensor_names:
        raise ValueError(f"sensor: unknown sensor {sensor!r}; available: {sc.sensor_names}")
    i = sc.sensor_names.index(sensor)
    aid = sc.aids[i].sensor
    truth = _true_sigma(aid, sc, sensor)
    comps = list(aid.components)
    t = sc.times
    ncols = 1 if len(comps) <= 2 else 3
    nrows = math.ceil(len(comps) / ncols)
    fig, axs = _new_axes(len(comps), None, ncols, figsize=(4.6 * ncols + 2.5, 2.6 * nrows + 1.4))
    styles = _method_styles(names)
    fault_handles: list = []
    for j, (ax, comp) in enumerate(zip(axs, comps, strict=True)):
        for name in names:
            ax.plot(
                t,
                np.sqrt(sr.results[name].R_hat[i][:, :, j]).mean(0),
                lw=1.0,
                label=f"VB σ̂ ({name})",
                **styles[name],
            )
        if truth is not None:
            ax.plot(t, truth[:, j], "k--", lw=1.0, label="true σ")
        fault_handles = _shade_faults(ax, sc, sensor=sensor)
        ax.set_title(comp, fontsize="medium")
        ax.grid(alpha=0.3)
        ax.set_xlim(0.0, t[-1])
        spec = ax.get_subplotspec()
        if spec.is_first_col():
            ax.set_ylabel("noise σ [measurement units]")
        if spec.is_last_row() or j + ncols >= len(comps):
            ax.set_xlabel("time [s]")
    _titles(
        fig,
        sc,
        title,
        f"scenario '{sc.name}': VB estimate of the {sensor} noise σ, mean over {sr.runs} runs",
    )
    handles, labels = axs[0].get_legend_handles_labels()
    fig.legend(
        handles + fault_handles,
        labels + [h.get_label() for h in fault_handles],
        loc="outside right upper",
        fontsize="small",
        frameon=False,
    )
    return fig


def default_figures(sr: ScenarioResult) -> tuple[FigureSpec, ...]:
    """The figures of an integrated scenario without ``[[figures]]``.

    Per group of :func:`~ftnav.plot.figures.method_groups` (the centralized reference
    plus up to three others): ``errors_position`` (E, N, U, horizontal),
    ``errors_velocity``, ``errors_attitude``, suffixed ``_2``, ``_3``, ... for the later
    groups; ``local_fused_<method>`` (and ``..._fault_free``) for every method with local
    filters; ``vb_noise_<method>_<aid>`` for every aid a method adapts the noise of.
    """
    sc = sr.scenario
    base = sc.description or sc.name
    groups = method_groups(sc, list(sr.results))
    specs = []
    for g, names in enumerate(groups, 1):
        suffix = "" if g == 1 else f"_{g}"
        title = base if len(groups) == 1 else f"{base} (methods, part {g} of {len(groups)})"
        specs += [
            FigureSpec(f"errors_{q}{suffix}", title, names, states)
            for q, states in QUANTITIES.items()
        ]
    for name in sr.results:
        if sr.results[name].local is None:
            continue
        specs.append(
            FigureSpec(f"local_fused_{name}", base, (name,), ("pos_N_m", "pos_E_m"), "local-fused")
        )
        if sr.fault_free:
            specs.append(
                FigureSpec(
                    f"local_fused_{name}_fault_free",
                    base,
                    (name,),
                    ("pos_N_m", "pos_E_m"),
                    "local-fused",
                    "fault-free",
                )
            )
    for m in sc.methods:
        if m.noise.kind == "none" or m.name not in sr.results:
            continue
        for s in m.noise.sensors or sc.sensor_names:
            specs.append(
                FigureSpec(f"vb_noise_{m.name}_{s}", base, (m.name,), (), "vb-noise", sensor=s)
            )
    return tuple(specs)


def draw_figure(sr: ScenarioResult, spec: FigureSpec) -> Figure:
    """The figure ``spec`` asks for, from an integrated run's result."""
    title = spec.title or None
    fault_free = spec.condition == "fault-free"
    if spec.kind == "local-fused":
        return local_fused_figure(
            sr, spec.methods, fault_free, states=spec.states or ("pos_N_m", "pos_E_m"), title=title
        )
    if spec.kind == "vb-noise":
        return vb_noise_figure(sr, spec.methods, spec.sensor, title=title)
    return error_figure(
        sr,
        fault_free=fault_free,
        states=spec.states or None,
        methods=spec.methods,
        title=title,
        run0=False,
    )


def save_integrated(
    sr: ScenarioResult, out_dir, second: ScenarioResult | None = None
) -> list[pathlib.Path]:
    """Write ``<name>.png`` for every figure of the scenario's ``[[figures]]`` (default:
    :func:`default_figures`), a ``flight = "second"`` one from ``second`` (the run on the
    scenario's test profile; skipped without it); returns the paths."""
    out_dir = pathlib.Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for spec in sr.scenario.figures or default_figures(sr):
        run = sr if spec.flight == "first" else second
        if run is None:
            continue
        path = out_dir / f"{spec.name}.png"
        draw_figure(run, spec).savefig(path, dpi=_DPI)
        paths.append(path)
    return paths
