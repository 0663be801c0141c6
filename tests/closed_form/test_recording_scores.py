"""Scores of a recording at the point its reference measures (issue 22, honest scores).

Oracle: pymap3d's geodetic ↔ ENU conversion, independent of ftnav's small-offset
``enu_metres``: an antenna placed with pymap3d at ``C_b^n · lever_arm`` from the IMU has a
zero error when the IMU's solution is scored at the antenna, and the whole lever arm as
its error when it is not.
"""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from ftnav.eval.recorded import Reference, reference_errors
from ftnav.nav import attitude
from ftnav.nav.mechanization import InsState


def _antennas(p_imu: np.ndarray, q: np.ndarray, arm: np.ndarray) -> np.ndarray:
    """The antenna's geodetic position, placed with pymap3d (ENU offset C_b^n · arm)."""
    out = []
    for (lat, lon, h), C in zip(p_imu, attitude.quat_to_dcm(q), strict=True):
        e, n, u = C @ arm
        la, lo, hh = pymap3d.enu2geodetic(e, n, u, np.degrees(lat), np.degrees(lon), h)
        out.append([np.radians(la), np.radians(lo), hh])
    return np.array(out)


@pytest.mark.parametrize("arm", [[-0.05, 0.0, 0.0], [0.3, 1.2, -0.8]])
def test_a_solution_at_the_imu_is_scored_at_the_antenna(arm):
    rng = np.random.default_rng(4)
    K = 20
    p = np.column_stack(
        [
            np.radians(rng.uniform(-60, 60, K)),
            np.radians(rng.uniform(-179, 179, K)),
            rng.uniform(-50, 3000, K),
        ]
    )
    euler = np.column_stack(
        [rng.uniform(-0.3, 0.3, K), rng.uniform(-0.3, 0.3, K), rng.uniform(-np.pi, np.pi, K)]
    )
    q = attitude.euler_to_quat(euler)
    arm = np.array(arm)
    sol = InsState(q[None], np.zeros((1, K, 3)), p[None], np.zeros((1, K, 3)))
    ref_p = _antennas(p, q, arm)
    at_antenna = reference_errors(sol, Reference(np.arange(K), ref_p, arm))
    np.testing.assert_allclose(at_antenna, 0.0, atol=2e-6)
    at_imu = reference_errors(sol, Reference(np.arange(K), ref_p))
    np.testing.assert_allclose(
        np.linalg.norm(at_imu, axis=1), np.linalg.norm(arm), rtol=1e-5, atol=1e-7
    )
