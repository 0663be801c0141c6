"""Aircraft trajectory generator: declarative segments → truth and ideal IMU increments.

Spec §10.  A :class:`Profile` is a start state and a list of :class:`Segment` s with
constant commands in the trajectory frame (speed-and-direction convention, spec
§10.1 (ii)): speed ``V̇ = a_f``, Euler-angle rates ``θ̇, γ̇, ψ̇`` or a coordinated turn
``ψ̇ = −g tan γ / V`` (right-positive roll turns right, i.e. ψ decreases); the velocity
points along the trajectory-frame forward axis ``v^n = V [−sψ cθ, cψ cθ, sθ]``.

Within a segment speed and attitude are closed-form functions of time, so the only
numerical integration is the position, ``ṗ = M_pv(p) v^n(t)`` (RK4 at twice the IMU
rate, then cubic Hermite interpolation), and the increments

    Δθ = ∫ ω_ib^b dt,  ω_ib^b = C_n^b (ω_nb^n + ω_in^n),
    Δv = ∫ f^b dt,     f^b = C_n^b (v̇^n + (2ω_ie^n + ω_en^n) × v^n − g^n)

(spec §10.2) are integrated exactly on each IMU interval up to 3-point
Gauss–Legendre quadrature (error O(T⁷) on the smooth integrand; segment boundaries
fall on IMU sample times, which the profile enforces).  The Earth model is
:mod:`ftnav.nav.earth`, the same as the mechanization's.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from ftnav.model.flight import Profile, Segment
from ftnav.nav import earth
from ftnav.nav.attitude import heading_deg

__all__ = ["Trajectory", "generate"]

_GL_X = np.array([-math.sqrt(0.6), 0.0, math.sqrt(0.6)])  # Gauss–Legendre nodes on [−1, 1]
_GL_W = np.array([5.0, 8.0, 5.0]) / 9.0


class Trajectory(NamedTuple):
    """Truth at the IMU sample times and the ideal IMU increments between them.

    Attributes
    ----------
    t : (K+1,) times (s), ``t[0] = 0``.
    p : (K+1, 3) ``[L, λ, h]`` (rad, rad, m).   v : (K+1, 3) ENU velocity (m/s).
    euler : (K+1, 3) ``[θ, γ, ψ]`` (rad).
    dtheta, dv : (K, 3) body increments (rad, m/s) over ``(t[k], t[k+1]]``.
    segment : (K+1,) index of the segment each sample belongs to.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    euler: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    segment: np.ndarray

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def heading_deg(self) -> np.ndarray:
        """Heading clockwise from North (deg) at the samples."""
        return heading_deg(self.euler[:, 2])


class _Kinematics(NamedTuple):
    V: np.ndarray
    Vdot: np.ndarray
    euler: np.ndarray  # (…, 3) θ, γ, ψ
    rates: np.ndarray  # (…, 3) θ̇, γ̇, ψ̇
    psi_ddot: np.ndarray


def _segment_kinematics(
    seg: Segment, V0: float, euler0: np.ndarray, g_c: float, tau
) -> _Kinematics:
    """Closed-form speed and attitude at local times ``tau`` of a segment."""
    tau = np.asarray(tau, dtype=float)
    V = V0 + seg.accel * tau
    theta = euler0[0] + seg.pitch_rate * tau
    gamma = euler0[1] + seg.roll_rate * tau
    if seg.yaw_rate is None:  # coordinated turn, roll constant in the segment
        k = g_c * math.tan(euler0[1])
        if seg.accel == 0.0:
            psi = euler0[2] - k * tau / V0
        else:
            psi = euler0[2] - k / seg.accel * np.log(V / V0)
        psi_dot = -k / V
        psi_ddot = k * seg.accel / V**2
    else:
        psi = euler0[2] + seg.yaw_rate * tau
        psi_dot = np.full_like(tau, seg.yaw_rate)
        psi_ddot = np.zeros_like(tau)
    rates = np.stack(
        [np.full_like(tau, seg.pitch_rate), np.full_like(tau, seg.roll_rate), psi_dot], -1
    )
    return _Kinematics(
        V, np.full_like(tau, seg.accel), np.stack([theta, gamma, psi], -1), rates, psi_ddot
    )


def _velocity(k: _Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """``v^n = V u(θ, ψ)`` and ``v̇^n`` (…, 3)."""
    th, ps = k.euler[..., 0], k.euler[..., 2]
    st, ct, sp, cp = np.sin(th), np.cos(th), np.sin(ps), np.cos(ps)
    u = np.stack([-sp * ct, cp * ct, st], -1)
    du_dth = np.stack([sp * st, -cp * st, ct], -1)
    du_dps = np.stack([-cp * ct, -sp * ct, np.zeros_like(st)], -1)
    vdot = k.Vdot[..., None] * u + k.V[..., None] * (
        du_dth * k.rates[..., 0:1] + du_dps * k.rates[..., 2:3]
    )
    return k.V[..., None] * u, vdot


def _dcm(euler: np.ndarray) -> np.ndarray:
    """``C_b^n = R_z(ψ) R_x(θ) R_y(γ)`` (…, 3, 3), closed form.

    Same as :func:`ftnav.nav.attitude.euler_to_dcm` (scipy) to rounding, and twice as fast
    on the ~10⁶ quadrature nodes of a long profile (generation time halves).
    """
    th, ga, ps = euler[..., 0], euler[..., 1], euler[..., 2]
    st, ct, sg, cg, sp, cp = np.sin(th), np.cos(th), np.sin(ga), np.cos(ga), np.sin(ps), np.cos(ps)
    return np.stack(
        [
            np.stack([cp * cg - sp * st * sg, -sp * ct, cp * sg + sp * st * cg], -1),
            np.stack([sp * cg + cp * st * sg, cp * ct, sp * sg - cp * st * cg], -1),
            np.stack([-ct * sg, st, ct * cg], -1),
        ],
        -2,
    )


def _omega_nb_n(euler: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """``ω_nb^n = e₃ψ̇ + R_z(ψ) e₁ θ̇ + R_z(ψ) R_x(θ) e₂ γ̇`` (spec §10.2)."""
    th, ps = euler[..., 0], euler[..., 2]
    st, ct, sp, cp = np.sin(th), np.cos(th), np.sin(ps), np.cos(ps)
    thd, gad, psd = rates[..., 0], rates[..., 1], rates[..., 2]
    return np.stack([cp * thd - sp * ct * gad, sp * thd + cp * ct * gad, psd + st * gad], -1)


@numba.njit(cache=True, error_model="numpy")
def _rk4_position(p0, v_stage, h):  # pragma: no cover - compiled
    """RK4 of ``ṗ = M_pv(p) v(t)`` with v given at t, t+h/2, t+h for each step.

    ``v_stage`` is (n, 3, 3): step, stage (start, middle, end), ENU.  Returns (n+1, 3)
    positions and (n+1, 3) position rates.
    """
    n = v_stage.shape[0]
    p = np.empty((n + 1, 3))
    pd = np.empty((n + 1, 3))
    p[0] = p0
    acc = np.empty(3)
    y = np.empty(3)
    for k in range(n + 1):
        L, h_ = p[k, 0], p[k, 2]
        j = k if k < n else n - 1
        s = 0 if k < n else 2
        RMh, RNh = earth.radii_nb(L, h_)
        pd[k, 0] = v_stage[j, s, 1] / RMh
        pd[k, 1] = v_stage[j, s, 0] / (RNh * np.cos(L))
        pd[k, 2] = v_stage[j, s, 2]
        if k == n:
            break
        k1 = pd[k]
        for i in range(3):
            acc[i] = k1[i]
            y[i] = p[k, i] + 0.5 * h * k1[i]
        for stage in range(3):
            vs = v_stage[k, 1 if stage < 2 else 2]
            RMh, RNh = earth.radii_nb(y[0], y[2])
            d0 = vs[1] / RMh
            d1 = vs[0] / (RNh * np.cos(y[0]))
            d2 = vs[2]
            w = 2.0 if stage < 2 else 1.0
            acc[0] += w * d0
            acc[1] += w * d1
            acc[2] += w * d2
            f = 0.5 if stage == 0 else 1.0
            if stage < 2:
                y[0] = p[k, 0] + f * h * d0
                y[1] = p[k, 1] + f * h * d1
                y[2] = p[k, 2] + f * h * d2
        for i in range(3):
            p[k + 1, i] = p[k, i] + h / 6.0 * acc[i]
    return p, pd


class Unflyable(ValueError):
    """A profile the local-level mechanization cannot fly (bad input: the message is one
    line naming the profile's field)."""


#: the latitude (deg) a flight may not reach: the north-east-up frame's transport rate
#: (``tan L``) and longitude rate (``1/cos L``) are singular at the poles
MAX_LATITUDE_DEG = 89.5


def generate(profile: Profile) -> Trajectory:
    """Truth and ideal IMU increments of a profile at its IMU rate (spec §10.2).

    Raises
    ------
    ValueError : a segment that cannot be flown (message names the segment field).
    Unflyable : a flight that reaches :data:`MAX_LATITUDE_DEG` (a flight over the pole
        gave latitude 90.097° and a run 33 m off with a 1 m GNSS, exit 0).
    """
    T = profile.dt
    counts = [int(round(s.duration / T)) for s in profile.segments]
    K = sum(counts)
    t = T * np.arange(K + 1)
    p_all = np.empty((K + 1, 3))
    v_all = np.empty((K + 1, 3))
    e_all = np.empty((K + 1, 3))
    seg_all = np.empty(K + 1, dtype=int)
    dth = np.empty((K, 3))
    dvv = np.empty((K, 3))
    p0 = np.array(profile.start.position, dtype=float)
    V0 = float(profile.start.speed)
    eul0 = np.array(profile.start.euler, dtype=float)
    k0 = 0
    for j, (seg, n) in enumerate(zip(profile.segments, counts, strict=True)):
        g_c = float(earth.gravity(p0[0], p0[2]))
        # position by RK4 on the sample grid, with v at the stage times
        tau = T * np.arange(n + 1)
        stages = np.stack([tau[:-1], tau[:-1] + 0.5 * T, tau[1:]], -1)
        v_stage, _ = _velocity(_segment_kinematics(seg, V0, eul0, g_c, stages))
        p, pd = _rk4_position(p0, np.ascontiguousarray(v_stage), T)
        polar = np.abs(p[:, 0]) >= np.radians(MAX_LATITUDE_DEG)
        if polar.any():
            i = int(np.argmax(polar))
            raise Unflyable(
                f"profile: segments[{j}] reaches latitude {np.degrees(p[i, 0]):.3f} deg at "
                f"t = {t[k0 + i]:.1f} s: the north-east-up mechanization is singular at the "
                f"poles (a flight stays within ±{MAX_LATITUDE_DEG:g} deg)"
            )
        kin = _segment_kinematics(seg, V0, eul0, g_c, tau)
        v, _ = _velocity(kin)
        sl = slice(k0, k0 + n + 1)
        p_all[sl], v_all[sl], e_all[sl], seg_all[sl] = p, v, kin.euler, j
        # increments: 3-point Gauss–Legendre on each interval
        x = 0.5 * (_GL_X + 1.0)  # nodes in (0, 1)
        tn = tau[:-1, None] + T * x[None, :]  # (n, 3)
        # cubic Hermite position at the nodes
        h00, h10, h01, h11 = (
            2 * x**3 - 3 * x**2 + 1,
            x**3 - 2 * x**2 + x,
            -2 * x**3 + 3 * x**2,
            x**3 - x**2,
        )
        pn = (
            h00[None, :, None] * p[:-1, None]
            + h10[None, :, None] * T * pd[:-1, None]
            + h01[None, :, None] * p[1:, None]
            + h11[None, :, None] * T * pd[1:, None]
        )
        kn = _segment_kinematics(seg, V0, eul0, g_c, tn)
        vn, vdn = _velocity(kn)
        L, hgt = pn[..., 0], pn[..., 2]
        w_ie = earth.omega_ie_n(L)
        w_en = earth.omega_en_n(L, hgt, vn)
        C = _dcm(kn.euler)
        w_nb = _omega_nb_n(kn.euler, kn.rates)
        g_n = np.zeros_like(vn)
        g_n[..., 2] = -earth.gravity(L, hgt)
        w_ib_n = w_nb + w_ie + w_en
        f_n = vdn + np.cross(2.0 * w_ie + w_en, vn) - g_n
        # C_n^b x = Cᵀ x
        w_ib_b = np.einsum("...ji,...j->...i", C, w_ib_n)
        f_b = np.einsum("...ji,...j->...i", C, f_n)
        dth[k0 : k0 + n] = 0.5 * T * np.einsum("m,nmi->ni", _GL_W, w_ib_b)
        dvv[k0 : k0 + n] = 0.5 * T * np.einsum("m,nmi->ni", _GL_W, f_b)
        # next segment starts where this one ends
        p0, V0, eul0 = p[-1].copy(), float(kin.V[-1]), kin.euler[-1].copy()
        k0 += n
    return Trajectory(t, p_all, v_all, e_all, dth, dvv, seg_all)
