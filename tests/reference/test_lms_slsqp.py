"""Projected LMS (spec §5.3) against a simplex-constrained least-squares oracle (spec §5.5).

The oracle is ``scipy.optimize.minimize(method="SLSQP")`` of the mean squared
residual ``(1/M) Σ_m (t⁽ᵐ⁾ − wᵀu⁽ᵐ⁾)²`` subject to ``w >= 0``, ``Σw = 1``, on the
same samples the neuron is trained on.  The objective is evaluated through its
Gram form ``wᵀGw − 2bᵀw + c`` (``G = UᵀU/M``, ``b = Uᵀt/M``), which is the same
function, with its exact gradient.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from ftnav.core.lms import lms_train

#: the oracle test's step numerator: the LMS misadjustment after 200 decaying
#: epochs is ~sqrt(μ/(2·200)·σ_ε²/tr R); μ = 0.1 leaves ~2e-3 on these data
MU = 0.005


def constrained_least_squares(U: np.ndarray, t: np.ndarray, q: np.ndarray | None = None):
    """SLSQP minimiser of ``Σ_m q_m (t_m − U_m w)²`` over ``{w >= 0, Σw = 1}``.

    ``U (M, N)``, ``t (M,)``, optional sample weights ``q (M,)`` (default 1).
    """
    M, N = U.shape
    q = np.ones(M) if q is None else q
    G = (U * q[:, None]).T @ U / M
    b = (U * q[:, None]).T @ t / M
    c = np.sum(q * t * t) / M
    res = minimize(
        lambda w: w @ G @ w - 2.0 * b @ w + c,
        np.full(N, 1.0 / N),
        jac=lambda w: 2.0 * (G @ w - b),
        method="SLSQP",
        bounds=[(0.0, None)] * N,
        constraints=[dict(type="eq", fun=lambda w: np.sum(w) - 1.0, jac=lambda w: np.ones_like(w))],
        options=dict(ftol=1e-15, maxiter=1000),
    )
    assert res.success, res.message
    return np.clip(res.x, 0.0, None)


def _centre(u: np.ndarray, t: np.ndarray):
    ubar = u.mean(axis=1, keepdims=True)
    return (u - ubar)[None], (t - ubar[:, 0])[None]


def independent_data(seed: int, M: int = 20_000):
    """σ = (1, 2, 4, 8) independent errors (spec §5.5), centred as spec §5.3."""
    rng = np.random.default_rng(seed)
    t = rng.normal(0.0, 10.0, M)
    u = t[:, None] + rng.standard_normal((M, 4)) * np.array([1.0, 2.0, 4.0, 8.0])
    return _centre(u, t)


#: correlated errors (σ = 1, 2, 3; ρ₁₂ = 0.9): the unconstrained optimum is
#: S⁻¹1/(1ᵀS⁻¹1) = (1.482, −0.539, 0.057), so w_2 >= 0 is active
SD = np.array([1.0, 2.0, 3.0])
CORR = np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]])
S_CORR = CORR * np.outer(SD, SD)


def correlated_data(seed: int, M: int = 20_000):
    rng = np.random.default_rng(seed)
    t = rng.normal(0.0, 10.0, M)
    u = t[:, None] + rng.multivariate_normal(np.zeros(3), S_CORR, M)
    return _centre(u, t)


@pytest.fixture(scope="module")
def independent():
    return independent_data(31)


@pytest.fixture(scope="module")
def correlated():
    return correlated_data(32)


def test_correlated_case_has_a_negative_unconstrained_weight():
    d = np.linalg.solve(S_CORR, np.ones(3))
    d /= d.sum()
    np.testing.assert_allclose(d, [1.482036, -0.538922, 0.056886], atol=1e-6)
    assert d[1] < 0.0


@pytest.mark.parametrize("case", ["independent", "correlated"])
def test_lms_matches_slsqp_oracle(case, request):
    """Spec §5.5: projection "simplex", step "lms", decay on -> within 1e-3 of SLSQP."""
    U, t = request.getfixturevalue(case)
    w_ref = constrained_least_squares(U[0], t[0])
    r = lms_train(
        U, t, projection="simplex", step="lms", mu=MU, decay=True, rng=np.random.default_rng(8)
    )
    err = np.abs(r.weights[0] - w_ref).max()
    assert err < 1e-3, (r.weights[0], w_ref, err)
    if case == "correlated":
        assert w_ref[1] < 1e-9 and r.weights[0, 1] < 1e-4  # the constraint is active
    # and LMS attains the oracle's minimum of the training MSE
    res = t[0] - U[0] @ w_ref
    assert r.mse[0] - np.mean(res * res) < 1e-5


@pytest.mark.parametrize("case", ["independent", "correlated"])
def test_nlms_matches_the_weighted_oracle(case, request):
    """Step "nlms" converges to the 1/‖u‖²-weighted constrained LS minimiser instead.

    On the correlated data the two minimisers are 0.09 apart; on the independent
    ones only ~2e-3.
    """
    U, t = request.getfixturevalue(case)
    q = 1.0 / (1e-12 + np.sum(U[0] ** 2, axis=1))
    w_weighted = constrained_least_squares(U[0], t[0], q)
    r = lms_train(U, t, projection="simplex", step="nlms", mu=MU, rng=np.random.default_rng(8))
    assert np.abs(r.weights[0] - w_weighted).max() < 1e-3
    if case == "correlated":
        w_plain = constrained_least_squares(U[0], t[0])
        assert np.abs(w_weighted - w_plain).max() > 0.05
        assert np.abs(r.weights[0] - w_plain).max() > 0.05


def test_seed_rule_is_biased_when_a_constraint_is_active(correlated):
    """The seed's clip-and-renormalize projection does not reach the constrained LS minimiser.

    With w_k held at 0, each update pushes w_k below 0 by η·g_k and the
    renormalization then shrinks every other weight by the same *factor*, not
    by the same amount (the Euclidean projection).  The mean update
    ``d = E[ε ũ] = b − G w`` (which sums to 0 on centred data) therefore stops
    where ``d_i = −d_k · w_i`` for the free weights, instead of the KKT
    condition ``d_i`` equal for all free weights.  That limit does not depend on
    the step size.
    """
    U, t = correlated
    w_ref = constrained_least_squares(U[0], t[0])
    r = lms_train(U, t, projection="seed", step="lms", mu=MU, rng=np.random.default_rng(8))
    w = r.weights[0]
    assert np.abs(w - w_ref).max() > 0.01
    G = U[0].T @ U[0] / U.shape[1]
    b = U[0].T @ t[0] / U.shape[1]
    d = b - G @ w
    free = np.array([0, 2])
    np.testing.assert_allclose(d[free], -d[1] * w[free], rtol=0, atol=2e-3)
