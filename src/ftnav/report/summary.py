"""Plain-text results table (terminal) and a Markdown report of a run."""

from __future__ import annotations

from ftnav.eval.evaluate import MethodMetrics
from ftnav.eval.montecarlo import ScenarioResult

__all__ = ["results_table", "detector_table", "markdown_report"]


def _f(v, fmt="{:.3g}"):
    return "-" if v is None else fmt.format(v)


def _rows(result: ScenarioResult, metrics: dict[str, MethodMetrics]):
    st = result.scenario.model.states[0]
    faulty = [f.sensor for f in result.scenario.faults if f.kind != "outage"]
    header = ["method", f"RMSE {st}", f"{st} in fault", f"{st} in window, no fault",
              "ratio", "ANEES", "Pd", "false alarms", "delay [s]"]
    rows = []
    for name, m in metrics.items():
        ff = m.fault_free["rmse_fault_window"][st] if m.fault_free and \
            m.fault_free["rmse_fault_window"] else None
        inside = m.rmse_fault[st] if m.rmse_fault else None
        ratio = inside / ff if inside is not None and ff else None
        det = m.detection.get(faulty[0]) if m.detection and faulty else None
        fa = None
        if m.detection:
            fas = [d["false_alarm_rate"] for d in m.detection.values()
                   if d["false_alarm_rate"] is not None]
            fa = max(fas) if fas else None
        rows.append([name, _f(m.rmse[st]), _f(inside), _f(ff), _f(ratio, "{:.2f}"),
                     _f(m.anees, "{:.2f}"), _f(det and det["rate"], "{:.3f}"),
                     _f(fa, "{:.2e}"), _f(det and det["mean_delay_s"], "{:.2f}")])
    return header, rows


def _detector_rows(result: ScenarioResult, metrics: dict[str, MethodMetrics]):
    """Every method with a detector, per faulty sensor: detection and error in/out of window."""
    sc = result.scenario
    st = sc.model.states[0]
    dt = sc.dt
    header = ["method", "detector", "sensor", "Pd", "events", "false alarms", "median delay [ep]",
              "recovery [s]", f"{st} in fault", f"{st} out of fault"]
    rows = []
    faulty = list(dict.fromkeys(f.sensor for f in sc.faults if f.kind != "outage"
                                and f.sensor in sc.sensor_names))  # not the SINS
    detectors = {m.name: m.detector for m in sc.methods}
    for name, m in metrics.items():
        if not m.detection:
            continue
        for s in faulty:
            d = m.detection[s]
            delay = None if d["median_delay_s"] is None else d["median_delay_s"] / dt
            rows.append([name, detectors.get(name, ""), s, _f(d["rate"], "{:.3f}"),
                         _f(d["event_rate"], "{:.2f}"), _f(d["false_alarm_rate"], "{:.2e}"),
                         _f(delay, "{:.1f}"), _f(d["mean_recovery_s"], "{:.1f}"),
                         _f(m.rmse_fault and m.rmse_fault[st]),
                         _f(m.rmse_nofault and m.rmse_nofault[st])])
    return header, rows


def _fixed(header, rows) -> str:
    widths = [max(len(str(r[c])) for r in [header] + rows) for c in range(len(header))]
    line = "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(out)


def detector_table(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> str:
    """Detectors side by side (learned and statistical): detection, delay, error in/out."""
    header, rows = _detector_rows(result, metrics)
    return _fixed(header, rows) if rows else ""


def results_table(result: ScenarioResult, metrics: dict[str, MethodMetrics]) -> str:
    """Fixed-width table: RMSE overall, in the fault window, fault-free, detection."""
    header, rows = _rows(result, metrics)
    widths = [max(len(str(r[c])) for r in [header] + rows) for c in range(len(header))]
    line = "  ".join(h.ljust(w) for h, w in zip(header, widths, strict=True))
    out = [line, "-" * len(line)]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(out)


def markdown_report(result: ScenarioResult, metrics: dict[str, MethodMetrics],
                    claims: list[dict], figures: list[str]) -> str:
    """The run's report: settings, table, claims with measured numbers, figures."""
    sc = result.scenario
    header, rows = _rows(result, metrics)
    md = [f"# ftnav run: {sc.name}", "", sc.description, "",
          f"{result.runs} Monte Carlo runs, root seed {result.seed}, {sc.steps} epochs of "
          f"{sc.dt} s. 'in fault' = epochs inside a fault window; 'in window, no fault' = the "
          "same epochs of a twin run on identical noise with the faults removed; "
          "'ratio' = their quotient. Pd, false alarms (per epoch) and delay refer to the "
          "faulty sensor under each method's own detector.", "",
          "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    md += ["| " + " | ".join(r) + " |" for r in rows]
    dh, drows = _detector_rows(result, metrics)
    if drows:
        md += ["", "## Detectors side by side", "",
               "Per method with a detector and per faulty sensor: per-epoch detection rate, "
               "detected events, false alarms per clean epoch, median delay in epochs, mean "
               "time to clear after the fault, and the RMSE inside and outside the fault "
               "window.", "", "| " + " | ".join(dh) + " |", "|" + "---|" * len(dh)]
        md += ["| " + " | ".join(r) + " |" for r in drows]
    if claims:
        md += ["", "## Claims checked", ""]
        for c in claims:
            verdict = {True: "holds", False: "does NOT hold", None: "not decided"}[c["holds"]]
            md.append(f"- **{c['source']}** — {c['claim']}: **{verdict}**."
                      + (f" {c['note']}." if c["note"] else ""))
            md.append(f"  Measured: `{_compact(c['measured'])}`")
    if figures:
        md += ["", "## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(md) + "\n"


def _compact(obj):
    if isinstance(obj, dict):
        return "{" + ", ".join(f"{k}: {_compact(v)}" for k, v in obj.items()) + "}"
    if isinstance(obj, float):
        return f"{obj:.4g}"
    return str(obj)
