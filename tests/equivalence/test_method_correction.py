"""A method's own SINS correction (spec §8.5) and the neuron centre's local copies.

Oracles:

* equivalence — a method with ``correction = "output"`` in a feedback scenario is, bit
  for bit, that method in the same scenario with ``[filter] correction = "output"``; the
  other methods beside it keep their feedback results (lock-step rows are independent);
* equivalence to first order — measuring an aid at each local's own copy of the SINS
  output changes nothing for an aid linear in the error states: for GNSS (whose H varies
  with position only through the Earth radii) the neuron centre's solution with local
  copies equals the one measured at the free SINS to well below a metre, while for the
  terrain aid (slopes read at the copy) it does not.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ftnav.engine import navigation_model
from ftnav.engine.driver import iterate, method_feedback
from ftnav.fusion.config import OracleDetector
from ftnav.fusion.neural import NeuralConfig, NeuralFusion
from ftnav.fusion.registry import build, method_config
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path
from ftnav.sim.ins import simulate_ins

STEPS = 120


@pytest.fixture(scope="module")
def seed001():
    sc = load_scenario(builtin_path("seed001"), models=False)
    return dataclasses.replace(sc, steps=STEPS, faults=())


def _solutions(sc, methods, runs=2):
    system = sc.system()
    model = navigation_model(sc, system)
    filters = {m.name: build(system, m) for m in methods}
    sim = simulate_ins(sc, range(runs), 1)
    p = {m.name: [] for m in methods}
    for r in iterate(model, sim.stream, filters, sc.steps):
        for j, m in enumerate(methods):
            p[m.name].append(r.solution.p[j * runs : (j + 1) * runs])
    return {k: np.stack(v, 1) for k, v in p.items()}, filters, model


def test_a_methods_own_output_correction_is_the_scenarios(seed001):
    ckf = method_config("centralized", name="ckf")
    ckf_out = method_config("centralized", name="ckf", correction="output")
    fkf = method_config("federated", name="fkf", mode="no-reset")
    mixed, filters, model = _solutions(seed001, [ckf_out, fkf])
    assert list(method_feedback(model, list(filters.values()))) == [False, True]
    alone, _, _ = _solutions(dataclasses.replace(seed001, correction="output"), [ckf])
    np.testing.assert_array_equal(mixed["ckf"], alone["ckf"])
    fed, _, _ = _solutions(seed001, [fkf])
    np.testing.assert_array_equal(mixed["fkf"], fed["fkf"])


def _neural(sc, copies: bool):
    cfg = NeuralConfig(name="n", detector=OracleDetector(kind="oracle"), correction="output")
    system = sc.system()
    model = navigation_model(sc, system)
    filt = NeuralFusion(system, cfg, collect=True, untrained="inverse-variance")
    if not copies:
        filt.local_copies = False  # type: ignore[misc]  # measured at the free SINS
    sim = simulate_ins(sc, range(2), 1)
    return np.stack([r.solution.p for r in iterate(model, sim.stream, {"n": filt}, sc.steps)], 1)


def test_local_copies_change_nothing_for_gnss_but_the_terrain_slopes(seed001):
    R = 6.4e6
    gps = dataclasses.replace(seed001, aids=seed001.aids[:1])
    d = np.abs(_neural(gps, True) - _neural(gps, False)) * np.array([R, R, 1.0])
    assert d.max() < 0.5, d.max()
    tan = dataclasses.replace(seed001, aids=seed001.aids[1:2])
    d = np.abs(_neural(tan, True) - _neural(tan, False)) * np.array([R, R, 1.0])
    assert d.max() > 1.0, d.max()


def test_a_correction_on_a_linear_scenario_is_refused(tmp_path, capsys):
    from ftnav.cli import main

    src = builtin_path("seed000").read_text()
    text = src.replace('name = "ckf"\n', 'name = "ckf"\ncorrection = "output"\n', 1)
    assert text != src
    path = tmp_path / "s.toml"
    path.write_text(text.replace('profile = "', 'profile = "'))
    assert main(["run", str(path), "--runs", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "correction: only read by integrated scenarios and recordings" in err, err


def test_local_copies_follow_output_correction_set_by_the_method_or_the_scenario(seed001):
    """The neuron centre measures at its locals' copies whether its own ``correction`` or
    the scenario's ``[filter] correction`` asks for output correction (bit for bit)."""
    system = seed001.system()
    sim = simulate_ins(seed001, range(2), 1)

    def solution(sc, correction):
        cfg = NeuralConfig(name="n", detector=OracleDetector(kind="oracle"), correction=correction)
        filt = NeuralFusion(system, cfg, collect=True, untrained="inverse-variance")
        model = navigation_model(sc, system)
        return np.stack([r.solution.p for r in iterate(model, sim.stream, {"n": filt}, STEPS)])

    by_method = solution(seed001, "output")
    by_scenario = solution(dataclasses.replace(seed001, correction="output"), None)
    np.testing.assert_array_equal(by_scenario, by_method)
