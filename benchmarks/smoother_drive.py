"""The RTS smoother on the real drive: drift through GNSS outages, forward vs smoothed.

The vendored rtklibexplorer car drive (``rtklib-drive``, MEMS IMU 100 Hz + RTK GNSS),
centralized filter (``ckf``), GNSS outages of ``--outage-length`` s every
``--outage-every`` s from ``--outage-start`` s after the first GNSS epoch (as
``ftnav process --outage-length``), once with the GNSS aids only and once with the
vehicle constraints (NHC + ZUPT, every aid of the file).  The forward pass records what
the smoother needs (``run(..., smoothing=True)``) and :func:`ftnav.engine.smoother.smooth`
runs the backward pass.  Printed per case, scored at the RTK fixes (Q = 1) that the
outages withheld (:func:`ftnav.eval.recorded.score_recording`):

* the RMS over outages of the maximum horizontal drift, forward and smoothed, their
  ratio (issue 22's target: smoothed ≤ half the forward) and the per-outage range;
* the mean 2-dof NEES of the horizontal error at the withheld fixes against the
  horizontal covariance plus the fix's own R (2 for a consistent σ), forward and
  smoothed, and the RMS of the horizontal error over those fixes divided by the RMS σ;
* the wall time of the forward pass and of the smoother.

    python benchmarks/smoother_drive.py
    python benchmarks/smoother_drive.py --outage-length 30
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ftnav.engine import navigation_model
from ftnav.engine.driver import Trace, run
from ftnav.engine.smoother import SmoothedTrace, smooth, smoothed_trace
from ftnav.eval.metrics import nees
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import reference_errors, score_recording
from ftnav.io.recording_file import LoadedRecording, load_recording
from ftnav.nav.earth import radii
from ftnav.nav.mechanization import InsState
from ftnav.pipeline import reference_of
from ftnav.recordings import recording_path


def horizontal_consistency(
    loaded: LoadedRecording, sol: InsState, P_nav: np.ndarray
) -> tuple[float, float]:
    """Mean 2-dof NEES and RMS error / RMS σ of the horizontal error at the withheld fixes
    (every run's own outages), at the antenna (the lever arm applied); ``sol`` (B, K, …)
    and ``P_nav`` (B, K, 9, 9)."""
    p = sol.p
    ref = reference_of(loaded)
    rec = loaded.recording
    R_fix = loaded.recording.system().sensors[0].R[:2, :2]  # the fix's own noise (m²)
    idx = loaded.reference_index
    t = rec.times[idx]
    eps, e2, s2 = [], [], []
    for g, outages in enumerate(loaded.outages):
        w = np.zeros(idx.shape, bool)
        for a, b in outages:
            w |= (t >= a) & (t < b)
        pw = p[g, idx[w]]
        e = reference_errors(sol, ref, g)[w, :2]
        R_Mh, R_Nh = radii(pw[:, 0], pw[:, 2])
        T = np.zeros((w.sum(), 2, 2))  # (E, N) m from (δL, δλ) rad
        T[:, 0, 1] = R_Nh * np.cos(pw[:, 0])
        T[:, 1, 0] = R_Mh
        S = T @ P_nav[g, idx[w], 6:8, 6:8] @ np.swapaxes(T, 1, 2) + R_fix
        eps.append(nees(e, S))
        e2.append((e**2).sum(1))
        s2.append(np.trace(S, axis1=1, axis2=2))
    ratio = np.sqrt(np.mean(np.concatenate(e2)) / np.mean(np.concatenate(s2)))
    return float(np.mean(np.concatenate(eps))), float(ratio)


def case(
    outage: tuple[float, float, float], aids: list[str] | None
) -> tuple[LoadedRecording, Trace, SmoothedTrace, float, float]:
    loaded = load_recording(
        recording_path("rtklib-drive"), outage=outage, methods=["ckf"], aids=aids, warn=False
    )
    rec = loaded.recording
    filters = build_filters(rec, rec.system(), rec.methods)
    t0 = time.perf_counter()
    tr = run(
        navigation_model(rec),
        loaded.stream,
        filters,
        rec.steps,
        nav_covariance=True,
        smoothing=True,
    )["ckf"]
    t1 = time.perf_counter()
    s = smooth(tr)
    return loaded, tr, s, t1 - t0, time.perf_counter() - t1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outage-length", type=float, default=15.0)
    ap.add_argument("--outage-every", type=float, default=60.0)
    ap.add_argument("--outage-start", type=float, default=40.0)
    a = ap.parse_args()
    outage = (a.outage_length, a.outage_every, a.outage_start)
    print(
        f"rtklib-drive, ckf, {a.outage_length:g} s outages every {a.outage_every:g} s from "
        f"{a.outage_start:g} s"
    )
    for name, aids in (("gnss only", ["gnss", "gnss-vel"]), ("nhc + zupt", None)):
        loaded, tr, s, t_fwd, t_smooth = case(outage, aids)
        ref = reference_of(loaded)
        rec = loaded.recording
        scores = {
            "forward": score_recording(rec, {"ckf": tr}, ref, loaded.outages)["ckf"].as_dict(),
            "smoothed": score_recording(rec, {"ckf": smoothed_trace(tr, s)}, ref, loaded.outages)[
                "ckf"
            ].as_dict(),
        }
        assert tr.solution is not None and tr.P_nav is not None and s.solution is not None
        consistency = {
            "forward": horizontal_consistency(loaded, tr.solution, tr.P_nav),
            "smoothed": horizontal_consistency(loaded, s.solution, s.P_nav),
        }
        o = {k: v["outages"] for k, v in scores.items()}
        ratio = o["smoothed"]["rms_max_error_m"] / o["forward"]["rms_max_error_m"]
        print(f"{name}: {o['forward']['count']} outages")
        for k in ("forward", "smoothed"):
            each = [r["max_error_m"] for r in o[k]["each"]]
            mean_nees, err_sigma = consistency[k]
            print(
                f"  {k:<9} RMS of max drift {o[k]['rms_max_error_m']:6.2f} m "
                f"({min(each):.2f}-{max(each):.2f}); at withheld fixes: mean NEES(2) "
                f"{mean_nees:6.2f}, RMS error / RMS sigma {err_sigma:5.2f}; GNSS on "
                f"{scores[k]['horizontal_rms_m']:.3f} m RMS"
            )
        print(
            f"  smoothed / forward {ratio:.3f} (target <= 0.5: "
            f"{'met' if ratio <= 0.5 else 'NOT met'}); forward pass {t_fwd:.1f} s, "
            f"smoother {t_smooth:.2f} s"
        )


if __name__ == "__main__":
    main()
