"""ftnav beside python-ins (pyins 1.0) on the NaveGo synthetic data set, same bias prior.

Both process NaveGo's two simulated IMUs (``navego-adis16488``: ``imu2.mat``;
``navego-adis16405``: ``imu1.mat``; 200 Hz) with its 5 Hz GNSS (position and velocity),
loosely coupled, from NaveGo's own start (the true ``ini_align`` at the first fix, σ
``ini_align_err``, the fix's σ 5, 5, 10 m and 0.0514 m/s), and are scored against the
exact truth ``ref.mat``.  GNSS outages of ``--outage-length`` s every ``--outage-every``
s from ``--outage-start`` s after the first GNSS epoch (ending 30 s before the last;
30/60/40: six outages, one run) are the outages of ftnav's loaded recording
(``LoadedRecording.outages``, per interleaved run), given to pyins run by run.  Printed
per set and tool: the RMS over outages of the maximum horizontal error within each
outage, its range over the outages, the horizontal RMS with GNSS on (the epochs outside
every outage), ftnav's 9-state NEES (its mean and the fraction of GNSS-on epochs after
60 s inside the two-sided 95 % χ²(9) band), and the wall time (load + run; pyins' first
run includes numba's compilation, about 8 s).  Both tools are scored at ftnav's
reference epochs (every filter epoch: 0.1 s for the ADIS16488, 0.02 s for the
ADIS16405).

The tools:

* ftnav: ``ckf`` (centralized EKF, 15 states, feedback) of the built-in recordings, with
  ``[filter] bias_compensation = true`` (their default: the bias estimates are fed back
  and subtracted from the increments, as pyins does), and once more with it off
  (``dataclasses.replace(recording, bias_compensation=False)`` on the loaded recording);
* pyins: ``benchmarks/peer_pyins_navego.py`` (``filters.run_feedback_filter``, 9 + 3 + 3
  states, covariance step 0.1 s), given the same prior.  Before running, every number
  pyins is given is checked against ftnav's loaded recording: per axis (ftnav's body
  x right, y forward, z up reordered to pyins' forward, right, down) gyro / accel
  ``bias_sd`` = the bias states' initial σ (hypot of the static σ and the Gauss–Markov
  σ), ``noise`` = sqrt of the white-noise PSD (ARW, VRW), ``bias_walk`` = sqrt of the
  bias random-walk PSD 2σ²/τ (σ, τ of the 100 s Gauss–Markov part), the level and
  heading σ, the velocity σ and the position σ N, E, D (to 1 %: ftnav's metres -> rad
  on a sphere, pyins' on the ellipsoid).  The table of that mapping is in the peer's
  docstring.

Usage::

    python benchmarks/bench_navego.py                     # both sets, 30 s every 60 s from 40 s
    python benchmarks/bench_navego.py --sets navego-adis16488

Measured 2026-12-02 (2-core shared machine; one run each):

    set               tool                 drift m per outage m   GNSS-on     NEES in band   wall s
    navego-adis16488  ftnav ckf               4.27   2.24-7.11      0.764  77.2 % (μ 12.8)      4.6
    navego-adis16488  ftnav ckf (no bc)       5.17   2.75-9.96      0.762  82.8 % (μ 12.4)      4.4
    navego-adis16488  pyins                   4.35   1.93-7.74      0.769                -    286.5
    navego-adis16405  ftnav ckf              11.37   4.88-17.51     1.077  95.8 % (μ 10.3)     22.2
    navego-adis16405  ftnav ckf (no bc)      28.25   5.91-63.85     1.082  81.6 % (μ 14.7)     19.8
    navego-adis16405  pyins                  12.53   5.05-17.72     1.080                -    283.7

With the same prior ftnav (bias compensation on) is ahead of pyins on both sets, by 2 %
on the ADIS16488 and 9 % on the ADIS16405.  The issue's targets (pyins' figures with its
own, tighter prior: 3.7 m and 11.9 m) are met on the ADIS16405 only: 4.27 m > 3.7 m on
the ADIS16488, where pyins with this prior gives 4.35 m.  ftnav's NEES on the ADIS16488
is inside the band at 77.2 % of the epochs (below 80 %; mean 12.8 against 9 for a
consistent filter: overconfident), at 95.8 % on the ADIS16405.  Without bias
compensation the ADIS16405's 3 deg/s gyro bias costs ftnav 2.5 times the drift.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from peer_pyins_navego import (  # noqa: E402
    SETS,
    PyinsSettings,
    _load,
    run_pyins,
    settings_from_navego,
)

from ftnav.io.recording_file import LoadedRecording  # noqa: E402
from ftnav.pipeline import prepare_recording  # noqa: E402

#: ftnav's body axes (x right, y forward, z up) -> pyins' (forward, right, down), per axis
#: σ (signs do not matter)
RFU_TO_FRD = [1, 0, 2]
EARTH_A_M = 6378137.0  # ftnav's metres -> rad of the initial position σ (a sphere)


def ftnav_set(
    name: str, outages: tuple, bias_compensation: bool
) -> tuple[dict, float, LoadedRecording]:
    """ftnav's ``ckf`` scores on one set, the wall time (load + run), the loaded recording."""
    t0 = time.perf_counter()
    prep = prepare_recording(name, methods=["ckf"], outages=outages)
    if bias_compensation != prep.recording.bias_compensation:
        rec = replace(prep.recording, bias_compensation=bias_compensation)
        prep = prepare_recording(prep.loaded._replace(recording=rec))
    result = prep.run()
    # in their JSON form, beside the peer's dicts of the same names
    return result.scores["ckf"].as_dict(), time.perf_counter() - t0, prep.loaded


def check_same_prior(loaded: LoadedRecording, st: PyinsSettings) -> None:
    """Raise unless pyins is given ftnav's bias prior, noise and initial σ (docstring)."""
    rec = loaded.recording
    em, sig = rec.error_model, np.asarray(rec.initial_sigma)
    lat, _, h = loaded.alignment.p
    R = EARTH_A_M + h
    pairs = {
        "gyro bias_sd": (sig[9:12][RFU_TO_FRD], st.gyro_bias_sd),
        "accel bias_sd": (sig[12:15][RFU_TO_FRD], st.accel_bias_sd),
        "gyro noise": (np.sqrt(em.gyro_psd)[RFU_TO_FRD], st.gyro_noise),
        "accel noise": (np.sqrt(em.accel_psd)[RFU_TO_FRD], st.accel_noise),
        "gyro bias_walk": (np.sqrt(em.gyro_bias_rw_psd)[RFU_TO_FRD], st.gyro_bias_walk),
        "accel bias_walk": (np.sqrt(em.accel_bias_rw_psd)[RFU_TO_FRD], st.accel_bias_walk),
        "level σ": (np.degrees(sig[0:2]), np.full(2, st.level_sd_deg)),
        "heading σ": (np.degrees(sig[2]), st.azimuth_sd_deg),
        "velocity σ": (sig[3:6], st.velocity_sd_mps),
    }
    for what, (ft, py) in pairs.items():
        np.testing.assert_allclose(py, ft, rtol=1e-9, err_msg=f"{rec.name}: {what}")
    pos = np.array([sig[6] * R, sig[7] * R * np.cos(lat), sig[8]])  # N, E, D m
    np.testing.assert_allclose(st.position_sd_m, pos, rtol=1e-2, err_msg=f"{rec.name}: position σ")


def pyins_set(name: str, loaded: LoadedRecording, st: PyinsSettings) -> dict:
    """pyins over ftnav's outage runs (one pyins run each, merged), at ftnav's reference
    epochs."""
    rec = loaded.recording
    score_times = np.asarray(rec.times)[loaded.reference_index]
    outages, wall, on = [], 0.0, None
    for run in loaded.outages:
        p = run_pyins(name, list(run), st, score_times)
        outages += p["outages"]
        wall += p["wall_s"]
        on = p["rms_gnss_on_m"] if on is None else on  # the first run's, as ftnav's
    maxima = np.array([o["max_error_m"] for o in outages])
    return {
        "rms_max_error_m": float(np.sqrt(np.mean(maxima**2))),
        "each": maxima,
        "rms_gnss_on_m": on,
        "wall_s": wall,
    }


def _row(name: str, tool: str, drift: float, each, on: float, nees: str, wall: float) -> str:
    each = np.asarray(each)
    return (
        f"{name:<17} {tool:<18} {drift:9.2f} {each.min():6.2f}-{each.max():<6.2f} "
        f"{on:8.3f} {nees:>16} {wall:8.1f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="+", choices=list(SETS), default=list(SETS))
    ap.add_argument("--outage-length", type=float, default=30.0)
    ap.add_argument("--outage-every", type=float, default=60.0)
    ap.add_argument("--outage-start", type=float, default=40.0)
    a = ap.parse_args()
    outages = (a.outage_length, a.outage_every, a.outage_start)
    print(
        f"{'set':<17} {'tool':<18} {'drift m':>9} {'per outage m':<13} {'GNSS-on':>8} "
        f"{'NEES in band':>16} {'wall s':>8}"
    )
    for name in a.sets:
        for bc in (True, False):
            s, wall, loaded = ftnav_set(name, outages, bc)
            o, nees = s["outages"], s["truth"]["nees"]
            band = f"{100 * nees['fraction_inside']:.1f} % (μ {nees['mean']:.1f})"
            tool = "ftnav ckf" + ("" if bc else " (no bc)")
            each = [r["max_error_m"] for r in o["each"]]
            print(_row(name, tool, o["rms_max_error_m"], each, s["horizontal_rms_m"], band, wall))
        imu = SETS[name]
        st = settings_from_navego(_load(imu, imu), _load("gnss", "gnss"))
        check_same_prior(loaded, st)
        p = pyins_set(name, loaded, st)
        row = _row(
            name, "pyins", p["rms_max_error_m"], p["each"], p["rms_gnss_on_m"], "-", p["wall_s"]
        )
        print(row, flush=True)


if __name__ == "__main__":
    main()
