"""Strapdown mechanization in increment form, ENU navigation frame (spec §8.2).

One update over the interval ``T`` (one or two IMU samples):

1. coning/sculling: rotation vector ``φ_b`` and velocity increment ``Δv_b`` from the
   gyro increments ``Δθ`` and accelerometer increments ``Δv`` (estimated biases
   subtracted first, ``Δθ −= ε̂ T_s``, ``Δv −= ∇̂ T_s``);
2. Earth quantities at mid-interval, extrapolated: ``v½ = v + ½ a T``,
   ``p½ = p + ½ T M_pv(p) v½``;
3. velocity ``v⁺ = v + (I − ½[(ω_in^n T)×]) C_b^n Δv_b + [g^n − (2ω_ie^n + ω_en^n)×v½] T``;
4. position, trapezoidal: ``p⁺ = p + M_pv(p½) (v + v⁺)/2 · T``;
5. attitude ``q⁺ = q(−ω_in^n T) ⊗ q ⊗ q(φ_b)``, normalized.

Algorithms for step 1 (``algorithm``):

* ``"two-sample"`` (spec default): two IMU samples per update,
  ``φ_b = Δθ₁ + Δθ₂ + ⅔ Δθ₁×Δθ₂``,
  ``Δv_b = Δv₁ + Δv₂ + ½(Δθ₁+Δθ₂)×(Δv₁+Δv₂) + ⅔(Δθ₁×Δv₂ + Δv₁×Δθ₂)``;
  the solution is produced every second sample.
* ``"single-sample"``: ``φ_b = Δθ``, ``Δv_b = Δv + ½Δθ×Δv``.

The kernel is compiled with numba and runs the batch of Monte Carlo runs in one
serial loop (each run a sequential loop over its samples; parallelism is over whole
chunks of runs in worker processes, :mod:`ftnav.parallel`); the state is an explicit
:class:`InsState`, so integration can be split into chunks (e.g. between aid epochs,
with feedback corrections in between) without changing the result.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ftnav.nav import attitude
from ftnav.nav.earth import OMEGA_IE, gravity_nb, radii_nb
from ftnav.types import BatchVector, Vector

__all__ = [
    "InsState",
    "NavSolution",
    "ALGORITHMS",
    "init_state",
    "integrate",
    "apply_correction",
    "feedback",
    "navigation_errors",
]

ALGORITHMS = {"single-sample": 1, "two-sample": 2}


class InsState(NamedTuple):
    """Mechanization state for B runs (everything the next update needs).

    Attributes
    ----------
    q : (B, 4) attitude quaternion ``q_b^n``, scalar first.
    v : (B, 3) velocity ``v^n`` ENU (m/s).
    p : (B, 3) position ``[L, λ, h]`` (rad, rad, m).
    a : (B, 3) last navigation-frame acceleration (for the mid-interval extrapolation).
    """

    q: BatchVector
    v: BatchVector
    p: BatchVector
    a: BatchVector


class NavSolution(NamedTuple):
    """Navigation solution at the output epochs: q (B, K, 4), v (B, K, 3), p (B, K, 3)."""

    q: BatchVector
    v: BatchVector
    p: BatchVector

    @property
    def euler(self) -> BatchVector:
        """``[θ, γ, ψ]`` (rad), (B, K, 3)."""
        return attitude.quat_to_euler(self.q)


def init_state(
    p: BatchVector, v: BatchVector, euler: BatchVector, batch: int | None = None
) -> InsState:
    """Initial state from position ``[L, λ, h]``, ENU velocity and ``[θ, γ, ψ]``.

    Inputs of shape (3,) are broadcast to ``batch`` runs (default 1); (B, 3) inputs
    give B runs.
    """
    p, v, euler = (np.asarray(a, dtype=float) for a in (p, v, euler))
    B = batch or max(a.shape[0] if a.ndim == 2 else 1 for a in (p, v, euler))
    p, v, euler = (np.broadcast_to(a, (B, 3)).copy() for a in (p, v, euler))
    if not np.all(np.abs(p[:, 0]) <= np.pi / 2):
        raise ValueError("p: latitude must be within ±90°")
    zeros = np.zeros((B, 3))
    return InsState(attitude.euler_to_quat(euler), v, p, zeros)


# ----------------------------------------------------------------------------- kernel


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _qmul(
    a0: float, a1: float, a2: float, a3: float, b0: float, b1: float, b2: float, b3: float
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _rv2q(
    x: float, y: float, z: float
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    n2 = x * x + y * y + z * z
    if n2 < 1e-16:  # |r| < 1e-8: series
        c = 1.0 - n2 / 8.0
        s = 0.5 - n2 / 48.0
    else:
        n = np.sqrt(n2)
        c = np.cos(0.5 * n)
        s = np.sin(0.5 * n) / n
    return c, s * x, s * y, s * z


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _cross(
    a0: float, a1: float, a2: float, b0: float, b1: float, b2: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _qrot(
    q0: float, q1: float, q2: float, q3: float, x: float, y: float, z: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """C(q) [x, y, z] for a unit quaternion."""
    t0, t1, t2 = _cross(q1, q2, q3, x, y, z)
    t0, t1, t2 = 2.0 * t0, 2.0 * t1, 2.0 * t2
    u0, u1, u2 = _cross(q1, q2, q3, t0, t1, t2)
    return x + q0 * t0 + u0, y + q0 * t1 + u1, z + q0 * t2 + u2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _run(
    b: int,
    q: BatchVector,
    v: BatchVector,
    p: BatchVector,
    a: BatchVector,
    dtheta: BatchVector,
    dv: BatchVector,
    dt: float,
    alg: int,
    gb: BatchVector,
    ab: BatchVector,
    every: int,
    q_out: BatchVector,
    v_out: BatchVector,
    p_out: BatchVector,
) -> None:  # pragma: no cover - compiled
    """Integrate run b over all its samples (sequential); writes the state back."""
    K = dtheta.shape[1]
    ns = 2 if alg == 2 else 1
    T = dt * ns
    q0, q1, q2, q3 = q[b, 0], q[b, 1], q[b, 2], q[b, 3]
    vE, vN, vU = v[b, 0], v[b, 1], v[b, 2]
    L, lam, h = p[b, 0], p[b, 1], p[b, 2]
    aE, aN, aU = a[b, 0], a[b, 1], a[b, 2]
    gx, gy, gz = gb[b, 0] * dt, gb[b, 1] * dt, gb[b, 2] * dt
    fx, fy, fz = ab[b, 0] * dt, ab[b, 1] * dt, ab[b, 2] * dt
    n_up = K // ns
    o = 0
    for n in range(n_up):
        k = n * ns
        tx, ty, tz = dtheta[b, k, 0] - gx, dtheta[b, k, 1] - gy, dtheta[b, k, 2] - gz
        wx, wy, wz = dv[b, k, 0] - fx, dv[b, k, 1] - fy, dv[b, k, 2] - fz
        if alg == 2:
            sx, sy, sz = (
                dtheta[b, k + 1, 0] - gx,
                dtheta[b, k + 1, 1] - gy,
                dtheta[b, k + 1, 2] - gz,
            )
            rx, ry, rz = dv[b, k + 1, 0] - fx, dv[b, k + 1, 1] - fy, dv[b, k + 1, 2] - fz
            c0, c1, c2 = _cross(tx, ty, tz, sx, sy, sz)
            phx, phy, phz = (
                tx + sx + 2.0 / 3.0 * c0,
                ty + sy + 2.0 / 3.0 * c1,
                tz + sz + 2.0 / 3.0 * c2,
            )
            Tx, Ty, Tz = tx + sx, ty + sy, tz + sz
            Vx, Vy, Vz = wx + rx, wy + ry, wz + rz
            r0, r1, r2 = _cross(Tx, Ty, Tz, Vx, Vy, Vz)
            s0, s1, s2 = _cross(tx, ty, tz, rx, ry, rz)
            e0, e1, e2 = _cross(wx, wy, wz, sx, sy, sz)
            dvx = Vx + 0.5 * r0 + 2.0 / 3.0 * (s0 + e0)
            dvy = Vy + 0.5 * r1 + 2.0 / 3.0 * (s1 + e1)
            dvz = Vz + 0.5 * r2 + 2.0 / 3.0 * (s2 + e2)
        else:
            r0, r1, r2 = _cross(tx, ty, tz, wx, wy, wz)
            phx, phy, phz = tx, ty, tz
            dvx, dvy, dvz = wx + 0.5 * r0, wy + 0.5 * r1, wz + 0.5 * r2
        # Earth quantities at the extrapolated mid-interval point
        hvE, hvN, hvU = vE + 0.5 * aE * T, vN + 0.5 * aN * T, vU + 0.5 * aU * T
        RMh, RNh = radii_nb(L, h)
        Lh = L + 0.5 * T * hvN / RMh
        hh = h + 0.5 * T * hvU
        RMh, RNh = radii_nb(Lh, hh)
        sL, cL = np.sin(Lh), np.cos(Lh)
        wieN, wieU = OMEGA_IE * cL, OMEGA_IE * sL
        wenE, wenN, wenU = -hvN / RMh, hvE / RNh, hvE * sL / cL / RNh
        winE, winN, winU = wenE, wieN + wenN, wieU + wenU
        g = gravity_nb(Lh, hh)
        # velocity
        fE, fN, fU = _qrot(q0, q1, q2, q3, dvx, dvy, dvz)
        k0, k1, k2 = _cross(winE, winN, winU, fE, fN, fU)
        fE, fN, fU = fE - 0.5 * T * k0, fN - 0.5 * T * k1, fU - 0.5 * T * k2
        c0, c1, c2 = _cross(winE, winN + wieN, winU + wieU, hvE, hvN, hvU)
        aE = fE / T - c0
        aN = fN / T - c1
        aU = fU / T - c2 - g
        nE, nN, nU = vE + aE * T, vN + aN * T, vU + aU * T
        # position (trapezoidal, M_pv at mid-interval)
        L = L + 0.5 * (vN + nN) / RMh * T
        lam = lam + 0.5 * (vE + nE) / (RNh * cL) * T
        h = h + 0.5 * (vU + nU) * T
        vE, vN, vU = nE, nN, nU
        # attitude
        b0, b1, b2, b3 = _rv2q(phx, phy, phz)
        q0, q1, q2, q3 = _qmul(q0, q1, q2, q3, b0, b1, b2, b3)
        m0, m1, m2, m3 = _rv2q(-winE * T, -winN * T, -winU * T)
        q0, q1, q2, q3 = _qmul(m0, m1, m2, m3, q0, q1, q2, q3)
        nq = np.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        if q0 < 0.0:
            nq = -nq
        q0, q1, q2, q3 = q0 / nq, q1 / nq, q2 / nq, q3 / nq
        if (n + 1) % every == 0:
            q_out[b, o, 0], q_out[b, o, 1], q_out[b, o, 2], q_out[b, o, 3] = q0, q1, q2, q3
            v_out[b, o, 0], v_out[b, o, 1], v_out[b, o, 2] = vE, vN, vU
            p_out[b, o, 0], p_out[b, o, 1], p_out[b, o, 2] = L, lam, h
            o += 1
    q[b, 0], q[b, 1], q[b, 2], q[b, 3] = q0, q1, q2, q3
    v[b, 0], v[b, 1], v[b, 2] = vE, vN, vU
    p[b, 0], p[b, 1], p[b, 2] = L, lam, h
    a[b, 0], a[b, 1], a[b, 2] = aE, aN, aU


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _integrate_serial(
    q: BatchVector,
    v: BatchVector,
    p: BatchVector,
    a: BatchVector,
    dtheta: BatchVector,
    dv: BatchVector,
    dt: float,
    alg: int,
    gb: BatchVector,
    ab: BatchVector,
    every: int,
    q_out: BatchVector,
    v_out: BatchVector,
    p_out: BatchVector,
) -> None:  # pragma: no cover - compiled
    for b in range(q.shape[0]):
        _run(b, q, v, p, a, dtheta, dv, dt, alg, gb, ab, every, q_out, v_out, p_out)


# ----------------------------------------------------------------------------- API


def integrate(
    state: InsState,
    dtheta: BatchVector,
    dv: BatchVector,
    dt: float,
    *,
    algorithm: str = "two-sample",
    gyro_bias: BatchVector | None = None,
    accel_bias: BatchVector | None = None,
    output_every: int = 1,
) -> tuple[InsState, NavSolution]:
    """Integrate IMU increments from ``state`` (spec §8.2).

    Parameters
    ----------
    state : the state at the start of the first increment.
    dtheta, dv : (B, K, 3) or (K, 3) body-frame increments (rad, m/s) over the IMU
        intervals; (K, 3) is shared by all B runs of ``state``.
    dt : IMU period T_s (s).
    algorithm : ``"two-sample"`` (K must be even) or ``"single-sample"`` (module
        docstring).
    gyro_bias, accel_bias : (B, 3) or (3,) estimated biases ε̂ (rad/s), ∇̂ (m/s²)
        subtracted from every sample (feedback of bias estimates, spec §8.5).
    output_every : keep the solution after every ``output_every``-th update.

    Returns
    -------
    (InsState, NavSolution) : the state after the last update, and the solution at the
        kept updates, (B, K // (ns · output_every), ...), ns = 2 for two-sample, else 1.
    """
    if algorithm not in ALGORITHMS:
        raise ValueError(f"algorithm: expected one of {sorted(ALGORITHMS)}, got {algorithm!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be a positive number of seconds, got {dt!r}")
    if int(output_every) != output_every or output_every < 1:
        raise ValueError(f"output_every: must be a positive integer, got {output_every!r}")
    alg = ALGORITHMS[algorithm]
    B = state.q.shape[0]
    dtheta = np.asarray(dtheta, dtype=float)
    dv = np.asarray(dv, dtype=float)
    if dtheta.shape != dv.shape or dtheta.shape[-1] != 3 or dtheta.ndim not in (2, 3):
        raise ValueError(
            f"dtheta, dv: expected equal shapes (B, K, 3) or (K, 3), got "
            f"{dtheta.shape} and {dv.shape}"
        )
    K = dtheta.shape[-2]
    if alg == 2 and K % 2:
        raise ValueError(
            f"dtheta: the two-sample algorithm needs an even number of samples, got {K}"
        )
    dtheta = np.ascontiguousarray(np.broadcast_to(dtheta, (B, K, 3)))
    dv = np.ascontiguousarray(np.broadcast_to(dv, (B, K, 3)))
    gb = np.ascontiguousarray(
        np.broadcast_to(0.0 if gyro_bias is None else gyro_bias, (B, 3)), dtype=float
    )
    ab = np.ascontiguousarray(
        np.broadcast_to(0.0 if accel_bias is None else accel_bias, (B, 3)), dtype=float
    )
    new = InsState(*(np.array(x, dtype=float, copy=True) for x in state))
    n_out = K // (2 if alg == 2 else 1) // output_every
    q_out, v_out, p_out = np.empty((B, n_out, 4)), np.empty((B, n_out, 3)), np.empty((B, n_out, 3))
    _integrate_serial(
        new.q,
        new.v,
        new.p,
        new.a,
        dtheta,
        dv,
        float(dt),
        alg,
        gb,
        ab,
        int(output_every),
        q_out,
        v_out,
        p_out,
    )
    return new, NavSolution(q_out, v_out, p_out)


def apply_correction(
    q: BatchVector,
    v: BatchVector,
    p: BatchVector,
    phi: BatchVector,
    dv: BatchVector,
    dp: BatchVector,
) -> tuple[BatchVector, BatchVector, BatchVector]:
    """Remove estimated errors from a navigation solution (spec §8.5).

    ``q ← q(φ̂) ⊗ q̃`` (i.e. ``C ← exp([φ̂×]) C̃ ≈ (I + [φ̂×]) C̃``), ``v ← ṽ − δv̂``,
    ``p ← p̃ − δp̂``; errors are computed − true (spec §0).  Used for output correction
    (the solution is corrected, the filter state is kept) and by :func:`feedback`.
    Shapes (B, 4) and (B, 3) run one compiled loop; other shapes broadcast (NumPy).
    """
    q, v, p, phi, dv, dp = (np.asarray(a, dtype=float) for a in (q, v, p, phi, dv, dp))
    if q.ndim == 2 and all(a.shape == q.shape[:1] + (3,) for a in (v, p, phi, dv, dp)):
        qc = np.empty_like(q)
        _correct_rows(np.ascontiguousarray(q), np.ascontiguousarray(phi), qc)
        return qc, v - dv, p - dp
    qc = attitude.quat_mul(attitude.rotvec_to_quat(phi), q)
    qc = qc / np.linalg.norm(qc, axis=-1, keepdims=True)
    return qc, v - dv, p - dp


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _correct_rows(
    q: BatchVector, phi: BatchVector, out: BatchVector
) -> None:  # pragma: no cover - compiled
    for b in range(q.shape[0]):
        r0, r1, r2, r3 = _rv2q(phi[b, 0], phi[b, 1], phi[b, 2])
        c0, c1, c2, c3 = _qmul(r0, r1, r2, r3, q[b, 0], q[b, 1], q[b, 2], q[b, 3])
        n = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3)
        out[b, 0], out[b, 1], out[b, 2], out[b, 3] = c0 / n, c1 / n, c2 / n, c3 / n


def navigation_errors(
    q: BatchVector,
    v: BatchVector,
    p: BatchVector,
    q_true: Vector,
    v_true: Vector,
    p_true: Vector,
) -> BatchVector:
    """(B, 9) true navigation error states ``[φ, δv, δL δλ δh]`` (spec §8.3 order).

    ``φ`` is :func:`ftnav.nav.attitude.quat_attitude_error` (the rotation vector of
    ``q_true ⊗ q̃*``), ``δv = ṽ − v``, ``δp = p̃ − p``; ``q``, ``v``, ``p`` (B, ·) are the
    INS solutions and the truth (4,), (3,), (3,) is shared.  One compiled loop.
    """
    q = np.ascontiguousarray(q, dtype=float)
    out = np.empty((q.shape[0], 9))
    _errors_rows(
        q,
        np.ascontiguousarray(v, dtype=float),
        np.ascontiguousarray(p, dtype=float),
        np.asarray(q_true, float),
        np.asarray(v_true, float),
        np.asarray(p_true, float),
        out,
    )
    return out


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _errors_rows(
    q: BatchVector,
    v: BatchVector,
    p: BatchVector,
    qt: Vector,
    vt: Vector,
    pt: Vector,
    out: BatchVector,
) -> None:  # pragma: no cover - compiled
    for b in range(q.shape[0]):
        # q_true ⊗ q̃*, sign fixed to a non-negative scalar part
        e0, e1, e2, e3 = _qmul(qt[0], qt[1], qt[2], qt[3], q[b, 0], -q[b, 1], -q[b, 2], -q[b, 3])
        n = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
        sg = 1.0 / n if e0 >= 0.0 else -1.0 / n
        e0, e1, e2, e3 = e0 * sg, e1 * sg, e2 * sg, e3 * sg
        sv = np.sqrt(e1 * e1 + e2 * e2 + e3 * e3)
        if sv < 1e-12:
            k = 2.0 / e0
        else:
            k = 2.0 * np.arctan2(sv, e0) / sv
        out[b, 0], out[b, 1], out[b, 2] = k * e1, k * e2, k * e3
        for i in range(3):
            out[b, 3 + i] = v[b, i] - vt[i]
            out[b, 6 + i] = p[b, i] - pt[i]


def feedback(state: InsState, phi: BatchVector, dv: BatchVector, dp: BatchVector) -> InsState:
    """Closed-loop correction of the mechanization state (spec §8.5).

    The caller zeroes the fed-back error states of its filter and passes the estimated
    biases to :func:`integrate` from then on.
    """
    q, v, p = apply_correction(state.q, state.v, state.p, phi, dv, dp)
    return state._replace(q=q, v=v, p=p)
