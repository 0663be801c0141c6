"""No truth enters the engine (docs/architecture.md, "The engine").

Equivalence oracle: the engine's trace of a simulated stream is computed three times --
as simulated; with every array of the simulator's truth poisoned with NaN in place (so a
read of the truth anywhere, through any alias, would show); and from a stream rebuilt
from fresh copies of its own arrays after the simulator's output is dropped.  The
navigation solutions, estimates and covariances must be bit-identical.  The fault
labels are the stream's annotations, read only by the ``oracle`` detector: with them
cleared, every other method gives the same trace too.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from ftnav.engine import navigation_model
from ftnav.engine.driver import Trace, run
from ftnav.eval.montecarlo import build_filters
from ftnav.io.scenario_file import load_scenario
from ftnav.model.streams import AidStream, ImuStream, InsStream
from ftnav.nav.mechanization import InsState
from ftnav.scenarios import builtin_path
from ftnav.sim.ins import simulate_ins
from ftnav.sim.linear import simulate

STEPS = 40


def _arrays(obj: Any, out: list[np.ndarray]) -> list[np.ndarray]:
    """Every float array reachable through the NamedTuples of ``obj``."""
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind == "f":
            out.append(obj)
    elif isinstance(obj, tuple):
        for item in obj:
            _arrays(item, out)
    return out


def _poisoned(truth: Any) -> list[tuple[np.ndarray, np.ndarray, bool]]:
    """NaN into every float array of ``truth`` in place; what it takes to restore them."""
    saved = []
    for a in _arrays(truth, []):
        saved.append((a, a.copy(), a.flags.writeable))
        a.setflags(write=True)
        a[...] = np.nan
    return saved


def _restore(saved: list[tuple[np.ndarray, np.ndarray, bool]]) -> None:
    for a, copy, writeable in saved:
        a[...] = copy
        a.setflags(write=writeable)


def _same(a: dict[str, Trace], b: dict[str, Trace]) -> None:
    assert a.keys() == b.keys()
    for name in a:
        for field in ("x", "P_diag"):
            np.testing.assert_array_equal(getattr(a[name], field), getattr(b[name], field))
        if a[name].solution is not None:
            for u, v in zip(a[name].solution, b[name].solution, strict=True):
                np.testing.assert_array_equal(u, v)


def _traces(sc: Any, stream: Any, methods: Any = None) -> dict[str, Trace]:
    system = sc.system()
    methods = sc.methods if methods is None else methods
    return run(navigation_model(sc, system), stream, build_filters(sc, system, methods), STEPS)


def _fresh(stream: InsStream, labels: np.ndarray | None = None) -> InsStream:
    """The stream rebuilt from copies of its arrays: nothing shared with the simulator."""
    imu = stream.imu
    return InsStream(
        ImuStream(imu.t0, imu.dt, imu.t.copy(), imu.dtheta.copy(), imu.dv.copy()),
        tuple(AidStream(*(np.array(f, copy=True) for f in aid)) for aid in stream.aids),
        InsState(*(a.copy() for a in stream.start)),
        stream.labels.copy() if labels is None else labels,
    )


@pytest.fixture(scope="module")
def seed002():
    sc = load_scenario(builtin_path("seed002"))
    return replace(sc, steps=STEPS)


def test_integrated_solution_is_blind_to_the_truth(seed002):
    sim = simulate_ins(seed002, range(2), 7)
    before = _traces(seed002, sim.stream)
    assert any(t.solution is not None for t in before.values())
    saved = _poisoned(sim.truth)
    try:
        assert len(saved) >= 5 and all(np.isnan(a).all() for a, _, _ in saved)
        poisoned = _traces(seed002, sim.stream)
    finally:
        _restore(saved)
    _same(before, poisoned)
    rebuilt = _fresh(sim.stream)
    del sim
    _same(before, _traces(seed002, rebuilt))


def test_labels_reach_only_the_oracle_detector(seed002):
    sim = simulate_ins(seed002, range(2), 7)
    methods = [m for m in seed002.methods if getattr(m.detector, "kind", "none") != "oracle"]
    assert methods
    assert not sim.stream.labels.any()  # seed002's fault windows start after STEPS epochs
    flagged = _fresh(sim.stream, labels=np.ones_like(sim.stream.labels))
    _same(_traces(seed002, sim.stream, methods), _traces(seed002, flagged, methods))


def test_linear_estimates_are_blind_to_the_truth():
    sc = replace(load_scenario(builtin_path("seed000")), steps=STEPS)
    sim = simulate(sc, 3, 5)
    before = _traces(sc, sim.stream)
    saved = _poisoned(sim.truth)
    try:
        assert saved and all(np.isnan(a).all() for a, _, _ in saved)
        _same(before, _traces(sc, sim.stream))
    finally:
        _restore(saved)
