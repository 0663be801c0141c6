"""The other aids back a held aid when the SINS itself failed (ftnav.fusion.guard), on ``seed002``.

A 1 °/h gyro bias step of ``seed002``'s SINS over [300, 500) s: the CUSUM method's
detector sees its star tracker disagree with the drifting attitude before the bias
states absorb the step, and isolates it.  Tested against an INS that drifts on, the
star tracker could not come back; the GNSS was isolated in turn, and the faulty INS
coasted: after the fault 75–1704 m in every one of these 8 runs of 1500 s (636 m RMS)
against the plain filter's 0.47 m.  With the backing rule (docs/integrity.md §1.6) the
GNSS velocities, which see the tilt, back the star tracker and it is re-admitted.  Oracles:
the plain filter's error after the fault, per run (issue 20's rule, within 1.5x: the
median run passes) and over the runs.  In one run a CUSUM false alarm 500 s after the
fault, at a GNSS fix that agreed with the estimate, found the GNSS's pulls of the
fault's time (the corrections of the drifting INS) "too large"; the star tracker and
altimeter read no horizontal row.  Rolled back and kept as a hypothesis, undone after
``confirm`` (20) epochs, it cost 47.7 m RMS after the fault in that run (332 m for the
20 s), and the CUSUM method was an expected failure over the runs; the rollback is now
deferred while the flagged fix agrees (docs/integrity.md §1.11).  Before the hypothesis
rule the same kind of rollback locked the GNSS out for 150-550 s: 462 m (CUSUM) and
509 m (chi2) in one run each.
"""

from __future__ import annotations

import numpy as np
import pytest
from seed002_fault import gyro_step, run_seed002

RUNS = 8
START, END, DURATION = 300.0, 500.0, 1500.0
GUARDED = ("fkf-chi2", "fkf-cusum")


@pytest.fixture(scope="module")
def drifted():
    fault = gyro_step(START, END, [1.0, 0.0, 0.0])
    return run_seed002(fault, DURATION, RUNS, ("ckf", *GUARDED), "a 1 deg/h gyro bias step")


def _after(res) -> np.ndarray:
    """(B,) each run's horizontal RMS from 10 s after the fault's end."""
    t = np.arange(res.error.shape[1]) * 1.0
    keep = t >= END + 10.0
    h2 = res.error[:, keep, 0] ** 2 + res.error[:, keep, 1] ** 2
    return np.sqrt(h2.mean(1))


def test_in_the_median_run_the_cusum_method_recovers_as_the_plain_filter(drifted):
    plain = np.median(_after(drifted.results["ckf"]))
    got = np.median(_after(drifted.results["fkf-cusum"]))
    assert got <= 1.5 * plain, (got, plain)


@pytest.mark.parametrize("name", GUARDED)
def test_over_the_runs_the_guarded_methods_recover_as_the_plain_filter(drifted, name):
    plain = np.sqrt(np.mean(_after(drifted.results["ckf"]) ** 2))
    got = np.sqrt(np.mean(_after(drifted.results[name]) ** 2))
    assert got <= 1.5 * plain, (name, got, plain)
