"""The ``[[figures]]`` section: parsed into frozen FigureSpec values, bad entries named.

Every bad entry raises a one-line ScenarioError naming the field (``figures[i].key``);
the built-in scenarios' sections parse and name only their own methods.
"""

from __future__ import annotations

import copy
import sys
import tomllib
from pathlib import Path

import pytest

from ftnav.io.common import ScenarioError
from ftnav.io.scenario_file import load_scenario, parse_scenario, scenario_to_dict
from ftnav.model.scenario import MAX_FIGURE_METHODS, FigureSpec
from ftnav.scenarios import builtin_path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "cli"))
from output_problems import INTEGRATED, NORTH_RAMP  # noqa: E402


def _linear(*figures: dict):
    data = tomllib.loads(NORTH_RAMP)
    data["figures"] = list(figures)
    return parse_scenario(data)


def _integrated(*figures: dict):
    from ftnav.io.ins_scenario_file import parse_ins_scenario

    data = tomllib.loads(INTEGRATED)
    data["figures"] = list(figures)
    return parse_ins_scenario(data)


def test_a_figure_entry_becomes_a_frozen_spec():
    sc = _linear(
        {
            "name": "north",
            "title": "North",
            "methods": ["ckf", "fkf-oracle"],
            "states": ["N"],
            "condition": "fault-free",
        }
    )
    assert sc.figures == (
        FigureSpec("north", "North", ("ckf", "fkf-oracle"), ("N",), "errors", "fault-free", ""),
    )
    assert sc.without_faults().figures == sc.figures
    with pytest.raises(AttributeError):
        sc.figures[0].name = "x"
    d = scenario_to_dict(sc)
    assert parse_scenario(copy.deepcopy(d)).figures == sc.figures


def test_defaults_of_a_figure_entry():
    (spec,) = _linear({"name": "f", "methods": ["ckf"]}).figures
    assert (spec.title, spec.states, spec.kind, spec.condition, spec.sensor) == (
        "",
        (),
        "errors",
        "faults",
        "",
    )


BAD_LINEAR = [
    ({"name": "f", "methods": ["ckf", "nope"]}, r"figures\[0\]\.methods\[1\]: unknown method"),
    (
        {"name": "f", "methods": ["ckf", "fkf-equal", "fkf-trace", "fkf-inverse-trace", "dkf"]},
        rf"figures\[0\]\.methods: at most {MAX_FIGURE_METHODS} methods per figure",
    ),
    ({"name": "f", "methods": ["ckf", "ckf"]}, r"figures\[0\]\.methods\[1\]: duplicate method"),
    ({"name": "f", "methods": []}, r"figures\[0\]\.methods: must have at least 1"),
    (
        {"name": "f", "methods": ["ckf"], "states": ["U"]},
        r"figures\[0\]\.states\[0\]: unknown state 'U' \(known: E, N\)",
    ),
    (
        {"name": "f", "methods": ["ckf"], "kind": "local-fused"},
        r"figures\[0\]\.kind: kind 'local-fused' needs an integrated scenario",
    ),
    ({"name": "f", "methods": ["ckf"], "kind": "pie"}, r"figures\[0\]\.kind: unknown value"),
    (
        {"name": "f", "methods": ["ckf"], "condition": "later"},
        r"figures\[0\]\.condition: unknown value",
    ),
    ({"name": "a/b", "methods": ["ckf"]}, r"figures\[0\]\.name: must be a file name"),
    ({"name": "sharing", "methods": ["ckf"]}, r"figures\[0\]\.name: 'sharing' is reserved"),
    (
        {"name": "f", "methods": ["ckf"], "sensor": "gnss"},
        r"figures\[0\]\.sensor: only used with kind = 'vb-noise'",
    ),
    ({"name": "f", "methods": ["ckf"], "colour": "red"}, r"figures\[0\]\.colour: unknown key"),
    ({"methods": ["ckf"]}, r"figures\[0\]\.name: missing required key"),
]


@pytest.mark.parametrize(("entry", "message"), BAD_LINEAR)
def test_bad_linear_figure_entries_name_the_field(entry, message):
    with pytest.raises(ScenarioError, match=message):
        _linear(entry)


def test_duplicate_figure_names():
    with pytest.raises(ScenarioError, match=r"figures\[1\]\.name: duplicate figure name"):
        _linear({"name": "f", "methods": ["ckf"]}, {"name": "f", "methods": ["dkf"]})


def test_integrated_figure_kinds():
    sc = _integrated(
        {"name": "pos", "methods": ["ckf", "dkf-vb"], "states": ["pos_N_m", "pos_horizontal_m"]},
        {"name": "loc", "kind": "local-fused", "methods": ["fkf-chi2"], "states": ["pos_E_m"]},
        {"name": "vb", "kind": "vb-noise", "methods": ["dkf-vb"], "sensor": "gnss"},
    )
    assert [f.kind for f in sc.figures] == ["errors", "local-fused", "vb-noise"]
    assert sc.figures[0].states == ("pos_N_m", "pos_horizontal_m")


BAD_INTEGRATED = [
    (
        {"name": "f", "kind": "local-fused", "methods": ["fkf-chi2"], "states": ["vel_E_m_s"]},
        r"figures\[0\]\.states\[0\]: unknown state 'vel_E_m_s' \(known: pos_E_m, pos_N_m",
    ),
    (
        {"name": "f", "kind": "vb-noise", "methods": ["dkf-vb"]},
        r"figures\[0\]\.sensor: required with kind 'vb-noise'",
    ),
    (
        {"name": "f", "kind": "vb-noise", "methods": ["dkf-vb"], "sensor": "tan"},
        r"figures\[0\]\.sensor: unknown sensor 'tan'",
    ),
    (
        {"name": "f", "kind": "vb-noise", "methods": ["dkf-vb", "ckf"], "sensor": "gnss"},
        r"figures\[0\]\.methods\[1\]: method 'ckf' does not estimate the noise of 'gnss'",
    ),
    (
        {"name": "f", "kind": "vb-noise", "methods": ["dkf-vb"], "sensor": "ads"},
        r"figures\[0\]\.methods\[0\]: method 'dkf-vb' does not estimate the noise of 'ads'",
    ),
    (
        {
            "name": "f",
            "kind": "vb-noise",
            "methods": ["dkf-vb"],
            "sensor": "gnss",
            "states": ["pos_E_m"],
        },
        r"figures\[0\]\.states\[0\]: not used with kind 'vb-noise'",
    ),
    (
        {"name": "f", "methods": ["ckf"], "states": ["s"]},
        r"figures\[0\]\.states\[0\]: unknown state 's'",
    ),
]


@pytest.mark.parametrize(("entry", "message"), BAD_INTEGRATED)
def test_bad_integrated_figure_entries_name_the_field(entry, message):
    with pytest.raises(ScenarioError, match=message):
        _integrated(entry)


@pytest.mark.parametrize("name", ["seed000", "seed001", "seed002"])
def test_builtin_scenarios_name_their_paper_figures(name):
    sc = load_scenario(builtin_path(name))
    assert sc.figures, name
    methods = {m.name for m in sc.methods}
    for f in sc.figures:
        assert set(f.methods) <= methods and 1 <= len(f.methods) <= MAX_FIGURE_METHODS
        assert f.title
    titles = " ".join(f.title for f in sc.figures)
    assert f"Paper {name[-3:]}" in titles
