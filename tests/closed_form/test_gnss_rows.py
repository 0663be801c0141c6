"""GNSS measurement rows are East, North, Up for position as for velocity (conventions.md).

Closed form: a receiver whose position reads 10 m too far north and 4 m too far east
(an error of the device's own reading, ``z = INS − aid`` changes by −e) gives
``z = [−4, −10, 0, ...]`` at the true position, and the position rows of H map the
latitude, longitude and height errors to metres on the North, East, Up rows.
"""

from __future__ import annotations

import numpy as np

from ftnav.nav.attitude import euler_to_quat
from ftnav.nav.earth import radii
from ftnav.sensors import AidTruth, Gnss


def test_position_rows_are_east_north_up():
    g = Gnss(pos_markov_sigma_m=0.0, vel_markov_sigma_m_s=0.0)
    assert g.components == ("pos_E", "pos_N", "pos_U", "vel_E", "vel_N", "vel_U")
    p = np.array([[np.radians(34.0), np.radians(108.0), 500.0]])
    v = np.array([[100.0, 50.0, 1.0]])
    truth = AidTruth(np.array([1.0]), p, v, euler_to_quat(np.zeros((1, 3))))
    e = np.zeros((1, 1, 6))
    e[0, 0, :3] = [4.0, 10.0, 0.0]  # East 4 m, North 10 m
    raw = g.output(truth, e, np.zeros((1, 0)))[:, 0]
    lin = g.measure(truth.q, v, p, raw)
    np.testing.assert_allclose(lin.z[0], [-4.0, -10.0, 0.0, 0.0, 0.0, 0.0], atol=1e-6)
    RM, RN = radii(p[0, 0], p[0, 2])
    H = lin.H[0]
    np.testing.assert_allclose(H[0, 7], RN * np.cos(p[0, 0]))  # East row <- dlambda
    np.testing.assert_allclose(H[1, 6], RM)  # North row <- dL
    assert H[2, 8] == 1.0 and H[0, 6] == 0.0 and H[1, 7] == 0.0


def test_the_default_markov_error_is_augmented_not_folded_into_R():
    g = Gnss()
    assert g.markov == "augment" and g.private is not None
    np.testing.assert_allclose(np.diag(g.R), [1.0] * 3 + [0.02**2] * 3)  # white only
    assert Gnss(pos_markov_sigma_m=0.0, vel_markov_sigma_m_s=0.0).private is None


def _receiver_epoch(lever=(0.0, 0.0, 0.0)):
    p = np.array([[np.radians(40.1), np.radians(-105.1), 1600.0]] * 2)
    v = np.array([[3.0, -7.0, 0.2], [0.0, 0.0, 0.0]])
    q = euler_to_quat(np.array([[0.05, -0.02, 1.0], [0.0, 0.0, -2.0]]))
    raw = np.concatenate([p + [[1e-6, -2e-6, 0.7]], v + [[0.1, -0.2, 0.05]]], -1)
    return q, v, p, raw


W_IB = np.array([[0.1, -0.2, 0.3], [0.0, 0.0, 0.0]])  # the gyro's rate (rad/s)


def test_a_position_aid_and_a_velocity_aid_are_the_two_halves_of_the_receiver():
    """rows = "position" / "velocity": z, H, R, the Markov states and the simulated
    errors are exactly the rows of the 6-row receiver (one receiver, two local filters)."""
    kw = dict(lever_arm_m=(0.1, -0.3, 0.5), vel_markov_sigma_m_s=(0.05, 0.06, 0.07))
    full = Gnss(**kw)
    q, v, p, raw = _receiver_epoch()
    whole = full.measure(q, v, p, raw, W_IB)
    truth = AidTruth(np.arange(3.0), p[[0, 0, 0]], v[[0, 0, 0]], q[[0, 0, 0]], W_IB[[0, 0, 0]])
    errs = full.simulate_errors(truth, 7, range(2), 1)
    for rows, r in (("position", slice(0, 3)), ("velocity", slice(3, 6))):
        half = Gnss(rows=rows, **kw)
        assert half.dim == 3 and half.components == full.components[r]
        lin = half.measure(q, v, p, raw, W_IB)
        np.testing.assert_array_equal(lin.z, whole.z[:, r])
        np.testing.assert_array_equal(lin.H, whole.H[:, r])
        np.testing.assert_array_equal(half.R, full.R[r, r])
        np.testing.assert_array_equal(half.private.P0, full.private.P0[r, r])
        np.testing.assert_array_equal(lin.H_private, -np.eye(3)[None].repeat(2, 0))
        e = half.simulate_errors(truth, 7, range(2), 1)
        np.testing.assert_array_equal(e.coloured, errs.coloured[..., r])
        np.testing.assert_array_equal(e.white, errs.white[..., r])
        out = half.output(truth, e.coloured + e.white, e.constants)
        ref = full.output(
            truth,
            np.where(np.arange(6) // 3 == r.start // 3, 1.0, 0.0) * (errs.coloured + errs.white),
            errs.constants,
        )
        np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)


def test_gnss_rows_must_be_named():
    import pytest

    with pytest.raises(ValueError, match="gnss.rows"):
        Gnss(rows="pos")


def test_per_epoch_sigma_whitens_each_row_to_the_epochs_own_sigma():
    """Closed form: the update with the whitened rows and the sensor's R equals the
    update with the raw rows and ``R_k = diag(σ_k²)`` (posterior and NIS); a missing or
    non-positive σ keeps the row's R; simulation appends the configured σ."""
    from ftnav.core import kalman as kf

    kw = dict(pos_markov_sigma_m=0.0, vel_markov_sigma_m_s=0.0, pos_white_sigma_m=(0.05, 0.06, 0.1))
    plain, per_epoch = Gnss(**kw), Gnss(per_epoch_sigma=True, **kw)
    q, v, p, raw = _receiver_epoch()
    sigma = np.array([[0.01, 0.02, 0.03, 0.2, 0.3, 0.4], [np.nan, 0.5, -1.0, 0.02, 0.02, 0.02]])
    lin0 = plain.measure(q, v, p, raw)
    lin = per_epoch.measure(q, v, p, np.concatenate([raw, sigma], -1))
    sig_R = np.sqrt(np.diag(plain.R))
    sigma_k = np.where(np.isfinite(sigma) & (sigma > 0), sigma, sig_R)
    rng = np.random.default_rng(3)
    x = rng.normal(size=(2, 18)) * 1e-3
    A = rng.normal(size=(2, 18, 18)) * 1e-3
    P = A @ A.transpose(0, 2, 1) + 1e-6 * np.eye(18)
    want = kf.update(x, P, lin0.z, lin0.H, np.stack([np.diag(s**2) for s in sigma_k]))
    got = kf.update(x, P, lin.z, lin.H, plain.R)
    np.testing.assert_allclose(got.x, want.x, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(got.P, want.P, rtol=1e-9, atol=1e-18)
    nis0 = kf.prior_nis(x, P, lin0.z, lin0.H, np.stack([np.diag(s**2) for s in sigma_k]))
    np.testing.assert_allclose(kf.prior_nis(x, P, lin.z, lin.H, plain.R), nis0, rtol=1e-9)
    truth = AidTruth(np.arange(2.0), p, v, q)
    out = per_epoch.output(truth, np.zeros((1, 2, 6)), np.zeros((1, 0)))
    np.testing.assert_array_equal(out[..., 6:], np.broadcast_to(sig_R, (1, 2, 6)))


def test_per_epoch_sigma_is_refused_with_a_differenced_markov_error():
    import pytest

    with pytest.raises(ValueError, match="gnss.per_epoch_sigma"):
        Gnss(per_epoch_sigma=True, markov="difference")
