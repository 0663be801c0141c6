"""Figures of a Monte Carlo scenario result: errors per state, sharing coefficients, flags.

Every function takes a :class:`ftnav.eval.montecarlo.ScenarioResult` and returns a
:class:`matplotlib.figure.Figure`.  Figures are built as plain ``Figure`` objects
(no ``pyplot`` global state), so they render with the non-interactive Agg canvas
and are safe to use from scripts, tests and worker processes; save them with
``fig.savefig(path)``.

Time axis: epoch ``k = 1..steps`` is drawn at ``t_k = k·dt`` seconds
(:attr:`ftnav.model.scenario.Scenario.times`).  Fault windows ``[start, end)`` are
shaded on every time axis.

Which figures a run draws (:func:`save_all`): the scenario's ``[[figures]]``
(:class:`~ftnav.model.scenario.FigureSpec`, ``docs/scenario-format.md``) or, when it has
none, :func:`default_figures`: the methods in groups of the centralized reference plus
up to three others (:func:`method_groups`), one figure per group with the faults and one
on the fault-free twin, one row of panels per state.  No axes ever holds more than
:data:`~ftnav.model.scenario.MAX_FIGURE_METHODS` method lines.  Titles come from the
figure section or from the scenario's description and name.
"""

from __future__ import annotations

import math
import pathlib
from collections.abc import Sequence

import matplotlib
import numpy as np
from matplotlib import ticker
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ftnav.eval.evaluate import split_unit
from ftnav.eval.metrics import position_norms
from ftnav.eval.montecarlo import MethodResult, ScenarioResult
from ftnav.model.scenario import (
    MAX_FIGURE_METHODS,
    METRIC_STATES,
    POSITION_NORMS,
    FigureSpec,
    Scenario,
)

__all__ = [
    "default_figures",
    "draw_figure",
    "error_figure",
    "fault_flag_figure",
    "method_groups",
    "save_all",
    "sharing_figure",
]

#: Long names of common one-letter state names, for titles.
_STATE_NAMES = {
    "s": "displacement",
    "p": "position",
    "x": "position",
    "v": "velocity",
    "a": "acceleration",
}
_QUANTITIES = {"pos": "position", "vel": "velocity", "att": "attitude"}
_COMPONENTS = {"E": "East", "N": "North", "U": "Up", "horizontal": "horizontal", "3d": "3-D"}

#: Shading colours of successive fault windows.
_FAULT_COLOURS = ("tab:red", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive")

_DPI = 120


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


class _PlainLogFormatter(ticker.LogFormatter):
    """Log-axis tick labels as plain numbers ("0.3", "2", "100") where labelled."""

    def __call__(self, x, pos=None):
        return f"{x:g}" if super().__call__(x, pos) else ""


def _method_styles(names: Sequence[str]) -> dict[str, dict]:
    """Colour and line style per method from the tab20 palette.

    The dark shade of each of the 10 tab20 hues is used first, then the light
    shades (dashed), so up to 10 methods get clearly distinct colours and up to
    20 stay distinguishable.
    """
    cmap = matplotlib.colormaps["tab20"]
    order = list(range(0, 20, 2)) + list(range(1, 20, 2))
    styles = {}
    for i, name in enumerate(names):
        j = i % 20
        styles[name] = {
            "color": cmap(order[j]),
            "linestyle": "-" if j < 10 else "--",
        }
    return styles


def _sensor_colours(names: Sequence[str]) -> dict[str, tuple]:
    """One tab10 colour per sensor."""
    cmap = matplotlib.colormaps["tab10"]
    return {name: cmap(i % 10) for i, name in enumerate(names)}


def _sensor_widths(n: int) -> np.ndarray:
    """Line widths per sensor, decreasing, so coinciding lines show as nested bands."""
    return np.linspace(2.6, 1.0, n) if n > 1 else np.array([1.3])


def _fault_label(fault) -> str:
    return f"fault: {fault.sensor} {fault.kind} [{fault.start:g}, {fault.end:g}) s"


def _shade_faults(
    ax: Axes, scenario: Scenario, injected: bool = True, sensor: str | None = None
) -> list:
    """Shade each fault window on ``ax`` (of ``sensor`` only, if given); one handle per fault.

    With ``injected=False`` the windows are only outlined (hatched), for runs in
    which the fault was removed, so the eye can still compare the same interval.
    """
    handles = []
    for i, f in enumerate(scenario.faults):
        if sensor is not None and f.sensor != sensor:
            continue
        c = _FAULT_COLOURS[i % len(_FAULT_COLOURS)]
        if injected:
            kw = {"facecolor": c, "alpha": 0.15, "edgecolor": "none"}
            label = _fault_label(f)
        else:
            kw = {"facecolor": "none", "edgecolor": c, "alpha": 0.3, "hatch": "/", "linewidth": 0.0}
            label = _fault_label(f) + " (not injected)"
        ax.axvspan(f.start, f.end, zorder=0, **kw)
        handles.append(Patch(label=label, **kw))
    return handles


def _select(pool: dict[str, MethodResult], methods: Sequence[str] | None) -> list[str]:
    """Method names to draw, in scenario order, checked against ``pool``."""
    if methods is None:
        return list(pool)
    unknown = [m for m in methods if m not in pool]
    if unknown:
        raise ValueError(f"methods: unknown method(s) {unknown}; available: {list(pool)}")
    return list(methods)


def _new_axes(
    n: int, axes: Sequence[Axes] | None, ncols: int, *, figsize, sharex=True, sharey=False
) -> tuple[Figure, list[Axes]]:
    """A grid of ``n`` axes in a new constrained-layout figure, or the given ``axes``."""
    if axes is not None:
        axes = list(np.ravel(axes))
        if len(axes) != n:
            raise ValueError(f"axes: expected {n} axes, got {len(axes)}")
        return axes[0].figure, axes
    nrows = math.ceil(n / ncols)
    fig = Figure(figsize=figsize, layout="constrained")
    grid = fig.subplots(nrows, ncols, sharex=sharex, sharey=sharey, squeeze=False).ravel()
    for extra in grid[n:]:
        extra.remove()
    kept = list(grid[:n])
    for ax in kept:  # shared x hides tick labels above removed cells: show them again
        if not _below_is_filled(ax, kept):
            ax.xaxis.set_tick_params(labelbottom=True)
    return fig, kept


def _label_grid(axs: Sequence[Axes], ylabel: str, every: bool) -> None:
    """Time label on the bottom row and ``ylabel`` on the left column (or on every axes)."""
    for ax in axs:
        spec = ax.get_subplotspec()
        if every or spec is None or spec.is_last_row() or not _below_is_filled(ax, axs):
            ax.set_xlabel("time [s]")
        if every or spec is None or spec.is_first_col():
            ax.set_ylabel(ylabel)


def _below_is_filled(ax: Axes, axs: Sequence[Axes]) -> bool:
    """Whether some axes of ``axs`` sits directly below ``ax`` in its grid."""
    spec = ax.get_subplotspec()
    for other in axs:
        o = other.get_subplotspec()
        if o is not None and o.colspan == spec.colspan and o.rowspan.start == spec.rowspan.stop:
            return True
    return False


def _grid_size(ncols: int, nrows: int, width: float = 5.0) -> tuple[float, float]:
    """Figure size of a grid of panels, with room for the legend on the right."""
    return max(width * ncols, 7.0) + 2.5, 3.0 * nrows + 1.2


def _grid_cols(n: int) -> int:
    return 1 if n == 1 else 2 if n <= 4 else 3


def _state_label(name: str) -> str:
    """Readable state name: ``s (displacement)``, ``North position``, ``3-D position``."""
    stem, unit = split_unit(name)
    if unit is None:
        return f"{name} ({_STATE_NAMES[name]})" if name in _STATE_NAMES else name
    prefix, _, component = stem.rpartition("_")
    if prefix in _QUANTITIES and component in _COMPONENTS:
        return f"{_COMPONENTS[component]} {_QUANTITIES[prefix]}"
    return stem


def _unit_label(name: str) -> str:
    unit = split_unit(name)[1]
    return f"[{unit}]" if unit else "[state units]"


def _states(scenario, states: Sequence[str | int] | None) -> list[str]:
    """State names to draw (default: every state), from names or indices, checked."""
    known = list(scenario.metric_states)
    plottable = known + (list(POSITION_NORMS) if all(s in known for s in METRIC_STATES[:3]) else [])
    if states is None:
        return known
    out = []
    for s in states:
        if isinstance(s, int | np.integer) and not isinstance(s, bool):
            if not 0 <= s < len(known):
                raise ValueError(f"states: index must be in [0, {len(known)}), got {s}")
            s = known[int(s)]
        if s not in plottable:
            raise ValueError(f"states: unknown state {s!r}; available: {plottable}")
        out.append(s)
    if not out:
        raise ValueError("states: at least one state is needed")
    return out


def _state_error(res: MethodResult, states: Sequence[str], name: str) -> np.ndarray:
    """(B, K) error of one state, or a position norm (horizontal, 3-D)."""
    states = list(states)
    if name in POSITION_NORMS:
        idx = [states.index(s) for s in METRIC_STATES[:3]]
        return position_norms(res.error[..., idx])[..., POSITION_NORMS.index(name)]
    return res.error[..., states.index(name)]


def _pool(result: ScenarioResult, fault_free: bool):
    """Results, whether faults are shaded as injected, and the condition's words."""
    sc = result.scenario
    if fault_free and result.fault_free:
        return result.fault_free, False, "fault-free twin (same noise, faults removed)"
    if fault_free and sc.faults:
        return result.results, True, "fault-free twin not computed: run WITH the faults"
    if sc.faults:
        return result.results, True, "with the faults (shaded)"
    return result.results, False, "no fault in the scenario"


def _check_count(names: Sequence[str], what: str = "methods") -> None:
    if len(names) > MAX_FIGURE_METHODS:
        raise ValueError(
            f"{what}: at most {MAX_FIGURE_METHODS} methods per figure (one line "
            f"each per axes), got {len(names)}; split them over several figures "
            "(see default_figures)"
        )


def _reference(scenario, names: Sequence[str]) -> str | None:
    """The centralized reference among ``names``: no detector, no adaptive noise."""
    for m in scenario.methods:
        if (
            m.name in names
            and m.architecture == "centralized"
            and m.detector.kind == "none"
            and m.noise.kind == "none"
        ):
            return m.name
    return None


def method_groups(scenario, names: Sequence[str]) -> list[tuple[str, ...]]:
    """``names`` in groups of at most :data:`MAX_FIGURE_METHODS`, for one figure each.

    Each group is the centralized reference (the first centralized method without a
    detector or adaptive noise, when there is one) followed by up to
    ``MAX_FIGURE_METHODS − 1`` other methods in scenario order.
    """
    ref = _reference(scenario, names)
    others = [n for n in names if n != ref]
    size = MAX_FIGURE_METHODS - (ref is not None)
    chunks = [others[i : i + size] for i in range(0, len(others), size)] or [[]]
    head = [ref] if ref is not None else []
    return [tuple(head + c) for c in chunks if head or c]


def _titles(fig: Figure, scenario, title: str | None, subtitle: str) -> None:
    """Suptitle: the given title (default: the scenario's description or name) and a line
    naming the scenario and what is drawn."""
    main = title or scenario.description or scenario.name
    # left-aligned, so that a legend outside the axes on the right cannot cover it
    fig.suptitle(f"{main}\n{subtitle}", fontsize="medium", x=0.01, ha="left")


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------


def error_figure(
    result: ScenarioResult,
    fault_free: bool = False,
    states: Sequence[str | int] | None = None,
    methods: Sequence[str] | None = None,
    title: str | None = None,
    axes: Sequence[Axes] | None = None,
    run0: bool = True,
) -> Figure:
    """Estimation error of each state vs time for a few methods (paper 000 Fig. 3, 4).

    One row of panels per state: the error ``x̂ − x`` of run 0 for each method and the
    ensemble RMS error over runs, ``sqrt(mean_b e_b(t)²)``, on a log axis.  Every axes
    holds one line per method, at most :data:`~ftnav.model.scenario.MAX_FIGURE_METHODS`.

    Parameters
    ----------
    result : ScenarioResult
        Output of :func:`ftnav.eval.montecarlo.run_scenario` (or the ``result`` of an
        integrated run, whose states are output errors).
    fault_free : bool, default False
        Draw the fault-free twin (``result.fault_free``) instead of the run with faults.
        When no twin was computed the faulty results are drawn and the title says so.
    states : sequence of str or int, optional
        States to draw, by name or index (default: every state); an integrated run also
        accepts ``pos_horizontal_m`` and ``pos_3d_m``.
    methods : sequence of str, optional
        Methods to draw, in this order, at most ``MAX_FIGURE_METHODS`` (default: the first
        group of :func:`method_groups`).
    title : str, optional
        First title line (default: the scenario's description, or its name); the second
        line always names the scenario, the condition, runs and seed.
    axes : sequence of Axes, optional
        Draw into these axes (two per state with ``run0``, else one) instead of a new figure.
    run0 : bool, default True
        Also draw run 0's error (left column); False draws the RMS panels only.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        An unknown state or method, or more than ``MAX_FIGURE_METHODS`` methods.
    """
    sc = result.scenario
    names_st = _states(sc, states)
    pool, injected, condition = _pool(result, fault_free)
    names = (
        _select(pool, methods) if methods is not None else list(method_groups(sc, list(pool))[0])
    )
    _check_count(names)
    styles = _method_styles(names)
    t = sc.times
    per_state = 2 if run0 else 1
    n = per_state * len(names_st)
    ncols = 2 if run0 else (1 if len(names_st) <= 4 else 3)
    nrows = math.ceil(n / ncols)
    fig, axs = _new_axes(
        n, axes, ncols, figsize=_grid_size(ncols, nrows, width=8.5 if ncols == 1 else 5.0)
    )
    # earlier methods are drawn wider, so methods giving identical curves (common
    # without faults) show as nested bands instead of hiding each other
    widths = np.linspace(2.4 if len(names) > 1 else 1.0, 0.7, len(names))
    fault_handles: list = []
    for i, st in enumerate(names_st):
        label, unit = _state_label(st), _unit_label(st)
        ax_run = axs[per_state * i] if run0 else None
        ax_rms = axs[per_state * i + per_state - 1]
        for name, lw in zip(names, widths, strict=True):
            err = _state_error(pool[name], sc.metric_states, st)
            if ax_run is not None:
                ax_run.plot(t, err[0], lw=lw, label=name, **styles[name])
            ax_rms.plot(t, np.sqrt(np.mean(err**2, axis=0)), lw=lw, label=name, **styles[name])
        for ax in (ax_run, ax_rms):
            if ax is None:
                continue
            fault_handles = _shade_faults(ax, sc, injected)
            ax.grid(True, which="major", lw=0.4, alpha=0.6)
            ax.set_xlim(0.0, t[-1])
        if ax_run is not None:
            ax_run.set_title(f"{label}: error, run 0", fontsize="medium")
            ax_run.set_ylabel(f"error {unit}")
        ax_rms.set_yscale("log")
        ax_rms.yaxis.set_major_formatter(_PlainLogFormatter(labelOnlyBase=False))
        ax_rms.yaxis.set_minor_formatter(
            _PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(1.2, 0.5))
        )
        ax_rms.grid(True, which="minor", axis="y", lw=0.3, alpha=0.3)
        ax_rms.set_title(f"{label}: RMS error over {result.runs} runs", fontsize="medium")
        ax_rms.set_ylabel(f"RMS error {unit}")
    for ax in axs:
        spec = ax.get_subplotspec()
        if axes is not None or spec is None or spec.is_last_row() or not _below_is_filled(ax, axs):
            ax.set_xlabel("time [s]")
    handles, labels = axs[0].get_legend_handles_labels()
    handles += fault_handles
    if axes is None:
        _titles(
            fig,
            sc,
            title,
            f"scenario '{sc.name}': estimation error per state, "
            f"{condition}; {result.runs} runs, seed {result.seed}",
        )
        fig.legend(
            handles,
            labels + [h.get_label() for h in fault_handles],
            loc="outside right upper",
            fontsize="small",
            title="method",
            title_fontsize="small",
            frameon=False,
        )
    else:
        axs[0].legend(handles=handles, fontsize="x-small")
    return fig


def _method_grid(result, methods, field: str, axes, empty_message: str):
    """Methods whose result has ``field`` (not None) and a grid of axes, one per method."""
    names = [
        m for m in _select(result.results, methods) if getattr(result.results[m], field) is not None
    ]
    if not names:
        raise ValueError(empty_message)
    ncols = _grid_cols(len(names))
    nrows = math.ceil(len(names) / ncols)
    fig, axs = _new_axes(len(names), axes, ncols, figsize=_grid_size(ncols, nrows), sharey=True)
    return names, fig, axs


def sharing_figure(
    result: ScenarioResult,
    methods: list[str] | None = None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Federated sharing coefficients β_i vs time, one subplot per method.

    Solid lines: mean over runs of β_i per sensor; dotted lines: run 0.
    Methods without sharing coefficients (centralized, distributed) are skipped.

    Parameters
    ----------
    result : ScenarioResult
        Output of :func:`ftnav.eval.montecarlo.run_scenario`.
    methods : list of str, optional
        Methods to consider (default: all); those without β are skipped.
    axes : sequence of Axes, optional
        One axes per drawn method, instead of a new figure.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If no selected method has sharing coefficients.
    """
    sc = result.scenario
    names, fig, axs = _method_grid(
        result,
        methods,
        "beta",
        axes,
        "sharing_figure: no selected method has sharing coefficients (beta)",
    )
    t = sc.times
    colours = _sensor_colours(sc.sensor_names)
    fault_handles: list = []
    widths = _sensor_widths(len(sc.sensor_names))
    for ax, name in zip(axs, names, strict=True):
        beta = result.results[name].beta
        for i, s in enumerate(sc.sensor_names):
            ax.plot(t, beta[:, :, i].mean(axis=0), color=colours[s], lw=widths[i], label=s)
            ax.plot(t, beta[0, :, i], color=colours[s], lw=0.9, ls=":")
        fault_handles = _shade_faults(ax, sc)
        ax.set_title(name, fontsize="medium")
        ax.set_xlim(0.0, t[-1])
        ax.grid(True, lw=0.4, alpha=0.6)
    top = max(float(np.nanmax(result.results[m].beta, initial=0.0)) for m in names)
    for ax in axs:  # after all lines: set_ylim turns autoscaling off
        ax.set_ylim(0.0, 1.05 * top if top > 0.0 else 1.0)
    _label_grid(axs, "sharing coefficient β [-]", every=axes is not None)
    handles = [
        Line2D([], [], color=colours[s], lw=w, label=f"{s} (mean over runs)")
        for s, w in zip(sc.sensor_names, widths, strict=True)
    ]
    handles.append(Line2D([], [], color="0.3", lw=0.9, ls=":", label="run 0"))
    handles += fault_handles
    if axes is None:
        fig.suptitle(
            f"Federated sharing coefficients β_i per sensor\n"
            f"scenario '{sc.name}', {result.runs} runs"
        )
        fig.legend(handles=handles, loc="outside right upper", fontsize="small", frameon=False)
    else:
        axs[0].legend(handles=handles, fontsize="x-small")
    return fig


def fault_flag_figure(
    result: ScenarioResult,
    methods: list[str] | None = None,
    axes: Sequence[Axes] | None = None,
) -> Figure:
    """Fraction of runs flagging each sensor vs time, one subplot per method.

    The true detectable fault windows of each sensor (outages excluded) are
    drawn as a dashed 0/1 step line in the sensor's colour over a shaded band.
    A method whose detector never fires shows flat lines at 0.

    Parameters
    ----------
    result : ScenarioResult
        Output of :func:`ftnav.eval.montecarlo.run_scenario`.
    methods : list of str, optional
        Methods to consider (default: all); those without a detector are skipped.
    axes : sequence of Axes, optional
        One axes per drawn method, instead of a new figure.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If no selected method has fault flags.
    """
    sc = result.scenario
    names, fig, axs = _method_grid(
        result, methods, "flag", axes, "fault_flag_figure: no selected method has fault flags"
    )
    t = sc.times
    colours = _sensor_colours(sc.sensor_names)
    detectable = [f for f in sc.faults if f.kind != "outage"]
    faulty = [s for s in sc.sensor_names if any(f.sensor == s for f in detectable)]
    widths = _sensor_widths(len(sc.sensor_names))
    for ax, name in zip(axs, names, strict=True):
        frac = result.results[name].flag.mean(axis=0)  # (K, N)
        for f in detectable:
            ax.axvspan(
                f.start, f.end, ymax=1.0, color=colours[f.sensor], alpha=0.13, lw=0.0, zorder=0
            )
            ax.hlines(1.0, f.start, f.end, color=colours[f.sensor], lw=3.0, alpha=0.5, zorder=1)
        for i, s in enumerate(sc.sensor_names):
            ax.step(t, frac[:, i], where="mid", color=colours[s], lw=widths[i], zorder=2)
        ax.set_title(name, fontsize="medium")
        ax.set_xlim(0.0, t[-1])
        ax.set_ylim(-0.03, 1.05)
        ax.grid(True, lw=0.4, alpha=0.6)
    _label_grid(axs, "fraction of runs flagging [-]", every=axes is not None)
    handles = [
        Line2D([], [], color=colours[s], lw=w, label=f"{s}: fraction flagged")
        for s, w in zip(sc.sensor_names, widths, strict=True)
    ]
    handles += [
        Patch(facecolor=colours[s], alpha=0.3, label=f"{s}: true fault window") for s in faulty
    ]
    if axes is None:
        fig.suptitle(
            f"Fault flags (after hysteresis): fraction of runs flagging each sensor\n"
            f"scenario '{sc.name}', {result.runs} runs"
        )
        fig.legend(handles=handles, loc="outside right upper", fontsize="small", frameon=False)
    else:
        axs[0].legend(handles=handles, fontsize="x-small")
    return fig


def default_figures(result: ScenarioResult) -> tuple[FigureSpec, ...]:
    """The error figures of a scenario without ``[[figures]]``.

    One figure per group of :func:`method_groups`: ``error_no_fault`` (the fault-free
    twin, paper 000 Fig. 3 condition) and ``error_fault`` (with the faults, Fig. 4
    condition), suffixed ``_2``, ``_3``, ... for the later groups; a scenario without
    faults gets ``error_no_fault`` only.  Every state is drawn.
    """
    sc = result.scenario
    groups = method_groups(sc, list(result.results))
    base = sc.description or sc.name
    specs = []
    for g, names in enumerate(groups, 1):
        suffix = "" if g == 1 else f"_{g}"
        title = base if len(groups) == 1 else f"{base} (methods, part {g} of {len(groups)})"
        if result.fault_free or not sc.faults:
            specs.append(
                FigureSpec(f"error_no_fault{suffix}", title, names, condition="fault-free")
            )
        if sc.faults:
            specs.append(FigureSpec(f"error_fault{suffix}", title, names))
    return tuple(specs)


def draw_figure(result: ScenarioResult, spec: FigureSpec) -> Figure:
    """The figure ``spec`` asks for (kind ``errors``: :func:`error_figure`)."""
    if spec.kind != "errors":
        raise ValueError(
            f"figure {spec.name!r}: kind {spec.kind!r} needs an integrated run "
            "(ftnav.plot.integrated)"
        )
    return error_figure(
        result,
        fault_free=spec.condition == "fault-free",
        states=spec.states or None,
        methods=spec.methods,
        title=spec.title or None,
    )


def save_all(result: ScenarioResult, out_dir: str | pathlib.Path) -> list[pathlib.Path]:
    """Write the figures of a result as PNG files (dpi 120).

    Files: ``<name>.png`` for every figure of the scenario's ``[[figures]]`` or, without
    any, of :func:`default_figures`; then ``sharing.png`` (only if some method has β) and
    ``fault_flags.png`` (only if some method has fault flags).

    Parameters
    ----------
    result : ScenarioResult
        Output of :func:`ftnav.eval.montecarlo.run_scenario`.
    out_dir : str or pathlib.Path
        Output folder, created if missing.

    Returns
    -------
    list of pathlib.Path
        The files written, in the order above.
    """
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    specs = result.scenario.figures or default_figures(result)
    figures: list[tuple[str, Figure]] = [(f"{s.name}.png", draw_figure(result, s)) for s in specs]
    if any(r.beta is not None for r in result.results.values()):
        figures.append(("sharing.png", sharing_figure(result)))
    if any(r.flag is not None for r in result.results.values()):
        figures.append(("fault_flags.png", fault_flag_figure(result)))
    paths = []
    for fname, fig in figures:
        path = out / fname
        fig.savefig(path, dpi=_DPI)
        paths.append(path)
    return paths
