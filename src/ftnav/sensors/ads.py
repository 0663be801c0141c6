"""Air-data barometric altitude aid (spec §9.5; S2).

One measurement row (m = 1, metres): ``z = h̃ − h_baro`` with ``H = 1`` on δh.

Truth: ``h_baro = h + b + n``, ``b`` a first-order Gauss-Markov bias (σ_b, τ_b; off by
default, spec §9.5 suggests σ 10 m, τ 1000 s [A]) and ``n`` white (σ 5 m [A]).  The
metric error ``e = b + n`` is the aid's own error, so ``z = δh − b − n``
(``z_per_error = −1``).  The device logs ``h_baro`` (B, K).

Filter model: with ``bias_state=True`` the bias is a private Markov state
(``F = e^{−dt/τ}``, ``Q = σ_b²(1 − e^{−2dt/τ})``, ``P0 = σ_b²``) with
``H_private = −1`` and ``R = σ_n²``; otherwise ``R = σ_n² + σ_b²`` (the bias lumped into
the white noise, as GNSS ``markov="white"``).

Random components (spawn key ``c``): 0 bias Markov, 1 white.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ftnav.model.system import PrivateStates
from ftnav.sensors.base import (
    N_STATES,
    AidErrors,
    AidTruth,
    Linearized,
    as_batch,
    check_bool,
    check_common,
    check_errors_metric,
    check_float,
    check_truth,
    finite_or_zero,
    markov_errors,
    markov_private,
    standard_normals,
)

__all__ = ["Barometer"]


@dataclass(frozen=True, slots=True)
class Barometer:
    """Barometric altimeter (module docstring); SI units.

    Attributes
    ----------
    name : str.
    sigma_m : float, m, white noise σ_n.
    bias_sigma_m : float, m, true Markov bias σ_b (0: no bias).
    bias_tau_s : float, s, its correlation time (> 0).
    bias_state : bool, carry the bias as a private state.
    assumed_sigma_m : float, optional, the filter's assumed white σ (overrides R).
    dt : float, s, sample period.
    """

    name: str = "ads"
    sigma_m: float = 5.0
    bias_sigma_m: float = 0.0
    bias_tau_s: float = 1000.0
    bias_state: bool = False
    assumed_sigma_m: float | None = None
    dt: float = 1.0

    z_per_error: ClassVar[int] = -1
    components: ClassVar[tuple[str, ...]] = ("h",)

    def __post_init__(self):
        check_common(self, ("assumed_sigma_m",))
        for field in ("sigma_m", "bias_sigma_m"):
            object.__setattr__(
                self, field, check_float(self.name, field, getattr(self, field), low=0.0)
            )
        object.__setattr__(
            self,
            "bias_tau_s",
            check_float(self.name, "bias_tau_s", self.bias_tau_s, low=0.0, strict=True),
        )
        check_bool(self.name, "bias_state", self.bias_state)

    @property
    def dim(self) -> int:
        """Measurement dimension m = 1."""
        return 1

    @property
    def R(self) -> np.ndarray:
        """(1, 1) m², the filter's assumed noise (module docstring)."""
        if self.assumed_sigma_m is not None:
            var = self.assumed_sigma_m**2
        else:
            var = self.sigma_m**2 + (0.0 if self.bias_state else self.bias_sigma_m**2)
        return np.array([[var]])

    @property
    def private(self) -> PrivateStates | None:
        """The Markov bias state (``H = −1``) when ``bias_state``, else None."""
        if not self.bias_state:
            return None
        return markov_private(
            ("b_baro",),
            np.array([self.bias_sigma_m]),
            np.array([self.bias_tau_s]),
            self.dt,
            -np.ones((1, 1)),
        )

    def simulate_errors(self, truth: AidTruth, seed: int, runs: range, stream: int) -> AidErrors:
        """``coloured = b``, ``white = n`` (B, K, 1) in m."""
        K = check_truth(truth, self.dt, self.name)
        bias = markov_errors(
            seed,
            runs,
            stream,
            0,
            K,
            np.array([self.bias_sigma_m]),
            np.array([self.bias_tau_s]),
            self.dt,
        )
        white = standard_normals(seed, runs, stream, 1, (K, 1)) * self.sigma_m
        return AidErrors(bias, white, np.zeros((len(runs), 0)))

    def output(
        self, truth: AidTruth, errors_metric: np.ndarray, constants: np.ndarray
    ) -> np.ndarray:
        """Barometric altitude (B, K) m: ``h_baro = h + e``."""
        K = check_truth(truth, self.dt, self.name)
        e, _ = check_errors_metric(errors_metric, constants, (None, K, 1), 0)
        return np.asarray(truth.p, dtype=float)[:, 2] + e[..., 0]

    def measure(
        self,
        q: np.ndarray,
        v: np.ndarray,
        p: np.ndarray,
        raw_k: np.ndarray,
        w_ib: np.ndarray | None = None,
    ) -> Linearized:
        """``z = h̃ − h_baro`` (B, 1), ``H`` (B, 1, 18) with 1 on δh.

        Parameters
        ----------
        q, v : (B, 4), (B, 3) (unused).  p : (B, 3) ``[L, λ, h]``.
        raw_k : (B,) barometric altitude (m) at this epoch.
        """
        p = as_batch(p, (3,), "p")
        B = p.shape[0]
        h_baro = np.asarray(raw_k, dtype=float)
        if h_baro.shape != (B,):
            raise ValueError(f"raw_k: expected shape ({B},), got {h_baro.shape}")
        z = (p[:, 2] - h_baro)[:, None]
        H = np.zeros((B, 1, N_STATES))
        H[:, 0, 8] = 1.0
        H_private = np.full((B, 1, 1 if self.bias_state else 0), -1.0)
        valid = np.isfinite(z[:, 0])
        return Linearized(finite_or_zero(z), H, H_private, valid)
