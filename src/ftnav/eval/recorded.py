"""Scores of a recording's solutions against its reference (issue 15 protocols).

The reference is a set of positions at some filter epochs (RTK fixes; a truth file):
nothing of it enters the engine.  Per method:

* ``horizontal_rms_m`` — RMS of the horizontal error over the reference epochs outside
  every outage and fault window (GNSS on: the solution after its update), at the point
  the reference measures (a GNSS reference's antenna: :class:`Reference` ``lever_arm``);
* ``prediction_horizontal_rms_m`` — the same for the solution just before each epoch's
  aiding (:attr:`ftnav.engine.driver.Trace.prediction`, when recorded): what a user had
  when the fix arrived, not the posterior at the fix just used;
* ``reference_span_s``, ``longest_unscored_s`` — what the reference covers;
* outages (protocol a) — per outage ``[s, e)`` the horizontal error at its last
  reference epoch and its maximum within, and the RMS over outages of the maxima;
* detection (protocol b) — per aid with injected faults, the flags against the fault
  windows (:func:`ftnav.eval.metrics.detection_stats`: Pd, false alarms, delay,
  recovery) on real noise;
* against a full truth (protocol c, :func:`score_truth`, under ``truth``): RMSE of
  position, velocity and attitude over the GNSS-on epochs, the NEES of the 9
  navigation error states with its χ² band, the estimated IMU biases against the
  known ones;
* ``integrity`` — what the method watched of itself (:mod:`ftnav.eval.integrity`:
  consistency with each aid, availability, isolation, the horizontal σ against its
  bound); needs no reference.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from ftnav.engine.driver import N_NAV, Trace
from ftnav.eval.evaluate import adapts, watch_settings
from ftnav.eval.integrity import MethodWatch, watch
from ftnav.eval.metrics import detection_stats
from ftnav.model.scenario import Recording, fault_window_mask
from ftnav.nav import attitude
from ftnav.nav.earth import enu_metres, radii
from ftnav.nav.mechanization import InsState
from ftnav.recorded.truth import Truth

__all__ = [
    "CONVERGENCE_S",
    "Reference",
    "navigation_errors",
    "reference_errors",
    "score_recording",
    "score_truth",
    "watch_trace",
]

#: NEES is counted after this time from the start (s): the filter's transient from the
#: initial σ (heading and biases become observable as the vehicle manoeuvres)
CONVERGENCE_S = 60.0


@dataclass(frozen=True, slots=True)
class Reference:
    """Reference positions at filter epochs: ``index`` (K_r,) 0-based epochs and
    ``p`` (K_r, 3) ``[L, λ, h]`` of the point ``lever_arm`` (3,) m from the IMU, body
    frame (a GNSS antenna; None or zeros: the IMU itself).  A solution is scored at that
    point: its IMU position moved by ``C_b^n · lever_arm``."""

    index: np.ndarray
    p: np.ndarray
    lever_arm: np.ndarray | None = None


def errors_at(
    p: np.ndarray, q: np.ndarray, reference_p: np.ndarray, lever_arm: np.ndarray | None
) -> np.ndarray:
    """(K_r, 3) ENU metres of IMU positions ``p`` (K_r, 3) with attitudes ``q`` (K_r, 4)
    minus the reference positions, at the point ``lever_arm`` (3,) m from the IMU, body
    frame (None or zeros: the IMU itself): ``p`` moved by ``C_b^n · lever_arm``."""
    err = enu_metres(p, reference_p)
    if lever_arm is not None and np.any(lever_arm):
        err = err + attitude.quat_to_dcm(q) @ np.asarray(lever_arm, float)
    return err


def reference_errors(solution: InsState, reference: Reference, run: int = 0) -> np.ndarray:
    """(K_r, 3) ENU metres of one run's solution minus the reference, at the point the
    reference measures (:class:`Reference`)."""
    i = reference.index
    return errors_at(solution.p[run, i], solution.q[run, i], reference.p, reference.lever_arm)


def _outages(
    per_run: Sequence[tuple[np.ndarray, np.ndarray, Sequence[tuple[float, float]]]],
) -> dict[str, Any]:
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


def horizontal_sigma(tr: Trace) -> np.ndarray:
    """(B, K) the fused horizontal position σ (m) of an integrated trace (error states
    δL, δλ in rad at indices 6, 7, spec §8.3) at its solution's latitude and height."""
    assert tr.solution is not None
    lat, h = tr.solution.p[..., 0], tr.solution.p[..., 2]
    R_Mh, R_Nh = radii(lat, h)
    var_N = tr.P_diag[..., 6] * R_Mh**2
    var_E = tr.P_diag[..., 7] * (R_Nh * np.cos(lat)) ** 2
    out: np.ndarray = np.sqrt(var_N + var_E)
    return out


def watch_trace(name: str, rec: Recording, tr: Trace, scheduled: np.ndarray) -> MethodWatch | None:
    """What one method of a recording watched of itself (:func:`ftnav.eval.integrity.watch`);
    ``scheduled`` (B, K, N) the epochs each aid was due.  None without the watch data."""
    if tr.nis is None or tr.available is None or tr.used is None:
        return None
    return watch(
        name,
        rec.times,
        rec.sensor_names,
        [a.dim for a in rec.aids],
        tr.nis,
        tr.available,
        tr.used,
        scheduled,
        tr.guard,
        horizontal_sigma(tr) if tr.solution is not None else None,
        watch_settings(rec.evaluation),
        adapts(next((m for m in rec.methods if m.name == name), None), rec.sensor_names),
    )


def score_recording(
    rec: Recording,
    traces: Mapping[str, Trace],
    reference: Reference,
    outages: Sequence[Sequence[tuple[float, float]]] = ((),),
    grace: float | None = None,
    truth: Truth | None = None,
    scheduled: np.ndarray | None = None,
) -> dict[str, dict[str, Any]]:
    """Every method's scores (module docstring); times relative to ``rec.t_start``.

    ``outages`` are per run of the batch (interleaved outage schedules); the GNSS-on
    scores are those of the first run outside its outages.  With a ``truth``
    (:attr:`ftnav.io.recording_file.LoadedRecording.truth`) each method also has
    ``truth`` (:func:`score_truth`).  ``grace`` after a fault (default the recording's
    ``[evaluation] grace``); ``scheduled`` (B, K, N) the epochs each aid was due (the
    stream's, :func:`ftnav.model.streams.scheduled`), for ``integrity``.
    """
    grace = rec.evaluation.grace if grace is None else grace
    times = rec.times
    t_ref = times[reference.index]
    blocked = fault_window_mask(t_ref, rec.faults)
    for s, e in outages[0]:
        blocked |= (t_ref >= s) & (t_ref < e)
    out: dict[str, dict[str, Any]] = {}
    for name, tr in traces.items():
        assert tr.solution is not None
        errs = [reference_errors(tr.solution, reference, g) for g in range(len(outages))]
        err = errs[0]
        e_h = np.hypot(err[:, 0], err[:, 1])
        on = ~blocked & np.isfinite(e_h)
        m: dict[str, Any] = {
            "horizontal_rms_m": float(np.sqrt(np.mean(e_h[on] ** 2))) if on.any() else None,
            "vertical_rms_m": float(np.sqrt(np.mean(err[on, 2] ** 2))) if on.any() else None,
            "reference_epochs": int(on.sum()),
            # what the reference covers: the scores say nothing outside it (a walk whose
            # fixes turn float after 88 s is scored on those 88 s only)
            "reference_span_s": [float(t_ref[0] + rec.t_start), float(t_ref[-1] + rec.t_start)]
            if t_ref.size
            else None,
            "longest_unscored_s": _longest_gap(t_ref, float(times[-1])),
            "nan_epochs": int(np.sum(~np.isfinite(tr.solution.p[0]).all(-1))),
        }
        if tr.prediction is not None:
            # the solution just before the fix is used: what a user had at that moment
            ep = reference_errors(tr.prediction, reference)
            eph = np.hypot(ep[:, 0], ep[:, 1])
            ok = on & np.isfinite(eph)
            m["prediction_horizontal_rms_m"] = (
                float(np.sqrt(np.mean(eph[ok] ** 2))) if ok.any() else None
            )
            m["prediction_vertical_rms_m"] = (
                float(np.sqrt(np.mean(ep[ok, 2] ** 2))) if ok.any() else None
            )
        if any(outages):
            per_run = [
                (t_ref, np.hypot(e[:, 0], e[:, 1]), w) for e, w in zip(errs, outages, strict=True)
            ]
            m["outages"] = _outages(per_run)
        if tr.flag is not None and rec.faults:
            m["detection"] = _detection(rec, tr.flag[0], grace)
        if truth is not None:
            m["truth"] = score_truth(rec, tr, truth, outages[0])
        if scheduled is not None:
            w = watch_trace(name, rec, tr, scheduled)
            if w is not None:
                m["integrity"] = w.as_dict()
        out[name] = m
    return out


def _longest_gap(t_ref: np.ndarray, t_end: float) -> float:
    """Longest stretch of the processed span (0 to ``t_end``) without a reference epoch, s."""
    edges = np.concatenate([[0.0], np.sort(t_ref), [t_end]])
    return float(np.max(np.diff(edges)))


def navigation_errors(tr: Trace, truth: Truth, run: int = 0) -> np.ndarray:
    """(K_t, 9) errors of the solution at the truth's epochs in the filter's error states:
    ``[φ (rad), δv (m/s), δL, δλ (rad), δh (m)]``, computed − true, φ with
    ``C̃_b^n = (I − [φ×]) C_b^n`` (``docs/conventions.md``)."""
    assert tr.solution is not None
    i = truth.index
    q = tr.solution.q[run, i]
    phi = attitude.attitude_error(attitude.quat_to_dcm(q), truth.C)
    dv = tr.solution.v[run, i] - truth.v
    dp = tr.solution.p[run, i] - truth.p
    dp[:, 1] = (dp[:, 1] + np.pi) % (2 * np.pi) - np.pi
    return np.concatenate([phi, dv, dp], -1)


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a)))) if a.size else float("nan")


def score_truth(
    rec: Recording,
    tr: Trace,
    truth: Truth,
    outages: Sequence[tuple[float, float]] = (),
    convergence_s: float = CONVERGENCE_S,
    run: int = 0,
) -> dict[str, Any]:
    """One method's solution against a full truth (run ``run``; module docstring).

    * ``rmse``: over the truth epochs outside outages and fault windows (GNSS on):
      position E, N, U and horizontal (m), velocity E, N, U and 3-D (m/s), roll, pitch
      and heading (deg, wrapped);
    * ``nees`` (when the trace holds :attr:`~ftnav.engine.driver.Trace.P_nav`): the NEES
      ``eᵀ P⁻¹ e`` of the 9 navigation errors (:func:`navigation_errors`) against the
      filter's posterior covariance at the same epochs; its mean, the two-sided 95 %
      band of one run's χ²(9), and the fraction of GNSS-on epochs after
      ``convergence_s`` inside it;
    * ``biases``: the filter's bias estimate at the last epoch (with bias compensation
      the biases the SINS subtracts, :attr:`~ftnav.engine.driver.Trace.bias`; plus what
      the alignment removed from the log) against the truth's (:mod:`ftnav.recorded.truth`) and the
      data set's nominal values; the error in % of the truth's.
    """
    assert tr.solution is not None
    t = rec.times[truth.index]
    on = ~fault_window_mask(t, rec.faults)
    for start, end in outages:
        on &= ~((t >= start) & (t < end))
    e = navigation_errors(tr, truth, run)
    on &= np.isfinite(e).all(-1)
    enu = enu_metres(tr.solution.p[run, truth.index], truth.p)
    est = attitude.dcm_to_euler(attitude.quat_to_dcm(tr.solution.q[run, truth.index]))
    ref = attitude.dcm_to_euler(truth.C)
    d_att = np.degrees(attitude.wrap_angle(est - ref))
    dv = e[:, 3:6]
    out: dict[str, Any] = {
        "epochs": int(on.sum()),
        "rmse": {
            "position_enu_m": [_rms(enu[on, j]) for j in range(3)],
            "horizontal_m": _rms(np.hypot(enu[on, 0], enu[on, 1])),
            "velocity_enu_mps": [_rms(dv[on, j]) for j in range(3)],
            "velocity_mps": _rms(np.linalg.norm(dv[on], axis=-1)),
            "roll_deg": _rms(d_att[on, 1]),
            "pitch_deg": _rms(d_att[on, 0]),
            "heading_deg": _rms(d_att[on, 2]),
        },
    }
    if tr.P_nav is not None:
        P = tr.P_nav[run, truth.index]
        nees = np.einsum("ki,ki->k", e, np.linalg.solve(P, e[..., None])[..., 0])
        lo, hi = chi2.ppf([0.025, 0.975], N_NAV)
        after = on & (t >= convergence_s)
        inside = (nees >= lo) & (nees <= hi)
        out["nees"] = {
            "dof": N_NAV,
            "band_95": [float(lo), float(hi)],
            "convergence_s": convergence_s,
            "epochs": int(after.sum()),
            "mean": float(np.mean(nees[after])) if after.any() else float("nan"),
            "fraction_inside": float(np.mean(inside[after])) if after.any() else float("nan"),
            "fraction_above": float(np.mean(nees[after] > hi)) if after.any() else float("nan"),
        }
    out["biases"] = _biases(rec, tr, truth, run)
    return out


def _biases(rec: Recording, tr: Trace, truth: Truth, run: int) -> dict[str, Any]:
    x = tr.x[run, -1]
    sd = np.sqrt(tr.P_diag[run, -1])
    if rec.error_model.states == 18:  # ε_b + ε_r; ∇
        gyro, accel = x[9:12] + x[12:15], x[15:18]
        gyro_sd, accel_sd = np.hypot(sd[9:12], sd[12:15]), sd[15:18]
    else:
        gyro, accel = x[9:12], x[12:15]
        gyro_sd, accel_sd = sd[9:12], sd[12:15]
    if tr.bias is not None:  # compensated: the states hold the residual, fed back already
        gyro, accel = tr.bias[run, -1, 0:3], tr.bias[run, -1, 3:6]
    gyro = gyro + truth.removed_gyro_bias
    out: dict[str, Any] = {}
    for key, value, sigma, known, nominal, unit, scale in (
        ("gyro", gyro, gyro_sd, truth.gyro_bias, truth.gyro_bias_nominal, "dps", np.degrees(1.0)),
        (
            "accel",
            accel,
            accel_sd,
            truth.accel_bias,
            truth.accel_bias_nominal,
            "mg",
            1 / 9.80665e-3,
        ),
    ):
        out[key] = {
            f"estimate_{unit}": (value * scale).tolist(),
            f"sigma_{unit}": (sigma * scale).tolist(),
            f"truth_{unit}": (known * scale).tolist(),
            f"nominal_{unit}": None if nominal is None else (nominal * scale).tolist(),
            "error_percent_of_truth": (100 * (value - known) / np.abs(known)).tolist(),
        }
    return out


def _detection(rec: Recording, flag: np.ndarray, grace: float) -> dict[str, dict[str, float]]:
    out = {}
    for i, name in enumerate(rec.sensor_names):
        windows = [(f.start, f.end) for f in rec.faults if f.sensor == name]
        if not windows:
            continue
        d = detection_stats(flag[None, :, i], rec.times, windows, grace)
        # the names and fields of a simulated run's detection (one name per quantity)
        out[name] = {k: v if k == "events" else float(v) for k, v in d._asdict().items()}
    return out
