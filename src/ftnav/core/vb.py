"""Variational-Bayes adaptive measurement noise (Särkkä & Nummenmaa 2009; spec §7).

The measurement noise is ``R = diag(σ²_j)`` with independent inverse-gamma
posteriors ``IG(α_j, β_j)``.  Shapes: ``alpha``, ``beta`` are ``(..., m)``.
"""

from __future__ import annotations

import numpy as np

from ftnav.core.kalman import Update, mT, mv, update

__all__ = ["vb_predict", "vb_update", "noise_estimate"]


def vb_predict(alpha: np.ndarray, beta: np.ndarray, rho: float) -> tuple[np.ndarray, np.ndarray]:
    """Forgetting of the noise posterior ``α⁻ = ρ α``, ``β⁻ = ρ β`` (spec §7.2)."""
    return rho * alpha, rho * beta


def noise_estimate(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Diagonal noise estimate ``R̂ = diag(β / α)`` as a (..., m, m) matrix."""
    return np.einsum("...i,ij->...ij", beta / alpha, np.eye(alpha.shape[-1]))


def vb_update(
    x: np.ndarray,
    P: np.ndarray,
    z: np.ndarray,
    H: np.ndarray,
    alpha: np.ndarray,
    beta: np.ndarray,
    *,
    iterations: int = 3,
    variant: str = "sarkka",
) -> tuple[Update, np.ndarray, np.ndarray, np.ndarray]:
    """VB measurement update (spec §7.2; ``variant="literal"``: paper 002 eq. 30, §7.3).

    Parameters
    ----------
    x, P : prior mean (..., n) and covariance (..., n, n).
    z : (..., m) measurement.  H : (..., m, n).
    alpha, beta : (..., m) predicted inverse-gamma parameters (after :func:`vb_predict`).
    iterations : fixed-point iterations N_it (spec default 3).
    variant : ``"sarkka"`` uses the posterior residual and ``H P⁺ Hᵀ`` (consistent);
        ``"literal"`` uses the prior innovation and ``H P⁻ Hᵀ`` without iterating,
        which over-estimates R (spec §7.3).

    Returns
    -------
    update : :class:`~ftnav.core.kalman.Update` of the final iteration; its
        ``innovation``, ``S`` and ``nis`` refer to the prior with the final R̂.
    alpha, beta : (..., m) posterior parameters.
    R : (..., m, m) the noise the returned posterior used: ``diag(β⁽ᴺ⁻¹⁾/α)`` for
        ``"sarkka"`` (one fixed-point step behind the returned ``β/α``), ``β/α`` for
        ``"literal"``; a plain KF with this R reproduces the update (spec §6.4).
    """
    alpha_post = alpha + 0.5
    if variant == "literal":
        nu = z - mv(H, x)
        hph = np.diagonal(H @ P @ mT(H), axis1=-2, axis2=-1)
        beta_post = beta + 0.5 * nu**2 + 0.5 * hph
        iterations = 1
        beta_iter = beta_post
    elif variant == "sarkka":
        beta_iter = beta
    else:
        raise ValueError(f"vb variant: unknown value {variant!r} (expected 'sarkka' or 'literal')")
    for _ in range(iterations):
        R = noise_estimate(alpha_post, beta_iter)
        up = update(x, P, z, H, R)  # Joseph form with this iteration's R (compiled)
        if variant == "sarkka":
            res = z - mv(H, up.x)
            hph = np.einsum("...ij,...jk,...ik->...i", H, up.P, H)
            beta_iter = beta + 0.5 * res**2 + 0.5 * hph
    return up, alpha_post, beta_iter, R
