"""Earth model and attitude conversions against closed forms and published WGS-84 values."""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.nav import attitude as at
from ftnav.nav import earth


def test_radii_at_equator_and_pole():
    RM, RN = earth.radii(0.0, 0.0)
    assert RN == pytest.approx(earth.A, rel=1e-15)
    assert RM == pytest.approx(earth.A * (1 - earth.E2), rel=1e-15)
    RM, RN = earth.radii(np.pi / 2, 100.0)
    polar = earth.A / np.sqrt(1 - earth.E2)  # a²/b, the polar radius of curvature
    assert RM == pytest.approx(polar + 100.0, rel=1e-14)
    assert RN == pytest.approx(polar + 100.0, rel=1e-14)


def test_normal_gravity_published_values():
    # WGS-84 (NIMA TR8350.2): γ_e = 9.7803253359, γ_p = 9.8321849378 m/s²
    assert earth.gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.gravity(np.pi / 2, 0.0) == pytest.approx(9.8321849378, abs=1e-9)
    # free-air gradient about 3.086e-6 1/s²
    _, dgdh = earth.gravity_gradient(np.radians(45.0), 0.0)
    assert dgdh == pytest.approx(-3.086e-6, rel=2e-3)


@pytest.mark.parametrize("L,h", [(0.1, 0.0), (0.6, 1500.0), (-1.2, 9000.0)])
def test_gravity_gradient_matches_finite_differences(L, h):
    dgdL, dgdh = earth.gravity_gradient(L, h)
    e = 1e-6
    assert dgdL == pytest.approx(
        (earth.gravity(L + e, h) - earth.gravity(L - e, h)) / (2 * e), rel=1e-6
    )
    assert dgdh == pytest.approx((earth.gravity(L, h + 1) - earth.gravity(L, h - 1)) / 2, rel=1e-6)


def _R(axis, a):
    c, s = np.cos(a), np.sin(a)
    return {
        "x": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


def test_euler_dcm_quaternion_round_trips():
    rng = np.random.default_rng(0)
    a = np.column_stack(
        [rng.uniform(-1.5, 1.5, 40), rng.uniform(-3, 3, 40), rng.uniform(-3, 3, 40)]
    )
    C = at.euler_to_dcm(a)
    ref = np.stack([_R("z", x[2]) @ _R("x", x[0]) @ _R("y", x[1]) for x in a])
    np.testing.assert_allclose(C, ref, atol=1e-14)
    np.testing.assert_allclose(at.dcm_to_euler(C), a, atol=1e-12)
    q = at.dcm_to_quat(C)
    np.testing.assert_allclose(at.quat_to_dcm(q), C, atol=1e-14)
    np.testing.assert_allclose(
        at.quat_to_dcm(at.quat_mul(q[:20], q[20:])), C[:20] @ C[20:], atol=1e-14
    )
    r = rng.normal(size=(10, 3))
    small = 0.1 * r
    np.testing.assert_allclose(at.quat_to_rotvec(at.rotvec_to_quat(small)), small, atol=1e-14)
    tiny = 1e-9 * r
    np.testing.assert_allclose(at.quat_to_rotvec(at.rotvec_to_quat(tiny)), tiny, rtol=1e-12)


def test_conventions_heading_and_body_axes():
    # heading 90° (East): ψ = −90°, the forward body axis (y) points East
    C = at.euler_to_dcm(np.array([0.0, 0.0, np.radians(-90.0)]))
    np.testing.assert_allclose(C @ [0, 1, 0], [1, 0, 0], atol=1e-15)
    assert at.heading_deg(np.radians(-90.0)) == pytest.approx(90.0)
    # positive pitch raises the nose, positive roll lowers the right wing
    C = at.euler_to_dcm(np.array([0.1, 0.0, 0.0]))
    assert (C @ [0, 1, 0])[2] > 0
    C = at.euler_to_dcm(np.array([0.0, 0.1, 0.0]))
    assert (C @ [1, 0, 0])[2] < 0


def test_attitude_error_sign_convention():
    rng = np.random.default_rng(1)
    C = at.euler_to_dcm(rng.uniform(-1, 1, 3))
    phi = np.array([2e-4, -1e-4, 3e-4])
    C_est = (np.eye(3) - at.skew(phi)) @ C  # spec §0 definition
    np.testing.assert_allclose(at.attitude_error(C_est, C), phi, rtol=1e-3)


def test_quaternion_attitude_error_equals_the_dcm_form():
    """``quat_attitude_error`` is ``attitude_error`` of the two DCMs, up to angles near π."""
    rng = np.random.default_rng(4)
    q_true = at.euler_to_quat(rng.uniform(-3, 3, (50, 3)))
    u = rng.standard_normal((50, 3))
    r = u / np.linalg.norm(u, axis=1, keepdims=True) * np.geomspace(1e-9, 3.0, 50)[:, None]
    q_est = at.quat_mul(at.rotvec_to_quat(-r), q_true)  # C̃ = exp(−[r×]) C
    q_est[::2] *= -1.0  # the sign of a quaternion does not matter
    phi = at.quat_attitude_error(q_est, q_true)
    np.testing.assert_allclose(phi, r, rtol=1e-9, atol=1e-15)
    ref = at.attitude_error(at.quat_to_dcm(q_est), at.quat_to_dcm(q_true))
    np.testing.assert_allclose(phi, ref, rtol=1e-7, atol=1e-14)
