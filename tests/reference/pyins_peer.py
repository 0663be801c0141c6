"""Run a trajectory's IMU increments through python-ins (pyins 1.x), the peer implementation.

pyins uses NED and a forward-right-down body frame; ftnav uses ENU and right-forward-up
(``docs/conventions.md``).  The body vectors map by the proper rotation
``x_frd = y_rfu, y_frd = x_rfu, z_frd = −z_rfu``; heading = −ψ.  pyins applies its own
coning/sculling (previous-sample form) and its own Earth model (gravity with a linear
height term), so agreement is a test of both implementations, not of shared code.
"""

from __future__ import annotations

import numpy as np

RFU_TO_FRD = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def pyins_integrate(t, p0, v0, euler0, dtheta, dv):
    """Integrate increments (K, 3) ending at ``t[1:]`` from the state at ``t[0]``.

    Returns (K+1, 3) positions ``[L, λ, h]`` in rad, rad, m.
    """
    import pandas as pd
    from pyins import strapdown
    from pyins.util import ACCEL_COLS, GYRO_COLS, LLA_COLS, RPH_COLS, VEL_COLS

    th = dtheta @ RFU_TO_FRD.T
    dvf = dv @ RFU_TO_FRD.T
    # increment sensors need a "before" sample (pyins convention): repeat the first one
    imu = pd.DataFrame(
        np.hstack([np.vstack([th[:1], th]), np.vstack([dvf[:1], dvf])]),
        index=np.asarray(t, dtype=float),
        columns=GYRO_COLS + ACCEL_COLS,
    )
    inc = strapdown.compute_increments_from_imu(imu, "increment")
    pva = pd.Series(
        np.hstack(
            [
                np.degrees(p0[:2]),
                p0[2],
                [v0[1], v0[0], -v0[2]],
                np.degrees([euler0[1], euler0[0], -euler0[2]]),
            ]
        ),
        index=LLA_COLS + VEL_COLS + RPH_COLS,
    )
    integ = strapdown.Integrator(pva)
    traj = integ.integrate(inc)
    lla = traj[LLA_COLS].to_numpy()
    return np.column_stack([np.radians(lla[:, 0]), np.radians(lla[:, 1]), lla[:, 2]])
