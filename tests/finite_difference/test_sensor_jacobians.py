"""Finite-difference checks of the aiding-sensor measurement models (spec §9.7 a–d).

Oracle: the nonlinear ``z = INS − aid`` of each sensor's ``measure``, evaluated at a
perturbed INS solution against the noise-free raw output of the truth.  The INS
attitude error φ follows ``ftnav.nav.attitude.attitude_error``: ``C̃ = exp(−[φ×]) C``,
i.e. ``q̃ = q(−φ) ⊗ q`` (the inverse of ``mechanization.apply_correction``).

Perturbations (spec §9.7 b): φ 1e-5 rad, δv 1e-3 m/s, δL/δλ 1e-7 rad, δh 1 m, random
signs, one group at a time and all together.  Central differences
``(z(x + δx) − z(x − δx))/2`` are compared with ``H δx``: the even-order remainders
cancel, which matters for TAN, whose second-order terrain term at 0.6 m steps is not
small next to the slope term.  Requirement ``‖Δz − H δx‖ ≤ 1e-3 ‖H δx‖ + atol``, with
``atol`` the float64 rounding floor of z (``R·eps·|p|`` ≈ 1e-9 m for geodetic positions,
1e-14 rad for attitudes), so that structurally zero columns are checked too.
Private-state columns are checked by perturbing the raw output's errors instead.
The GNSS antenna on a lever arm (``gnss-arm``) reads the gyro's rate ``w_ib`` (a
measured input, not a state): the truth's rate goes to both its simulated output and
``measure``, so (a) checks that the two put the antenna at the same place and velocity.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.nav.attitude import (
    attitude_error,
    dcm_to_euler,
    euler_to_quat,
    quat_mul,
    quat_to_dcm,
    rotvec_to_quat,
)
from ftnav.nav.earth import omega_ie_n
from ftnav.sensors import (
    AidTruth,
    AnalyticTerrain,
    Barometer,
    Doppler,
    Gnss,
    StarTracker,
    Tan,
)
from ftnav.sensors.cns import dcm_n_to_e, euler_jacobian

DEG = np.pi / 180.0
N_POINTS = 12
STEP = {"phi": 1e-5, "dv": 1e-3, "dp": np.array([1e-7, 1e-7, 1.0])}
GROUPS = {"phi": slice(0, 3), "dv": slice(3, 6), "dp": slice(6, 9)}
TERRAIN = AnalyticTerrain.random(
    np.random.default_rng(7), 40.0, 10.0, n_waves=6, h0_m=300.0, wavelength_range_m=(1000.0, 5000.0)
)

SENSORS = {
    "gnss-white": Gnss(),
    "gnss-augment": Gnss(markov="augment"),
    # an antenna 2.7 m from the IMU: the arm's rotation in the velocity rows
    "gnss-arm": Gnss(lever_arm_m=(0.8, 2.6, -0.5)),
    "tan": Tan(TERRAIN),
    "dns-augment": Doppler(),
    "dns-white": Doppler(states="white"),
    "cns-dcm": StarTracker(),
    "cns-euler": StarTracker(form="euler"),
    "cns-dcm-position": StarTracker(position_coupling=True),
    "cns-euler-position": StarTracker(form="euler", position_coupling=True),
    "ads": Barometer(),
    "ads-bias-state": Barometer(bias_sigma_m=10.0, bias_state=True),
}
UNCOUPLED_DNS = Doppler(attitude_coupling=False)


def flight_states(seed: int, sensor) -> AidTruth:
    """N_POINTS random flight states (L 20–60°, |v_h| 50–250 m/s, |pitch| < 30°)."""
    rng = np.random.default_rng(seed)
    n = N_POINTS
    if isinstance(sensor, Tan):  # near the terrain origin, on sloped ground, above it
        L0, lam0 = TERRAIN.origin_lat_deg * DEG, TERRAIN.origin_lon_deg * DEG
        L = np.empty(n)
        lam = np.empty(n)
        k = 0
        while k < n:
            Lc, lc = L0 + rng.uniform(-2e-3, 2e-3), lam0 + rng.uniform(-2e-3, 2e-3)
            _, s_E, s_N = TERRAIN.height_and_slope(Lc, lc)
            if min(abs(s_E), abs(s_N)) > 0.02:
                L[k], lam[k] = Lc, lc
                k += 1
        h = TERRAIN.height_and_slope(L, lam)[0] + rng.uniform(300.0, 3000.0, n)
    else:
        L = rng.uniform(20.0, 60.0, n) * DEG
        lam = rng.uniform(-180.0, 180.0, n) * DEG
        h = rng.uniform(0.0, 10000.0, n)
    speed = rng.uniform(50.0, 250.0, n)
    course = rng.uniform(-np.pi, np.pi, n)
    v = np.stack([speed * np.sin(course), speed * np.cos(course), rng.uniform(-20, 20, n)], -1)
    a = (
        np.stack([rng.uniform(-30, 30, n), rng.uniform(-60, 60, n), rng.uniform(-180, 180, n)], -1)
        * DEG
    )
    w = rng.uniform(-0.5, 0.5, (n, 3))  # the gyro's rate (rad/s): a lever arm's rotation
    return AidTruth(np.arange(n) * sensor.dt, np.stack([L, lam, h], -1), v, euler_to_quat(a), w)


def noise_free_raw(sensor, truth: AidTruth, e=None, c=None) -> np.ndarray:
    """Raw output (K, …) with metric errors ``e`` (K, m) and constants ``c`` (c,)."""
    m = sensor.dim
    n_const = 1 if isinstance(sensor, Doppler) else 0
    e = np.zeros((1, len(truth.t), m)) if e is None else e[None]
    c = np.zeros((1, n_const)) if c is None else np.asarray(c, dtype=float)[None]
    return sensor.output(truth, e, c)[0]


def perturbed(truth: AidTruth, dx: np.ndarray):
    """INS solution (q̃, ṽ, p̃) with error dx (K, 9): ``C̃ = exp(−[φ×]) C``."""
    q = quat_mul(rotvec_to_quat(-dx[:, 0:3]), truth.q)
    return q, truth.v + dx[:, 3:6], truth.p + dx[:, 6:9]


def random_dx(rng, groups) -> np.ndarray:
    dx = np.zeros((N_POINTS, 9))
    for g in groups:
        dx[:, GROUPS[g]] = rng.choice([-1.0, 1.0], (N_POINTS, 3)) * STEP[g]
    return dx


def atol(sensor) -> float:
    return 1e-14 if isinstance(sensor, StarTracker) else 1e-8


@pytest.mark.parametrize("key", list(SENSORS))
def test_zero_error_gives_zero_innovation(key):
    """(a) Noise-free aid and INS = truth: z = 0 to rounding, every epoch accepted."""
    sensor = SENSORS[key]
    truth = flight_states(1, sensor)
    lin = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth), truth.w)
    assert lin.z.shape == (N_POINTS, sensor.dim)
    assert lin.H.shape == (N_POINTS, sensor.dim, 18)
    p = 0 if sensor.private is None else len(sensor.private.names)
    assert lin.H_private.shape == (N_POINTS, sensor.dim, p)
    # a few roundings of a geodetic position (R·eps·|L| ≈ 1.4e-9 m each) at most
    assert np.max(np.abs(lin.z)) < 5e-9
    assert lin.valid.all()


@pytest.mark.parametrize(
    "groups", [("phi",), ("dv",), ("dp",), ("phi", "dv", "dp")], ids=["phi", "dv", "dp", "all"]
)
@pytest.mark.parametrize("key", list(SENSORS))
def test_jacobian_matches_central_differences(key, groups):
    """(b) Central difference of the nonlinear z against H δx at N_POINTS flight states."""
    sensor = SENSORS[key]
    truth = flight_states(2, sensor)
    raw = noise_free_raw(sensor, truth)
    dx = random_dx(np.random.default_rng(3), groups)
    z_plus = sensor.measure(*perturbed(truth, dx), raw, truth.w).z
    z_minus = sensor.measure(*perturbed(truth, -dx), raw, truth.w).z
    H = sensor.measure(truth.q, truth.v, truth.p, raw, truth.w).H
    Hdx = np.einsum("bij,bj->bi", H[:, :, :9], dx)
    dz = 0.5 * (z_plus - z_minus)
    err = np.linalg.norm(dz - Hdx, axis=-1)
    bound = 1e-3 * np.linalg.norm(Hdx, axis=-1) + atol(sensor)
    assert np.all(err <= bound), np.max(err / bound)
    assert np.all(H[:, :, 9:] == 0.0)  # no coupling to the IMU bias states


@pytest.mark.parametrize("key", list(SENSORS))
def test_jacobian_columns_match_central_differences(key):
    """(b) Column by column: each of the 9 navigation-error columns of H against the
    central difference along that state alone (the group test above can hide a small
    error in a weak column next to a strong one, e.g. δL next to δh for TAN)."""
    sensor = SENSORS[key]
    truth = flight_states(15, sensor)
    raw = noise_free_raw(sensor, truth)
    H = sensor.measure(truth.q, truth.v, truth.p, raw, truth.w).H
    steps = np.concatenate([np.full(3, STEP["phi"]), np.full(3, STEP["dv"]), STEP["dp"]])
    for j in range(9):
        dx = np.zeros((N_POINTS, 9))
        dx[:, j] = steps[j]
        dz = 0.5 * (
            sensor.measure(*perturbed(truth, dx), raw, truth.w).z
            - sensor.measure(*perturbed(truth, -dx), raw, truth.w).z
        )
        Hdx = H[:, :, j] * steps[j]
        err = np.linalg.norm(dz - Hdx, axis=-1)
        bound = 1e-3 * np.linalg.norm(Hdx, axis=-1) + atol(sensor)
        assert np.all(err <= bound), (j, np.max(err / bound))


def test_uncoupled_doppler_drops_only_the_attitude_term():
    """attitude_coupling=False: zero φ columns; the dropped term is the coupled one."""
    truth = flight_states(4, UNCOUPLED_DNS)
    raw = noise_free_raw(UNCOUPLED_DNS, truth)
    H0 = UNCOUPLED_DNS.measure(truth.q, truth.v, truth.p, raw).H
    H1 = SENSORS["dns-augment"].measure(truth.q, truth.v, truth.p, raw).H
    assert np.all(H0[:, :, 0:3] == 0.0)
    np.testing.assert_array_equal(H0[:, :, 3:], H1[:, :, 3:])
    assert np.all(np.abs(H1[:, :, 0:3]).sum(axis=(1, 2)) > 0.0)
    dx = random_dx(np.random.default_rng(5), ("phi",))
    dz = 0.5 * (
        UNCOUPLED_DNS.measure(*perturbed(truth, dx), raw).z
        - UNCOUPLED_DNS.measure(*perturbed(truth, -dx), raw).z
    )
    Hdx = np.einsum("bij,bj->bi", H1[:, :, :3], dx[:, :3])
    np.testing.assert_allclose(dz, Hdx, rtol=1e-3, atol=1e-8)


def _private_case(key, rng):
    """(sensor, metric error perturbation (K, m), constants perturbation, δ private)."""
    sensor = SENSORS[key]
    truth = flight_states(6, sensor)
    if key == "gnss-augment":
        db = rng.choice([-1.0, 1.0], (N_POINTS, 6)) * np.array([1.0] * 3 + [1e-3] * 3)
        return sensor, truth, db, None, db
    if key == "ads-bias-state":
        db = rng.choice([-1.0, 1.0], (N_POINTS, 1))
        return sensor, truth, db, None, db
    # Doppler: δK via the constants, δV_D along the true track through the metric error
    dK = 1e-4
    dvd = rng.choice([-1.0, 1.0], N_POINTS) * 1e-2
    u = truth.v[:, :2] / np.linalg.norm(truth.v[:, :2], axis=-1, keepdims=True)
    return sensor, truth, dvd[:, None] * u, [dK], np.stack([np.full(N_POINTS, dK), dvd], -1)


@pytest.mark.parametrize("key", ["gnss-augment", "dns-augment", "ads-bias-state"])
def test_private_columns_match_error_perturbations(key):
    """(b) H_private against the change of z when the raw output's errors change."""
    sensor, truth, de, dc, dxp = _private_case(key, np.random.default_rng(8))
    lin0 = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth))
    lin1 = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth, de, dc))
    pred = np.einsum("bij,bj->bi", lin0.H_private, dxp)
    err = np.linalg.norm(lin1.z - lin0.z - pred, axis=-1)
    assert np.all(err <= 1e-3 * np.linalg.norm(pred, axis=-1) + 1e-8)
    assert np.all(np.linalg.norm(pred, axis=-1) > 0.0)
    assert sensor.private.H.shape == (sensor.dim, len(sensor.private.names))


@pytest.mark.parametrize("position", [False, True], ids=["attitude", "with-position"])
def test_cns_dcm_and_euler_forms_agree(position):
    """(c) The same small error: H_Euler δx = Euler difference within 1e-9 (1e-6 rad)."""
    dcm = StarTracker(position_coupling=position)
    eul = StarTracker(form="euler", position_coupling=position)
    truth = flight_states(9, dcm)
    rng = np.random.default_rng(10)
    dx = np.zeros((N_POINTS, 9))
    dx[:, 0:3] = rng.choice([-1.0, 1.0], (N_POINTS, 3)) * 1e-6
    if position:
        dx[:, 6:8] = rng.choice([-1.0, 1.0], (N_POINTS, 2)) * 1e-7
    ins = perturbed(truth, dx)
    z_dcm = dcm.measure(*ins, noise_free_raw(dcm, truth)).z
    lin = eul.measure(*ins, noise_free_raw(eul, truth))
    if not position:  # the aid is the true attitude: z is the plain Euler difference
        euler_diff = dcm_to_euler(quat_to_dcm(ins[0])) - dcm_to_euler(quat_to_dcm(truth.q))
        np.testing.assert_allclose(lin.z, euler_diff, atol=1e-15)
    Hx = np.einsum("bij,bj->bi", lin.H[:, :, :9], dx)
    assert np.max(np.abs(Hx - lin.z)) < 1e-9
    a = dcm_to_euler(quat_to_dcm(ins[0]))
    assert np.max(np.abs(np.einsum("bij,bj->bi", euler_jacobian(a), z_dcm) - lin.z)) < 1e-9
    assert np.max(np.abs(lin.z)) > 1e-7  # the check is not vacuous


def test_euler_rows_against_numeric_euler_derivative():
    """(c) ``∂a/∂φ`` of spec §9.4 (all three rows, ψ counter-clockwise) by central differences."""
    rng = np.random.default_rng(11)
    a = (
        np.stack(
            [rng.uniform(-30, 30, 20), rng.uniform(-60, 60, 20), rng.uniform(-180, 180, 20)], -1
        )
        * DEG
    )
    q = euler_to_quat(a)
    J = np.empty((20, 3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = 1e-6  # C̃ = exp(−[φ×]) C  ⇔  q̃ = q(−φ) ⊗ q
        diff = dcm_to_euler(quat_to_dcm(quat_mul(rotvec_to_quat(-d), q))) - dcm_to_euler(
            quat_to_dcm(quat_mul(rotvec_to_quat(d), q))
        )
        diff[:, 1:] = (diff[:, 1:] + np.pi) % (2 * np.pi) - np.pi
        J[:, :, j] = diff / 2e-6
    np.testing.assert_allclose(J, euler_jacobian(a), atol=1e-8)


def test_position_coupling_columns_match_frame_rotation():
    """(d) The INS-computed local level is rotated by δθ = [−δL, δλ cos L, δλ sin L]."""
    sensor = SENSORS["cns-dcm-position"]
    truth = flight_states(12, sensor)
    rng = np.random.default_rng(13)
    dp = np.zeros((N_POINTS, 3))
    dp[:, :2] = rng.choice([-1.0, 1.0], (N_POINTS, 2)) * 1e-7
    L, lam = truth.p[:, 0], truth.p[:, 1]
    C = quat_to_dcm(truth.q)
    # numeric: C_CNS' = C_n^e(p̃)ᵀ C_n^e(p) C, rotated from C by δθ: C_CNS' = exp(−[δθ×]) C
    C_ne = dcm_n_to_e(L, lam)
    C_ne_ins = dcm_n_to_e(L + dp[:, 0], lam + dp[:, 1])
    dtheta = attitude_error(np.swapaxes(C_ne_ins, -1, -2) @ C_ne @ C, C)
    formula = np.stack([-dp[:, 0], dp[:, 1] * np.cos(L), dp[:, 1] * np.sin(L)], -1)
    np.testing.assert_allclose(dtheta, formula, rtol=1e-6, atol=1e-15)
    # the sensor's columns: z = φ − δθ, so H on (δL, δλ) is −∂δθ/∂(δL, δλ)
    H = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth)).H
    np.testing.assert_allclose(
        np.einsum("bij,bj->bi", H[:, :, 6:8], dp[:, :2]), -dtheta, rtol=1e-6, atol=1e-15
    )
    np.testing.assert_array_equal(H[:, 0, 6], 1.0)
    np.testing.assert_allclose(H[:, 1, 7], -np.cos(L))
    np.testing.assert_allclose(H[:, 2, 7], -np.sin(L))


@pytest.mark.parametrize("key", list(SENSORS))
def test_metric_error_enters_z_with_the_documented_sign(key):
    """A metric offset γ changes z by ``z_per_error · γ`` (first order, INS = truth)."""
    sensor = SENSORS[key]
    truth = flight_states(14, sensor)
    gamma = np.full((N_POINTS, sensor.dim), 1e-6 if isinstance(sensor, StarTracker) else 0.1)
    z0 = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth), truth.w).z
    z1 = sensor.measure(truth.q, truth.v, truth.p, noise_free_raw(sensor, truth, gamma), truth.w).z
    np.testing.assert_allclose(z1 - z0, sensor.z_per_error * gamma, rtol=1e-4, atol=1e-12)


def test_the_arm_rotation_is_in_the_velocity_rows():
    """The antenna's velocity ``v + C(ω_eb × l)``: with the arm and the rate the
    innovation is 0 (the test above); measured as if at the IMU (no arm) the velocity
    rows miss exactly ``C(ω_eb × l)``, and the position rows ``C l``."""
    arm = SENSORS["gnss-arm"]
    truth = flight_states(16, arm)
    raw = noise_free_raw(arm, truth)
    z = Gnss().measure(truth.q, truth.v, truth.p, raw, truth.w).z
    C = quat_to_dcm(truth.q)
    l_b = np.array(arm.lever_arm_m)
    w_eb = truth.w - np.einsum("kji,kj->ki", C, omega_ie_n(truth.p[:, 0]))
    np.testing.assert_allclose(
        z[:, 3:], -np.einsum("kij,kj->ki", C, np.cross(w_eb, l_b)), atol=1e-9
    )
    np.testing.assert_allclose(z[:, :3], -C @ l_b, atol=1e-6)
    assert np.min(np.linalg.norm(z[:, 3:], axis=-1)) > 0.05  # turning: not vacuous
    with pytest.raises(ValueError, match="need the rate w_ib"):
        arm.measure(truth.q, truth.v, truth.p, raw)
