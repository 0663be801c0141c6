"""What ``ftnav process`` reports: ``metrics.json`` and the table it prints."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ftnav.eval.integrity import LOCKOUT_S
from ftnav.eval.recorded import RecordedScores, TruthScores
from ftnav.io.recording_file import LoadedRecording

__all__ = ["recording_metrics", "recording_report", "recording_table"]


def recording_metrics(
    loaded: LoadedRecording,
    scores: dict[str, RecordedScores],
    elapsed_s: float,
    files: list[str] | None = None,
) -> dict[str, Any]:
    """The ``metrics.json`` document of a processed recording.

    ``files``: the names of the files ``ftnav process`` wrote into its folder (``metrics.json``
    included), listed under ``"files"``.
    """
    rec, al = loaded.recording, loaded.alignment
    return {
        "recording": rec.name,
        "description": rec.description,
        "time_base": {
            "t_start_s": rec.t_start,
            "t_first_gnss_s": rec.t_origin,
            "epochs": rec.steps,
            "dt_s": rec.dt,
        },
        "alignment": {
            "pitch_deg": math.degrees(float(al.euler[0])),
            "roll_deg": math.degrees(float(al.euler[1])),
            "heading_deg": math.degrees(float(-al.euler[2])) % 360.0,
            "static_samples": al.static[0],
            "static_specific_force_mps2": al.static[1],
            "gyro_bias_removed_dps": np.degrees(al.gyro_bias).tolist(),
            "heading_from": al.heading_from,
            "heading_sigma_deg": (
                math.degrees(al.heading_sigma) if math.isfinite(al.heading_sigma) else None
            ),
        },
        "aids": list(rec.sensor_names),
        # solution.csv is the IMU's; the scores are at the point the reference measures
        "solution_point": "imu",
        "reference_lever_arm_m": [float(x) for x in loaded.reference_lever_arm],
        "data": loaded.counts,
        "outages_s_after_first_gnss": [
            [[s + rec.t_start - rec.t_origin, e + rec.t_start - rec.t_origin] for s, e in run]
            for run in loaded.outages
        ],
        "faults": [
            {
                "sensor": f.sensor,
                "kind": f.kind,
                "start_s": f.start + rec.t_start,
                "end_s": f.end + rec.t_start,
                "magnitude": f.magnitude.tolist(),
            }
            for f in rec.faults
        ],
        "wall_time_s": elapsed_s,
        "runs": len(loaded.outages),
        "files": list(files or []),
        # the typed scores become dicts here, in the JSON document only
        "methods": {name: s.as_dict() for name, s in scores.items()},
    }


def _f(x: Any, spec: str = ".3f") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def recording_table(scores: dict[str, RecordedScores]) -> str:
    """One line per method: GNSS-on horizontal/vertical RMS (after the fix; before it,
    the prediction), outage drift (and the smoothed solution's, or without outages its
    GNSS-on RMS), detection (one aid per line when a
    method tests several)."""
    smoothed = any(m.smoothed is not None for m in scores.values())
    head = "method           horiz RMS m  pred RMS m  vert RMS m  outages RMS max m   " + (
        "smoothed m  " if smoothed else ""
    )
    lines = [head + "detection"]
    for name, m in scores.items():
        o = m.outages
        drift = f"{_f(o.rms_max_error_m)} ({o.count})" if o is not None else "-"
        det = [
            f"{s}: Pd {_f(d.rate, '.2f')} FA {_f(d.false_alarm_rate, '.3f')} "
            f"recovery {_f(d.mean_recovery_s, '.1f')} s"
            for s, d in (m.detection or {}).items()
        ] or ["-"]
        sm = ""
        if smoothed:  # its outage drift, or without outages its GNSS-on RMS
            ms = m.smoothed
            so = None if ms is None else ms.outages
            value = (
                _f(so.rms_max_error_m)
                if so is not None
                else (_f(ms.horizontal_rms_m) if ms is not None else "-")
            )
            sm = f"{value:>10}  "
        pred = None if m.prediction is None else m.prediction.horizontal_rms_m
        mark = "! " if m.integrity is not None and m.integrity.locked_out else "  "
        lines.append(
            f"{name:<16} {_f(m.horizontal_rms_m):>11}{mark}"
            f"{_f(pred):>10}  {_f(m.vertical_rms_m):>10}  "
            f"{drift:>17}   {sm}{det[0]}"
        )
        lines += [" " * len(head) + d for d in det[1:]]
    locked = [nm for nm, m in scores.items() if m.integrity is not None and m.integrity.locked_out]
    if locked:
        lines.append(
            f"! {', '.join(locked)}: every aid that measured was left out for "
            f"{LOCKOUT_S:g} s or longer (a lock-out; the warnings say when): a coast's numbers"
        )
    truth = {nm: m.truth for nm, m in scores.items() if m.truth is not None}
    if truth:
        lines += ["", truth_table(truth)]
    return "\n".join(lines)


def truth_table(truth: dict[str, TruthScores]) -> str:
    """Against a full truth: horizontal, velocity and attitude RMSE, NEES in its band."""
    lines = ["against the truth  horiz m  vel m/s  roll/pitch/heading deg  NEES mean  in 95 % band"]
    for name, t in truth.items():
        r, n = t.rmse, t.nees
        att = "/".join(_f(a, ".2f") for a in (r.roll_deg, r.pitch_deg, r.heading_deg))
        lines.append(
            f"{name:<17} {_f(r.horizontal_m):>8}  {_f(r.velocity_mps):>7}  {att:>22}  "
            f"{_f(None if n is None else n.mean, '.1f'):>9}  "
            f"{_f(None if n is None else n.fraction_inside, '.2f'):>12}"
        )
    return "\n".join(lines)


def recording_report(
    loaded: LoadedRecording,
    scores: dict[str, RecordedScores],
    figures: list[str],
    findings: list[str],
) -> str:
    """``report.md`` of ``ftnav process``: what was processed, the table it prints, what
    each method watched of itself, the figures (``report.html`` is made from it)."""
    rec = loaded.recording
    methods = ", ".join(m.name for m in rec.methods)
    md = [
        f"# ftnav process: {rec.name}",
        "",
        f"{rec.steps} filter epochs of {rec.dt:.4g} s from {rec.t_start:.3f} s "
        f"(the recording's time base); methods {methods}; batch of "
        f"{loaded.stream.batch} run(s) (one per interleaved outage schedule). "
        "Scores against the recording's reference (metrics.json names it and its point); "
        "'pred' is the prediction before each fix, what a user sees between fixes.",
        "",
        "```",
        recording_table(scores),
        "```",
        "",
    ]
    if findings:
        md += ["## What the methods watched of themselves", ""]
        md += [f"- {line}" for line in findings] + [""]
    if figures:
        md += ["## Figures", ""] + [f"![{f}]({f})" for f in figures]
    return "\n".join(md).rstrip("\n") + "\n"
