"""Discretization of continuous linear-Gaussian models ``ẋ = F x + G w`` (spec §8.4).

Every function is pure and batched: ``F`` and ``GQGt`` are ``(..., n, n)`` with
leading batch axes that broadcast against each other, so one call discretizes the
models of B Monte Carlo runs at once.  Nothing here imports from the rest of ftnav
outside :mod:`ftnav.core`.

Notation: ``F`` continuous system matrix (1/s), ``GQGt = G q Gᵀ`` the continuous
process-noise spectral density mapped into the state (state units² per second),
``T`` step (s), ``Phi = e^{F T}`` the transition matrix and
``Q_k = ∫₀ᵀ e^{F s} G q Gᵀ e^{Fᵀ s} ds`` the discrete process-noise covariance.
"""

from __future__ import annotations

from math import factorial

import numba
import numpy as np
from scipy.linalg import expm

from ftnav.core.kalman import mT, symmetrize
from ftnav.types import Array, ArrayLike, BatchMatrix, BatchScalar, Matrix

__all__ = ["van_loan", "series", "series_reference", "series_row", "markov_discrete"]


def _check(
    F: ArrayLike, GQGt: ArrayLike, T: ArrayLike
) -> tuple[BatchMatrix, BatchMatrix, Array, tuple[int, ...]]:
    F = np.asarray(F, dtype=float)
    GQGt = np.asarray(GQGt, dtype=float)
    if F.ndim < 2 or F.shape[-1] != F.shape[-2]:
        raise ValueError(f"F must be (..., n, n), got shape {F.shape}")
    if GQGt.shape[-2:] != F.shape[-2:]:
        raise ValueError(
            f"GQGt must be (..., {F.shape[-1]}, {F.shape[-1]}), got shape {GQGt.shape}"
        )
    batch = np.broadcast_shapes(F.shape[:-2], GQGt.shape[:-2])
    T = np.asarray(T, dtype=float)
    if not np.all(np.isfinite(T)) or np.any(T <= 0.0):
        raise ValueError("T must be positive and finite")
    batch = np.broadcast_shapes(batch, T.shape)
    return F, GQGt, T[..., None, None], batch


def van_loan(F: BatchMatrix, GQGt: BatchMatrix, T: ArrayLike) -> tuple[BatchMatrix, BatchMatrix]:
    """Exact discretization by Van Loan's matrix exponential (spec §8.4).

    ``B = expm([[−F, G q Gᵀ], [0, Fᵀ]] T)``, ``Φ = B₂₂ᵀ``, ``Q_k = Φ B₁₂`` (symmetrized).
    Source: C. F. Van Loan, "Computing integrals involving the matrix exponential",
    IEEE TAC 23(3):395-404, 1978.

    Parameters
    ----------
    F : (..., n, n) continuous system matrix.
    GQGt : (..., n, n) mapped noise spectral density ``G q Gᵀ``.
    T : float or (...) array, step in seconds (> 0).

    Returns
    -------
    Phi : (..., n, n) transition matrix.
    Q : (..., n, n) discrete process-noise covariance.
    """
    F, GQGt, T, batch = _check(F, GQGt, T)
    n = F.shape[-1]
    A = np.zeros(batch + (2 * n, 2 * n))
    A[..., :n, :n] = -F * T
    A[..., :n, n:] = GQGt * T
    A[..., n:, n:] = mT(F) * T
    B = expm(A)  # scipy's expm works on stacks of matrices: no loop over the batch
    Phi = mT(B[..., n:, n:])
    return Phi, symmetrize(Phi @ B[..., :n, n:])


def series(
    F: BatchMatrix, GQGt: BatchMatrix, T: ArrayLike, order: int = 5
) -> tuple[BatchMatrix, BatchMatrix]:
    """Truncated-series discretization (spec §8.4; PSINS ``kfc2d``).

    ``Φ = Σ_{j=0}^{order} (F T)^j / j!`` and ``Q_k = Σ_{j=1}^{order} M_j T^j / j!`` with
    ``M_1 = G q Gᵀ`` and ``M_{j+1} = F M_j + (F M_j)ᵀ`` (symmetrized).  Order 5 at
    T = 1 s matches Van Loan to Φ < 1e-10 and Q < 1e-4 relative on the 18-state
    SINS model (spec §8.6 f); ``order=1`` gives ``Φ = I + F T``, ``Q = G q Gᵀ T``.
    One compiled loop over the batch; :func:`series_reference` is the plain NumPy
    form (its test oracle).

    Parameters
    ----------
    F : (..., n, n) continuous system matrix.
    GQGt : (..., n, n) mapped noise spectral density ``G q Gᵀ``.
    T : float or (...) array, step in seconds (> 0).
    order : int ≥ 1, highest power of T kept.

    Returns
    -------
    Phi : (..., n, n) transition matrix.
    Q : (..., n, n) discrete process-noise covariance.
    """
    F, GQGt, T, batch = _check(F, GQGt, T)
    if int(order) != order or order < 1:
        raise ValueError(f"order must be an integer ≥ 1, got {order}")
    n = F.shape[-1]
    Ff = np.ascontiguousarray(np.broadcast_to(F, batch + (n, n))).reshape(-1, n, n)
    Gf = np.ascontiguousarray(np.broadcast_to(GQGt, batch + (n, n))).reshape(-1, n, n)
    Tf = np.ascontiguousarray(np.broadcast_to(T[..., 0, 0], batch)).reshape(-1)
    Phi, Q = np.empty_like(Ff), np.empty_like(Ff)
    _series_rows(Ff, Gf, Tf, int(order), Phi, Q)
    return Phi.reshape(batch + (n, n)), Q.reshape(batch + (n, n))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def series_row(
    F: Matrix,
    GQGt: Matrix,
    T: float,
    order: int,
    Phi: Matrix,
    Q: Matrix,
    X: Matrix,
    nxt: Matrix,
    Mj: Matrix,
    FM: Matrix,
) -> None:  # pragma: no cover - compiled
    """:func:`series` of one model (n, n) into ``Phi``, ``Q``; X … FM are (n, n) scratch.

    ``Φ`` by Horner, ``X ← I + (F T / j) X`` for j = order … 1, so every product has
    the sparse F on the left (its zeros are skipped); the same sum as the series.
    """
    n = F.shape[0]
    for i in range(n):
        for j in range(n):
            X[i, j] = 1.0 if i == j else 0.0
            Mj[i, j] = GQGt[i, j]
            Q[i, j] = GQGt[i, j] * T
    for k in range(order, 0, -1):  # X ← I + (F T / k) X
        for i in range(n):
            for j in range(n):
                nxt[i, j] = 1.0 if i == j else 0.0
            for p in range(n):
                a = F[i, p]
                if a != 0.0:
                    a *= T / k
                    for j in range(n):
                        nxt[i, j] += a * X[p, j]
        X[:, :] = nxt
    Phi[:, :] = X
    coef = T
    for k in range(2, order + 1):  # M ← F M + (F M)ᵀ, Q += M T^k / k!
        coef *= T / k
        FM[:, :] = 0.0
        for i in range(n):
            for p in range(n):
                a = F[i, p]
                if a != 0.0:
                    for j in range(n):
                        FM[i, j] += a * Mj[p, j]
        for i in range(n):
            for j in range(n):
                Mj[i, j] = FM[i, j] + FM[j, i]
                Q[i, j] += Mj[i, j] * coef
    for i in range(n):  # symmetrize
        for j in range(i):
            v = 0.5 * (Q[i, j] + Q[j, i])
            Q[i, j] = v
            Q[j, i] = v


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _series_rows(
    F: BatchMatrix, GQGt: BatchMatrix, T: BatchScalar, order: int, Phi: BatchMatrix, Q: BatchMatrix
) -> None:  # pragma: no cover - compiled
    n = F.shape[1]
    X, nxt, Mj, FM = np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    for b in range(F.shape[0]):
        series_row(F[b], GQGt[b], T[b], order, Phi[b], Q[b], X, nxt, Mj, FM)


def series_reference(
    F: BatchMatrix, GQGt: BatchMatrix, T: ArrayLike, order: int = 5
) -> tuple[BatchMatrix, BatchMatrix]:
    """Plain NumPy form of :func:`series` (the compiled kernel's test oracle)."""
    F, GQGt, T, batch = _check(F, GQGt, T)
    if int(order) != order or order < 1:
        raise ValueError(f"order must be an integer ≥ 1, got {order}")
    n = F.shape[-1]
    FT = F * T
    term = np.broadcast_to(np.eye(n), batch + (n, n))
    Phi = term.copy()
    M = np.broadcast_to(GQGt, batch + (n, n))
    Q = M * T
    for j in range(1, int(order) + 1):
        term = term @ FT / j
        Phi = Phi + term
        if j >= 2:
            FM = F @ M
            M = FM + mT(FM)
            Q = Q + M * (T**j / factorial(j))
    return Phi, symmetrize(Q)


def markov_discrete(sigma: ArrayLike, tau: ArrayLike, T: ArrayLike) -> tuple[Array, Array]:
    """First-order Gauss-Markov process sampled every T (spec §8.4).

    ``b_{k+1} = a b_k + w_k`` with ``a = e^{−T/τ}`` and
    ``var(w_k) = σ² (1 − e^{−2T/τ})``, so the stationary variance stays ``σ²``.

    Parameters
    ----------
    sigma : array_like, stationary standard deviation σ (any unit).
    tau : array_like, correlation time τ (s, > 0; ``inf`` gives a random constant).
    T : array_like, sampling interval (s, ≥ 0).

    Returns
    -------
    a : ndarray, broadcast shape of the inputs, transition factor.
    var : ndarray, same shape, driving-noise variance (unit²).
    """
    sigma, tau, T = (np.asarray(x, dtype=float) for x in (sigma, tau, T))
    if np.any(tau <= 0.0) or np.any(np.isnan(tau)):
        raise ValueError("tau must be positive")
    if np.any(T < 0.0) or not np.all(np.isfinite(T)):
        raise ValueError("T must be non-negative and finite")
    a = np.exp(-T / tau)
    return a, sigma**2 * -np.expm1(-2.0 * T / tau)
