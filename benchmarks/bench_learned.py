"""Speed of the learned components (issue 4), each beside a peer in the same run.

1. Constrained LMS training (spec §5.3, 20 000 samples, N = 4): ftnav's numba kernel
   against a plain NumPy per-sample loop of the same rule (the way the update is
   usually written), per epoch, and the ratio.
2. The RBF detector inside the federated filter: seed000 (1200 epochs) batched over
   runs, ms per run with the RBF detector, with the chi-square test, and with no
   detector (each filter built with ``ftnav.fusion.registry.build`` and run by the
   engine, ``ftnav.engine.driver.run``); FilterPy's KalmanFilter on the same model
   (one plain local filter, no fusion) as the outside reference.

Run: ``python benchmarks/bench_learned.py [--runs 200] [--steps 1200]`` (part 2's
batch and seed000's epochs: fewer for a quick check of the script).  Numbers depend on
the machine; compare the printed ratios.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from ftnav.core.lms import lms_train, project_simplex
from ftnav.engine.driver import run
from ftnav.engine.linear import LinearModel
from ftnav.fusion.config import NOTHING_LEARNED, NoDetector
from ftnav.fusion.registry import build
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path
from ftnav.sim.linear import simulate


def _python_lms_epoch(U, t, w, eta, order):
    for m in order:
        u = U[m]
        w = project_simplex(w + eta * (t[m] - w @ u) * u)
    return w


def bench_lms():
    rng = np.random.default_rng(0)
    M, sig = 20000, np.array([1.0, 2.0, 4.0, 8.0])
    truth = rng.normal(0, 10, M)
    U = truth[:, None] + rng.standard_normal((M, 4)) * sig
    ubar = U.mean(1, keepdims=True)
    U, t = U - ubar, truth - ubar[:, 0]
    lms_train(U[None, :200], t[None, :200], epochs=1, rng=np.random.default_rng(1))  # compile
    t0 = time.perf_counter()
    res = lms_train(U[None], t[None], epochs=20, tol=0.0, rng=np.random.default_rng(1))
    ours = (time.perf_counter() - t0) / 20
    eta = 0.1 / (U**2).sum(1).mean()
    t0 = time.perf_counter()
    _python_lms_epoch(U, t, np.full(4, 0.25), eta, rng.permutation(M)[:2000])
    peer = (time.perf_counter() - t0) * M / 2000
    print(
        f"LMS, 20 000 samples, N = 4: ftnav {1e3 * ours:.2f} ms/epoch, NumPy loop "
        f"{1e3 * peer:.0f} ms/epoch, ratio {peer / ours:.0f}x; weights "
        f"{np.round(res.weights[0], 3)}"
    )


def bench_detectors(runs: int = 200, steps: int | None = None):
    sc = load_scenario(builtin_path("seed000"))
    if steps is not None:
        sc = dataclasses.replace(sc, steps=steps)
    system = sc.system()
    model = LinearModel(system)
    sim = simulate(sc, runs, 1)
    warm = simulate(sc, 2, 9)
    by = {m.name: m for m in sc.methods}
    cases = {
        "rbf": by["fkf-inverse-trace-rbf"],
        "chi2": by["fkf-inverse-trace-chi2"],
        "none": by["fkf-inverse-trace-chi2"].model_copy(update={"detector": NoDetector()}),
    }
    out = {}
    for name, m in cases.items():
        filt = build(system, m, sc.learned_for(m.name) or NOTHING_LEARNED)
        run(model, warm.stream, {name: filt}, sc.steps)  # warm up
        t0 = time.perf_counter()
        run(model, sim.stream, {name: filt}, sc.steps)
        out[name] = (time.perf_counter() - t0) / runs
    from filterpy.kalman import KalmanFilter

    s = sc.sensors[0]
    z = sim.stream.z[0][0, :, 0]
    t0 = time.perf_counter()
    kf = KalmanFilter(dim_x=3, dim_z=1)
    kf.F, kf.Q, kf.H, kf.R = sc.model.F, sc.model.Q, s.H, s.R
    kf.P = sc.model.P0.copy()
    for zk in z:
        kf.predict()
        kf.update(zk)
    peer = time.perf_counter() - t0
    print(
        f"seed000 federated inverse-trace ({sc.steps} epochs), {runs} runs batched, per run: "
        + ", ".join(f"{k} {1e3 * v:.2f} ms" for k, v in out.items())
        + f"; RBF overhead over chi2 {out['rbf'] / out['chi2']:.2f}x"
    )
    print(
        f"FilterPy, one local filter (1 sensor, {sc.steps} epochs): {1e3 * peer:.1f} ms/run; "
        f"ftnav's whole federated filter with the RBF detector is {peer / out['rbf']:.0f}x "
        "faster per run"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200, help="runs batched in part 2")
    ap.add_argument("--steps", type=int, default=None, help="epochs of seed000 (default: 1200)")
    args = ap.parse_args()
    bench_lms()
    bench_detectors(args.runs, args.steps)


if __name__ == "__main__":
    main()
