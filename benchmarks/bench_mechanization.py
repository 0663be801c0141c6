"""Speed of the strapdown mechanization beside python-ins (pyins), in one run.

What is measured (``seed002`` profile: 3600 s at 100 Hz, 360 000 IMU samples):

* one run: ftnav's batched kernel with B = 1 (two-sample algorithm), and pyins'
  ``Integrator`` on the same increments (its own coning/sculling via
  ``compute_increments_from_imu``; the DataFrame construction is included, as a
  user of pyins pays it);
* 100 runs batched: each run gets its own white gyro/accelerometer noise (added per
  60 s chunk, not timed), the mechanization is timed, solution kept at 1 Hz.

Targets (issue 3): one run ≤ 1 s; 100 runs ≤ 0.3 s per run.  Both implementations
are also checked to end near the truth (horizontal metres).

Usage: ``python benchmarks/bench_mechanization.py [--runs 100]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ftnav.io.profile_file import resolve_profile
from ftnav.nav import earth
from ftnav.nav import mechanization as mech
from ftnav.sim.trajectory import generate

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "reference"))
from pyins_peer import pyins_integrate  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--profile", default="seed002")
    args = ap.parse_args()

    t0 = time.perf_counter()
    tr = generate(resolve_profile(args.profile))
    t_gen = time.perf_counter() - t0
    K = tr.dtheta.shape[0]
    st0 = mech.init_state(tr.p[0], tr.v[0], tr.euler[0])
    mech.integrate(st0, tr.dtheta[:200], tr.dv[:200], tr.dt)  # compile / load the cache
    mech.integrate(
        mech.init_state(tr.p[0], tr.v[0], tr.euler[0], batch=2), tr.dtheta[:200], tr.dv[:200], tr.dt
    )

    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _, sol = mech.integrate(st0, tr.dtheta, tr.dv, tr.dt)
        best = min(best, time.perf_counter() - t0)
    e_ft = earth.enu_metres(sol.p[0, -1], tr.p[-1])

    t0 = time.perf_counter()
    p_peer = pyins_integrate(tr.t, tr.p[0], tr.v[0], tr.euler[0], tr.dtheta, tr.dv)
    t_peer = time.perf_counter() - t0
    e_peer = earth.enu_metres(p_peer[-1], tr.p[-1])

    # 100 runs batched, in 60 s chunks, each run with its own white noise
    B, chunk = args.runs, 6000
    rng = np.random.default_rng(1)
    st = mech.init_state(tr.p[0], tr.v[0], tr.euler[0], batch=B)
    t_batch = 0.0
    arw, vrw = np.radians(0.01) / 60 * np.sqrt(tr.dt), 1e-4 * np.sqrt(tr.dt)
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        n = k1 - k0
        dth = tr.dtheta[k0:k1] + arw * rng.standard_normal((B, n, 3))
        dv = tr.dv[k0:k1] + vrw * rng.standard_normal((B, n, 3))
        t0 = time.perf_counter()
        st, _ = mech.integrate(st, dth, dv, tr.dt, output_every=50)
        t_batch += time.perf_counter() - t0
    spread = np.hypot(*earth.enu_metres(st.p, tr.p[-1])[:, :2].T)

    print(
        f"profile {args.profile}: {K * tr.dt:.0f} s at {1 / tr.dt:.0f} Hz ({K} samples); "
        f"generated in {t_gen:.2f} s"
    )
    print(
        f"ftnav one run : {best:.3f} s (best of 3); horizontal error at the end "
        f"{np.hypot(*e_ft[:2]):.3f} m"
    )
    print(
        f"pyins one run : {t_peer:.3f} s; horizontal error at the end {np.hypot(*e_peer[:2]):.3f} m"
    )
    print(f"ratio         : ftnav is {t_peer / best:.0f}x faster for one run")
    print(
        f"ftnav {B} runs: {t_batch:.2f} s batched -> {t_batch / B:.3f} s per run "
        f"(median horizontal drift with white IMU noise {np.median(spread):.1f} m)"
    )
    print(
        f"targets       : one run <= 1 s -> {'met' if best <= 1 else 'NOT met'}; "
        f"<= 0.3 s per run batched -> {'met' if t_batch / B <= 0.3 else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
