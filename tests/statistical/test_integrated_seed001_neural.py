"""Seed001 (paper 001): the neuron fusion centre's χ² flags — detection and re-admission.

Spec §3.1 (residual test), §5.4 (configuration selection from the flags), §6.3
(time-update isolation) and §11 (detection metrics).

Scenario: the built-in seed001 without its SINS gyro-bias fault, 700 s, 8 runs, the
``neural-chi2`` method alone.  As in paper 001 each SINS/aid local filter tests its
*own* prior residual and a flagged local discards its measurement (time update only);
the flag pattern picks the bank of neurons.

Why Pd ≥ 0.95.  The sizes are those of ``test_integrated_seed001.py`` (every bias
≥ 5.4 σ of its residual with the local's own prior at the onset, where that prior is
sharp: TAN height σ 1.3 m).  Measured, seed 1: Pd GPS / TAN / DNS = 1.000 / 0.961 /
1.000 over 8 runs (0.965 for TAN over 20 runs).

Why TAN re-admission fails in one run of 8 (strict xfail below).  While it is isolated
the SINS/TAN local filter coasts on its own SINS solution.  It has no velocity aid, so
its horizontal velocity error grows (≈ 0.5 m/s relative to the fused output after
70 s in run 11 of 20, 0.08 → 0.24 m/s σ), and through the terrain slopes of ``H`` its
prior drifts towards the biased clearance while ``S`` grows.  The single-epoch
statistic falls to 3-4 against the threshold 10.83, five passes in a row clear the
flag inside the window, the local absorbs the +40 m bias, and once the aid recovers it
is flagged against its own biased estimate and coasts on it for ever (lock-out).
Measured remedies that did not hold, 20 runs (docs/claims.md): a joint χ² test of the
last ``n_off`` epochs for the release (TAN Pd 0.987, still one lock-out); reinitializing
a locked-out local from the neuron output when its aid agrees with that output under the
banks' training error covariance (all re-admitted within 5 s, but the neuron output is
not accurate enough to be the reference: horizontal RMSE 117 → 474 m); P_FA = 0.01
(TAN Pd 0.992, false alarms 29 %, horizontal RMSE 1.4 km).
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
RUNS = 8
AIDS = ("gps", "tan", "dns")


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(builtin_path("seed001"))
    method = next(m for m in sc.methods if m.name == METHOD)
    assert method.prior == "local" and method.isolation == "time-update"  # paper 001's test
    faults = tuple(f for f in sc.faults if f.sensor != SINS)
    return dataclasses.replace(sc, steps=700, faults=faults, methods=(method,))


@pytest.fixture(scope="module")
def result(scenario):
    return run_ins_scenario(scenario, RUNS, seed=1, fault_free=False).result


@pytest.fixture(scope="module")
def metrics(result):
    return evaluate(result)[METHOD]


def _recovery(result, aid):
    """Seconds from the end of the aid's fault window until its flag clears, per run."""
    sc = result.scenario
    (f,) = [f for f in sc.faults if f.sensor == aid]
    flags = result.results[METHOD].flag[..., sc.sensor_names.index(aid)]
    t = sc.times
    assert flags[:, (t >= f.start) & (t < f.end)].any(1).all()  # flagged in every run
    after = t >= f.end
    cleared = ~flags[:, after]
    return np.where(cleared.any(1), t[after][np.argmax(cleared, 1)] - f.end, np.inf)


@pytest.mark.parametrize("aid", AIDS)
def test_every_aid_fault_is_detected_by_the_local_filters_own_test(metrics, aid):
    """Per-epoch Pd inside the fault window ≥ 0.95, pooled over the 8 runs."""
    det = metrics.detection[aid]
    assert det["events"] == RUNS and det["missed_rate"] == 0.0
    assert det["rate"] >= 0.95, f"{aid}: Pd = {det['rate']:.4f}"


@pytest.mark.parametrize("aid", ("gps", "dns"))
def test_gps_and_dns_are_readmitted_within_15_s_in_every_run(result, aid):
    recovery = _recovery(result, aid)
    assert (recovery <= 15.0).all(), f"{aid}: recovery per run {recovery} s"


@pytest.mark.xfail(strict=True, reason=(
    "lock-out of the coasting SINS/TAN local filter (module doc): in run 3 of 8 it "
    "absorbs the +40 m bias after a premature release inside the window and is never "
    "re-admitted; issue 5 stays open on this point"))
def test_tan_is_readmitted_within_15_s_in_every_run(result):
    recovery = _recovery(result, "tan")
    assert (recovery <= 15.0).all(), f"tan: recovery per run {recovery} s"
