"""Where a single run's time goes, and how far it is from the arithmetic it must do (issue 24).

Two single runs, each profiled in this process (``cProfile``) after a warm-up run that
compiles the kernels:

* ``seed002``: one run of ``--seconds`` of the flight (default 300 s, 1 Hz filter epochs,
  100 Hz SINS), every method and the fault-free twin (what ``ftnav run seed002 --runs 1``
  does);
* the vendored drive with the centralized filter alone (``ckf``: GNSS positions and
  velocities, NHC, ZUPT; 12 Hz filter epochs), what ``ftnav process rtklib-drive
  --methods ckf`` runs.

Printed per run: the wall time without the profiler, the wall time per filter epoch, the
Python-level calls per epoch, and the profiled self time (a function's own time, not its
callees') by kind of code:

* **compiled kernels**: ftnav's numba functions (their time is the compiled loop's);
* **ftnav Python** by part of the package (engine, architectures, guard, detectors,
  Kalman core, navigation, sensors, evaluation, other);
* **NumPy / SciPy** called from ftnav (``np.stack``, ``nan_to_num``, ``linalg.solve``, …);
* **built-ins** (ufunc reductions, ``ndarray.any``, ``copy``, …).

Two readings of how far the run is from its arithmetic:

* the compiled kernels' share of the profiled time: were every other cost gone (a
  compiled epoch whose glue costs nothing), the run would be ``1 / share`` times faster
  with the kernels as they are;
* a dense textbook flop count of the Kalman arithmetic: every time and measurement update
  and every fusion through :mod:`ftnav.core.kalman`'s compiled kernels, counted by their
  shapes (time update ``4n³``, Joseph update ``4n³ + 6mn² + 4m²n + m³/3``, fusion of N
  estimates ``(N + 1) n³``), against the wall time.  The kernels skip the zeros of Φ and
  H, so they do less than this count; the guard's rollback pulls
  (:mod:`ftnav.fdi.separation`), the VB iterations and the mechanization are outside it.

The profiler adds its own cost per Python call, so the shares, not the profiled seconds,
are the reading.

    python benchmarks/profile_epoch.py                 # both runs, 300 s of seed002
    python benchmarks/profile_epoch.py --seconds 3600  # the whole flight
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import importlib
import pstats
import sys
import time
import warnings
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import numba
import numpy as np

import ftnav.core.kalman as kalman
from ftnav import process_recording
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path

#: parts of the package, by module prefix (the first that matches)
PARTS = (
    ("guard", "ftnav.fusion.guard"),
    ("detectors", "ftnav.fdi"),
    ("detectors", "ftnav.fusion.detection"),
    ("architectures", "ftnav.fusion"),
    ("Kalman core", "ftnav.core"),
    ("engine", "ftnav.engine"),
    ("navigation", "ftnav.nav"),
    ("sensors", "ftnav.sensors"),
    ("evaluation", "ftnav.eval"),
    ("other ftnav", "ftnav"),
)


class FlopCounter:
    """Counts the arithmetic of :mod:`ftnav.core.kalman`'s compiled kernels by shape."""

    def __init__(self) -> None:
        self.flops = 0.0
        self.calls: dict[str, int] = defaultdict(int)
        self._saved: dict[str, Any] = {}

    def _wrap(self, name: str, cost: Callable[..., float]) -> None:
        inner = getattr(kalman, name)
        self._saved[name] = inner

        def counted(*args: Any) -> Any:
            self.flops += cost(*args)
            self.calls[name] += 1
            return inner(*args)

        setattr(kalman, name, counted)

    def __enter__(self) -> FlopCounter:
        def predict(x: np.ndarray, *_: Any) -> float:
            rows, n = x.shape
            return rows * 4.0 * n**3

        def update(x: np.ndarray, P: np.ndarray, z: np.ndarray, *_: Any) -> float:
            rows, n = x.shape
            m = z.shape[-1]
            return rows * (4.0 * n**3 + 6.0 * m * n**2 + 4.0 * m**2 * n + m**3 / 3.0)

        def fuse(x: np.ndarray, *_: Any) -> float:
            rows, N, n = x.shape if x.ndim == 3 else (x.shape[0], 1, x.shape[-1])
            return rows * (N + 1.0) * n**3

        self._wrap("predict_kernel", predict)
        self._wrap("update_kernel", update)
        self._wrap("fuse_kernel", fuse)
        return self

    def __exit__(self, *_: Any) -> None:
        for name, inner in self._saved.items():
            setattr(kalman, name, inner)


def _module(filename: str) -> str | None:
    """The ftnav module of a source file, or None."""
    path = filename.replace("\\", "/")
    if "/ftnav/" not in path or "site-packages" in path:
        return None
    rel = path.split("/ftnav/", 1)[1].removesuffix(".py")
    return "ftnav." + rel.replace("/", ".").removesuffix(".__init__")


def _compiled(module: str, func: str) -> bool:
    try:
        obj = getattr(importlib.import_module(module), func, None)
    except ImportError:
        return False
    return isinstance(obj, numba.core.registry.CPUDispatcher)


def kind_of(filename: str, func: str) -> str:
    """The kind of code a profiled function is (module docstring)."""
    module = _module(filename)
    if module is not None:
        if _compiled(module, func):
            return "compiled kernels"
        return next(part for part, prefix in PARTS if module.startswith(prefix))
    if filename == "~" or filename.startswith("<"):
        return "built-ins"
    if "numpy" in filename or "scipy" in filename:
        return "NumPy / SciPy"
    return "other Python"


def profile(label: str, work: Callable[[], Any], epochs: int) -> None:
    """Time ``work`` plain, then profiled with the flops counted; print the breakdown."""
    t0 = time.perf_counter()
    work()
    wall = time.perf_counter() - t0
    prof = cProfile.Profile()
    with FlopCounter() as fc:
        prof.enable()
        work()
        prof.disable()
    stats = pstats.Stats(prof)
    raw: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    by_kind: dict[str, float] = defaultdict(float)
    calls = 0
    for (filename, _, func), (_, ncalls, self_time, _, _) in raw.items():
        by_kind[kind_of(filename, func)] += self_time
        calls += ncalls
    total = sum(by_kind.values())
    print(f"\n## {label}\n")
    print(
        f"wall {wall:.2f} s for {epochs} filter epochs: {1e3 * wall / epochs:.2f} ms per "
        f"epoch; {calls / epochs:.0f} Python-level calls per epoch (profiled: {total:.2f} s)"
    )
    print("\n| kind of code | self time (profiled) | share |\n|---|---|---|")
    for kind, seconds in sorted(by_kind.items(), key=lambda kv: -kv[1]):
        print(f"| {kind} | {seconds:.3f} s | {100 * seconds / total:.1f} % |")
    share = by_kind["compiled kernels"] / total
    print(
        f"\nCompiled kernels: {100 * share:.1f} % of the time; with every other cost gone "
        f"the run would be {1 / max(share, 1e-9):.0f} x faster (the kernels as they are)."
    )
    kernels = ", ".join(f"{n} {c}" for n, c in sorted(fc.calls.items()))
    print(
        f"Kalman arithmetic, dense textbook count: {fc.flops / 1e6:.0f} Mflop in {kernels} "
        f"calls, {fc.flops / 1e6 / wall:.0f} Mflop/s of the wall time"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=300.0, help="seed002 flight seconds")
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    sc = load_scenario(builtin_path("seed002"))
    steps = int(a.seconds / sc.dt)
    sc = dataclasses.replace(sc, steps=steps)
    run_scenario(dataclasses.replace(sc, steps=5), 1, 1)  # compile and warm the caches
    profile(
        f"seed002, one run of {a.seconds:.0f} s, {len(sc.methods)} methods + fault-free twin",
        lambda: run_scenario(sc, 1, 1, workers=1),
        steps,
    )
    first = process_recording("rtklib-drive", methods=["ckf"])  # warm
    profile(
        "rtklib-drive, ckf alone (GNSS + NHC + ZUPT)",
        lambda: process_recording("rtklib-drive", methods=["ckf"]),
        first.recording.steps,
    )


if __name__ == "__main__":
    sys.exit(main())
