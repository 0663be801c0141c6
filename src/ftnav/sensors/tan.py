"""Terrain-aided navigation, SITAN form (spec §9.2; S1 eq. 18; Hostetler & Andreas 1983).

One measurement row (m = 1, metres).  The radar altimeter measures the clearance
above the terrain; the filter predicts it from the INS position and the map::

    ĉ = h̃ − h_T(L̃, λ̃),     z = ĉ − c_m  ≈  δh − s_E δE − s_N δN − e

``H`` has ``−∂h_T/∂L`` on δL, ``−∂h_T/∂λ`` on δλ and ``+1`` on δh, with the exact
map gradient at the INS position.  Spec §9.2 writes the first two as ``−s_N R_Mh``
and ``−s_E R_Nh cos L``, which is the same up to O(h/R) (≤ 1.6e-3 at 10 km): the
terrain point under the aircraft moves by ``R_M δL`` on the ground, not ``R_Mh δL``,
so the exact derivative is used here (it is what the finite-difference check of
spec §9.7 b verifies).

Truth: the truth uses the same surface as the filter's map (``terrain``); the map
error σ_m and the altimeter noise σ_r are simulated together as one white metric
error ``e ~ N(0, σ_m² + σ_r²)`` and the device logs ``c_m = h − h_T(L, λ) + e``.
Sign: as for every aid, ``e`` is the error of the device's own reading (a +30 m fault
means the altimeter reads 30 m too much clearance), so it lowers z
(``z_per_error = −1``).  ``R = σ_m² + σ_r²``.

Gating (``valid`` False): slope norm ``√(s_E² + s_N²) < min_slope`` (flat terrain; slopes
per ground metre, ``s_N = (∂h_T/∂L)/R_M``, ``s_E = (∂h_T/∂λ)/(R_N cos L)``),
predicted clearance ``ĉ < min_clearance_m``, INS horizontal speed ``< min_speed_m_s``
(taxi, take-off), or off the map.  Large initial position errors (σ_pos beyond the
terrain correlation length) can make the single EKF diverge; SITAN used parallel
acquisition filters for that, which are out of scope here.

Random components (spawn key ``c``): 0 white.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.nav.earth import radii
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
from ftnav.sensors.terrain import Terrain

__all__ = ["Tan"]


@dataclass(frozen=True, slots=True)
class Tan:
    """SITAN radar-altimeter / terrain-map aid (module docstring); SI units.

    Attributes
    ----------
    terrain : :class:`~ftnav.sensors.terrain.AnalyticTerrain` or
        :class:`~ftnav.sensors.terrain.GridDem`, the map (also the true surface).
    name : str.
    altimeter_sigma_m : float, m, radar altimeter white noise σ_r (S1: 5 m).
    map_sigma_m : float, m, map error σ_m, simulated as white (S1: 5 m).
    min_slope : float, m/m, gating threshold on the slope norm (spec §9.2: 0.01).
    min_clearance_m : float, m, gating threshold on the predicted clearance.
    min_speed_m_s : float, m/s, gating threshold on the INS horizontal speed.
    sigma_m : float, optional, the filter's assumed total σ (default √(σ_m² + σ_r²)).
    dt : float, s, sample period.
    """

    terrain: Terrain
    name: str = "tan"
    altimeter_sigma_m: float = 5.0
    map_sigma_m: float = 5.0
    min_slope: float = 0.01
    min_clearance_m: float = 50.0
    min_speed_m_s: float = 30.0
    sigma_m: float | None = None
    dt: float = 1.0

    z_per_error: ClassVar[int] = -1
    components: ClassVar[tuple[str, ...]] = ("clearance",)

    def __post_init__(self):
        check_common(self, ("sigma_m",))
        if not isinstance(self.terrain, Terrain):
            raise ValueError(
                f"{self.name}.terrain: expected an AnalyticTerrain or GridDem, "
                f"got {type(self.terrain).__name__}"
            )
        for field in (
            "altimeter_sigma_m",
            "map_sigma_m",
            "min_slope",
            "min_clearance_m",
            "min_speed_m_s",
        ):
            low = None if field == "min_clearance_m" else 0.0
            object.__setattr__(
                self, field, check_float(self.name, field, getattr(self, field), low=low)
            )

    @property
    def dim(self) -> int:
        """Measurement dimension m = 1."""
        return 1

    @property
    def R(self) -> np.ndarray:
        """(1, 1) m², the filter's assumed noise ``σ_m² + σ_r²`` (or ``sigma_m²``)."""
        if self.sigma_m is not None:
            return np.array([[self.sigma_m**2]])
        return np.array([[self.map_sigma_m**2 + self.altimeter_sigma_m**2]])

    @property
    def private(self) -> PrivateStates | None:
        """No private states."""
        return None

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """White metric error (B, K, 1) with σ = √(σ_m² + σ_r²); no coloured part."""
        K = check_truth(truth, self.dt, self.name)
        white = standard_normals(seed, runs, stream, 0, (K, 1))
        white *= np.hypot(self.map_sigma_m, self.altimeter_sigma_m)
        B = len(runs)
        return AidErrors(np.zeros((B, K, 1)), white, np.zeros((B, 0)))

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """Measured clearance (B, K) in m: ``c_m = h − h_T(L, λ) + e``."""
        K = check_truth(truth, self.dt, self.name)
        e, _ = check_errors_metric(errors_metric, constants, (None, K, 1), 0)
        p = np.asarray(truth.p, dtype=float)
        h_T = self.terrain.height_and_gradient(p[:, 0], p[:, 1])[0]
        return (p[:, 2] - h_T) + e[..., 0]

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = ĉ − c_m`` (B, 1) and ``H`` (B, 1, 18) at the INS solution, with gating.

        Parameters
        ----------
        q : (B, 4) (unused).  v : (B, 3) m/s ENU.  p : (B, 3) ``[L, λ, h]``.
        raw_k : (B,) measured clearance (m) at this epoch.
        """
        v = as_batch(v, (3,), "v")
        B = v.shape[0]
        p = as_batch(p, (3,), "p", B)
        c_m = np.asarray(raw_k, dtype=float)
        if c_m.shape != (B,):
            raise ValueError(f"raw_k: expected shape ({B},), got {c_m.shape}")
        L, lam, h = p[:, 0], p[:, 1], p[:, 2]
        h_T, gL, glam = self.terrain.height_and_gradient(L, lam)
        RM, RN = radii(L, 0.0)  # slopes in metres per ground metre, for the gating
        slope = np.hypot(gL / RM, glam / (RN * np.cos(L)))
        c_hat = h - h_T
        z = (c_hat - c_m)[:, None]
        H = np.zeros((B, 1, N_STATES))
        H[:, 0, 6] = -gL
        H[:, 0, 7] = -glam
        H[:, 0, 8] = 1.0
        with np.errstate(invalid="ignore"):
            valid = (
                np.isfinite(z[:, 0])
                & np.isfinite(gL)
                & np.isfinite(glam)
                & (slope >= self.min_slope)
                & (c_hat >= self.min_clearance_m)
                & (np.hypot(v[:, 0], v[:, 1]) >= self.min_speed_m_s)
            )
        return Linearized(finite_or_zero(z), finite_or_zero(H), np.zeros((B, 1, 0)), valid)
