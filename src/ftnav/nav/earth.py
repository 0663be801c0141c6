"""WGS-84 Earth model used by the trajectory generator and the mechanization alike (spec §8.1).

One gravity model (Somigliana normal gravity with the second-order height
correction) serves both, so an error-free IMU reproduces the truth (spec §8.6 a).
Every function is a NumPy expression on arrays of any shape (batch axes allowed)
and is also compiled by numba for the mechanization kernel (``*_nb`` names).

Symbols: ``L`` latitude (rad), ``h`` height (m), ``v`` ENU velocity (m/s).
Geodetic/ECEF/ENU conversions are left to :mod:`pymap3d`.
"""

from __future__ import annotations

from typing import overload

import numba
import numpy as np

from ftnav.types import ArrayLike, BatchScalar, BatchVector

__all__ = [
    "A",
    "F",
    "E2",
    "OMEGA_IE",
    "GM",
    "radii",
    "gravity",
    "gravity_gradient",
    "omega_ie_n",
    "omega_ie_n_dL",
    "omega_en_n",
    "enu_metres",
]

A = 6378137.0  #: semi-major axis (m)
F = 1.0 / 298.257223563  #: flattening
E2 = F * (2.0 - F)  #: first eccentricity squared
OMEGA_IE = 7.292115e-5  #: Earth rotation rate (rad/s)
GM = 3.986004418e14  #: gravitational constant (m³/s²)
_GE = 9.7803253359  #: normal gravity at the equator (m/s²)
_K = 0.00193185265241  #: Somigliana constant
_M = 0.00344978650684  #: ω² a² b / GM


@overload
def radii(L: float, h: float) -> tuple[float, float]: ...
@overload
def radii(L: BatchScalar, h: float | BatchScalar) -> tuple[BatchScalar, BatchScalar]: ...
def radii(
    L: float | BatchScalar, h: float | BatchScalar
) -> tuple[float | BatchScalar, float | BatchScalar]:
    """``(R_Mh, R_Nh)``: meridian and prime-vertical radii plus height (m), spec §8.1.

    ``R_M = a(1−e²)/(1−e² sin²L)^{3/2}``, ``R_N = a/(1−e² sin²L)^{1/2}``.
    """
    w = 1.0 - E2 * np.sin(L) ** 2
    RN = A / np.sqrt(w)
    return RN * (1.0 - E2) / w + h, RN + h


@overload
def gravity(L: float, h: float) -> float: ...
@overload
def gravity(L: BatchScalar, h: float | BatchScalar) -> BatchScalar: ...
def gravity(L: float | BatchScalar, h: float | BatchScalar) -> float | BatchScalar:
    """Normal gravity magnitude g(L, h) (m/s², positive), spec §8.1.

    ``g = g_e (1 + k sin²L)/√(1 − e² sin²L) · [1 − (2/a)(1 + f + m − 2f sin²L) h + 3h²/a²]``;
    the navigation-frame vector is ``g^n = [0, 0, −g]``.
    """
    s2 = np.sin(L) ** 2
    g0 = _GE * (1.0 + _K * s2) / np.sqrt(1.0 - E2 * s2)
    g: float | BatchScalar = g0 * (
        1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h + 3.0 * h * h / A**2
    )
    return g


@overload
def gravity_gradient(L: float, h: float) -> tuple[float, float]: ...
@overload
def gravity_gradient(L: BatchScalar, h: float | BatchScalar) -> tuple[BatchScalar, BatchScalar]: ...
def gravity_gradient(
    L: float | BatchScalar, h: float | BatchScalar
) -> tuple[float | BatchScalar, float | BatchScalar]:
    """``(∂g/∂L, ∂g/∂h)`` of :func:`gravity` (1/s² per rad and per m), for the error model."""
    s = np.sin(L)
    c = np.cos(L)
    s2 = s * s
    w = 1.0 - E2 * s2
    g0 = _GE * (1.0 + _K * s2) / np.sqrt(w)
    # d g0 / d(s²), then chain rule d(s²)/dL = 2 s c
    dg0 = _GE * (_K * np.sqrt(w) + (1.0 + _K * s2) * 0.5 * E2 / np.sqrt(w)) / w
    bracket = 1.0 - 2.0 / A * (1.0 + F + _M - 2.0 * F * s2) * h + 3.0 * h * h / A**2
    dbracket = 4.0 * F / A * h  # d bracket / d(s²)
    dgdL = (dg0 * bracket + g0 * dbracket) * 2.0 * s * c
    dgdh = g0 * (-2.0 / A * (1.0 + F + _M - 2.0 * F * s2) + 6.0 * h / A**2)
    return dgdL, dgdh


def omega_ie_n(L: ArrayLike) -> BatchVector:
    """Earth rate in n, ``[0, ω_ie cos L, ω_ie sin L]`` (rad/s), shape ``L.shape + (3,)``."""
    L = np.asarray(L, dtype=float)
    return np.stack([np.zeros_like(L), OMEGA_IE * np.cos(L), OMEGA_IE * np.sin(L)], -1)


def omega_ie_n_dL(L: ArrayLike) -> BatchVector:
    """``∂ω_ie^n/∂L = [0, −ω_ie sin L, ω_ie cos L]`` (rad/s per rad), ``L.shape + (3,)``."""
    L = np.asarray(L, dtype=float)
    return np.stack([np.zeros_like(L), -OMEGA_IE * np.sin(L), OMEGA_IE * np.cos(L)], -1)


def omega_en_n(L: BatchScalar, h: float | BatchScalar, v: BatchVector) -> BatchVector:
    """Transport rate ``[−v_N/R_Mh, v_E/R_Nh, v_E tan L/R_Nh]`` (rad/s), spec §8.1."""
    RMh, RNh = radii(L, h)
    vE, vN = v[..., 0], v[..., 1]
    return np.stack([-vN / RMh, vE / RNh, vE * np.tan(L) / RNh], -1)


def enu_metres(p_est: BatchVector, p_true: BatchVector) -> BatchVector:
    """Position error ``[e_E, e_N, e_U]`` in metres of ``p_est − p_true`` (spec §11).

    ``e_N = R_Mh (L̂ − L)``, ``e_E = R_Nh cos L (λ̂ − λ)``, ``e_U = ĥ − h``, with the radii
    at the true position; ``p`` is ``(..., 3)`` ``[L, λ, h]``.
    """
    L, h = p_true[..., 0], p_true[..., 2]
    RMh, RNh = radii(L, h)
    d = p_est - p_true
    dlon = (d[..., 1] + np.pi) % (2.0 * np.pi) - np.pi
    return np.stack([RNh * np.cos(L) * dlon, RMh * d[..., 0], d[..., 2]], -1)


# compiled scalar forms for the mechanization kernel
radii_nb = numba.njit(cache=True)(radii)
gravity_nb = numba.njit(cache=True)(gravity)
gravity_gradient_nb = numba.njit(cache=True)(gravity_gradient)
