"""Plain-text results tables (terminal) and a Markdown report of a run.

Every table has one column per state of the scenario (all linear states; the nine
navigation output errors of an integrated run, plus its horizontal and 3-D position
error), one row per method, and one quantity per table:

1. RMSE over the evaluation window (mean over runs of each run's RMSE);
2. RMSE inside the fault windows, with the faults;
3. RMSE on the same epochs of the fault-free twin (identical noise, faults removed);
4. the ratio of 2 to 3, **per state**: a fault shows in the state it reaches (a North
   ramp gives a ratio above 1 in the North column, about 1 elsewhere), and the
   "fault acts on" line names each faulty sensor's own state;
5. consistency (ANEES) and detection per faulty sensor.

A value averaged over runs carries its 95 % confidence interval
(:mod:`ftnav.eval.intervals`): ``3.66 ±0.03`` where the interval is symmetric (t over
runs), ``0.998 [0.990, 1.000]`` where it is not (rates, bootstrap delays).

Column headers say what they are: a linear state is headed ``state`` / ``s`` (its units
are those of the scenario, which the file does not name); a state whose name ends in a
unit (``_m``, ``_m_s``, ``_arcmin``, ...) is grouped by quantity with the unit in brackets
(``position [m]`` / ``E``).  :func:`summary_tables` returns the tables as typed values.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ftnav.eval.evaluate import MethodMetrics, split_unit
from ftnav.eval.intervals import Interval
from ftnav.eval.montecarlo import ScenarioResult
from ftnav.model.scenario import POSITION_NORMS

__all__ = [
    "Column",
    "Table",
    "summary_tables",
    "fault_states",
    "results_table",
    "detector_table",
    "markdown_report",
]

#: Terminal tables wider than this are split into column blocks.
WIDTH = 100

_QUANTITIES = {"pos": "position", "vel": "velocity", "att": "attitude"}
_COMPONENTS = {"horizontal": "horiz.", "3d": "3-D"}


class Column(NamedTuple):
    """One value column: ``key`` in the metric maps, two header lines, a Markdown header."""

    key: str
    group: str
    label: str
    markdown: str
    fmt: str = "num"


class Table(NamedTuple):
    """One quantity: ``rows`` are (method, one value per column; None = not defined;
    an :class:`~ftnav.eval.intervals.Interval` where the value has one)."""

    title: str
    columns: tuple[Column, ...]
    rows: tuple[tuple[str, tuple[float | Interval | None, ...]], ...]
    note: str = ""


# ---------------------------------------------------------------------------
# columns and values
# ---------------------------------------------------------------------------


def _state_column(name: str) -> Column:
    stem, unit = split_unit(name)
    if unit is None:
        return Column(name, "state", name, f"state {name}")
    prefix, _, component = stem.rpartition("_")
    markdown = f"{stem} [{unit}]"
    if prefix:
        return Column(
            name,
            f"{_QUANTITIES.get(prefix, prefix)} [{unit}]",
            _COMPONENTS.get(component, component),
            markdown,
        )
    return Column(name, f"[{unit}]", stem, markdown)


def _state_columns(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> tuple[Column, ...]:
    """Every state in model order; the horizontal and 3-D error after the position states."""
    states = list(result.scenario.metric_states)
    keys = set().union(*(m.rmse for m in metrics.values())) if metrics else set()
    norms = [k for k in POSITION_NORMS if k in keys]
    if norms and "pos_U_m" in states:
        i = states.index("pos_U_m") + 1
        states[i:i] = norms
    return tuple(_state_column(s) for s in states)


def fault_states(scenario) -> dict[str, str]:
    """Faulty sensor → the state (metric key) its fault acts on.

    Integrated runs: the horizontal position error (``pos_horizontal_m``), through which
    every aid's fault reaches the navigation solution.  Linear scenarios: the state that
    carries a bias or ramp offset, ``argmax |H⁺ magnitude|``; for other kinds the state
    the sensor measures most, ``argmax`` of the column norms of ``H``.  Outages and
    faults of a component that is not a sensor of the scenario are left out.
    """
    states = tuple(scenario.metric_states)
    out: dict[str, str] = {}
    names = scenario.sensor_names
    for f in scenario.faults:
        if f.kind == "outage" or f.sensor not in names or f.sensor in out:
            continue
        if scenario.kind == "integrated":
            out[f.sensor] = POSITION_NORMS[0]
            continue
        sensors = {s.name: s for s in scenario.sensors}
        H = np.asarray(sensors[f.sensor].H, dtype=float)
        mag = np.asarray(f.magnitude, dtype=float)
        if f.kind in ("bias", "ramp") and mag.shape == (H.shape[0],) and np.any(mag):
            weight = np.abs(np.linalg.lstsq(H, mag, rcond=None)[0])
        else:
            weight = np.linalg.norm(H, axis=0)
        out[f.sensor] = states[int(np.argmax(weight))]
    return out


def _values(
    source: dict[str, float] | None,
    columns: Sequence[Column],
    intervals: dict[str, Interval] | None = None,
) -> tuple:
    """The columns' values of ``source``, as their intervals where ``intervals`` has them."""
    if source is None:
        return (None,) * len(columns)
    return tuple(
        intervals[c.key] if intervals and c.key in intervals else source.get(c.key) for c in columns
    )


def _value(x: float | Interval | None) -> float | None:
    return x.value if isinstance(x, Interval) else x


def _ratio(inside, free) -> float | None:
    return inside / free if inside is not None and free else None


def summary_tables(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> list[Table]:
    """The run's tables: RMSE, RMSE in fault windows, fault-free twin, ratio, detection.

    Tables 2-4 are left out when no epoch lies in a fault window, table 3 and 4 also
    when no method has a fault-free twin; see the module docstring.
    """
    sc = result.scenario
    cols = _state_columns(result, metrics)
    units = (
        "in the scenario's state units"
        if not any(c.group != "state" for c in cols)
        else "units in brackets"
    )
    tables = [
        Table(
            f"RMSE over the evaluation window (mean over runs of each run's RMSE; {units})",
            cols,
            tuple(
                (n, _values(m.rmse, cols, m.intervals and m.intervals.rmse))
                for n, m in metrics.items()
            ),
        )
    ]
    if any(m.rmse_fault for m in metrics.values()):
        by_state: dict[str, list[str]] = {}
        for sensor, key in fault_states(sc).items():
            by_state.setdefault(key, []).append(sensor)
        acts = "; ".join(
            f"{_state_column(k).markdown} ({', '.join(v)})" for k, v in by_state.items()
        )
        note = f"The faults act on: {acts}." if acts else ""
        inside = {
            n: _values(m.rmse_fault, cols, m.intervals and m.intervals.rmse_fault)
            for n, m in metrics.items()
        }
        tables.append(
            Table(
                "RMSE inside the fault windows, with the faults", cols, tuple(inside.items()), note
            )
        )
        twin = {
            n: _values(m.fault_free and m.fault_free.rmse_fault_window, cols)
            for n, m in metrics.items()
        }
        if any(v is not None for row in twin.values() for v in row):
            tables.append(
                Table(
                    "RMSE on the same epochs of the fault-free twin (identical "
                    "noise, faults removed)",
                    cols,
                    tuple(twin.items()),
                )
            )
            ratio = tuple(
                (
                    n,
                    tuple(
                        _ratio(_value(a), _value(b))
                        for a, b in zip(inside[n], twin[n], strict=True)
                    ),
                )
                for n in metrics
            )
            tables.append(
                Table(
                    "Ratio in fault / fault-free twin, per state (1 = the fault "
                    "does not reach the state)",
                    tuple(c._replace(fmt="ratio") for c in cols),
                    ratio,
                    note,
                )
            )
    tables.append(_detection_table(result, metrics))
    return tables


def _detection_table(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> Table:
    sc = result.scenario
    n = len(sc.metric_states)
    cols = [Column("anees", "consistency", "ANEES", "ANEES", "ratio")]
    twin = any(m.fault_free for m in metrics.values())
    if twin:  # the fault-free twin's beside the faulty run's (issue 20)
        cols.append(Column("anees_ff", "consistency", "fault-free", "ANEES fault-free", "ratio"))
    faulty = list(fault_states(sc))
    if any(m.detection for m in metrics.values()):
        for s in faulty:
            cols += [
                Column(f"{s}:rate", f"sensor {s}", "Pd", f"{s} Pd", "rate"),
                Column(f"{s}:mean_delay_s", f"sensor {s}", "delay [s]", f"{s} delay [s]", "delay"),
            ]
        cols.append(
            Column("false_alarm_rate", "all sensors", "false alarms", "false alarms (max)", "small")
        )
    rows = []
    for name, m in metrics.items():
        ci = m.intervals
        values: list[float | Interval | None] = [ci.anees if ci else m.anees]
        if twin:
            ff = m.fault_free.anees if m.fault_free else None
            values.append(ci.fault_free_anees if ci and ci.fault_free_anees else ff)
        if len(cols) > 1 + twin:
            det = m.detection or {}
            det_ci = (ci and ci.detection) or {}
            for s in faulty:
                d, dci = det.get(s), det_ci.get(s)
                rate = dci.rate if dci else (d.rate if d else None)
                values += [rate, dci.mean_delay_s if dci else None]
            fas = [
                (d.false_alarm_rate, c.false_alarm_rate if (c := det_ci.get(s)) else None)
                for s, d in det.items()
                if d.false_alarm_rate is not None
            ]
            worst = max(fas, key=lambda x: x[0]) if fas else None
            values.append(None if worst is None else worst[1] or worst[0])
        rows.append((name, tuple(values)))
    return Table(
        f"Consistency (ANEES, {n} for a consistent filter; with the faults and of the "
        "fault-free twin) and detection of each "
        "faulty sensor (Pd per epoch, mean delay; false alarms per clean epoch, "
        "largest over sensors)",
        tuple(cols),
        tuple(rows),
    )


# ---------------------------------------------------------------------------
# formatting
# ---------------------------------------------------------------------------


def _format(value, fmt: str = "num") -> str:
    if isinstance(value, Interval):
        return _format_interval(value, fmt)
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    if fmt == "ratio":
        return f"{value:.2f}"
    if fmt == "rate":
        return f"{value:.3f}"
    if fmt == "delay":
        return f"{value:.1f}"
    if fmt == "small":
        return f"{value:.1e}"
    a = abs(value)
    if a >= 1000.0:
        return f"{value:.0f}"
    if a != 0.0 and a < 1e-3:
        return f"{value:.2e}"
    return f"{value:.3g}"


def _format_interval(i: Interval, fmt: str) -> str:
    """``value ±h`` for a symmetric (t) interval, ``value [lo, hi]`` otherwise; the
    value alone where there is no interval (one run)."""
    v = _format(i.value, fmt)
    if not (math.isfinite(i.lo) and math.isfinite(i.hi)) or v == "-":
        return v
    if i.method == "t":
        return f"{v} ±{_format(i.half_width, fmt)}"
    return f"{v} [{_format(i.lo, fmt)}, {_format(i.hi, fmt)}]"


def _blocks(groups: list[str], widths: list[int], room: int) -> list[range]:
    """Consecutive column blocks that fit in ``room``, split between groups if possible."""
    blocks, start, used = [], 0, 0
    for j, w in enumerate(widths):
        cut = j > start and used + 2 + w > room
        if cut:
            k = j
            while k > start and groups[k - 1] == groups[k]:
                k -= 1
            k = k if k > start else j
            blocks.append(range(start, k))
            start = k
            used = sum(2 + widths[i] for i in range(start, j))
        used += 2 + w
    blocks.append(range(start, len(widths)))
    return blocks


def _render(table: Table, width: int = WIDTH) -> str:
    """Fixed-width text: title, group and label header lines, rows; split if too wide."""
    names = ["method"] + [r[0] for r in table.rows]
    name_w = max(len(s) for s in names)
    cells = [
        [_format(v, c.fmt) for v, c in zip(vals, table.columns, strict=True)]
        for _, vals in table.rows
    ]
    groups = [c.group for c in table.columns]
    widths = [max([len(c.label)] + [len(r[j]) for r in cells]) for j, c in enumerate(table.columns)]
    j = 0
    while j < len(groups):  # widen a group's last column until its label fits
        k = j
        while k + 1 < len(groups) and groups[k + 1] == groups[j]:
            k += 1
        span = sum(widths[j : k + 1]) + 2 * (k - j)
        widths[k] += max(0, len(groups[j]) - span)
        j = k + 1
    out = textwrap.wrap(table.title, width)
    if table.note:
        out += textwrap.wrap(table.note, width)
    for block in _blocks(groups, widths, width - name_w):
        line_g, line_l = " " * name_w, "method".ljust(name_w)
        j = block.start
        while j < block.stop:
            k = j
            while k + 1 < block.stop and groups[k + 1] == groups[j]:
                k += 1
            span = sum(widths[j : k + 1]) + 2 * (k - j)
            line_g += "  " + groups[j].ljust(span)
            j = k + 1
        for j in block:
            line_l += "  " + table.columns[j].label.ljust(widths[j])
        rule = "-" * name_w + "".join("  " + "-" * widths[j] for j in block)
        rows = [
            name.ljust(name_w) + "".join("  " + r[j].ljust(widths[j]) for j in block)
            for (name, _), r in zip(table.rows, cells, strict=True)
        ]
        out += [line_g.rstrip(), line_l.rstrip(), rule, *(r.rstrip() for r in rows)]
        if block.stop < len(widths):
            out.append("")
    return "\n".join(out)


def _markdown(table: Table) -> list[str]:
    head = ["method"] + [c.markdown for c in table.columns]
    md = [f"**{table.title}**", ""]
    if table.note:
        md += [table.note, ""]
    md += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    md += [
        "| "
        + " | ".join([name] + [_format(v, c.fmt) for v, c in zip(vals, table.columns, strict=True)])
        + " |"
        for name, vals in table.rows
    ]
    return md


# ---------------------------------------------------------------------------
# public text
# ---------------------------------------------------------------------------


def _detector_rows(result: ScenarioResult, metrics: dict[str, MethodMetrics]):
    """Every method with a detector, per faulty sensor: detection and error in/out of window.

    The error is that of the state the sensor's fault acts on (:func:`fault_states`).
    """
    sc = result.scenario
    dt = sc.dt
    header = [
        "method",
        "detector",
        "sensor",
        "Pd",
        "events",
        "false alarms",
        "median delay [ep]",
        "recovery [s]",
        "RMSE of",
        "in fault",
        "out of fault",
    ]
    rows = []
    own = fault_states(sc)
    detectors = {m.name: m.detector.kind for m in sc.methods}
    for name, m in metrics.items():
        if not m.detection:
            continue
        for s, key in own.items():
            d = m.detection[s]
            dci = (m.intervals and m.intervals.detection or {}).get(s)
            delay: float | Interval | None = (
                None if d.median_delay_s is None else d.median_delay_s / dt
            )
            if dci is not None and delay is not None:
                med = dci.median_delay_s
                delay = Interval(med.value / dt, med.lo / dt, med.hi / dt, med.runs, med.method)
            rows.append(
                [
                    name,
                    detectors.get(name, ""),
                    s,
                    _format(dci.rate if dci else d.rate, "rate"),
                    _format(dci.event_rate if dci else d.event_rate, "ratio"),
                    _format(dci.false_alarm_rate if dci else d.false_alarm_rate, "small"),
                    _format(delay, "delay"),
                    _format(dci.mean_recovery_s if dci else d.mean_recovery_s, "delay"),
                    _state_column(key).markdown,
                    _format(m.rmse_fault and m.rmse_fault.get(key)),
                    _format(m.rmse_nofault and m.rmse_nofault.get(key)),
                ]
            )
    return header, rows


def _fixed(header, rows) -> str:
    widths = [max(len(str(r[c])) for r in [header] + rows) for c in range(len(header))]
    line = "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))
    out = [line.rstrip(), "-" * len(line.rstrip())]
    out += [
        "  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows
    ]
    return "\n".join(out)


def detector_table(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> str:
    """Detectors side by side (learned and statistical): detection, delay, error in/out."""
    header, rows = _detector_rows(result, metrics)
    return _fixed(header, rows) if rows else ""


def results_table(
    result: ScenarioResult, metrics: dict[str, MethodMetrics], width: int = WIDTH
) -> str:
    """The tables of :func:`summary_tables` as fixed-width text, at most ``width`` wide.

    A table with more columns than fit is printed in blocks of columns, each with the
    method column.
    """
    return "\n\n".join(_render(t, width) for t in summary_tables(result, metrics))


def markdown_report(
    result: ScenarioResult,
    metrics: dict[str, MethodMetrics],
    claims: list[dict],
    figures: list[str],
) -> str:
    """The run's report: settings, tables, claims with measured numbers, figures."""
    sc = result.scenario
    md = [
        f"# ftnav run: {sc.name}",
        "",
        sc.description,
        "",
        f"{result.runs} Monte Carlo runs, root seed {result.seed}, {sc.steps} epochs of "
        f"{sc.dt} s. One column per state; 'in the fault windows' = epochs inside a fault "
        "window; 'fault-free twin' = the same epochs of a twin run on identical noise with "
        "the faults removed; the ratio is their quotient per state, so a fault shows in "
        "the state it reaches. Linear states are in the scenario's own units; states whose "
        "name ends in a unit carry it in brackets. Pd, false alarms (per epoch) and delay "
        "refer to each faulty sensor under each method's own detector. A value averaged "
        "over runs carries its 95 % confidence interval: `±h` (Student t over runs) or "
        "`[lo, hi]` (rates: Wilson with the runs as clusters; delays: bootstrap over "
        "runs).",
        "",
    ]
    for t in summary_tables(result, metrics):
        md += _markdown(t) + [""]
    dh, drows = _detector_rows(result, metrics)
    if drows:
        md += [
            "## Detectors side by side",
            "",
            "Per method with a detector and per faulty sensor: per-epoch detection rate, "
            "detected events, false alarms per clean epoch, median delay in epochs, mean "
            "time to clear after the fault, and the RMSE of the state the sensor's fault "
            "acts on inside and outside the fault windows.",
            "",
            "| " + " | ".join(dh) + " |",
            "|" + "---|" * len(dh),
        ]
        md += ["| " + " | ".join(r) + " |" for r in drows]
        md.append("")
    if claims:
        md += ["## Claims checked", ""]
        for c in claims:
            verdict = (
                {True: "holds", False: "does NOT hold", None: "undecided"}[c["holds"]]
                if c.get("checked", True)
                else "not checked"
            )
            md.append(
                f"- **{c['source']}** — {c['claim']}: **{verdict}**."
                + (f" {c['note']}." if c["note"] else "")
            )
            md.append(f"  Measured: `{_compact(c['measured'])}`")
            for i in c.get("intervals", ()):
                side = "<" if i["holds_if"] == "below" else ">"
                md.append(
                    f"  95 % interval of {i['quantity']}: {i['value']:.4g} "
                    f"[{i['lo']:.4g}, {i['hi']:.4g}] ({i['runs']} runs, {i['method']}); "
                    f"holds if {side} {i['threshold']:g}"
                )
        md.append("")
    if figures:
        md += ["## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(md).rstrip("\n") + "\n"


def _compact(obj):
    if isinstance(obj, dict):
        return "{" + ", ".join(f"{k}: {_compact(v)}" for k, v in obj.items()) + "}"
    if isinstance(obj, float):
        return f"{obj:.4g}"
    return str(obj)
