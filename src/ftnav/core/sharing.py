"""Information-sharing rules of the federated filter (spec §2).

Each rule maps the local covariances ``P_i`` (posterior after the local update and
*before* the fusion reset, spec §2 notation) to sharing coefficients ``β_i >= 0``
with ``Σ β_i = 1 − β_m`` (the master keeps ``β_m``).  Fault factors ``r_i ∈ {0,1}``
remove faulty filters: ``β_i = 0`` when ``r_i = 0`` (spec §1.8, paper 000 eq. 5).
All functions are batched: ``P`` is ``(..., N, n, n)``, ``r`` is ``(..., N)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ftnav.types import BatchMatrix, BatchScalar, Matrix, Vector

__all__ = ["RULES", "sharing_coefficients", "scaled_trace", "information_content"]

RULES = ("equal", "fixed", "information", "trace", "eigen-trace", "frobenius", "inverse-trace")


def scaled_trace(P: BatchMatrix, scale: Vector | None = None) -> BatchScalar:
    """``tr(W P W)`` with ``W = diag(scale)``; plain ``tr P`` if ``scale`` is None.

    Spec §2.6 unit-mixing note: the default scale is ``diag(P0)^(-1/2)`` so the
    trace does not add m², (m/s)² and rad² unweighted.
    """
    d = np.diagonal(P, axis1=-2, axis2=-1)
    if scale is not None:
        d = d * scale**2
    tr: BatchScalar = d.sum(axis=-1)
    return tr


def _frobenius(P: BatchMatrix, scale: Vector | None) -> BatchScalar:
    if scale is not None:
        P = P * scale[:, None] * scale[None, :]
    norm: BatchScalar = np.sqrt(np.einsum("...ij,...ij->...", P, P))
    return norm


def information_content(
    H: Sequence[Matrix], R: Sequence[Matrix], scale: Vector | None = None
) -> Vector:
    """``tr(W⁻¹ Hᵢᵀ Rᵢ⁻¹ Hᵢ W⁻¹)`` per sensor (spec §2 item 2), shape (N,).

    Information is scaled by the inverse of the covariance scaling ``W`` so that
    the rule is invariant to state units, like the scaled trace rules.
    """
    out = []
    for Hi, Ri in zip(H, R, strict=True):
        info = Hi.T @ np.linalg.solve(Ri, Hi)
        d = np.diag(info)
        if scale is not None:
            d = d / scale[: d.shape[0]] ** 2
        out.append(d.sum())
    return np.asarray(out)


def _normalize(weights: BatchScalar, r: BatchScalar, master_share: float) -> BatchScalar:
    w = np.where(r > 0, weights, 0.0)
    total = w.sum(axis=-1, keepdims=True)
    safe = np.where(total > 0, total, 1.0)
    return np.where(total > 0, (1.0 - master_share) * w / safe, 0.0)


def sharing_coefficients(
    rule: str,
    P: BatchMatrix,
    r: BatchScalar,
    *,
    master_share: float = 0.0,
    betas: Vector | None = None,
    info: Vector | None = None,
    scale: Vector | None = None,
) -> BatchScalar:
    """Sharing coefficients β (..., N) for one of the spec §2 rules.

    Parameters
    ----------
    rule : one of :data:`RULES`.
        ``equal`` β_i ∝ 1 (§2.1); ``fixed`` the user's β renormalized over the
        healthy filters; ``information`` β_i ∝ tr(Hᵢᵀ Rᵢ⁻¹ Hᵢ) (§2.2);
        ``trace`` and its alias ``eigen-trace`` β_i ∝ tr P_i (§2.3-2.4, tr Λ = tr P);
        ``frobenius`` β_i ∝ ‖P_i‖_F (§2.5); ``inverse-trace`` β_i ∝ r_i / tr P_i
        (paper 000 eq. 5, §2.6; the reference l_0 cancels).
    P : (..., N, n, n) local covariances over the fused common states.
    r : (..., N) fault factors, 1 healthy, 0 faulty (isolated).
    master_share : β_m in [0, 1).
    betas : (N,) user coefficients for ``fixed``.
    info : (N,) information content for ``information``.
    scale : (n,) state scaling ``diag(W)``; None for the raw trace.

    Returns
    -------
    beta : (..., N) with β >= 0 and Σβ = 1 − β_m over healthy filters; all zero
        where every filter is faulty (the master then propagates alone, §1.4).
    """
    r = np.asarray(r, dtype=float)
    if rule == "equal":
        w = np.ones_like(r)
    elif rule == "fixed":
        w = np.broadcast_to(np.asarray(betas, dtype=float), r.shape)
    elif rule == "information":
        w = np.broadcast_to(np.asarray(info, dtype=float), r.shape)
    elif rule in ("trace", "eigen-trace"):
        w = scaled_trace(P, scale)
    elif rule == "frobenius":
        w = _frobenius(P, scale)
    elif rule == "inverse-trace":
        tr = scaled_trace(P, scale)
        l0 = tr.mean(axis=-1, keepdims=True)
        w = 1.0 / (tr / l0)
    else:
        raise ValueError(f"sharing: unknown rule {rule!r} (expected one of {', '.join(RULES)})")
    return _normalize(w, r, master_share)
