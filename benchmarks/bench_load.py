"""``ftnav run`` on a quiet machine and beside a busy CPU-bound process (issue 13).

What is measured: the wall time of the whole command ``ftnav run seed000 --runs 100
--no-figures --quiet`` (the ``make demo`` job without its figures) as a user runs it,
once on a quiet machine and once while one extra process spins on a CPU for the whole
run (``python -c "while True: pass"``, the "one busy core" of a shared machine).  The
busy/quiet ratio must stay at most 2: ftnav's parallel work is whole tasks in worker
processes, never a thread pool entered at every epoch (which made the same command 17-28x
slower under load before issue 13: 210-362 s against 12.7 s single-threaded).

Peer in the same run: the same command with ``FTNAV_WORKERS=1`` (one process, no
parallelism at all), quiet and busy, so the machine's own speed and its share of the busy
core are measured beside ftnav's parallel default.

Every configuration is timed ``--repeat`` times; the median is reported with the range.

Usage: ``python benchmarks/bench_load.py [--runs 100] [--repeat 1] [--scenario seed000]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FTNAV = [sys.executable, "-m", "ftnav.cli"]


def timed_run(scenario: str, runs: int, out: Path, env: dict[str, str]) -> float:
    """Wall seconds of one ``ftnav run`` (fails loudly if the command fails)."""
    t0 = time.perf_counter()
    subprocess.run(
        [
            *FTNAV,
            "run",
            scenario,
            "--runs",
            str(runs),
            "--no-figures",
            "--quiet",
            "--out",
            str(out),
        ],
        check=True,
        stdout=subprocess.DEVNULL,
        env=env,
    )
    return time.perf_counter() - t0


class BusyCore:
    """One CPU-bound process spinning for as long as the context lasts."""

    def __enter__(self):
        self.proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(0.5)  # let it take its core
        return self

    def __exit__(self, *exc):
        self.proc.kill()
        self.proc.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="seed000")
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=1)
    args = ap.parse_args()
    base = dict(os.environ)
    base.pop("FTNAV_WORKERS", None)
    configs = {
        "ftnav (default workers)": base,
        "ftnav, FTNAV_WORKERS=1": base | {"FTNAV_WORKERS": "1"},
    }
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        timed_run(args.scenario, 2, out, base)  # warm the kernel cache and the OS caches
        times: dict[tuple[str, str], list[float]] = {}
        for _ in range(args.repeat):
            for label, env in configs.items():
                times.setdefault((label, "quiet"), []).append(
                    timed_run(args.scenario, args.runs, out, env)
                )
                with BusyCore():
                    times.setdefault((label, "busy"), []).append(
                        timed_run(args.scenario, args.runs, out, env)
                    )
    cpus = len(os.sched_getaffinity(0))
    print(
        f"ftnav run {args.scenario} --runs {args.runs} --no-figures on {cpus} CPUs, "
        f"{args.repeat} repeat(s), median (min-max) wall seconds"
    )
    for label in configs:
        q, b = times[(label, "quiet")], times[(label, "busy")]
        mq, mb = statistics.median(q), statistics.median(b)
        print(
            f"  {label:26s} quiet {mq:7.1f} ({min(q):.1f}-{max(q):.1f})   "
            f"one busy core {mb:7.1f} ({min(b):.1f}-{max(b):.1f})   ratio {mb / mq:.2f}"
        )


if __name__ == "__main__":
    main()
