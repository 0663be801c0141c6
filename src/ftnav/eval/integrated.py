"""Closed-loop Monte Carlo runner of integrated navigation (spec §6.2, §8.4-§8.5, §9).

Every method owns a SINS mechanization per run (batched, :mod:`ftnav.nav.mechanization`)
and a fusion filter over the SINS/aid local error-state filters.  Per filter epoch:

1. the 18-state error model is linearized at each run's INS solution at the start of
   the epoch (specific force averaged over the epoch) and discretized (spec §8.4);
2. the SINS integrates the epoch's IMU increments;
3. each aid's nonlinear measurement ``z = INS − aid`` and its ``H`` are formed at the
   INS solution (:mod:`ftnav.sensors`); gated epochs count as missing;
4. the filter steps with these per-run matrices (:class:`~ftnav.model.system.Linearization`:
   every local filter and the centre use the same ones);
5. with ``correction = "feedback"`` the fused navigation errors are fed back to the
   SINS and every estimate is shifted by the same correction (spec §6.2).

The reported output is the corrected navigation solution; its errors against the
truth (spec §11) are the metric states of :data:`~ftnav.model.ins_scenario.METRIC_STATES`.
The loop over epochs is in Python; everything inside is batched over runs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.eval.metrics import nees
from ftnav.eval.montecarlo import MethodResult, ScenarioResult, build_filter, split_result
from ftnav.fusion.feedback import local_estimates, shift_estimates
from ftnav.model.ins_scenario import InsScenario
from ftnav.model.scenario import LinearModel, Sensor
from ftnav.model.system import Linearization, LinearSystem
from ftnav.nav import attitude
from ftnav.nav.earth import radii
from ftnav.nav.error_model import discrete_model
from ftnav.nav.mechanization import InsState, feedback, integrate, navigation_errors
from ftnav.parallel import run_tasks, split_even
from ftnav.sim.ins_data import InsData, simulate_ins

__all__ = [
    "build_ins_system",
    "run_ins_scenario",
    "run_ins_methods",
    "chunk_runs",
    "IntegratedSimulation",
    "initial_ins_state",
]

_ARCMIN = np.pi / 180.0 / 60.0
N_NAV = 9


class IntegratedSimulation(NamedTuple):
    """What the metric code reads as ``result.simulation``.

    ``truth`` is zero: the method results already hold output *errors* (computed −
    true) in the metric states, so ``estimate − truth`` is the error.
    """

    truth: np.ndarray
    data: InsData | None = None


class InsSystem(LinearSystem):
    """The local filters' model: 18 SINS error states plus each aid's private states.

    Its transition and measurement matrices come from each epoch's
    :class:`~ftnav.model.system.Linearization`; the constant ``H`` of the sensors is a
    nominal value (used only by the ``information`` sharing rule).
    """

    def compatibility(self) -> dict:
        """As :meth:`LinearSystem.compatibility`, without F, Q and the nominal H.

        A learned model trained along one flight must serve another flight of the
        same sensors and filters.
        """
        from ftnav.io.model_file import system_hash

        parts = {"states": list(self.model.states), "P0": self.model.P0}
        for s in self.sensors:
            parts[f"sensor:{s.name}"] = {
                "R": s.R,
                "every": s.every,
                "offset": s.offset,
                "private": None
                if s.private is None
                else {
                    "names": list(s.private.names),
                    "F": s.private.F,
                    "Q": s.private.Q,
                    "P0": s.private.P0,
                },
            }
        return {
            "states": list(self.model.states),
            "sensors": [s.name for s in self.sensors],
            "measurement_dims": [s.dim for s in self.sensors],
            "system_hash": system_hash(parts),
        }


def _nominal_H(sensor, truth, n: int) -> np.ndarray:
    """H of a sensor at the middle epoch of the flight, error-free (a fixed nominal)."""
    from ftnav.sensors.base import AidTruth

    j = truth.t.size // 2
    tr = AidTruth(*(a[j : j + 1] for a in truth))
    c = sensor.simulate_errors(tr, 0, range(1), 0).constants * 0.0
    raw = sensor.output(tr, np.zeros((1, 1, sensor.dim)), c)[:, 0]
    lin = sensor.measure(tr.q, tr.v, tr.p, raw)
    H = np.nan_to_num(lin.H[0, :, :n])
    return H


def build_ins_system(sc: InsScenario) -> InsSystem:
    """The linear-system view of a scenario the fusion architectures work on."""
    from ftnav.sim.ins_data import epoch_truth, trajectory_of

    n = sc.error_model.n
    P0 = np.diag(np.asarray(sc.initial_sigma[:n], float) ** 2)
    model = LinearModel(
        sc.error_model.names, np.eye(n), np.zeros((n, n)), np.zeros(n), P0, np.zeros((n, n))
    )
    truth = epoch_truth(trajectory_of(sc.profile), sc.samples_per_epoch, sc.steps)
    sensors = tuple(
        Sensor(
            a.name,
            _nominal_H(a.sensor, truth, n),
            a.sensor.R,
            a.sensor.R,
            a.every,
            a.offset,
            a.sensor.private,
        )
        for a in sc.aids
    )
    return InsSystem(model, sensors)


def initial_ins_state(data: InsData) -> InsState:
    """Truth at t = 0 plus each run's initial navigation error (spec §8.3 order)."""
    traj = data.trajectory
    e = data.init_error
    B = e.shape[0]
    q_true = attitude.euler_to_quat(traj.euler[0])
    q = attitude.quat_mul(attitude.rotvec_to_quat(-e[:, 0:3]), np.broadcast_to(q_true, (B, 4)))
    v = traj.v[0] + e[:, 3:6]
    p = traj.p[0] + e[:, 6:9]
    return InsState(q / np.linalg.norm(q, axis=-1, keepdims=True), v, p, np.zeros((B, 3)))


#: Order of the metric states (E, N, U position; velocity; φ) in the spec §8.3 error state.
_METRIC_ORDER = [7, 6, 8, 3, 4, 5, 0, 1, 2]


def _metric_scale(p_true: np.ndarray) -> np.ndarray:
    """(..., 9) metric units per error-state unit, in metric-state order (spec §9, §11)."""
    RM, RN = radii(p_true[..., 0], p_true[..., 2])
    h = p_true[..., 2]
    scale = np.empty(p_true.shape[:-1] + (N_NAV,))
    scale[..., 0] = (RN + h) * np.cos(p_true[..., 0])
    scale[..., 1] = RM + h
    scale[..., 2:6] = 1.0
    scale[..., 6:9] = 1.0 / _ARCMIN
    return scale


def _metric_errors(e: np.ndarray, p_true: np.ndarray) -> np.ndarray:
    """(..., 9) output errors in metric states: E/N/U m, E/N/U m/s, φ E/N/U arcmin."""
    return e[..., _METRIC_ORDER] * _metric_scale(p_true)


def _metric_variances(P: np.ndarray, p_true: np.ndarray) -> np.ndarray:
    """(B, 9) variances of the metric states from a covariance over ``[φ, δv, δp, ...]``."""
    d = np.diagonal(P, axis1=-2, axis2=-1)[..., :N_NAV]
    return d[..., _METRIC_ORDER] * _metric_scale(p_true) ** 2


class LocalTrack(NamedTuple):
    """Per-epoch local-filter output errors (B, K, N, 3): position E/N/U in metres."""

    pos: np.ndarray


class _Recorder:
    """Per-epoch outputs of one method, filled in place."""

    def __init__(self, B: int, K: int, N: int, dims):
        self.x = np.empty((B, K, N_NAV))
        self.P = np.empty((B, K, N_NAV))
        self.nees = np.empty((B, K))
        self.beta = self.stat = self.thr = self.raw = self.flag = None
        self.R_hat = [np.empty((B, K, m)) for m in dims]
        self.nan = np.zeros((B, N), dtype=int)
        self.local = None
        self.features = None
        self.truth = None
        self.shape = (B, K, N)

    def detection(self, k, out):
        B, K, N = self.shape
        if out.beta is not None:
            if self.beta is None:
                self.beta = np.empty((B, K, N))
            self.beta[:, k] = out.beta
        if out.detection is not None:
            if self.stat is None:
                self.stat, self.thr = np.empty((B, K, N)), np.empty((B, K, N))
                self.raw, self.flag = np.empty((B, K, N), bool), np.empty((B, K, N), bool)
            d = out.detection
            self.stat[:, k], self.thr[:, k] = d.statistic, d.threshold
            self.raw[:, k], self.flag[:, k] = d.raw, d.flag
        for i, r in enumerate(out.R_hat):
            self.R_hat[i][:, k] = r
        self.nan += out.nan
        if out.features is not None:
            if self.features is None:
                self.features = np.empty((B, K, out.features.shape[-1]))
            self.features[:, k] = out.features

    def result(self) -> tuple[MethodResult, LocalTrack | None]:
        res = MethodResult(
            self.x,
            self.P,
            self.nees,
            self.beta,
            self.stat,
            self.thr,
            self.raw,
            self.flag,
            tuple(self.R_hat),
            self.nan,
            self.features,
        )
        return res, (None if self.local is None else LocalTrack(self.local))


def _tile(a: np.ndarray, M: int) -> np.ndarray:
    return a if M == 1 else np.concatenate([a] * M, 0)


def run_ins_methods(
    filters: dict,
    sc: InsScenario,
    data: InsData,
    system: InsSystem,
    progress: Callable[[int], None] | None = None,
    check_spd: bool = False,
    true_states: np.ndarray | None = None,
) -> dict[str, tuple[MethodResult, LocalTrack | None]]:
    """Run every fusion method closed-loop over the simulated runs (module docstring).

    Each method has its own SINS per run; the SINS of all methods are integrated,
    linearized and measured as one batch of ``methods × runs`` (lock-step), and each
    filter steps on its slice.  A NaN or inf output raises ``FloatingPointError``;
    ``check_spd`` also requires every fused covariance to be symmetric positive
    definite at every epoch.  ``true_states`` (B, K, n), if given, is filled with the
    true error state before feedback (navigation errors of the first method's SINS,
    then the IMU's true biases as the error model's states hold them: 18 states
    ε_b, ε_r, ∇ = constant + Markov accelerometer bias; 15 states ε and ∇ each
    constant + Markov): the targets of learned fusion.
    """
    names = list(filters)
    M = len(names)
    B = data.init_error.shape[0]
    K, N = sc.steps, len(sc.aids)
    n = system.n_common
    spe = sc.samples_per_epoch
    dt_imu = data.trajectory.dt
    ins = initial_ins_state(data)
    ins = InsState(*(_tile(a, M) for a in ins))
    states = [filters[nm].init(B) for nm in names]
    zr = [getattr(filters[nm], "zr", False) for nm in names]
    rec = [_Recorder(B, K, N, [a.dim for a in sc.aids]) for _ in names]
    feedback_on = sc.correction == "feedback"
    truth = data.truth
    every = spe // (2 if sc.algorithm == "two-sample" else 1)
    parts = [slice(j * B, (j + 1) * B) for j in range(M)]
    d_all, P_all = np.empty((M * B, N_NAV)), np.empty((M * B, N_NAV, N_NAV))
    psi = [getattr(a.sensor, "difference_factor", None) for a in sc.aids]
    differencing = any(p is not None for p in psi)
    previous = [None] * N  # last raw (z, H, usable) of each differenced aid
    shift = None  # the correction fed back after the last epoch, over the common states
    for k in range(1, K + 1):
        sl = slice((k - 1) * spe, k * spe)
        dth, dvel = _tile(data.dtheta[:, sl], M), _tile(data.dv[:, sl], M)
        f_b = dvel.sum(1) / sc.dt
        C_bn = attitude.quat_to_dcm(ins.q)
        Phi, Q = discrete_model(
            ins.p[:, 0],
            ins.p[:, 1],
            ins.p[:, 2],
            ins.v,
            f_b,
            C_bn,
            sc.error_model,
            sc.dt,
            sc.discretization,
            5,
        )
        ins, _ = integrate(ins, dth, dvel, dt_imu, algorithm=sc.algorithm, output_every=every)
        z, H, avail = [], [], np.zeros((M * B, N), bool)
        for i, aid in enumerate(sc.aids):
            raw = _tile(data.raw[i][:, k - 1], M)
            lin = aid.sensor.measure(ins.q, ins.v, ins.p, np.nan_to_num(raw, nan=1.0))
            ok = _tile(data.available[:, k - 1, i], M) & lin.valid & np.isfinite(lin.z).all(-1)
            zi, Hi = lin.z, np.nan_to_num(np.concatenate([lin.H[..., :n], lin.H_private], -1))
            if psi[i] is not None:  # measurement differencing of a Markov error (GNSS)
                this = (zi, Hi, ok)
                if previous[i] is None:
                    ok = np.zeros_like(ok)  # nothing to difference with yet
                else:
                    z_prev, H_prev, ok_prev = previous[i]
                    zi, Hi = kf.differenced_measurement(zi, Hi, z_prev, H_prev, Phi, psi[i], shift)
                    ok = ok & ok_prev
                previous[i] = this
            z.append(np.where(ok[:, None], zi, np.nan))
            H.append(Hi)
            avail[:, i] = ok
        e_true = navigation_errors(
            ins.q, ins.v, ins.p, truth.q[k - 1], truth.v[k - 1], truth.p[k - 1]
        )
        if true_states is not None:
            it = data.imu_truth
            accel = it.accel_bias + it.accel_markov[:, k - 1]  # ∇ holds both (18 and 15)
            gyro = (
                [it.gyro_bias, it.gyro_markov[:, k - 1]]
                if n == 18
                else [it.gyro_bias + it.gyro_markov[:, k - 1]]
            )
            true_states[:, k - 1] = np.concatenate([e_true[:B], *gyro, accel], -1)
        for j, nm in enumerate(names):
            p = parts[j]
            lin_k = Linearization(Phi[p], Q[p], tuple(h[p] for h in H))
            states[j], out = filters[nm].step(
                states[j], k, [zz[p] for zz in z], avail[p], data.oracle[k - 1], lin=lin_k
            )
            if not (np.isfinite(out.x).all() and np.isfinite(out.P).all()):
                raise FloatingPointError(f"methods[{nm}]: NaN or inf at epoch {k}")
            if check_spd and not fused_covariance_ok(out.P):
                raise FloatingPointError(
                    f"methods[{nm}]: covariance not symmetric positive definite at epoch {k}"
                )
            r = rec[j]
            xg = out.x[:, :N_NAV]
            d_all[p], P_all[p] = xg, out.P[:, :N_NAV, :N_NAV]
            locs = None if zr[j] else local_estimates(states[j], N_NAV)
            if locs is not None:
                if r.local is None:
                    r.local = np.empty((B, K, N, 3))
                r.local[:, k - 1] = _metric_errors(e_true[p][:, None, :] - locs, truth.p[k - 1])[
                    ..., :3
                ]
            if feedback_on:
                states[j] = shift_estimates(states[j], xg, information=zr[j])
            else:
                r.x[:, k - 1] = _metric_errors(e_true[p] - xg, truth.p[k - 1])
            r.detection(k - 1, out)
            if progress is not None:
                progress(1)
        # NEES and variances of every method in one batch
        eps = nees(d_all - e_true, P_all)
        var = _metric_variances(P_all, truth.p[k - 1])
        for j in range(M):
            rec[j].nees[:, k - 1], rec[j].P[:, k - 1] = eps[parts[j]], var[parts[j]]
        if feedback_on:
            ins = feedback(ins, d_all[:, 0:3], d_all[:, 3:6], d_all[:, 6:9])
            if differencing:
                shift = np.concatenate([d_all, np.zeros((M * B, n - N_NAV))], 1)
            e_out = _metric_errors(
                navigation_errors(
                    ins.q, ins.v, ins.p, truth.q[k - 1], truth.v[k - 1], truth.p[k - 1]
                ),
                truth.p[k - 1],
            )
            for j in range(M):
                rec[j].x[:, k - 1] = e_out[parts[j]]
    return {nm: rec[j].result() for j, nm in enumerate(names)}


class IntegratedResult(NamedTuple):
    """Result of :func:`run_ins_scenario` (a :class:`ScenarioResult` plus local tracks)."""

    result: ScenarioResult
    local: dict[str, LocalTrack | None]
    local_fault_free: dict[str, LocalTrack | None]


#: memory budget of one batch's simulated IMU increments (bytes); the simulation's
#: temporaries roughly double it at its peak
CHUNK_BYTES = 2 << 30


def chunk_runs(sc: InsScenario, twin: bool = True) -> int:
    """Runs per batch so the batch's IMU increments stay within :data:`CHUNK_BYTES`.

    Per run and per SINS: the increments ``dθ``, ``Δv``, ``2 × 3`` float64 per IMU
    sample; the fault-free twin doubles it.  A 3600 s flight at 100 Hz gives 62 runs
    per batch.
    """
    per_run = sc.samples_per_epoch * sc.steps * 6 * 8 * (2 if twin else 1)
    return max(1, CHUNK_BYTES // per_run)


def run_ins_scenario(
    sc: InsScenario,
    runs: int,
    seed: int,
    *,
    methods=None,
    fault_free: bool = True,
    first_run: int = 0,
    progress: Callable[[int], None] | None = None,
    check_spd: bool = False,
    chunk: int | None = None,
    workers: int = 1,
) -> IntegratedResult:
    """Simulate and run every method closed-loop; with faults, also the fault-free twin.

    The fault-free twin draws the same random streams with the faults removed and
    runs in the same batch (2·runs), as in :func:`ftnav.eval.montecarlo.run_scenario`.
    Runs are processed in batches of ``chunk`` (default :func:`chunk_runs`, which
    bounds the memory of the simulated IMU data); every run draws its own random
    streams, so the results do not depend on the batching.  ``workers > 1`` runs the
    batches (and, with fewer batches than workers, groups of methods) in that many
    processes (:mod:`ftnav.parallel`), each simulating its own runs; the results
    are the same.  The simulated data are kept in ``result.simulation.data`` when
    everything ran as one batch in this process, else None.
    """
    if runs < 1:
        raise ValueError(f"runs: must be >= 1, got {runs}")
    methods = tuple(sc.methods if methods is None else methods)
    chunk = chunk_runs(sc, fault_free and bool(sc.faults)) if chunk is None else int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk: must be >= 1, got {chunk}")
    system = build_ins_system(sc)
    for m in methods:  # validate every method before anything is simulated
        build_filter(system, m)
    if workers > 1:  # no more runs per batch than share the workers evenly
        chunk = min(chunk, -(-runs // workers))
    starts = range(first_run, first_run + runs, chunk)
    groups = [methods]
    if workers > 1 and len(starts) < workers:
        groups = [tuple(g) for g in split_even(methods, -(-workers // len(starts)))]
    keep = len(starts) * len(groups) == 1  # the simulated data stay in this process
    tasks = [
        (sc, range(s, min(s + chunk, first_run + runs)), seed, g, fault_free, check_spd, keep)
        for s in starts
        for g in groups
    ]
    parts = run_tasks(_ins_task, tasks, workers, progress)
    by_chunk = [
        _merge_methods(parts[i : i + len(groups)], methods)
        for i in range(0, len(parts), len(groups))
    ]
    if len(by_chunk) == 1:
        return by_chunk[0]
    return _merge_chunks(by_chunk, runs)


def _ins_task(task, progress: Callable[[int], None] | None = None) -> IntegratedResult:
    """One task of :func:`run_ins_scenario`: a group of methods over a batch of runs."""
    sc, rr, seed, methods, fault_free, check_spd, keep = task
    runs = len(rr)
    system = build_ins_system(sc)
    filters = {m.name: build_filter(system, m) for m in methods}
    data = simulate_ins(sc, rr, seed)
    twin = fault_free and bool(sc.faults)
    both = data
    if twin:
        both = _concat(data, simulate_ins(sc.without_faults(), rr, seed))
    results, ff, local, local_ff = {}, {}, {}, {}
    for name, (res, loc) in run_ins_methods(filters, sc, both, system, progress, check_spd).items():
        if twin:
            results[name], ff[name] = split_result(res, runs)
            local[name] = None if loc is None else LocalTrack(loc.pos[:runs])
            local_ff[name] = None if loc is None else LocalTrack(loc.pos[runs:])
        else:
            results[name], local[name] = res, loc
    zeros = np.zeros((runs, sc.steps, N_NAV))
    sr = ScenarioResult(
        sc,
        runs,
        seed,
        IntegratedSimulation(zeros, data if keep else None),
        results,
        IntegratedSimulation(zeros) if twin else None,
        ff,
    )
    return IntegratedResult(sr, local, local_ff)


def _merge_methods(parts: list[IntegratedResult], methods) -> IntegratedResult:
    """One result from groups of methods run on the same batch of runs."""
    if len(parts) == 1:
        return parts[0]
    order = [m.name for m in methods]

    def union(dicts):
        merged = {k: v for d in dicts for k, v in d.items()}
        return {k: merged[k] for k in order if k in merged}

    r0 = parts[0].result
    sr = r0._replace(
        simulation=IntegratedSimulation(r0.simulation.truth),
        results=union([p.result.results for p in parts]),
        fault_free=union([p.result.fault_free for p in parts]),
    )
    return IntegratedResult(
        sr, union([p.local for p in parts]), union([p.local_fault_free for p in parts])
    )


def _merge_chunks(parts: list[IntegratedResult], runs: int) -> IntegratedResult:
    """One result from batches of consecutive runs (the run axis concatenated)."""

    def cat(arrays):
        first = arrays[0]
        if first is None:
            return None
        if isinstance(first, tuple):
            return tuple(cat(list(a)) for a in zip(*arrays, strict=True))
        return np.concatenate(arrays, 0)

    def methods(dicts):
        return {
            name: type(dicts[0][name])(*cat([d[name] for d in dicts]))
            if dicts[0][name] is not None
            else None
            for name in dicts[0]
        }

    r0 = parts[0].result
    sc = r0.scenario
    zeros = np.zeros((runs, sc.steps, N_NAV))
    sr = ScenarioResult(
        sc,
        runs,
        r0.seed,
        IntegratedSimulation(zeros),
        methods([p.result.results for p in parts]),
        None if r0.fault_free_simulation is None else IntegratedSimulation(zeros),
        methods([p.result.fault_free for p in parts]),
    )
    return IntegratedResult(
        sr, methods([p.local for p in parts]), methods([p.local_fault_free for p in parts])
    )


def _concat(a: InsData, b: InsData) -> InsData:
    """Two simulations of the same runs as one batch (the oracle becomes per run)."""
    B = a.init_error.shape[0]
    oracle = np.concatenate(
        [
            np.broadcast_to(a.oracle[:, None], (a.oracle.shape[0], B, a.oracle.shape[1])),
            np.broadcast_to(b.oracle[:, None], (b.oracle.shape[0], B, b.oracle.shape[1])),
        ],
        1,
    )
    from ftnav.sim.imu import ImuErrorTruth

    return InsData(
        a.trajectory,
        a.truth,
        np.concatenate([a.dtheta, b.dtheta]),
        np.concatenate([a.dv, b.dv]),
        ImuErrorTruth(
            *(np.concatenate([x, y]) for x, y in zip(a.imu_truth, b.imu_truth, strict=True))
        ),
        np.concatenate([a.init_error, b.init_error]),
        tuple(np.concatenate([x, y]) for x, y in zip(a.raw, b.raw, strict=True)),
        np.concatenate([a.available, b.available]),
        oracle,
        a.runs,
    )


def fused_covariance_ok(P: np.ndarray) -> bool:
    """Symmetric and positive definite (Cholesky succeeds) for every run."""
    if (
        not np.allclose(P, kf.mT(P), rtol=0, atol=1e-12 * np.abs(P).max())
        or not (np.diagonal(P, axis1=-2, axis2=-1) > 0).all()
    ):
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True
