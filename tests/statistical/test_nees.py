"""Monte Carlo consistency of the federated modes and the sharing-rule benchmarks
(spec §1.6, §1.9 item 3, §2 tests d-e, §12.1).

NEES bounds.  For a consistent filter the run average of the NEES over M runs
satisfies ``M·ε̄_k ~ χ²(M n)``, so ε̄_k has mean n and standard deviation
``√(2n/M)``; with M = 200 and n = 3 that is 0.17.  The spec's NR bound
``n + 3√(2n/M)`` = 3.52 is a 3σ upper bound (NR is conservative, so its NEES sits
below n).  For FR every epoch (= CKF) the 95% two-sided band of one epoch is
``[χ²_{600}(0.025), χ²_{600}(0.975)]/200`` = [2.67, 3.35]; the time average over
the last 100 epochs has a smaller spread, so requiring it inside the per-epoch
band is a loose check, and the per-epoch averages are required inside the band
for at least 85% of the epochs (95% expected; epochs are correlated, so the
fraction fluctuates more than a binomial one).
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.eval.metrics import chi2_band
from ftnav.eval.montecarlo import build_filter, run_filter
from ftnav.model.scenario import Fault, Method, Scenario
from ftnav.model.system import LinearModel, Sensor
from ftnav.model.system import LinearSystem
from ftnav.sim.linear import simulate

T = 0.05
F_CA = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
H_GAINS = (1.0, 2.5, 0.5)


def s0_example(Q, P0, steps, faults=()) -> Scenario:
    """Spec §12.1 constant-acceleration example (dt = 1 s per step for the fault window)."""
    model = LinearModel(("s", "v", "a"), F_CA, Q, np.zeros(3), P0, Q)
    R = np.array([[30.0]])
    sensors = tuple(Sensor(f"z{i}", np.array([[h, 0.0, 0.0]]), R, R) for i, h in enumerate(H_GAINS))
    return Scenario("s0", 1.0, steps, model, sensors, faults)


# ---------------------------------------------------------------------------
# §1.6 Monte Carlo NEES
# ---------------------------------------------------------------------------

RUNS = 200


@pytest.fixture(scope="module")
def nees_problem():
    sc = s0_example(np.diag([5.0, 2.0, 3.0]) * 1e-3, np.diag([100.0, 10.0, 1.0]), 400)
    return LinearSystem.from_scenario(sc), simulate(sc, RUNS, seed=16)


def _last_100(system, sim, method) -> np.ndarray:
    """Run-averaged NEES of the last 100 epochs, (100,)."""
    return run_filter(build_filter(system, method), sim, 3).nees[:, -100:].mean(0)


@pytest.mark.parametrize(
    "method", [Method("nr", mode="no-reset"), Method("fr5", reset_interval=5)], ids=["NR", "FR/5"]
)
def test_conservative_modes_nees_bound(nees_problem, method):
    """§1.9 item 3: NR (and FR/5) ANEES ≤ n + 3√(2n/200) = 3.52 (measured: NR 2.89, FR/5 3.09;
    spec: NR 2.80, FR/5 2.99)."""
    system, sim = nees_problem
    anees = _last_100(system, sim, method).mean()
    assert anees <= 3.0 + 3.0 * np.sqrt(2.0 * 3.0 / RUNS), anees


def test_no_reset_is_conservative(nees_problem):
    """NR's ANEES is below the consistent filter's: it over-states its covariance."""
    system, sim = nees_problem
    nr = _last_100(system, sim, Method("nr", mode="no-reset")).mean()
    fr = _last_100(system, sim, Method("fr")).mean()
    assert nr < fr - 0.1, (nr, fr)


@pytest.mark.parametrize("architecture", ["federated", "centralized"])
def test_fusion_reset_every_epoch_is_consistent(nees_problem, architecture):
    """§1.6: FR/1 (= CKF) run-averaged NEES inside the 95% χ² band."""
    system, sim = nees_problem
    per_epoch = _last_100(system, sim, Method("fr", architecture=architecture))
    lo, hi = chi2_band(3 * RUNS, RUNS)
    assert lo < per_epoch.mean() < hi, per_epoch.mean()
    assert ((per_epoch > lo) & (per_epoch < hi)).mean() >= 0.85


# ---------------------------------------------------------------------------
# §2 (d), (e): the sharing rules on the S0 example with a step fault
# ---------------------------------------------------------------------------

FAULT_START, FAULT_END = 300, 500  # steps 300..499


@pytest.fixture(scope="module")
def faulty_s0():
    fault = Fault("z0", "bias", float(FAULT_START), float(FAULT_END), np.array([60.0]))
    # §12.1 runs 1200 steps; the filters are causal and the window ends at step 499,
    # so the first 500 steps give the same window statistics at 40% of the cost
    sc = s0_example(np.diag([5.0, 2.0, 3.0]), 100.0 * np.eye(3), FAULT_END, (fault,))
    system = LinearSystem.from_scenario(sc)
    sim = simulate(sc, 20, seed=2)
    window = sc.fault_mask()
    assert window.sum() == FAULT_END - FAULT_START and window[FAULT_START - 1]
    return system, sim, window


def _displacement_rmse(system, sim, window, method) -> float:
    res = run_filter(build_filter(system, method), sim, 3)
    err = res.x[:, window, 0] - sim.truth[:, window, 0]
    return float(np.sqrt((err**2).mean(1)).mean())


def test_inverse_trace_beats_trace_with_reset_interval_10(faulty_s0):
    """§2 (e), §12.1: +60 step on sensor 1, no fault factor, reset every 10 epochs: the
    inverse-trace rule's displacement RMSE over the fault window is ≥ 5% lower than the
    trace rule's over 20 Monte Carlo runs (measured 8.95 vs 10.65; spec 8.7 vs 10.4)."""
    system, sim, window = faulty_s0
    inverse = _displacement_rmse(
        system, sim, window, Method("inv", sharing="inverse-trace", reset_interval=10)
    )
    trace = _displacement_rmse(
        system, sim, window, Method("tr", sharing="trace", reset_interval=10)
    )
    assert inverse <= 0.95 * trace, (inverse, trace)


RULES = ("equal", "information", "trace", "eigen-trace", "frobenius", "inverse-trace")


def test_sharing_rule_does_not_matter_with_reset_every_epoch(faulty_s0):
    """§2 (d), §1.6 consequence: with FR every epoch the fused estimate is β-invariant,
    fault or not: every rule gives the same x̂_g within 1e-9 (relative to its scale)."""
    system, sim, _ = faulty_s0
    xs = {
        rule: run_filter(build_filter(system, Method(rule, sharing=rule)), sim, 3).x
        for rule in RULES
    }
    ref = xs["equal"]
    scale = max(1.0, float(np.abs(ref).max()))
    for rule, x in xs.items():
        np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-9 * scale, err_msg=rule)
