"""RBF-network fault detector of paper 000 (spec §4).

The network (spec §4.2) maps a z-scored feature vector ``x`` (spec §4.1,
:mod:`ftnav.fdi.features`) to one output per local filter,

    h_j(x) = exp(−‖x − c_j‖² / (2 σ_j²)),   y = Wᵀ [h(x); 1],

with centres ``c_j`` from k-means (k-means++ initialisation, ``n_init``
restarts, scikit-learn), widths by Haykin's global rule ``σ = d_max/√(2M)`` or
per centre (mean distance to the 2 nearest centres), and the output layer by
ridge least squares ``W = (AᵀDA + ρI)⁻¹ AᵀDT`` (``D`` = class weights when
faulty epochs are rare).  :class:`RBFNetwork` follows the scikit-learn
estimator contract (``fit``/``predict``/``decision_function``, hyper-parameters
stored verbatim, learned attributes end in ``_``, ``random_state``).

:class:`RBFDetector` turns the outputs into the spec §3.4 detector contract:
raw flag ``y_i > τ``, hysteresis ``n_on``/``n_off``, fault factor
``r_i = 1 − flag``, so it plugs in wherever a chi-square detector does.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ftnav.fdi.chi2 import DetectorOutput, DetectorState, apply_hysteresis

__all__ = ["KMEANS_SAMPLES", "MODEL_KIND", "RBFDetector", "RBFModel", "RBFNetwork"]

#: ``kind`` of an RBF detector model file (:mod:`ftnav.io.learned`).
MODEL_KIND = "rbf-detector"

_WIDTHS = ("global", "nearest")


#: training samples k-means reads at most (a random subset of a larger set)
KMEANS_SAMPLES = 20000


class RBFNetwork:
    """Gaussian RBF network with k-means centres and a ridge output layer (spec §4.2).

    Parameters
    ----------
    n_centres : int
        Hidden units M (spec default 60, range 20-100).
    width : {"global", "nearest"}
        ``"global"``: one σ = d_max/√(2M) (Haykin); ``"nearest"``: σ_j = mean
        distance from c_j to its 2 nearest centres.
    ridge : float
        ρ of the ridge least squares (spec default 1e-6).
    n_init : int
        k-means restarts; the lowest inertia is kept (spec: >= 10).
    class_weight : {"none", "auto"}
        ``"auto"`` balances faulty and healthy epochs per output when faulty
        epochs are under 10 % of the samples (spec §4.2).  The default is
        ``"none"``: on seed000 the balanced fit raised held-out false alarms from
        0.1 % to 4-14 % per epoch (see ``docs/architecture.md``).
    kmeans_samples : int
        k-means runs on at most this many samples drawn at random (the centres
        of 10⁵ near-duplicate epochs need not see every one); the output layer
        is fitted on all samples.
    transform : {"signed-log", "none"}
        Applied to each raw feature before the z-score: ``sign(x)·log(1 + |x|)``
        compresses the large whitened values of big faults, so fault sizes
        beyond the training range still land near trained centres instead of
        where every Gaussian unit is ~0 (an RBF network does not extrapolate).
    balance : bool
        k-means sees as many faulty epochs (any target 1) as healthy ones, so
        centres cover the fault regions too (class-balanced clustering).
    random_state : int or None
        Seed of the k-means initialisation and subsample; training is
        deterministic for it.

    Attributes
    ----------
    mean_, scale_ : (F,) z-score of the features (training statistics).
    centres_ : (M, F) centres in z-scored units.   widths_ : (M,) σ_j.
    weights_ : (M + 1, N) output layer, last row the bias.
    """

    def __init__(
        self,
        n_centres: int = 60,
        width: str = "global",
        ridge: float = 1e-6,
        n_init: int = 10,
        class_weight: str = "none",
        kmeans_samples: int = KMEANS_SAMPLES,
        transform: str = "signed-log",
        balance: bool = True,
        random_state: int | None = None,
    ):
        self.n_centres = n_centres
        self.width = width
        self.ridge = ridge
        self.n_init = n_init
        self.class_weight = class_weight
        self.kmeans_samples = kmeans_samples
        self.transform = transform
        self.balance = balance
        self.random_state = random_state

    # -- training ------------------------------------------------------------------
    def _check_params(self) -> None:
        if int(self.n_centres) < 2:
            raise ValueError(f"n_centres: must be >= 2, got {self.n_centres}")
        if self.width not in _WIDTHS:
            raise ValueError(f"width: expected one of {list(_WIDTHS)}, got {self.width!r}")
        if not self.ridge > 0:
            raise ValueError(f"ridge: must be > 0, got {self.ridge}")
        if int(self.n_init) < 1:
            raise ValueError(f"n_init: must be >= 1, got {self.n_init}")
        if int(self.kmeans_samples) < int(self.n_centres):
            raise ValueError(f"kmeans_samples: must be >= n_centres, got {self.kmeans_samples}")
        if self.transform not in ("signed-log", "none"):
            raise ValueError(f"transform: expected 'signed-log' or 'none', got {self.transform!r}")
        if self.class_weight not in ("auto", "none"):
            raise ValueError(f"class_weight: expected 'auto' or 'none', got {self.class_weight!r}")

    def fit(self, X: np.ndarray, Y: np.ndarray) -> RBFNetwork:
        """Fit centres, widths and output weights.

        Parameters
        ----------
        X : (K, F) raw features.   Y : (K, N) targets in {0, 1} (1 = faulty).
        """
        from sklearn.cluster import KMeans
        from threadpoolctl import threadpool_limits

        self._check_params()
        X = np.asarray(X, dtype=float)
        Y = np.asarray(Y, dtype=float)
        if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
            raise ValueError(
                f"X, Y: expected (K, F) and (K, N) with the same K, got {X.shape} and {Y.shape}"
            )
        if not np.isfinite(X).all():
            raise ValueError("X: features must be finite")
        M = int(self.n_centres)
        if X.shape[0] < M:
            raise ValueError(f"X: {X.shape[0]} samples are fewer than n_centres = {M}")
        Xt = self._transform(X)
        self.mean_ = Xt.mean(0)
        self.scale_ = np.where(Xt.std(0) > 0, Xt.std(0), 1.0)
        Xn = (Xt - self.mean_) / self.scale_
        sub = self._kmeans_subsample(Xn, Y.any(1))
        # one OpenMP thread: scikit-learn's threads fight numba's for the same cores
        # (11 s instead of 0.2 s on a busy 2-core machine), and one thread is deterministic
        with threadpool_limits(1, user_api="openmp"):
            km = KMeans(
                n_clusters=M,
                init="k-means++",
                n_init=int(self.n_init),
                random_state=self.random_state,
            ).fit(sub)
        self.centres_ = km.cluster_centers_
        self.inertia_ = float(km.inertia_)
        d = np.sqrt(((self.centres_[:, None, :] - self.centres_[None, :, :]) ** 2).sum(-1))
        if self.width == "global":
            self.widths_ = np.full(M, max(d.max(), 1e-12) / np.sqrt(2.0 * M))
        else:
            nearest = np.sort(d + np.diag(np.full(M, np.inf)), axis=1)[:, :2]
            self.widths_ = np.maximum(nearest.mean(1), 1e-12)
        A = self._design(Xn)
        self.weights_ = np.empty((M + 1, Y.shape[1]))
        for j in range(Y.shape[1]):
            D = self._sample_weights(Y[:, j])
            G = A.T @ (A * D[:, None]) + self.ridge * np.eye(M + 1)
            self.weights_[:, j] = np.linalg.solve(G, A.T @ (D * Y[:, j]))
        self.n_features_in_ = X.shape[1]
        self.n_outputs_ = Y.shape[1]
        return self

    def _kmeans_subsample(self, Xn: np.ndarray, faulty: np.ndarray) -> np.ndarray:
        """Samples k-means sees: at most ``kmeans_samples``, half faulty when ``balance``.

        Faulty epochs are a few per cent of the data; unbalanced k-means puts
        nearly every centre in the healthy cloud, and far from every centre the
        network's output falls back to its bias.
        """
        rng = np.random.default_rng(self.random_state)
        cap = int(self.kmeans_samples)
        if not self.balance or faulty.all() or not faulty.any():
            if Xn.shape[0] <= cap:
                return Xn
            return Xn[np.sort(rng.choice(Xn.shape[0], cap, replace=False))]
        idx = []
        for group in (np.flatnonzero(faulty), np.flatnonzero(~faulty)):
            n = min(cap // 2, group.size)
            idx.append(np.sort(rng.choice(group, n, replace=False)))
        return Xn[np.concatenate(idx)]

    def _sample_weights(self, y: np.ndarray) -> np.ndarray:
        pos = float(y.sum())
        K = y.size
        if self.class_weight == "none" or pos == 0 or pos == K or pos >= 0.1 * K:
            return np.ones(K)
        return np.where(y > 0.5, K / (2.0 * pos), K / (2.0 * (K - pos)))

    def _design(self, Xn: np.ndarray) -> np.ndarray:
        """``A = [h(x); 1]``, (K, M + 1)."""
        from sklearn.metrics.pairwise import euclidean_distances

        d2 = euclidean_distances(Xn, self.centres_, squared=True)
        H = np.exp(-d2 / (2.0 * self.widths_**2))
        return np.concatenate([H, np.ones((Xn.shape[0], 1))], axis=1)

    # -- inference -----------------------------------------------------------------
    def hidden(self, X: np.ndarray) -> np.ndarray:
        """Hidden-layer outputs ``h(x)`` of raw features X (K, F) -> (K, M)."""
        return self._design(self._normalise(X))[:, :-1]

    def _normalise(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != self.n_features_in_:
            raise ValueError(f"X: expected (K, {self.n_features_in_}) features, got {X.shape}")
        return (self._transform(X) - self.mean_) / self.scale_

    def _transform(self, X: np.ndarray) -> np.ndarray:
        return np.sign(X) * np.log1p(np.abs(X)) if self.transform == "signed-log" else X

    def decision_function(self, X: np.ndarray) -> np.ndarray:
        """Network outputs ``y`` (K, N); ~0 healthy, ~1 faulty."""
        return self._design(self._normalise(X)) @ self.weights_

    def predict(self, X: np.ndarray, threshold: float = 0.5) -> np.ndarray:
        """Raw fault decisions ``y > τ`` (K, N) bool (spec §4.2)."""
        return self.decision_function(X) > threshold

    # -- arrays for the model file ----------------------------------------------------
    def to_arrays(self) -> dict[str, np.ndarray]:
        return {
            "mean": self.mean_,
            "scale": self.scale_,
            "centres": self.centres_,
            "widths": self.widths_,
            "weights": self.weights_,
        }

    def get_params(self) -> dict:
        return {
            "n_centres": int(self.n_centres),
            "width": self.width,
            "ridge": float(self.ridge),
            "n_init": int(self.n_init),
            "class_weight": self.class_weight,
            "kmeans_samples": int(self.kmeans_samples),
            "transform": self.transform,
            "balance": bool(self.balance),
            "random_state": self.random_state,
        }

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray], params: Mapping) -> RBFNetwork:
        """Rebuild a fitted network (shapes checked)."""
        net = cls(**params)
        c, w, W = arrays["centres"], arrays["widths"], arrays["weights"]
        M, F = c.shape
        if (
            arrays["mean"].shape != (F,)
            or arrays["scale"].shape != (F,)
            or w.shape != (M,)
            or W.shape[0] != M + 1
            or M != int(net.n_centres)
        ):
            raise ValueError("arrays: inconsistent RBF network shapes")
        if not (w > 0).all() or not (arrays["scale"] > 0).all():
            raise ValueError("arrays: widths and feature scales must be positive")
        net.mean_, net.scale_ = np.array(arrays["mean"]), np.array(arrays["scale"])
        net.centres_, net.widths_, net.weights_ = np.array(c), np.array(w), np.array(W)
        net.n_features_in_, net.n_outputs_ = F, W.shape[1]
        return net


@dataclass(frozen=True)
class RBFModel:
    """A trained detector: the network, its feature definition and decision rule.

    Attributes
    ----------
    network : fitted :class:`RBFNetwork`.
    features : feature kinds (spec §4.1) in stacking order.
    prior : prior the innovations are whitened against (``"local"``/``"global"``).
    threshold : (N,) decision threshold τ_i per output.   n_on, n_off : default hysteresis.
    compatibility : what a scenario must match to use the model (states,
        sensors, measurement sizes, system hash).
    training : provenance and held-out metrics (free-form, JSON).
    """

    network: RBFNetwork
    features: tuple[str, ...]
    prior: str
    threshold: np.ndarray
    n_on: int
    n_off: int
    compatibility: dict
    training: dict


class RBFDetector:
    """Threshold and hysteresis on the network outputs (spec §4.2 decision, §3.4).

    Parameters
    ----------
    model : trained :class:`RBFModel`.
    threshold, n_on, n_off : override the model's defaults when given.
    """

    def __init__(
        self,
        model: RBFModel,
        threshold: float | None = None,
        n_on: int | None = None,
        n_off: int | None = None,
    ):
        self.model = model
        self.threshold = np.asarray(model.threshold if threshold is None else float(threshold))
        self.n_on = model.n_on if n_on is None else int(n_on)
        self.n_off = model.n_off if n_off is None else int(n_off)

    @property
    def features(self) -> tuple[str, ...]:
        return self.model.features

    def init(self, batch: int, n_filters: int) -> DetectorState:
        shape = (batch, n_filters)
        if n_filters != self.model.network.n_outputs_:
            raise ValueError(
                f"model: trained for {self.model.network.n_outputs_} local "
                f"filters, this system has {n_filters}"
            )
        return DetectorState(
            np.zeros(shape + (0,)),
            np.zeros(shape + (0,), dtype=int),
            np.zeros(shape, dtype=int),
            np.zeros(shape, dtype=int),
            np.zeros(shape, dtype=bool),
        )

    def step(
        self, state: DetectorState, features: np.ndarray, tested: np.ndarray
    ) -> tuple[DetectorState, DetectorOutput]:
        """One epoch: features (B, F), tested (B, N) -> new state and spec §3.4 output."""
        y = self.model.network.decision_function(features)
        raw = tested & (y > self.threshold)
        on, off, flag = apply_hysteresis(state, raw, tested, self.n_on, self.n_off)
        return (
            DetectorState(state.history, state.history_dof, on, off, flag),
            DetectorOutput(
                np.where(tested, y, 0.0), np.broadcast_to(self.threshold, y.shape), raw, flag
            ),
        )
