"""The peak-memory estimate of a run (:mod:`ftnav.eval.resources`) against a measurement.

Oracle: the peak of the memory traced by :mod:`tracemalloc` (Python objects and every
NumPy array buffer) while a fresh Python process runs the command, minus what was
traced just before (everything imported, every kernel compiled or loaded by a first run
of the same command, the flight's cache cleared).  Unlike the resident memory it does
not depend on what the allocator kept from the first run, nor on a numba cache that
another test process writes at the same time.
The estimate counts the run's arrays only, so it must lie within
``[LOW, HIGH] x`` the measured peak.  Measured on the 2-core reference machine
(estimate / measured): the linear file below 0.97 (118 / 122 MiB), with
``--save-estimates`` 1.13 (197 / 175 MiB); the integrated file below 1.13 (199 / 177
MiB), in batches of 8 runs 1.13.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ftnav.eval.resources import run_memory_bytes
from ftnav.io.scenario_file import load_scenario

LOW, HIGH = 0.7, 1.5

MEASURE = r"""
import gc, json, sys, tempfile, tracemalloc
args = json.loads(sys.argv[1])

from ftnav.cli import main
from ftnav.sim.ins import trajectory_of

def command(d, name):
    if args.get("chunk"):
        from ftnav.eval.evaluate import evaluate
        from ftnav.eval.montecarlo import run_scenario
        from ftnav.io.scenario_file import load_scenario
        evaluate(run_scenario(load_scenario(args["path"]), args["runs"], 1, chunk=args["chunk"]))
    else:
        assert main(["run", args["path"], "--runs", str(args["runs"]), "--out", d + name,
                     "--quiet", "--no-figures", *args["extra"]]) == 0

with tempfile.TemporaryDirectory() as d:
    # the same command once first: every kernel it calls is compiled or loaded in this
    # process before the measurement (compiling allocates hundreds of MiB)
    command(d, "/w")
    trajectory_of.cache_clear()
    gc.collect()
    tracemalloc.start()  # NumPy reports its array buffers to tracemalloc
    before = tracemalloc.get_traced_memory()[0]
    command(d, "/r")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
print(json.dumps({"measured": peak - before}))
"""

LINEAR = """
name = "memory"
dt = 1.0
steps = {steps}
[model]
states = ["s", "v", "a"]
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]
[[sensors]]
name = "pos1"
H = [[1.0, 0.0, 0.0]]
R = [[30.0]]
[[sensors]]
name = "pos2"
H = [[2.5, 0.0, 0.0]]
R = [[30.0]]
[[faults]]
sensor = "pos1"
kind = "bias"
start = 20.0
end = 40.0
magnitude = [60.0]
[[methods]]
name = "ckf"
architecture = "centralized"
[[methods]]
name = "fkf"
sharing = "inverse-trace"
detector = {{ kind = "residual-chi2", prior = "global" }}
[[methods]]
name = "dkf"
architecture = "distributed"
"""

INTEGRATED = """
kind = "integrated"
name = "memory-ins"
profile = "seed002"
imu = "seed001"
[filter]
duration_s = {duration}
[[aids]]
type = "gnss"
[[aids]]
type = "ads"
[[faults]]
sensor = "gnss"
kind = "noise-scale"
start = {start}
end = {end}
magnitude = [5.0]
[[methods]]
name = "ckf"
architecture = "centralized"
[[methods]]
name = "fkf"
detector = {{ kind = "residual-chi2", prior = "global" }}
isolation = "time-update"
"""


def _measure(path, runs, extra=(), chunk=None) -> int:
    args = {"path": str(path), "runs": runs, "extra": list(extra), "chunk": chunk}
    proc = subprocess.run(
        [sys.executable, "-c", MEASURE, json.dumps(args)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])["measured"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("memory")
    out = {}
    ins = INTEGRATED.format
    for name, text in (
        ("linear", LINEAR.format(steps=4000)),
        ("integrated", ins(duration=300.0, start=100.0, end=200.0)),
    ):
        out[name] = d / f"{name}.toml"
        out[name].write_text(text)
    return out


@pytest.mark.parametrize(("runs", "extra"), [(40, ()), (40, ("--save-estimates",))])
def test_linear_run_estimate_is_within_the_factor_of_the_measured_peak(files, runs, extra):
    measured = _measure(files["linear"], runs, extra)
    estimate = run_memory_bytes(load_scenario(files["linear"]), runs, save_estimates=bool(extra))
    assert measured > 50 << 20  # the run's arrays dominate the allocator's noise
    assert LOW <= estimate / measured <= HIGH, (estimate, measured)


@pytest.mark.parametrize("chunk", [None, 8])
def test_integrated_run_estimate_is_within_the_factor_of_the_measured_peak(files, chunk):
    runs = 24
    measured = _measure(files["integrated"], runs, chunk=chunk)
    estimate = run_memory_bytes(load_scenario(files["integrated"]), runs, chunk=chunk)
    assert measured > 50 << 20
    assert LOW <= estimate / measured <= HIGH, (estimate, measured)


def test_estimate_grows_with_runs_and_counts_the_twin_and_the_workers(files):
    sc = load_scenario(files["linear"])
    one, two, many = (run_memory_bytes(sc, r) for r in (1, 2, 100))
    assert 0 < one < two < many
    assert many == pytest.approx(100 * one, rel=0.05)  # the arrays are per run
    assert run_memory_bytes(sc, 10, fault_free=False) < 0.6 * run_memory_bytes(sc, 10)
    assert run_memory_bytes(sc, 10, workers=2) > run_memory_bytes(sc, 10)
    ins = load_scenario(files["integrated"])
    # batches bound the simulated IMU data, not the results every run keeps
    assert run_memory_bytes(ins, 2400, chunk=8) < run_memory_bytes(ins, 2400, chunk=2400)
    with pytest.raises(ValueError, match="^runs: must be >= 1"):
        run_memory_bytes(sc, 0)
    with pytest.raises(ValueError, match="^workers: must be >= 1"):
        run_memory_bytes(sc, 1, workers=0)


def test_max_runs_within_is_the_largest_that_fits(files):
    from ftnav.eval.resources import max_runs_within

    sc = load_scenario(files["linear"])
    budget = 1 << 30
    n = max_runs_within(sc, budget)
    assert run_memory_bytes(sc, n) <= budget < run_memory_bytes(sc, n + 1)
    assert max_runs_within(sc, 1) == 0


def test_available_memory_is_what_the_kernel_reports():
    from ftnav.eval.resources import available_memory_bytes

    meminfo = dict(line.split(":", 1) for line in open("/proc/meminfo"))
    total = int(meminfo["MemTotal"].split()[0]) * 1024
    available = available_memory_bytes()
    assert available is not None and 0 < available <= total


def test_format_bytes():
    from ftnav.eval.resources import format_bytes

    assert format_bytes(23.4 * (1 << 30)) == "23.4 GiB"
    assert format_bytes(512 << 20) == "512 MiB"
    assert format_bytes(3 << 40) == "3.0 TiB"
    assert format_bytes(100) == "100 B"
