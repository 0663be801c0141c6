"""Strapdown mechanization and trajectory generator against closed forms (spec §8.6, §10.4).

Oracles: a stationary vehicle (truth known exactly), the generator's truth on the
``seed001`` flight (error-free IMU), the geometry of a coordinated turn, and exact
equalities (batched = single run, chunked = one call, deterministic output).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ftnav.io.profile_file import resolve_profile
from ftnav.model.flight import Profile, Segment, Start
from ftnav.nav import attitude as at
from ftnav.nav import earth
from ftnav.nav import mechanization as mech
from ftnav.sim.trajectory import generate

D = math.radians


@pytest.fixture(scope="module")
def seed001():
    return generate(resolve_profile("seed001"))


def _stationary(hours=1.0, heading_deg=30.0, rate=100.0):
    start = Start((D(32.0), D(118.0), 5.0), 0.0, (D(1.0), D(-2.0), -D(heading_deg)))
    return Profile("static", rate, start, (Segment(3600.0 * hours),))


def test_stationary_hour_with_error_free_imu():
    """Spec §8.6 (a): horizontal |δp| < 1 mm, |δv| < 1e-6 m/s; vertical |δh| < 1 cm."""
    tr = generate(_stationary())
    st, sol = mech.integrate(
        mech.init_state(tr.p[0], tr.v[0], tr.euler[0]), tr.dtheta, tr.dv, tr.dt
    )
    e = earth.enu_metres(sol.p[0], tr.p[2::2])
    assert np.abs(e[:, :2]).max() < 1e-3
    assert np.abs(e[:, 2]).max() < 1e-2
    assert np.abs(sol.v[0, :, :2]).max() < 1e-6
    phi = at.attitude_error(at.quat_to_dcm(sol.q[0, -1]), at.euler_to_dcm(tr.euler[-1]))
    assert np.abs(phi).max() < 1e-9


def test_stationary_increments_are_earth_rate_and_gravity():
    """Spec §10.4 (c): |f^b| = g(L, h) within 1e-9 and ω_ib^b = C_n^b ω_ie^n."""
    tr = generate(_stationary(hours=0.01))
    T = tr.dt
    L, h = tr.p[0, 0], tr.p[0, 2]
    np.testing.assert_allclose(
        np.linalg.norm(tr.dv / T, axis=1), earth.gravity(L, h), rtol=0, atol=1e-9
    )
    C = at.euler_to_dcm(tr.euler[0])
    np.testing.assert_allclose(
        tr.dtheta / T, np.broadcast_to(C.T @ earth.omega_ie_n(L), tr.dtheta.shape), atol=1e-17
    )


@pytest.mark.parametrize("algorithm", ["two-sample", "single-sample"])
def test_seed001_round_trip_with_error_free_imu(seed001, algorithm):
    """Spec §8.6 (b) / §10.4 (d): back to the truth within 1 m horizontally after 1000 s.

    Measured: 7.5 mm (two-sample) and 1.9 mm (single-sample) maximum horizontal error.
    """
    tr = seed001
    ns = 2 if algorithm == "two-sample" else 1
    _, sol = mech.integrate(
        mech.init_state(tr.p[0], tr.v[0], tr.euler[0]), tr.dtheta, tr.dv, tr.dt, algorithm=algorithm
    )
    e = earth.enu_metres(sol.p[0], tr.p[ns::ns])
    assert np.hypot(e[:, 0], e[:, 1]).max() < 0.05  # far inside the 1 m target
    assert np.hypot(*e[-1, :2]) < 1.0
    assert np.abs(sol.v[0] - tr.v[ns::ns]).max() < 1e-3


def test_batched_chunked_and_biased_integration_are_exact(seed001):
    tr = seed001
    n = 20000
    st0 = mech.init_state(tr.p[0], tr.v[0], tr.euler[0])
    _, one = mech.integrate(st0, tr.dtheta[:n], tr.dv[:n], tr.dt)
    # three runs in one batch (shared increments) equal the single run
    st3 = mech.init_state(tr.p[0], tr.v[0], tr.euler[0], batch=3)
    _, three = mech.integrate(st3, tr.dtheta[:n], tr.dv[:n], tr.dt)
    for x1, x3 in zip(one, three, strict=True):
        np.testing.assert_array_equal(np.broadcast_to(x1, x3.shape), x3)
    # two chunks carry the state exactly
    mid, a = mech.integrate(st0, tr.dtheta[: n // 2], tr.dv[: n // 2], tr.dt)
    _, b = mech.integrate(mid, tr.dtheta[n // 2 : n], tr.dv[n // 2 : n], tr.dt)
    np.testing.assert_array_equal(np.concatenate([a.p, b.p], 1), one.p)
    # a bias added to the increments and subtracted as an estimate cancels
    gb, ab = np.array([1e-5, -2e-5, 3e-5]), np.array([1e-3, 2e-3, -1e-3])
    _, biased = mech.integrate(
        st0, tr.dtheta[:n] + gb * tr.dt, tr.dv[:n] + ab * tr.dt, tr.dt, gyro_bias=gb, accel_bias=ab
    )
    np.testing.assert_allclose(biased.p, one.p, rtol=0, atol=1e-9)


def test_feedback_removes_a_known_error(seed001):
    tr = seed001
    st = mech.init_state(tr.p[0], tr.v[0], tr.euler[0])
    phi, dv, dp = (
        np.array([1e-3, -2e-3, 5e-3]),
        np.array([0.3, -0.2, 0.1]),
        np.array([1e-5, -1e-5, 10.0]),
    )
    C = (np.eye(3) - at.skew(phi)) @ at.quat_to_dcm(st.q[0])  # spec §0 error definition
    bad = st._replace(q=at.dcm_to_quat(C)[None], v=st.v + dv, p=st.p + dp)
    fixed = mech.feedback(bad, phi, dv, dp)
    np.testing.assert_allclose(fixed.p, st.p, atol=1e-12)
    np.testing.assert_allclose(fixed.v, st.v, atol=1e-12)
    err = at.attitude_error(at.quat_to_dcm(fixed.q[0]), at.quat_to_dcm(st.q[0]))
    assert np.abs(err).max() < 1e-5  # second order in |φ| = 5e-3


def test_profile_durations_and_continuity(seed001):
    """Spec §10.4 (a): durations sum to the profile length; speed and attitude continuous."""
    pr = resolve_profile("seed001")
    assert pr.duration == 1000.0
    assert seed001.t[-1] == pytest.approx(1000.0)
    jumps_v = np.abs(np.diff(seed001.v, axis=0)).max()
    jumps_a = np.abs(np.diff(np.unwrap(seed001.euler, axis=0), axis=0)).max()
    # the largest acceleration is the 30° coordinated turn at 100 m/s, g tan 30° = 5.66 m/s²
    assert jumps_v < 5.7 * seed001.dt
    assert jumps_a < D(6.0) * seed001.dt * 1.01  # at most the largest rate × T


def test_coordinated_turn_radius_and_lateral_force():
    """Spec §10.4 (b): radius V²/(g tan γ) within 1 %; body-x specific force ≈ 0."""
    V, bank = 100.0, D(30.0)
    start = Start((D(32.0), D(118.0), 1000.0), V, (0.0, bank, 0.0))
    tr = generate(Profile("turn", 100.0, start, (Segment(60.0, yaw_rate=None),)))
    import pymap3d

    e, n, _ = pymap3d.geodetic2enu(
        np.degrees(tr.p[:, 0]), np.degrees(tr.p[:, 1]), tr.p[:, 2], 32.0, 118.0, 1000.0
    )
    # algebraic circle fit  x² + y² + a x + b y + c = 0
    A = np.column_stack([e, n, np.ones_like(e)])
    a, b, c = np.linalg.lstsq(A, -(e**2 + n**2), rcond=None)[0]
    radius = math.sqrt(a * a / 4 + b * b / 4 - c)
    g = earth.gravity(D(32.0), 1000.0)
    assert radius == pytest.approx(V**2 / (g * math.tan(bank)), rel=1e-2)
    f_b = tr.dv / tr.dt
    assert np.abs(f_b[:, 0]).max() < 1e-2 * g
    assert tr.heading_deg[-1] > 0  # right bank turns right (clockwise)


def test_generator_is_deterministic(seed001):
    again = generate(resolve_profile("seed001"))
    for a, b in zip(seed001, again, strict=True):
        np.testing.assert_array_equal(a, b)
