"""Batched linear-Gaussian kernel: predict, Joseph update, information form.

Every function is pure and works on arrays with arbitrary leading batch axes:
vectors are ``(..., n)`` and matrices ``(..., n, n)``, so one call advances B Monte
Carlo runs (or B runs x N local filters) in lock-step.  Nothing here imports from
the rest of ftnav.

Notation (spec §0): ``x`` state mean, ``P`` covariance, ``F`` transition matrix
(Φ), ``Q`` process-noise covariance (already mapped through Γ), ``H`` measurement
matrix, ``R`` measurement-noise covariance, ``Y = P⁻¹`` information matrix and
``y = P⁻¹ x`` information vector, ``nu = z − H x⁻`` innovation,
``S = H P⁻ Hᵀ + R`` its covariance and ``nis = nuᵀ S⁻¹ nu``.
"""

from __future__ import annotations

from typing import NamedTuple, cast

import numpy as np

from ftnav.core.linalg import (
    batch_shape,
    flat,
    fuse_kernel,
    nis_kernel,
    predict_kernel,
    spd_inv,
    spd_solve,
    update_kernel,
)
from ftnav.types import Array, BatchMatrix, BatchScalar, BatchVector, Vector

__all__ = [
    "Gaussian",
    "Update",
    "symmetrize",
    "mT",
    "mv",
    "prior_nis",
    "differenced_measurement",
    "predict",
    "update",
    "nis",
    "to_information",
    "from_information",
    "information_predict",
    "spd_inverse",
    "intersect",
]


class Gaussian(NamedTuple):
    """Mean ``x`` (..., n) and covariance ``P`` (..., n, n)."""

    x: BatchVector
    P: BatchMatrix


class Update(NamedTuple):
    """Result of a measurement update (spec §0, §3.1).

    Attributes
    ----------
    x : (..., n) posterior mean.
    P : (..., n, n) posterior covariance (Joseph form, symmetrized).
    innovation : (..., m) ``z − H x⁻``.
    S : (..., m, m) innovation covariance ``H P⁻ Hᵀ + R``.
    nis : (...,) normalized innovation squared ``νᵀ S⁻¹ ν``.
    """

    x: BatchVector
    P: BatchMatrix
    innovation: BatchVector
    S: BatchMatrix
    nis: BatchScalar


def mT(A: Array) -> Array:
    """Transpose of the last two axes."""
    return np.swapaxes(A, -1, -2)


def mv(A: BatchMatrix, x: BatchVector) -> BatchVector:
    """Batched matrix-vector product ``A x`` for ``A (..., m, n)``, ``x (..., n)``."""
    return (A @ x[..., None])[..., 0]


def symmetrize(P: BatchMatrix) -> BatchMatrix:
    """Return ``½(P + Pᵀ)`` (spec §0, numerics)."""
    return 0.5 * (P + mT(P))


def predict(x: BatchVector, P: BatchMatrix, F: BatchMatrix, Q: BatchMatrix) -> Gaussian:
    """Kalman time update ``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q`` (spec §1.3 step 1).

    Parameters
    ----------
    x : (..., n) posterior mean at k−1.
    P : (..., n, n) posterior covariance at k−1.
    F : (..., n, n) transition matrix Φ_k (broadcast against the batch).
    Q : (..., n, n) process-noise covariance Γ Q_k Γᵀ.
    """
    n = x.shape[-1]
    batch = batch_shape(x.shape[:-1], P.shape[:-2], F.shape[:-2], Q.shape[:-2])
    xf = flat(x, batch, (n,))
    x_out, P_out = np.empty_like(xf), np.empty((xf.shape[0], n, n))
    predict_kernel(
        xf,
        flat(P, batch, (n, n)),
        flat(F, batch, (n, n), True),
        flat(Q, batch, (n, n), True),
        x_out,
        P_out,
    )
    return Gaussian(x_out.reshape(batch + (n,)), P_out.reshape(batch + (n, n)))


def intersect(x: BatchVector, P: BatchMatrix, omega: BatchScalar | None = None) -> Gaussian:
    """Covariance intersection ``P⁻¹ = Σ ω_i P_i⁻¹``, ``P⁻¹ x = Σ ω_i P_i⁻¹ x_i``.

    Julier & Uhlmann (ACC 1997): with ``ω_i ≥ 0`` and ``Σ ω_i = 1`` the result is
    consistent (``P`` bounds the error covariance of ``x``) for *any* cross-covariance
    of the estimates' errors, which need not be known.  ``omega`` defaults to the
    equal weights ``1/N``.  Used by the neuron centre's detector (spec §3.1 with the
    reference of :mod:`ftnav.fusion.neural`).

    Parameters
    ----------
    x : (..., N, n) estimates.   P : (..., N, n, n) their covariances.
    omega : (..., N) weights on the simplex.
    """
    N = x.shape[-2]
    if omega is None:
        omega = np.full(x.shape[:-1], 1.0 / N)
    omega = np.asarray(omega, dtype=float)
    if (omega < 0).any() or np.abs(omega.sum(-1) - 1.0).max() > 1e-12:
        raise ValueError("omega: covariance intersection needs weights >= 0 that sum to 1")
    return fuse(x, P, omega)


def predict_reference(x: BatchVector, P: BatchMatrix, F: BatchMatrix, Q: BatchMatrix) -> Gaussian:
    """Plain NumPy form of :func:`predict` (the test oracle of the compiled one)."""
    return Gaussian(mv(F, x), symmetrize(F @ P @ mT(F) + Q))


def update(
    x: BatchVector, P: BatchMatrix, z: BatchVector, H: BatchMatrix, R: BatchMatrix
) -> Update:
    """Kalman measurement update in Joseph form (spec §0).

    ``K = P Hᵀ S⁻¹``, ``x⁺ = x + K ν``,
    ``P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ``, then symmetrized.  Solves with ``S``
    instead of forming ``S⁻¹``.

    Parameters
    ----------
    x : (..., n) prior mean.
    P : (..., n, n) prior covariance.
    z : (..., m) measurement.
    H : (..., m, n) measurement matrix.
    R : (..., m, m) measurement-noise covariance.
    """
    n, m = x.shape[-1], z.shape[-1]
    batch = batch_shape(x.shape[:-1], P.shape[:-2], z.shape[:-1], H.shape[:-2], R.shape[:-2])
    xf, Pf, zf = flat(x, batch, (n,)), flat(P, batch, (n, n)), flat(z, batch, (m,))
    Hf, Rf = flat(H, batch, (m, n), True), flat(R, batch, (m, m), True)
    M = xf.shape[0]
    x_out, P_out = np.empty((M, n)), np.empty((M, n, n))
    nu, S, q = np.empty((M, m)), np.empty((M, m, m)), np.empty(M)
    ok = update_kernel(xf, Pf, zf, Hf, Rf, x_out, P_out, nu, S, q)
    if not ok.all():  # S not numerically SPD: LU fallback, never a silent wrong answer
        bad = ~ok
        Hb = Hf[bad] if Hf.shape[0] > 1 else Hf[0]
        Rb = Rf[bad] if Rf.shape[0] > 1 else Rf[0]
        ref = update_reference(xf[bad], Pf[bad], zf[bad], Hb, Rb)
        x_out[bad], P_out[bad], nu[bad], S[bad], q[bad] = ref
    return Update(
        x_out.reshape(batch + (n,)),
        P_out.reshape(batch + (n, n)),
        nu.reshape(batch + (m,)),
        S.reshape(batch + (m, m)),
        q.reshape(batch),
    )


def update_reference(
    x: BatchVector, P: BatchMatrix, z: BatchVector, H: BatchMatrix, R: BatchMatrix
) -> Update:
    """Plain NumPy form of :func:`update` (LU solves; the compiled kernel's oracle)."""
    nu = z - mv(H, x)
    PHt = P @ mT(H)
    S = symmetrize(H @ PHt + R)
    # K = P Hᵀ S⁻¹  <=>  Kᵀ = S⁻¹ H P (S and P symmetric); the casts here and below:
    # numpy's stubs type LAPACK results as any float, they are float64 for float64 input
    K = mT(cast(BatchMatrix, np.linalg.solve(S, mT(PHt))))
    x_post = x + mv(K, nu)
    n = x.shape[-1]
    A = np.eye(n) - K @ H
    P_post = symmetrize(A @ P @ mT(A) + K @ R @ mT(K))
    return Update(x_post, P_post, nu, S, nis(nu, S))


def prior_nis(
    x: BatchVector, P: BatchMatrix, z: BatchVector, H: BatchMatrix, R: BatchMatrix
) -> BatchScalar:
    """NIS of ``z`` against the prior ``(x, P)``: ``νᵀ S⁻¹ ν``, ``ν = z − H x``,
    ``S = H P Hᵀ + R`` (spec §3.1), shape (...); one compiled pass, no update.

    Shapes as in :func:`update`.  Where ``S`` is not numerically SPD the value is
    computed by :func:`nis` with an LU solve.
    """
    n, m = x.shape[-1], z.shape[-1]
    batch = batch_shape(x.shape[:-1], P.shape[:-2], z.shape[:-1], H.shape[:-2], R.shape[:-2])
    xf, Pf, zf = flat(x, batch, (n,)), flat(P, batch, (n, n)), flat(z, batch, (m,))
    Hf, Rf = flat(H, batch, (m, n), True), flat(R, batch, (m, m), True)
    q = np.empty(xf.shape[0])
    ok = nis_kernel(xf, Pf, zf, Hf, Rf, q)
    if not ok.all():
        bad = ~ok
        Hb = Hf[bad] if Hf.shape[0] > 1 else Hf[0]
        Rb = Rf[bad] if Rf.shape[0] > 1 else Rf[0]
        nu = zf[bad] - mv(Hb, xf[bad])
        S = symmetrize(Hb @ Pf[bad] @ mT(Hb) + Rb)
        q[bad] = np.einsum("...i,...i->...", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    return q.reshape(batch)


def differenced_measurement(
    z: BatchVector,
    H: BatchMatrix,
    z_prev: BatchVector,
    H_prev: BatchMatrix,
    Phi: BatchMatrix,
    psi: Vector,
    shift: BatchVector | None = None,
) -> tuple[BatchVector, BatchMatrix]:
    """Measurement differencing for first-order Markov measurement errors.

    Bryson & Henrikson (1968).  With ``z_k = H_k x_k + b_k + n_k``,
    ``b_k = ψ b_{k−1} + w_{k−1}`` (ψ diagonal) and ``x_k = Φ (x_{k−1} − s) + u``, where
    ``s`` is a correction removed from the state between the epochs (closed-loop
    feedback; 0 without it)::

        z* = z_k − ψ (z_{k−1} − H_{k−1} s),   H* = H_k − ψ H_{k−1} Φ⁻¹,
        z* − H* x_k = w_{k−1} + n_k − ψ n_{k−1} + ψ H_{k−1} Φ⁻¹ u.

    Parameters
    ----------
    z, z_prev : (..., m) measurements at k and k−1.
    H, H_prev : (..., m, n) their measurement matrices.
    Phi : (..., n, n) transition from k−1 to k (invertible).
    psi : (m,) Markov factors ``e^{−T/τ}``.
    shift : (..., n) correction removed from the state after the k−1 update, or None.

    Returns
    -------
    z_star : (..., m).   H_star : (..., m, n).
    """
    psi = np.asarray(psi, dtype=float)
    prev = z_prev if shift is None else z_prev - mv(H_prev, shift)
    # H_{k−1} Φ⁻¹ = (Φ⁻ᵀ H_{k−1}ᵀ)ᵀ: one LU solve per run, no inverse formed
    HPhi_inv = mT(cast(BatchMatrix, np.linalg.solve(mT(Phi), mT(H_prev))))
    return z - psi * prev, H - psi[:, None] * HPhi_inv


def nis(nu: BatchVector, S: BatchMatrix) -> BatchScalar:
    """Normalized innovation squared ``νᵀ S⁻¹ ν`` (spec §3.1), shape (...)."""
    q: BatchScalar = np.einsum("...i,...i->...", nu, spd_solve(S, nu[..., None])[..., 0])
    return q


def spd_inverse(P: BatchMatrix) -> BatchMatrix:
    """Inverse of a symmetric positive-definite matrix, symmetrized."""
    return spd_inv(P)


def to_information(x: BatchVector, P: BatchMatrix) -> tuple[BatchVector, BatchMatrix]:
    """Covariance form to information form: ``Y = P⁻¹``, ``y = P⁻¹ x`` (spec §0)."""
    Y = spd_inverse(P)
    return mv(Y, x), Y


def from_information(y: BatchVector, Y: BatchMatrix) -> Gaussian:
    """Information form to covariance form: ``P = Y⁻¹``, ``x = P y`` (spec §0)."""
    P = spd_inverse(Y)
    return Gaussian(mv(P, y), P)


def information_predict(
    y: BatchVector, Y: BatchMatrix, F: BatchMatrix, Q: BatchMatrix
) -> tuple[BatchVector, BatchMatrix]:
    """Information-form time update valid for singular ``Y`` (spec §1.5, ZR note).

    With ``M = F⁻ᵀ Y F⁻¹`` the prior information is ``Y⁻ = (I + M Q)⁻¹ M``
    (equal to ``(F Y⁻¹ Fᵀ + Q)⁻¹`` when ``Y`` is invertible) and
    ``y⁻ = (I + M Q)⁻¹ F⁻ᵀ y``.  Works for ``Y = 0`` (no information) and for a
    singular ``Q``; needs ``F`` invertible, which holds for any discretized
    continuous-time model.
    """
    n = y.shape[-1]
    Finv = cast(BatchMatrix, np.linalg.inv(F))
    FinvT = mT(Finv)
    M = FinvT @ Y @ Finv
    A = np.eye(n) + M @ Q
    Y_prior = symmetrize(cast(BatchMatrix, np.linalg.solve(A, M)))
    y_prior = cast(BatchVector, np.linalg.solve(A, mv(FinvT, y)[..., None])[..., 0])
    return y_prior, Y_prior


def fuse(
    x: BatchVector,
    P: BatchMatrix,
    weight: BatchScalar,
    y0: BatchVector | None = None,
    Y0: BatchMatrix | None = None,
) -> Gaussian:
    """Information fusion ``P_g = (Y0 + Σ w_i P_i⁻¹)⁻¹``, ``x_g = P_g (y0 + Σ w_i P_i⁻¹ x_i)``.

    Spec §1.3 step 3 (paper 000 eq. 2) with ``w_i ∈ {0, 1}`` selecting the active
    set, and an optional prior information ``(y0, Y0)`` (the master filter or
    the distributed centre, spec §6.1).

    Parameters
    ----------
    x : (..., N, n) local estimates.   P : (..., N, n, n) their covariances.
    weight : (..., N) weights (0 leaves a filter out).
    y0, Y0 : (..., n), (..., n, n) information added to the sum (default 0).

    Raises
    ------
    numpy.linalg.LinAlgError
        If the total information is not positive definite (nothing fused).
    """
    N, n = x.shape[-2:]
    batch = batch_shape(x.shape[:-2], P.shape[:-3], weight.shape[:-1])
    xf, Pf = flat(x, batch, (N, n)), flat(P, batch, (N, n, n))
    wf = flat(weight, batch, (N,))
    M = xf.shape[0]
    Y0f = np.zeros((M, n, n)) if Y0 is None else flat(Y0, batch, (n, n))
    y0f = np.zeros((M, n)) if y0 is None else flat(y0, batch, (n,))
    x_out, P_out = np.empty((M, n)), np.empty((M, n, n))
    ok = fuse_kernel(xf, Pf, wf, Y0f, y0f, x_out, P_out)
    if not ok.all():  # fall back to LU; raises if the information is singular
        bad = ~ok
        Yi = np.linalg.inv(Pf[bad])
        Y = Y0f[bad] + np.einsum("bk,bkij->bij", wf[bad], Yi)
        y = y0f[bad] + np.einsum("bk,bkij,bkj->bi", wf[bad], Yi, xf[bad])
        P_out[bad] = symmetrize(np.linalg.inv(Y))
        x_out[bad] = mv(P_out[bad], y)
    return Gaussian(x_out.reshape(batch + (n,)), P_out.reshape(batch + (n, n)))
