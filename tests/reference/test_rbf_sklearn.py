"""The RBF network (spec §4.2) against scikit-learn, piece by piece.

Centres are scikit-learn's k-means on the same (balanced) subsample, the hidden
layer equals ``sklearn.metrics.pairwise.rbf_kernel`` with ``γ = 1/(2σ²)`` and
the output layer equals ``sklearn.linear_model.Ridge`` (no intercept, the bias
column penalised like the others) on the design matrix ``[h(x); 1]``.
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import KMeans
from sklearn.linear_model import Ridge
from sklearn.metrics.pairwise import rbf_kernel

from ftnav.fdi.rbf import RBFNetwork


@pytest.fixture(scope="module")
def data():
    rng = np.random.default_rng(7)
    K, F = 3000, 4
    X = rng.standard_normal((K, F))
    Y = np.zeros((K, 2))
    X[:300, 0] += 6.0  # output 0 faulty: shifted cluster
    Y[:300, 0] = 1.0
    X[300:500, 2] -= 5.0
    Y[300:500, 1] = 1.0
    return X, Y


@pytest.mark.parametrize("transform", ["none", "signed-log"])
def test_pieces_match_sklearn(data, transform):
    X, Y = data
    net = RBFNetwork(
        n_centres=12, n_init=3, transform=transform, kmeans_samples=1000, random_state=3
    ).fit(X, Y)
    Xt = np.sign(X) * np.log1p(np.abs(X)) if transform == "signed-log" else X
    Xn = (Xt - Xt.mean(0)) / Xt.std(0)
    np.testing.assert_allclose(net.mean_, Xt.mean(0), rtol=1e-12)
    sub = net._kmeans_subsample(Xn, Y.any(1))
    assert sub.shape == (1000, 4)  # half faulty, half healthy
    km = KMeans(n_clusters=12, init="k-means++", n_init=3, random_state=3).fit(sub)
    np.testing.assert_allclose(net.centres_, km.cluster_centers_, atol=1e-12)
    d = np.linalg.norm(km.cluster_centers_[:, None] - km.cluster_centers_[None], axis=-1)
    sigma = d.max() / np.sqrt(2 * 12)  # Haykin's global width
    np.testing.assert_allclose(net.widths_, sigma, rtol=1e-12)
    H = rbf_kernel(Xn, km.cluster_centers_, gamma=1.0 / (2 * sigma**2))
    np.testing.assert_allclose(net.hidden(X), H, atol=1e-12)
    A = np.hstack([H, np.ones((len(X), 1))])
    ridge = Ridge(alpha=1e-6, fit_intercept=False, solver="cholesky").fit(A, Y)
    np.testing.assert_allclose(net.weights_, ridge.coef_.T, atol=1e-7)
    np.testing.assert_allclose(net.decision_function(X), A @ ridge.coef_.T, atol=1e-7)


def test_nearest_width_rule(data):
    X, Y = data
    net = RBFNetwork(n_centres=10, width="nearest", n_init=2, random_state=0).fit(X, Y)
    c = net.centres_
    d = np.linalg.norm(c[:, None] - c[None], axis=-1)
    np.fill_diagonal(d, np.inf)
    np.testing.assert_allclose(net.widths_, np.sort(d, 1)[:, :2].mean(1), rtol=1e-12)


def test_class_weights_are_weighted_ridge(data):
    """``class_weight="auto"`` (faulty < 10 %) equals sklearn's Ridge with sample weights."""
    X, Y = data
    net = RBFNetwork(n_centres=8, n_init=2, class_weight="auto", random_state=0).fit(X, Y)
    A = np.hstack([net.hidden(X), np.ones((len(X), 1))])
    y = Y[:, 1]  # 200 / 3000 faulty
    w = np.where(y > 0.5, len(y) / (2 * y.sum()), len(y) / (2 * (len(y) - y.sum())))
    ridge = Ridge(alpha=1e-6, fit_intercept=False, solver="cholesky").fit(A, y, sample_weight=w)
    np.testing.assert_allclose(net.weights_[:, 1], ridge.coef_, atol=1e-7)


def test_shifted_clusters_rank_first(data):
    """Faulty samples (a 5-6σ shift) score above healthy ones: ROC AUC (sklearn) >= 0.98."""
    from sklearn.metrics import roc_auc_score

    X, Y = data
    y = RBFNetwork(n_centres=20, n_init=3, random_state=1).fit(X, Y).decision_function(X)
    assert min(roc_auc_score(Y[:, j], y[:, j]) for j in range(2)) >= 0.98


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"n_centres": 1}, "n_centres"),
        ({"width": "wide"}, "width"),
        ({"ridge": 0.0}, "ridge"),
        ({"n_init": 0}, "n_init"),
        ({"class_weight": "x"}, "class_weight"),
        ({"transform": "log"}, "transform"),
        ({"kmeans_samples": 5}, "kmeans_samples"),
    ],
)
def test_bad_hyper_parameters(data, kw, field):
    X, Y = data
    with pytest.raises(ValueError, match=f"^{field}:"):
        RBFNetwork(**kw).fit(X, Y)


def test_bad_inputs(data):
    X, Y = data
    with pytest.raises(ValueError, match="^X, Y:"):
        RBFNetwork().fit(X, Y[:10])
    Xbad = X.copy()
    Xbad[0, 0] = np.nan
    with pytest.raises(ValueError, match="^X: features must be finite"):
        RBFNetwork().fit(Xbad, Y)
    net = RBFNetwork(n_centres=5, n_init=1, random_state=0).fit(X, Y)
    with pytest.raises(ValueError, match=r"^X: expected \(K, 4\)"):
        net.decision_function(X[:, :3])
