"""Attitude representations with the conventions of spec §0 (``docs/conventions.md``).

* DCM ``C_b^n`` (…, 3, 3) maps body vectors (x right, y forward, z up) to ENU.
* Euler ``a = [θ pitch, γ roll, ψ yaw]`` (rad), ``C_b^n = R_z(ψ) R_x(θ) R_y(γ)``;
  ψ positive counter-clockwise from North; heading (clockwise from North) is −ψ.
* Quaternion ``q_b^n = [q0, q1, q2, q3]``, scalar first, ``q ⊗ v ⊗ q*`` maps b to n.
* Attitude error φ: ``C̃_b^n = (I − [φ×]) C_b^n`` (spec §0).

Conversions to and from DCMs and Euler angles use :class:`scipy.spatial.transform.Rotation`
(intrinsic ``"ZXY"`` = ``R_z R_x R_y``); the quaternion algebra the mechanization needs
is written here, batched, and also compiled (:mod:`ftnav.nav.mechanization`).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.spatial.transform import Rotation

from ftnav.types import Array, ArrayLike, BatchMatrix, BatchScalar, BatchVector

__all__ = [
    "skew",
    "euler_to_dcm",
    "dcm_to_euler",
    "dcm_to_quat",
    "quat_to_dcm",
    "euler_to_quat",
    "quat_to_euler",
    "quat_mul",
    "quat_conj",
    "rotvec_to_quat",
    "quat_to_rotvec",
    "attitude_error",
    "quat_attitude_error",
    "heading_deg",
    "wrap_angle",
]


def skew(a: BatchVector) -> BatchMatrix:
    """``[a×]`` (…, 3, 3) with ``[a×] b = a × b``."""
    a = np.asarray(a, dtype=float)
    z = np.zeros_like(a[..., 0])
    return np.stack(
        [
            np.stack([z, -a[..., 2], a[..., 1]], -1),
            np.stack([a[..., 2], z, -a[..., 0]], -1),
            np.stack([-a[..., 1], a[..., 0], z], -1),
        ],
        -2,
    )


def _flat(a: ArrayLike, core: tuple[int, ...]) -> tuple[Array, tuple[int, ...]]:
    a = np.asarray(a, dtype=float)
    return a.reshape((-1,) + core), a.shape[: a.ndim - len(core)]


def euler_to_dcm(a: BatchVector) -> BatchMatrix:
    """``C_b^n = R_z(ψ) R_x(θ) R_y(γ)`` from ``a = [θ, γ, ψ]`` (…, 3) in rad."""
    f, batch = _flat(a, (3,))
    C: BatchMatrix = Rotation.from_euler("ZXY", f[:, [2, 0, 1]]).as_matrix()
    return C.reshape(batch + (3, 3))


def dcm_to_euler(C: BatchMatrix) -> BatchVector:
    """``[θ, γ, ψ]`` (rad) from ``C_b^n``; θ in [−π/2, π/2], γ and ψ in (−π, π]."""
    f, batch = _flat(C, (3, 3))
    # closed form of R_z(ψ) R_x(θ) R_y(γ): C32 = sin θ, C31 = −cos θ sin γ, C33 = cos θ cos γ,
    # C12 = −sin ψ cos θ, C22 = cos ψ cos θ
    theta = np.arcsin(np.clip(f[:, 2, 1], -1.0, 1.0))
    gamma = np.arctan2(-f[:, 2, 0], f[:, 2, 2])
    psi = np.arctan2(-f[:, 0, 1], f[:, 1, 1])
    return np.stack([theta, gamma, psi], -1).reshape(batch + (3,))


def quat_to_dcm(q: BatchVector) -> BatchMatrix:
    """``C_b^n`` from the scalar-first quaternion ``q_b^n`` (normalized first).

    The closed-form rotation matrix of a unit quaternion (the same as scipy's
    ``Rotation.from_quat(...).as_matrix()``, tested), in one compiled loop: it runs
    several times at every filter epoch and scipy's per-call overhead dominated the
    integrated runs.
    """
    q = np.asarray(q, dtype=float)
    flat = np.ascontiguousarray(q).reshape(-1, 4)
    C = np.empty((flat.shape[0], 3, 3))
    _quat_to_dcm_rows(flat, C)
    return C.reshape(q.shape[:-1] + (3, 3))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _quat_to_dcm_rows(q: BatchVector, C: BatchMatrix) -> None:  # pragma: no cover - compiled
    for b in range(q.shape[0]):
        n = np.sqrt(q[b, 0] ** 2 + q[b, 1] ** 2 + q[b, 2] ** 2 + q[b, 3] ** 2)
        q0, q1, q2, q3 = q[b, 0] / n, q[b, 1] / n, q[b, 2] / n, q[b, 3] / n
        C[b, 0, 0] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
        C[b, 0, 1] = 2.0 * (q1 * q2 - q0 * q3)
        C[b, 0, 2] = 2.0 * (q1 * q3 + q0 * q2)
        C[b, 1, 0] = 2.0 * (q1 * q2 + q0 * q3)
        C[b, 1, 1] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
        C[b, 1, 2] = 2.0 * (q2 * q3 - q0 * q1)
        C[b, 2, 0] = 2.0 * (q1 * q3 - q0 * q2)
        C[b, 2, 1] = 2.0 * (q2 * q3 + q0 * q1)
        C[b, 2, 2] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)


def dcm_to_quat(C: BatchMatrix) -> BatchVector:
    """Scalar-first ``q_b^n`` with ``q0 ≥ 0`` from ``C_b^n``."""
    f, batch = _flat(C, (3, 3))
    q: BatchVector = Rotation.from_matrix(f).as_quat()[:, [3, 0, 1, 2]]
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(batch + (4,))


def euler_to_quat(a: BatchVector) -> BatchVector:
    """Scalar-first ``q_b^n`` from ``[θ, γ, ψ]``."""
    return dcm_to_quat(euler_to_dcm(a))


def quat_to_euler(q: BatchVector) -> BatchVector:
    """``[θ, γ, ψ]`` from a scalar-first ``q_b^n``."""
    return dcm_to_euler(quat_to_dcm(q))


def quat_mul(p: BatchVector, q: BatchVector) -> BatchVector:
    """Hamilton product ``p ⊗ q`` of scalar-first quaternions (…, 4)."""
    p0, p1, p2, p3 = np.moveaxis(np.asarray(p, dtype=float), -1, 0)
    q0, q1, q2, q3 = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    pq: BatchVector = np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        -1,
    )
    return pq


def quat_conj(q: BatchVector) -> BatchVector:
    """Conjugate (inverse of a unit quaternion)."""
    q_conj: BatchVector = np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])
    return q_conj


def rotvec_to_quat(r: BatchVector) -> BatchVector:
    """``q(r) = [cos(|r|/2), sin(|r|/2) r/|r|]`` with the series for small |r| (spec §8.2)."""
    r = np.asarray(r, dtype=float)
    n2 = np.sum(r * r, -1)
    n = np.sqrt(n2)
    small = n < 1e-8
    safe = np.where(small, 1.0, n)
    c = np.where(small, 1.0 - n2 / 8.0, np.cos(0.5 * n))
    s = np.where(small, 0.5 - n2 / 48.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([c[..., None], s[..., None] * r], -1)


def quat_to_rotvec(q: BatchVector) -> BatchVector:
    """Rotation vector of a unit quaternion (angle in [0, π])."""
    q = np.asarray(q, dtype=float)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    v = q[..., 1:]
    s = np.sqrt(np.sum(v * v, -1))
    angle = 2.0 * np.arctan2(s, q[..., 0])
    scale = np.where(
        s < 1e-12, 2.0 / np.maximum(q[..., 0], 1e-300), angle / np.where(s < 1e-12, 1.0, s)
    )
    rotvec: BatchVector = scale[..., None] * v
    return rotvec


def attitude_error(C_est: BatchMatrix, C_true: BatchMatrix) -> BatchVector:
    """Attitude error φ (rad) of ``C_est`` against ``C_true`` (spec §0, §11).

    Defined exactly by ``C̃_b^n = exp(−[φ×]) C_b^n``, i.e. φ is the rotation vector of
    ``(C̃ Cᵀ)ᵀ``; to first order ``C̃ = (I − [φ×]) C`` as in spec §0.
    """
    D = np.swapaxes(C_est @ np.swapaxes(C_true, -1, -2), -1, -2)
    f, batch = _flat(D, (3, 3))
    phi: BatchVector = Rotation.from_matrix(f).as_rotvec()
    return phi.reshape(batch + (3,))


def quat_attitude_error(q_est: BatchVector, q_true: BatchVector) -> BatchVector:
    """:func:`attitude_error` of the attitudes of two quaternions ``q_b^n`` (…, 4).

    ``C_true C̃ᵀ`` is the DCM of ``q_true ⊗ q̃*``, so φ is that quaternion's rotation
    vector; no DCM is formed (this runs at every epoch of the closed-loop runner).
    """
    return quat_to_rotvec(quat_mul(q_true, quat_conj(q_est)))


def heading_deg(psi: BatchScalar) -> BatchScalar:
    """Heading clockwise from North in degrees [0, 360) from the yaw ψ (rad)."""
    heading: BatchScalar = np.mod(-np.degrees(psi), 360.0)
    return heading


def wrap_angle(a: Array) -> Array:
    """Wrap to (−π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(a, dtype=float), 2.0 * np.pi)
