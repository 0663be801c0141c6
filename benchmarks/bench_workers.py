"""``ftnav run`` with one worker process against two, same runs and seed (issue 23).

What is measured: the wall time of ``ftnav run seed002 --runs 64 --no-figures --quiet``
with ``--workers 1`` and ``--workers 2`` on the 2-core machine (the target: two workers
take at most 0.6x the one-worker time), and whether the two ``metrics.json`` are
identical, every number (the results must not depend on the worker count).

Usage: ``python benchmarks/bench_workers.py [--scenario seed002] [--runs 64]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FTNAV = [sys.executable, "-m", "ftnav.cli"]


def timed(scenario: str, runs: int, workers: int, out: Path) -> tuple[float, dict]:
    """Wall seconds of one ``ftnav run`` and its metrics (fails loudly if it fails)."""
    t0 = time.perf_counter()
    subprocess.run(
        [
            *FTNAV,
            "run",
            scenario,
            "--runs",
            str(runs),
            "--workers",
            str(workers),
            "--out",
            str(out),
            "--no-figures",
            "--quiet",
        ],
        check=True,
        stdout=subprocess.DEVNULL,
        env={**os.environ, "PYTHONHASHSEED": "0"},
    )
    wall = time.perf_counter() - t0
    return wall, json.loads((out / "metrics.json").read_text())["methods"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="seed002")
    ap.add_argument("--runs", type=int, default=64)
    args = ap.parse_args()
    print(f"CPUs available: {len(os.sched_getaffinity(0))}")
    with tempfile.TemporaryDirectory() as tmp:
        one, m1 = timed(args.scenario, args.runs, 1, Path(tmp) / "w1")
        two, m2 = timed(args.scenario, args.runs, 2, Path(tmp) / "w2")
    print(f"ftnav run {args.scenario} --runs {args.runs}")
    print(f"  --workers 1: {one:7.1f} s")
    print(f"  --workers 2: {two:7.1f} s  ({two / one:.2f}x; target <= 0.60x)")
    print(f"  metrics identical: {'yes' if m1 == m2 else 'NO'}")


if __name__ == "__main__":
    main()
