"""Scores of a recording's solutions against its reference (issue 15 protocols).

The reference is a set of positions at some filter epochs (RTK fixes; a truth file):
nothing of it enters the engine.  Per method:

* ``horizontal_rms_m`` — RMS of the horizontal error over the reference epochs outside
  every outage and fault window (GNSS on: the solution after its update);
* outages (protocol a) — per outage ``[s, e)`` the horizontal error at its last
  reference epoch and its maximum within, and the RMS over outages of the maxima;
* detection (protocol b) — per aid with injected faults, the flags against the fault
  windows (:func:`ftnav.eval.metrics.detection_stats`: Pd, false alarms, delay,
  recovery) on real noise.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from ftnav.engine.driver import Trace
from ftnav.eval.metrics import detection_stats
from ftnav.model.scenario import Recording, fault_window_mask
from ftnav.nav.earth import radii

__all__ = ["Reference", "horizontal_errors", "score_recording"]


class Reference(NamedTuple):
    """Reference positions at filter epochs: ``index`` (K_r,) 0-based epochs and
    ``p`` (K_r, 3) ``[L, λ, h]``."""

    index: np.ndarray
    p: np.ndarray


def horizontal_errors(p: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(K, 3) East, North, Up errors in metres of positions ``p`` against ``ref``."""
    RM, RN = radii(ref[:, 0], ref[:, 2])
    dlon = (p[:, 1] - ref[:, 1] + np.pi) % (2 * np.pi) - np.pi
    return np.stack(
        [dlon * RN * np.cos(ref[:, 0]), (p[:, 0] - ref[:, 0]) * RM, p[:, 2] - ref[:, 2]], -1
    )


def _outages(per_run: Sequence[tuple[np.ndarray, np.ndarray, Sequence]]) -> dict:
    rows = []
    for t, e_h, outages in per_run:
        for s, e in outages:
            w = (t >= s) & (t < e)
            if w.any():
                rows.append(_outage_row(s, e, e_h[w]))
    rows.sort(key=lambda r: r["start_s"])
    maxima = np.array([r["max_error_m"] for r in rows])
    return {
        "count": len(rows),
        "rms_max_error_m": float(np.sqrt(np.mean(maxima**2))) if rows else float("nan"),
        "rms_end_error_m": (
            float(np.sqrt(np.mean([r["end_error_m"] ** 2 for r in rows]))) if rows else float("nan")
        ),
        "each": rows,
    }


def _outage_row(s: float, e: float, e_h: np.ndarray) -> dict[str, float]:
    return {
        "start_s": s,
        "end_s": e,
        "end_error_m": float(e_h[-1]),
        "max_error_m": float(e_h.max()),
    }


def score_recording(
    rec: Recording,
    traces: Mapping[str, Trace],
    reference: Reference,
    outages: Sequence[Sequence[tuple[float, float]]] = ((),),
    grace: float = 10.0,
) -> dict[str, dict[str, Any]]:
    """Every method's scores (module docstring); times relative to ``rec.t_start``.

    ``outages`` are per run of the batch (interleaved outage schedules); the GNSS-on
    scores are those of the first run outside its outages.
    """
    times = rec.times
    t_ref = times[reference.index]
    blocked = fault_window_mask(t_ref, rec.faults)
    for s, e in outages[0]:
        blocked |= (t_ref >= s) & (t_ref < e)
    out: dict[str, dict[str, Any]] = {}
    for name, tr in traces.items():
        assert tr.solution is not None
        errs = [
            horizontal_errors(tr.solution.p[g, reference.index], reference.p)
            for g in range(len(outages))
        ]
        err = errs[0]
        e_h = np.hypot(err[:, 0], err[:, 1])
        on = ~blocked & np.isfinite(e_h)
        m: dict[str, Any] = {
            "horizontal_rms_m": float(np.sqrt(np.mean(e_h[on] ** 2))) if on.any() else None,
            "vertical_rms_m": float(np.sqrt(np.mean(err[on, 2] ** 2))) if on.any() else None,
            "reference_epochs": int(on.sum()),
            "nan_epochs": int(np.sum(~np.isfinite(tr.solution.p[0]).all(-1))),
        }
        if any(outages):
            per_run = [
                (t_ref, np.hypot(e[:, 0], e[:, 1]), w) for e, w in zip(errs, outages, strict=True)
            ]
            m["outages"] = _outages(per_run)
        if tr.flag is not None and rec.faults:
            m["detection"] = _detection(rec, tr.flag[0], grace)
        out[name] = m
    return out


def _detection(rec: Recording, flag: np.ndarray, grace: float) -> dict[str, dict[str, float]]:
    out = {}
    for i, name in enumerate(rec.sensor_names):
        windows = [(f.start, f.end) for f in rec.faults if f.sensor == name]
        if not windows:
            continue
        d = detection_stats(flag[None, :, i], rec.times, windows, grace)
        out[name] = {
            "pd": d.rate,
            "false_alarm_rate": d.false_alarm_rate,
            "mean_delay_s": d.mean_delay_s,
            "mean_recovery_s": d.mean_recovery_s,
            "events": d.events,
        }
    return out
