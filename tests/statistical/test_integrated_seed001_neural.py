"""Seed001 (paper 001): the neuron fusion centre's χ² flags — detection and re-admission.

Spec §3.1 (residual test), §5.4 (configuration selection from the flags), §6.3
(time-update isolation) and §11 (detection metrics).

Scenario: the built-in seed001 without its SINS gyro-bias fault, 700 s, 8 runs, two
neuron centres on the same data: the built-in ``neural-chi2`` (``prior =
"intersection"``: each aid's residual is tested against the covariance intersection
of the local priors) and paper 001's literal test (``prior = "local"``: each local
filter tests its own residual).  In both a flagged local discards its measurement
(time update only) and the flag pattern picks the bank of neurons.

Why Pd ≥ 0.95.  The intersection ``P⁻¹ = Σ P_i⁻¹ / 3`` is consistent for any
correlation of the local errors (``tests/closed_form/test_covariance_intersection.py``)
and keeps the TAN filter's height (σ 1.3 m, so σ ≤ 2.3 m in the intersection) and the
GPS and Doppler filters' horizontal information.  The biases are ≥ 5.4 σ of the
residual as in ``test_integrated_seed001.py``; a flagged local's coasted prior is
diluted by the others instead of drifting alone.  Measured, seed 1, 20 runs:
Pd 1.000 for every aid, re-admission ≤ 4 s in every run (seeds 2 and 3 the same).

Why the literal test fails TAN re-admission in one run of 8 (strict xfail).  While it
is isolated the SINS/TAN local filter coasts on its own SINS solution.  It has no
velocity aid, so its horizontal velocity error grows (≈ 0.5 m/s relative to the fused
output 70 s into the window in the worst of 20 runs), and through the terrain slopes of
``H`` its prior drifts towards the biased clearance while ``S`` grows.  The statistic
falls to 3–4 against the threshold 10.83, five passes in a row clear the flag inside
the window, the local absorbs the +40 m bias, and once the aid recovers it is flagged
against its own biased estimate for ever (lock-out).  Measured, seed 1: Pd GPS / TAN /
DNS 1.000 / 0.961 / 1.000 over these 8 runs; re-admission never in run 3.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ftnav.eval.evaluate import evaluate
from ftnav.eval.integrated import run_ins_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path
from ftnav.sim.ins_scenario import SINS

METHOD = "neural-chi2"
LITERAL = "neural-chi2-own"  # paper 001's own-residual test
RUNS = 8
AIDS = ("gps", "tan", "dns")


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(builtin_path("seed001"))
    method = next(m for m in sc.methods if m.name == METHOD)
    assert method.prior == "intersection" and method.isolation == "time-update"
    literal = dataclasses.replace(method, name=LITERAL, prior="local")
    faults = tuple(f for f in sc.faults if f.sensor != SINS)
    return dataclasses.replace(sc, steps=700, faults=faults, methods=(method, literal))


@pytest.fixture(scope="module")
def result(scenario):
    return run_ins_scenario(scenario, RUNS, seed=1, fault_free=False).result


@pytest.fixture(scope="module")
def metrics(result):
    return evaluate(result)


def _recovery(result, aid, method=METHOD):
    """Seconds from the end of the aid's fault window until its flag clears, per run."""
    sc = result.scenario
    (f,) = [f for f in sc.faults if f.sensor == aid]
    flags = result.results[method].flag[..., sc.sensor_names.index(aid)]
    t = sc.times
    assert flags[:, (t >= f.start) & (t < f.end)].any(1).all()  # flagged in every run
    after = t >= f.end
    cleared = ~flags[:, after]
    return np.where(cleared.any(1), t[after][np.argmax(cleared, 1)] - f.end, np.inf)


@pytest.mark.parametrize("method", [METHOD, LITERAL])
@pytest.mark.parametrize("aid", AIDS)
def test_every_aid_fault_is_detected(metrics, method, aid):
    """Per-epoch Pd inside the fault window ≥ 0.95, pooled over the 8 runs."""
    det = metrics[method].detection[aid]
    assert det["events"] == RUNS and det["missed_rate"] == 0.0
    assert det["rate"] >= 0.95, f"{method}, {aid}: Pd = {det['rate']:.4f}"


@pytest.mark.parametrize("aid", AIDS)
def test_every_aid_is_readmitted_within_15_s_in_every_run(result, aid):
    recovery = _recovery(result, aid)
    assert (recovery <= 15.0).all(), f"{aid}: recovery per run {recovery} s"


@pytest.mark.parametrize("aid", AIDS)
def test_false_alarm_rate_sanity(metrics, aid):
    """Loose bound: alarms on < 5 % of the clean epochs (measured ≤ 0.2 % here)."""
    assert metrics[METHOD].detection[aid]["false_alarm_rate"] < 0.05


@pytest.mark.parametrize("aid", ("gps", "dns"))
def test_own_residual_test_readmits_gps_and_dns(result, aid):
    recovery = _recovery(result, aid, LITERAL)
    assert (recovery <= 15.0).all(), f"{aid}: recovery per run {recovery} s"


@pytest.mark.xfail(strict=True, reason=(
    "paper 001's own-residual test: the coasting SINS/TAN local filter absorbs the +40 m "
    "bias after a premature release inside the window and is never re-admitted in run 3 "
    "of 8 (module doc); the built-in prior = 'intersection' has no such lock-out"))
def test_own_residual_test_readmits_tan(result):
    recovery = _recovery(result, "tan", LITERAL)
    assert (recovery <= 15.0).all(), f"tan: recovery per run {recovery} s"
