"""Variational-Bayes adaptive measurement noise (Särkkä & Nummenmaa 2009; spec §7).

The measurement noise is ``R = diag(σ²_j)`` with independent inverse-gamma
posteriors ``IG(α_j, β_j)``.  Shapes: ``alpha``, ``beta`` are ``(..., m)``.
"""

from __future__ import annotations

import numpy as np

from ftnav.core.kalman import Update, mT, mv, update
from ftnav.core.linalg import batch_shape, flat, vb_kernel
from ftnav.types import BatchMatrix, BatchVector

__all__ = ["vb_predict", "vb_update", "vb_update_reference", "noise_estimate"]


def vb_predict(
    alpha: BatchVector, beta: BatchVector, rho: float
) -> tuple[BatchVector, BatchVector]:
    """Forgetting of the noise posterior ``α⁻ = ρ α``, ``β⁻ = ρ β`` (spec §7.2)."""
    return rho * alpha, rho * beta


def noise_estimate(alpha: BatchVector, beta: BatchVector) -> BatchMatrix:
    """Diagonal noise estimate ``R̂ = diag(β / α)`` as a (..., m, m) matrix."""
    R: BatchMatrix = np.einsum("...i,ij->...ij", beta / alpha, np.eye(alpha.shape[-1]))
    return R


def vb_update(
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    alpha: BatchVector,
    beta: BatchVector,
    *,
    iterations: int = 3,
    variant: str = "sarkka",
) -> tuple[Update, BatchVector, BatchVector, BatchMatrix]:
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

    The ``"sarkka"`` iterations run in one compiled loop over the batch
    (:func:`ftnav.core.linalg.vb_kernel`); :func:`vb_update_reference` is the plain
    NumPy form and the fallback where ``S`` is not numerically positive definite.
    """
    if variant != "sarkka" or iterations < 1:
        return vb_update_reference(x, P, z, H, alpha, beta, iterations=iterations, variant=variant)
    n, m = x.shape[-1], z.shape[-1]
    batch = batch_shape(
        x.shape[:-1], P.shape[:-2], z.shape[:-1], H.shape[:-2], alpha.shape[:-1], beta.shape[:-1]
    )
    xf, Pf, zf = flat(x, batch, (n,)), flat(P, batch, (n, n)), flat(z, batch, (m,))
    Hf = flat(H, batch, (m, n), True)
    alpha_post = flat(alpha, batch, (m,)) + 0.5
    bf = flat(beta, batch, (m,))
    M = xf.shape[0]
    x_out, P_out = np.empty((M, n)), np.empty((M, n, n))
    nu, S, q = np.empty((M, m)), np.empty((M, m, m)), np.empty(M)
    b_out, R = np.empty((M, m)), np.empty((M, m, m))
    ok = vb_kernel(
        xf, Pf, zf, Hf, alpha_post, bf, int(iterations), x_out, P_out, nu, S, q, b_out, R
    )
    if not ok.all():
        bad = ~ok
        Hb = Hf[bad] if Hf.shape[0] > 1 else Hf[0]
        up, _, b_out[bad], R[bad] = vb_update_reference(
            xf[bad],
            Pf[bad],
            zf[bad],
            Hb,
            alpha_post[bad] - 0.5,
            bf[bad],
            iterations=iterations,
            variant=variant,
        )
        x_out[bad], P_out[bad], nu[bad], S[bad], q[bad] = up
    return (
        Update(
            x_out.reshape(batch + (n,)),
            P_out.reshape(batch + (n, n)),
            nu.reshape(batch + (m,)),
            S.reshape(batch + (m, m)),
            q.reshape(batch),
        ),
        alpha_post.reshape(batch + (m,)),
        b_out.reshape(batch + (m,)),
        R.reshape(batch + (m, m)),
    )


def vb_update_reference(
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    alpha: BatchVector,
    beta: BatchVector,
    *,
    iterations: int = 3,
    variant: str = "sarkka",
) -> tuple[Update, BatchVector, BatchVector, BatchMatrix]:
    """Plain NumPy form of :func:`vb_update` (its test oracle; also the fallback)."""
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
