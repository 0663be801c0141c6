"""Isolation that cannot lock out (ftnav.fusion.guard), on the built-in ``slowramp``.

``slowramp``: a GNSS-like fix, the only absolute position (σ 1 m), and an odometer
(σ 0.1 m/s); the fix drifts by 30 m over [300, 500) s, then comes back at once.  The
filter follows the ramp before a single-epoch test sees it; when the ramp ends the
healthy fixes look like a jump of what it absorbed, and the coasting covariance grows
too slowly to cover it.  Oracles, 60 runs:

* the plain filter's error after the fault (the issue's rule: never worse than it once
  a fault ended) and its fault-free twin (no fault-tolerant method more than 10 % worse);
* the same χ² method without the guard, which locks the fix out in about half the runs
  (what the guard is for);
* re-admission (the flag clears after the fault) in every run: the issue asks ≥ 99 %.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.common import read_toml
from ftnav.io.scenario_file import load_scenario, parse_scenario
from ftnav.scenarios import builtin_path

RUNS = 60
GUARDED = ("ckf-chi2", "fkf-chi2", "dkf-chi2", "ckf-cusum", "ckf-glr", "ckf-separation")
#: independent locals keep no pulls: no rollback, no patience
NO_RESET = "fkf-nr-chi2"
END = 500.0  # the ramp's end


@pytest.fixture(scope="module")
def slowramp():
    sc = load_scenario(builtin_path("slowramp"))
    keep = ("ckf", "ckf-chi2-unguarded", *GUARDED, NO_RESET)
    sc = dataclasses.replace(sc, methods=tuple(m for m in sc.methods if m.name in keep))
    result = run_scenario(sc, RUNS, 1)
    return sc, result, evaluate(result)


def _after(sc, res) -> float:
    """RMS position error after the fault ended (plus 20 s)."""
    after = sc.times >= END + 20.0
    return float(np.sqrt(np.mean(res.error[:, after, 0] ** 2)))


@pytest.mark.parametrize(
    "name",
    (
        *GUARDED,
        pytest.param(
            NO_RESET,
            marks=pytest.mark.xfail(
                strict=True,
                reason="open (docs/integrity.md §1.3, §5): the no-reset federated method holds "
                "the fix's jump back 69 s on average after the ramp, 10.9 m after it (ckf 0.51 m)",
            ),
        ),
    ),
)
def test_the_fix_comes_back_after_the_ramp_in_every_run(slowramp, name):
    sc, result, metrics = slowramp
    assert metrics[name].detection["gnss"].readmitted == 1.0
    assert metrics[name].detection["gnss"].mean_recovery_s <= 10.0
    plain = _after(sc, result.results["ckf"])
    assert _after(sc, result.results[name]) <= 1.5 * plain


def test_without_the_guard_the_fix_is_locked_out_in_many_runs(slowramp):
    sc, result, metrics = slowramp
    unguarded = metrics["ckf-chi2-unguarded"].detection["gnss"].readmitted
    assert unguarded < 0.8, unguarded
    assert _after(sc, result.results["ckf-chi2-unguarded"]) > 5 * _after(
        sc, result.results["ckf-chi2"]
    )


@pytest.mark.parametrize("name", GUARDED)
def test_fault_free_twins_are_within_10_percent_of_the_plain_filter(slowramp, name):
    _, _, metrics = slowramp
    plain = metrics["ckf"].fault_free.rmse["s"]
    assert metrics[name].fault_free.rmse["s"] <= 1.1 * plain


NOISY = (
    "ckf-chi2",
    "fkf-chi2",
    "dkf-chi2",
    "ckf-cusum",
    "ckf-glr",
    "ckf-separation",
    NO_RESET,
)


def _slowramp_with(fault, label, methods, runs):
    """``slowramp`` with its own ramp replaced by ``fault``: ``ckf`` and ``methods``,
    ``runs`` runs without the fault-free twins."""
    path = builtin_path("slowramp")
    doc = read_toml(path)
    doc["faults"] = [fault]
    sc = parse_scenario(doc, f"slowramp, {label}", Path(path).parent)
    keep = ("ckf", *methods)
    sc = dataclasses.replace(sc, methods=tuple(m for m in sc.methods if m.name in keep))
    return sc, run_scenario(sc, runs, 1, fault_free=False)


@pytest.fixture(scope="module")
def noisy():
    """``slowramp`` with its ramp replaced by the fix's noise at 10 times its σ over
    [300, 500) s: the odometer measures beside the fix, so the only-aid noise rule does
    not apply; a noisy fix that passed the coasting allowance by chance was taken whole,
    relaxed (ckf-chi2 1.40 m after the noise against ckf's 0.30 m, 3 runs of 20 some
    8 m off for 100 s).  The sequential detectors, quiet after an alarm, let five strict
    passes in a row count by chance once the coast had grown: a noisy fix re-admitted
    mid-noise left the estimate 3-5 m off, held 100-300 s after (CUSUM 1.17 m, GLR
    1.01 m); no pass counts now while the increments show a noise past 16 times R.  The
    no-reset federated method, whose locals kept no increments, took the noisy fix back
    every 40-50 s through the grown allowance (1.66 m)."""
    fault = {"sensor": "gnss", "kind": "noise-scale", "start": 300.0, "end": 500.0}
    return _slowramp_with({**fault, "magnitude": [10.0]}, "the fix noisy", NOISY, 20)


@pytest.mark.parametrize("name", NOISY)
def test_a_noisy_fix_beside_the_odometer_comes_back_as_for_the_plain_filter(noisy, name):
    sc, result = noisy
    plain = _after(sc, result.results["ckf"])
    assert _after(sc, result.results[name]) <= 1.5 * plain


LONG = ("ckf-chi2", "ckf-separation")


@pytest.fixture(scope="module")
def long_step():
    """``slowramp`` with its ramp replaced by a 20 m step of the fix over [300, 700) s,
    longer than the guard's ``lasting_s`` (300 s): the held fix keeps one offset beside
    the odometer, which cannot judge it."""
    fault = {"sensor": "gnss", "kind": "bias", "start": 300.0, "end": 700.0}
    return _slowramp_with({**fault, "magnitude": [20.0]}, "a long step of the fix", LONG, 10)


@pytest.mark.parametrize("name", LONG)
def test_a_step_that_outlasts_lasting_s_is_taken_and_its_end_comes_home(long_step, name):
    """Past ``lasting_s`` the held fix's offset is taken (as the plain filter follows a
    step), and the jump back at the step's end cancels it: the fix is used again at
    once.  The separation method alarms on the pull of the jump back rather than
    flagging it; before the jump back came home without a flag its fix was held 300 s
    more after the step (19.9 m after it against ``ckf``'s 0.50 m)."""
    sc, result = long_step
    res = result.results[name]
    assert res.guard is not None
    t = sc.times
    taken = res.guard.taken[:, :, 0]
    assert taken[:, (t > 590.0) & (t < 620.0)].any(1).all()  # lasting_s after the onset
    back = (t >= 708.0) & (t < 720.0)  # home at 700 (the separation's alarm after: 5 s)
    assert not res.guard.hold[:, back, 0].any()
    after = t >= 720.0
    plain = float(np.sqrt(np.mean(result.results["ckf"].error[:, after, 0] ** 2)))
    got = float(np.sqrt(np.mean(res.error[:, after, 0] ** 2)))
    assert got <= 1.5 * plain, (got, plain)


@pytest.fixture(scope="module")
def odometer_ramp():
    """``slowramp`` with its ramp replaced by the odometer's, to 1 m/s over [300, 500) s,
    under the no-reset federated χ² method: its test against the fused prior flags the
    healthy fix (the fused velocity follows the odometer), the fused position then
    follows the odometer's dead reckoning 100 m off, and the fix, the only position,
    was held to the end in 19 runs of 20 (109 m after the fault against ``ckf``'s
    0.32 m).  At the ramp's end the odometer is held beside it: two devices held at
    once under a single fault, so they back each other (``Guard._support`` across the
    independent locals), and the fix's local restarts from the fused reference."""
    fault = {"sensor": "odometer", "kind": "ramp", "start": 300.0, "end": 500.0}
    return _slowramp_with({**fault, "magnitude": [1.0]}, "an odometer ramp", (NO_RESET,), 20)


def test_independent_locals_take_a_healthy_held_fix_back_after_another_aids_fault(
    odometer_ramp,
):
    sc, result = odometer_ramp
    res = result.results[NO_RESET]
    assert res.guard is not None
    t = sc.times
    held = res.guard.hold[:, :, 0]
    assert held[:, (t > 300.0) & (t < 500.0)].any(1).mean() >= 0.5  # the premise
    back = ~held[:, (t >= END) & (t <= END + 30.0)]
    assert back.any(1).all()  # back within 30 s of the fault's end in every run
    plain = _after(sc, result.results["ckf"])
    assert _after(sc, res) <= 1.5 * plain, (_after(sc, res), plain)


@pytest.fixture(scope="module")
def fix_step():
    """``slowramp`` with its ramp replaced by a 20 m step of the fix over [300, 500) s,
    under the no-reset federated χ² method: the coasting allowance let the step in about
    60 s after its onset (the estimate followed it), and its end was held as long again
    (6.35 m after the step against ``ckf``'s 0.42 m).  Its locals now keep their jump
    sums, so the jump back that undoes the one the fix was re-admitted with comes home
    at once (``Guard._home``), as for the fused estimates."""
    fault = {"sensor": "gnss", "kind": "bias", "start": 300.0, "end": 500.0}
    return _slowramp_with({**fault, "magnitude": [20.0]}, "a step of the fix", (NO_RESET,), 20)


def test_independent_locals_take_a_step_back_home_at_its_end(fix_step):
    sc, result = fix_step
    res = result.results[NO_RESET]
    assert res.guard is not None
    t = sc.times
    held = res.guard.hold[:, :, 0]
    assert held[:, (t >= 300.0) & (t < 310.0)].any(1).all()  # the premise: held at onset
    assert not held[:, (t >= END + 10.0) & (t < END + 20.0)].any()  # home at the end
    plain = _after(sc, result.results["ckf"])
    assert _after(sc, res) <= 1.5 * plain, (_after(sc, res), plain)


SEQUENTIAL = ("ckf-cusum", "ckf-separation")


@pytest.fixture(scope="module")
def odometer_ramp_sequential():
    """``slowramp`` with its ramp replaced by the odometer's, to 1 m/s over [300, 500) s:
    the sequential detectors blame the fix (the estimate follows the odometer, 55-98 m
    off by the ramp's end), and the fix is taken back relaxed when the ramp ends.  Then
    a later alarm on the fix, at a measurement that agreed with the estimate, rolled
    back its pulls of the re-convergence as "too large" (CUSUM, one run of 20: 3.5 m,
    held 100 s) or removed the window that raised it (separation, several runs: 4-9 m):
    0.53 and 0.58 m after the fault against ``ckf``'s 0.32 m.  Such a rollback over the
    fine window after the aid's relaxed re-admission now waits while the flagged
    measurement agrees (docs/integrity.md §1.13): 0.30 and 0.31 m.  Deferring every such
    rollback where the measurement agrees fixed this too but broke ``slowramp``'s own
    ramp for every other guarded method (0.30 → 4.5-7.4 m)."""
    fault = {"sensor": "odometer", "kind": "ramp", "start": 300.0, "end": 500.0}
    return _slowramp_with({**fault, "magnitude": [1.0]}, "the odometer ramp", SEQUENTIAL, 20)


@pytest.mark.parametrize("name", SEQUENTIAL)
def test_after_an_odometer_ramp_no_rollback_leaves_the_fix_held(odometer_ramp_sequential, name):
    sc, result = odometer_ramp_sequential
    plain = _after(sc, result.results["ckf"])
    got = _after(sc, result.results[name])
    assert got <= 1.5 * plain, (got, plain)
    after = sc.times >= END + 20.0
    held = result.results[name].guard.hold[:, after, 0]
    assert held.mean(1).max() < 0.1, held.mean(1)


@pytest.fixture(scope="module")
def long_odometer_step():
    """``slowramp`` with its ramp replaced by a 1 m/s step of the odometer over [300, 700)
    s, 20 runs: the sequential detectors hold both aids, and the two, of different
    devices, back each other (the guard's rule 6).  When a backing faded the whole
    covariance there too (docs/integrity.md §1.18, tried), the faulty odometer, let back
    beside the healthy fix, led the faded estimate, and the CUSUM method held the fix
    from 354 s to the run's end in one run (77.8 m after the fault against ``ckf``'s
    0.35 m).  A backing fades only where the backers are not held."""
    fault = {"sensor": "odometer", "kind": "bias", "start": 300.0, "end": 700.0}
    return _slowramp_with({**fault, "magnitude": [1.0]}, "a long odometer step", SEQUENTIAL, 20)


@pytest.mark.parametrize("name", SEQUENTIAL)
def test_two_held_aids_backing_each_other_leave_no_fix_held(long_odometer_step, name):
    sc, result = long_odometer_step
    after = sc.times >= 720.0
    plain = float(np.sqrt(np.mean(result.results["ckf"].error[:, after, 0] ** 2)))
    res = result.results[name]
    got = float(np.sqrt(np.mean(res.error[:, after, 0] ** 2)))
    assert got <= 1.5 * plain, (got, plain)
    assert not res.guard.hold[:, sc.times >= sc.times[-1] - 10.0, 0].all(1).any()
