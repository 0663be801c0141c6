"""Constrained LMS training of the neuron fusion centre (spec §5.3, tests of §5.5).

Oracles: the closed-form optimal fusion weights of independent errors (spec §5.1,
``D_i ∝ σ_i⁻²``), a brute-force enumeration of the simplex projection's support,
its KKT conditions, and hand-worked examples of the seed's clip-and-renormalize rule.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from ftnav.core.lms import (
    LmsResult,
    _project_simplex_inplace,
    clip_renormalize,
    lms_train,
    project_simplex,
)

SIGMA = np.array([1.0, 2.0, 4.0, 8.0])
#: spec §5.5: (1, 1/4, 1/16, 1/64) / Σ
W_OPT = SIGMA**-2 / np.sum(SIGMA**-2)


def fusion_data(seed: int, sigma=SIGMA, M: int = 20_000, bias: dict | None = None):
    """Centred training samples of one neuron, shapes (1, M, N) and (1, M).

    Truth ``t ~ N(0, 10²)``, local estimates ``u_i = t + e_i`` with independent
    ``e_i ~ N(0, σ_i²)`` plus an optional constant ``bias[i]``; centred as spec
    §5.3 (``ũ_i = u_i − ū``, ``t̃ = t − ū``, ``ū`` the mean of the inputs).
    """
    rng = np.random.default_rng(seed)
    sigma = np.asarray(sigma, dtype=float)
    t = rng.normal(0.0, 10.0, M)
    u = t[:, None] + rng.standard_normal((M, sigma.size)) * sigma
    for i, b in (bias or {}).items():
        u[:, i] += b
    ubar = u.mean(axis=1, keepdims=True)
    return (u - ubar)[None], (t - ubar[:, 0])[None]


def correlated_data(seed: int, M: int = 5_000):
    """Centred samples whose unconstrained optimum has a negative weight (spec §5.1)."""
    sd = np.array([1.0, 2.0, 3.0])
    C = np.eye(3)
    C[0, 1] = C[1, 0] = 0.9
    S = C * np.outer(sd, sd)
    rng = np.random.default_rng(seed)
    t = rng.normal(0.0, 10.0, M)
    u = t[:, None] + rng.multivariate_normal(np.zeros(3), S, M)
    ubar = u.mean(axis=1, keepdims=True)
    return (u - ubar)[None], (t - ubar[:, 0])[None]


@pytest.fixture(scope="module")
def sigma_data():
    return fusion_data(11)


# --------------------------------------------------------------------------- projections


def _brute_force_simplex(v):
    """Projection of ``v (N,)`` by enumerating every support set S.

    On S the projection is ``v_S − (Σ v_S − 1)/|S|``; among the candidates that
    are feasible (>= 0 on S), the nearest to ``v`` is the projection.
    """
    N = v.size
    best, best_d = None, np.inf
    for r in range(1, N + 1):
        for S in itertools.combinations(range(N), r):
            S = list(S)
            w = np.zeros(N)
            w[S] = v[S] - (v[S].sum() - 1.0) / r
            if (w[S] >= 0.0).all():
                d = np.sum((w - v) ** 2)
                if d < best_d:
                    best, best_d = w, d
    return best


@pytest.mark.parametrize("shape", [(200, 2), (200, 5), (4, 6, 3)])
def test_project_simplex_matches_brute_force_and_kkt(shape):
    rng = np.random.default_rng(shape)
    V = rng.normal(0.0, 1.0, shape) * rng.choice([0.1, 1.0, 10.0], shape[:-1] + (1,))
    W = project_simplex(V)
    assert W.shape == shape
    assert (W >= 0.0).all()
    np.testing.assert_allclose(W.sum(axis=-1), 1.0, rtol=0, atol=1e-12)
    for v, w in zip(V.reshape(-1, shape[-1]), W.reshape(-1, shape[-1]), strict=True):
        np.testing.assert_allclose(w, _brute_force_simplex(v), rtol=0, atol=1e-12)
        # KKT: w = max(v − θ, 0) for a single θ
        pos = w > 0.0
        theta = v[pos] - w[pos]
        np.testing.assert_allclose(theta, theta[0], rtol=0, atol=1e-12)
        assert (v[~pos] <= theta[0] + 1e-12).all()


def test_project_simplex_idempotent_and_hand_examples():
    rng = np.random.default_rng(0)
    P = rng.dirichlet(np.ones(5), 100)
    P[:10, 2] = 0.0  # points on faces too
    P[:10] /= P[:10].sum(axis=1, keepdims=True)
    np.testing.assert_allclose(project_simplex(P), P, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        project_simplex(project_simplex(P + 3.0)), project_simplex(P + 3.0), rtol=0, atol=1e-15
    )
    # worked by hand: θ = (3 + 1 − 1)/2 = 1.5 -> (1.5, 0, 0); θ = (0.6+0.6−1)/2 = 0.1
    np.testing.assert_allclose(project_simplex([3.0, 1.0, -2.0]), [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(project_simplex([0.6, 0.6, 0.0]), [0.5, 0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(project_simplex([-1.0, -1.0, -1.0, -1.0]), [0.25] * 4, atol=1e-15)
    # shifting by c·1 does not change the projection (used by raw-vs-centred training)
    v = rng.normal(size=(50, 4))
    np.testing.assert_allclose(project_simplex(v + 1000.0), project_simplex(v), atol=1e-12)


def test_compiled_projection_matches_numpy():
    rng = np.random.default_rng(1)
    V = rng.normal(0.0, 2.0, (300, 4))
    W = V.copy()
    s = np.empty(4)
    for j in range(W.shape[0]):
        _project_simplex_inplace(W, j, s)
    np.testing.assert_allclose(W, project_simplex(V), rtol=0, atol=1e-15)


def test_clip_renormalize_hand_examples():
    np.testing.assert_allclose(
        clip_renormalize([0.5, -0.2, 0.3]), [0.625, 0.0, 0.375], rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(clip_renormalize([2.0, 2.0]), [0.5, 0.5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        clip_renormalize([-1.0, -2.0, -3.0, -4.0]), [0.25] * 4, rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(clip_renormalize([0.0, 0.0]), [0.5, 0.5], rtol=0, atol=1e-15)
    out = clip_renormalize([[1.0, 3.0, -5.0], [-1.0, -1.0, -1.0]])
    np.testing.assert_allclose(out, [[0.25, 0.75, 0.0], [1 / 3, 1 / 3, 1 / 3]], rtol=0, atol=1e-15)
    # unlike the Euclidean projection, the seed rule is not shift-invariant
    assert not np.allclose(clip_renormalize([0.6, 0.3, 0.1]), clip_renormalize([1.6, 1.3, 1.1]))


# --------------------------------------------------------------------------- training


@pytest.mark.parametrize("step", ["lms", "nlms"])
@pytest.mark.parametrize("projection", ["simplex", "seed"])
def test_converges_to_optimal_fusion_weights(sigma_data, projection, step):
    """Spec §5.5: σ = (1, 2, 4, 8), 20 000 samples -> within 0.02 of (0.753, …, 0.012)."""
    U, t = sigma_data
    r = lms_train(U, t, projection=projection, step=step, rng=np.random.default_rng(5))
    assert isinstance(r, LmsResult)
    assert r.weights.shape == (1, 4)
    np.testing.assert_allclose(W_OPT, [0.753, 0.188, 0.047, 0.012], atol=5e-4)
    err = np.abs(r.weights[0] - W_OPT).max()
    assert err < 0.02, (r.weights, err)
    # the fused error variance is the optimal one, 1/Σσ⁻² = 0.753, up to sampling error
    assert abs(r.mse[0] - 1.0 / np.sum(SIGMA**-2)) < 0.03


@pytest.mark.parametrize("step", ["lms", "nlms"])
@pytest.mark.parametrize("projection", ["simplex", "seed"])
def test_constraints_hold_after_every_update(projection, step):
    """Spec §5.5: w >= 0 and |Σw − 1| < 1e-12 after every single update.

    The correlated case drives the middle weight against w >= 0 (its
    unconstrained optimum is −0.54), so the projection is active all the time.
    """
    U1, t1 = correlated_data(2)
    U2, t2 = fusion_data(3, sigma=[1.0, 2.0, 3.0], M=5_000)
    U, t = np.concatenate([U1, U2]), np.concatenate([t1, t2])
    r = lms_train(U, t, projection=projection, step=step, epochs=40, rng=np.random.default_rng(9))
    assert (r.min_weight >= 0.0).all()
    assert (r.max_sum_error < 1e-12).all()
    assert (r.min_weight <= r.weights.min(axis=1)).all()
    # the diagnostics did see the active constraint (a weight clipped to exactly 0)
    assert r.min_weight[0] == 0.0
    assert r.weights[0, 1] < 0.01


@pytest.mark.parametrize("projection", ["simplex", "seed"])
@pytest.mark.parametrize("biased", [0, 2])
def test_biased_input_is_down_weighted(projection, biased):
    """Spec §5.5: input 3 (σ_3 = 4, 1-based) with a constant bias 10 σ_3 gets w_3 < 0.05.

    Since Σw = 1, the residual is −(wᵀe + w_i b), so the optimum is the
    independent-error one with σ_i² replaced by σ_i² + b² = 101 σ_i².  The
    unbiased w_3 = 0.047 is already below 0.05, so the test also requires a
    tenfold drop, and repeats the case on input 1 (unbiased weight 0.753).
    """
    b = 10.0 * SIGMA[biased]
    U, t = fusion_data(21, bias={biased: b})
    r = lms_train(U, t, projection=projection, rng=np.random.default_rng(4))
    w = r.weights[0]
    assert w[biased] < 0.05
    assert w[biased] < 0.1 * W_OPT[biased]
    s2 = SIGMA**2
    s2[biased] += b**2
    w_pred = s2**-1 / np.sum(s2**-1)
    assert np.abs(w - w_pred).max() < 0.02, (w, w_pred)


def test_deterministic_for_a_seed():
    U, t = fusion_data(5, M=2_000)
    a = lms_train(U, t, epochs=30, rng=np.random.default_rng(123))
    b = lms_train(U, t, epochs=30, rng=np.random.default_rng(123))
    c = lms_train(U, t, epochs=30, rng=np.random.default_rng(124))
    assert np.array_equal(a.weights, b.weights)
    assert np.array_equal(a.mse, b.mse) and np.array_equal(a.min_weight, b.min_weight)
    assert not np.array_equal(a.weights, c.weights)
    assert np.abs(a.weights - c.weights).max() > 1e-8


@pytest.mark.parametrize("step", ["lms", "nlms"])
def test_batched_neurons_equal_single_neurons(step):
    """Neurons share the permutation but not the step: a batch equals its parts bit for bit."""
    parts = [
        fusion_data(6, M=1_500),
        fusion_data(7, sigma=[3.0, 1.0, 2.0, 0.5], M=1_500),
        fusion_data(8, bias={1: 15.0}, M=1_500),
    ]
    U = np.concatenate([p[0] for p in parts])
    t = np.concatenate([p[1] for p in parts])
    kw = dict(step=step, epochs=25, tol=0.0)
    batch = lms_train(U, t, rng=np.random.default_rng(77), **kw)
    assert batch.epochs_run == 25 and not batch.converged
    for j, (Uj, tj) in enumerate(parts):
        one = lms_train(Uj, tj, rng=np.random.default_rng(77), **kw)
        assert np.array_equal(one.weights[0], batch.weights[j])
        assert one.min_weight[0] == batch.min_weight[j]


@pytest.mark.parametrize("step", ["lms", "nlms"])
@pytest.mark.parametrize("projection", ["simplex", "seed"])
def test_centred_and_raw_training_agree(projection, step):
    """Spec §5.5: centred and raw training give the same weights when both converge.

    Noise-free samples ``t = w*ᵀu`` so that both runs converge (max|Δw| < tol).
    The raw inputs carry an offset of 1000 (10× their spread), so the
    trace-normalized step of the raw run is ~100× smaller; the constant step
    (``decay=False``) lets the raw run still converge in a few hundred epochs.
    """
    rng = np.random.default_rng(3)
    M, N = 60, 3
    Uc = rng.normal(0.0, 100.0, (M, N))
    Uc -= Uc.mean(axis=1, keepdims=True)
    w_true = np.array([0.6, 0.3, 0.1])
    tc = Uc @ w_true
    kw = dict(projection=projection, step=step, mu=0.5, decay=False, epochs=5_000, tol=1e-10)
    cen = lms_train(Uc[None], tc[None], rng=np.random.default_rng(1), **kw)
    raw = lms_train((Uc + 1000.0)[None], (tc + 1000.0)[None], rng=np.random.default_rng(1), **kw)
    assert cen.converged and raw.converged
    assert cen.epochs_run < 20 < raw.epochs_run  # raw training is far slower
    assert np.abs(cen.weights[0] - raw.weights[0]).max() < 1e-6
    assert np.abs(cen.weights[0] - w_true).max() < 1e-6


def test_epochs_and_w0():
    U, t = fusion_data(9, M=500)
    r = lms_train(U, t, epochs=7, tol=0.0, rng=np.random.default_rng(0))
    assert r.epochs_run == 7 and r.converged is False
    # w0 on (N,) and on (J, N) give the same run; the default is 1/N (spec §5.3)
    a = lms_train(U, t, epochs=3, w0=np.full(4, 0.25), rng=np.random.default_rng(0))
    b = lms_train(U, t, epochs=3, w0=np.full((1, 4), 0.25), rng=np.random.default_rng(0))
    c = lms_train(U, t, epochs=3, rng=np.random.default_rng(0))
    assert np.array_equal(a.weights, b.weights) and np.array_equal(a.weights, c.weights)
    d = lms_train(U, t, epochs=3, w0=[1.0, 0.0, 0.0, 0.0], rng=np.random.default_rng(0))
    assert not np.array_equal(a.weights, d.weights)


_U, _t = np.zeros((2, 10, 3)) + np.arange(3.0), np.zeros((2, 10))


@pytest.mark.parametrize(
    "args, kwargs, field",
    [
        ((np.zeros((10, 3)), _t), {}, "U"),
        ((np.zeros((2, 3, 3)), np.zeros((2, 3))), {}, "U"),  # M <= N
        ((np.zeros((2, 10, 3)), _t), {}, "U"),  # tr R = 0 for step "lms"
        ((np.where(_U == 1.0, np.nan, _U), _t), {}, "U"),
        ((_U, np.zeros((2, 9))), {}, "t"),
        ((_U, np.full((2, 10), np.inf)), {}, "t"),
        ((_U, _t), dict(projection="clip"), "projection"),
        ((_U, _t), dict(step="rls"), "step"),
        ((_U, _t), dict(mu=0.0), "mu"),
        ((_U, _t), dict(mu=-0.1), "mu"),
        ((_U, _t), dict(mu=2.0), "mu"),
        ((_U, _t), dict(mu="fast"), "mu"),
        ((_U, _t), dict(epochs=0), "epochs"),
        ((_U, _t), dict(epochs=2.5), "epochs"),
        ((_U, _t), dict(tol=-1e-6), "tol"),
        ((_U, _t), dict(tol=np.nan), "tol"),
        ((_U, _t), dict(decay="yes"), "decay"),
        ((_U, _t), dict(w0=np.full(4, 0.25)), "w0"),
        ((_U, _t), dict(w0=[0.5, 0.6, -0.1]), "w0"),
        ((_U, _t), dict(w0=[0.5, 0.6, 0.1]), "w0"),
    ],
)
def test_bad_arguments_raise(args, kwargs, field):
    with pytest.raises(ValueError, match=rf"^{field}:"):
        lms_train(*args, rng=np.random.default_rng(0), **kwargs)


def test_bad_rng_and_projection_inputs_raise():
    with pytest.raises(ValueError, match=r"^rng:"):
        lms_train(_U, _t, rng=np.random.RandomState(0))
    with pytest.raises(ValueError, match=r"^w:"):
        project_simplex(np.array([1.0, np.nan]))
    with pytest.raises(ValueError, match=r"^w:"):
        clip_renormalize(np.float64(1.0))
