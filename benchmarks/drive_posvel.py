"""How well the drive's receiver agrees with itself: positions against integrated velocities.

Could a test of the receiver's positions against its own velocities catch a slow ramp of
the positions (issue 20: a 0.05 m/s ramp within 20 s at <= 1 % false alarms)?  On the
fault-free drive (``rtklib-drive``'s RTKLIB ``.pos``, Q = 1 fixes, 4 Hz), over windows of
``w`` seconds: the position change minus the trapezoid integral of the velocities (shifted
by the lag the data README gives, 0.125 s, and by none), north and east.  Printed per
window and lag: its σ per axis, the 99th percentile and the largest horizontal value,
beside what a 0.05 m/s ramp adds over the window.

    python benchmarks/drive_posvel.py      # a second
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ftnav.recordings import recording_path

POS = recording_path("rtklib-drive").parent / "data/rtklibexplorer/drive_0708/gnss_1934_sf.pos"
R_EARTH = 6378137.0


def main() -> None:
    d = pd.read_csv(POS, sep=r"\s+", comment="%", header=None)
    stamp = pd.to_datetime(d[0] + " " + d[1])
    t = (stamp - stamp.iloc[0]).dt.total_seconds().to_numpy()
    lat, lon = np.radians(d[2].to_numpy()), np.radians(d[3].to_numpy())
    north = (lat - lat[0]) * R_EARTH  # local, small-area: the drive spans a few km
    east = (lon - lon[0]) * R_EARTH * np.cos(lat[0])
    fixed = d[5].to_numpy() == 1
    vn, ve = d[15].to_numpy(), d[16].to_numpy()
    print("| window s | lag s | σ north m | σ east m | p99 m | max m | 0.05 m/s ramp m |")
    print("|---|---|---|---|---|---|---|")
    for w in (10.0, 20.0):
        for lag in (0.0, 0.125):
            # the velocity at t is the receiver's reading at t + lag (it lags the positions)
            v = [np.interp(t + lag, t, x) for x in (vn, ve)]
            ints = [
                np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))]) for x in v
            ]
            rn, re = north - ints[0], east - ints[1]
            j = np.searchsorted(t, t + w)
            i = np.flatnonzero(j < len(t))
            j = j[i]
            keep = (np.abs(t[j] - t[i] - w) < 0.01) & fixed[i] & fixed[j]
            i, j = i[keep], j[keep]
            dn, de = rn[j] - rn[i], re[j] - re[i]
            h = np.hypot(dn, de)
            print(
                f"| {w:.0f} | {lag:.3f} | {dn.std():.3f} | {de.std():.3f} | "
                f"{np.percentile(h, 99):.3f} | {h.max():.3f} | {0.05 * w:.2f} |"
            )


if __name__ == "__main__":
    main()
