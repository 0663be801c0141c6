"""Batching is invisible: how runs are grouped never changes a run's result.

Oracles: the same runs processed (a) in separate batches (each simulated stream alone
through the engine, :func:`ftnav.engine.driver.iterate`, scored against its truth),
(b) concatenated into one batch by :func:`run_scenario` (faulty and fault-free twin
together) must agree exactly (runs are independent, and each row runs the same
compiled code).  Worker processes:
``tests/equivalence/test_workers.py``.
"""

from __future__ import annotations

import dataclasses

import pytest
from equivalence_problems import assert_identical

from ftnav.engine.driver import iterate
from ftnav.engine.linear import LinearModel
from ftnav.eval.montecarlo import build_filters, run_scenario, score
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path
from ftnav.sim.linear import simulate

METHODS = ("ckf", "fkf-inverse-trace-chi2", "fkf-inverse-trace-oracle", "dkf-chi2")


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(builtin_path("seed000"))
    methods = tuple(m for m in sc.methods if m.name in METHODS)
    assert len(methods) == len(METHODS)
    return dataclasses.replace(sc, steps=600, methods=methods)


def _alone(scenario, method, sim):
    """One method's scored result on one simulated batch, run through the engine alone."""
    system = scenario.system()
    model = LinearModel(system)
    records = iterate(model, sim.stream, build_filters(scenario, system, (method,)), scenario.steps)
    return score(scenario, records, sim.truth, [method.name], sim.stream, model)[method.name]


def test_fault_free_twin_in_one_batch_equals_separate_batches(scenario):
    runs, seed = 5, 11
    res = run_scenario(scenario, runs, seed)
    sim = simulate(scenario, runs, seed)
    sim_ff = simulate(scenario.without_faults(), runs, seed)
    for m in scenario.methods:
        assert_identical(res.results[m.name], _alone(scenario, m, sim))
        assert_identical(res.fault_free[m.name], _alone(scenario, m, sim_ff))
