"""Peer run: python-ins (pyins 1.x) loosely coupled GNSS/INS on the NaveGo synthetic data set.

Data: ``navego_synthetic`` (R. Gonzalez, NaveGo, LGPL-3; Zenodo 10.5281/zenodo.6549626;
see its README): a simulated ADIS16405 (``imu1.mat``) or ADIS16488 (``imu2.mat``) at
200 Hz, GNSS at 5 Hz (``gnss.mat``) and the exact 200 Hz truth (``ref.mat``).  Read from
``$FTNAV_NAVEGO_DIR``, else ``<repository>/../shared/data/navego_synthetic`` (as ftnav's
``navego-adis16488.toml`` / ``navego-adis16405.toml``).

What the peer does (everything through pyins' public API except one documented patch;
nothing from ftnav):

* IMU: ``wb`` (rad/s) and ``fb`` (m/s^2) as stored: NaveGo's body axes (x forward, y right,
  z down) are pyins' body axes; ``strapdown.compute_increments_from_imu(..., 'rate')``.
* Start (NaveGo's own, ftnav's ``[alignment] mode = "given"``): at the first GNSS fix at or
  after the first IMU sample (t = 0 s), its position and NED velocity, the attitude
  ``ini_align`` (the true one: roll, pitch, yaw).  Initial σ: roll and pitch
  ``ini_align_err[0:2]``, heading ``ini_align_err[2]``, velocity ``stdv``, position the
  fix's σ N, E, D from ``std`` (lat, lon rad -> m with pyins' radii; h m): 5, 5, 10 m.
  ``run_feedback_filter`` takes one position σ for all three axes; a scoped wrapper of
  ``filters._initialize_covariance`` adds the rest of the down variance (10^2 - 5^2 m^2)
  so the vertical starts at 10 m as in ftnav.  The fix at the start is the initial
  position and is not processed again (ftnav's first update is one epoch later).
* ``filters.run_feedback_filter`` (EKF with feedback: 9 INS + 3 gyro + 3 accel bias
  states; the bias estimates are subtracted from the increments, as ftnav's
  ``bias_compensation``) with ``measurements.Position`` (σ N, E, D from ``std``) and
  ``measurements.NedVelocity`` (σ ``stdv``) at every 5 Hz fix outside the outages; no
  lever arm (``larm = 0``); ``time_step`` (covariance propagation) 0.1 s, pyins'
  default and ftnav's epoch spacing for the ADIS16488 (ftnav runs the ADIS16405 at
  0.02 s, for a reason of its own error model; pyins takes about 1 s per second of data
  at 0.1 s on one core, and five times the steps at 0.02 s).
* The bias prior, per axis, from the data set's own SI fields (the numbers of ftnav's
  recordings, whose 15-state model has a random-constant bias driven by a random walk):

  ===================================  =========================================
  pyins ``EstimationModel``            ftnav 15-state model / NaveGo field
  ===================================  =========================================
  gyro ``bias_sd`` (rad/s)             hypot(``gyro_bias_sd``, ``gyro_markov_sd``)
                                       = hypot(``gb_sta``, ``gb_dyn``)
  gyro ``noise`` (rad/s/sqrt(Hz))      ``gyro_arw`` = ``arw``
  gyro ``bias_walk`` (rad/s/sqrt(s))   sqrt(2 σ²/τ) of the Markov part
                                       = ``gb_dyn`` · sqrt(2 / ``gb_corr``)
  accel ``bias_sd`` (m/s^2)            hypot(``ab_sta``, ``ab_dyn``)
  accel ``noise`` (m/s^2/sqrt(Hz))     ``accel_vrw`` = ``vrw``
  accel ``bias_walk`` (m/s^2/sqrt(s))  ``ab_dyn`` · sqrt(2 / ``ab_corr``)
  ===================================  =========================================

  ftnav's model stores the walk as the PSD ``2σ²/τ`` (``gyro_bias_rw_psd``) and the
  white noise as the PSD ``ARW²``; pyins takes their square roots.
  ``benchmarks/bench_navego.py`` checks every number against ftnav's loaded recording.

Scores (horizontal, against ``ref.mat``, at the score epochs: by default every
``time_step`` from the start, the bench gives ftnav's reference epochs): per outage
``[s, e)`` (s after the start) the error at its last epoch and the maximum within;
``rms_max_drift_m`` is the RMS over outages of those maxima; ``rms_gnss_on_m`` the RMS
over the epochs outside every outage.  pyins returns per-state σ only (not the 9 x 9
covariance), so no NEES is reported.

Usage: ``python benchmarks/peer_pyins_navego.py [--set navego-adis16405] [--outage-length
30] [--outage-every 60] [--outage-start 40] [--time-step 0.02]`` (no ``--outage-length``:
GNSS on all the time).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd
from scipy.io import loadmat

_SHARED = Path(__file__).parents[2] / "shared/data/navego_synthetic"
DATA_DIR = Path(os.environ.get("FTNAV_NAVEGO_DIR") or str(_SHARED))
#: ftnav's recording name -> the IMU struct of the data set
SETS = {"navego-adis16488": "imu2", "navego-adis16405": "imu1"}
END_MARGIN_S = 30.0


class PyinsSettings(NamedTuple):
    """What pyins is given: per-axis (3,) sensor-model parameters in SI (module docstring),
    the initial σ and the covariance time step."""

    gyro_bias_sd: np.ndarray
    gyro_noise: np.ndarray
    gyro_bias_walk: np.ndarray
    accel_bias_sd: np.ndarray
    accel_noise: np.ndarray
    accel_bias_walk: np.ndarray
    level_sd_deg: float
    azimuth_sd_deg: float
    velocity_sd_mps: np.ndarray  # (3,) N, E, D
    position_sd_m: np.ndarray  # (3,) N, E, D
    time_step_s: float


def _load(name: str, what: str):
    return loadmat(DATA_DIR / f"{name}.mat", squeeze_me=True, struct_as_record=False)[what]


def settings_from_navego(imu, gnss, time_step_s: float = 0.1) -> PyinsSettings:
    """The bias prior and initial σ of ftnav's NaveGo recordings, from the data set's own
    fields (module docstring's table)."""
    ini_err = np.degrees(np.asarray(imu.ini_align_err, float))
    if ini_err[0] != ini_err[1]:
        raise ValueError(f"pyins takes one level σ; ini_align_err gives roll, pitch {ini_err[:2]}")
    rn, _, rp = _radii(gnss)
    std = np.asarray(gnss.std, float)
    return PyinsSettings(
        gyro_bias_sd=np.hypot(imu.gb_sta, imu.gb_dyn),
        gyro_noise=np.asarray(imu.arw, float),
        gyro_bias_walk=imu.gb_dyn * np.sqrt(2.0 / imu.gb_corr),
        accel_bias_sd=np.hypot(imu.ab_sta, imu.ab_dyn),
        accel_noise=np.asarray(imu.vrw, float),
        accel_bias_walk=imu.ab_dyn * np.sqrt(2.0 / imu.ab_corr),
        level_sd_deg=float(ini_err[0]),
        azimuth_sd_deg=float(ini_err[2]),
        velocity_sd_mps=np.asarray(gnss.stdv, float) * np.ones(3),
        position_sd_m=np.array([std[0] * rn, std[1] * rp, std[2]]),
        time_step_s=time_step_s,
    )


def _radii(gnss) -> tuple[float, float, float]:
    from pyins import earth

    lat = float(np.degrees(np.mean(gnss.lat)))
    return earth.principal_radii(lat, float(np.mean(gnss.h)))


@contextmanager
def _position_sd_down(sd_down: float, sd: float) -> Iterator[None]:
    """``run_feedback_filter`` with the initial down σ ``sd_down`` instead of the ``sd`` it
    gives all three position axes: its covariance initializer, wrapped while inside."""
    from pyins import filters

    original = filters._initialize_covariance

    def initialize(pva, pos_sd, vel_sd, level_sd, azimuth_sd, error_model, *models):
        P = original(pva, pos_sd, vel_sd, level_sd, azimuth_sd, error_model, *models)
        extra = np.zeros((9, 9))
        extra[error_model.DRD, error_model.DRD] = sd_down**2 - sd**2
        T = error_model.transform_to_internal(pva)
        n = error_model.n_states
        P[:n, :n] += T @ extra @ T.T
        return P

    filters._initialize_covariance = initialize
    try:
        yield
    finally:
        filters._initialize_covariance = original


def _schedule(length, every, start, t_last):
    out = []
    s = start
    while s + length <= t_last - END_MARGIN_S + 1e-9:
        out.append((s, s + length))
        s += every
    return out


def run_pyins(
    name: str = "navego-adis16488",
    outages: Sequence[tuple[float, float]] = (),
    settings: PyinsSettings | None = None,
    score_times: np.ndarray | None = None,
) -> dict:
    """Process one NaveGo set with pyins; see the module docstring for what is reported.

    ``outages`` (s after the start: the first GNSS fix in the IMU log, t = 0 here) remove
    the GNSS fixes in ``[s, e)``; ``settings`` default to :func:`settings_from_navego`;
    ``score_times`` (s after the start) default to every ``time_step_s``.
    """
    from pyins import filters, inertial_sensor, measurements, strapdown, transform
    from pyins.util import ACCEL_COLS, GYRO_COLS, LLA_COLS, RPH_COLS, VEL_COLS

    wall0 = time.perf_counter()
    what = SETS[name]
    imu_s, gnss_s, ref_s = _load(what, what), _load("gnss", "gnss"), _load("ref", "ref")
    st = settings_from_navego(imu_s, gnss_s) if settings is None else settings

    imu = pd.DataFrame(
        np.hstack([imu_s.wb, imu_s.fb]),
        index=np.asarray(imu_s.t, float),
        columns=GYRO_COLS + ACCEL_COLS,
    )
    increments = strapdown.compute_increments_from_imu(imu, "rate")
    fixes = pd.DataFrame(
        {
            "lat": np.degrees(gnss_s.lat),
            "lon": np.degrees(gnss_s.lon),
            "alt": gnss_s.h,
            "VN": gnss_s.vel[:, 0],
            "VE": gnss_s.vel[:, 1],
            "VD": gnss_s.vel[:, 2],
        },
        index=np.asarray(gnss_s.t, float),
    )
    t_imu = imu.index.to_numpy()
    within = fixes.index[(fixes.index >= t_imu[0]) & (fixes.index < t_imu[-1])]
    t_start = float(within.min())
    first = fixes.loc[t_start]
    pva0 = pd.Series(
        np.hstack([first[LLA_COLS + VEL_COLS].to_numpy(float), np.degrees(imu_s.ini_align)]),
        index=LLA_COLS + VEL_COLS + RPH_COLS,
        name=t_start,
    )

    rel = fixes.index.to_numpy() - t_start
    used = rel > 1e-9
    for s, e in outages:
        used &= ~((rel >= s - 1e-9) & (rel < e - 1e-9))
    meas = [
        measurements.Position(fixes[used], st.position_sd_m),
        measurements.NedVelocity(fixes[used], st.velocity_sd_mps),
    ]
    gyro_model = inertial_sensor.EstimationModel(
        bias_sd=st.gyro_bias_sd, noise=st.gyro_noise, bias_walk=st.gyro_bias_walk
    )
    accel_model = inertial_sensor.EstimationModel(
        bias_sd=st.accel_bias_sd, noise=st.accel_noise, bias_walk=st.accel_bias_walk
    )
    sd_h = float(np.max(st.position_sd_m[:2]))
    with _position_sd_down(float(st.position_sd_m[2]), sd_h):
        result = filters.run_feedback_filter(
            pva0,
            sd_h,
            float(np.max(st.velocity_sd_mps)),
            st.level_sd_deg,
            st.azimuth_sd_deg,
            increments,
            gyro_model=gyro_model,
            accel_model=accel_model,
            measurements=meas,
            time_step=st.time_step_s,
        )
    traj = result.trajectory

    if score_times is None:
        last = float(traj.index[-1]) - t_start
        score_times = np.arange(1, int(last / st.time_step_s + 1e-9) + 1) * st.time_step_s
    t_abs = t_start + np.asarray(score_times, float)
    tt, t_ref = traj.index.to_numpy(), np.asarray(ref_s.t, float)
    est = np.column_stack([np.interp(t_abs, tt, traj[c].to_numpy()) for c in LLA_COLS])
    ref_lla = np.column_stack(
        [np.degrees(ref_s.lat), np.degrees(ref_s.lon), np.asarray(ref_s.h, float)]
    )
    truth = np.column_stack([np.interp(t_abs, t_ref, ref_lla[:, j]) for j in range(3)])
    d = transform.compute_lla_difference(est, truth)
    err = np.hypot(d[:, 0], d[:, 1])

    rel_t = np.asarray(score_times, float)
    on = np.ones(len(rel_t), dtype=bool)
    report = []
    for s, e in outages:
        inside = (rel_t >= s) & (rel_t < e)
        on &= ~inside
        if inside.any():
            e_in = err[inside]
            report.append(
                {
                    "start": s,
                    "end": e,
                    "end_error_m": float(e_in[-1]),
                    "max_error_m": float(e_in.max()),
                }
            )
    maxima = np.array([o["max_error_m"] for o in report])
    return {
        "wall_s": time.perf_counter() - wall0,
        "t_start": t_start,
        "rms_gnss_on_m": float(np.sqrt(np.mean(err[on] ** 2))),
        "outages": report,
        "rms_max_drift_m": float(np.sqrt(np.mean(maxima**2))) if len(maxima) else None,
        "n_fixes_used": int(used.sum()),
        "gyro_bias_final_dps": np.degrees(result.gyro.iloc[-1].to_numpy()).tolist(),
        "accel_bias_final_mg": (result.accel.iloc[-1].to_numpy() / 9.80665e-3).tolist(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", choices=list(SETS), default="navego-adis16488")
    ap.add_argument("--outage-length", type=float, default=None)
    ap.add_argument("--outage-every", type=float, default=60.0)
    ap.add_argument("--outage-start", type=float, default=40.0)
    ap.add_argument("--time-step", type=float, default=0.1)
    args = ap.parse_args()
    gnss = _load("gnss", "gnss")
    settings = settings_from_navego(_load(SETS[args.set], SETS[args.set]), gnss, args.time_step)
    outages = []
    if args.outage_length is not None:
        t = np.asarray(gnss.t, float)
        outages = _schedule(args.outage_length, args.outage_every, args.outage_start, t[-1] - t[0])
    r = run_pyins(args.set, outages, settings)
    mode = "GNSS on" if not outages else f"{args.outage_length:g} s outages"
    print(f"pyins {args.set}, {mode}: wall {r['wall_s']:.1f} s, {r['n_fixes_used']} fixes used")
    print(f"  horizontal RMS with GNSS on {r['rms_gnss_on_m']:.3f} m")
    print(f"  final gyro bias {np.round(r['gyro_bias_final_dps'], 4)} deg/s, "
          f"accel bias {np.round(r['accel_bias_final_mg'], 2)} mg")  # fmt: skip
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
