"""Scores of a recording's solutions against its reference (issue 15 protocols).

The reference is a set of positions at some filter epochs (RTK fixes; a truth file):
nothing of it enters the engine.  Per method:

* ``horizontal_rms_m`` — RMS of the horizontal error over the reference epochs outside
  every outage and fault window (GNSS on: the solution after its update), at the point
  the reference measures (a GNSS reference's antenna: :class:`Reference` ``lever_arm``);
* ``prediction_horizontal_rms_m`` — the same for the solution just before each epoch's
  aiding (:attr:`ftnav.engine.driver.Trace.prediction`, when recorded): what a user had
  when the fix arrived, not the posterior at the fix just used (and not at the first
  fix after an outage: its prior is the coast, scored with the outage);
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

The scores are typed (:class:`RecordedScores` and the classes it holds); each has an
``as_dict()``, its ``metrics.json`` form (``methods.<name>``, docs/recording-format.md),
the only place they become dicts.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any, cast

import numpy as np
from scipy.stats import chi2

from ftnav.engine.driver import N_NAV, Trace
from ftnav.eval.evaluate import DetectionMetrics, adapts, readmitted_fraction, watch_settings
from ftnav.eval.integrity import MethodWatch, watch
from ftnav.eval.metrics import detection_stats
from ftnav.model.scenario import Recording, fault_window_mask
from ftnav.nav import attitude
from ftnav.nav.earth import enu_metres, radii
from ftnav.nav.mechanization import InsState
from ftnav.recorded.truth import Truth

__all__ = [
    "CONVERGENCE_S",
    "BiasScore",
    "OutageScore",
    "OutageScores",
    "PredictionScores",
    "RecordedScores",
    "Reference",
    "TruthNees",
    "TruthRmse",
    "TruthScores",
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


def _floats(a: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in np.asarray(a, float).ravel())


class _Plain:
    """A score whose JSON form is its fields (tuples are written as arrays)."""

    __slots__ = ()

    def as_dict(self) -> dict[str, Any]:
        """The JSON form: the fields by name."""
        out: dict[str, Any] = asdict(cast(Any, self))  # a dataclass of the subclass
        return out


@dataclass(frozen=True, slots=True)
class OutageScore(_Plain):
    """One outage ``[start_s, end_s)`` (s on the processing's time base): the horizontal
    error at its last reference epoch and the largest within it, m."""

    start_s: float
    end_s: float
    end_error_m: float
    max_error_m: float


@dataclass(frozen=True, slots=True)
class OutageScores:
    """Every outage of every run (protocol a), in order of start; the RMS over them of
    the maximum and of the end horizontal error, m (NaN without an outage)."""

    each: tuple[OutageScore, ...]

    @property
    def count(self) -> int:
        """How many outages were scored."""
        return len(self.each)

    @property
    def rms_max_error_m(self) -> float:
        """RMS over the outages of each one's maximum horizontal error, m."""
        return _rms(np.array([o.max_error_m for o in self.each]))

    @property
    def rms_end_error_m(self) -> float:
        """RMS over the outages of each one's horizontal error at its end, m."""
        return _rms(np.array([o.end_error_m for o in self.each]))

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``outages``)."""
        return {
            "count": self.count,
            "rms_max_error_m": self.rms_max_error_m,
            "rms_end_error_m": self.rms_end_error_m,
            "each": [o.as_dict() for o in self.each],
        }


@dataclass(frozen=True, slots=True)
class PredictionScores:
    """The solution just before each fix is used (what a user had when it arrived):
    horizontal and vertical RMS over the GNSS-on reference epochs, m (None: none)."""

    horizontal_rms_m: float | None
    vertical_rms_m: float | None


@dataclass(frozen=True, slots=True)
class TruthRmse(_Plain):
    """RMSE against a full truth over the GNSS-on epochs: position E, N, U and
    horizontal (m), velocity E, N, U and 3-D (m/s), roll, pitch, heading (deg)."""

    position_enu_m: tuple[float, float, float]
    horizontal_m: float
    velocity_enu_mps: tuple[float, float, float]
    velocity_mps: float
    roll_deg: float
    pitch_deg: float
    heading_deg: float


@dataclass(frozen=True, slots=True)
class TruthNees(_Plain):
    """NEES of the 9 navigation error states against a full truth (:func:`score_truth`):
    its mean over the GNSS-on epochs after ``convergence_s`` and the fractions of them
    inside and above the two-sided 95 % band of one run's χ²(``dof``)."""

    dof: int
    band_95: tuple[float, float]
    convergence_s: float
    epochs: int
    mean: float
    fraction_inside: float
    fraction_above: float


@dataclass(frozen=True, slots=True)
class BiasScore:
    """One sensor's bias estimate at the last epoch against the truth's, per axis, in
    ``unit`` (``dps`` or ``mg``); ``nominal`` the data set's values (None: unknown)."""

    unit: str
    estimate: tuple[float, ...]
    sigma: tuple[float, ...]
    truth: tuple[float, ...]
    nominal: tuple[float, ...] | None
    error_percent_of_truth: tuple[float, ...]

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``truth.biases.gyro``, ``truth.biases.accel``)."""
        u = self.unit
        return {
            f"estimate_{u}": list(self.estimate),
            f"sigma_{u}": list(self.sigma),
            f"truth_{u}": list(self.truth),
            f"nominal_{u}": None if self.nominal is None else list(self.nominal),
            "error_percent_of_truth": list(self.error_percent_of_truth),
        }


@dataclass(frozen=True, slots=True)
class TruthScores:
    """One method against a full truth (protocol c, :func:`score_truth`)."""

    epochs: int
    rmse: TruthRmse
    nees: TruthNees | None
    gyro_bias: BiasScore
    accel_bias: BiasScore

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``truth``)."""
        out: dict[str, Any] = {"epochs": self.epochs, "rmse": self.rmse.as_dict()}
        if self.nees is not None:
            out["nees"] = self.nees.as_dict()
        out["biases"] = {"gyro": self.gyro_bias.as_dict(), "accel": self.accel_bias.as_dict()}
        return out


@dataclass(frozen=True, slots=True)
class RecordedScores:
    """One method's scores on a recording (module docstring); what is not scored is None
    (no prediction recorded, no outage, no injected fault, no truth, no watch, not
    smoothed).

    Attributes
    ----------
    horizontal_rms_m, vertical_rms_m : GNSS-on RMS at the reference's point, m.
    reference_epochs : the reference epochs scored.
    reference_span_s : first and last reference time (the recording's time base).
    longest_unscored_s : longest stretch without a reference epoch, s.
    nan_epochs : epochs whose solution was not finite.
    prediction : the same before each fix is used.
    outages : per outage (protocol a).
    detection : per aid with injected faults, the flags against the fault windows
        (:class:`~ftnav.eval.evaluate.DetectionMetrics`, as a simulated campaign's).
    truth : against a full truth (protocol c).
    integrity : what the method watched of itself.
    smoothed : the RTS-smoothed solution's scores (no integrity).
    """

    horizontal_rms_m: float | None
    vertical_rms_m: float | None
    reference_epochs: int
    reference_span_s: tuple[float, float] | None
    longest_unscored_s: float
    nan_epochs: int
    prediction: PredictionScores | None = None
    outages: OutageScores | None = None
    detection: Mapping[str, DetectionMetrics] | None = None
    truth: TruthScores | None = None
    integrity: MethodWatch | None = None
    smoothed: RecordedScores | None = None

    def scalars(self) -> dict[str, float | int | None]:
        """The scalar scores by their JSON names (a row of
        :meth:`~ftnav.pipeline.RecordingResult.scores_frame`)."""
        return {k: v for k, v in self.as_dict().items() if v is None or isinstance(v, int | float)}

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``metrics.json``'s ``methods.<name>``)."""
        out: dict[str, Any] = {
            "horizontal_rms_m": self.horizontal_rms_m,
            "vertical_rms_m": self.vertical_rms_m,
            "reference_epochs": self.reference_epochs,
            "reference_span_s": None
            if self.reference_span_s is None
            else list(self.reference_span_s),
            "longest_unscored_s": self.longest_unscored_s,
            "nan_epochs": self.nan_epochs,
        }
        if self.prediction is not None:
            out["prediction_horizontal_rms_m"] = self.prediction.horizontal_rms_m
            out["prediction_vertical_rms_m"] = self.prediction.vertical_rms_m
        if self.outages is not None:
            out["outages"] = self.outages.as_dict()
        if self.detection is not None:
            out["detection"] = {aid: asdict(d) for aid, d in self.detection.items()}
        if self.truth is not None:
            out["truth"] = self.truth.as_dict()
        if self.integrity is not None:
            out["integrity"] = self.integrity.as_dict()
        if self.smoothed is not None:
            out["smoothed"] = self.smoothed.as_dict()
        return out


def reference_errors(solution: InsState, reference: Reference, run: int = 0) -> np.ndarray:
    """(K_r, 3) ENU metres of one run's solution minus the reference, at the point the
    reference measures (:class:`Reference`)."""
    i = reference.index
    return errors_at(solution.p[run, i], solution.q[run, i], reference.p, reference.lever_arm)


def _outages(
    per_run: Sequence[tuple[np.ndarray, np.ndarray, Sequence[tuple[float, float]]]],
) -> OutageScores:
    rows = []
    for t, e_h, outages in per_run:
        for s, e in outages:
            w = (t >= s) & (t < e)
            if w.any():
                rows.append(OutageScore(s, e, float(e_h[w][-1]), float(e_h[w].max())))
    return OutageScores(tuple(sorted(rows, key=lambda r: r.start_s)))


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
) -> dict[str, RecordedScores]:
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
    returned = np.zeros(t_ref.shape, bool)  # the first reference epoch after each outage
    for s, e in outages[0]:
        blocked |= (t_ref >= s) & (t_ref < e)
        first = int(np.searchsorted(t_ref, e))
        if first < t_ref.size:
            returned[first] = True
    out: dict[str, RecordedScores] = {}
    for name, tr in traces.items():
        assert tr.solution is not None
        errs = [reference_errors(tr.solution, reference, g) for g in range(len(outages))]
        err = errs[0]
        e_h = np.hypot(err[:, 0], err[:, 1])
        on = ~blocked & np.isfinite(e_h)
        prediction = None
        if tr.prediction is not None:
            # the solution just before the fix is used: what a user had at that moment
            # (not at the first fix after an outage: its prior is the coast, which the
            # outage scores hold; it made the drive's 0.04 m about 0.8 m with 15 s outages)
            ep = reference_errors(tr.prediction, reference)
            eph = np.hypot(ep[:, 0], ep[:, 1])
            ok = on & ~returned & np.isfinite(eph)
            prediction = PredictionScores(
                float(np.sqrt(np.mean(eph[ok] ** 2))) if ok.any() else None,
                float(np.sqrt(np.mean(ep[ok, 2] ** 2))) if ok.any() else None,
            )
        per_run = [
            (t_ref, np.hypot(e[:, 0], e[:, 1]), w) for e, w in zip(errs, outages, strict=True)
        ]
        out[name] = RecordedScores(
            horizontal_rms_m=float(np.sqrt(np.mean(e_h[on] ** 2))) if on.any() else None,
            vertical_rms_m=float(np.sqrt(np.mean(err[on, 2] ** 2))) if on.any() else None,
            reference_epochs=int(on.sum()),
            # what the reference covers: the scores say nothing outside it (a walk whose
            # fixes turn float after 88 s is scored on those 88 s only)
            reference_span_s=(float(t_ref[0] + rec.t_start), float(t_ref[-1] + rec.t_start))
            if t_ref.size
            else None,
            longest_unscored_s=_longest_gap(t_ref, float(times[-1])),
            nan_epochs=int(np.sum(~np.isfinite(tr.solution.p[0]).all(-1))),
            prediction=prediction,
            outages=_outages(per_run) if any(outages) else None,
            detection=_detection(
                rec, tr.flag[0], grace, None if tr.available is None else tr.available[0]
            )
            if tr.flag is not None and rec.faults
            else None,
            truth=None if truth is None else score_truth(rec, tr, truth, outages[0]),
            integrity=None if scheduled is None else watch_trace(name, rec, tr, scheduled),
        )
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
) -> TruthScores:
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
    rmse = TruthRmse(
        position_enu_m=(_rms(enu[on, 0]), _rms(enu[on, 1]), _rms(enu[on, 2])),
        horizontal_m=_rms(np.hypot(enu[on, 0], enu[on, 1])),
        velocity_enu_mps=(_rms(dv[on, 0]), _rms(dv[on, 1]), _rms(dv[on, 2])),
        velocity_mps=_rms(np.linalg.norm(dv[on], axis=-1)),
        roll_deg=_rms(d_att[on, 1]),
        pitch_deg=_rms(d_att[on, 0]),
        heading_deg=_rms(d_att[on, 2]),
    )
    nees_scores = None
    if tr.P_nav is not None:
        P = tr.P_nav[run, truth.index]
        nees = np.einsum("ki,ki->k", e, np.linalg.solve(P, e[..., None])[..., 0])
        lo, hi = chi2.ppf([0.025, 0.975], N_NAV)
        after = on & (t >= convergence_s)
        inside = (nees >= lo) & (nees <= hi)
        nees_scores = TruthNees(
            dof=N_NAV,
            band_95=(float(lo), float(hi)),
            convergence_s=convergence_s,
            epochs=int(after.sum()),
            mean=float(np.mean(nees[after])) if after.any() else float("nan"),
            fraction_inside=float(np.mean(inside[after])) if after.any() else float("nan"),
            fraction_above=float(np.mean(nees[after] > hi)) if after.any() else float("nan"),
        )
    gyro, accel = _biases(rec, tr, truth, run)
    return TruthScores(int(on.sum()), rmse, nees_scores, gyro, accel)


def _biases(rec: Recording, tr: Trace, truth: Truth, run: int) -> tuple[BiasScore, BiasScore]:
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
    gyro_bias, accel_bias = (
        BiasScore(
            unit,
            _floats(value * scale),
            _floats(sigma * scale),
            _floats(known * scale),
            None if nominal is None else _floats(nominal * scale),
            _floats(100 * (value - known) / np.abs(known)),
        )
        for value, sigma, known, nominal, unit, scale in (
            (gyro, gyro_sd, truth.gyro_bias, truth.gyro_bias_nominal, "dps", np.degrees(1.0)),
            (accel, accel_sd, truth.accel_bias, truth.accel_bias_nominal, "mg", 1 / 9.80665e-3),
        )
    )
    return gyro_bias, accel_bias


def _detection(
    rec: Recording, flag: np.ndarray, grace: float, available: np.ndarray | None = None
) -> dict[str, DetectionMetrics]:
    """Per aid with injected faults, its flags against the fault windows: a simulated
    campaign's :class:`~ftnav.eval.evaluate.DetectionMetrics` (one type, one name per
    quantity), ``readmitted`` whether the aid was used again after each fault's end.
    A fault there is nothing to detect in is no event: an ``outage`` (the aid is
    absent, not wrong) and a window where the aid measured nothing (``available``
    (K, N), e.g. inside a GNSS outage of the schedule) were counted as missed."""
    out = {}
    for i, name in enumerate(rec.sensor_names):
        windows = [
            (f.start, f.end)
            for f in rec.faults
            if f.sensor == name
            and f.kind != "outage"
            and (
                available is None
                or available[(rec.times >= f.start) & (rec.times < f.end), i].any()
            )
        ]
        if windows:
            flags = flag[None, :, i]
            out[name] = DetectionMetrics.of(
                detection_stats(flags, rec.times, windows, grace),
                readmitted_fraction(flags, rec.times, windows),
            )
    return out
