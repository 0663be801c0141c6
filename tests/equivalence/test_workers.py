"""Worker processes are invisible: the results of any split equal one process, bit for bit.

Oracle: the same scenario, runs and seed run in this process (``workers = 1``) and in
two spawned worker processes, split by groups of methods (linear) and by chunks of runs
and groups of methods (integrated).  Runs are independent and every task runs the same
serial compiled code, so every array must be identical.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from equivalence_problems import assert_identical

from ftnav.eval import montecarlo
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.parallel import default_workers, run_tasks, split_even
from ftnav.scenarios import builtin_path


def _assert_same_results(one, two):
    assert list(one.results) == list(two.results)
    assert list(one.fault_free) == list(two.fault_free)
    for name in one.results:
        assert_identical(one.results[name], two.results[name])
    for name in one.fault_free:
        assert_identical(one.fault_free[name], two.fault_free[name])


def test_linear_method_groups_in_two_processes_equal_one(monkeypatch):
    sc = load_scenario(builtin_path("seed000"))
    keep = ("ckf", "fkf-fr-inverse-trace", "fkf-inverse-trace-chi2", "dkf-chi2")
    sc = dataclasses.replace(sc, steps=300, methods=tuple(m for m in sc.methods if m.name in keep))
    monkeypatch.setattr(montecarlo, "PARALLEL_MIN_WORK", 1)
    ticks: list[int] = []
    one = run_scenario(sc, 3, 5)
    two = run_scenario(sc, 3, 5, workers=2, progress=ticks.append)
    _assert_same_results(one, two)
    np.testing.assert_array_equal(one.truth.states, two.truth.states)
    # every epoch of every method (faulty and fault-free in one batch) reported once
    assert sum(ticks) == len(keep) * sc.steps


def test_integrated_run_chunks_and_method_groups_in_two_processes_equal_one():
    sc = load_scenario(builtin_path("seed002"))
    sc = dataclasses.replace(sc, steps=120)
    one = run_scenario(sc, 3, 2)
    by_runs = run_scenario(sc, 3, 2, workers=2)  # chunks of 2 + 1 runs
    by_methods = run_scenario(sc, 1, 2, workers=2)  # one run: groups of methods
    _assert_same_results(one, by_runs)
    for name, res in one.results.items():
        assert (res.local is None) == (by_runs.results[name].local is None)
    single = run_scenario(sc, 1, 2)
    _assert_same_results(single, by_methods)
    assert by_runs.stream is None


def _fail(task, progress):
    raise ArithmeticError(f"task {task}")


def test_a_worker_exception_is_raised_with_its_type_and_message():
    with pytest.raises(ArithmeticError, match="task 1"):
        run_tasks(_fail, [1, 2], 2)


def test_split_even_and_the_worker_count(monkeypatch):
    assert split_even([1, 2, 3, 4, 5], 2) == [[1, 3, 5], [2, 4]]
    assert split_even([1], 4) == [[1]]
    monkeypatch.setenv("FTNAV_WORKERS", "3")
    assert default_workers() == 3
    monkeypatch.setenv("FTNAV_WORKERS", "0")
    with pytest.raises(ValueError, match="^FTNAV_WORKERS: expected an integer >= 1, got 0$"):
        default_workers()


def test_workers_with_one_blas_thread_equal_a_parent_with_more(monkeypatch):
    """Dask's ``LocalCluster`` sets ``OMP_NUM_THREADS``, ``MKL_NUM_THREADS`` and
    ``OPENBLAS_NUM_THREADS`` to 1 in the process that starts it; a campaign started after
    that ran its spawned workers with one BLAS thread beside a parent with the machine's,
    and the integrated ``seed002`` differed in the last bits (4e-13 in the CUSUM's
    statistic).  The workers now take the parent's BLAS thread count.  (One thread
    everywhere is no cure: with one OpenBLAS thread a chunk of one run and the batch of
    two differed in the same bits.)"""
    sc = load_scenario(builtin_path("seed002"))
    sc = dataclasses.replace(sc, steps=60)
    one = run_scenario(sc, 2, 2)
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        monkeypatch.setenv(name, "1")
    two = run_scenario(sc, 2, 2, workers=2)
    _assert_same_results(one, two)
