"""The Rauch–Tung–Striebel smoother of the closed-loop error states (:mod:`ftnav.engine.smoother`).

Oracles:

* independent reference — on a time-varying linear model with multi-rate sensors and a
  gap without measurements, the engine's forward pass (``run(..., smoothing=True)``) and
  the batched backward pass equal FilterPy's ``KalmanFilter`` and ``rts_smoother``, run
  by run, to 1e-9;
* equivalence — a linear error model run closed loop (its fused navigation errors fed
  back and every estimate reset after each epoch) and open loop (output correction)
  gives the same smoothed navigation solution and variances to 1e-9;
* closed forms — with no measurement after epoch k the smoothed estimate equals the
  filtered one from k on (the last epoch always); ``P^s ≤ P⁺`` (the eigenvalues of
  ``P⁺ − P^s`` are ≥ −1e-12 of the scale) and ``P^s`` is symmetric positive definite;
* seeded consistency — on seed002's simulated flight (fault-free, centralized, 10 runs
  of 600 s) the smoothed ANEES of the 9 navigation states lies in ``chi2_band(90, 10)``
  (the bound of ``tests/statistical/test_integrated_seed002.py``, derivation there);
* the real drive (rtklib-drive, GNSS only, 170 s, 15 s outages every 60 s): at the
  withheld RTK fixes the smoothed horizontal error is below the forward filter's in every
  outage and its RMS of the maxima is at most half the forward one; its σ is checked
  against a stated band (see the test: overconfident by about 2 in σ on this drive);
* input validation — a differenced aid, a trace without a record and bad shapes are
  refused with ValueError.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
import pytest
from equivalence_problems import centralized, random_scenario, random_spd
from recording_runs import drive_copy

from ftnav.core import kalman as kf
from ftnav.engine import navigation_model
from ftnav.engine.driver import run
from ftnav.engine.linear import LinearModel as EngineModel
from ftnav.engine.smoother import rts_smoother, smooth, smoothed_trace
from ftnav.eval.metrics import chi2_band, nees
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import errors_at, score_recording
from ftnav.fusion.registry import build, method_config
from ftnav.io.recording_file import load_recording
from ftnav.io.scenario_file import load_scenario
from ftnav.model.system import Epoch, Linearization, LinearModel, LinearSystem, Sensor, TimeVarying
from ftnav.nav.earth import radii
from ftnav.nav.mechanization import InsState, navigation_errors
from ftnav.pipeline import reference_of
from ftnav.scenarios import builtin_path
from ftnav.sim.ins import simulate_ins
from ftnav.sim.linear import simulate

filterpy_kalman = pytest.importorskip("filterpy.kalman")


def _close(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> None:
    np.testing.assert_allclose(a, b, rtol=rtol, atol=rtol * max(1.0, float(np.abs(b).max())))


# -- FilterPy --------------------------------------------------------------------------


def test_linear_smoother_equals_filterpy_for_every_run_of_a_batch():
    rng = np.random.default_rng(1965)
    K, B = 80, 3
    sc = random_scenario(rng, 4, [2, 1], K, every=[1, 2])
    n = sc.model.n
    assert sc.model.F is not None
    Phi = sc.model.F + 0.05 * rng.standard_normal((K, n, n))  # a time-varying model
    Q = np.stack([random_spd(rng, n, 0.1) for _ in range(K)])
    system = sc.system()
    sim = simulate(sc, B, seed=7)
    available = sim.stream.available.copy()
    available[:, 30:45] = False  # 15 epochs without any measurement
    stream = sim.stream._replace(available=available)
    model = EngineModel(system, TimeVarying(Phi, Q))
    tr = run(model, stream, {"ckf": centralized(system)}, K, smoothing=True)["ckf"]
    rec = tr.smoothing
    assert rec is not None and rec.n_fed == 0 and rec.base is None
    x_s, P_s = rts_smoother(rec.x, rec.P, rec.Phi, rec.Q, rec.n_fed)
    s = smooth(tr)
    np.testing.assert_array_equal(s.x, x_s)
    np.testing.assert_array_equal(s.P_diag, np.diagonal(P_s, axis1=-2, axis2=-1))
    dims = [sen.dim for sen in sc.sensors]
    for b in range(B):
        f = filterpy_kalman.KalmanFilter(dim_x=n, dim_z=sum(dims))
        f.x, f.P = sc.model.x0.copy(), sc.model.P0.copy()
        xs, Ps = [], []
        for k in range(K):
            f.predict(F=Phi[k], Q=Q[k])
            use = [i for i in range(len(dims)) if available[b, k, i]]
            if use:
                H = np.vstack([sc.sensors[i].H for i in use])
                R = np.zeros((H.shape[0], H.shape[0]))
                r = 0
                for i in use:
                    R[r : r + dims[i], r : r + dims[i]] = sc.sensors[i].R
                    r += dims[i]
                f.update(np.concatenate([stream.z[i][b, k] for i in use]), R=R, H=H)
            xs.append(np.asarray(f.x).copy())
            Ps.append(np.asarray(f.P).copy())
        x_ref, P_ref, _, _ = f.rts_smoother(np.array(xs), np.array(Ps), Fs=Phi, Qs=Q)
        _close(rec.x[b], np.array(xs))  # the same forward pass
        _close(x_s[b], x_ref)
        _close(P_s[b], P_ref)
    assert np.abs(x_s - rec.x).max() > 1e-3  # the smoother did something


# -- a linear closed-loop "SINS" -------------------------------------------------------

N = 11  # φ (3: decoupled and unobserved, so its estimate stays 0), δv, δp, 2 bias states
M_POS, M_VEL = 3, 3
V_TRUE, P_TRUE = np.array([1.0, -2.0, 0.5]), np.array([0.3, 1.2, 50.0])


class ToyStream(NamedTuple):
    """A linear error model's epochs: Φ, Q (B, K, n, n), process and measurement noise
    draws, availability (B, K, 2), the initial error (B, n)."""

    Phi: np.ndarray
    Q: np.ndarray
    w: np.ndarray
    v: tuple[np.ndarray, np.ndarray]
    H: tuple[np.ndarray, np.ndarray]
    available: np.ndarray
    labels: np.ndarray
    e0: np.ndarray

    @property
    def batch(self) -> int:
        return int(self.e0.shape[0])


class ToySins:
    """A "SINS" whose error evolves exactly by Φ (a linear error model): its state is the
    true error e (rows, n); its solution is the truth plus e (attitude exact); feedback
    removes the fused navigation errors from e (spec §8.5)."""

    per_method_rows = True
    n_fed = 9
    n_local: int | None = 9

    def __init__(self, system: LinearSystem, feedback: bool, psi: tuple = ()):
        self.system, self.feedback, self.psi = system, feedback, psi

    def start(self, stream: ToyStream, copies: int) -> np.ndarray:
        return np.concatenate([stream.e0] * copies)

    def epoch(self, e, stream: ToyStream, k: int, copies: int, local_copies=None):
        def tile(a):
            return np.concatenate([a] * copies)

        Phi, Q = tile(stream.Phi[:, k - 1]), tile(stream.Q[:, k - 1])
        e = kf.mv(Phi, e) + tile(stream.w[:, k - 1])
        avail = tile(stream.available[:, k - 1])
        z = tuple(
            np.where(avail[:, i, None], e @ H.T + tile(v[:, k - 1]), np.nan)
            for i, (H, v) in enumerate(zip(stream.H, stream.v, strict=True))
        )
        Hs = tuple(np.broadcast_to(H, (e.shape[0],) + H.shape) for H in stream.H)
        return e, Epoch(k, z, avail, stream.labels[k - 1], Linearization(Phi, Q, Hs))

    def navigation(self, e) -> InsState:
        rows = e.shape[0]
        q = np.tile([1.0, 0.0, 0.0, 0.0], (rows, 1))
        return InsState(q, V_TRUE + e[:, 3:6], P_TRUE + e[:, 6:9], np.zeros((rows, 3)))

    def compensated_bias(self, e) -> None:
        return None

    def correct(self, e, fused, rows=None):
        if not self.feedback:
            return e
        e = e.copy()
        e[:, :9] -= fused[:, :9]
        return e

    def output(self, e, fused, rows=None) -> InsState:
        nav = self.navigation(e)
        if self.feedback:
            return nav
        return nav._replace(v=nav.v - fused[:, 3:6], p=nav.p - fused[:, 6:9])


def _toy(K: int, B: int, seed: int = 3) -> tuple[LinearSystem, ToyStream]:
    rng = np.random.default_rng(seed)
    m = N - 3
    ortho, _ = np.linalg.qr(rng.standard_normal((m, m)))
    Phi = np.tile(np.eye(N), (B, K, 1, 1))
    Phi[..., 3:, 3:] = 0.98 * ortho + 0.03 * rng.standard_normal((B, K, m, m))
    Q = np.zeros((B, K, N, N))
    Q[..., :3, :3] = 1e-4 * np.eye(3)
    Q[..., 3:, 3:] = random_spd(rng, m, 0.05) * (1.0 + 0.5 * rng.random((B, K, 1, 1)))
    P0 = np.zeros((N, N))
    P0[:3, :3] = 0.01 * np.eye(3)
    P0[3:, 3:] = random_spd(rng, m, 4.0)
    H_pos = np.zeros((M_POS, N))
    H_pos[:, 6:9] = np.eye(3)
    H_pos[:, 9:] = 0.3 * rng.standard_normal((M_POS, 2))
    H_vel = np.zeros((M_VEL, N))
    H_vel[:, 3:6] = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    R_pos, R_vel = random_spd(rng, M_POS, 0.2), random_spd(rng, M_VEL, 0.05)
    model = LinearModel(tuple(f"s{j}" for j in range(N)), None, None, np.zeros(N), P0, None)
    sensors = (Sensor("pos", None, R_pos, R_pos), Sensor("vel", None, R_vel, R_vel))
    system = LinearSystem(model, sensors)
    L = np.linalg.cholesky(Q)
    w = kf.mv(L, rng.standard_normal((B, K, N)))
    v = tuple(
        rng.standard_normal((B, K, R.shape[0])) @ np.linalg.cholesky(R).T for R in (R_pos, R_vel)
    )
    available = np.ones((B, K, 2), bool)
    available[:, 1::3, 0] = False  # position every third epoch missing
    available[:, 20:32] = False  # an outage of both
    e0 = rng.standard_normal((B, N)) @ np.linalg.cholesky(P0).T
    labels = np.zeros((K, 2), bool)
    return system, ToyStream(Phi, Q, w, v, (H_pos, H_vel), available, labels, e0)


def _toy_run(system, stream, feedback: bool, K: int):
    model = ToySins(system, feedback)
    return run(model, stream, {"ckf": centralized(system)}, K, smoothing=True)["ckf"]


def test_closed_loop_and_open_loop_smoothers_agree_on_a_linear_error_model():
    K, B = 60, 3
    system, stream = _toy(K, B)
    closed = _toy_run(system, stream, True, K)
    open_ = _toy_run(system, stream, False, K)
    assert closed.smoothing is not None and closed.smoothing.n_fed == 9
    assert open_.smoothing is not None and open_.smoothing.n_fed == 0
    assert closed.solution is not None and open_.solution is not None
    _close(closed.solution.p, open_.solution.p)  # linear: the forward loops agree
    s_c, s_o = smooth(closed), smooth(open_)
    assert s_c.solution is not None and s_o.solution is not None
    for a, b in ((s_c.solution.v, s_o.solution.v), (s_c.solution.p, s_o.solution.p)):
        _close(a, b)
    _close(s_c.P_diag, s_o.P_diag)
    np.testing.assert_array_equal(s_c.solution.q, closed.solution.q)  # φ̂ = 0 exactly
    assert np.abs(s_c.solution.p - closed.solution.p).max() > 1e-2  # not the forward one
    # smoothed closer to the truth than filtered (RMS over runs and epochs, 9 states)
    err_s = np.sqrt(np.mean((s_c.solution.p - P_TRUE) ** 2))
    err_f = np.sqrt(np.mean((closed.solution.p - P_TRUE) ** 2))
    assert err_s < err_f


def test_no_measurement_after_k_leaves_the_filtered_estimate_and_p_s_below_p_plus():
    K, B, last = 50, 2, 35
    system, stream = _toy(K, B, seed=8)
    available = stream.available.copy()
    available[:, last:] = False  # measurements at epochs 1..last only
    available[:, last - 1] = True
    tr = _toy_run(system, stream._replace(available=available), True, K)
    rec = tr.smoothing
    assert rec is not None
    x_s, P_s = rts_smoother(rec.x, rec.P, rec.Phi, rec.Q, rec.n_fed)
    _close(x_s[:, last - 1 :], rec.x[:, last - 1 :], 1e-10)
    _close(P_s[:, last - 1 :], rec.P[:, last - 1 :], 1e-10)
    assert np.abs(x_s[:, : last - 1] - rec.x[:, : last - 1]).max() > 1e-3
    s = smooth(tr)
    assert s.solution is not None and tr.solution is not None
    _close(s.solution.p[:, last - 1 :], tr.solution.p[:, last - 1 :], 1e-10)
    scale = float(np.abs(rec.P).max())
    assert np.linalg.eigvalsh(rec.P - P_s).min() >= -1e-12 * scale
    np.testing.assert_array_equal(P_s, np.swapaxes(P_s, -1, -2))
    np.linalg.cholesky(P_s)  # positive definite at every run and epoch
    assert np.linalg.eigvalsh(P_s).min() > 0


# -- seeded consistency on a simulated SINS ---------------------------------------------


def test_smoothed_anees_of_a_simulated_flight_is_inside_the_chi2_band():
    sc = load_scenario(builtin_path("seed002"), models=False)
    sc = dataclasses.replace(sc, steps=600, faults=())
    system = sc.system()
    runs = 10
    sim = simulate_ins(sc, range(runs), 1)
    ckf = build(system, method_config("centralized", name="ckf"))
    tr = run(navigation_model(sc, system), sim.stream, {"ckf": ckf}, sc.steps, smoothing=True)
    s = smooth(tr["ckf"])
    assert s.solution is not None
    truth = sim.truth.epochs
    eps = np.empty((runs, sc.steps))
    for k in range(sc.steps):
        sol = [a[:, k] for a in s.solution[:3]]
        e = navigation_errors(*sol, truth.q[k], truth.v[k], truth.p[k])
        eps[:, k] = nees(e, s.P_nav[:, k])
    window = sc.times >= sc.evaluation.skip_initial
    anees = float(eps[:, window].mean())
    lo, hi = chi2_band(90, runs)
    assert lo <= anees <= hi, f"smoothed ANEES {anees:.2f} outside [{lo:.2f}, {hi:.2f}]"


# -- the real drive --------------------------------------------------------------------


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The drive's first 170 s after the alignment, GNSS only, 15 s outages every 60 s."""

    def short(doc):
        doc["filter"]["duration_s"] = 170.0

    path = drive_copy(tmp_path_factory.mktemp("drive") / "drive.toml", short)
    loaded = load_recording(
        path, outage=(15.0, 60.0, 40.0), methods=["ckf"], aids=["gnss", "gnss-vel"], warn=False
    )
    rec = loaded.recording
    filters = build_filters(rec, rec.system(), rec.methods)
    tr = run(navigation_model(rec), loaded.stream, filters, rec.steps, smoothing=True)["ckf"]
    return loaded, tr, smooth(tr)


def test_smoothing_the_drive_shrinks_the_drift_at_withheld_fixes(drive):
    loaded, tr, s = drive
    ref = reference_of(loaded)
    rec = loaded.recording
    fwd = score_recording(rec, {"ckf": tr}, ref, loaded.outages)["ckf"].outages
    smo = score_recording(rec, {"ckf": smoothed_trace(tr, s)}, ref, loaded.outages)["ckf"]
    assert fwd is not None and smo.outages is not None
    assert fwd.count == smo.outages.count == 3
    for f, g in zip(fwd.each, smo.outages.each, strict=True):
        assert g.max_error_m < f.max_error_m
    assert smo.outages.rms_max_error_m <= 0.5 * fwd.rms_max_error_m
    assert smo.horizontal_rms_m < 0.1  # GNSS on: at the fixes, as the forward filter


def test_smoothed_sigma_at_withheld_fixes_is_within_the_stated_band(drive):
    """The 2-dof NEES of the horizontal error at the withheld fixes (against the smoothed
    covariance plus the fix's own R, 0.05 m per axis) has mean 2 for a consistent σ.
    Measured: 6.7 on this span at the antenna (7.1 at the IMU; 8.2 over the whole drive,
    the forward filter 4.4 there:
    ``benchmarks/smoother_drive.py``): the smoothed σ is overconfident by a factor of
    about 2, probably because the 15-state model holds no scale-factor or timing error,
    which dominate once the fixes on both sides have removed the drift (on a simulated
    flight, where the model is exact, it is consistent: above).  The band [0.5, 20]
    states what holds: consistent within a factor of about 3 in σ, not 1."""
    loaded, _, s = drive
    rec = loaded.recording
    assert s.solution is not None
    idx = loaded.reference_index
    t = rec.times[idx]
    withheld = np.zeros(idx.shape, bool)
    for a, b in loaded.outages[0]:
        withheld |= (t >= a) & (t < b)
    p = s.solution.p[0, idx]
    # at the antenna, the point the fixes measure
    e = errors_at(p, s.solution.q[0, idx], loaded.reference_p, loaded.reference_lever_arm)[:, :2]
    R_Mh, R_Nh = radii(p[:, 0], p[:, 2])
    T = np.zeros((idx.size, 2, 2))  # (E, N) metres from (δL, δλ) rad
    T[:, 0, 1] = R_Nh * np.cos(p[:, 0])
    T[:, 1, 0] = R_Mh
    S = T @ s.P_nav[0, idx, 6:8, 6:8] @ np.swapaxes(T, 1, 2) + 0.05**2 * np.eye(2)
    eps = nees(e[withheld], S[withheld])
    assert 0.5 <= float(eps.mean()) <= 20.0


# -- refusals --------------------------------------------------------------------------


def test_a_differenced_aid_a_trace_without_record_and_bad_shapes_are_refused():
    K, B = 5, 1
    system, stream = _toy(K, B)
    differenced = ToySins(system, True, psi=(np.full(3, 0.9), None))
    with pytest.raises(ValueError, match="'pos' uses measurement differencing"):
        run(differenced, stream, {"ckf": centralized(system)}, K, smoothing=True)
    tr = run(differenced, stream, {"ckf": centralized(system)}, K)["ckf"]
    assert tr.smoothing is None
    with pytest.raises(ValueError, match="smoothing=True"):
        smooth(tr)
    x, P = np.zeros((B, K, 2)), np.tile(np.eye(2), (B, K, 1, 1))
    with pytest.raises(ValueError, match="Phi and Q"):
        rts_smoother(x, P, P[:, :, :1], P)
    with pytest.raises(ValueError, match=r"x \(B, K, n\)"):
        rts_smoother(x[0], P, P, P)
    with pytest.raises(ValueError, match="n_fed"):
        rts_smoother(x, P, P, P, 3)
