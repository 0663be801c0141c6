"""Faults nobody specified on ``slowramp``: every method after each, beside ``ckf``.

``slowramp`` (a position fix, the only position, σ 1 m, and an odometer, σ 0.1 m/s) with
its own ramp replaced by one fault over [300, 500) s (the frozen fix to 400 s, the fast
ramp to 330 s), 20 runs from seed 1.  Printed per case and method: the RMS position
error from 20 s after the fault's end to the end of the run (issue 20: within 1.5x
``ckf``'s), and in how many runs an aid is held through the run's last 10 s.

    python benchmarks/slowramp_faults.py                  # every case, about 5 min on 2 cores
    python benchmarks/slowramp_faults.py "odometer step 1 m/s"
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from ftnav.eval.montecarlo import run_scenario
from ftnav.io.common import read_toml
from ftnav.io.scenario_file import parse_scenario
from ftnav.scenarios import builtin_path

RUNS = 20


def _fault(sensor: str, kind: str, start: float, end: float, magnitude: float) -> dict[str, Any]:
    return {"sensor": sensor, "kind": kind, "start": start, "end": end, "magnitude": [magnitude]}


CASES: dict[str, dict[str, Any] | None] = {
    "own ramp (30 m)": None,
    "odometer ramp to 1 m/s": _fault("odometer", "ramp", 300, 500, 1.0),
    "odometer step 1 m/s": _fault("odometer", "bias", 300, 500, 1.0),
    "fix step 20 m": _fault("gnss", "bias", 300, 500, 20.0),
    "fix step 200 m": _fault("gnss", "bias", 300, 500, 200.0),
    "fix noise x10": _fault("gnss", "noise-scale", 300, 500, 10.0),
    "fix frozen 100 s": _fault("gnss", "stuck", 300, 400, 0.0),
    "fix ramp 60 m in 30 s": _fault("gnss", "ramp", 300, 330, 60.0),
    "fix outage 200 s": _fault("gnss", "outage", 300, 500, 0.0),
    "fix step 20 m for 400 s": _fault("gnss", "bias", 300, 700, 20.0),
    "odometer step 1 m/s for 400 s": _fault("odometer", "bias", 300, 700, 1.0),
}


def main(names: list[str]) -> None:
    path = builtin_path("slowramp")
    for name in names:
        doc = read_toml(path)
        fault = CASES[name]
        if fault is not None:
            doc["faults"] = [fault]
        w = time.time()
        sc = parse_scenario(doc, f"slowramp, {name}", Path(path).parent)
        result = run_scenario(sc, RUNS, 1)
        end = 500.0 if fault is None else float(fault["end"])
        after = sc.times >= end + 20.0
        cells = []
        for method, res in result.results.items():
            rms = float(np.sqrt(np.mean(res.error[:, after, 0] ** 2)))
            held = ""
            if res.guard is not None:  # an aid held through the last 10 s
                stuck = res.guard.hold[:, sc.times >= sc.times[-1] - 10.0].all(1).any(-1)
                held = f", held at the end {int(stuck.sum())}"
            cells.append(f"{method} {rms:.2f}{held}")
        took = time.time() - w
        print(f"| {name} | " + " | ".join(cells) + f" |  <!-- {took:.0f} s -->", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or list(CASES))
