"""Faults of the receiver nobody had named, on the real drive (issue 20: "faults and
cases you were not told about will be tried").

``drive_integrity.py`` faults the GNSS positions north from 100 s; ``drive_ramps.py``
moves its ramps to other start times.  This one tries other kinds on the vendored
rtklibexplorer drive (``rtklib-drive``; every aid, or the aids ``--aids`` names): faults
of the receiver's velocities (a 0.5 m/s east bias, a ramp to 1 m/s, a freeze, the noise
10 times its σ), position ramps east and up, a one-epoch 1 km outlier, a 60 s outage of
the whole receiver, a 0.01 m/s ramp for 300 s (longer than any rollback window), a step
in the first 35 s, the positions and velocities drifting together (a consistent slow
error of the receiver), an intermittent fault, a position step with noisy velocities
and the whole receiver frozen.  Printed per case and method: ``during`` and ``after``,
the horizontal RMS against the RTK fixes over the fault and from its end to the end of
the run (m); ``back``, the seconds from the end until the positions / velocities are
used again and stay so for 2 s; ``T``/``U``, whether the self-watch calls the run
trusted; and the worst fault-tolerant method's ``after`` over ``ckf``'s (issue 20's bar:
1.5).

    python benchmarks/drive_faults.py                       # about 6 min on 2 cores
    python benchmarks/drive_faults.py --aids gnss,gnss-vel  # the receiver alone
    python benchmarks/drive_faults.py --aids gnss           # the positions alone
    python benchmarks/drive_faults.py --aids gnss,nhc,zupt  # no velocities (open, §5)
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from ftnav import process_recording
from ftnav.model.scenario import Fault

METHODS = ["ckf", "fkf-chi2", "fkf-glr"]
RECEIVER = ("gnss", "gnss-vel")
_ROWS = {"e": 0, "n": 1, "u": 2, "ve": 3, "vn": 4, "vu": 5}


def _mag(**rows: float) -> np.ndarray:
    """A fault's magnitude in the receiver's rows (m E, N, U; m/s E, N, U)."""
    out = np.zeros(6)
    for k, v in rows.items():
        out[_ROWS[k]] = v
    return out


def cases(t0: float) -> dict[str, list[Fault]]:
    """The faults, ``t0`` the recording's start (times below are seconds after it)."""

    def f(aid: str, kind: str, a: float, b: float, mag: np.ndarray | None = None) -> Fault:
        return Fault(aid, kind, t0 + a, t0 + b, np.zeros(6) if mag is None else mag)  # type: ignore[arg-type]

    noise = np.full(6, 10.0)
    return {
        "velocities +0.5 m/s east, 100-160 s": [f("gnss-vel", "bias", 100, 160, _mag(ve=0.5))],
        "velocities ramp to 1 m/s north, 100-160 s": [
            f("gnss-vel", "ramp", 100, 160, _mag(vn=1.0))
        ],
        "velocities frozen, 100-130 s": [f("gnss-vel", "stuck", 100, 130)],
        "velocities noise x10, 100-160 s": [f("gnss-vel", "noise-scale", 100, 160, noise)],
        "positions ramp 3 m east, 150-210 s": [f("gnss", "ramp", 150, 210, _mag(e=3.0))],
        "positions ramp 6 m up, 150-210 s": [f("gnss", "ramp", 150, 210, _mag(u=6.0))],
        "one fix 1 km north, 200 s": [f("gnss", "bias", 200, 200.3, _mag(n=1000.0))],
        "receiver outage 60 s, 200-260 s": [f(a, "outage", 200, 260) for a in RECEIVER],
        "positions ramp 0.01 m/s, 100-400 s": [f("gnss", "ramp", 100, 400, _mag(n=3.0))],
        "positions 5 m north, 5-35 s": [f("gnss", "bias", 5, 35, _mag(n=5.0))],
        "receiver drifting 0.05 m/s north, 150-210 s": [
            f("gnss", "ramp", 150, 210, _mag(n=3.0)),
            f("gnss-vel", "bias", 150, 210, _mag(vn=0.05)),
        ],
        "positions 3 m north 1 s in 2, 150-210 s": [
            f("gnss", "bias", 150 + 2 * i, 151 + 2 * i, _mag(n=3.0)) for i in range(30)
        ],
        "positions 5 m east, velocities noise x5, 150-210 s": [
            f("gnss", "bias", 150, 210, _mag(e=5.0)),
            f("gnss-vel", "noise-scale", 150, 210, np.full(6, 5.0)),
        ],
        "receiver frozen, 150-180 s": [f(a, "stuck", 150, 180) for a in RECEIVER],
    }


def _back(t: np.ndarray, flag: np.ndarray, end: float, stay: float = 2.0) -> float:
    """Seconds from ``end`` until the aid is used again and stays so for ``stay`` s (a
    release between the fixes followed by a new hold at the next one is not back)."""
    after = t >= end
    tt, down = t[after], ~flag[after]
    for i in np.flatnonzero(down):
        if down[i : np.searchsorted(tt, tt[i] + stay)].all() and tt[-1] >= tt[i] + stay:
            return float(tt[i] - end)
    return float("inf")


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--aids", default=None, help="comma-separated aids (default every aid)")
    text = ap.parse_args().aids
    aids = None if text is None else text.split(",")
    warnings.simplefilter("ignore")
    t0 = process_recording("rtklib-drive", methods=["ckf"]).loaded.recording.t_start
    head = " | ".join(f"{m} during / after m (back s) watch" for m in METHODS)
    print(f"| fault | {head} | worst / ckf |")
    print("|---" * (len(METHODS) + 2) + "|")
    for name, faults in cases(t0).items():
        if aids is not None and any(f.sensor not in aids for f in faults):
            continue
        res = process_recording("rtklib-drive", methods=METHODS, aids=aids, faults=faults)
        rec, loaded = res.recording, res.loaded
        t, ri = rec.times, loaded.reference_index
        a = min(f.start for f in faults) - t0
        b = max(f.end for f in faults) - t0
        cells, after = [], []
        for m in METHODS:
            tr = res.traces[m]
            e = res.errors(m)  # at the antenna, as the scores
            h = np.hypot(e[:, 0], e[:, 1])
            over, past = (t[ri] >= a) & (t[ri] < b), t[ri] >= b
            during = float(np.sqrt(np.mean(h[over] ** 2)))
            after.append(float(np.sqrt(np.mean(h[past] ** 2))))
            watch = "T" if res.scores[m].integrity.trusted else "U"
            back = ""
            if tr.flag is not None:
                backs = []
                for aid in RECEIVER:
                    if aid not in rec.sensor_names:
                        continue
                    backs.append(_back(t, tr.flag[0, :, rec.sensor_names.index(aid)], b))
                back = " (" + " / ".join(f"{x:.1f}" for x in backs) + ")"
            cells.append(f"{during:.3f} / {after[-1]:.3f}{back} {watch}")
        worst = max(after[1:]) / after[0]
        print(f"| {name} | " + " | ".join(cells) + f" | {worst:.2f} |", flush=True)


if __name__ == "__main__":
    main()
