"""ftnav beside python-ins (pyins 1.0) on the same real drive and the same GNSS outages.

Both process the vendored rtklibexplorer car drive (MEMS IMU 100 Hz + RTK GNSS 4 Hz),
loosely coupled, scored against the RTK fixes (Q = 1): GNSS on, then outages of
``--outage-length`` s every ``--outage-every`` s from ``--outage-start`` s (after the first
GNSS epoch, clipped 30 s before the end), once with GNSS only and once with the vehicle
constraints (ftnav: NHC + ZUPT; pyins: NHC).  Printed per case: the RMS over outages of
the maximum horizontal drift, the per-outage range, and the wall time of each tool.

Same inputs for both: the GNSS epochs (Q = 1), the timing of ``rtklib-drive.toml`` (IMU
stamps + its ``time_offset_s``; the RTKLIB velocities moved onto the position stamps by
its ``velocity_time_offset_s``; ``--upstream-timing`` gives pyins upstream's -0.125 s and
velocities as stamped instead), and the same outage schedule: a long outage schedule
that ftnav splits into interleaved runs (:func:`ftnav.recorded.stream.interleave`, 60 s
every 60 s: two runs) is run by pyins as the same runs, one pyins run each.

    python benchmarks/bench_recorded.py                       # 15 s and 60 s outages
    python benchmarks/bench_recorded.py --lengths 15          # one schedule

The pyins side is ``benchmarks/peer_pyins_drive.py`` (its settings in its docstring).
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from peer_pyins_drive import run_pyins  # noqa: E402

from ftnav.engine import navigation_model  # noqa: E402
from ftnav.engine.driver import run  # noqa: E402
from ftnav.eval.montecarlo import build_filters  # noqa: E402
from ftnav.eval.recorded import Reference, score_recording  # noqa: E402
from ftnav.io.recording_file import load_recording  # noqa: E402
from ftnav.io.recording_readers import read_rtklib_pos  # noqa: E402
from ftnav.recorded.stream import interleave, outage_schedule  # noqa: E402
from ftnav.recordings import recording_path  # noqa: E402

POS = "data/rtklibexplorer/drive_0708/gnss_1934_sf.pos"


def drive_timing() -> tuple[float, float]:
    """The IMU time offset and the GNSS velocity time offset of rtklib-drive.toml."""
    doc = tomllib.loads(recording_path("rtklib-drive").read_text())
    gnss = next(a for a in doc["aids"] if a["type"] == "gnss")
    return doc["imu"]["time_offset_s"], gnss.get("velocity_time_offset_s", 0.0)


def pyins_runs(length: float, every: float, start: float, nhc: bool, timing: dict) -> dict:
    """pyins over ftnav's (interleaved) schedule: one pyins run per ftnav run, merged."""
    last = _last_gnss_s()
    runs = interleave(outage_schedule(length, every, start, last), every)
    outages, wall = [], 0.0
    for r in runs:
        p = run_pyins(length, every, start, nhc=nhc, outages=list(r), **timing)
        outages += p["outages"]
        wall += p["wall_s"]
    maxima = np.array([o["max_error_m"] for o in outages])
    return {
        "count": len(outages),
        "rms_max_error_m": float(np.sqrt(np.mean(maxima**2))),
        "each": [{"max_error_m": o["max_error_m"]} for o in outages],
        "wall_s": wall,
    }


def _last_gnss_s() -> float:
    """Seconds from the first to the last GNSS epoch of the drive (outage clipping)."""
    pos = read_rtklib_pos(recording_path("rtklib-drive").parent / POS)
    return float(pos.t.max() - pos.t.min())


def ftnav_drive(outage, aids) -> tuple[dict, float]:
    """The centralized filter's scores on the drive and its wall time (load + run)."""
    t0 = time.perf_counter()
    loaded = load_recording(
        recording_path("rtklib-drive"), outage=outage, methods=["ckf"], aids=aids
    )
    rec = loaded.recording
    filters = build_filters(rec, rec.system(), rec.methods)
    traces = run(navigation_model(rec), loaded.stream, filters, rec.steps)
    ref = Reference(loaded.reference_index, loaded.reference_p)
    scores = score_recording(rec, traces, ref, loaded.outages)["ckf"]
    return scores, time.perf_counter() - t0


def _row(tool: str, case: str, o: dict | None, on: float | None, wall: float) -> str:
    if o is None:
        return f"{tool:<6} {case:<24} GNSS on: {on:.3f} m RMS{'':<28} {wall:6.1f} s"
    each = [r["max_error_m"] for r in o["each"]]
    return (
        f"{tool:<6} {case:<24} {o['count']} outages: RMS of max drift "
        f"{o['rms_max_error_m']:7.2f} m ({min(each):.1f}-{max(each):.1f})  {wall:6.1f} s"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", type=float, nargs="+", default=[15.0, 60.0])
    ap.add_argument("--outage-every", type=float, default=60.0)
    ap.add_argument("--outage-start", type=float, default=40.0)
    ap.add_argument("--upstream-timing", action="store_true")
    a = ap.parse_args()
    imu_off, vel_off = drive_timing()
    timing = (
        {} if a.upstream_timing else {"imu_t_off_s": imu_off, "velocity_time_offset_s": vel_off}
    )
    peer = "upstream -0.125 s, velocities as stamped" if a.upstream_timing else "the same"
    print(f"timing: IMU {imu_off:+g} s, GNSS velocities {vel_off:+g} s (ftnav); pyins: {peer}")
    gnss = ["gnss", "gnss-vel"]  # the receiver's position and velocity aids
    s, w = ftnav_drive(None, gnss)
    print(_row("ftnav", "gnss", None, s["horizontal_rms_m"], w))
    p = run_pyins(None, **timing)
    print(_row("pyins", "gnss", None, p["rms_after_update_m"], p["wall_s"]))
    for length in a.lengths:
        outage = (length, a.outage_every, a.outage_start)
        for ft_aids, py_nhc, case in ((gnss, False, "gnss"), (None, True, "constraints")):
            s, w = ftnav_drive(outage, ft_aids)
            print(_row("ftnav", f"{length:g} s, {case}", s["outages"], None, w), flush=True)
            po = pyins_runs(length, a.outage_every, a.outage_start, py_nhc, timing)
            print(_row("pyins", f"{length:g} s, {case}", po, None, po["wall_s"]), flush=True)


if __name__ == "__main__":
    main()
