"""Per-epoch input features of the learned fault detector (spec §4.1, paper 000 §3.1).

Paper 000 feeds its RBF network two kinds of input; spec §4.1 fixes their
normalisation so one network serves every sensor scale:

``"state-difference"``
    ``ê_ig = diag(P_i)^{-1/2} (x̂_i − x̂_g)`` for every local filter i on the
    common states, with ``x̂_i``, ``P_i`` the local posterior of the epoch and
    ``x̂_g`` the reference estimate (the fused prior ``Φ x̂_g(k−1)``).
``"innovation"``
    ``z̄e_i = chol(A_i)⁻¹ ν_i``: the innovation whitened by its covariance
    ``A_i = H_i P H_iᵀ + R_i`` (against the prior the method tests with,
    ``prior = "local"`` or ``"global"``); zero where sensor i has no measurement.

Feature order: all state differences (filter-major, then state), then all
innovations (sensor-major).  The z-score with the training statistics is part
of the trained model (:class:`ftnav.fdi.rbf.RBFNetwork`), not of this module.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["FEATURE_KINDS", "feature_names", "whitened_innovation", "detector_features"]

#: The feature kinds of spec §4.1, in the order they are stacked.
FEATURE_KINDS = ("state-difference", "innovation")


def feature_names(
    kinds: Sequence[str], states: Sequence[str], sensors: Sequence[str], dims: Sequence[int]
) -> list[str]:
    """Column names of the feature matrix, e.g. ``"e[pos1].s"``, ``"nu[pos2][0]"``."""
    unknown = [k for k in kinds if k not in FEATURE_KINDS]
    if unknown or not kinds:
        raise ValueError(
            f"features: expected a non-empty subset of {list(FEATURE_KINDS)}, got {list(kinds)}"
        )
    names: list[str] = []
    if "state-difference" in kinds:
        names += [f"e[{s}].{x}" for s in sensors for x in states]
    if "innovation" in kinds:
        names += [f"nu[{s}][{j}]" for s, m in zip(sensors, dims, strict=True) for j in range(m)]
    return names


def whitened_innovation(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, use: np.ndarray, H: np.ndarray, R: np.ndarray
) -> np.ndarray:
    """``chol(H P Hᵀ + R)⁻¹ (z − H x)`` (spec §4.1), zero where ``use`` is False.

    Parameters
    ----------
    x, P : (B, n), (B, n, n) prior.   z : (B, m).   use : (B,) bool.
    H : (m, n), or (B, m, n) on a linearized (integrated) system.   R : (m, m) or (B, m, m).

    Returns
    -------
    (B, m) whitened innovation; its squared norm is the NIS of spec §3.1.
    """
    nu = np.where(use[:, None], z, 0.0) - np.einsum("...ij,...j->...i", H, x)
    A = H @ P @ np.swapaxes(H, -1, -2) + R
    L = np.linalg.cholesky(0.5 * (A + np.swapaxes(A, -1, -2)))
    w = np.linalg.solve(L, nu[..., None])[..., 0]
    return np.where(use[:, None], w, 0.0)


def detector_features(
    kinds: Sequence[str],
    local_x: np.ndarray,
    local_var: np.ndarray,
    reference: np.ndarray,
    innovations: Sequence[np.ndarray],
) -> np.ndarray:
    """Raw (un-normalised) feature matrix of one epoch (spec §4.1).

    Parameters
    ----------
    kinds : subset of :data:`FEATURE_KINDS`.
    local_x : (B, N, n_c) local posteriors on the common states.
    local_var : (B, N, n_c) their variances ``diag(P_i)``.
    reference : (B, n_c) the reference estimate ``x̂_g``.
    innovations : per sensor (B, m_i) whitened innovations.

    Returns
    -------
    (B, F) features in the order of :func:`feature_names`.
    """
    parts = []
    if "state-difference" in kinds:
        e = (local_x - reference[:, None, :]) / np.sqrt(local_var)
        parts.append(e.reshape(e.shape[0], -1))
    if "innovation" in kinds:
        parts.extend(innovations)
    return np.concatenate(parts, axis=1)
