"""Peer run: python-ins (pyins 1.x) loosely coupled GNSS/INS on a real car drive.

Data: ``rtklibexplorer_gnss_imu/drive_0708`` (see its README): a roof-mounted MEMS IMU at
100 Hz (``imu_1934_gpst.csv``, GPST stamps) and RTKLIB RTK solutions at 4 Hz
(``gnss_1934_sf.pos``).  "rtklibexplorer/GNSS_IMU (Tim Everett, 2025), BSD-3-Clause".

What the peer does (everything through pyins' public API; nothing from ftnav):

* IMU: stamps + ``imu_t_off`` (-0.125 s); g -> m/s^2, deg/s -> rad/s; rotated from the
  sensor axes into the vehicle forward-right-down frame with the mounting
  ``rpy = [180, 0, 180] deg`` plus the misalignment ``[0, -6.79, 5.35] deg`` (README
  values; applied as ``x_body = M^T x_sensor`` with ``M = mat_from_rph(rpy)``, which
  levels the static specific force to within 0.1 deg in pitch);
  ``strapdown.compute_increments_from_imu(..., 'rate')``.
* Initial attitude: roll and pitch from the mean specific force over the first 35 s
  (static), heading from the GNSS course ``atan2(ve, vn)`` at the first Q = 1 epoch
  faster than 1 m/s (the car does not turn before that).  The filter starts at the
  first IMU sample, at the first GNSS fix (lever arm removed).
* ``filters.run_feedback_filter`` (EKF, 9 INS + 3 + 3 bias states) with
  ``measurements.Position`` and ``measurements.NedVelocity`` from the Q = 1 epochs
  (their median ``sdn/sde/sdu`` and ``sdvn/sdve/sdvu``, NEU velocity -> NED), the GNSS
  lever arm ``[0, -0.05, 0] m`` (antenna minus IMU offset), README noise: gyro
  0.0038 deg/s/sqrt(Hz), accel 70 ug/sqrt(Hz), accel bias walk 7 ug/sqrt(Hz), gyro bias
  walk 3.8e-5 deg/s/sqrt(s), each times upstream's factors (1, 2, 4, 2).
* IMU rows that exactly repeat the previous row (1 138 stale reads, 2.1 %) are dropped.
* ``nhc=True``: a non-holonomic constraint (body lateral and vertical velocity zero)
  with upstream's drive settings: at every GNSS epoch time (4 Hz, inside outages too)
  when faster than 2 m/s and turning slower than 10 deg/s, 0.10 m/s with GNSS and
  0.05 m/s inside an outage.  pyins 1.0 has no NHC class, so it is a small
  ``measurements.Measurement`` subclass built on pyins' ``body_velocity_error_jacobian``.

Scores (horizontal, at the antenna, against the Q = 1 RTK fixes):

* ``rms_before_update_m``: the predicted antenna position minus the fix at every
  processed fix (the Position innovation before the update; with outages this includes
  the first fix after each outage, i.e. the outage drift);
* ``rms_after_update_m``: the filter's output trajectory interpolated to the processed
  fixes;
* per outage ``[start, start + length)``, start = outage_start_s + k * outage_every_s
  after the first GNSS epoch, clipped to end >= 30 s before the last GNSS epoch: the error
  at the last fix inside the outage and the maximum over it; ``rms_max_drift_m`` is the
  RMS over outages of that maximum.

Usage: ``python benchmarks/peer_pyins_drive.py [--outage-length 15] [--outage-every 60]
[--outage-start 40] [--nhc]`` (no ``--outage-length``: GNSS on all the time).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

# the copy vendored with ftnav (its licence beside it); FTNAV_RTKLIBEXPLORER_DIR overrides
_VENDORED = Path(__file__).parents[1] / "src/ftnav/recordings/data/rtklibexplorer"
DATA_DIR = Path(os.environ.get("FTNAV_RTKLIBEXPLORER_DIR", str(_VENDORED)))
IMU_FILE = DATA_DIR / "drive_0708" / "imu_1934_gpst.csv"
POS_FILE = DATA_DIR / "drive_0708" / "gnss_1934_sf.pos"

G0 = 9.80665
IMU_T_OFF_S = -0.125
MOUNT_RPY_DEG = np.array([180.0, 0.0, 180.0]) + np.array([0.0, -6.79, 5.35])
IMU_OFFSET_M = np.array([0.0, 0.0, -0.65])  # forward, right, down from the system origin
GNSS_OFFSET_M = np.array([0.0, -0.05, -0.65])
STATIC_S = 35.0
HEADING_MIN_SPEED = 1.0
END_MARGIN_S = 30.0
DROP_STALE = True  # drop rows that exactly repeat the previous one (stale reads)

# README noise specs and upstream's process-noise factors (gyro noise, accel noise,
# accel bias, gyro bias)
GYRO_NOISE = 0.0038 * np.pi / 180 * 1  # rad/s/sqrt(Hz)
ACCEL_NOISE = 70e-6 * G0 * 2  # m/s^2/sqrt(Hz)
ACCEL_BIAS_WALK = 7e-6 * G0 * 4  # m/s^2/sqrt(s)
GYRO_BIAS_WALK = 3.8e-5 * np.pi / 180 * 2  # rad/s/sqrt(s)
# initial uncertainties (upstream drive configuration)
GYRO_BIAS_SD = 0.1 * np.pi / 180  # rad/s
ACCEL_BIAS_SD = 0.1  # m/s^2
LEVEL_SD_DEG = 2.0
AZIMUTH_SD_DEG = 10.0
POSITION_SD0 = 0.05
VELOCITY_SD0 = 0.1

# NHC as in upstream's drive configuration
NHC_SD = 0.10  # m/s, with GNSS
NHC_SD_COAST = 0.05  # m/s, inside a GNSS outage
NHC_MIN_SPEED = 2.0  # m/s
NHC_MAX_YAW_RATE_DPS = 10.0
NHC_RATE_HZ = None  # None: at the GNSS epochs (4 Hz)


def _load_pos() -> pd.DataFrame:
    cols = [
        "date", "time", "lat", "lon", "alt", "Q", "ns", "sdn", "sde", "sdu", "sdne", "sdeu",
        "sdun", "age", "ratio", "vn", "ve", "vu", "sdvn", "sdve", "sdvu", "sdvne", "sdveu",
        "sdvun",
    ]  # fmt: skip
    pos = pd.read_csv(POS_FILE, sep=r"\s+", comment="%", header=None, names=cols)
    stamp = pd.to_datetime(pos["date"] + " " + pos["time"], format="%Y/%m/%d %H:%M:%S.%f")
    pos["t"] = (stamp - stamp.iloc[0]).dt.total_seconds().round(6)
    pos["t0_unix"] = (stamp.iloc[0] - pd.Timestamp("1970-01-01")).total_seconds()
    return pos


def _load_imu(t0_unix: float, imu_t_off_s: float = IMU_T_OFF_S) -> pd.DataFrame:
    from pyins import transform
    from pyins.util import ACCEL_COLS, GYRO_COLS

    raw = pd.read_csv(IMU_FILE)
    if DROP_STALE:
        values = raw.iloc[:, 1:7].to_numpy()
        stale = np.r_[False, np.all(values[1:] == values[:-1], axis=1)]
        raw = raw[~stale]
    t = (raw["t_gpst_unix_s"].to_numpy() - t0_unix + imu_t_off_s).round(6)
    acc = raw[["acc_x_g", "acc_y_g", "acc_z_g"]].to_numpy() * G0
    gyro = np.deg2rad(raw[["gyro_x_dps", "gyro_y_dps", "gyro_z_dps"]].to_numpy())
    mat_sb = transform.mat_from_rph(MOUNT_RPY_DEG)
    # x_body = M^T x_sensor
    return pd.DataFrame(
        np.hstack([gyro @ mat_sb, acc @ mat_sb]), index=t, columns=GYRO_COLS + ACCEL_COLS
    )


def _schedule(length, every, start, t_last):
    if length is None:
        return []
    out = []
    s = start
    while s + length <= t_last - END_MARGIN_S + 1e-9:
        out.append((s, s + length))
        s += every
    return out


def _make_measurement_classes():
    from pyins import measurements, transform
    from pyins.util import RPH_COLS, VEL_COLS

    class RecordingPosition(measurements.Position):
        """pyins Position that keeps its innovation (predicted minus measured, NED m)."""

        def __init__(self, data, sd, imu_to_antenna_b=None):
            super().__init__(data, sd, imu_to_antenna_b)
            self.record_t: list[float] = []
            self.record_z: list[np.ndarray] = []

        def compute_matrices(self, time, pva, error_model):
            ret = super().compute_matrices(time, pva, error_model)
            if ret is not None:
                self.record_t.append(time)
                self.record_z.append(np.asarray(ret[0][:2], dtype=float))
            return ret

    class Nhc(measurements.Measurement):
        """Body lateral and vertical velocity zero (vehicle frame = pyins body frame).

        ``sd`` is per time (m/s); applied when the horizontal speed exceeds ``min_speed``
        and the body yaw rate is below ``max_yaw_rate`` (rad/s).
        """

        def __init__(self, times, sd, min_speed, max_yaw_rate):
            data = pd.DataFrame({"VY": 0.0, "VZ": 0.0, "sd": sd}, index=pd.Index(times))
            super().__init__(data)
            self.min_speed = min_speed
            self.max_yaw_rate = max_yaw_rate

        def compute_matrices(self, time, pva, error_model):
            if time not in self.data.index:
                return None
            v_n = np.asarray(pva[VEL_COLS], dtype=float)
            if np.hypot(v_n[0], v_n[1]) < self.min_speed:
                return None
            if "rate_z" in pva and abs(pva["rate_z"]) > self.max_yaw_rate:
                return None
            row = self.data.loc[time]
            mat_nb = transform.mat_from_rph(pva[RPH_COLS])
            z = (mat_nb.T @ v_n)[1:] - row[["VY", "VZ"]].to_numpy(dtype=float)
            H = error_model.body_velocity_error_jacobian(pva)[1:]
            return z, H, row["sd"] ** 2 * np.eye(2)

    return RecordingPosition, Nhc


def _horizontal_error_at(trajectory, fixes, lever_b):
    """Horizontal antenna error (m) of ``trajectory`` at the fix times (NaN outside)."""
    from pyins import transform
    from pyins.util import LLA_COLS

    ant = transform.translate_trajectory(trajectory, lever_b)
    t = fixes["t"].to_numpy()
    tt = ant.index.to_numpy()
    inside = (t >= tt[0]) & (t <= tt[-1])
    lla = np.column_stack([np.interp(t, tt, ant[c].to_numpy()) for c in LLA_COLS])
    d = transform.compute_lla_difference(lla, fixes[LLA_COLS].to_numpy())
    err = np.hypot(d[:, 0], d[:, 1])
    err[~inside] = np.nan
    return err


def run_pyins(
    outage_length_s: float | None,
    outage_every_s: float = 60.0,
    outage_start_s: float = 40.0,
    nhc: bool = False,
    *,
    imu_t_off_s: float = IMU_T_OFF_S,
    velocity_time_offset_s: float = 0.0,
    outages: list[tuple[float, float]] | None = None,
) -> dict:
    """Process the drive with pyins; see the module docstring for what is reported.

    ``imu_t_off_s`` is added to the IMU stamps; ``velocity_time_offset_s`` (< 0: the
    RTKLIB velocities lag the positions) moves each velocity onto the position stamps by
    linear interpolation at ``t − offset``, as ftnav's recording option of that name;
    ``outages`` (s after the first GNSS epoch) replaces the regular schedule (ftnav's
    interleaved schedules of long outages are run one list at a time).
    """
    from pyins import filters, inertial_sensor, measurements, strapdown, transform
    from pyins.util import LLA_COLS, RPH_COLS, VEL_COLS

    wall0 = time.perf_counter()
    pos = _load_pos()
    imu = _load_imu(float(pos["t0_unix"].iloc[0]), imu_t_off_s)
    if velocity_time_offset_s:
        for c in ("vn", "ve", "vu"):
            pos[c] = np.interp(pos["t"] - velocity_time_offset_s, pos["t"], pos[c])
    fixes = pos[pos["Q"] == 1].copy()
    fixes["VN"], fixes["VE"], fixes["VD"] = fixes["vn"], fixes["ve"], -fixes["vu"]
    fixes = fixes.set_index("t", drop=False)
    t_last = float(pos["t"].iloc[-1])
    if outages is None:
        outages = _schedule(outage_length_s, outage_every_s, outage_start_s, t_last)

    # static levelling
    f_static = imu.loc[imu.index < STATIC_S, ["accel_x", "accel_y", "accel_z"]].mean()
    fx, fy, fz = f_static.to_numpy()
    roll = np.degrees(np.arctan2(-fy, -fz))
    pitch = np.degrees(np.arctan2(fx, np.hypot(fy, fz)))
    # heading from the GNSS course at the first fix faster than HEADING_MIN_SPEED
    moving = fixes[np.hypot(fixes["vn"], fixes["ve"]) > HEADING_MIN_SPEED].iloc[0]
    heading = np.degrees(np.arctan2(moving["ve"], moving["vn"]))

    lever_b = GNSS_OFFSET_M - IMU_OFFSET_M
    t_start = float(imu.index[0])
    first = fixes[fixes["t"] <= t_start].iloc[-1] if (fixes["t"] <= t_start).any() else None
    first = fixes.iloc[0] if first is None else first
    pva_ant = pd.Series(
        np.hstack([first[LLA_COLS].to_numpy(float), [0.0, 0.0, 0.0], [roll, pitch, heading]]),
        index=LLA_COLS + VEL_COLS + RPH_COLS,
    )
    pva0 = transform.translate_trajectory(pva_ant, -lever_b)
    pva0.name = t_start

    increments = strapdown.compute_increments_from_imu(imu, "rate")

    used = np.ones(len(fixes), dtype=bool)
    for s, e in outages:
        used &= ~((fixes["t"] >= s) & (fixes["t"] < e)).to_numpy()
    meas_fixes = fixes[used]
    pos_sd = float(np.median(fixes[["sdn", "sde", "sdu"]].to_numpy()))
    vel_sd = float(np.median(fixes[["sdvn", "sdve", "sdvu"]].to_numpy()))
    RecordingPosition, Nhc = _make_measurement_classes()
    position = RecordingPosition(meas_fixes, pos_sd, lever_b)
    velocity = measurements.NedVelocity(meas_fixes, vel_sd, lever_b)
    meas = [position, velocity]
    if nhc:
        t_nhc = pos["t"].to_numpy()
        if NHC_RATE_HZ is not None:
            t_nhc = np.round(np.arange(0.0, t_last, 1.0 / NHC_RATE_HZ), 6)
        coast = np.zeros(len(t_nhc), dtype=bool)
        for s, e in outages:
            coast |= (t_nhc >= s) & (t_nhc < e)
        sd = np.where(coast, NHC_SD_COAST, NHC_SD)
        meas.append(Nhc(t_nhc, sd, NHC_MIN_SPEED, np.deg2rad(NHC_MAX_YAW_RATE_DPS)))

    gyro_model = inertial_sensor.EstimationModel(
        bias_sd=GYRO_BIAS_SD, noise=GYRO_NOISE, bias_walk=GYRO_BIAS_WALK
    )
    accel_model = inertial_sensor.EstimationModel(
        bias_sd=ACCEL_BIAS_SD, noise=ACCEL_NOISE, bias_walk=ACCEL_BIAS_WALK
    )
    result = filters.run_feedback_filter(
        pva0,
        POSITION_SD0,
        VELOCITY_SD0,
        LEVEL_SD_DEG,
        AZIMUTH_SD_DEG,
        increments,
        gyro_model=gyro_model,
        accel_model=accel_model,
        measurements=meas,
        time_step=0.1,
    )
    trajectory = result.trajectory

    z = np.asarray(position.record_z)
    before = np.hypot(z[:, 0], z[:, 1])
    err = _horizontal_error_at(trajectory, fixes, lever_b)
    after = err[used & ~np.isnan(err)]
    report = []
    for s, e in outages:
        inside = ((fixes["t"] >= s) & (fixes["t"] < e)).to_numpy() & ~np.isnan(err)
        if not inside.any():
            continue
        e_in = err[inside]
        report.append(
            {"start": s, "end": e, "end_error_m": float(e_in[-1]), "max_error_m": float(e_in.max())}
        )
    maxima = np.array([o["max_error_m"] for o in report])
    wall = time.perf_counter() - wall0
    return {
        "wall_s": wall,
        "rms_before_update_m": float(np.sqrt(np.mean(before**2))),
        "rms_after_update_m": float(np.sqrt(np.mean(after**2))),
        "outages": report,
        "rms_max_drift_m": float(np.sqrt(np.mean(maxima**2))) if len(maxima) else None,
        "n_fixes_used": int(len(before)),
        "gyro_bias_final_dps": np.degrees(result.gyro.iloc[-1].to_numpy()).tolist(),
        "accel_bias_final": result.accel.iloc[-1].to_numpy().tolist(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outage-length", type=float, default=None)
    ap.add_argument("--outage-every", type=float, default=60.0)
    ap.add_argument("--outage-start", type=float, default=40.0)
    ap.add_argument("--nhc", action="store_true")
    args = ap.parse_args()
    r = run_pyins(args.outage_length, args.outage_every, args.outage_start, args.nhc)
    mode = "GNSS on" if args.outage_length is None else f"{args.outage_length:g} s outages"
    print(f"pyins drive_0708, {mode}{', NHC' if args.nhc else ''}: wall {r['wall_s']:.1f} s")
    print(f"  horizontal RMS before update {r['rms_before_update_m']:.3f} m, "
          f"after {r['rms_after_update_m']:.3f} m ({r['n_fixes_used']} fixes)")  # fmt: skip
    if r["outages"]:
        print(f"  {'start s':>8} {'end s':>8} {'end err m':>10} {'max err m':>10}")
        for o in r["outages"]:
            print(
                f"  {o['start']:8.1f} {o['end']:8.1f} {o['end_error_m']:10.2f} "
                f"{o['max_error_m']:10.2f}"
            )
        print(f"  RMS of the per-outage maximum drift: {r['rms_max_drift_m']:.2f} m")


if __name__ == "__main__":
    main()
