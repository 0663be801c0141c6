"""Compiled navigation helpers equal their NumPy forms (spec §0, §8.5).

Oracles: ``attitude.quat_attitude_error`` (itself equal to the DCM definition of φ,
``tests/closed_form/test_earth_attitude.py``) for :func:`navigation_errors`, and the
broadcasting NumPy branch of :func:`apply_correction` for its compiled (B, ·) branch.
"""

from __future__ import annotations

import numpy as np

from ftnav.nav import attitude as at
from ftnav.nav.mechanization import apply_correction, navigation_errors


def _solutions(B=9, seed=0):
    rng = np.random.default_rng(seed)
    q_true = at.euler_to_quat(rng.uniform(-1, 1, 3))
    u = rng.standard_normal((B, 3))
    r = u / np.linalg.norm(u, axis=1, keepdims=True) * np.geomspace(1e-10, 3.0, B)[:, None]
    q = at.quat_mul(at.rotvec_to_quat(-r), np.broadcast_to(q_true, (B, 4)))
    q[::3] *= -1.0
    return rng, q, r, q_true


def test_navigation_errors_equal_the_numpy_form():
    rng, q, r, q_true = _solutions()
    v, p = rng.standard_normal((9, 3)), rng.standard_normal((9, 3))
    v_t, p_t = rng.standard_normal(3), rng.standard_normal(3)
    e = navigation_errors(q, v, p, q_true, v_t, p_t)
    np.testing.assert_allclose(e[:, :3], at.quat_attitude_error(q, q_true), rtol=1e-12, atol=1e-16)
    np.testing.assert_allclose(e[:, :3], r, rtol=1e-9, atol=1e-15)
    np.testing.assert_array_equal(e[:, 3:6], v - v_t)
    np.testing.assert_array_equal(e[:, 6:9], p - p_t)


def test_compiled_correction_equals_the_broadcast_form():
    rng, q, _, _ = _solutions(seed=1)
    v, p = rng.standard_normal((9, 3)), rng.standard_normal((9, 3))
    phi = rng.standard_normal((9, 3)) * np.geomspace(1e-12, 0.5, 9)[:, None]
    dv, dp = rng.standard_normal((9, 3)), rng.standard_normal((9, 3))
    got = apply_correction(q, v, p, phi, dv, dp)
    ref = apply_correction(
        q[:, None], v[:, None], p[:, None], phi[:, None], dv[:, None], dp[:, None]
    )  # (B, 1, ·): the NumPy branch
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b[:, 0], rtol=1e-13, atol=1e-15)
