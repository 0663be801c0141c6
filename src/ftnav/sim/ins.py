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

from ftnav.model.faults import fault_effect, hold_stuck
from ftnav.model.flight import Profile
from ftnav.model.scenario import SINS, InsScenario
from ftnav.model.streams import AidStream, ImuStream, InsStream
from ftnav.nav import attitude
from ftnav.nav.mechanization import InsState
from ftnav.sensors.base import AidTruth
from ftnav.sim.imu import ImuErrorTruth, simulate_imu_errors
from ftnav.sim.trajectory import Trajectory, generate

__all__ = [
    "InsTruth",
    "SimulatedIns",
    "epoch_truth",
    "initial_solution",
    "simulate_ins",
    "trajectory_of",
]

#: Stream numbers (spawn_key component) of the initial INS error draws.
_INIT_STREAM = 900


class InsTruth(NamedTuple):
    """The truth of B simulated runs of an integrated scenario.

    Attributes
    ----------
    trajectory : the true flight (shared by all runs).
    epochs : the truth at the K filter epochs (:class:`~ftnav.sensors.base.AidTruth`).
    imu : the true IMU errors of each run; the Markov drifts (B, K, 3) at the K
        filter epochs (the value over each epoch's last IMU interval).
    init_error : (B, n) initial INS error (the 9 navigation states are applied; the
        bias states are the IMU's own truth).
    runs : the run indices.
    """

    trajectory: Trajectory
    epochs: AidTruth
    imu: ImuErrorTruth
    init_error: np.ndarray
    runs: range


class SimulatedIns(NamedTuple):
    """A simulator's output: the stream the engine consumes and, apart, the truth."""

    stream: InsStream
    truth: InsTruth


@lru_cache(maxsize=4)
def trajectory_of(profile: Profile) -> Trajectory:
    """The true flight of a profile (cached: profiles are immutable)."""
    return generate(profile)


def epoch_truth(traj: Trajectory, every: int, steps: int) -> AidTruth:
    """Truth at the filter epochs ``t_k``, ``k = 1..steps`` (every ``every`` IMU samples)."""
    idx = every * np.arange(1, steps + 1)
    q = attitude.euler_to_quat(traj.euler[idx])
    # the gyro's rate at t_k: the mean of the increments on either side (the last one
    # alone at the trajectory's end), a central difference of the ideal attitude
    after = traj.dtheta[np.minimum(idx, len(traj.dtheta) - 1)]
    w = 0.5 * (traj.dtheta[idx - 1] + after) / traj.dt
    return AidTruth(traj.t[idx], traj.p[idx], traj.v[idx], q, w)


def initial_solution(traj: Trajectory, init_error: np.ndarray) -> InsState:
    """Truth at t = 0 plus each run's initial navigation error (spec §8.3 order)."""
    e = init_error
    B = e.shape[0]
    q_true = attitude.euler_to_quat(traj.euler[0])
    q = attitude.quat_mul(attitude.rotvec_to_quat(-e[:, 0:3]), np.broadcast_to(q_true, (B, 4)))
    v = traj.v[0] + e[:, 3:6]
    p = traj.p[0] + e[:, 6:9]
    return InsState(q / np.linalg.norm(q, axis=-1, keepdims=True), v, p, np.zeros((B, 3)))


def simulate_ins(scenario: InsScenario, runs: range, seed: int) -> SimulatedIns:
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
            window = (t_imu >= f.start) & (t_imu < f.end)
            dtheta[:, window] += np.asarray(f.magnitude) * traj.dt
    truth = epoch_truth(traj, n, K)
    n_states = sc.initial_sigma.shape[0]  # 18, 15 or 21: the first 9 draws are the same
    init = (
        np.stack(
            [
                np.random.default_rng(
                    np.random.SeedSequence(seed, spawn_key=(r, _INIT_STREAM))
                ).standard_normal(max(18, n_states))[:n_states]
                for r in runs
            ]
        )
        * sc.initial_sigma
    )
    aids, labels = [], np.zeros((K, len(sc.aids)), bool)
    for i, aid in enumerate(sc.aids):
        s = aid.sensor
        err = s.simulate_errors(truth, seed, runs, i)
        effect = fault_effect(sc.faults, s.name, truth.t, s.dim)
        total = err.coloured + err.white * effect.scale[None] + effect.offset[None]
        raw = hold_stuck(np.array(s.output(truth, total, err.constants), dtype=float), effect)
        ok = aid.available(K)[None, :] & ~effect.outage[None, :] & np.ones((B, 1), bool)
        raw[~ok] = np.nan
        aids.append(AidStream(truth.t, raw, ok))
        labels[:, i] = effect.label
    stream = InsStream(
        ImuStream(0.0, traj.dt, t_imu, dtheta, dv),
        tuple(aids),
        initial_solution(traj, init),
        labels,
    )
    return SimulatedIns(stream, InsTruth(traj, truth, imu_truth, init, runs))
