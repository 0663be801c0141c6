"""Speed of the closed-loop integrated-navigation runner (seed002) beside FilterPy.

What is measured:

* ftnav: ``ftnav.eval.montecarlo.run_scenario(seed002)`` with its three methods (centralized,
  federated with chi-square isolation, distributed with VB), closed loop (100 Hz
  SINS, GNSS/CNS/ADS at 1 Hz), the fault-free twin included, for one run and for a
  batch of runs.  A shortened flight (``--seconds``) is timed and the cost is scaled
  to 3600 s (the per-epoch cost is flat along the flight); the whole flight is timed
  with ``--seconds 3600``.
* FilterPy peer: what a user writes with FilterPy today for the *filter part only*
  of one run: one 18-state ``KalmanFilter`` (the centralized filter), its F and Q
  given, GNSS/CNS/ADS updates every second; cost per 3600 epochs.  ftnav does
  three filters plus the SINS, the linearization and the aids in its time.

Targets (issue 5): one seed002 run (all methods) <= 10 s; 100 runs at <= 2 s per run.

Every batch size is timed ``--repeat`` times (runs x seconds up to 36000) and the
fastest is reported.  Runs go in batches bounded by the IMU-data memory
(:func:`ftnav.eval.montecarlo.chunk_runs`: 62 runs of a 3600 s flight).

Usage: ``python benchmarks/bench_integrated.py [--seconds 600] [--runs 1 20] [--repeat 3]
[--workers 2]``;
the full targets: ``--seconds 3600 --runs 1 100``.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from filterpy.kalman import KalmanFilter

from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path


def filterpy_peer(epochs: int) -> float:
    """Seconds for one FilterPy 18-state filter over ``epochs`` GNSS/CNS/ADS epochs."""
    rng = np.random.default_rng(0)
    kf = KalmanFilter(dim_x=18, dim_z=10)
    F = np.eye(18) + 1e-3 * rng.standard_normal((18, 18))
    Q = np.eye(18) * 1e-6
    H = np.zeros((10, 18))
    H[:9, :9] = np.eye(9)
    H[9, 8] = 1.0
    kf.F, kf.Q, kf.H, kf.R, kf.P = F, Q, H, np.eye(10), np.eye(18)
    z = rng.standard_normal((epochs, 10))
    t0 = time.perf_counter()
    for k in range(epochs):
        kf.predict()
        kf.update(z[k])
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--runs", type=int, nargs="+", default=[1, 20])
    ap.add_argument(
        "--workers", type=int, default=1, help="worker processes (ftnav.parallel); 1 = this process"
    )
    ap.add_argument(
        "--repeat",
        type=int,
        default=3,
        help="timings per batch size; the fastest is reported (the others are "
        "printed: a shared machine's load only ever adds time)",
    )
    a = ap.parse_args()
    sc = load_scenario(builtin_path("seed002"))
    steps = int(a.seconds / sc.dt)
    sc = dataclasses.replace(sc, steps=steps)
    scale = 3600.0 / a.seconds
    run_scenario(dataclasses.replace(sc, steps=5), 1, 1)  # compile and warm the caches
    peer = min(filterpy_peer(3600) for _ in range(a.repeat))
    print(f"FilterPy, one 18-state filter, 3600 epochs: {peer:.2f} s (filter part only)")
    for runs in a.runs:
        walls = []
        for _ in range(a.repeat if runs * a.seconds <= 36000 else 1):
            t0 = time.perf_counter()
            run_scenario(sc, runs, 1, workers=a.workers)
            walls.append(time.perf_counter() - t0)
        wall = min(walls)
        per_run = wall * scale / runs
        print(
            f"ftnav seed002 ({a.workers} worker(s)), {len(sc.methods)} methods + fault-free "
            f"twin, {runs} run(s) x "
            f"{a.seconds:.0f} s: {wall:.1f} s (of {', '.join(f'{w:.1f}' for w in walls)}) -> "
            f"{per_run:.2f} s per run per 3600 s (ratio to the FilterPy single filter: "
            f"{per_run / peer:.1f}x)"
        )


if __name__ == "__main__":
    main()
