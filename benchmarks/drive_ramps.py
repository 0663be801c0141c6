"""Slow GNSS ramps on the real drive at every start time, not only the one of
``drive_integrity.py`` (issue 20: "faults and cases you were not told about").

The vendored rtklibexplorer drive (``rtklib-drive``; every aid: GNSS positions and
velocities, NHC, ZUPT; or the aids ``--aids`` names), a north ramp of the GNSS
positions of 0.05 m/s for 60 s and of 0.2 m/s for 35 s, starting 60, 150, 184, 250,
300, 350 and 420 s after the recording's start (where the run is long enough).
Printed per case and method: ``after``, the horizontal RMS against the RTK fixes from
the ramp's end to the end of the run (m); ``back``, the seconds from the end until the
GNSS positions are used again; the aids the method's detector flagged during the ramp
besides the GNSS positions; and the worst fault-tolerant method's ``after`` over
``ckf``'s (issue 20's bar: 1.5).

    python benchmarks/drive_ramps.py                       # about 5 min on 2 cores
    python benchmarks/drive_ramps.py --aids gnss,gnss-vel  # the receiver alone
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from ftnav import process_recording

METHODS = ["ckf", "fkf-chi2", "fkf-glr"]
STARTS = (60.0, 150.0, 184.0, 250.0, 300.0, 350.0, 420.0)
RAMPS = ((0.05, 60.0), (0.2, 35.0))  # (m/s, s)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aids", default=None, help="comma-separated aids (default every aid)")
    aids = ap.parse_args().aids
    warnings.simplefilter("ignore")
    t0 = process_recording("rtklib-drive", methods=["ckf"]).loaded.recording.t_start
    print("| ramp | start s | " + " | ".join(f"{m} after m / back s" for m in METHODS), end="")
    print(" | worst / ckf |")
    print("|---" * (len(METHODS) + 3) + "|")
    for rate, length in RAMPS:
        for a in STARTS:
            b = a + length
            res = process_recording(
                "rtklib-drive",
                methods=METHODS,
                aids=None if aids is None else aids.split(","),
                faults=[f"gnss:ramp:{t0 + a}:{t0 + b}:{rate * length}"],
            )
            rec, loaded = res.recording, res.loaded
            if b + 20.0 > rec.times[-1]:
                continue
            t, ri = rec.times, loaded.reference_index
            g = rec.sensor_names.index("gnss")
            cells, after = [], []
            for m in METHODS:
                tr = res.traces[m]
                e = res.errors(m)  # at the antenna, as the scores
                h = np.hypot(e[:, 0], e[:, 1])[t[ri] >= b]
                after.append(float(np.sqrt(np.mean(h**2))))
                if tr.flag is None:
                    cells.append(f"{after[-1]:.3f}")
                    continue
                flag = tr.flag[0]
                down = ~flag[t >= b, g]
                back = t[t >= b][np.argmax(down)] - b if down.any() else np.inf
                during = (t >= a) & (t < b)
                others = [
                    n for i, n in enumerate(rec.sensor_names) if i != g and flag[during, i].any()
                ]
                also = f" (flagged {', '.join(others)})" if others else ""
                cells.append(f"{after[-1]:.3f} / {back:.1f}{also}")
            worst = max(after[1:]) / after[0]
            print(f"| {rate} m/s, {length:.0f} s | {a:.0f} | " + " | ".join(cells), end="")
            print(f" | {worst:.2f} |", flush=True)


if __name__ == "__main__":
    main()
