"""The benchmark scripts still run on the current API (benchmarks/*.py).

Oracle: each script, run as a user runs it (``python benchmarks/<name>.py``) with small
sizes, exits with status 0 and prints its comparison lines: ftnav beside its peer in the
same run.  The numbers are not checked (they depend on the machine); an API change that
breaks a script fails here instead of at the next ``make bench``.

Not covered: ``bench_load.py``, which has no quick mode (it times ``ftnav run seed000``
five times).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NUMBER = r"[0-9.e+-]+"


def run_benchmark(name: str, *args: str) -> str:
    """Stdout of ``python benchmarks/<name>.py args``; fails on a non-zero exit status."""
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / f"{name}.py"), *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, f"{name} exited {proc.returncode}:\n{proc.stderr[-4000:]}"
    return proc.stdout


def assert_lines(out: str, patterns: list[str]) -> None:
    """Every pattern matches one printed line, in this order."""
    lines = out.splitlines()
    at = 0
    for pat in patterns:
        for i in range(at, len(lines)):
            if re.search(pat, lines[i]):
                at = i + 1
                break
        else:
            pytest.fail(f"no line after line {at} matches {pat!r}; printed:\n{out}")


def test_bench_federated():
    out = run_benchmark(
        "bench_federated",
        *("--runs", "2", "--peer-runs", "2", "--workers", "2"),
        *("--scenario-runs", "2", "--steps", "60"),
    )
    assert_lines(
        out,
        [
            r"^seed000 model, 60 epochs, fusion-reset every epoch, inverse-trace sharing$",
            rf"^ftnav    : 2 runs batched, best of 3: {NUMBER} ms per run",
            rf"^FilterPy : 2 runs one by one in {NUMBER} s -> {NUMBER} ms per run$",
            rf"^ratio    : ftnav is {NUMBER}x faster per run$",
            r"^agreement: max relative difference of fused estimates",
            r"^target   : <= 3 ms per run per 1200 steps -> (met|NOT met) as measured",
            rf"^run_scenario\(seed000, runs=2, workers=1\): \d+ methods .* in {NUMBER} s",
            rf"^run_scenario\(seed000, runs=2, workers=2\): \d+ methods .* in {NUMBER} s",
        ],
    )
    # ftnav and FilterPy implement the same equations: their fused estimates agree
    diff = float(re.search(r"fused estimates (\S+)", out).group(1))
    assert diff < 1e-9


def test_bench_integrated():
    out = run_benchmark("bench_integrated", "--seconds", "10", "--runs", "1", "2", "--repeat", "1")
    assert_lines(
        out,
        [
            rf"^FilterPy, one 18-state filter, 3600 epochs: {NUMBER} s",
            r"^ftnav seed002 \(1 worker\(s\)\), \d+ methods \+ fault-free twin, 1 run\(s\) x 10 s: "
            rf"{NUMBER} s .* -> {NUMBER} s per run per 3600 s \(ratio to the FilterPy single "
            rf"filter: {NUMBER}x\)$",
            r"^ftnav seed002 \(1 worker\(s\)\), \d+ methods \+ fault-free twin, 2 run\(s\) x 10 s",
        ],
    )


def test_bench_learned():
    out = run_benchmark("bench_learned", "--runs", "2", "--steps", "60")
    assert_lines(
        out,
        [
            rf"^LMS, 20 000 samples, N = 4: ftnav {NUMBER} ms/epoch, NumPy loop {NUMBER} "
            rf"ms/epoch, ratio {NUMBER}x",
            r"^seed000 federated inverse-trace \(60 epochs\), 2 runs batched, per run: "
            rf"rbf {NUMBER} ms, chi2 {NUMBER} ms, none {NUMBER} ms; RBF overhead over chi2 "
            rf"{NUMBER}x$",
            rf"^FilterPy, one local filter \(1 sensor, 60 epochs\): {NUMBER} ms/run; ftnav's "
            r"whole federated filter with the RBF detector is",
        ],
    )


#: a 60 s flight: bench_mechanization's --profile takes a profile file
SHORT_PROFILE = """
name = "short"
imu_rate_hz = 100.0

[start]
lat_deg = 32.0
lon_deg = 118.0
h_m = 5.0
speed_m_s = 0.0
heading_deg = 0.0

[[segments]]
label = "stationary"
duration_s = 10.0

[[segments]]
label = "accelerate"
duration_s = 50.0
accel_m_s2 = 1.0
"""


def test_bench_mechanization(tmp_path):
    # its quick mode: a few runs (--runs) of a short flight (--profile FILE)
    profile = tmp_path / "short.toml"
    profile.write_text(SHORT_PROFILE)
    out = run_benchmark("bench_mechanization", "--runs", "2", "--profile", str(profile))
    assert_lines(
        out,
        [
            r"^profile .*short\.toml: 60 s at 100 Hz \(6000 samples\)",
            rf"^ftnav one run : {NUMBER} s \(best of 3\); horizontal error at the end {NUMBER} m$",
            rf"^pyins one run : {NUMBER} s; horizontal error at the end {NUMBER} m$",
            rf"^ratio         : ftnav is {NUMBER}x faster for one run$",
            rf"^ftnav 2 runs: {NUMBER} s batched -> {NUMBER} s per run",
            r"^targets       : one run <= 1 s -> (met|NOT met); <= 0.3 s per run batched",
        ],
    )


def test_bench_detection():
    out = run_benchmark("bench_detection", "--quick", "--no-drive")
    assert_lines(
        out,
        [
            r"^seed002, GNSS north position, 2 runs",
            r"^fault +fkf-chi2 +fkf-cusum +fkf-glr$",
            r"^ramp 0\.5 m/s ",
            r"^false alarms/h ",
            r"^seed000, pos1, 2 runs",
            r"fkf-inverse-trace-rbf$",
        ],
    )
