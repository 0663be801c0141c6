"""``common_mode = "keep"``: every local flagged at once means the shared reference failed.

Oracle flags from zero-magnitude faults (the data are untouched): when all three
sensors are flagged over the same window, a federated filter with
``common_mode = "keep"`` fuses them all and equals the filter without a detector;
with the default ``"isolate"`` it does not (the test has teeth); when only one sensor
is flagged, ``keep`` isolates it exactly as ``isolate`` does.  ``common_mode_quorum = q``
keeps them all as soon as q of them are flagged together: two of three flagged with
q = 2 equals the filter without a detector, while the default quorum (all three)
isolates those two exactly as ``isolate``; one flagged with q = 2 is still isolated.
"""

from __future__ import annotations

import numpy as np
import pytest
from equivalence_problems import assert_same, drive, random_scenario, simulate_problem

from ftnav.fusion.federated import FederatedFilter
from ftnav.fusion.registry import method_config
from ftnav.io.sections import resolve_methods
from ftnav.model.scenario import Fault

STEPS = 300


def _problem(sensors):
    rng = np.random.default_rng(4242)
    faults = tuple(Fault(f"z{i}", "bias", 100.0, 200.0, np.zeros(1)) for i in sensors)
    sc = random_scenario(rng, 3, [1, 1, 1], STEPS, faults=faults)
    return sc.system(), simulate_problem(sc, runs=3, seed=5)


def _fkf(system, **kw):
    """The fusion-reset federated filter with ``kw``, checked against the system as a
    scenario's methods are (the refusal names the setting)."""
    config = method_config("federated", name="f", mode="fusion-reset", **kw)
    resolve_methods((config,), system, None, "<test>")
    return FederatedFilter(system, config)


def test_all_flagged_keep_equals_no_detector():
    system, sim = _problem([0, 1, 2])
    assert sim.stream.labels[100:199].all()
    ref = drive(_fkf(system), sim)
    keep = drive(_fkf(system, detector="oracle", common_mode="keep"), sim)
    isolate = drive(_fkf(system, detector="oracle"), sim)
    assert_same(keep, ref)
    assert np.abs(isolate.x - ref.x).max() > 1e-3 * np.abs(ref.x).max()


def test_single_flag_keep_equals_isolate():
    system, sim = _problem([1])
    keep = drive(_fkf(system, detector="oracle", common_mode="keep"), sim)
    isolate = drive(_fkf(system, detector="oracle"), sim)
    assert_same(keep, isolate, rtol=0.0)


def test_quorum_of_flags_keep_equals_no_detector():
    system, sim = _problem([0, 1])
    assert sim.stream.labels[100:199, :2].all() and not sim.stream.labels[:, 2].any()
    ref = drive(_fkf(system), sim)
    quorum = drive(_fkf(system, detector="oracle", common_mode="keep", common_mode_quorum=2), sim)
    every = drive(_fkf(system, detector="oracle", common_mode="keep"), sim)
    isolate = drive(_fkf(system, detector="oracle"), sim)
    assert_same(quorum, ref)
    assert_same(every, isolate, rtol=0.0)  # two of three: below the default quorum
    assert np.abs(isolate.x - ref.x).max() > 1e-3 * np.abs(ref.x).max()


def test_single_flag_below_quorum_is_isolated():
    system, sim = _problem([1])
    quorum = drive(_fkf(system, detector="oracle", common_mode="keep", common_mode_quorum=2), sim)
    isolate = drive(_fkf(system, detector="oracle"), sim)
    assert_same(quorum, isolate, rtol=0.0)


def test_quorum_of_every_sensor_is_the_default():
    system, sim = _problem([0, 1, 2])
    every = drive(_fkf(system, detector="oracle", common_mode="keep"), sim)
    quorum = drive(_fkf(system, detector="oracle", common_mode="keep", common_mode_quorum=3), sim)
    assert_same(quorum, every, rtol=0.0)


@pytest.mark.parametrize(
    "kw",
    [
        {"common_mode_quorum": 2},
        {"common_mode": "keep", "common_mode_quorum": 1},
        {"common_mode": "keep", "common_mode_quorum": 4},
    ],
)
def test_quorum_out_of_range_is_refused(kw):
    system, _ = _problem([0])
    with pytest.raises(ValueError, match="common_mode_quorum"):
        _fkf(system, detector="oracle", **kw)
