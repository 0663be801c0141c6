"""Batching the runs of an integrated scenario does not change any run's result.

Oracle: the same runs in one batch.  Every run draws its own random streams (keyed by
its run index) and every kernel loops over the batch row by row, so running the runs
in batches of 2 must reproduce the one-batch result to rounding, twin included.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ftnav.eval.montecarlo import CHUNK_BYTES, RESULT_FIELDS, chunk_runs, run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path


@pytest.fixture(scope="module")
def seed002():
    sc = load_scenario(builtin_path("seed002"))
    return dataclasses.replace(sc, steps=40)


def test_runs_in_batches_equal_one_batch(seed002):
    one = run_scenario(seed002, 3, seed=5, chunk=3)
    parts = run_scenario(seed002, 3, seed=5, chunk=2)
    assert one.stream is not None and parts.stream is None
    for pool in ("results", "fault_free"):
        a, b = getattr(one, pool), getattr(parts, pool)
        assert a.keys() == b.keys() and a
        for name in a:
            for field in RESULT_FIELDS:
                fa, fb = getattr(a[name], field), getattr(b[name], field)
                if fa is None:
                    assert fb is None
                    continue
                for xa, xb in zip(
                    fa if isinstance(fa, tuple) else (fa,),
                    fb if isinstance(fb, tuple) else (fb,),
                    strict=True,
                ):
                    assert xa.shape == xb.shape and xa.shape[0] == 3
                    np.testing.assert_allclose(xb, xa, rtol=1e-9, atol=1e-12)


def test_default_batch_bounds_the_imu_memory(seed002):
    full = dataclasses.replace(seed002, steps=3600)
    n = chunk_runs(full)
    per_run = full.samples_per_epoch * 3600 * 6 * 8 * 2
    assert n * per_run <= CHUNK_BYTES < (n + 1) * per_run
    assert n == 62
    with pytest.raises(ValueError, match="chunk"):
        run_scenario(seed002, 2, seed=1, chunk=0)
