"""Linearized SINS error models: the 18-state model of spec §8.3 and a 15-state variant.

Frames, units and signs follow ``docs/conventions.md`` (spec §0): ENU navigation
frame, errors are **computed − true**, the attitude error φ is defined by
``C̃_b^n = (I − [φ×]) C_b^n``, position ``[L, λ, h]`` in rad, rad, m.

States (spec §8.3)::

    18: [φ_E, φ_N, φ_U, δv_E, δv_N, δv_U, δL, δλ, δh,
         ε_bx, ε_by, ε_bz, ε_rx, ε_ry, ε_rz, ∇_x, ∇_y, ∇_z]
    15: [φ_E, φ_N, φ_U, δv_E, δv_N, δv_U, δL, δλ, δh,
         ε_x, ε_y, ε_z, ∇_x, ∇_y, ∇_z]
    21: the 15 states, then [s_gx, s_gy, s_gz, s_ax, s_ay, s_az]

18 states: ε_b gyro random-constant drift, ε_r gyro first-order Gauss-Markov drift
(σ_g, T_g), ∇ accelerometer first-order Gauss-Markov bias (σ_a, T_a).

15 states (PSINS ``etm.m``/``kfinit.m`` style, a design choice of ftnav): ε is one
gyro bias and ∇ one accelerometer bias, each modelled as a **random walk**
``ε̇ = w_ε``, ``∇̇ = w_∇`` whose PSDs ``gyro_bias_rw_psd`` and ``accel_bias_rw_psd``
default to 0, i.e. a pure random constant exactly as in PSINS ``etm.m`` (zero rows
of F).  The Markov parameters are not used by the 15-state model; a positive
random-walk PSD lets a 15-state filter absorb slowly varying (Markov) drift.

21 states (the 15 and the gyro and accelerometer scale-factor errors, as KF-GINS's
21-state filter): the IMU reads ``ω̃ = (I + S_g) ω + ε``, ``f̃ = (I + S_a) f + ∇``
with ``S = diag(s)``, so the compensated output's error is ``ε + S_g ω_ib^b`` and
``∇ + S_a f^b``: the φ rows gain ``−C_b^n diag(ω_ib^b)`` on s_g and the δv rows
``C_b^n diag(f^b)`` on s_a.  The scale factors are random constants (no driving
noise); the model needs the body rate ``w_b`` and the body frame.

Continuous model ``ẋ = F x + G w`` with ``w = [w_g, w_v, w_3, w_4]`` (12 white
noises, PSDs ``q``): ``w_g`` gyro angle random walk (φ rows, ``−C_b^n``), ``w_v``
accelerometer white noise (δv rows, ``+C_b^n``; zero unless a VRW is given),
``w_3``/``w_4`` drive ε_r/∇ (18 states: ``q = 2σ²/T``) or the random walks of ε/∇
(15 states).  With ``bias_frame="nav"`` the mapping ``C_b^n`` of the bias columns and
of ``G`` is replaced by ``I`` (spec §8.3 [A], S1's platform wording).

Discretization (spec §8.4) is :func:`ftnav.core.discretize.van_loan` or
:func:`ftnav.core.discretize.series`; the filter evaluates F from the current INS
solution (:class:`NavState`) at each step through :func:`discrete_model`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numba
import numpy as np

from ftnav.core.discretize import series_row, van_loan
from ftnav.nav.attitude import skew
from ftnav.nav.earth import (
    OMEGA_IE,
    gravity_gradient,
    gravity_gradient_nb,
    omega_en_n,
    omega_ie_n,
    radii,
    radii_nb,
)
from ftnav.types import ArrayLike, BatchMatrix, BatchScalar, BatchVector, Matrix, Vector

__all__ = [
    "STATES_18",
    "STATES_15",
    "STATES_21",
    "ErrorModelParams",
    "ContinuousModel",
    "NavState",
    "continuous_model",
    "discrete_model",
]

STATES_18 = (
    "phi_E",
    "phi_N",
    "phi_U",
    "dv_E",
    "dv_N",
    "dv_U",
    "dL",
    "dlam",
    "dh",
    "eps_bx",
    "eps_by",
    "eps_bz",
    "eps_rx",
    "eps_ry",
    "eps_rz",
    "nabla_x",
    "nabla_y",
    "nabla_z",
)  #: state names of the 18-state model, in order (spec §8.3)
STATES_15 = STATES_18[:9] + ("eps_x", "eps_y", "eps_z", "nabla_x", "nabla_y", "nabla_z")
#: state names of the 15-state model, in order
STATES_21 = STATES_15 + ("sg_x", "sg_y", "sg_z", "sa_x", "sa_y", "sa_z")
#: state names of the 21-state model (15 + gyro and accelerometer scale factors), in order

Vec3 = tuple[float, float, float]


def _axes(name: str, value: ArrayLike, positive: bool = False) -> Vec3:
    try:
        a = np.broadcast_to(np.asarray(value, dtype=float), (3,))
    except ValueError:
        raise ValueError(f"{name} must be a scalar or three values, got {value!r}") from None
    if not np.all(np.isfinite(a)) or np.any(a < 0.0) or (positive and np.any(a == 0.0)):
        raise ValueError(
            f"{name} must be finite and {'> 0' if positive else '≥ 0'} on every axis, got {value!r}"
        )
    return float(a[0]), float(a[1]), float(a[2])


@dataclass(frozen=True, slots=True)
class ErrorModelParams:
    """Assumed IMU error parameters of the SINS error model (SI units; spec §8.3).

    Scalars apply to all three axes; per-axis values are given as three numbers
    (body x, y, z).  The gyro random-constant drift of the 18-state model has no
    driving noise; its size enters only through the filter's ``P0``.

    Attributes
    ----------
    gyro_psd : (3,) rad²/s, gyro angle-random-walk PSD ``q_g`` (ARW² in rad²/s; spec
        Table 1 reading: ``(0.01·π/180/60)²`` for 0.01°/√h).
    gyro_markov_sigma : (3,) rad/s, steady-state σ of the Markov drift ε_r.
    gyro_markov_tau : (3,) s, correlation time ``T_g`` of ε_r (> 0).
    accel_markov_sigma : (3,) m/s², steady-state σ of the Markov bias ∇.
    accel_markov_tau : (3,) s, correlation time ``T_a`` of ∇ (> 0).
    accel_psd : (3,) m²/s³, accelerometer white-noise (VRW²) PSD ``q_v``; default 0.
    gyro_bias_rw_psd : (3,) rad²/s³, 15 and 21 states: random-walk PSD of ε (0: constant).
    accel_bias_rw_psd : (3,) m²/s⁵, 15 and 21 states: random-walk PSD of ∇ (0: constant).
    bias_frame : ``"body"`` (default, ``C_b^n`` mapping) or ``"nav"`` (``C_b^n = I``;
        not with 21 states: a scale factor acts on a body axis).
    states : 18, 15 or 21.
    """

    gyro_psd: Vec3 = (0.0, 0.0, 0.0)
    gyro_markov_sigma: Vec3 = (0.0, 0.0, 0.0)
    gyro_markov_tau: Vec3 = (3600.0, 3600.0, 3600.0)
    accel_markov_sigma: Vec3 = (0.0, 0.0, 0.0)
    accel_markov_tau: Vec3 = (3600.0, 3600.0, 3600.0)
    accel_psd: Vec3 = (0.0, 0.0, 0.0)
    gyro_bias_rw_psd: Vec3 = (0.0, 0.0, 0.0)
    accel_bias_rw_psd: Vec3 = (0.0, 0.0, 0.0)
    bias_frame: Literal["body", "nav"] = "body"
    states: Literal[18, 15, 21] = 18

    def __post_init__(self) -> None:
        for name in (
            "gyro_psd",
            "gyro_markov_sigma",
            "accel_markov_sigma",
            "accel_psd",
            "gyro_bias_rw_psd",
            "accel_bias_rw_psd",
        ):
            object.__setattr__(self, name, _axes(name, getattr(self, name)))
        for name in ("gyro_markov_tau", "accel_markov_tau"):
            object.__setattr__(self, name, _axes(name, getattr(self, name), positive=True))
        if self.bias_frame not in ("body", "nav"):
            raise ValueError(f"bias_frame must be 'body' or 'nav', got {self.bias_frame!r}")
        if self.states not in (18, 15, 21):
            raise ValueError(f"states must be 18, 15 or 21, got {self.states!r}")
        if self.states == 21 and self.bias_frame != "body":
            raise ValueError(
                "states = 21 needs bias_frame 'body': a scale factor acts on a body axis"
            )

    @property
    def n(self) -> int:
        """Number of states."""
        return int(self.states)

    @property
    def names(self) -> tuple[str, ...]:
        """State names in order (:data:`STATES_18`, :data:`STATES_15` or :data:`STATES_21`)."""
        return {18: STATES_18, 15: STATES_15, 21: STATES_21}[self.states]

    @property
    def noise_psd(self) -> Vector:
        """``q`` (12,): PSDs of ``w = [w_g, w_v, w_3, w_4]`` (module docstring).

        18 states: ``q_r = 2σ_g²/T_g``, ``q_a = 2σ_a²/T_a`` (spec §8.3).
        """
        if self.states == 18:
            s_g, t_g = np.array(self.gyro_markov_sigma), np.array(self.gyro_markov_tau)
            s_a, t_a = np.array(self.accel_markov_sigma), np.array(self.accel_markov_tau)
            q3, q4 = 2.0 * s_g**2 / t_g, 2.0 * s_a**2 / t_a
        else:
            q3, q4 = np.array(self.gyro_bias_rw_psd), np.array(self.accel_bias_rw_psd)
        return np.concatenate([self.gyro_psd, self.accel_psd, q3, q4])


class ContinuousModel(NamedTuple):
    """Continuous error model ``ẋ = F x + G w``, ``E[w wᵀ] = diag(q) δ(t−s)``.

    Attributes
    ----------
    F : (..., n, n) system matrix (1/s, mixed state units).
    G : (..., n, 12) noise input matrix.
    q : (12,) noise PSDs (shared by the batch).
    """

    F: BatchMatrix
    G: BatchMatrix
    q: Vector

    @property
    def GQGt(self) -> BatchMatrix:
        """``G diag(q) Gᵀ`` (..., n, n)."""
        GQGt: BatchMatrix = (self.G * self.q) @ np.swapaxes(self.G, -1, -2)
        return GQGt


class NavState(NamedTuple):
    """INS solution at an epoch, the point where the error model is linearized (spec §8.4).

    Attributes
    ----------
    L : (B,) latitude, rad.
    lam : (B,) longitude, rad (F does not depend on it).
    h : (B,) height, m.
    v_enu : (B, 3) velocity, m/s.
    f_b : (B, 3) specific force in the body frame (bias-compensated IMU output), m/s².
    C_bn : (B, 3, 3) attitude ``C_b^n``.
    """

    L: BatchScalar
    lam: BatchScalar
    h: BatchScalar
    v_enu: BatchVector
    f_b: BatchVector
    C_bn: BatchMatrix


def _mat(rows: Sequence[Sequence[ArrayLike]], batch: tuple[int, ...]) -> BatchMatrix:
    """Fill (batch, 3, 3) from a nested 3×3 list of scalars/arrays (one allocation)."""
    out = np.empty(batch + (3, 3))
    for i, r in enumerate(rows):
        for j, e in enumerate(r):
            out[..., i, j] = e
    return out


def _nav_blocks(L: BatchScalar, h: BatchScalar, v: BatchVector, f_n: BatchVector) -> BatchMatrix:
    """The 9×9 navigation blocks of F (spec §8.3), shape ``L.shape + (9, 9)``."""
    batch = L.shape
    s, c, t = np.sin(L), np.cos(L), np.tan(L)
    RMh, RNh = radii(L, h)
    vE, vN = v[..., 0], v[..., 1]
    w_ie = omega_ie_n(L)
    w_en = omega_en_n(L, h, v)
    z = np.zeros(batch)
    F_av = _mat([[z, -1.0 / RMh, z], [1.0 / RNh, z, z], [t / RNh, z, z]], batch)
    M1 = _mat([[z, z, z], [-OMEGA_IE * s, z, z], [OMEGA_IE * c, z, z]], batch)
    M2 = _mat(
        [[z, z, vN / RMh**2], [z, z, -vE / RNh**2], [vE / (RNh * c**2), z, -vE * t / RNh**2]], batch
    )
    dgdL, dgdh = gravity_gradient(L, h)
    F_g = _mat([[z, z, z], [z, z, z], [-dgdL, z, -dgdh]], batch)
    Vx = skew(v)
    F = np.zeros(batch + (9, 9))
    F[..., 0:3, 0:3] = -skew(w_ie + w_en)
    F[..., 0:3, 3:6] = F_av
    F[..., 0:3, 6:9] = M1 + M2
    F[..., 3:6, 0:3] = skew(f_n)
    F[..., 3:6, 3:6] = Vx @ F_av - skew(2.0 * w_ie + w_en)
    F[..., 3:6, 6:9] = Vx @ (2.0 * M1 + M2) + F_g
    F[..., 6:9, 3:6] = _mat([[z, 1.0 / RMh, z], [1.0 / (RNh * c), z, z], [z, z, z + 1.0]], batch)
    F[..., 6:9, 6:9] = _mat(
        [[z, z, -vN / RMh**2], [vE * t / (RNh * c), z, -vE / (RNh**2 * c)], [z, z, z]], batch
    )
    return F


def _nav_inputs(
    L: ArrayLike, h: ArrayLike, v_enu: BatchVector, f_b: BatchVector, C_bn: BatchMatrix
) -> tuple[BatchScalar, BatchScalar, BatchVector, BatchVector, BatchMatrix, tuple[int, ...]]:
    L, h = np.asarray(L, dtype=float), np.asarray(h, dtype=float)
    v, f_b, C = (np.asarray(a, dtype=float) for a in (v_enu, f_b, C_bn))
    batch = L.shape
    if h.shape == batch and v.shape == f_b.shape == batch + (3,) and C.shape == batch + (3, 3):
        return L, h, v, f_b, C, batch  # one batch shape already: nothing to broadcast
    if v.shape[-1:] != (3,) or f_b.shape[-1:] != (3,) or C.shape[-2:] != (3, 3):
        raise ValueError(
            f"v_enu and f_b must be (..., 3) and C_bn (..., 3, 3); got "
            f"{v.shape}, {f_b.shape}, {C.shape}"
        )
    try:
        batch = np.broadcast_shapes(L.shape, h.shape, v.shape[:-1], f_b.shape[:-1], C.shape[:-2])
    except ValueError as err:
        raise ValueError(f"navigation inputs do not broadcast: {err}") from None
    L, h = np.broadcast_to(L, batch), np.broadcast_to(h, batch)
    v = np.broadcast_to(v, batch + (3,))
    f_b = np.broadcast_to(f_b, batch + (3,))
    C = np.broadcast_to(C, batch + (3, 3))
    return L, h, v, f_b, C, batch


def continuous_model(
    L: ArrayLike,
    lam: ArrayLike,
    h: ArrayLike,
    v_enu: BatchVector,
    f_b: BatchVector,
    C_bn: BatchMatrix,
    params: ErrorModelParams,
    *,
    w_b: BatchVector | None = None,
) -> ContinuousModel:
    """Continuous SINS error model ``(F, G, q)`` linearized at an INS solution (spec §8.3).

    ``φ̇ = F_aa φ + F_av δv + F_ap δp − C_b^n (ε_b + ε_r) − C_b^n w_g``,
    ``δv̇ = [f^n×] φ + F_vv δv + F_vp δp + C_b^n ∇ + C_b^n w_v``,
    ``δṗ = F_pv δv + F_pp δp``, ``ε̇_b = 0``, ``ε̇_r = −ε_r/T_g + w_r``,
    ``∇̇ = −∇/T_a + w_a`` (18 states; 15 states: module docstring), with the blocks
    ``F_aa = −[ω_in^n×]``, ``F_ap = M1 + M2``, ``F_vv = [v×]F_av − [(2ω_ie^n + ω_en^n)×]``,
    ``F_vp = [v×](2M1 + M2) + F_g`` etc. as printed in spec §8.3 (PSINS ``etm.m``).
    The blocks neglect ∂R_M/∂L and ∂R_N/∂L (an O(e²) effect, spec §8.6 c).

    Built by one compiled loop over the batch (it runs at every filter epoch of the
    closed-loop runner); :func:`continuous_model_reference` is the same model in
    plain NumPy, its test oracle.

    Parameters
    ----------
    L, lam, h : (...) latitude (rad), longitude (rad, unused), height (m).
    v_enu : (..., 3) ENU velocity, m/s.
    f_b : (..., 3) body specific force, m/s²; ``f^n = C_b^n f^b``.
    C_bn : (..., 3, 3) attitude ``C_b^n``.
    params : ErrorModelParams.
    w_b : (..., 3) body angular rate ω_ib^b (bias-compensated gyro output), rad/s;
        needed by the 21-state model (its scale-factor columns), unused otherwise.

    Returns
    -------
    ContinuousModel with ``F`` (..., n, n), ``G`` (..., n, 12), ``q`` (12,).
    """
    L, h, v, f_b, C, batch = _nav_inputs(L, h, v_enu, f_b, C_bn)
    n = params.n
    M = int(np.prod(batch))
    F, G = np.zeros((M, n, n)), np.zeros((M, n, 12))
    _model_rows(
        *_flat_inputs(L, h, v, f_b, C, M),
        _body_rate(w_b, batch, params, M),
        params.bias_frame == "body",
        n,
        np.asarray(params.gyro_markov_tau, float),
        np.asarray(params.accel_markov_tau, float),
        F,
        G,
    )
    return ContinuousModel(F.reshape(batch + (n, n)), G.reshape(batch + (n, 12)), params.noise_psd)


def _body_rate(
    w_b: BatchVector | None, batch: tuple[int, ...], params: ErrorModelParams, M: int
) -> BatchVector:
    """``w_b`` flattened to (M, 3); zeros where the model does not use it."""
    if w_b is None:
        if params.n == 21:
            raise ValueError("w_b: the 21-state model needs the body angular rate")
        return np.zeros((M, 3))
    w = np.asarray(w_b, dtype=float)
    if w.shape[-1:] != (3,):
        raise ValueError(f"w_b must be (..., 3), got {w.shape}")
    return np.ascontiguousarray(np.broadcast_to(w, batch + (3,))).reshape(M, 3)


def _flat_inputs(
    L: BatchScalar, h: BatchScalar, v: BatchVector, f_b: BatchVector, C: BatchMatrix, M: int
) -> tuple[BatchScalar, BatchScalar, BatchVector, BatchVector, BatchMatrix]:
    return (
        np.ascontiguousarray(L, float).reshape(M),
        np.ascontiguousarray(h, float).reshape(M),
        np.ascontiguousarray(v, float).reshape(M, 3),
        np.ascontiguousarray(f_b, float).reshape(M, 3),
        np.ascontiguousarray(C, float).reshape(M, 3, 3),
    )


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _skew_into(
    F: Matrix, r: int, c: int, sign: float, a0: float, a1: float, a2: float
) -> None:  # pragma: no cover - compiled
    """``F[r:r+3, c:c+3] += sign·[a×]``."""
    F[r, c + 1] += -sign * a2
    F[r, c + 2] += sign * a1
    F[r + 1, c] += sign * a2
    F[r + 1, c + 2] += -sign * a0
    F[r + 2, c] += -sign * a1
    F[r + 2, c + 1] += sign * a0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _model_row(
    L: float,
    h: float,
    v: Vector,
    f_b: Vector,
    C: Matrix,
    w_b: Vector,
    body: bool,
    n: int,
    tau_g: Vector,
    tau_a: Vector,
    F: Matrix,
    G: Matrix,
) -> None:  # pragma: no cover
    """F (n, n) and G (n, 12) of :func:`continuous_model` at one INS solution (zeroed)."""
    Fav = np.zeros((3, 3))
    Fap = np.zeros((3, 3))
    Fvp = np.zeros((3, 3))
    Cb = np.zeros((3, 3))
    s, c = np.sin(L), np.cos(L)
    t = s / c
    RMh, RNh = radii_nb(L, h)
    vE, vN, vU = v[0], v[1], v[2]
    wie = (0.0, OMEGA_IE * c, OMEGA_IE * s)
    wen = (-vN / RMh, vE / RNh, vE * t / RNh)
    dgdL, dgdh = gravity_gradient_nb(L, h)
    fn = np.zeros(3)
    for i in range(3):
        for j in range(3):
            fn[i] += C[i, j] * f_b[j]
            Cb[i, j] = C[i, j] if body else (1.0 if i == j else 0.0)
    # F_av, M1 + M2 (F_ap) and F_vp = [v×](2 M1 + M2) + F_g
    Fav[0, 1] = -1.0 / RMh
    Fav[1, 0] = 1.0 / RNh
    Fav[2, 0] = t / RNh
    m1 = np.zeros((3, 3))
    m1[1, 0] = -OMEGA_IE * s
    m1[2, 0] = OMEGA_IE * c
    m2 = np.zeros((3, 3))
    m2[0, 2] = vN / RMh**2
    m2[1, 2] = -vE / RNh**2
    m2[2, 0] = vE / (RNh * c**2)
    m2[2, 2] = -vE * t / RNh**2
    Vx = np.array([[0.0, -vU, vN], [vU, 0.0, -vE], [-vN, vE, 0.0]])
    for i in range(3):
        for j in range(3):
            Fap[i, j] = m1[i, j] + m2[i, j]
            a = 0.0
            d = 0.0
            for p in range(3):
                a += Vx[i, p] * (2.0 * m1[p, j] + m2[p, j])
                d += Vx[i, p] * Fav[p, j]
            Fvp[i, j] = a
            F[0 + i, 3 + j] = Fav[i, j]
            F[0 + i, 6 + j] = Fap[i, j]
            F[3 + i, 3 + j] = d
    Fvp[2, 0] += -dgdL
    Fvp[2, 2] += -dgdh
    for i in range(3):
        for j in range(3):
            F[3 + i, 6 + j] = Fvp[i, j]
    _skew_into(F, 0, 0, -1.0, wie[0] + wen[0], wie[1] + wen[1], wie[2] + wen[2])
    _skew_into(F, 3, 0, 1.0, fn[0], fn[1], fn[2])
    _skew_into(F, 3, 3, -1.0, 2.0 * wie[0] + wen[0], 2.0 * wie[1] + wen[1], 2.0 * wie[2] + wen[2])
    F[6, 4] = 1.0 / RMh
    F[7, 3] = 1.0 / (RNh * c)
    F[8, 5] = 1.0
    F[6, 8] = -vN / RMh**2
    F[7, 6] = vE * t / (RNh * c)
    F[7, 8] = -vE / (RNh**2 * c)
    for i in range(3):
        for j in range(3):
            F[i, 9 + j] = -Cb[i, j]
            G[i, j] = -Cb[i, j]
            G[3 + i, 3 + j] = Cb[i, j]
            if n == 18:
                F[i, 12 + j] = -Cb[i, j]
                F[3 + i, 15 + j] = Cb[i, j]
            else:
                F[3 + i, 12 + j] = Cb[i, j]
            if n == 21:  # scale factors: −C_b^n diag(ω_ib^b), C_b^n diag(f^b)
                F[i, 15 + j] = -Cb[i, j] * w_b[j]
                F[3 + i, 18 + j] = Cb[i, j] * f_b[j]
        if n == 18:
            F[12 + i, 12 + i] = -1.0 / tau_g[i]
            F[15 + i, 15 + i] = -1.0 / tau_a[i]
            G[12 + i, 6 + i] = 1.0
            G[15 + i, 9 + i] = 1.0
        else:
            G[9 + i, 6 + i] = 1.0
            G[12 + i, 9 + i] = 1.0


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _model_rows(
    L: BatchScalar,
    h: BatchScalar,
    v: BatchVector,
    f_b: BatchVector,
    C: BatchMatrix,
    w_b: BatchVector,
    body: bool,
    n: int,
    tau_g: Vector,
    tau_a: Vector,
    F: BatchMatrix,
    G: BatchMatrix,
) -> None:  # pragma: no cover
    for b in range(L.shape[0]):
        _model_row(L[b], h[b], v[b], f_b[b], C[b], w_b[b], body, n, tau_g, tau_a, F[b], G[b])


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _discrete_rows(
    L: BatchScalar,
    h: BatchScalar,
    v: BatchVector,
    f_b: BatchVector,
    C: BatchMatrix,
    w_b: BatchVector,
    body: bool,
    n: int,
    tau_g: Vector,
    tau_a: Vector,
    q: Vector,
    T: float,
    order: int,
    Phi: BatchMatrix,
    Q: BatchMatrix,
) -> None:  # pragma: no cover - compiled
    """Φ, Q (M, n, n) of :func:`discrete_model` with ``method="series"``, one loop."""
    F, G, GQGt = np.empty((n, n)), np.empty((n, 12)), np.empty((n, n))
    X, nxt, Mj, FM = np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    for b in range(L.shape[0]):
        F[:, :] = 0.0
        G[:, :] = 0.0
        _model_row(L[b], h[b], v[b], f_b[b], C[b], w_b[b], body, n, tau_g, tau_a, F, G)
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for w in range(12):
                    acc += G[i, w] * q[w] * G[j, w]
                GQGt[i, j] = acc
                GQGt[j, i] = acc
        series_row(F, GQGt, T, order, Phi[b], Q[b], X, nxt, Mj, FM)


def continuous_model_reference(
    L: ArrayLike,
    lam: ArrayLike,
    h: ArrayLike,
    v_enu: BatchVector,
    f_b: BatchVector,
    C_bn: BatchMatrix,
    params: ErrorModelParams,
    *,
    w_b: BatchVector | None = None,
) -> ContinuousModel:
    """Plain NumPy form of :func:`continuous_model` (the compiled kernel's test oracle)."""
    L, h, v, f_b, C, batch = _nav_inputs(L, h, v_enu, f_b, C_bn)
    n = params.n
    w = _body_rate(w_b, batch, params, int(np.prod(batch))).reshape(batch + (3,))
    f_n = (C @ f_b[..., None])[..., 0]
    Cb = C if params.bias_frame == "body" else np.broadcast_to(np.eye(3), batch + (3, 3))
    F = np.zeros(batch + (n, n))
    F[..., :9, :9] = _nav_blocks(L, h, v, f_n)
    F[..., 0:3, 9:12] = -Cb
    G = np.zeros(batch + (n, 12))
    G[..., 0:3, 0:3] = -Cb
    G[..., 3:6, 3:6] = Cb
    if n == 18:
        F[..., 0:3, 12:15] = -Cb
        F[..., 3:6, 15:18] = Cb
        idx = np.arange(3)
        F[..., 12 + idx, 12 + idx] = -1.0 / np.array(params.gyro_markov_tau)
        F[..., 15 + idx, 15 + idx] = -1.0 / np.array(params.accel_markov_tau)
        G[..., 12:15, 6:9] = np.eye(3)
        G[..., 15:18, 9:12] = np.eye(3)
    else:
        F[..., 3:6, 12:15] = Cb
        G[..., 9:12, 6:9] = np.eye(3)
        G[..., 12:15, 9:12] = np.eye(3)
    if n == 21:
        F[..., 0:3, 15:18] = -Cb * w[..., None, :]
        F[..., 3:6, 18:21] = Cb * f_b[..., None, :]
    return ContinuousModel(F, G, params.noise_psd)


Method = Literal["van-loan", "series"]


def discrete_model(
    L: ArrayLike,
    lam: ArrayLike,
    h: ArrayLike,
    v_enu: BatchVector,
    f_b: BatchVector,
    C_bn: BatchMatrix,
    params: ErrorModelParams,
    T: float,
    method: Method = "van-loan",
    order: int = 5,
    *,
    w_b: BatchVector | None = None,
) -> tuple[BatchMatrix, BatchMatrix]:
    """Discrete SINS error model ``(Φ_k, Q_k)`` over a step T (spec §8.3, §8.4).

    F is held at the given INS solution over the step; ``method="van-loan"`` is exact
    for that F, ``"series"`` is the PSINS ``kfc2d`` series of the given ``order``.

    Parameters
    ----------
    L, lam, h, v_enu, f_b, C_bn, params, w_b : as in :func:`continuous_model`.
    T : float, step in seconds (> 0).
    method : ``"van-loan"`` or ``"series"``.
    order : int, series order (``method="series"`` only).

    Returns
    -------
    Phi : (..., n, n) transition matrix.
    Q : (..., n, n) discrete process-noise covariance.
    """
    if method not in ("van-loan", "series"):
        raise ValueError(f"method must be 'van-loan' or 'series', got {method!r}")
    T = float(T)
    if not np.isfinite(T) or T <= 0.0:
        raise ValueError(f"T must be positive and finite, got {T!r}")
    if method == "van-loan":
        m = continuous_model(L, lam, h, v_enu, f_b, C_bn, params, w_b=w_b)
        return van_loan(m.F, m.GQGt, T)
    if int(order) != order or order < 1:
        raise ValueError(f"order must be an integer ≥ 1, got {order}")
    L, h, v, f_b, C, batch = _nav_inputs(L, h, v_enu, f_b, C_bn)
    n, M = params.n, int(np.prod(batch))
    Phi, Q = np.empty((M, n, n)), np.empty((M, n, n))
    _discrete_rows(
        *_flat_inputs(L, h, v, f_b, C, M),
        _body_rate(w_b, batch, params, M),
        params.bias_frame == "body",
        n,
        np.asarray(params.gyro_markov_tau, float),
        np.asarray(params.accel_markov_tau, float),
        params.noise_psd,
        float(T),
        int(order),
        Phi,
        Q,
    )
    return Phi.reshape(batch + (n, n)), Q.reshape(batch + (n, n))
