"""Seed001 (paper 001, SINS/GPS/TAN/DNS): χ² detection and re-admission of aid faults.

Spec §3.1 (residual test), §5.4 (the neuron centre's configuration from the flags),
§6.3 (time-update isolation) and §11 (detection metrics).

Scenario: the built-in seed001 without its SINS gyro-bias fault (a common-mode fault
no aid-level test can attribute), 700 s, 8 runs, three methods on the same data:

* ``fkf-nr-chi2``: the no-reset federated filter with the residual χ² test against
  the fused prior (P_FA = 1e-3, n_on = 1, n_off = 5);
* ``neural-chi2-feedback``: the neuron centre with feedback correction, each aid's
  residual tested against the covariance intersection of the local priors
  (``prior = "intersection"``); paper 001's output-correction form (``neural-chi2``)
  has standalone SINS/aid filters whose SINS/TAN filter does not converge from the
  paper's initial error in every run, so its detection is reported, not asserted here
  (docs/claims.md);
* ``neural-chi2-own``: the same with paper 001's own-residual test (``prior = "local"``).

In every one a flagged local filter discards its measurement (time update only).

**Federated filter.**

Why Pd ≥ 0.95.  The residual of aid i under a bias b is ``ν ~ N(b, S)`` with
``S = H P Hᵀ + R``; the statistic ``νᵀ S⁻¹ ν`` is non-central χ²(m, λ) with
``λ ≤ bᵀ R⁻¹ b``.  From the sensors' R (checked by the first test):

* GPS, ``markov = "augment"``: R is the 1 m white part; the 25 m, τ 100 s Markov
  error is a private state of the GPS filter that its own measurements barely separate
  from the position, so its prior σ stays near 25 m and S ≈ (25 m)² per position axis;
  +150 m East and North is ≈ 6 σ per axis, λ ≈ 72 over m = 6; threshold
  χ²₆(0.999) = 22.46; Pd ≈ 0.9999.
* TAN: σ = √(5² + 5²) = 7.07 m; +40 m is 5.66 σ, λ = 32, m = 1; threshold 10.83; Pd = 0.991.
* DNS, ``states = "augment"``: σ = 0.05 m/s; +1 m/s East and North is 20 σ per axis,
  λ = 800, m = 2; Pd = 1.

For TAN and DNS ``H P Hᵀ`` is small against R (the fused prior keeps the isolated
local's coasted estimate: TAN 40 m ≥ 5.4 σ, DNS 1 m/s ≥ 9 σ), so λ stays close to
these values and Pd ≥ 0.95 holds with margin (measured 1.000 for all three, 20 runs).

Re-admission.  After the window the statistic returns to χ²(m); with ``n_off = 5``
the flag clears after 5 clean epochs, so within 15 s, provided the fused prior is
consistent with the healthy aid.  Two things make it so: the GPS Markov error is
augmented (with ``markov = "white"`` the fused height was overconfident, ANEES ~300,
and followed the GPS Markov error while TAN was isolated, so the healthy TAN was never
re-admitted in one run of 4), and a no-reset local filter isolated by time update
stays in the fusion on its coasted estimate (dropping it left the fused height to GPS
alone: TAN Pd 0.69 with the augmented GPS).  Measured, 20 runs: Pd 1.000 for every
aid, re-admission 3-4 s.

**Neuron centre.**  Why Pd ≥ 0.95.  The intersection ``P⁻¹ = Σ P_i⁻¹ / 3`` is
consistent for any correlation of the local errors
(``tests/closed_form/test_covariance_intersection.py``) and keeps the TAN filter's
height (σ 1.3 m, so σ ≤ 2.3 m in the intersection) and the GPS and Doppler filters'
horizontal information.  The biases are ≥ 5.4 σ of the residual, as above; a flagged
local's coasted prior is diluted by the others instead of drifting alone.  Measured,
seed 1, 20 runs: Pd 1.000 for every aid, re-admission ≤ 4 s in every run (seeds 2 and
3 the same).

Why the literal test fails TAN re-admission in one run of 8 (strict xfail).  While it
is isolated the SINS/TAN local filter coasts on its own SINS solution.  It has no
velocity aid, so its horizontal velocity error grows (≈ 0.5 m/s relative to the fused
output 70 s into the window in the worst of 20 runs), and through the terrain slopes of
``H`` its prior drifts towards the biased clearance while ``S`` grows.  The statistic
falls to 3–4 against the threshold 10.83, five passes in a row clear the flag inside
the window, the local absorbs the +40 m bias, and once the aid recovers it is flagged
against its own biased estimate for ever (lock-out).  Measured without the guard,
seed 1: Pd GPS / TAN / DNS 1.000 / 0.961 / 1.000 over these 8 runs; re-admission never
in run 3.

Why the guard removes it (issue 20).  The guard re-tests a held aid of this test against
the neuron output's common states (which the coasting local does not drag), restarts a
re-admitted local from that reference, and, since independent locals have no rollback,
keeps the detector's word while the aid is held (no re-admission through the coasting
allowance, which let a +40 m TAN and a +150 m GPS back in before their faults ended and
locked them out afterwards).  Measured, seed 1, 8 runs: TAN re-admitted in every run.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.model.scenario import SINS
from ftnav.scenarios import builtin_path

FKF = "fkf-nr-chi2"
NEURAL = "neural-chi2-feedback"  # feedback: one SINS shared by the locals
LITERAL = "neural-chi2-own"  # paper 001's own-residual test
RUNS = 8
AIDS = ("gps", "tan", "dns")


@pytest.fixture(scope="module")
def seed001():
    sc = load_scenario(builtin_path("seed001"))
    fkf, neural = (next(m for m in sc.methods if m.name == n) for n in (FKF, NEURAL))
    assert neural.detector.prior == "intersection" and neural.isolation == "time-update"
    literal = neural.model_copy(
        update={"name": LITERAL, "detector": neural.detector.model_copy(update={"prior": "local"})}
    )
    faults = tuple(f for f in sc.faults if f.sensor != SINS)
    # the literal variant fuses with the same trained neuron banks as neural-chi2
    learned = sc.learned + ((LITERAL, sc.learned_for(NEURAL)),)
    return dataclasses.replace(
        sc, steps=700, faults=faults, methods=(fkf, neural, literal), learned=learned
    )


@pytest.fixture(scope="module")
def result(seed001):
    return run_scenario(seed001, RUNS, seed=1, fault_free=False)


@pytest.fixture(scope="module")
def metrics(result):
    return evaluate(result)


def _fault(sc, aid):
    (f,) = [f for f in sc.faults if f.sensor == aid]
    return f


def test_injected_biases_are_at_least_5_sigma_of_the_aid_noise(seed001):
    """The premise of the Pd bound: every fault is ≥ 5 σ of the sensor's assumed R."""
    assert {f.sensor for f in seed001.faults} == set(AIDS)
    for aid in AIDS:
        f = _fault(seed001, aid)
        assert f.kind == "bias" and f.end - f.start == 100.0
        sigma = np.sqrt(np.diag(seed001.aids[seed001.sensor_names.index(aid)].sensor.R))
        assert np.sqrt(np.sum((f.magnitude / sigma) ** 2)) >= 5.0, aid


def _recovery(result, aid, method):
    """Seconds from the end of the aid's fault window until its flag clears, per run."""
    sc = result.scenario
    f = _fault(sc, aid)
    flags = result.results[method].flag[..., sc.sensor_names.index(aid)]
    t = sc.times
    assert flags[:, (t >= f.start) & (t < f.end)].any(1).all()  # flagged in every run
    after = t >= f.end
    cleared = ~flags[:, after]
    return np.where(cleared.any(1), t[after][np.argmax(cleared, 1)] - f.end, np.inf)


@pytest.mark.parametrize("method", [FKF, NEURAL, LITERAL])
@pytest.mark.parametrize("aid", AIDS)
def test_every_aid_fault_is_detected(metrics, method, aid):
    """Per-epoch Pd inside the fault window ≥ 0.95, pooled over the 8 runs."""
    det = metrics[method].detection[aid]
    assert det.events == RUNS and det.missed_rate == 0.0
    assert det.rate >= 0.95, f"{method}, {aid}: Pd = {det.rate:.4f}"


@pytest.mark.parametrize(
    "method, aid",
    [(FKF, a) for a in AIDS] + [(NEURAL, a) for a in AIDS] + [(LITERAL, "gps"), (LITERAL, "dns")],
)
def test_a_recovered_aid_is_readmitted_within_15_s_in_every_run(result, method, aid):
    """After the window ends the flag clears within 15 s, in each run."""
    recovery = _recovery(result, aid, method)
    assert (recovery <= 15.0).all(), f"{method}, {aid}: recovery per run {recovery} s"


def test_own_residual_test_readmits_tan(result):
    """The literal test's TAN lock-out (module doc) is gone under the guard."""
    recovery = _recovery(result, "tan", LITERAL)
    assert (recovery <= 15.0).all(), f"tan: recovery per run {recovery} s"


@pytest.mark.parametrize("method, bound", [(FKF, 0.2), (NEURAL, 0.05)])
@pytest.mark.parametrize("aid", AIDS)
def test_false_alarm_rate_sanity(metrics, method, bound, aid):
    """Loose bounds on the alarms per clean epoch (measured: FKF ≤ 0.11, neural ≤ 0.002)."""
    assert metrics[method].detection[aid].false_alarm_rate < bound
