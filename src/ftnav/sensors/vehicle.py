"""Land-vehicle constraints as aids: non-holonomic constraint and zero-velocity update.

Both are pseudo-measurements of a vehicle's motion, not of a device; their "reading"
is the constraint's value (0) plus the white noise that stands for how well the
vehicle keeps it.  Conventions as every aid (``docs/conventions.md``): ``z = INS − aid``
in the aid's metric space, ``H`` on the 18 error states of spec §8.3, attitude error
``C̃_b^n = (I − [φ×]) C_b^n``.

* :class:`Nhc` — a wheeled vehicle does not slide sideways nor leave the road: the
  body-frame velocity ``v^b = C_n^b v^n`` has no right (x) and no up (z) component
  (body frame x right, y forward, z up).  Rows ``[v^b_x, v^b_z]`` (m/s)::

      z = C̃_n^b ṽ^n  ≈  v^b + C_n^b δv − C_n^b [v^n ×] φ      (v^b_x = v^b_z = 0)

  so ``H_δv = C_n^b`` and ``H_φ = −C_n^b [v^n ×]`` (rows x and z).  The constraint
  holds at a point of the vehicle (the rear axle's centre for a car), ``lever_arm_m``
  ``l`` from the IMU in the body frame (default 0: the IMU is taken there, and the arm
  is part of the noise σ: in a turn at ω the IMU ``d`` ahead of the axle slides
  sideways at ``ω d``).  With an arm the rows are the point's velocity,
  ``v^b + ω_eb^b × l`` with ``ω_eb^b = ω_ib^b − C_n^b ω_ie^n`` (``ω_ib^b`` the gyro's
  rate at the epoch, the ``w_ib`` of ``measure``), which adds
  ``−[l×] C_n^b [ω_ie^n×]`` to ``H_φ``.  Mounting misalignment of the IMU against the
  vehicle's axes stays part of the noise σ.
* :class:`Zupt` — a vehicle at rest: ``z = ṽ^n`` (3 rows, E, N, U, m/s), ``H_δv = I``.
  Which epochs are at rest is decided outside the filter, from the IMU alone
  (:func:`ftnav.recorded.imu.stationary`); the aid is available only there.

Both are gated (``gate_probability``, 0: off): an epoch whose innovation's χ² against
the filter's prior fails the gate is left out (the constraint does not hold there: a
slip in a hard turn, a creep the IMU reads as a stop), neither used nor tested for a
fault (:func:`ftnav.fusion.locals.gated`).

Simulation: the reading is white noise of σ (spawn key component 0), a vehicle that
keeps the constraint up to that noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.nav.attitude import quat_to_dcm, skew
from ftnav.nav.earth import omega_ie_n, omega_ie_n_dL
from ftnav.sensors.base import (
    N_STATES,
    AidErrors,
    AidTruth,
    Linearized,
    as_batch,
    check_common,
    check_errors_metric,
    check_float,
    check_truth,
    finite_or_zero,
    standard_normals,
)

__all__ = ["Nhc", "Zupt"]


@dataclass(frozen=True, slots=True)
class _Constraint:
    """What both constraints share: a white σ per row and a zero reading."""

    name: str = "constraint"
    sigma_m_s: float = 0.1
    dt: float = 1.0
    gate_probability: float = 1e-3

    z_per_error: ClassVar[int] = -1
    components: ClassVar[tuple[str, ...]] = ()
    #: a pseudo-measurement: its recorded output is 0 by design, so a repeat of it is no
    #: frozen sensor (:func:`ftnav.model.streams.repeated`; the engine reads this)
    pseudo: ClassVar[bool] = True

    def __post_init__(self) -> None:
        check_common(self)
        object.__setattr__(
            self,
            "sigma_m_s",
            check_float(self.name, "sigma_m_s", self.sigma_m_s, low=0.0, strict=True),
        )
        p = check_float(self.name, "gate_probability", self.gate_probability, low=0.0)
        if p >= 1.0:
            raise ValueError(f"{self.name}.gate_probability: must be in [0, 1), got {p}")
        object.__setattr__(self, "gate_probability", p)

    @property
    def dim(self) -> int:
        """Measurement rows (the length of :attr:`components`)."""
        return len(self.components)

    @property
    def R(self) -> np.ndarray:
        """(m, m) (m/s)², ``σ² I``."""
        return np.eye(self.dim) * self.sigma_m_s**2

    @property
    def private(self) -> PrivateStates | None:
        """No private states."""
        return None

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """White noise of σ per row (B, K, m)."""
        K = check_truth(truth, self.dt, self.name)
        white = standard_normals(seed, runs, stream, 0, (K, self.dim)) * self.sigma_m_s
        return AidErrors(np.zeros_like(white), white, np.zeros((len(runs), 0)))

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """The constraint's reading (B, K, m): 0 plus the error."""
        K = check_truth(truth, self.dt, self.name)
        e, _ = check_errors_metric(errors_metric, constants, (None, K, self.dim), 0)
        return np.asarray(e, dtype=float)


@dataclass(frozen=True, slots=True)
class Nhc(_Constraint):
    """Non-holonomic constraint (module docstring): rows ``v^b_x, v^b_z`` (m/s) of the
    point ``lever_arm_m`` (3,) m from the IMU, body frame right, forward, up."""

    name: str = "nhc"
    sigma_m_s: float = 0.1
    lever_arm_m: tuple[float, float, float] | float = 0.0

    components: ClassVar[tuple[str, ...]] = ("vel_x", "vel_z")

    def __post_init__(self) -> None:
        super(Nhc, self).__post_init__()
        arm = check_float(self.name, "lever_arm_m", self.lever_arm_m, n=3)
        object.__setattr__(self, "lever_arm_m", arm)

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = (C̃_n^b ṽ + ω̃_eb × l)_{x,z} − reading`` (B, 2) and ``H`` (B, 2, 18).

        Parameters
        ----------
        q : (B, 4) INS ``q_b^n``.  v : (B, 3) ENU m/s.  p : (B, 3) ``[L, λ, h]`` (read
        with a lever arm only).  raw_k : (B, 2) the reading (0 for a recording).
        w_ib : (B, 3) rad/s, the gyro's rate at the epoch (needed with a lever arm).
        """
        v = as_batch(v, (3,), "v")
        B = v.shape[0]
        C_bn = np.swapaxes(quat_to_dcm(as_batch(q, (4,), "q", B)), -1, -2)
        raw = as_batch(raw_k, (2,), "raw_k", B)
        v_b = np.einsum("bij,bj->bi", C_bn, v)
        H = np.zeros((B, 3, N_STATES))
        H[:, :, 3:6] = C_bn
        H[:, :, 0:3] = -C_bn @ skew(v)
        if any(self.lever_arm_m):  # the point the constraint holds for (module docstring)
            if w_ib is None:
                raise ValueError(f"{self.name}: a lever arm needs the rate w_ib")
            arm = np.asarray(self.lever_arm_m, dtype=float)
            L = as_batch(p, (3,), "p", B)[:, 0]
            w_ie = omega_ie_n(L)
            w_ie_b = np.einsum("bij,bj->bi", C_bn, w_ie)
            v_b = v_b + np.cross(as_batch(w_ib, (3,), "w_ib", B) - w_ie_b, arm)
            H[:, :, 0:3] -= skew(arm) @ C_bn @ skew(w_ie)
            # the Earth's rate in the body turns with latitude
            w_ie_b_dL = np.einsum("bij,bj->bi", C_bn, omega_ie_n_dL(L))
            H[:, :, 6] += np.einsum("ij,bj->bi", skew(arm), w_ie_b_dL)
        z = v_b[:, [0, 2]] - raw
        H = H[:, [0, 2]]
        valid = np.all(np.isfinite(z), -1)
        return Linearized(finite_or_zero(z), H, np.zeros((B, 2, 0)), valid)


@dataclass(frozen=True, slots=True)
class Zupt(_Constraint):
    """Zero-velocity update (module docstring): rows ``v_E, v_N, v_U`` (m/s)."""

    name: str = "zupt"
    sigma_m_s: float = 0.02

    components: ClassVar[tuple[str, ...]] = ("vel_E", "vel_N", "vel_U")

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = ṽ − reading`` (B, 3) and ``H`` (B, 3, 18) with I on δv.

        Parameters
        ----------
        q, p : (unused).  v : (B, 3) ENU m/s.  raw_k : (B, 3) the reading (0 at rest).
        """
        v = as_batch(v, (3,), "v")
        B = v.shape[0]
        z = v - as_batch(raw_k, (3,), "raw_k", B)
        H = np.zeros((B, 3, N_STATES))
        H[:, [0, 1, 2], [3, 4, 5]] = 1.0
        valid = np.all(np.isfinite(z), -1)
        return Linearized(finite_or_zero(z), H, np.zeros((B, 3, 0)), valid)
