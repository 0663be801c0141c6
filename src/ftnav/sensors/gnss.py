"""GNSS position and velocity aid (spec §9.1; S1 eq. 17, S2).

Measurement rows (m = 6), metric space ``e = [δE, δN, δU (m), δv_E, δv_N, δv_U (m/s)]``,
East, North, Up for position and velocity alike (``docs/conventions.md``)::

    z_p = D_p(p̃) (p̃ − p_GNSS)   rows E, N, U (m),  D_p: E ← (R_Nh cos L) δλ, N ← R_Mh δL
    z_v = ṽ − v_GNSS              rows E, N, U (m/s)

so ``H_p`` maps the ``(δL, δλ, δh)`` columns to rows (N, E, U) = (R_Mh, R_Nh cos L, 1)
and ``H_v = I₃`` on δv; ``R`` follows the same row order.

Truth (spec §9.1): ``p_GNSS = p + D_p(p)⁻¹ e_pos`` and ``v_GNSS = v + e_vel`` with
``e = b + n``: ``b`` first-order Gauss-Markov per axis (S1: σ_p 25 m, σ_v 0.05 m/s,
τ 100 s), ``n`` white (defaults 1 m, 0.02 m/s [A]).  The metric error is the aid's
error, so ``z = H x − e`` (``z_per_error = −1``).

Coloured-noise handling ``markov`` [A]: ``"augment"`` (the default) adds the 6 Markov
errors as private states (order of :attr:`Gnss.components`) with ``H_private = −I₆``,
``R = diag(σ_n²)``, and adds nothing when every Markov σ is 0; ``"white"`` lumps the
Markov part into ``R = diag(σ_b² + σ_n²)`` (S1's choice; with the default 25 m, 100 s
error every filter is overconfident, ``docs/claims.md``);
``"difference"`` differences consecutive measurements (Bryson & Henrikson 1968,
:func:`ftnav.core.kalman.differenced_measurement`): ``z* = z_k − ψ z_{k−1}`` with
``ψ = e^{−dt/τ}`` (:attr:`Gnss.difference_factor`) removes the Markov part up to its
driving noise, ``R* = diag(σ_b²(1 − ψ²) + (1 + ψ²) σ_n²)``; the correlation of ``z*``
with the previous epoch's white noise and with the process noise is neglected.

Rows ``rows`` [A]: ``"position-velocity"`` (the 6 rows above), ``"position"`` (E, N, U
position rows) or ``"velocity"`` (the velocity rows): one receiver as two aids of their own
(two local filters of a federated or distributed fusion, each with its own test), the
Markov states, R and the simulated errors restricted to the rows measured; the receiver
output stays the 6 columns (a velocity-only aid's position columns are ignored).

Per-epoch σ ``per_epoch_sigma`` [A]: the receiver output carries each epoch's own σ of
the six rows after the six values (``[L, λ, h, v_E, v_N, v_U, σ_pE, σ_pN, σ_pU, σ_vE,
σ_vN, σ_vU]``; a solution file's ``sdn, sde, sdu, sdvn, ...``), and the epoch's
measurement is whitened to them: each row of ``z``, ``H`` and ``H_private`` is scaled by
``s = σ_R / σ_k`` (``σ_R`` the row's σ in :attr:`R`), so the filter weighs the row as if
``R_k = diag(σ_k²)`` — exact for a diagonal R, and the χ² statistic is that of ``R_k``.
A σ that is missing (NaN) or ≤ 0 keeps the row's :attr:`R` (``s = 1``).  The recorded
R̂ stays :attr:`R`.  Simulation appends the configured σ (the same filter as without).

Random components (spawn key ``c``): 0 position Markov, 1 velocity Markov, 2 white.  The
position draws of each run are taken in the order N, E, U (the row order before the rows
became E, N, U) and then reordered, so a run's errors are those of earlier versions.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar, Literal

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.nav.attitude import quat_to_dcm, skew
from ftnav.nav.earth import omega_ie_n, omega_ie_n_dL, radii
from ftnav.sensors.base import (
    N_STATES,
    AidErrors,
    AidTruth,
    Linearized,
    as_batch,
    check_choice,
    check_common,
    check_errors_metric,
    check_float,
    check_truth,
    finite_or_zero,
    markov_errors,
    markov_private,
    standard_normals,
)

__all__ = ["Gnss"]

Vec3 = float | tuple[float, float, float]


#: E, N, U rows from N, E, U columns (and back: the permutation is its own inverse)
_EN = [1, 0, 2]


def _metres(p: np.ndarray) -> np.ndarray:
    """(…, 3) metres per unit of ``[δL, δλ, δh]``: ``(R_Mh, R_Nh cos L, 1)`` (rows N, E, U)."""
    RMh, RNh = radii(p[..., 0], p[..., 2])
    return np.stack([RMh, RNh * np.cos(p[..., 0]), np.ones_like(RMh)], -1)


@dataclass(frozen=True, slots=True)
class Gnss:
    """GNSS position/velocity receiver (spec §9.1); all parameters in SI units.

    Attributes
    ----------
    name : str, sensor name (prefix of error messages).
    pos_markov_sigma_m : float or (3,) E, N, U, steady-state σ of the position Markov error.
    pos_markov_tau_s : float or (3,), its correlation time (> 0).
    vel_markov_sigma_m_s : float or (3,) E, N, U, velocity Markov σ.
    vel_markov_tau_s : float or (3,), its correlation time (> 0).
    pos_white_sigma_m : float or (3,) E, N, U, white position noise σ.
    vel_white_sigma_m_s : float or (3,) E, N, U, white velocity noise σ.
    markov : ``"white"``, ``"augment"`` or ``"difference"`` (module docstring).
    pos_sigma_m, vel_sigma_m_s : float, optional
        The filter's assumed σ per axis (overrides the value derived from the truth
        settings: ``√(σ_b² + σ_n²)`` for ``"white"``, ``σ_n`` for ``"augment"``, the
        differenced noise for ``"difference"``).
    dt : float, s, sample period (Markov simulation, F and Q of the private states).
    rows : ``"position-velocity"``, ``"position"`` or ``"velocity"`` (module docstring).
    per_epoch_sigma : bool, the output carries each epoch's σ (module docstring).
    lever_arm_m : (3,) m, the antenna from the IMU in the body frame (x right, y forward,
        z up).  The position rows compare the antenna, ``p̃ + C̃_b^n l``, whose attitude
        column is ``[(C_b^n l)×]``; the velocity rows the antenna's velocity
        ``ṽ + C̃_b^n (ω_ib^b × l) − ω_ie^n × (C̃_b^n l)`` (the body's rate relative to
        the Earth, ``ω_eb^b``, turning the arm; ``ω_ib^b`` the gyro's rate at the epoch,
        :meth:`measure`'s ``w_ib``), whose attitude column is
        ``[(C_b^n (ω_ib^b × l))×] − [ω_ie^n×][(C_b^n l)×]``.  The gyro bias's column
        (``|l|`` times the bias's error: 0.1 mm/s for 2.6 m and 10 °/h) is left out.
        Simulation puts the antenna there as well (its rate from the trajectory,
        :attr:`AidTruth.w`).

    Vector fields are stored as tuples of 3 floats.

    Raises
    ------
    ValueError
        ``"<name>.<field>: <reason>"`` for a negative σ, τ ≤ 0, non-finite values or an
        unknown ``markov`` option.
    """

    name: str = "gnss"
    pos_markov_sigma_m: Vec3 = 25.0
    pos_markov_tau_s: Vec3 = 100.0
    vel_markov_sigma_m_s: Vec3 = 0.05
    vel_markov_tau_s: Vec3 = 100.0
    pos_white_sigma_m: Vec3 = 1.0
    vel_white_sigma_m_s: Vec3 = 0.02
    markov: Literal["white", "augment", "difference"] = "augment"
    pos_sigma_m: float | None = None
    vel_sigma_m_s: float | None = None
    dt: float = 1.0
    lever_arm_m: Vec3 = 0.0
    rows: Literal["position-velocity", "position", "velocity"] = "position-velocity"
    per_epoch_sigma: bool = False

    z_per_error: ClassVar[int] = -1
    ALL_COMPONENTS: ClassVar[tuple[str, ...]] = (
        "pos_E",
        "pos_N",
        "pos_U",
        "vel_E",
        "vel_N",
        "vel_U",
    )

    def __post_init__(self):
        check_common(self, ("pos_sigma_m", "vel_sigma_m_s"))
        for field in (
            "pos_markov_sigma_m",
            "vel_markov_sigma_m_s",
            "pos_white_sigma_m",
            "vel_white_sigma_m_s",
        ):
            object.__setattr__(
                self, field, check_float(self.name, field, getattr(self, field), low=0.0, n=3)
            )
        for field in ("pos_markov_tau_s", "vel_markov_tau_s"):
            object.__setattr__(
                self,
                field,
                check_float(self.name, field, getattr(self, field), low=0.0, strict=True, n=3),
            )
        check_choice(self.name, "markov", self.markov, ("white", "augment", "difference"))
        check_choice(self.name, "rows", self.rows, ("position-velocity", "position", "velocity"))
        if self.per_epoch_sigma and self.markov == "difference":
            raise ValueError(
                f"{self.name}.per_epoch_sigma: not with markov = 'difference' (a difference "
                "of two epochs whitened to different σ is not the differenced measurement)"
            )
        object.__setattr__(
            self, "lever_arm_m", check_float(self.name, "lever_arm_m", self.lever_arm_m, n=3)
        )

    @property
    def _rows(self) -> slice:
        """The measured rows of the 6 (module docstring)."""
        return {"position": slice(0, 3), "velocity": slice(3, 6)}.get(self.rows, slice(0, 6))

    @property
    def components(self) -> tuple[str, ...]:
        """Names of the measured rows (of :attr:`ALL_COMPONENTS`)."""
        return self.ALL_COMPONENTS[self._rows]

    @property
    def dim(self) -> int:
        """Measurement dimension m: 6, or 3 for a position or velocity aid."""
        return len(self.components)

    @property
    def _markov_sigma(self) -> np.ndarray:
        return np.array(self.pos_markov_sigma_m + self.vel_markov_sigma_m_s)[self._rows]

    @property
    def _markov_tau(self) -> np.ndarray:
        return np.array(self.pos_markov_tau_s + self.vel_markov_tau_s)[self._rows]

    @property
    def R(self) -> np.ndarray:
        """(m, m) the filter's assumed measurement noise (rows of :attr:`components`)."""
        var = np.array(self.pos_white_sigma_m + self.vel_white_sigma_m_s)[self._rows] ** 2
        if self.markov == "white":
            var = var + self._markov_sigma**2
        elif self.markov == "difference":
            psi = self.difference_factor
            var = self._markov_sigma**2 * (1.0 - psi**2) + (1.0 + psi**2) * var
        full = np.full(6, np.nan)
        full[self._rows] = var
        if self.pos_sigma_m is not None:
            full[:3] = self.pos_sigma_m**2
        if self.vel_sigma_m_s is not None:
            full[3:] = self.vel_sigma_m_s**2
        return np.diag(full[self._rows])

    @property
    def sigma_all(self) -> np.ndarray:
        """(6,) the configured σ of all six values E, N, U (m), v_E, v_N, v_U (m/s),
        whichever rows are measured: the square root of the diagonal of R over every
        row."""
        return np.sqrt(np.diag(replace(self, rows="position-velocity").R))

    @property
    def difference_factor(self) -> np.ndarray | None:
        """(m,) ``ψ = e^{−dt/τ}`` of each component for ``markov="difference"``, else None.

        The closed-loop runner then passes ``z_k − ψ z_{k−1}`` and the matching ``H*`` to
        the filters (:func:`ftnav.core.kalman.differenced_measurement`).
        """
        if self.markov != "difference":
            return None
        return np.exp(-self.dt / self._markov_tau)

    @property
    def _augmented(self) -> bool:
        return self.markov == "augment" and bool(np.any(self._markov_sigma > 0))

    @property
    def private(self) -> PrivateStates | None:
        """The m Markov states for ``markov="augment"`` (``H = −I_m``), else None.

        None also when every Markov σ is 0: there is nothing to augment.
        """
        if not self._augmented:
            return None
        return markov_private(
            tuple(f"b_{c}" for c in self.components),
            self._markov_sigma,
            self._markov_tau,
            self.dt,
            -np.eye(self.dim),
        )

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """Metric errors ``e = b + n`` (B, K, m) of runs ``runs`` (module docstring).

        The 6 components are drawn whatever :attr:`rows` is (a run's draws do not depend
        on it) and the measured rows returned."""
        K = check_truth(truth, self.dt, self.name)
        # position draws in N, E, U order (module docstring), rows E, N, U
        pos = markov_errors(
            seed,
            runs,
            stream,
            0,
            K,
            np.array(self.pos_markov_sigma_m)[_EN],
            np.array(self.pos_markov_tau_s)[_EN],
            self.dt,
        )[..., _EN]
        vel = markov_errors(
            seed,
            runs,
            stream,
            1,
            K,
            np.array(self.vel_markov_sigma_m_s),
            np.array(self.vel_markov_tau_s),
            self.dt,
        )
        white = standard_normals(seed, runs, stream, 2, (K, 6))
        white[..., :3] = white[..., _EN]
        white *= np.array(self.pos_white_sigma_m + self.vel_white_sigma_m_s)
        r = self._rows
        return AidErrors(
            np.concatenate([pos, vel], -1)[..., r], white[..., r], np.zeros((len(runs), 0))
        )

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """Receiver output (B, K, 6) ``[L, λ, h (rad, rad, m), v_E, v_N, v_U (m/s)]``.

        ``p_GNSS = p + D_p(p)⁻¹ e_pos`` (``e_pos`` in E, N, U metres), ``v_GNSS = v + e_vel``;
        ``errors_metric`` (B, K, m) holds the measured rows, the others are error-free.
        """
        K = check_truth(truth, self.dt, self.name)
        e_m, _ = check_errors_metric(errors_metric, constants, (None, K, self.dim), 0)
        e = np.zeros(e_m.shape[:-1] + (6,))
        e[..., self._rows] = e_m
        d = _metres(np.asarray(truth.p, dtype=float))  # (K, 3) N, E, U per L, λ, h
        if any(self.lever_arm_m):  # the antenna's position and velocity (class docstring)
            if truth.w is None:
                raise ValueError(f"{self.name}.lever_arm_m: the truth carries no body rate w")
            arm_p, arm_v = self._arm(np.asarray(truth.q), np.asarray(truth.p), truth.w)
            e = e + np.concatenate([arm_p, arm_v], -1)
        dp = e[..., _EN] / d  # δL = δN/R_Mh, δλ = δE/(R_Nh cos L), δh = δU
        out = np.concatenate([truth.p + dp, truth.v + e[..., 3:]], -1)
        if self.per_epoch_sigma:  # the configured σ of every row
            out = np.concatenate([out, np.broadcast_to(self.sigma_all, out.shape)], -1)
        return out

    def _arm(self, q: np.ndarray, p: np.ndarray, w_ib: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(…, 3) each: the antenna's offset from the IMU ``l_n = C_b^n l`` (E, N, U m)
        and its velocity relative to the IMU ``C_b^n (ω_eb^b × l)`` (m/s), with
        ``ω_eb^b = ω_ib^b − C_n^b ω_ie^n`` (class docstring)."""
        C = quat_to_dcm(q)
        arm = np.asarray(self.lever_arm_m, dtype=float)
        w_eb = w_ib - np.einsum("...ji,...j->...i", C, omega_ie_n(p[..., 0]))
        return C @ arm, np.einsum("...ij,...j->...i", C, np.cross(w_eb, arm))

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = [D_p(p̃)(p̃ − p_GNSS); ṽ − v_GNSS]`` (B, m: the rows measured) and ``H``;
        at a lever arm, of the antenna (class docstring).

        Parameters
        ----------
        q : (B, 4) INS ``q_b^n`` (read with a lever arm only).
        v : (B, 3) m/s.  p : (B, 3) ``[L, λ, h]``.
        raw_k : (B, 6) receiver output at this epoch (:meth:`output`).
        w_ib : (B, 3) rad/s, the gyro's rate at the epoch: needed by velocity rows at a
            lever arm (a ValueError without it), else unused.
        """
        v = as_batch(v, (3,), "v")
        B = v.shape[0]
        p = as_batch(p, (3,), "p", B)
        raw = as_batch(raw_k, (12 if self.per_epoch_sigma else 6,), "raw_k", B)
        d = _metres(p)
        dpos = p - raw[:, :3]
        dpos[:, 1] = (dpos[:, 1] + np.pi) % (2.0 * np.pi) - np.pi
        z = np.concatenate([(d * dpos)[:, _EN], v - raw[:, 3:6]], -1)
        H = np.zeros((B, 6, N_STATES))
        H[:, [1, 0, 2], [6, 7, 8]] = d  # row N ← δL, row E ← δλ, row U ← δh
        H[:, [3, 4, 5], [3, 4, 5]] = 1.0
        r, m = self._rows, self.dim
        if any(self.lever_arm_m):  # the antenna, not the IMU (class docstring)
            rate = np.zeros((B, 3)) if w_ib is None else as_batch(w_ib, (3,), "w_ib", B)
            if w_ib is None and self.rows != "position":
                raise ValueError(f"{self.name}: velocity rows at a lever arm need the rate w_ib")
            l_n, arm_v = self._arm(as_batch(q, (4,), "q", B), p, rate)
            z[:, :3] += l_n
            z[:, 3:] += arm_v
            H[:, 0:3, 0:3] = skew(l_n)
            w_ie = omega_ie_n(p[:, 0])  # C̃(ω_ib × l) − ω_ie × (C̃ l) moves with φ:
            H[:, 3:6, 0:3] = skew(arm_v + np.cross(w_ie, l_n)) - skew(w_ie) @ skew(l_n)
            # and the Earth's rate turns with latitude: ∂(−ω_ie × l_n)/∂L
            H[:, 3:6, 6] += np.cross(l_n, omega_ie_n_dL(p[:, 0]))
        z, H = z[:, r], H[:, r]
        p_priv = m if self._augmented else 0
        H_private = np.broadcast_to(-np.eye(m)[:, :p_priv], (B, m, p_priv)).copy()
        valid = np.all(np.isfinite(z), -1)
        if self.per_epoch_sigma:  # whitened to the epoch's σ (module docstring)
            sigma_k = raw[:, 6:][:, r]
            ok = np.isfinite(sigma_k) & (sigma_k > 0)
            scale = np.where(ok, np.sqrt(np.diag(self.R)) / np.where(ok, sigma_k, 1.0), 1.0)
            z, H, H_private = z * scale, H * scale[..., None], H_private * scale[..., None]
        return Linearized(finite_or_zero(z), H, H_private, valid)
