"""Information-sharing rules (spec §2 tests a-c) against hand-worked and eigen-based oracles."""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core.sharing import RULES, sharing_coefficients


def random_spd_batch(rng, B, N, n):
    A = rng.standard_normal((B, N, n, n)) * rng.uniform(0.1, 10.0, (B, N, 1, 1))
    return A @ np.swapaxes(A, -1, -2) + 0.01 * np.eye(n)


def random_faults(rng, B, N):
    """Random fault factors with at least one healthy filter per run."""
    r = (rng.random((B, N)) < 0.7).astype(float)
    r[np.arange(B), rng.integers(0, N, B)] = 1.0
    return r


def _kwargs(rule, N, rng):
    return dict(betas=rng.dirichlet(np.ones(N)), info=rng.uniform(0.1, 5.0, N))


@pytest.mark.parametrize("master_share", [0.0, 0.2, 1.0 / 3.0])
@pytest.mark.parametrize("rule", RULES)
@pytest.mark.parametrize("scaled", [False, True])
def test_rules_are_a_partition_of_unity(rule, master_share, scaled):
    """Spec §2 (a): β ≥ 0, β_i = 0 where r_i = 0, and Σβ + β_m = 1 within 1e-12."""
    rng = np.random.default_rng([RULES.index(rule), int(master_share * 10), scaled])
    B, N, n = 64, 4, 3
    P = random_spd_batch(rng, B, N, n)
    r = random_faults(rng, B, N)
    scale = rng.uniform(0.1, 3.0, n) if scaled else None
    beta = sharing_coefficients(
        rule, P, r, master_share=master_share, scale=scale, **_kwargs(rule, N, rng)
    )
    assert beta.shape == (B, N)
    assert (beta >= 0.0).all()
    assert (beta[r == 0] == 0.0).all()
    assert (beta[r == 1] > 0.0).all()
    np.testing.assert_allclose(beta.sum(-1) + master_share, 1.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("rule", RULES)
def test_all_faulty_gives_all_zero(rule):
    """Spec §1.4/§2.6: no healthy filter -> no local is fused (the master propagates)."""
    rng = np.random.default_rng(1)
    P = random_spd_batch(rng, 3, 3, 2)
    beta = sharing_coefficients(
        rule, P, np.zeros((3, 3)), master_share=0.1, **_kwargs(rule, 3, rng)
    )
    np.testing.assert_array_equal(beta, 0.0)


@pytest.mark.parametrize("master_share", [0.0, 0.25])
def test_trace_equals_eigenvalue_trace(master_share):
    """Spec §2 (b): β_i = (1 − β_m) r_i tr Λ_i / Σ_j r_j tr Λ_j, Λ from ``eigh``."""
    rng = np.random.default_rng(2)
    B, N, n = 50, 5, 4
    P = random_spd_batch(rng, B, N, n)
    r = random_faults(rng, B, N)
    eig_trace = np.linalg.eigh(P)[0].sum(-1) * r
    expected = (1.0 - master_share) * eig_trace / eig_trace.sum(-1, keepdims=True)
    for rule in ("trace", "eigen-trace"):
        beta = sharing_coefficients(rule, P, r, master_share=master_share)
        np.testing.assert_allclose(beta, expected, rtol=0, atol=1e-12)


def test_inverse_trace_of_scaled_identities():
    """Spec §2 (c): P_i = c_i I, r = 1 -> β_i ∝ 1/c_i; with r_2 = 0 -> β_2 = 0 exactly."""
    c = np.array([1.0, 4.0, 0.5])
    P = c[:, None, None] * np.eye(3)
    beta = sharing_coefficients("inverse-trace", P, np.ones(3))
    inv = 1.0 / c
    np.testing.assert_allclose(beta, inv / inv.sum(), rtol=0, atol=1e-15)
    np.testing.assert_allclose(beta, [4 / 13, 1 / 13, 8 / 13], rtol=0, atol=1e-15)
    beta = sharing_coefficients("inverse-trace", P, np.array([1.0, 0.0, 1.0]), master_share=0.4)
    assert beta[1] == 0.0
    np.testing.assert_allclose(beta, [0.6 * 1 / 3, 0.0, 0.6 * 2 / 3], rtol=0, atol=1e-15)


def test_inverse_trace_reference_cancels():
    """l_0 = mean tr P_j cancels (spec §2.6): scaling every P by 1e6 leaves β unchanged."""
    rng = np.random.default_rng(3)
    P = random_spd_batch(rng, 4, 3, 3)
    r = np.ones((4, 3))
    np.testing.assert_allclose(
        sharing_coefficients("inverse-trace", P * 1e6, r),
        sharing_coefficients("inverse-trace", P, r),
        rtol=1e-12,
    )


def test_frobenius_by_hand():
    """‖diag(3,4)‖_F = 5, ‖diag(5,12)‖_F = 13 -> β = (5, 13)/18, times 1 − β_m."""
    P = np.array([np.diag([3.0, 4.0]), np.diag([5.0, 12.0])])
    np.testing.assert_allclose(
        sharing_coefficients("frobenius", P, np.ones(2)), [5 / 18, 13 / 18], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(
        sharing_coefficients("frobenius", P, np.ones(2), master_share=0.1),
        [0.25, 0.65],
        rtol=0,
        atol=1e-15,
    )
    # off-diagonal entries count: ‖[[1,2],[2,1]]‖_F = √10
    P2 = np.array([[[1.0, 2.0], [2.0, 1.0]], np.diag([3.0, 1.0])])
    np.testing.assert_allclose(
        sharing_coefficients("frobenius", P2, np.ones(2)), [0.5, 0.5], rtol=0, atol=1e-15
    )


def test_equal_fixed_and_information_rules():
    r = np.array([[1.0, 1.0, 0.0, 1.0]])
    P = np.broadcast_to(np.eye(2), (1, 4, 2, 2))
    np.testing.assert_allclose(
        sharing_coefficients("equal", P, r, master_share=0.1), [[0.3, 0.3, 0.0, 0.3]], atol=1e-15
    )
    np.testing.assert_allclose(
        sharing_coefficients("fixed", P, r, betas=np.array([0.1, 0.3, 0.2, 0.4])),
        [[0.125, 0.375, 0.0, 0.5]],
        atol=1e-15,
    )
    np.testing.assert_allclose(
        sharing_coefficients("information", P, r, info=np.array([1.0, 2.0, 5.0, 1.0])),
        [[0.25, 0.5, 0.0, 0.25]],
        atol=1e-15,
    )


def test_scaled_trace_uses_weighting():
    """tr(W P W) with W = diag(0.1, 1): traces 100·0.01 + 1 = 2 and 0.01 + 100 = 100.01."""
    P = np.array([np.diag([100.0, 1.0]), np.diag([1.0, 100.0])])
    raw = sharing_coefficients("trace", P, np.ones(2))
    scaled = sharing_coefficients("trace", P, np.ones(2), scale=np.array([0.1, 1.0]))
    np.testing.assert_allclose(raw, [0.5, 0.5], atol=1e-15)
    np.testing.assert_allclose(scaled, [2.0 / 102.01, 100.01 / 102.01], atol=1e-15)


def test_unknown_rule_raises():
    with pytest.raises(ValueError, match="unknown rule"):
        sharing_coefficients("bogus", np.eye(2)[None], np.ones(1))
