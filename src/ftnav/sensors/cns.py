"""Celestial navigation / star-tracker attitude aid (spec §9.4; S2).

Three measurement rows (m = 3, rad).  Two forms [A]:

* ``form="dcm"`` (default): ``z = attitude_error(C̃_b^n, C_CNS)``, the rotation vector
  ρ with ``C̃ = exp(−[ρ×]) C_CNS`` (spec §9.4 ``[z×] = I − C̃ C_CNSᵀ`` to first order,
  PSINS qq2phi), rows E, N, U; ``H = [I₃, 0]``.  Metric error η (rad, n frame): the
  device attitude is ``C_CNS = exp(−[η×]) C_b^n`` (the exact rotation, so
  ``attitude_error(C_CNS, C) = η`` exactly and ``z ≈ φ − η``).
* ``form="euler"`` (S2: roll, pitch and heading in the geographic frame):
  ``z = ã − a_CNS`` with ``a = [θ pitch, γ roll, ψ yaw]`` (:mod:`ftnav.nav.attitude`),
  the roll and yaw differences wrapped to (−π, π].  Metric error δa (rad): the device attitude
  is ``a_CNS = a + δa``, so ``z ≈ −M(a)⁻¹ φ − δa``.  The rows of ``H`` on φ (spec §9.4,
  confirmed by finite differences against ``dcm_to_euler``)::

      δθ: [−cψ, −sψ, 0],  δγ: [sψ/cθ, −cψ/cθ, 0],  δψ: [−tθ sψ, tθ cψ, −1]

  (ψ counter-clockwise; singular at θ = ±90°).

In both forms the metric error is the aid's own error, ``z_per_error = −1``; the
simulated error is white with σ = ``sigma_arcsec`` per row and ``R = σ² I₃``.

Position coupling (``position_coupling=True``, spec §9.4, §9.7 d): the CNS attitude
is referred to the INS-computed local level.  The device then logs its attitude in
Earth-fixed axes, ``C_b^e = C_n^e(L, λ) C_CNS`` — the star tracker's inertial attitude
``C_b^i`` rotated by its own clock, ``C_b^e = C_i^e(t) C_b^i``; the clock is taken as
exact, so t cancels and :meth:`StarTracker.measure` needs no time — and the filter
forms ``C_CNS' = C_n^e(L̃, λ̃)ᵀ C_b^e``.  That frame is rotated from the true one by
``δθ = [−δL, δλ cos L, δλ sin L]``, so ``z ≈ φ − δθ − η``: ``H`` gains +1 at (E, δL)
and −cos L, −sin L at (N, δλ), (U, δλ) (PSINS ``sinsgpscns.m``); the Euler form
gets ``−M⁻¹`` times these rows.  Without position coupling the raw output is
``q_b^n`` of ``C_CNS``.

Random components (spawn key ``c``): 0 white.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.nav.attitude import (
    attitude_error,
    dcm_to_euler,
    dcm_to_quat,
    euler_to_dcm,
    quat_to_dcm,
    skew,
    wrap_angle,
)
from ftnav.sensors.base import (
    N_STATES,
    AidErrors,
    AidTruth,
    Linearized,
    as_batch,
    check_bool,
    check_choice,
    check_common,
    check_errors_metric,
    check_float,
    check_truth,
    finite_or_zero,
    standard_normals,
)

__all__ = ["StarTracker", "dcm_n_to_e", "euler_jacobian"]

ARCSEC = math.pi / 180.0 / 3600.0  #: one arc-second in rad


def dcm_n_to_e(L, lam) -> np.ndarray:
    """``C_n^e`` (…, 3, 3): columns are the ENU unit vectors in ECEF at ``(L, λ)`` (rad)."""
    L, lam = np.broadcast_arrays(np.asarray(L, dtype=float), np.asarray(lam, dtype=float))
    sL, cL, sl, cl = np.sin(L), np.cos(L), np.sin(lam), np.cos(lam)
    z = np.zeros_like(L)
    return np.stack(
        [
            np.stack([-sl, -sL * cl, cL * cl], -1),
            np.stack([cl, -sL * sl, cL * sl], -1),
            np.stack([z, cL, sL], -1),
        ],
        -2,
    )


def euler_jacobian(a: np.ndarray) -> np.ndarray:
    """``∂a/∂φ = −M(a)⁻¹`` (…, 3, 3) for ``C̃ = exp(−[φ×]) C`` (spec §9.4)."""
    a = np.asarray(a, dtype=float)
    th, psi = a[..., 0], a[..., 2]
    c, s, ct, tt = np.cos(psi), np.sin(psi), np.cos(th), np.tan(th)
    J = np.zeros(a.shape[:-1] + (3, 3))
    J[..., 0, 0], J[..., 0, 1] = -c, -s
    J[..., 1, 0], J[..., 1, 1] = s / ct, -c / ct
    J[..., 2, 0], J[..., 2, 1], J[..., 2, 2] = -tt * s, tt * c, -1.0
    return J


def _rotation(eta: np.ndarray) -> np.ndarray:
    """``exp([η×])`` (…, 3, 3) by Rodrigues' formula."""
    th = np.linalg.norm(eta, axis=-1)[..., None, None]
    K = skew(eta)
    small = th < 1e-8
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


@dataclass(frozen=True, slots=True)
class StarTracker:
    """Star-tracker attitude aid (module docstring).

    Attributes
    ----------
    name : str.
    sigma_arcsec : float, arcsec, white attitude noise σ per row (S2's value lost; 10″ [A]).
    form : ``"dcm"`` (rows φ_E, φ_N, φ_U) or ``"euler"`` (rows pitch, roll, yaw).
    position_coupling : bool, attitude referred to the INS-computed local level.
    assumed_sigma_arcsec : float, optional, the filter's assumed σ (default ``sigma_arcsec``).
    dt : float, s, sample period.
    """

    name: str = "cns"
    sigma_arcsec: float = 10.0
    form: Literal["dcm", "euler"] = "dcm"
    position_coupling: bool = False
    assumed_sigma_arcsec: float | None = None
    dt: float = 1.0

    z_per_error: ClassVar[int] = -1

    def __post_init__(self):
        check_common(self, ("assumed_sigma_arcsec",))
        object.__setattr__(
            self, "sigma_arcsec", check_float(self.name, "sigma_arcsec", self.sigma_arcsec, low=0.0)
        )
        check_choice(self.name, "form", self.form, ("dcm", "euler"))
        check_bool(self.name, "position_coupling", self.position_coupling)

    @property
    def dim(self) -> int:
        """Measurement dimension m = 3."""
        return 3

    @property
    def components(self) -> tuple[str, ...]:
        """Row names: ``phi_E, phi_N, phi_U`` (dcm) or ``pitch, roll, yaw`` (euler)."""
        return ("phi_E", "phi_N", "phi_U") if self.form == "dcm" else ("pitch", "roll", "yaw")

    @property
    def R(self) -> np.ndarray:
        """(3, 3) rad², ``σ² I₃`` with the assumed σ."""
        s = self.sigma_arcsec if self.assumed_sigma_arcsec is None else self.assumed_sigma_arcsec
        return (s * ARCSEC) ** 2 * np.eye(3)

    @property
    def private(self) -> PrivateStates | None:
        """No private states."""
        return None

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """White metric error (B, K, 3) rad with σ = ``sigma_arcsec``."""
        K = check_truth(truth, self.dt, self.name)
        white = standard_normals(seed, runs, stream, 0, (K, 3)) * (self.sigma_arcsec * ARCSEC)
        B = len(runs)
        return AidErrors(np.zeros((B, K, 3)), white, np.zeros((B, 0)))

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """Device attitude quaternion (B, K, 4): ``q_b^n`` of C_CNS, or ``q_b^e`` with
        position coupling (module docstring)."""
        K = check_truth(truth, self.dt, self.name)
        e, _ = check_errors_metric(errors_metric, constants, (None, K, 3), 0)
        C = quat_to_dcm(truth.q)  # (K, 3, 3)
        if self.form == "dcm":
            C_cns = _rotation(-e) @ C
        else:
            C_cns = euler_to_dcm(dcm_to_euler(C) + e)
        if self.position_coupling:
            p = np.asarray(truth.p, dtype=float)
            C_cns = dcm_n_to_e(p[:, 0], p[:, 1]) @ C_cns
        return dcm_to_quat(C_cns)

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z`` (B, 3) rad and ``H`` (B, 3, 18) at the INS solution (module docstring).

        Parameters
        ----------
        q : (B, 4) INS ``q_b^n``.  v : (B, 3) (unused).  p : (B, 3) ``[L, λ, h]``.
        raw_k : (B, 4) device quaternion at this epoch (:meth:`output`).
        """
        q = as_batch(q, (4,), "q")
        B = q.shape[0]
        as_batch(v, (3,), "v", B)
        p = as_batch(p, (3,), "p", B)
        raw = as_batch(raw_k, (4,), "raw_k", B)
        C_ins = quat_to_dcm(q)
        C_cns = quat_to_dcm(raw)
        H = np.zeros((B, 3, N_STATES))
        H[:, [0, 1, 2], [0, 1, 2]] = 1.0
        if self.position_coupling:
            L, lam = p[:, 0], p[:, 1]
            C_cns = np.swapaxes(dcm_n_to_e(L, lam), -1, -2) @ C_cns
            H[:, 0, 6] = 1.0
            H[:, 1, 7] = -np.cos(L)
            H[:, 2, 7] = -np.sin(L)
        if self.form == "dcm":
            z = attitude_error(C_ins, C_cns)
        else:
            a_ins = dcm_to_euler(C_ins)
            z = a_ins - dcm_to_euler(C_cns)
            z[:, 1:] = wrap_angle(z[:, 1:])
            H = euler_jacobian(a_ins) @ H
        valid = np.all(np.isfinite(z), -1)
        return Linearized(finite_or_zero(z), H, np.zeros((B, 3, 0)), valid)
