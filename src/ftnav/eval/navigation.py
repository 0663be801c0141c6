"""The reported output errors of integrated navigation against a reference (spec §11).

The engine's error states are ``[φ, δv, δL δλ δh, ...]`` (spec §8.3, rad and m); the
reported (metric) states are position East/North/Up in metres, velocity East/North/Up
in m/s and attitude φ East/North/Up in arcmin (:data:`~ftnav.model.scenario.METRIC_STATES`),
scaled at the reference position.
"""

from __future__ import annotations

import numpy as np

from ftnav.nav.earth import radii

__all__ = ["N_NAV", "metric_errors", "metric_scale", "metric_variances"]

N_NAV = 9
_ARCMIN = np.pi / 180.0 / 60.0
#: Order of the metric states (E, N, U position; velocity; φ) in the spec §8.3 error state.
_METRIC_ORDER = [7, 6, 8, 3, 4, 5, 0, 1, 2]


def metric_scale(p_true: np.ndarray) -> np.ndarray:
    """(..., 9) metric units per error-state unit, in metric-state order (spec §9, §11)."""
    # radii() returns R_M + h and R_N + h already (h was once added twice: issue 22)
    RMh, RNh = radii(p_true[..., 0], p_true[..., 2])
    scale = np.empty(p_true.shape[:-1] + (N_NAV,))
    scale[..., 0] = RNh * np.cos(p_true[..., 0])
    scale[..., 1] = RMh
    scale[..., 2:6] = 1.0
    scale[..., 6:9] = 1.0 / _ARCMIN
    return scale


def metric_errors(e: np.ndarray, p_true: np.ndarray) -> np.ndarray:
    """(..., 9) output errors in metric states: E/N/U m, E/N/U m/s, φ E/N/U arcmin."""
    out: np.ndarray = e[..., _METRIC_ORDER] * metric_scale(p_true)
    return out


def metric_variances(P: np.ndarray, p_true: np.ndarray) -> np.ndarray:
    """(B, 9) variances of the metric states from a covariance over ``[φ, δv, δp, ...]``."""
    d = np.diagonal(P, axis1=-2, axis2=-1)[..., :N_NAV]
    var: np.ndarray = d[..., _METRIC_ORDER] * metric_scale(p_true) ** 2
    return var
