"""Navigation solutions of a processed recording: ``solution.csv`` and a GeoJSON track.

``solution.csv`` (``docs/recording-format.md``) has exactly the columns
``time_s, lat_deg, lon_deg, height_m, v_east_mps, v_north_mps, v_up_mps, roll_deg,
pitch_deg, yaw_deg, sigma_east_m, sigma_north_m, sigma_up_m`` at every filter epoch
(every primary GNSS epoch and at least the recording's ``filter.rate_hz``); ``time_s`` is
on the recording's own time base; ``yaw_deg`` is the heading, clockwise from North in
[0, 360) (``docs/conventions.md``: −ψ); the σ are the filter's position σ, metres East,
North, Up.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ftnav.engine.driver import Trace
from ftnav.nav import attitude
from ftnav.nav.earth import radii

__all__ = ["SOLUTION_COLUMNS", "solution_table", "write_solution_csv", "write_track_geojson"]

SOLUTION_COLUMNS = (
    "time_s",
    "lat_deg",
    "lon_deg",
    "height_m",
    "v_east_mps",
    "v_north_mps",
    "v_up_mps",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "sigma_east_m",
    "sigma_north_m",
    "sigma_up_m",
)


def solution_table(trace: Trace, times: np.ndarray, run: int = 0) -> np.ndarray:
    """(K, 13) rows of :data:`SOLUTION_COLUMNS` of one run of a trace."""
    sol = trace.solution
    assert sol is not None
    p, v = sol.p[run], sol.v[run]
    euler = np.degrees(attitude.quat_to_euler(sol.q[run]))
    RM, RN = radii(p[:, 0], p[:, 2])
    var = trace.P_diag[run]
    sig = np.sqrt(np.maximum(var[:, 6:9], 0.0))
    return np.column_stack(
        [
            times,
            np.degrees(p[:, 0]),
            np.degrees(p[:, 1]),
            p[:, 2],
            v,
            euler[:, 1],
            euler[:, 0],
            (-euler[:, 2]) % 360.0,
            sig[:, 1] * RN * np.cos(p[:, 0]),
            sig[:, 0] * RM,
            sig[:, 2],
        ]
    )


def write_solution_csv(table: np.ndarray, path: Path) -> Path:
    """Write :func:`solution_table` rows with a header line."""
    fmt = ["%.4f", "%.9f", "%.9f", "%.4f"] + ["%.4f"] * 3 + ["%.4f"] * 3 + ["%.4f"] * 3
    np.savetxt(path, table, fmt=fmt, delimiter=",", header=",".join(SOLUTION_COLUMNS), comments="")
    return path


def write_track_geojson(
    tracks: dict[str, np.ndarray], reference: np.ndarray | None, path: Path
) -> Path:
    """A GeoJSON FeatureCollection: one LineString per method (``(K, 13)`` solution
    tables) and the reference (``(K_r, 3)`` ``[lat, lon, h]`` rad, rad, m) if given."""
    features = []
    for name, tab in tracks.items():
        coords = np.round(tab[:, [2, 1, 3]], 9).tolist()
        features.append(
            {
                "type": "Feature",
                "properties": {"name": name, "kind": "solution"},
                "geometry": {"type": "LineString", "coordinates": coords},
            }
        )
    if reference is not None and len(reference):
        ll = np.column_stack([np.degrees(reference[:, 1]), np.degrees(reference[:, 0])])
        features.append(
            {
                "type": "Feature",
                "properties": {"name": "reference", "kind": "reference"},
                "geometry": {
                    "type": "LineString",
                    "coordinates": np.round(np.column_stack([ll, reference[:, 2]]), 9).tolist(),
                },
            }
        )
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return path
