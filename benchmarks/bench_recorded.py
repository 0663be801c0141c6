"""ftnav beside python-ins (pyins 1.0) on the same real drive and the same GNSS outages.

Both process the vendored rtklibexplorer car drive (MEMS IMU 100 Hz + RTK GNSS 4 Hz),
loosely coupled, scored against the RTK fixes (Q = 1): GNSS on, then outages of
``--outage-length`` s every ``--outage-every`` s from ``--outage-start`` s (after the first
GNSS epoch, clipped 30 s before the end), once with GNSS only and once with the vehicle
constraints (ftnav: NHC + ZUPT; pyins: NHC).  Printed per case: the RMS over outages of
the maximum horizontal drift, the per-outage range, and the wall time of each tool.

    python benchmarks/bench_recorded.py                       # 15 s and 60 s outages
    python benchmarks/bench_recorded.py --lengths 15          # one schedule

The pyins side is ``benchmarks/peer_pyins_drive.py`` (its settings in its docstring).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from peer_pyins_drive import run_pyins  # noqa: E402

from ftnav.engine import navigation_model  # noqa: E402
from ftnav.engine.driver import run  # noqa: E402
from ftnav.eval.montecarlo import build_filters  # noqa: E402
from ftnav.eval.recorded import Reference, score_recording  # noqa: E402
from ftnav.io.recording_file import load_recording  # noqa: E402
from ftnav.recordings import recording_path  # noqa: E402


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
    a = ap.parse_args()
    s, w = ftnav_drive(None, ["gnss"])
    print(_row("ftnav", "gnss", None, s["horizontal_rms_m"], w))
    p = run_pyins(None)
    print(_row("pyins", "gnss", None, p["rms_after_update_m"], p["wall_s"]))
    for length in a.lengths:
        outage = (length, a.outage_every, a.outage_start)
        for ft_aids, py_nhc, case in ((["gnss"], False, "gnss"), (None, True, "constraints")):
            s, w = ftnav_drive(outage, ft_aids)
            print(_row("ftnav", f"{length:g} s, {case}", s["outages"], None, w))
            p = run_pyins(length, a.outage_every, a.outage_start, nhc=py_nhc)
            po = {
                "count": len(p["outages"]),
                "rms_max_error_m": p["rms_max_drift_m"],
                "each": [{"max_error_m": r["max_error_m"]} for r in p["outages"]],
            }
            print(_row("pyins", f"{length:g} s, {case}", po, None, p["wall_s"]))


if __name__ == "__main__":
    main()
