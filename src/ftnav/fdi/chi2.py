"""Chi-square fault detection: residual, windowed residual and state tests (spec §3).

Per epoch and local filter every detector yields a statistic, a threshold, a raw
flag and a flag after hysteresis (spec §3.4).  All arrays carry a leading batch
axis ``(B, N)`` (runs x local filters).
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.stats import chi2

__all__ = [
    "chi2_threshold",
    "DetectorState",
    "DetectorOutput",
    "ChiSquareDetector",
    "state_statistic",
    "apply_hysteresis",
]


@lru_cache(maxsize=4096)
def _threshold(dof: int, pfa: float) -> float:
    return float(chi2.isf(pfa, dof)) if dof > 0 else np.inf


def chi2_threshold(dof, pfa: float) -> np.ndarray:
    """Threshold ``T_D = F⁻¹_{χ²(dof)}(1 − P_FA)`` (spec §3.1), elementwise over ``dof``.

    ``dof = 0`` (nothing tested) gives ``inf`` so it never alarms.
    """
    dof = np.asarray(dof, dtype=int)
    table = np.array([_threshold(d, pfa) for d in range(int(dof.max(initial=0)) + 1)])
    return table[dof]


class DetectorState(NamedTuple):
    """Running detector state, shapes (B, N) unless noted."""

    history: np.ndarray  # (B, N, W) statistics of the last W tested epochs
    history_dof: np.ndarray  # (B, N, W) their degrees of freedom
    on_count: np.ndarray  # consecutive exceedances
    off_count: np.ndarray  # consecutive passes
    flag: np.ndarray  # bool, flag after hysteresis


class DetectorOutput(NamedTuple):
    """Spec §3.4 output contract, each (B, N)."""

    statistic: np.ndarray
    threshold: np.ndarray
    raw: np.ndarray
    flag: np.ndarray


class ChiSquareDetector:
    """Thresholding, windowing and hysteresis of per-epoch chi-square statistics.

    Spec §3.1: the windowed statistic ``Λ_k = Σ_{last W tested epochs} λ_j`` is
    ``χ²(Σ dof)`` under H0; a fault is declared after ``n_on`` consecutive
    exceedances and cleared after ``n_off`` consecutive passes (spec §3.1
    hysteresis).  Epochs without a test (no measurement) leave the state as is.

    Parameters
    ----------
    pfa : false-alarm probability per test.
    window : W >= 1.
    n_on, n_off : hysteresis counts.
    """

    def __init__(self, pfa: float, window: int = 1, n_on: int = 1, n_off: int = 5):
        if not 0.0 < pfa < 1.0:
            raise ValueError(f"false_alarm_probability: must be in (0, 1), got {pfa}")
        for name, value in (("window", window), ("n_on", n_on), ("n_off", n_off)):
            if int(value) < 1:
                raise ValueError(f"{name}: must be >= 1, got {value}")
        self.pfa = float(pfa)
        self.window = int(window)
        self.n_on = int(n_on)
        self.n_off = int(n_off)

    def init(self, batch: int, n_filters: int) -> DetectorState:
        shape = (batch, n_filters)
        return DetectorState(
            np.zeros(shape + (self.window,)),
            np.zeros(shape + (self.window,), dtype=int),
            np.zeros(shape, dtype=int),
            np.zeros(shape, dtype=int),
            np.zeros(shape, dtype=bool),
        )

    def step(
        self, state: DetectorState, statistic: np.ndarray, dof: np.ndarray, tested: np.ndarray
    ) -> tuple[DetectorState, DetectorOutput]:
        """Advance one epoch.

        Parameters
        ----------
        statistic : (B, N) single-epoch statistic λ (ignored where not tested).
        dof : (B, N) its degrees of freedom.
        tested : (B, N) bool, whether a test happened this epoch.
        """
        t = tested[..., None]
        hist = np.where(
            t, np.concatenate([state.history[..., 1:], statistic[..., None]], -1), state.history
        )
        hdof = np.where(
            t, np.concatenate([state.history_dof[..., 1:], dof[..., None]], -1), state.history_dof
        )
        total = hist.sum(-1)
        total_dof = hdof.sum(-1)
        threshold = chi2_threshold(total_dof, self.pfa)
        raw = tested & (total > threshold)
        on, off, flag = apply_hysteresis(state, raw, tested, self.n_on, self.n_off)
        statistic_out = np.where(tested, total, 0.0)
        return (
            DetectorState(hist, hdof, on, off, flag),
            DetectorOutput(statistic_out, threshold, raw, flag),
        )


def apply_hysteresis(
    state: DetectorState, raw: np.ndarray, tested: np.ndarray, n_on: int, n_off: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spec §3.1 hysteresis: set after ``n_on`` alarms in a row, clear after ``n_off`` passes.

    Epochs that are not tested leave the counters and the flag as they are.

    Returns
    -------
    on_count, off_count, flag : (B, N) each.
    """
    passed = tested & ~raw
    on = np.where(raw, state.on_count + 1, np.where(passed, 0, state.on_count))
    off = np.where(passed, state.off_count + 1, np.where(raw, 0, state.off_count))
    flag = np.where(on >= n_on, True, np.where(off >= n_off, False, state.flag))
    return on, off, flag


def state_statistic(
    x: np.ndarray, P: np.ndarray, xs: np.ndarray, Ps: np.ndarray, rtol: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """State chi-square statistic with the exact covariance ``Pˢ − P`` (spec §3.2).

    ``β = x̂ − x̂ˢ``, ``λ = βᵀ T⁺ β`` with ``T = Pˢ − P`` and ``T⁺`` its
    pseudo-inverse; the degrees of freedom are the rank of ``T`` with tolerance
    ``rtol·‖T‖`` (unobservable directions have ``Pˢ ≈ P`` and are not tested).

    Parameters
    ----------
    x, P : (..., n), (..., n, n) Kalman posterior.
    xs, Ps : (..., n), (..., n, n) pure propagator started with the filter.

    Returns
    -------
    statistic : (...) λ.   dof : (...) int rank of T.
    """
    T = 0.5 * (Ps - P + np.swapaxes(Ps - P, -1, -2))
    w, V = np.linalg.eigh(T)
    tol = rtol * np.maximum(np.abs(w).max(-1, keepdims=True), 1e-300)
    keep = w > tol
    proj = np.einsum("...ji,...j->...i", V, x - xs)
    lam = np.where(keep, proj**2 / np.where(keep, w, 1.0), 0.0).sum(-1)
    return lam, keep.sum(-1)
