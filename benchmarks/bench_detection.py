"""The detection picture (issue 20): delay and false alarms against ramp rate and step size.

For the residual χ² test, the CUSUM and the windowed GLR (spec §3.1, §3.3), each with
the guard (the built-in defaults), and the RBF network where a trained model exists:

1. ``seed002`` (SINS/GNSS/CNS/ADS, simulated): a north GNSS position ramp of each rate
   from ``--start`` s for ``--length`` s, and a step of each size for the same time,
   ``--runs`` runs batched; the fault-free twin gives the false alarms.
2. ``seed000`` (paper 000's linear model, with its trained RBF model): the same on
   sensor ``pos1``.
3. The real drive (rtklibexplorer, MEMS IMU + RTK fixes; ``--drive-span`` s of it):
   the same faults injected into the recorded GNSS positions; the fault-free drive
   gives the false alarms (one run: the recording).  χ² and GLR: the CUSUM is refused
   on recordings (it alarmed 415 times an hour here, ~100 times its setting).

A detection probability counts any alarm inside the fault window: where it equals the
chance of a false alarm in a window that long (the false-alarm row), it is not a detection.

Per detector and fault: the detection probability (runs with an alarm inside the fault
window, the ramp included), the median delay from the fault's start to the first raw
alarm, and, fault-free, the alarms per hour and the fraction of tests flagged.  Printed as
tables; with ``--figure PATH`` the delays against ramp rate and step size as a figure.

Run: ``python benchmarks/bench_detection.py`` (a few minutes); ``--quick`` for a check
of the script (small sizes, the numbers meaningless).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# the recorded-log helpers of the tests: a drive copy by absolute paths, its traces
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "reference"))
from recording_runs import drive_copy, traces_of  # noqa: E402

from ftnav.eval.montecarlo import run_scenario
from ftnav.fusion import registry
from ftnav.io.recording_file import load_recording
from ftnav.io.scenario_file import load_scenario
from ftnav.model.scenario import Fault
from ftnav.scenarios import builtin_path

FED = {"mode": "fusion-reset", "sharing": "equal"}


def _glr(prior: str = "global") -> dict:
    return {"kind": "glr", "prior": prior, "arl0": 1e4, "window": 64}


def _alarms(flag: np.ndarray, times: np.ndarray, start: float, end: float):
    """(detected (B,), delay (B,) s, inf where missed) of raw alarms (B, K)."""
    inside = (times >= start) & (times < end)
    hit = flag[:, inside]
    found = hit.any(1)
    first = np.where(found, times[inside][np.argmax(hit, 1)] - start, np.inf)
    return found, first


def _false_alarms(raw: np.ndarray, dt: float) -> tuple[float, float]:
    """(alarms per hour, fraction of tests) of fault-free raw alarms (B, K)."""
    rises = (raw[:, 1:] & ~raw[:, :-1]).sum() + raw[:, 0].sum()
    hours = raw.shape[0] * raw.shape[1] * dt / 3600.0
    return float(rises / hours), float(raw.mean())


def _row(name: str, fault: str, found: np.ndarray, delay: np.ndarray) -> dict:
    d = delay[np.isfinite(delay)]
    return {
        "detector": name,
        "fault": fault,
        "pd": float(found.mean()),
        "delay_s": float(np.median(d)) if d.size else np.inf,
    }


def _faults(rates, steps, start, length, sensor, dims, axis):
    out = []
    for r in rates:
        m = np.zeros(dims)
        m[axis] = r * length
        out.append((f"ramp {r:g} m/s", Fault(sensor, "ramp", start, start + length, m)))
    for s in steps:
        m = np.zeros(dims)
        m[axis] = s
        out.append((f"step {s:g} m", Fault(sensor, "bias", start, start + length, m)))
    return out


# ------------------------------------------------------------------------ simulated
def simulated(name, sensor, methods, faults, runs, steps, seed=1):
    sc = load_scenario(builtin_path(name))
    sc = dataclasses.replace(sc, steps=steps, faults=(), methods=tuple(methods))
    a = sc.sensor_names.index(sensor)
    times = sc.times
    rows, fa = [], {}
    res = run_scenario(sc, runs, seed=seed, fault_free=False, workers=1)
    for m in methods:
        fa[m.name] = _false_alarms(res.results[m.name].raw_flag[..., a], sc.dt)
    for label, f in faults:
        r = run_scenario(
            dataclasses.replace(sc, faults=(f,)), runs, seed=seed, fault_free=False, workers=1
        )
        for m in methods:
            found, delay = _alarms(r.results[m.name].raw_flag[..., a], times, f.start, f.end)
            rows.append(_row(m.name, label, found, delay))
    return rows, fa


def seed002_methods():
    sc = load_scenario(builtin_path("seed002"))
    by = {m.name: m for m in sc.methods}
    glr = registry.method_config("federated", name="fkf-glr", detector=_glr(), **FED)
    return [by["fkf-chi2"], by["fkf-cusum"], glr]


def seed000_methods():
    sc = load_scenario(builtin_path("seed000"))
    by = {m.name: m for m in sc.methods}
    glr = registry.method_config(
        "federated", name="fkf-inverse-trace-glr", sharing="inverse-trace", detector=_glr()
    )
    names = ("fkf-inverse-trace-chi2", "fkf-inverse-trace-cusum", "fkf-inverse-trace-rbf")
    return [by[names[0]], by[names[1]], glr, by[names[2]]]


# --------------------------------------------------------------------------- drive
def _drive(folder: Path, span: float) -> Path:
    """The built-in drive cut to ``span`` s with its χ² and GLR methods."""

    def edit(doc):
        doc["filter"]["duration_s"] = span
        # the CUSUM is refused on recordings (docs/integrity.md: ~100 times its arl0 there)
        doc["methods"] = [m for m in doc["methods"] if m["name"] in ("fkf-chi2", "fkf-glr")]

    return drive_copy(folder / "drive.toml", edit)


def drive(span, rates, steps, start, length):
    with tempfile.TemporaryDirectory() as d:
        path = _drive(Path(d), span)
        rows, fa = [], {}

        def once(faults):
            loaded = load_recording(path, faults=faults, warn=False)
            return loaded.recording, traces_of(loaded)

        rec, traces = once([])
        a = rec.sensor_names.index("gnss")
        for name, tr in traces.items():
            fa[name] = _false_alarms(tr.raw_flag[..., a], rec.dt)
        t0 = rec.t_start
        for label, f in _faults(rates, steps, start, length, "gnss", 6, 1):
            shifted = dataclasses.replace(f, start=t0 + f.start, end=t0 + f.end)
            rec, traces = once([shifted])
            for name, tr in traces.items():
                found, delay = _alarms(tr.raw_flag[..., a], rec.times, f.start, f.end)
                rows.append(_row(name, label, found, delay))
    return rows, fa


# --------------------------------------------------------------------------- output
def table(title, rows, fa):
    print(f"\n{title}", flush=True)
    names = list(dict.fromkeys(r["detector"] for r in rows)) or list(fa)
    faults = list(dict.fromkeys(r["fault"] for r in rows))
    w = max(len(n) for n in names) + 2
    print("fault".ljust(16) + "".join(n.rjust(w + 6) for n in names))
    for f in faults:
        line = f.ljust(16)
        for n in names:
            (r,) = [r for r in rows if r["detector"] == n and r["fault"] == f]
            cell = f"{r['pd']:.2f} / " + (
                "-" if not np.isfinite(r["delay_s"]) else f"{r['delay_s']:.1f} s"
            )
            line += cell.rjust(w + 6)
        print(line)
    line = "false alarms/h".ljust(16)
    for n in names:
        per_h, frac = fa[n]
        line += f"{per_h:.1f} ({100 * frac:.2f}%)".rjust(w + 6)
    print(line)
    print("(cells: detection probability / median delay from the fault's start)")


def figure(path, panels):
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(panels), figsize=(4.2 * len(panels), 6.5), squeeze=False)
    for j, (title, rows) in enumerate(panels):
        for i, kind in enumerate(("ramp", "step")):
            ax = axes[i, j]
            for n in dict.fromkeys(r["detector"] for r in rows):
                pts = [r for r in rows if r["detector"] == n and r["fault"].startswith(kind)]
                x = [float(r["fault"].split()[1]) for r in pts]
                y = [r["delay_s"] if np.isfinite(r["delay_s"]) else np.nan for r in pts]
                ax.plot(x, y, "o-", label=n)
            ax.set_xscale("log")
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_xlabel("ramp rate, m/s" if kind == "ramp" else "step, m")
            ax.set_ylabel("median delay, s (missed: no point)")
            ax.set_title(f"{title}: {kind}s", fontsize=9)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--steps", type=int, default=900, help="seed002 and seed000 epochs")
    ap.add_argument("--start", type=float, default=300.0, help="fault start (simulated), s")
    ap.add_argument("--length", type=float, default=200.0, help="fault length, s")
    ap.add_argument("--drive-span", type=float, default=260.0)
    ap.add_argument("--no-drive", action="store_true")
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a check of the script")
    ap.add_argument("--figure", type=Path, default=None)
    a = ap.parse_args()
    rates, steps = [0.01, 0.02, 0.05, 0.1, 0.2, 0.5], [2.0, 5.0, 10.0, 20.0]
    drive_rates, drive_steps = [0.02, 0.05, 0.1, 0.2, 0.5], [0.5, 1.0, 2.0, 5.0]
    if a.quick:
        a.runs, a.steps, a.start, a.length, a.drive_span = 2, 40, 10.0, 20.0, 40.0
        rates, steps, drive_rates, drive_steps = [0.5], [10.0], [0.5], [5.0]
    panels = []
    for name, sensor, methods, dims, axis, what in (
        ("seed002", "gnss", seed002_methods(), 6, 1, "GNSS north position"),
        ("seed000", "pos1", seed000_methods(), 1, 0, "pos1"),
    ):
        t = time.perf_counter()
        faults = _faults(rates, steps, a.start, a.length, sensor, dims, axis)
        rows, fa = simulated(name, sensor, methods, faults, a.runs, a.steps)
        took = time.perf_counter() - t
        table(f"{name}, {what}, {a.runs} runs ({took:.0f} s)", rows, fa)
        panels.append((name, rows))
    if not a.no_drive:
        t = time.perf_counter()
        start, length = (100.0, 60.0) if not a.quick else (10.0, 20.0)
        rows, fa = drive(a.drive_span, drive_rates, drive_steps, start, length)
        table(
            f"rtklib-drive, first {a.drive_span:g} s, GNSS north position from {start:g} s "
            f"for {length:g} s ({time.perf_counter() - t:.0f} s)",
            rows,
            fa,
        )
        panels.append(("drive", rows))
    if a.figure is not None:
        figure(a.figure, panels)


if __name__ == "__main__":
    main()
