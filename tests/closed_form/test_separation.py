"""Tracked pulls (ftnav.fdi.separation) against the filters they stand for.

Oracles, on random linear models:

* one aid: its pull over a window *is* the filter less the same filter without the
  window's measurements (a pure prediction from the window's start), and its covariance
  is the prediction's covariance less the filter's: exact (1e-9);
* two aids: the pull of aid 0 is the filter less the filter that skips aid 0 and takes
  aid 1 with the first filter's gain (the first-order exclusion): exact; its covariance
  makes the separation χ²(rank) under H0 (Monte Carlo: mean within 3 standard errors);
  against the optimal exclusion filter (its own gains) the covariance is conservative;
* the covariance inflation of a relaxed re-admission gives the innovation a χ² equal to
  its dimension.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.fdi import separation as sep
from ftnav.fusion.guard import inflation, reduction


def model(rng, n=4, ms=(2,)):
    A = rng.normal(size=(n, n)) * 0.3
    F = np.eye(n) + 0.1 * (A - A.T) + 0.02 * rng.normal(size=(n, n))
    L = rng.normal(size=(n, n)) * 0.1
    Q = L @ L.T + 1e-3 * np.eye(n)
    Hs = [rng.normal(size=(m, n)) for m in ms]
    Rs = [np.diag(rng.uniform(0.2, 1.0, m)) for m in ms]
    return F, Q, Hs, Rs


def gain(P, H, R):
    S = H @ P @ H.T + R
    return P @ H.T @ np.linalg.inv(S), S


def test_one_aid_pull_is_the_filter_less_the_prediction():
    rng = np.random.default_rng(0)
    F, Q, (H,), (R,) = model(rng)
    n = F.shape[0]
    x, P = rng.normal(size=n), np.eye(n)
    p = sep.init_pulls(1, 1, 0, n)
    xp, Pp = x.copy(), P.copy()  # the filter without the window's measurements
    for _ in range(40):
        x, P = F @ x, F @ P @ F.T + Q
        xp, Pp = F @ xp, F @ Pp @ F.T + Q
        p = sep.propagate(p, F)
        K, S = gain(P, H, R)
        z = rng.normal(size=H.shape[0]) * 3
        d = K @ (z - H @ x)
        p = sep.with_own(p, 0, d[None], reduction(K[None], (H @ P @ H.T)[None], R[None]))
        x, P = x + d, (np.eye(n) - K @ H) @ P
    c, G = sep.windows(p, 0)
    np.testing.assert_allclose(c[0, 0], x - xp, atol=1e-9, rtol=1e-9)
    np.testing.assert_allclose(G[0, 0], Pp - P, atol=1e-9, rtol=1e-9)


def first_order(rng, F, Q, Hs, Rs, steps, B, x_true=None):
    """Run the two-aid filter and its first-order exclusion of aid 0 (aid 1 with the
    filter's own gain) on simulated data; return the pulls, the two filters, the truth."""
    n = F.shape[0]
    x = np.zeros((B, n))
    P = np.eye(n)
    x_ex = x.copy()  # without aid 0, aid 1 at the filter's gain
    x_opt, P_opt = x.copy(), P.copy()  # without aid 0, optimal
    truth = rng.multivariate_normal(np.zeros(n), P, size=B)
    p = sep.init_pulls(B, 2, 0, n)
    Lq = np.linalg.cholesky(Q)
    for _ in range(steps):
        truth = truth @ F.T + rng.normal(size=(B, n)) @ Lq.T
        x, P = x @ F.T, F @ P @ F.T + Q
        x_ex = x_ex @ F.T
        x_opt, P_opt = x_opt @ F.T, F @ P_opt @ F.T + Q
        p = sep.propagate(p, F)
        for i, (H, R) in enumerate(zip(Hs, Rs, strict=True)):
            z = truth @ H.T + rng.normal(size=(B, H.shape[0])) @ np.linalg.cholesky(R).T
            K, S = gain(P, H, R)
            nu = z - x @ H.T
            Kb = np.broadcast_to(K, (B,) + K.shape)
            Hb = np.broadcast_to(H, (B,) + H.shape)
            p = sep.map_others(p, i, Kb, Hb, np.ones(B, bool))
            D = np.broadcast_to(reduction(K, H @ P @ H.T, R), (B, n, n))
            p = sep.with_own(p, i, nu @ K.T, D)
            if i == 1:
                x_ex = x_ex + (z - x_ex @ H.T) @ K.T
                Ko, _ = gain(P_opt, H, R)
                x_opt = x_opt + (z - x_opt @ H.T) @ Ko.T
                P_opt = (np.eye(n) - Ko @ H) @ P_opt
            x, P = x + nu @ K.T, (np.eye(n) - K @ H) @ P
    return p, x, P, x_ex, x_opt, P_opt


def test_two_aids_pull_is_the_first_order_exclusion():
    rng = np.random.default_rng(1)
    F, Q, Hs, Rs = model(rng, ms=(2, 1))
    p, x, _, x_ex, _, _ = first_order(rng, F, Q, Hs, Rs, 30, 3)
    c, _ = sep.windows(p, 0)
    np.testing.assert_allclose(c[:, 0], x - x_ex, atol=1e-9, rtol=1e-9)


def test_separation_is_chi2_under_h0_and_conservative_against_the_optimal_exclusion():
    rng = np.random.default_rng(2)
    F, Q, Hs, Rs = model(rng, ms=(2, 2))
    B = 3000
    p, x, P, _, x_opt, P_opt = first_order(rng, F, Q, Hs, Rs, 25, B)
    c, G = sep.windows(p, 0)
    H0 = Hs[0]
    lam, dof = sep.separation(c[:, :1], G[:, :1], H0)
    assert (dof == 2).all()
    # a χ²(2) mean over B runs: standard error 2/√B
    assert abs(lam.mean() - 2.0) < 3 * 2 / np.sqrt(B), lam.mean()
    # the optimal exclusion is at least as close as the first-order one says
    d_opt = x - x_opt
    e = d_opt @ H0.T
    T = H0 @ G[0, 0] @ H0.T
    lam_opt = np.einsum("bi,bi->b", e, np.linalg.solve(T, e.T).T)
    assert lam_opt.mean() <= 2.0 + 3 * 2 / np.sqrt(B)
    # and its covariance P_opt − P is the covariance of d_opt (orthogonality)
    T_opt = H0 @ (P_opt - P) @ H0.T
    lam_true = np.einsum("bi,bi->b", e, np.linalg.solve(T_opt, e.T).T)
    assert abs(lam_true.mean() - 2.0) < 3 * 2 / np.sqrt(B)


def test_blocks_rotate_into_windows_of_whole_blocks():
    n = 2
    p = sep.init_pulls(1, 1, 2, n)
    F = np.eye(n)
    for k in range(7):
        p = sep.propagate(p, F)
        p = sep.with_own(p, 0, np.array([[1.0, 0.0]]), np.zeros((1, n, n)))
        if (k + 1) % 3 == 0:
            p = sep.rotate(p)
    c, _ = sep.windows(p, 0)
    # 7 epochs in blocks of 3: current block 1 epoch, then 3, then 3
    np.testing.assert_allclose(c[0, :, 0], [1.0, 4.0, 7.0])
    p = sep.clear(p, 0, np.array([True]))
    assert not sep.windows(p, 0)[0].any()


def test_inflation_covers_the_innovation():
    rng = np.random.default_rng(4)
    m, B = 3, 50
    L = rng.normal(size=(B, m, m))
    A = L @ np.swapaxes(L, -1, -2) + 0.1 * np.eye(m)
    R = np.broadcast_to(0.05 * np.eye(m), (B, m, m))
    nu = rng.normal(size=(B, m)) * rng.uniform(0.1, 30, (B, 1))
    gam = inflation(nu, A, R)
    q = np.einsum(
        "bi,bi->b", nu, np.linalg.solve((1 + gam)[:, None, None] * A + R, nu[..., None])[..., 0]
    )
    before = np.einsum("bi,bi->b", nu, np.linalg.solve(A + R, nu[..., None])[..., 0])
    np.testing.assert_allclose(q[before > m], m, rtol=1e-9)
    assert (gam[before <= m] == 0).all() and (gam[before > m] > 0).all()


def test_separation_of_an_empty_window_is_zero():
    lam, dof = sep.separation(np.zeros((2, 3, 4)), np.zeros((2, 3, 4, 4)), np.eye(2, 4))
    assert (lam == 0).all() and (dof == 0).all()
    with pytest.raises(ValueError):
        sep.separation(np.zeros((2, 3, 4)), np.zeros((2, 3, 4, 4)), np.eye(2, 5))


@pytest.mark.parametrize("shared_H", [True, False])
def test_compiled_map_others_equals_the_numpy_form(shared_H):
    # the compiled low-rank form and the einsum form are the same products summed in
    # another order: equal to rounding, with runs masked out left as they were
    rng = np.random.default_rng(5)
    B, A, J, n, m = 5, 3, 4, 7, 3
    L = rng.normal(size=(B, A, J, n, n))
    p = sep.Pulls(rng.normal(size=(B, A, J, n)), L @ np.swapaxes(L, -1, -2))
    K = rng.normal(size=(B, n, m)) * 0.3
    H = rng.normal(size=(m, n)) if shared_H else rng.normal(size=(B, m, n))
    use = np.array([True, False, True, True, False])
    for aid in range(A):
        got, want = sep.map_others(p, aid, K, H, use), sep.map_others_numpy(p, aid, K, H, use)
        np.testing.assert_allclose(got.c, want.c, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.G, want.G, rtol=1e-12, atol=1e-12)
        assert np.array_equal(got.G, np.swapaxes(got.G, -1, -2))
        assert np.array_equal(got.c[~use], p.c[~use]) and np.array_equal(got.c[:, aid], p.c[:, aid])


@pytest.mark.parametrize("per_run", [True, False])
def test_compiled_propagate_equals_the_numpy_form(per_run):
    # the compiled form skips Φ's zeros (an error-state transition is mostly zeros) and
    # mirrors Γ's upper triangle: equal to the dense products to rounding, exactly
    # symmetric, on a sparse Φ and on a dense one
    rng = np.random.default_rng(11)
    B, A, J, n = 4, 3, 5, 9
    L = rng.normal(size=(B, A, J, n, n))
    p = sep.Pulls(rng.normal(size=(B, A, J, n)), L @ np.swapaxes(L, -1, -2))
    dense = np.eye(n) + 0.1 * rng.normal(size=(B, n, n) if per_run else (n, n))
    sparse = np.where(rng.uniform(size=dense.shape) < 0.3, dense, 0.0) + np.eye(n)
    for F in (sparse, dense):
        got, want = sep.propagate(p, F), sep.propagate_numpy(p, F)
        np.testing.assert_allclose(got.c, want.c, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.G, want.G, rtol=1e-12, atol=1e-12)
        assert np.array_equal(got.G, np.swapaxes(got.G, -1, -2))


def test_the_lazy_form_equals_the_explicit_one():
    # the lazy form (closed blocks stored as at the last rotation, one map T per aid)
    # against every block mapped every epoch, through time updates, other aids' updates,
    # own updates, rotations into coarse blocks, clears and windows: equal to rounding
    rng = np.random.default_rng(21)
    B, A, n, m, nb, nc = 3, 3, 6, 2, 3, 2
    lazy = sep.init_pulls(B, A, nb, n, nc)
    assert lazy.T is not None
    plain = sep.Pulls(lazy.c.copy(), lazy.G.copy())  # the explicit form
    for k in range(40):
        F = np.eye(n) + 0.05 * rng.normal(size=(B, n, n))
        lazy, plain = sep.propagate(lazy, F), sep.propagate(plain, F)
        for aid in range(A):
            K = 0.2 * rng.normal(size=(B, n, m))
            H = rng.normal(size=(m, n))
            use = rng.uniform(size=B) < 0.8
            L = rng.normal(size=(B, n, n)) * 0.1
            d, D = rng.normal(size=(B, n)), L @ np.swapaxes(L, -1, -2)
            lazy = sep.with_own(sep.map_others(lazy, aid, K, H, use), aid, d, D)
            plain = sep.with_own(sep.map_others(plain, aid, K, H, use), aid, d, D)
        if k == 23:
            where, window = np.array([True, False, True]), np.array([1, 0, 4])
            lazy, plain = sep.clear(lazy, 1, where, window), sep.clear(plain, 1, where, window)
        if k % 2 == 1:
            close = k % 6 == 5
            lazy, plain = sep.rotate(lazy, nc, close), sep.rotate(plain, nc, close)
        for aid in range(A):
            for first in (None, 2):
                (cl, Gl), (cp, Gp) = sep.windows(lazy, aid, first), sep.windows(plain, aid, first)
                scale = np.abs(Gp).max()
                np.testing.assert_allclose(cl, cp, rtol=1e-9, atol=1e-9 * np.abs(cp).max())
                np.testing.assert_allclose(Gl, Gp, rtol=1e-9, atol=1e-9 * scale)
                assert np.array_equal(Gl, np.swapaxes(Gl, -1, -2))
    e = sep.explicit(lazy)
    assert e.T is None
    np.testing.assert_allclose(e.G, plain.G, rtol=1e-9, atol=1e-9 * np.abs(plain.G).max())
