"""CSV output of generated trajectories (what ``ftnav trajectory`` writes).

``truth.csv``: ``t, lat_deg, lon_deg, h_m, v_e, v_n, v_u, roll_deg, pitch_deg,
heading_deg`` at the IMU sample times (heading clockwise from North).
``imu.csv``: ``t, dtheta_x, dtheta_y, dtheta_z, dv_x, dv_y, dv_z``: increments (rad,
m/s) over the interval ending at ``t``, body frame x right, y forward, z up.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ftnav.sim.trajectory import Trajectory

__all__ = ["TRUTH_COLUMNS", "IMU_COLUMNS", "write_truth_csv", "write_imu_csv", "read_imu_csv"]

TRUTH_COLUMNS = (
    "t",
    "lat_deg",
    "lon_deg",
    "h_m",
    "v_e",
    "v_n",
    "v_u",
    "roll_deg",
    "pitch_deg",
    "heading_deg",
)
IMU_COLUMNS = ("t", "dtheta_x", "dtheta_y", "dtheta_z", "dv_x", "dv_y", "dv_z")


def write_truth_csv(traj: Trajectory, path: Path) -> Path:
    """Write the truth of a trajectory at every IMU sample time."""
    e = np.degrees(traj.euler)
    data = np.column_stack(
        [
            traj.t,
            np.degrees(traj.p[:, 0]),
            np.degrees(traj.p[:, 1]),
            traj.p[:, 2],
            traj.v,
            e[:, 1],
            e[:, 0],
            traj.heading_deg,
        ]
    )
    np.savetxt(
        path,
        data,
        delimiter=",",
        header=",".join(TRUTH_COLUMNS),
        comments="",
        fmt=["%.4f", "%.12f", "%.12f", "%.6f"] + ["%.9f"] * 6,
    )
    return Path(path)


def write_imu_csv(t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, path: Path) -> Path:
    """Write increments; ``t`` (K,) are the interval end times."""
    data = np.column_stack([t, dtheta, dv])
    np.savetxt(
        path,
        data,
        delimiter=",",
        header=",".join(IMU_COLUMNS),
        comments="",
        fmt=["%.4f"] + ["%.17g"] * 6,
    )
    return Path(path)


def read_imu_csv(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read ``imu.csv`` back: ``(t, dtheta, dv)``; checks the header."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    if tuple(header) != IMU_COLUMNS:
        raise ValueError(
            f"{path}: expected columns {','.join(IMU_COLUMNS)}, got {','.join(header)}"
        )
    d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return d[:, 0], d[:, 1:4], d[:, 4:7]
