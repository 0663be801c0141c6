"""Stationary first-order Gauss-Markov sequences from white draws (spec §8.4).

The exact discrete form used by every simulator of coloured errors (IMU drifts,
aid errors): ``b_0 = σ ε_0``, ``b_k = e^{−dt/τ} b_{k−1} + σ√(1 − e^{−2dt/τ}) ε_k``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from ftnav.types import ArrayLike, BatchMatrix, Vector

__all__ = ["check_dt", "gauss_markov", "gauss_markov_inplace"]


def _show(value: object) -> str:
    """One-line rendering of a bad input for an error message."""
    return np.array2string(value, separator=", ") if isinstance(value, np.ndarray) else repr(value)


def gauss_markov_inplace(w: BatchMatrix, sigma: Vector, tau: Vector, dt: float) -> BatchMatrix:
    """Turn standard normals ``w`` (..., K, n) into stationary Gauss-Markov sequences."""
    a = np.exp(-dt / tau)
    w[..., 1:, :] *= sigma * np.sqrt(-np.expm1(-2.0 * dt / tau))
    w[..., 0, :] *= sigma  # stationary start
    if np.all(a == a[0]):
        b: BatchMatrix = lfilter([1.0], [1.0, -a[0]], w, axis=-2)
        return b
    out = np.empty_like(w)
    for j, aj in enumerate(a):
        out[..., j] = lfilter([1.0], [1.0, -aj], w[..., j], axis=-1)
    return out


def gauss_markov(white: ArrayLike, sigma: ArrayLike, tau: ArrayLike, dt: float) -> BatchMatrix:
    """Stationary first-order Gauss-Markov sequences from standard normals (spec §8.4).

    ``b_0 = σ ε_0``, ``b_k = e^{−dt/τ} b_{k−1} + σ√(1 − e^{−2dt/τ}) ε_k``, so every
    ``b_k ~ N(0, σ²)`` and ``corr(b_k, b_{k+j}) = e^{−j·dt/τ}``.

    Parameters
    ----------
    white : (..., K, n) array_like
        Independent standard normal draws ε.
    sigma : (n,) or scalar, unit
        Steady-state standard deviation, ≥ 0.
    tau : (n,) or scalar, s
        Correlation time, > 0.
    dt : float, s
        Sample interval.

    Returns
    -------
    (..., K, n) ndarray, unit
    """
    w = np.array(white, dtype=float)
    if w.ndim < 2:
        raise ValueError(f"white: expected (..., K, n), got shape {w.shape}")
    n = w.shape[-1]
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (n,))
    tau = np.broadcast_to(np.asarray(tau, dtype=float), (n,))
    if not np.all(np.isfinite(sigma)) or np.any(sigma < 0.0):
        raise ValueError(f"sigma: must be finite and >= 0, got {_show(sigma)}")
    if not np.all(np.isfinite(tau)) or np.any(tau <= 0.0):
        raise ValueError(f"tau: must be finite and > 0, got {_show(tau)}")
    return gauss_markov_inplace(w, sigma, tau, check_dt(dt))


def check_dt(dt: float) -> float:
    """``float(dt)``, checked finite and > 0 (``ValueError`` naming ``dt`` otherwise)."""
    try:
        value = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt: expected a number of seconds, got {dt!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"dt: must be a finite number > 0, got {dt!r}")
    return value
