"""Closed-form and reference checks of the Kalman kernel (``ftnav.core.kalman``, ``linalg``).

Oracles: a scalar step worked by hand; the textbook standard-form update
``P − K S Kᵀ``; the plain-NumPy ``*_reference`` functions; ``numpy.linalg``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core import kalman as kf
from ftnav.core.linalg import spd_inv, spd_solve


def random_spd(rng, shape, n, floor=0.1):
    A = rng.standard_normal(shape + (n, n))
    return A @ np.swapaxes(A, -1, -2) / n + floor * np.eye(n)


def test_scalar_step_by_hand():
    """x=2, P=4, F=1.5, Q=1 -> x⁻=3, P⁻=10; H=2, R=4, z=8 -> ν=2, S=44, K=5/11,
    x⁺ = 3 + 10/11 = 43/11, P⁺ = (1 − KH) P⁻ = 10/11, NIS = 4/44 = 1/11."""
    x, P = np.array([2.0]), np.array([[4.0]])
    pr = kf.predict(x, P, np.array([[1.5]]), np.array([[1.0]]))
    assert pr.x[0] == pytest.approx(3.0, abs=1e-15)
    assert pr.P[0, 0] == pytest.approx(10.0, abs=1e-14)
    up = kf.update(pr.x, pr.P, np.array([8.0]), np.array([[2.0]]), np.array([[4.0]]))
    assert up.innovation[0] == pytest.approx(2.0, abs=1e-15)
    assert up.S[0, 0] == pytest.approx(44.0, abs=1e-13)
    assert up.x[0] == pytest.approx(43.0 / 11.0, abs=1e-14)
    assert up.P[0, 0] == pytest.approx(10.0 / 11.0, abs=1e-14)
    assert up.nis == pytest.approx(1.0 / 11.0, abs=1e-15)


def test_two_state_step_by_hand():
    """Position/velocity, measure position: P⁻ = [[2,1],[1,1]] (F=[[1,1],[0,1]], P=I, Q=0),
    R = 1: S = 3, K = [2/3, 1/3], P⁺ = P⁻ − K S Kᵀ = [[2/3, 1/3], [1/3, 2/3]]."""
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    pr = kf.predict(np.array([0.0, 1.0]), np.eye(2), F, np.zeros((2, 2)))
    np.testing.assert_allclose(pr.x, [1.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(pr.P, [[2.0, 1.0], [1.0, 1.0]], atol=1e-15)
    up = kf.update(pr.x, pr.P, np.array([4.0]), np.array([[1.0, 0.0]]), np.eye(1))
    np.testing.assert_allclose(up.x, [1.0 + 2.0, 1.0 + 1.0], atol=1e-14)
    np.testing.assert_allclose(up.P, [[2 / 3, 1 / 3], [1 / 3, 2 / 3]], atol=1e-15)


@pytest.mark.parametrize("n,m", [(1, 1), (3, 1), (5, 2), (18, 6)])
def test_joseph_equals_standard_form(n, m):
    """Joseph form = ``P − K S Kᵀ`` with the optimal gain (spec §0), random SPD problems."""
    rng = np.random.default_rng([1, n, m])
    B = 6
    x, z = rng.standard_normal((B, n)), rng.standard_normal((B, m))
    P, R = random_spd(rng, (B,), n), random_spd(rng, (B,), m)
    H = rng.standard_normal((B, m, n))
    up = kf.update(x, P, z, H, R)
    S = H @ P @ np.swapaxes(H, -1, -2) + R
    K = P @ np.swapaxes(H, -1, -2) @ np.linalg.inv(S)
    P_std = P - K @ S @ np.swapaxes(K, -1, -2)
    x_std = x + (K @ (z - (H @ x[..., None])[..., 0])[..., None])[..., 0]
    np.testing.assert_allclose(up.P, P_std, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(up.x, x_std, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(up.S, S, rtol=1e-12, atol=1e-12)
    nis = np.einsum("bi,bi->b", up.innovation, np.linalg.solve(S, up.innovation[..., None])[..., 0])
    np.testing.assert_allclose(up.nis, nis, rtol=1e-10)
    np.testing.assert_array_equal(up.P, np.swapaxes(up.P, -1, -2))  # exactly symmetric


@pytest.mark.parametrize("n,m", [(1, 1), (3, 1), (5, 2), (18, 6)])
@pytest.mark.parametrize("shared", [True, False], ids=["shared F/H", "batched F/H"])
def test_compiled_kernels_equal_reference(n, m, shared):
    """Compiled ``predict``/``update`` = the plain NumPy ``*_reference`` forms."""
    rng = np.random.default_rng([2, n, m, shared])
    B = 5
    x, P = rng.standard_normal((B, n)), random_spd(rng, (B,), n)
    mat_shape = () if shared else (B,)
    F = rng.standard_normal(mat_shape + (n, n))
    Q = random_spd(rng, mat_shape, n, floor=0.01)
    H = rng.standard_normal(mat_shape + (m, n))
    R = random_spd(rng, mat_shape, m)
    z = rng.standard_normal((B, m))
    got, ref = kf.predict(x, P, F, Q), kf.predict_reference(x, P, F, Q)
    np.testing.assert_allclose(got.x, ref.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.P, ref.P, rtol=1e-12, atol=1e-12)
    gu, ru = kf.update(got.x, got.P, z, H, R), kf.update_reference(ref.x, ref.P, z, H, R)
    for a, b in zip(gu, ru, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-11)


def test_unbatched_call_keeps_shapes():
    rng = np.random.default_rng(3)
    x, P = rng.standard_normal(4), random_spd(rng, (), 4)
    pr = kf.predict(x, P, np.eye(4), np.eye(4))
    up = kf.update(pr.x, pr.P, rng.standard_normal(2), rng.standard_normal((2, 4)), np.eye(2))
    assert pr.x.shape == (4,) and pr.P.shape == (4, 4)
    assert up.x.shape == (4,) and up.S.shape == (2, 2) and np.shape(up.nis) == ()


@pytest.mark.parametrize("m", [1, 2])
def test_indefinite_innovation_covariance_falls_back(m):
    """A negative-definite R makes S indefinite: the Cholesky kernel must hand over to the
    LU reference instead of returning NaN or garbage."""
    rng = np.random.default_rng([4, m])
    n, B = 3, 4
    x, P = rng.standard_normal((B, n)), random_spd(rng, (B,), n)
    H = rng.standard_normal((m, n))
    R = np.broadcast_to(-(np.abs(H @ P[0] @ H.T).max() * 50.0 + 10.0) * np.eye(m), (B, m, m))
    R = R.copy()
    R[0] = np.eye(m)  # one healthy element in the same batch
    z = rng.standard_normal((B, m))
    got, ref = kf.update(x, P, z, H, R), kf.update_reference(x, P, z, H, R)
    assert np.isfinite(got.x).all() and np.isfinite(got.P).all()
    assert (np.linalg.eigvalsh(got.S[1:]) < 0).any()  # really indefinite
    for a, b in zip(got, ref, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------------------
# Information form
# ---------------------------------------------------------------------------


def test_information_round_trip():
    rng = np.random.default_rng(5)
    x, P = rng.standard_normal((7, 4)), random_spd(rng, (7,), 4)
    y, Y = kf.to_information(x, P)
    np.testing.assert_allclose(Y @ P, np.broadcast_to(np.eye(4), P.shape), atol=1e-12)
    np.testing.assert_allclose(y, np.linalg.solve(P, x[..., None])[..., 0], rtol=1e-10)
    back = kf.from_information(y, Y)
    np.testing.assert_allclose(back.x, x, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(back.P, P, rtol=1e-10, atol=1e-12)


def test_information_predict_matches_covariance_predict():
    """``Y⁻ = (F Y⁻¹ Fᵀ + Q)⁻¹`` and ``y⁻ = Y⁻ F x`` for invertible Y."""
    rng = np.random.default_rng(6)
    B, n = 5, 4
    x, P = rng.standard_normal((B, n)), random_spd(rng, (B,), n)
    F = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    Q = random_spd(rng, (), n, floor=0.05)
    y, Y = kf.to_information(x, P)
    y_pr, Y_pr = kf.information_predict(y, Y, F, Q)
    P_pr = F @ P @ F.T + Q
    Y_ref = np.linalg.inv(P_pr)
    np.testing.assert_allclose(Y_pr, Y_ref, rtol=1e-9, atol=1e-12 * np.abs(Y_ref).max())
    y_ref = (Y_ref @ (F @ x[..., None]))[..., 0]
    np.testing.assert_allclose(y_pr, y_ref, rtol=1e-9, atol=1e-12 * np.abs(y_ref).max())


def test_information_predict_of_no_information_is_zero():
    rng = np.random.default_rng(7)
    n = 3
    F = np.eye(n) + 0.2 * rng.standard_normal((n, n))
    y_pr, Y_pr = kf.information_predict(
        np.zeros((2, n)), np.zeros((2, n, n)), F, random_spd(rng, (), n)
    )
    assert np.isfinite(Y_pr).all()
    np.testing.assert_array_equal(Y_pr, 0.0)
    np.testing.assert_array_equal(y_pr, 0.0)


def test_information_predict_with_singular_information_and_process_noise():
    """Rank-1 Y (one scalar measurement so far), singular Q: compare with the limit of a
    tiny regularization ``Y + δI`` (covariance form), which converges as δ → 0."""
    rng = np.random.default_rng(8)
    n = 3
    h = rng.standard_normal(n)
    Y = np.outer(h, h) / 2.0
    y = h * 0.7
    F = np.eye(n) + 0.2 * rng.standard_normal((n, n))
    Q = np.diag([0.5, 0.0, 0.0])
    y_pr, Y_pr = kf.information_predict(y, Y, F, Q)
    d = 1e-9
    Yd = Y + d * np.eye(n)
    P_pr = F @ np.linalg.inv(Yd) @ F.T + Q
    Y_ref = np.linalg.inv(P_pr)
    y_ref = Y_ref @ F @ np.linalg.solve(Yd, y)
    np.testing.assert_allclose(Y_pr, Y_ref, atol=1e-6)
    np.testing.assert_allclose(y_pr, y_ref, atol=1e-6)


# ---------------------------------------------------------------------------
# SPD solves
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("n,k", [(1, 1), (1, 3), (2, 1), (4, 4), (9, 2)])
def test_spd_solve_matches_numpy(n, k):
    rng = np.random.default_rng([9, n, k])
    A = random_spd(rng, (3, 2), n)
    Bm = rng.standard_normal((3, 2, n, k))
    np.testing.assert_allclose(spd_solve(A, Bm), np.linalg.solve(A, Bm), rtol=1e-10, atol=1e-12)
    # broadcasting a single matrix against a batch of right-hand sides
    np.testing.assert_allclose(
        spd_solve(A[0, 0], Bm), np.linalg.solve(A[0, 0], Bm), rtol=1e-10, atol=1e-12
    )
    inv = spd_inv(A)
    np.testing.assert_allclose(inv, np.linalg.inv(A), rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(inv, np.swapaxes(inv, -1, -2))


def test_spd_solve_falls_back_for_indefinite_matrices():
    rng = np.random.default_rng(10)
    A = random_spd(rng, (3,), 3)
    A[1] = np.diag([1.0, -2.0, 3.0])  # Cholesky fails, LU does not
    Bm = rng.standard_normal((3, 3, 2))
    got = spd_solve(A, Bm)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, np.linalg.solve(A, Bm), rtol=1e-10, atol=1e-12)


def test_nis_matches_explicit_formula():
    rng = np.random.default_rng(11)
    S = random_spd(rng, (6,), 3)
    nu = rng.standard_normal((6, 3))
    ref = np.einsum("bi,bij,bj->b", nu, np.linalg.inv(S), nu)
    np.testing.assert_allclose(kf.nis(nu, S), ref, rtol=1e-10)


@pytest.mark.parametrize("shared", [False, True])
def test_prior_nis_matches_the_explicit_formula_and_the_update(shared):
    """``prior_nis`` (one compiled pass) = ``νᵀ S⁻¹ ν`` formed explicitly = ``update``'s NIS."""
    rng = np.random.default_rng(12)
    B, n, m = 7, 6, 3
    x = rng.standard_normal((B, n))
    P = random_spd(rng, (B,), n)
    z = rng.standard_normal((B, m))
    H = rng.standard_normal((m, n) if shared else (B, m, n))
    R = random_spd(rng, () if shared else (B,), m)
    nu = z - kf.mv(H, x)
    S = H @ P @ kf.mT(H) + R
    ref = np.einsum("bi,bij,bj->b", nu, np.linalg.inv(S), nu)
    got = kf.prior_nis(x, P, z, H, R)
    np.testing.assert_allclose(got, ref, rtol=1e-10)
    np.testing.assert_allclose(got, kf.update(x, P, z, H, R).nis, rtol=1e-10)


def test_prior_nis_and_spd_inv_fall_back_where_cholesky_fails():
    rng = np.random.default_rng(13)
    x, P = rng.standard_normal((3, 2)), np.broadcast_to(np.eye(2), (3, 2, 2)).copy()
    R = np.broadcast_to(np.eye(2), (3, 2, 2)).copy()
    R[1] = np.diag([-3.0, 1.0])  # S = P + R = diag(-2, 2): indefinite
    z = rng.standard_normal((3, 2))
    nu = z - x
    ref = np.einsum("bi,bij,bj->b", nu, np.linalg.inv(P + R), nu)
    np.testing.assert_allclose(kf.prior_nis(x, P, z, np.eye(2), R), ref, rtol=1e-12)
    A = P + R
    np.testing.assert_allclose(spd_inv(A), np.linalg.inv(A), rtol=1e-12)


@pytest.mark.parametrize(
    "shapes", [((3, 2), (3, 2), ()), ((), ()), ((4,), (1,)), ((2, 1), (5,)), ((3,), ())]
)
def test_batch_shape_equals_numpy_broadcast_shapes(shapes):
    from ftnav.core.linalg import batch_shape

    assert batch_shape(*shapes) == np.broadcast_shapes(*shapes)


def test_batch_shape_refuses_what_does_not_broadcast():
    from ftnav.core.linalg import batch_shape

    with pytest.raises(ValueError):
        batch_shape((3,), (4,))
