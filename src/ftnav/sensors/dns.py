"""Doppler navigation sensor, DNS (spec §9.3; S1 eq. 19).

Two measurement rows (m = 2): horizontal navigation-frame velocity, E and N (m/s).

Truth (spec §9.3): the horizontal Doppler velocity in n is
``V_D = (1 + δK) v_h + δV_D u_t + n_D`` with ``u_t = v_h/|v_h|`` (along-track, true
velocity; 0 when the truth is at rest), δK a random constant per run (σ 0.25 %), δV_D
first-order Gauss-Markov (σ 0.278 m/s, τ 300 s) and ``n_D`` white (0.05 m/s [A]).  The
metric error is ``e = δV_D u_t + n_D`` (B, K, 2) and ``constants = δK`` (B, 1).  The
device logs the body-frame velocity ``v_D^b = C_n^b [(1 + δK) v_h + e; v_U]`` with the
true attitude (vertical component error-free).

Measurement at the INS solution: ``z = ṽ_h − (C̃_b^n v_D^b)_h``.  With
``C̃ = (I − [φ×]) C`` this is, to first order (``z_per_error = −1``)::

    z = δv_h − δK v_h − δV_D u_t − n_D − ([v×] φ)_h

so ``H`` on φ is ``[[0, v_U, −v_N], [−v_U, 0, v_E]]`` (spec §9.3's sign, confirmed by
finite differences), ``I₂`` on ``(δv_E, δv_N)``, and the private columns are
``−v_h`` on δK and ``−u_t`` on δV_D, all at the INS velocity.

Options [A]: ``attitude_coupling=False`` drops the φ term (platform-INS textbook form;
the nonlinear z still depends on the attitude).  ``states="augment"`` carries
``[δK, δV_D]`` as private states, ``F = diag(1, e^{−dt/τ})``,
``Q = diag(0, σ_D²(1 − e^{−2dt/τ}))``, ``P0 = diag(σ_K², σ_D²)``, ``R = σ_n² I₂``;
``states="white"`` has no private states and the documented approximation
``R = (σ_D² + σ_n² + (σ_K v_nom)²) I₂`` at ``v_nom = nominal_speed_m_s`` (the δK and δV_D
errors are along-track only; this spreads them isotropically).  S1's DNS filter drops
δv_U and δh from its 18 states (spec §8.3 [A]); that is the filter's business, the
rows here act on the common 18-state order.  ``valid`` is False when the INS horizontal
speed is below ``min_speed_m_s``.

Random components (spawn key ``c``): 0 δV_D Markov, 1 white, 2 δK.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.nav.attitude import quat_to_dcm
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
    markov_errors,
    standard_normals,
)

__all__ = ["Doppler"]


def _along_track(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u_t (…, 2), |v_h| (…))`` with ``u_t = 0`` where the horizontal speed is 0."""
    vh = v[..., :2]
    speed = np.hypot(vh[..., 0], vh[..., 1])
    u = vh / np.where(speed > 0.0, speed, 1.0)[..., None]
    return u, speed


@dataclass(frozen=True, slots=True)
class Doppler:
    """Doppler velocity sensor (module docstring); SI units.

    Attributes
    ----------
    name : str.
    scale_sigma : float, dimensionless, σ_K of the random-constant scale error δK.
    markov_sigma_m_s : float, m/s, σ_D of δV_D.  markov_tau_s : float, s, its τ (> 0).
    white_sigma_m_s : float, m/s, σ_n of the white noise (per axis).
    attitude_coupling : bool, keep the φ columns of H.
    states : ``"augment"`` (private ``[δK, δV_D]``) or ``"white"``.
    min_speed_m_s : float, m/s, gating threshold on the INS horizontal speed.
    sigma_m_s : float, optional, the filter's assumed σ per axis (overrides R).
    nominal_speed_m_s : float, m/s, speed of the ``"white"`` R and the nominal private H.
    dt : float, s, sample period.
    """

    name: str = "dns"
    scale_sigma: float = 0.0025
    markov_sigma_m_s: float = 0.278
    markov_tau_s: float = 300.0
    white_sigma_m_s: float = 0.05
    attitude_coupling: bool = True
    states: Literal["white", "augment"] = "augment"
    min_speed_m_s: float = 5.0
    sigma_m_s: float | None = None
    nominal_speed_m_s: float = 100.0
    dt: float = 1.0

    z_per_error: ClassVar[int] = -1
    components: ClassVar[tuple[str, ...]] = ("vel_E", "vel_N")

    def __post_init__(self):
        check_common(self, ("sigma_m_s",))
        for field in (
            "scale_sigma",
            "markov_sigma_m_s",
            "white_sigma_m_s",
            "min_speed_m_s",
            "nominal_speed_m_s",
        ):
            object.__setattr__(
                self, field, check_float(self.name, field, getattr(self, field), low=0.0)
            )
        object.__setattr__(
            self,
            "markov_tau_s",
            check_float(self.name, "markov_tau_s", self.markov_tau_s, low=0.0, strict=True),
        )
        check_bool(self.name, "attitude_coupling", self.attitude_coupling)
        check_choice(self.name, "states", self.states, ("white", "augment"))

    @property
    def dim(self) -> int:
        """Measurement dimension m = 2."""
        return 2

    @property
    def R(self) -> np.ndarray:
        """(2, 2) (m/s)², the filter's assumed noise (module docstring)."""
        if self.sigma_m_s is not None:
            var = self.sigma_m_s**2
        elif self.states == "augment":
            var = self.white_sigma_m_s**2
        else:
            var = (
                self.markov_sigma_m_s**2
                + self.white_sigma_m_s**2
                + (self.scale_sigma * self.nominal_speed_m_s) ** 2
            )
        return var * np.eye(2)

    @property
    def private(self) -> PrivateStates | None:
        """``[δK, δV_D]`` for ``states="augment"``, else None.

        ``H`` is the nominal one for a northward velocity of ``nominal_speed_m_s``;
        :meth:`measure` gives the per-epoch columns.
        """
        if self.states != "augment":
            return None
        a = np.exp(-self.dt / self.markov_tau_s)
        return PrivateStates(
            names=("dK", "dV_D"),
            F=np.diag([1.0, a]),
            Q=np.diag(
                [0.0, self.markov_sigma_m_s**2 * -np.expm1(-2.0 * self.dt / self.markov_tau_s)]
            ),
            x0=np.zeros(2),
            P0=np.diag([self.scale_sigma**2, self.markov_sigma_m_s**2]),
            H=np.array([[0.0, 0.0], [-self.nominal_speed_m_s, -1.0]]),
        )

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """``coloured = δV_D u_t``, ``white = n_D`` (B, K, 2), ``constants = δK`` (B, 1)."""
        K = check_truth(truth, self.dt, self.name)
        u, _ = _along_track(np.asarray(truth.v, dtype=float))
        dvd = markov_errors(
            seed,
            runs,
            stream,
            0,
            K,
            np.array([self.markov_sigma_m_s]),
            np.array([self.markov_tau_s]),
            self.dt,
        )
        white = standard_normals(seed, runs, stream, 1, (K, 2)) * self.white_sigma_m_s
        dK = standard_normals(seed, runs, stream, 2, (1,)) * self.scale_sigma
        return AidErrors(dvd * u, white, dK)

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """Body-frame Doppler velocity (B, K, 3) m/s: ``C_n^b [(1 + δK) v_h + e; v_U]``."""
        K = check_truth(truth, self.dt, self.name)
        e, dK = check_errors_metric(errors_metric, constants, (None, K, 2), 1)
        v = np.asarray(truth.v, dtype=float)
        vn = np.empty(e.shape[:2] + (3,))
        vn[..., :2] = (1.0 + dK[:, :, None]) * v[:, :2] + e
        vn[..., 2] = v[:, 2]
        C = quat_to_dcm(truth.q)  # (K, 3, 3) C_b^n
        return np.einsum("kji,bkj->bki", C, vn)

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = ṽ_h − (C̃_b^n v_D^b)_h`` (B, 2) and ``H`` at the INS solution.

        Parameters
        ----------
        q : (B, 4) INS ``q_b^n``.  v : (B, 3) m/s ENU.  p : (B, 3) (unused).
        raw_k : (B, 3) body-frame Doppler velocity (m/s) at this epoch.
        """
        q = as_batch(q, (4,), "q")
        B = q.shape[0]
        v = as_batch(v, (3,), "v", B)
        as_batch(p, (3,), "p", B)
        raw = as_batch(raw_k, (3,), "raw_k", B)
        V = np.einsum("bij,bj->bi", quat_to_dcm(q), raw)
        z = v[:, :2] - V[:, :2]
        H = np.zeros((B, 2, N_STATES))
        H[:, 0, 3] = H[:, 1, 4] = 1.0
        if self.attitude_coupling:
            H[:, 0, 1] = v[:, 2]
            H[:, 0, 2] = -v[:, 1]
            H[:, 1, 0] = -v[:, 2]
            H[:, 1, 2] = v[:, 0]
        u, speed = _along_track(v)
        if self.states == "augment":
            H_private = np.stack([-v[:, :2], -u], -1)
        else:
            H_private = np.zeros((B, 2, 0))
        valid = np.all(np.isfinite(z), -1) & (speed >= self.min_speed_m_s)
        return Linearized(finite_or_zero(z), H, H_private, valid)
