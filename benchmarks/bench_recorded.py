"""ftnav beside python-ins (pyins 1.0) on the same real drive and the same GNSS outages.

Both process the vendored rtklibexplorer car drive (MEMS IMU 100 Hz + RTK GNSS 4 Hz),
loosely coupled, scored at the antenna against the RTK fixes (Q = 1): GNSS on (ftnav: the
posterior at each fix and the prediction just before it; pyins: its output trajectory and
its prediction), then several outage schedules (``--schedules LENGTH:EVERY``, from
``--outage-start`` s after the first GNSS epoch, clipped 30 s before the end), once with GNSS
only and once with the vehicle constraints (ftnav: NHC + ZUPT; pyins: NHC), for each IMU
time offset of ``--imu-offsets`` (the drive file's -0.20 s, chosen on this drive, and
upstream's -0.125 s: the sensitivity of the headline to that choice).  Printed per case: the
RMS over outages of the maximum horizontal drift, the per-outage range, the wall time of
each tool, and which is ahead: the difference of the two RMS with its 95 % interval, a
percentile bootstrap over the outages resampled in pairs (the same outage for both
tools; :data:`ftnav.eval.intervals.BOOTSTRAP_SEED`'s generator), "ahead" or "behind"
only when the interval excludes 0 (:func:`ftnav.eval.intervals.decide`), else
"undecided".

Same inputs for both: the GNSS epochs (Q = 1), the timing of ``rtklib-drive.toml`` (IMU
stamps + its ``time_offset_s``; the RTKLIB velocities moved onto the position stamps by
its ``velocity_time_offset_s``; ``--upstream-timing`` gives pyins upstream's -0.125 s and
velocities as stamped instead), and the same outage schedule: a long outage schedule
that ftnav splits into interleaved runs (:func:`ftnav.recorded.stream.interleave`, 60 s
every 60 s: two runs) is run by pyins as the same runs, one pyins run each.

    python benchmarks/bench_recorded.py                       # 3 schedules x 2 IMU offsets
    python benchmarks/bench_recorded.py --schedules 15:60 --imu-offsets -0.2

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

import tempfile  # noqa: E402

import tomli_w  # noqa: E402
from peer_pyins_drive import run_pyins  # noqa: E402

from ftnav.eval.intervals import (  # noqa: E402
    BOOTSTRAP_REPLICATES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    Interval,
    decide,
)
from ftnav.io.recording_readers import read_rtklib_pos  # noqa: E402
from ftnav.pipeline import process_recording  # noqa: E402
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
    outages.sort(key=lambda o: o["start"])
    maxima = np.array([o["max_error_m"] for o in outages])
    return {
        "count": len(outages),
        "rms_max_error_m": float(np.sqrt(np.mean(maxima**2))),
        "each": [{"max_error_m": o["max_error_m"]} for o in outages],
        "wall_s": wall,
    }


def paired_difference(ours: np.ndarray, theirs: np.ndarray) -> Interval:
    """RMS(ours) − RMS(theirs) of the per-outage maxima (the same outages, in order)
    with its percentile-bootstrap interval over the outages resampled in pairs."""
    n = len(ours)

    def rms(a: np.ndarray) -> np.ndarray:
        return np.asarray(np.sqrt(np.mean(a**2, -1)))

    value = float(rms(ours) - rms(theirs))
    pick = np.random.default_rng(BOOTSTRAP_SEED).integers(0, n, (BOOTSTRAP_REPLICATES, n))
    d = rms(ours[pick]) - rms(theirs[pick])
    lo, hi = np.quantile(d, [0.5 - CONFIDENCE / 2, 0.5 + CONFIDENCE / 2])
    return Interval(value, float(lo), float(hi), n, "paired bootstrap")


def _last_gnss_s() -> float:
    """Seconds from the first to the last GNSS epoch of the drive (outage clipping)."""
    pos = read_rtklib_pos(recording_path("rtklib-drive").parent / POS)
    return float(pos.t.max() - pos.t.min())


def drive_file(imu_offset: float, folder: Path) -> Path:
    """The drive's recording file with another IMU time offset (data paths made absolute)."""
    src = recording_path("rtklib-drive")
    doc = tomllib.loads(src.read_text())
    doc["imu"]["file"] = str(src.parent / doc["imu"]["file"])
    for a in doc["aids"]:
        if "file" in a:
            a["file"] = str(src.parent / a["file"])
    doc["imu"]["time_offset_s"] = imu_offset
    path = folder / f"drive{imu_offset:+.3f}.toml"
    path.write_text(tomli_w.dumps(doc))
    return path


def ftnav_drive(path: Path, outage, aids) -> tuple[dict, float]:
    """The centralized filter's scores on the drive and its wall time (load + run)."""
    t0 = time.perf_counter()
    r = process_recording(path, outages=outage, methods=["ckf"], aids=aids)
    # in their JSON form, beside the peer's dicts of the same names
    return r.scores["ckf"].as_dict(), time.perf_counter() - t0


def _row(tool: str, case: str, o: dict | None, on: tuple | None, wall: float) -> str:
    if o is None:
        post, pred = on or (None, None)
        pr = "-" if pred is None else f"{pred:.3f}"
        text = f"GNSS on: {post:.3f} m RMS (prediction {pr} m)"
        return f"{tool:<6} {case:<30} {text:<56} {wall:6.1f} s"
    each = [r["max_error_m"] for r in o["each"]]
    return (
        f"{tool:<6} {case:<30} {o['count']} outages: RMS of max drift "
        f"{o['rms_max_error_m']:7.2f} m ({min(each):.1f}-{max(each):.1f})  {wall:6.1f} s"
    )


def _schedule(text: str) -> tuple[float, float]:
    length, every = (float(x) for x in text.split(":"))
    return length, every


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--schedules", type=_schedule, nargs="+", default=[(15, 60), (10, 45), (30, 90)]
    )
    ap.add_argument("--outage-start", type=float, default=40.0)
    ap.add_argument("--imu-offsets", type=float, nargs="+", default=None)
    a = ap.parse_args()
    imu_off, vel_off = drive_timing()
    offsets = a.imu_offsets or [imu_off, -0.125]
    gnss = ["gnss", "gnss-vel"]  # the receiver's position and velocity aids
    ahead = []
    with tempfile.TemporaryDirectory() as tmp:
        for off in offsets:
            path = drive_file(off, Path(tmp))
            timing = {"imu_t_off_s": off, "velocity_time_offset_s": vel_off}
            print(f"IMU time offset {off:+g} s, GNSS velocities {vel_off:+g} s (both tools)")
            s, w = ftnav_drive(path, None, gnss)
            on = (s["horizontal_rms_m"], s.get("prediction_horizontal_rms_m"))
            print(_row("ftnav", "gnss", None, on, w))
            p = run_pyins(None, **timing)
            on = (p["rms_after_update_m"], p["rms_before_update_m"])
            print(_row("pyins", "gnss", None, on, p["wall_s"]))
            for length, every in a.schedules:
                outage = (length, every, a.outage_start)
                for ft_aids, py_nhc, case in ((gnss, False, "gnss"), (None, True, "constraints")):
                    label = f"{length:g}/{every:g} s, {case}"
                    s, w = ftnav_drive(path, outage, ft_aids)
                    print(_row("ftnav", label, s["outages"], None, w), flush=True)
                    po = pyins_runs(length, every, a.outage_start, py_nhc, timing)
                    print(_row("pyins", label, po, None, po["wall_s"]), flush=True)
                    f, q = s["outages"]["rms_max_error_m"], po["rms_max_error_m"]
                    ours = np.array([r["max_error_m"] for r in s["outages"]["each"]])
                    theirs = np.array([r["max_error_m"] for r in po["each"]])
                    assert len(ours) == len(theirs), (len(ours), len(theirs))
                    ahead.append((off, label, f, q, paired_difference(ours, theirs)))
    print("\nftnav against pyins (RMS of the maximum drift; ftnav − pyins, 95 % interval):")
    for off, label, f, q, d in ahead:
        verdict = decide(d, 0.0, holds_below=True)
        mark = {True: "ahead", False: "BEHIND", None: "undecided"}[verdict]
        print(
            f"  IMU {off:+g} s  {label:<30} ftnav {f:6.2f} m  pyins {q:6.2f} m  "
            f"{d.value:+6.2f} [{d.lo:+.2f}, {d.hi:+.2f}] m over {d.runs} outages: {mark}"
        )


if __name__ == "__main__":
    main()
