"""Recorded-log building blocks against closed forms and finite differences.

Oracles: levelling recovers the pitch and roll that generated a still IMU's specific
force (``f^b = C_n^b [0, 0, g]``); the increments of sample-and-hold rates on any grid
sum to the exact integral and equal it piecewise; the outage schedule and its
interleaving follow their definitions; the NHC and the GNSS lever arm Jacobians equal
central finite differences of their measurement functions.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftnav.model.scenario import Fault
from ftnav.model.streams import AidStream, ImuStream, InsStream
from ftnav.nav import attitude
from ftnav.nav.earth import enu_metres, omega_ie_n
from ftnav.nav.mechanization import InsState
from ftnav.pipeline import parse_fault
from ftnav.recorded.imu import ImuLog, clean, increments, stationary
from ftnav.recorded.stream import (
    GnssLog,
    gnss_raw,
    imu_with_faults,
    interleave,
    level,
    on_grid,
    outage_schedule,
    retime_velocity,
    with_outages,
)
from ftnav.sensors.gnss import Gnss
from ftnav.sensors.vehicle import Nhc, Zupt


@pytest.mark.parametrize("theta,gamma", [(0.1, -0.2), (-0.3, 0.05), (0.0, 0.0), (0.7, 1.2)])
def test_levelling_inverts_the_still_specific_force(theta, gamma):
    C_bn = attitude.euler_to_dcm(np.array([theta, gamma, 0.37]))
    f_b = C_bn.T @ np.array([0.0, 0.0, 9.81])
    t, g = level(f_b)
    assert t == pytest.approx(theta, abs=1e-12) and g == pytest.approx(gamma, abs=1e-12)


def test_increments_are_exact_integrals_of_held_rates():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.006, 0.014, 400))
    gyro, acc = rng.normal(size=(400, 3)), rng.normal(size=(400, 3))
    log = ImuLog(t, gyro, acc)
    grid = np.linspace(t[0], t[-1], 137)
    dth, dv = increments(log, grid)
    exact = (gyro[1:] * np.diff(t)[:, None]).sum(0)
    np.testing.assert_allclose(dth.sum(0), exact, rtol=1e-12)
    # a grid point between samples i-1 and i splits sample i's held rate exactly
    i = 200
    mid = 0.5 * (t[i - 1] + t[i])
    d1, _ = increments(log, np.array([t[i - 1], mid, t[i]]))
    np.testing.assert_allclose(d1, [gyro[i] * (mid - t[i - 1]), gyro[i] * (t[i] - mid)])
    np.testing.assert_allclose(dv.sum(0), (acc[1:] * np.diff(t)[:, None]).sum(0), rtol=1e-12)


def test_a_sins_gyro_bias_step_adds_its_rate_times_the_time_inside_its_window():
    """The step's rate is held on every sample stamped in ``[start, end)`` (a sample's
    stamp ends its interval): the increments over the window grow by rate × the covered
    time exactly, the accelerometers and everything outside are untouched."""
    t = 0.01 * np.arange(1, 1001)
    rng = np.random.default_rng(5)
    log = ImuLog(t, rng.normal(size=(1000, 3)), rng.normal(size=(1000, 3)))
    before = log.gyro.copy()
    rate = np.radians([0.1, -0.2, 0.5])
    start, end = 2.005, 6.005  # samples stamped 2.01 ... 6.00: intervals (2.00, 6.00]
    faulty = imu_with_faults(log, [Fault("sins", "gyro-bias", start, end, rate)])
    assert faulty.accel is log.accel
    grid = np.array([t[0], 2.0, 6.0, t[-1]])
    d0, v0 = increments(log, grid)
    d1, v1 = increments(faulty, grid)
    np.testing.assert_allclose(d1 - d0, [np.zeros(3), rate * 4.0, np.zeros(3)], atol=1e-12)
    np.testing.assert_array_equal(v1, v0)
    np.testing.assert_array_equal(log.gyro, before)  # the log given is not changed
    assert imu_with_faults(log, [Fault("gnss", "bias", start, end, np.ones(6))]) is log


def test_clean_drops_stale_rows_and_repeated_stamps_and_refuses_going_back():
    t = np.array([0.0, 0.01, 0.02, 0.02, 0.03, 0.04])
    g = np.array([[1.0] * 3, [2.0] * 3, [2.0] * 3, [3.0] * 3, [4.0] * 3, [5.0] * 3])
    log, info = clean(ImuLog(t, g, g.copy()))
    assert info.repeated_rows == 1 and info.repeated_stamps == 1 and info.rows == 6
    np.testing.assert_array_equal(log.t, [0.0, 0.01, 0.03, 0.04])
    with pytest.raises(ValueError, match="^row 2: time goes backwards"):
        clean(ImuLog(np.array([0.0, 0.02, 0.01]), g[:3], g[:3]))


def test_stationary_from_the_spread_of_the_samples():
    t = np.arange(0, 10, 0.01)
    acc = np.tile([0.0, 0.0, 9.8], (t.size, 1))
    acc[t > 5, 1] += np.sin(40 * t[t > 5])  # moving: the accelerometer varies
    rest = stationary(ImuLog(t, np.zeros_like(acc), acc), np.array([2.0, 8.0]), 1.0, 0.1, 0.01)
    np.testing.assert_array_equal(rest, [True, False])


def test_outage_schedule_and_interleaving():
    s = outage_schedule(15.0, 60.0, 40.0, last=549.0)
    assert s[0] == (40.0, 55.0) and s[-1][1] <= 549.0 - 30.0 and len(s) == 8
    assert interleave(s, 60.0) == [s]
    long = outage_schedule(60.0, 60.0, 40.0, last=549.0)
    runs = interleave(long, 60.0)
    assert len(runs) == 2 and runs[0][1][0] - runs[0][0][1] == 60.0  # GNSS back between
    assert sorted(runs[0] + runs[1]) == long


def test_on_grid_counts_off_grid_duplicated_and_unsorted_epochs():
    t = np.array([0.25, 0.5, 0.5, 1.0, 0.75, 1.13])
    p = on_grid(t, 0.0, 0.25, 10)
    assert (p.off_grid, p.duplicated) == (1, 1) and p.unsorted > 0
    np.testing.assert_array_equal(np.sort(p.index), [0, 1, 2, 3])


def _state(rng, B=4):
    q = attitude.euler_to_quat(rng.uniform(-0.4, 0.4, (B, 3)))
    v = rng.normal(0, 8, (B, 3))
    p = np.column_stack([rng.uniform(-1, 1, B), rng.uniform(-3, 3, B), rng.uniform(0, 2e3, B)])
    return InsState(q, v, p, np.zeros((B, 3)))


def _perturbed(s: InsState, dx: np.ndarray) -> InsState:
    """The INS solution with error dx (φ, δv, δL δλ δh): C̃ = (I − [φ×]) C."""
    q = attitude.quat_mul(attitude.rotvec_to_quat(-dx[:, 0:3]), s.q)
    return InsState(q, s.v + dx[:, 3:6], s.p + dx[:, 6:9], s.a)


@pytest.mark.parametrize(
    "sensor",
    [
        Nhc(),
        Zupt(),
        Gnss(lever_arm_m=(0.3, -1.2, 0.8), markov="white"),
        Nhc(lever_arm_m=(0.1, -1.4, -0.3)),
    ],
    ids=["nhc", "zupt", "gnss-lever-arm", "nhc-lever-arm"],
)
def test_jacobians_equal_finite_differences(sensor):
    rng = np.random.default_rng(7)
    s = _state(rng)
    w_ib = rng.uniform(-0.5, 0.5, (4, 3))  # the gyro's rate (rad/s): an input, not a state
    raw = (
        np.concatenate([s.p, s.v], 1) + rng.normal(0, 1e-9, (4, 6))
        if isinstance(sensor, Gnss)
        else np.zeros((4, sensor.dim))
    )
    base = sensor.measure(s.q, s.v, s.p, raw, w_ib)
    steps = np.r_[[1e-6] * 3, [1e-4] * 3, [1e-9, 1e-9, 1e-3]]
    for j in range(9):
        dx = np.zeros((4, 9))
        dx[:, j] = steps[j]
        up, dn = _perturbed(s, dx), _perturbed(s, -dx)
        zu = sensor.measure(up.q, up.v, up.p, raw, w_ib).z
        zd = sensor.measure(dn.q, dn.v, dn.p, raw, w_ib).z
        fd = (zu - zd) / (2 * steps[j])
        # the difference's rounding floor, eps |z| / step: the arm's δL column (the Earth's
        # rate turning with latitude, 1e-4 m/s per rad) sits near it at δL = 1e-9 rad
        floor = 4 * np.finfo(float).eps * np.abs(zu).max() / steps[j]
        atol = max(1e-6 * np.abs(fd).max(), floor)
        np.testing.assert_allclose(base.H[:, :, j], fd, rtol=1e-5, atol=atol)


def test_retime_velocity_moves_a_lagging_velocity_onto_the_position_stamps():
    """A receiver whose velocity lags by 0.125 s on a constant acceleration of 2 m/s²:
    ``v_stamped(t) = a (t − 0.125)``; re-timed, ``v(t) = a t`` exactly (linear in t)
    inside the log, held at its last epoch at the end."""
    t = 100.0 + 0.25 * np.arange(12)
    v = np.zeros((12, 3))
    v[:, 1] = 2.0 * (t - 100.0 - 0.125)
    log = GnssLog(t=t, p=np.zeros((12, 3)), v=v, quality=np.ones(12, int))
    out = retime_velocity(log, -0.125)
    np.testing.assert_allclose(out.v[:-1, 1], 2.0 * (t[:-1] - 100.0), atol=1e-12)
    assert out.v[-1, 1] == v[-1, 1]
    assert retime_velocity(log, 0.0) is log
    shuffled = GnssLog(t=t[::-1], p=log.p, v=v[::-1], quality=log.quality)
    np.testing.assert_allclose(retime_velocity(shuffled, -0.125).v[::-1], out.v)


def test_an_outage_removes_every_aid_of_the_receiver():
    K = 8
    times = 0.5 * np.arange(1, K + 1)
    aid = AidStream(times, np.ones((1, K, 3)), np.ones((1, K), bool))
    imu = ImuStream(0.0, 0.1, np.arange(1, 41) * 0.1, np.zeros((1, 40, 3)), np.zeros((1, 40, 3)))
    start = InsState(
        np.array([[1.0, 0, 0, 0]]), np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3))
    )
    stream = InsStream(imu, (aid, aid, aid), start, np.zeros((K, 3), bool))
    out = with_outages(stream, [0, 1], times, [[(1.0, 2.0)], [(3.0, 3.5)]])
    gone = [(times >= 1.0) & (times < 2.0), (times >= 3.0) & (times < 3.5)]
    for i in (0, 1):
        for g in (0, 1):
            assert np.array_equal(out.aids[i].available[g], ~gone[g])
            assert np.isnan(out.aids[i].raw[g, gone[g]]).all()
    assert out.aids[2].available.all() and out.imu.dtheta.shape[0] == 2


@pytest.mark.parametrize("psi_deg", [-170.0, -60.0, 0.0, 35.0, 100.0, 179.0])
def test_gyrocompassing_recovers_the_heading_from_the_earth_rate(psi_deg):
    """Closed form: a still IMU at latitude L reads f = C_n^b [0, 0, g] and
    ω = C_n^b [0, Ω cos L, Ω sin L]; the heading is recovered exactly, and a gyro bias b
    across the Earth rate's horizontal part turns it by atan(b / (Ω cos L)) (to first
    order the σ gyrocompass_sigma predicts)."""
    from ftnav.nav.earth import OMEGA_IE, omega_ie_n
    from ftnav.recorded.stream import gyrocompass, gyrocompass_sigma

    L = np.radians(40.1)
    euler = np.array([np.radians(3.0), np.radians(-2.0), np.radians(psi_deg)])
    C = attitude.euler_to_dcm(euler)  # C_b^n
    f = C.T @ np.array([0.0, 0.0, 9.8])
    w = C.T @ omega_ie_n(L)
    theta, gamma, psi = gyrocompass(f, w)
    np.testing.assert_allclose([theta, gamma], euler[:2], atol=1e-12)
    assert abs(attitude.wrap_angle(psi - euler[2])) < 1e-9
    b = 1e-3 * OMEGA_IE  # 0.1 % of the Earth rate, on the body axes that point East
    _, _, psi_b = gyrocompass(f, w + b * (C.T @ [1.0, 0.0, 0.0]))
    turn = float(attitude.wrap_angle(psi_b - euler[2]))
    np.testing.assert_allclose(abs(turn), np.arctan(b / (OMEGA_IE * np.cos(L))), rtol=1e-9)
    assert gyrocompass_sigma(L, b, 0.0, 30.0) == pytest.approx(b / (OMEGA_IE * np.cos(L)))


def test_a_noise_scale_fault_adds_the_missing_noise_to_a_recording():
    """A recording already holds noise of the σ the filter assumes: a noise-scale fault of
    factor s adds white noise of σ·√(s² − 1) inside its window only (the total σ is then
    s·σ), drawn reproducibly; offsets are untouched elsewhere.  Oracle: the sample σ of
    the added noise over 40 000 epochs (standard error 0.35 %) against the closed form."""
    K = 80_000
    t = np.arange(K) * 0.1
    p = np.tile([np.radians(45.0), np.radians(7.0), 300.0], (K, 1))
    log = GnssLog(t, p, np.zeros((K, 3)), np.ones(K, int))
    sigma = np.array([0.05, 0.05, 0.1, 0.1, 0.1, 0.2])
    s = 10.0
    fault = Fault("gnss", "noise-scale", 2000.0, 6000.0, np.full(6, s))
    raw, labels = gnss_raw(log, [fault], "gnss", np.broadcast_to(sigma, (K, 6)))
    inside = (t >= 2000.0) & (t < 6000.0)
    assert np.array_equal(labels, inside)
    added = np.concatenate([enu_metres(raw[:, :3], p), raw[:, 3:]], -1)
    assert np.all(added[~inside] == 0.0)
    sd = added[inside].std(0)
    np.testing.assert_allclose(sd, sigma * np.sqrt(s**2 - 1.0), rtol=0.012)
    corr = np.corrcoef(added[inside].T)
    assert np.abs(corr - np.eye(6)).max() < 0.02  # independent rows
    lag = np.mean(added[inside][1:] * added[inside][:-1], 0) / sd**2
    assert np.abs(lag).max() < 0.02  # white
    again, _ = gnss_raw(log, [fault], "gnss", np.broadcast_to(sigma, (K, 6)))
    assert np.array_equal(again, raw)  # reproducible
    other, _ = gnss_raw(log, [replace(fault, sensor="gnss2")], "gnss2", sigma[None])
    assert not np.array_equal(other, raw)  # another aid's noise is its own


def test_a_noise_scale_fault_of_one_is_no_fault_and_needs_the_sigma():
    K = 10
    t = np.arange(K, dtype=float)
    log = GnssLog(t, np.tile([0.5, 0.1, 10.0], (K, 1)), np.zeros((K, 3)), np.ones(K, int))
    one = Fault("gnss", "noise-scale", 2.0, 6.0, np.ones(6))
    raw, _ = gnss_raw(log, [one], "gnss", np.ones((K, 6)))
    np.testing.assert_array_equal(raw[:, :3], log.p)
    with pytest.raises(ValueError, match="needs the aid's σ"):
        gnss_raw(log, [replace(one, magnitude=np.full(6, 2.0))], "gnss")


def test_a_velocity_aids_bias_and_ramp_move_its_north_velocity_only():
    """``--fault gnss-vel:bias|ramp:START:END:M`` on an aid that measures velocity only:
    M m/s on the north velocity (a ramp from 0 at START to M at END), nothing on the
    positions or the other rows, nothing outside [START, END).  Oracle: the closed form
    of the offset, epoch by epoch."""
    aids = {"gnss": "gnss", "gnss-vel": "gnss-velocity"}
    K = 100
    t = np.arange(K, dtype=float)
    v = np.tile([3.0, -2.0, 0.1], (K, 1))
    log = GnssLog(t, np.tile([0.5, 0.1, 10.0], (K, 1)), v, np.ones(K, int))
    for kind, expected in (
        ("bias", np.where((t >= 20) & (t < 60), 1.5, 0.0)),
        ("ramp", np.where((t >= 20) & (t < 60), 1.5 * (t - 20) / 40, 0.0)),
    ):
        fault = parse_fault(f"gnss-vel:{kind}:20:60:1.5", aids)
        np.testing.assert_array_equal(fault.magnitude, [0, 0, 0, 0, 1.5, 0])
        raw, labels = gnss_raw(log, [fault], "gnss-vel")
        np.testing.assert_array_equal(raw[:, :3], log.p)
        np.testing.assert_array_equal(raw[:, [3, 5]], v[:, [0, 2]])
        np.testing.assert_allclose(raw[:, 4] - v[:, 1], expected, rtol=0, atol=1e-12)
        assert np.array_equal(labels, (t >= 20) & (t < 60))
    # a position aid's stays metres on the north position
    np.testing.assert_array_equal(
        parse_fault("gnss:bias:20:60:1.5", aids).magnitude, [0, 1.5, 0, 0, 0, 0]
    )


def test_the_constraint_holds_at_its_point_on_a_turning_car():
    """A car turning at ω about the vertical with its rear axle's centre on a circle of
    radius r (speed ω r, no sideways slip there) and the IMU d ahead of the axle: the
    IMU slides sideways at ω d (to the left in a left turn: z_x = −ω d), and with the
    arm ``l = (0, −d, 0)`` from the IMU to the axle the constraint reads 0."""
    omega, r, d = 0.3, 20.0, 1.5  # rad/s (left turn), m, m
    yaw = 0.7
    q = attitude.euler_to_quat(np.array([[0.0, 0.0, yaw]]))
    C = attitude.quat_to_dcm(q)[0]
    # the IMU's velocity: the axle's forward ω r plus ω × (d forward) = ω d to the left
    v_b = np.array([-omega * d, omega * r, 0.0])
    v_n = (C @ v_b)[None]
    p = np.array([[0.0, 0.0, 0.0]])  # on the equator the Earth's rate is along north
    w_ib = (C.T @ omega_ie_n(p[:, 0])[0] + np.array([0.0, 0.0, omega]))[None]
    zero = np.zeros((1, 2))
    np.testing.assert_allclose(Nhc().measure(q, v_n, p, zero, w_ib).z, [[-omega * d, 0.0]])
    at_axle = Nhc(lever_arm_m=(0.0, -d, 0.0)).measure(q, v_n, p, zero, w_ib).z
    np.testing.assert_allclose(at_axle, zero, atol=1e-12)
    with pytest.raises(ValueError, match="needs the rate w_ib"):
        Nhc(lever_arm_m=(0.0, -d, 0.0)).measure(q, v_n, p, zero)
