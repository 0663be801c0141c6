"""Simulated data of an integrated-navigation scenario: IMU, aids and faults (spec §9-§10).

Truth and corruption stay apart (style §6): the profile gives the true trajectory
and ideal IMU increments; :func:`ftnav.sim.imu.simulate_imu_errors` corrupts them;
each aid simulates its errors in its metric measurement space, the faults of spec
§9.6 are applied to those errors (or to the IMU), and only then is the raw output a
real device would log formed.  Every random draw comes from a per-run stream
(``SeedSequence(seed, spawn_key=(run, ...))``), so run i is the same alone or in a
batch, and switching a fault off leaves every other draw unchanged.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from ftnav.model.flight import Profile
from ftnav.model.ins_scenario import SINS, InsFault, InsScenario
from ftnav.nav import attitude
from ftnav.sensors.base import AidTruth
from ftnav.sim.imu import ImuErrorTruth, simulate_imu_errors
from ftnav.sim.trajectory import Trajectory, generate

__all__ = ["InsData", "simulate_ins", "trajectory_of", "epoch_truth", "fault_profiles"]

#: Stream numbers (spawn_key component) of the initial INS error draws.
_INIT_STREAM = 900


class InsData(NamedTuple):
    """Data of B runs.

    Attributes
    ----------
    trajectory : the true flight (shared by all runs).
    truth : truth at the K filter epochs.
    dtheta, dv : (B, K·n, 3) measured IMU increments (n samples per filter epoch).
    imu_truth : the true IMU errors of each run; the Markov drifts (B, K, 3) at the K
        filter epochs (the value over each epoch's last IMU interval).
    init_error : (B, n) initial INS error, n the filter's states (only the 9 navigation
        states are applied; the bias states are the IMU's own truth).
    raw : per aid, the raw output at the K epochs (B, K, ...), NaN where there is none.
    available : (B, K, N) bool, the aid has an output (schedule, outages).
    oracle : (K, N) bool, true detectable fault windows per aid.
    runs : the run indices.
    """

    trajectory: Trajectory
    truth: AidTruth
    dtheta: np.ndarray
    dv: np.ndarray
    imu_truth: ImuErrorTruth
    init_error: np.ndarray
    raw: tuple[np.ndarray, ...]
    available: np.ndarray
    oracle: np.ndarray
    runs: range


@lru_cache(maxsize=4)
def trajectory_of(profile: Profile) -> Trajectory:
    """The true flight of a profile (cached: profiles are immutable)."""
    return generate(profile)


def epoch_truth(traj: Trajectory, every: int, steps: int) -> AidTruth:
    """Truth at the filter epochs ``t_k``, ``k = 1..steps`` (every ``every`` IMU samples)."""
    idx = every * np.arange(1, steps + 1)
    q = attitude.euler_to_quat(traj.euler[idx])
    return AidTruth(traj.t[idx], traj.p[idx], traj.v[idx], q)


def _window(t: np.ndarray, f: InsFault) -> np.ndarray:
    return (t >= f.start) & (t < f.end)


def fault_profiles(faults, sensor: str, t: np.ndarray, m: int):
    """Offset (K, m) and white-noise scale (K,) of an aid's faults (spec §9.6)."""
    offset = np.zeros((t.size, m))
    scale = np.ones(t.size)
    for f in faults:
        if f.sensor != sensor:
            continue
        w = _window(t, f)
        frac = np.clip((t - f.start) / max(f.end - f.start, 1e-12), 0.0, 1.0)
        if f.kind == "bias":
            offset[w] += f.magnitude
        elif f.kind == "ramp":
            offset[w] += frac[w, None] * f.magnitude
        elif f.kind == "noise-scale":
            scale[w] *= float(f.magnitude[0])
        elif f.kind == "noise-ramp":
            scale[w] *= 1.0 + (float(f.magnitude[0]) - 1.0) * frac[w]
    return offset, scale


def simulate_ins(scenario: InsScenario, runs: range, seed: int) -> InsData:
    """Simulate the IMU and every aid of ``scenario`` for the given runs."""
    sc = scenario
    traj = trajectory_of(sc.profile)
    n = sc.samples_per_epoch
    K = sc.steps
    n_imu = n * K
    if n_imu > traj.dtheta.shape[0]:
        raise ValueError(f"steps: {K} epochs of {sc.dt} s exceed the profile's {traj.t[-1]:.0f} s")
    B = len(runs)
    imu = simulate_imu_errors(
        traj.dtheta[:n_imu], traj.dv[:n_imu], traj.dt, sc.imu, seed, runs.start, runs=B
    )
    dtheta, dv = imu.dtheta, imu.dv  # fresh arrays of this call: faults are added in place
    # the Markov truth at the filter epochs only (the last IMU interval of each epoch):
    # the IMU-rate arrays would double the memory of a batch
    imu_truth = imu.truth._replace(
        gyro_markov=imu.truth.gyro_markov[:, n - 1 :: n].copy(),
        accel_markov=imu.truth.accel_markov[:, n - 1 :: n].copy(),
    )
    del imu
    t_imu = traj.dt * np.arange(1, n_imu + 1)  # end time of each IMU interval
    for f in sc.faults:
        if f.sensor == SINS and f.kind == "gyro-bias":
            dtheta[:, _window(t_imu, f)] += np.asarray(f.magnitude) * traj.dt
    truth = epoch_truth(traj, n, K)
    n_states = sc.initial_sigma.shape[0]  # 18 or 15: the first 9 draws are the same
    init = (
        np.stack(
            [
                np.random.default_rng(
                    np.random.SeedSequence(seed, spawn_key=(r, _INIT_STREAM))
                ).standard_normal(18)[:n_states]
                for r in runs
            ]
        )
        * sc.initial_sigma
    )
    raws, avail, oracle = (
        [],
        np.zeros((B, K, len(sc.aids)), bool),
        np.zeros((K, len(sc.aids)), bool),
    )
    for i, aid in enumerate(sc.aids):
        s = aid.sensor
        err = s.simulate_errors(truth, seed, runs, i)
        offset, scale = fault_profiles(sc.faults, s.name, truth.t, s.dim)
        total = err.coloured + err.white * scale[None, :, None] + offset[None]
        raw = np.array(s.output(truth, total, err.constants), dtype=float)
        ok = np.broadcast_to(aid.available(K), (B, K)).copy()
        for f in sc.faults:
            if f.sensor != s.name:
                continue
            w = _window(truth.t, f)
            if f.kind == "outage":
                ok[:, w] = False
            elif f.kind == "stuck":
                first = int(np.argmax(w))
                if w.any() and first > 0:
                    raw[:, w] = raw[:, first - 1 : first]
            if f.kind != "outage":
                oracle[:, i] |= w
        raw[~ok] = np.nan
        raws.append(raw)
        avail[:, :, i] = ok
    return InsData(traj, truth, dtheta, dv, imu_truth, init, tuple(raws), avail, oracle, runs)
