"""A sweep with its points in one batch beside the same points one after another.

``ftnav sweep`` runs the points of a sweep over fault settings together
(:func:`ftnav.eval.montecarlo.run_points`: every point's runs and one shared fault-free
twin in one batch), and a sweep over method settings as one campaign of the union of
the points' methods (:func:`ftnav.sweep.shared_methods`: the methods the sweep does not
touch run once); before issue 23's batching each point was a campaign of its own
(:func:`ftnav.eval.montecarlo.run_scenario`, the point's runs and its own twin).  Both
are timed here in the same process, on the same grid, one worker, and their metrics
compared (they must be identical).

* ``seed000`` (paper 000's linear model, every built-in method), the fault's size at
  five values; then the χ² detector's false-alarm probability of
  ``fkf-inverse-trace-chi2`` (one of its 19 methods) at five values (an ROC sweep);
* ``seed002`` (the integrated SINS/GNSS/CNS/ADS flight) shortened to ``--seconds``, its
  first fault's size at three values (``--integrated``).

    python benchmarks/bench_sweep.py [--runs 20] [--repeat 3] [--integrated]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
import warnings
from pathlib import Path

import tomli_w

from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.common import read_toml
from ftnav.scenarios import builtin_path
from ftnav.sweep import grid, parse_set, run_sweep


def _text(metrics: dict) -> str:
    return json.dumps({k: dataclasses.asdict(v) for k, v in metrics.items()}, default=str)


def compare(path: Path, key: str, runs: int, repeat: int) -> None:
    axes = [parse_set(key)]
    points = grid(path, axes)
    run_scenario(dataclasses.replace(points[0][1], steps=5), 1, 1)  # compile, warm caches
    batched, alone = [], []
    for _ in range(repeat):
        t = time.perf_counter()
        sweep = run_sweep(points, axes, runs, 1, workers=1)
        batched.append(time.perf_counter() - t)
        t = time.perf_counter()
        each = [evaluate(run_scenario(sc, runs, 1, workers=1)) for _, sc in points]
        alone.append(time.perf_counter() - t)
    same = all(_text(a) == _text(b) for a, b in zip(sweep.metrics, each, strict=True))
    b, s = min(batched), min(alone)
    print(
        f"{points[0][1].name}, {key} ({len(points)} points) x {runs} runs: points batched "
        f"{b:.1f} s (of {', '.join(f'{w:.1f}' for w in batched)}), one after another "
        f"{s:.1f} s (of {', '.join(f'{w:.1f}' for w in alone)}): {b / s:.2f}x; "
        f"metrics identical: {same}",
        flush=True,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3, help="timings; the fastest is reported")
    ap.add_argument("--integrated", action="store_true", help="also seed002, shortened")
    ap.add_argument("--seconds", type=float, default=300.0, help="seed002's flight, s")
    a = ap.parse_args()
    warnings.simplefilter("ignore")
    compare(builtin_path("seed000"), "faults.0.magnitude=5,10,20,40,80", a.runs, a.repeat)
    roc = "methods.10.detector.false_alarm_probability=1e-4,1e-3,1e-2,5e-2,1e-1"
    compare(builtin_path("seed000"), roc, a.runs, a.repeat)
    if a.integrated:
        doc = read_toml(builtin_path("seed002"))
        doc["filter"]["duration_s"] = a.seconds
        doc["faults"] = [doc["faults"][0] | {"start": a.seconds / 3, "end": 2 * a.seconds / 3}]
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "seed002-short.toml"
            path.write_text(tomli_w.dumps(doc))
            compare(path, "faults.0.magnitude=2,5,10", max(1, a.runs // 5), 1)


if __name__ == "__main__":
    main()
