"""Spec §4.1 features and the §4.2 decision rule, by hand."""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.fdi.chi2 import apply_hysteresis
from ftnav.fdi.features import detector_features, feature_names, whitened_innovation
from ftnav.fdi.rbf import RBFDetector, RBFModel, RBFNetwork
from ftnav.fusion.locals import residual_statistic


def test_whitened_innovation_squared_norm_is_the_nis():
    rng = np.random.default_rng(3)
    B, n, m = 5, 4, 2
    x = rng.standard_normal((B, n))
    A = rng.standard_normal((B, n, n))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(n)
    H = rng.standard_normal((m, n))
    R = np.array([[2.0, 0.3], [0.3, 1.0]])
    z = rng.standard_normal((B, m))
    use = np.array([True, True, False, True, True])
    w = whitened_innovation(x, P, z, use, H, R)
    np.testing.assert_allclose((w**2).sum(-1), residual_statistic(x, P, z, use, H, R), rtol=1e-12)
    assert np.all(w[2] == 0.0)
    # whitening: L w = nu with L the Cholesky factor of H P Hᵀ + R
    L = np.linalg.cholesky(H @ P[0] @ H.T + R)
    np.testing.assert_allclose(L @ w[0], z[0] - H @ x[0], rtol=1e-12)


def test_feature_layout_and_names():
    local_x = np.array([[[1.0, 2.0], [3.0, 4.0]]])  # (B=1, N=2, nc=2)
    var = np.array([[[4.0, 1.0], [1.0, 16.0]]])
    ref = np.array([[0.0, 2.0]])
    nu = [np.array([[0.5]]), np.array([[-1.0, 2.0]])]
    f = detector_features(("state-difference", "innovation"), local_x, var, ref, nu)
    np.testing.assert_allclose(f, [[0.5, 0.0, 3.0, 0.5, 0.5, -1.0, 2.0]])
    names = feature_names(("state-difference", "innovation"), ("s", "v"), ("a", "b"), (1, 2))
    assert names == ["e[a].s", "e[a].v", "e[b].s", "e[b].v", "nu[a][0]", "nu[b][0]", "nu[b][1]"]
    with pytest.raises(ValueError, match="^features:"):
        feature_names(("bogus",), ("s",), ("a",), (1,))


def test_hysteresis_counts():
    class S:  # the three fields apply_hysteresis reads
        on_count = np.zeros((1, 1), int)
        off_count = np.zeros((1, 1), int)
        flag = np.zeros((1, 1), bool)

    raw_seq = [1, 1, 0, 1, 0, 0, 0, 1]
    tested = np.ones((1, 1), bool)
    flags = []
    s = S()
    for r in raw_seq:
        on, off, flag = apply_hysteresis(s, np.full((1, 1), bool(r)), tested, 2, 3)
        s.on_count, s.off_count, s.flag = on, off, flag
        flags.append(bool(flag[0, 0]))
    # set after 2 alarms in a row, cleared after 3 passes in a row
    assert flags == [False, True, True, True, True, True, False, False]


def test_detector_thresholds_network_outputs_per_output():
    rng = np.random.default_rng(0)
    X = rng.standard_normal((400, 2))
    Y = np.stack([X[:, 0] > 1.0, X[:, 1] > 1.0], 1).astype(float)
    net = RBFNetwork(n_centres=10, n_init=2, random_state=0).fit(X, Y)
    model = RBFModel(net, ("innovation",), "global", np.array([0.3, 0.7]), 1, 1, {}, {})
    det = RBFDetector(model)
    state = det.init(400, 2)
    tested = np.ones((400, 2), bool)
    tested[0] = False
    state, out = det.step(state, X, tested)
    y = net.decision_function(X)
    np.testing.assert_array_equal(out.raw[1:], (y > [0.3, 0.7])[1:])
    assert not out.raw[0].any() and np.all(out.statistic[0] == 0.0)
    np.testing.assert_array_equal(out.flag, out.raw)  # n_on = 1
    override = RBFDetector(model, threshold=0.5)
    _, out2 = override.step(override.init(400, 2), X, np.ones((400, 2), bool))
    np.testing.assert_array_equal(out2.raw, y > 0.5)
    with pytest.raises(ValueError, match="^model: trained for 2 local filters"):
        det.init(4, 3)


def test_whitened_innovation_with_one_h_per_run_is_each_runs_own():
    """A linearized (integrated) system has H (B, m, n): each run is whitened with its own."""
    rng = np.random.default_rng(5)
    B, n, m = 3, 4, 2
    x = rng.standard_normal((B, n))
    A = rng.standard_normal((B, n, n))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(n)
    H = rng.standard_normal((B, m, n))
    R = np.diag([0.5, 2.0])
    z = rng.standard_normal((B, m))
    use = np.array([True, False, True])
    w = whitened_innovation(x, P, z, use, H, R)
    for b in range(B):
        one = whitened_innovation(x[b : b + 1], P[b : b + 1], z[b : b + 1], use[b : b + 1], H[b], R)
        np.testing.assert_allclose(w[b], one[0], rtol=1e-12, atol=1e-15)
    assert np.all(w[1] == 0.0)
