"""Figures of the inertial core: the flight of a generated trajectory.

matplotlib is imported lazily (``import ftnav`` does not import it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["trajectory_figure"]


def trajectory_figure(traj, title: str = ""):
    """Ground track, altitude, speed and attitude of a :class:`~ftnav.sim.trajectory.Trajectory`.

    The ground track is East/North (km) from the start point, computed with
    :func:`pymap3d.geodetic2enu` on the WGS-84 ellipsoid.
    """
    import pymap3d
    from matplotlib.figure import Figure

    lat, lon, h = np.degrees(traj.p[:, 0]), np.degrees(traj.p[:, 1]), traj.p[:, 2]
    e, n, _ = pymap3d.geodetic2enu(lat, lon, h, lat[0], lon[0], h[0])
    t = traj.t
    fig = Figure(figsize=(11, 8), layout="constrained")
    ax = fig.subplots(2, 2)
    ax[0, 0].plot(e / 1e3, n / 1e3)
    ax[0, 0].plot(e[0] / 1e3, n[0] / 1e3, "o", label="start")
    ax[0, 0].set(xlabel="East (km)", ylabel="North (km)", title="ground track", aspect="equal")
    ax[0, 0].legend()
    ax[0, 1].plot(t, h)
    ax[0, 1].set(xlabel="t (s)", ylabel="h (m)", title="altitude")
    ax[1, 0].plot(t, np.linalg.norm(traj.v, axis=1))
    ax[1, 0].set(xlabel="t (s)", ylabel="speed (m/s)", title="speed")
    eul = np.degrees(traj.euler)
    ax[1, 1].plot(t, eul[:, 1], label="roll")
    ax[1, 1].plot(t, eul[:, 0], label="pitch")
    ax[1, 1].plot(t, np.degrees(np.unwrap(-traj.euler[:, 2])), label="heading (unwrapped)")
    ax[1, 1].set(xlabel="t (s)", ylabel="deg", title="attitude")
    ax[1, 1].legend()
    if title:
        fig.suptitle(title)
    return fig
