"""Scenario-file validation: every bad input gives one line naming the field."""

from __future__ import annotations

import copy
import json
import math
import pickle
from collections.abc import Callable
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel

from ftnav.fdi.rbf import RBFModel, RBFNetwork
from ftnav.fusion.centralized import CentralizedConfig
from ftnav.fusion.config import FixedNoise, RbfDetector, ResidualChi2, StateChi2, VbNoise
from ftnav.fusion.federated import FederatedConfig
from ftnav.fusion.neural_model import NeuronModel
from ftnav.fusion.registry import ARCHITECTURES
from ftnav.io.common import ScenarioError
from ftnav.io.learned import compatibility, save_neuron_model, save_rbf_model
from ftnav.io.scenario_file import (
    load_scenario,
    parse_scenario,
    scenario_json_schema,
    scenario_to_dict,
)
from ftnav.model.scenario import Scenario

NAN = float("nan")
INF = float("inf")


def base() -> dict[str, Any]:
    """A valid scenario dictionary (as tomllib would return it)."""
    return {
        "name": "example",
        "dt": 1.0,
        "steps": 1200,
        "model": {
            "states": ["s", "v", "a"],
            "F": [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]],
            "Q": [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]],
            "x0": [0.0, 0.0, 0.0],
            "P0": [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]],
        },
        "sensors": [
            {"name": "pos1", "H": [[1.0, 0.0, 0.0]], "R": [[30.0]], "every": 1},
            {"name": "pos2", "H": [[2.5, 0.0, 0.0]], "R": [[30.0]], "every": 1},
            {"name": "pos3", "H": [[0.5, 0.0, 0.0]], "R": [[30.0]], "every": 1},
        ],
        "faults": [
            {"sensor": "pos1", "kind": "bias", "start": 300.0, "end": 500.0, "magnitude": [60.0]},
        ],
        "methods": [
            {
                "name": "fkf-fault-factor",
                "architecture": "federated",
                "mode": "fusion-reset",
                "reset_interval": 1,
                "sharing": "inverse-trace",
                "detector": "residual-chi2",
            },
            {"name": "ckf", "architecture": "centralized"},
        ],
    }


def with_private() -> dict[str, Any]:
    d = base()
    d["sensors"][0]["private"] = {
        "states": ["b1"],
        "F": [[0.99]],
        "Q": [[0.01]],
        "x0": [0.0],
        "P0": [[1.0]],
        "H": [[1.0]],
    }
    return d


def _set(path: str, value: Any, make: Callable[[], dict] = base) -> Callable[[], dict]:
    """A mutation: set the dotted path (``sensors.1.R``) to ``value``."""

    def mutate() -> dict:
        d = make()
        *head, last = path.split(".")
        node: Any = d
        for key in head:
            node = node[int(key)] if key.isdigit() else node[key]
        node[int(last) if last.isdigit() else last] = value
        return d

    return mutate


def _del(path: str, make: Callable[[], dict] = base) -> Callable[[], dict]:
    def mutate() -> dict:
        d = make()
        *head, last = path.split(".")
        node: Any = d
        for key in head:
            node = node[int(key)] if key.isdigit() else node[key]
        del node[last]
        return d

    return mutate


def _add_method(**kw: Any) -> Callable[[], dict]:
    def mutate() -> dict:
        d = base()
        d["methods"].append({"name": "extra", **kw})
        return d

    return mutate


def _add_fault(**kw: Any) -> Callable[[], dict]:
    def mutate() -> dict:
        d = base()
        d["faults"].append(
            {"sensor": "pos2", "kind": "bias", "start": 10.0, "end": 20.0, "magnitude": [1.0], **kw}
        )
        return d

    return mutate


def _dup_sensor() -> dict:
    d = base()
    d["sensors"][2]["name"] = "pos1"
    return d


def _dup_method() -> dict:
    d = base()
    d["methods"][1]["name"] = "fkf-fault-factor"
    return d


#: each enumerated setting of a method (the settings that go with it) and its field path
ENUMS: dict[str, tuple[dict[str, Any], str]] = {
    "architecture": ({"architecture": "foo"}, "methods[2].architecture"),
    "mode": ({"mode": "foo"}, "methods[2].mode"),
    "sharing": ({"sharing": "foo"}, "methods[2].sharing"),
    "trace_mode": ({"sharing": "trace", "trace_mode": "foo"}, "methods[2].trace_mode"),
    "detector": ({"detector": {"kind": "foo"}}, "methods[2].detector.kind"),
    "prior": ({"detector": {"kind": "residual-chi2", "prior": "foo"}}, "methods[2].detector.prior"),
    "noise": ({"noise": {"kind": "foo"}}, "methods[2].noise.kind"),
    "increment": ({"architecture": "distributed", "increment": "foo"}, "methods[2].increment"),
}

BAD: list[tuple[str, Callable[[], dict], str]] = [
    # --- top level
    ("steps-zero", _set("steps", 0), r"^steps: "),
    ("steps-float", _set("steps", 10.5), r"^steps: expected an integer"),
    ("steps-bool", _set("steps", True), r"^steps: expected an integer"),
    ("dt-negative", _set("dt", -1.0), r"^dt: must be > 0"),
    ("dt-zero", _set("dt", 0.0), r"^dt: "),
    ("dt-nan", _set("dt", NAN), r"^dt: is NaN or inf"),
    ("dt-inf", _set("dt", INF), r"^dt: is NaN or inf"),
    ("dt-string", _set("dt", "1.0"), r"^dt: expected a number"),
    ("unknown-top-key", _set("bogus", 1), r"^bogus: unknown key$"),
    ("missing-name", _del("name"), r"^name: missing required key"),
    ("empty-name", _set("name", "  "), r"^name: "),
    ("missing-model", _del("model"), r"^model: missing required key"),
    ("no-sensors", _set("sensors", []), r"^sensors: must have at least 1 entry"),
    ("no-methods", _set("methods", []), r"^methods: must have at least 1 entry"),
    ("missing-methods", _del("methods"), r"^methods: missing required key"),
    ("sensors-not-array", _set("sensors", {"name": "x"}), r"^sensors: expected an array"),
    # --- model
    (
        "F-2x3",
        _set("model.F", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        r"^model\.F: expected a 3x3 matrix \(from model\.states\), got 2x3$",
    ),
    (
        "F-ragged",
        _set("model.F", [[1.0, 0.0, 0.0], [0.0, 1.0], [0.0, 0.0, 1.0]]),
        r"^model\.F: rows have different lengths",
    ),
    ("F-nan", _set("model.F.1.1", NAN), r"^model\.F: contains NaN or inf$"),
    ("F-inf", _set("model.F.0.2", -INF), r"^model\.F: contains NaN or inf$"),
    ("F-string-entry", _set("model.F.0.1", "x"), r"^model\.F\[0\]\[1\]: expected a number"),
    ("F-bool-entry", _set("model.F.0.1", True), r"^model\.F\[0\]\[1\]: expected a number"),
    ("F-vector", _set("model.F", [1.0, 2.0, 3.0]), r"^model\.F\[0\]: expected an array"),
    (
        "x0-length",
        _set("model.x0", [0.0, 0.0]),
        r"^model\.x0: expected 3 values \(from model\.states\), got 2$",
    ),
    ("x0-nan", _set("model.x0.0", NAN), r"^model\.x0: contains NaN or inf$"),
    ("Q-not-symmetric", _set("model.Q.0.1", 1.0), r"^model\.Q: not symmetric$"),
    (
        "Q-not-pd",
        _set("model.Q", [[1.0, 0, 0], [0, 0.0, 0], [0, 0, 1.0]]),
        r"^model\.Q: not positive definite$",
    ),
    ("Q-negative", _set("model.Q.2.2", -3.0), r"^model\.Q: not positive definite$"),
    (
        "Q-wrong-size",
        _set("model.Q", [[1.0, 0.0], [0.0, 1.0]]),
        r"^model\.Q: expected a 3x3 matrix",
    ),
    ("Q-inf", _set("model.Q.0.0", INF), r"^model\.Q: contains NaN or inf$"),
    (
        "P0-not-pd",
        _set("model.P0", [[1.0, 2.0, 0], [2.0, 1.0, 0], [0, 0, 1.0]]),
        r"^model\.P0: not positive definite$",
    ),
    ("P0-nan", _set("model.P0.2.2", NAN), r"^model\.P0: contains NaN or inf$"),
    (
        "Q_true-not-psd",
        _set("model.Q_true", [[1.0, 0, 0], [0, -1.0, 0], [0, 0, 1.0]]),
        r"^model\.Q_true: not positive semi-definite",
    ),
    (
        "Q_true-not-symmetric",
        _set("model.Q_true", [[1.0, 0.5, 0], [0, 1.0, 0], [0, 0, 1.0]]),
        r"^model\.Q_true: not symmetric$",
    ),
    (
        "states-duplicate",
        _set("model.states", ["s", "v", "s"]),
        r"^model\.states\[2\]: duplicate state name 's'$",
    ),
    ("states-empty-name", _set("model.states", ["s", "", "a"]), r"^model\.states\[1\]: "),
    ("states-empty", _set("model.states", []), r"^model\.states: must have at least 1"),
    ("model-unknown-key", _set("model.G", [[1.0]]), r"^model\.G: unknown key$"),
    # --- sensors
    (
        "H-columns",
        _set("sensors.1.H", [[1.0, 0.0]]),
        r"^sensors\[1\]\.H: expected 3 columns \(from model\.states\), got 1x2$",
    ),
    ("H-no-rows", _set("sensors.0.H", []), r"^sensors\[0\]\.H: expected at least one row$"),
    ("H-nan", _set("sensors.2.H", [[NAN, 0.0, 0.0]]), r"^sensors\[2\]\.H: contains NaN or inf$"),
    (
        "R-size",
        _set("sensors.0.R", [[30.0, 0.0], [0.0, 30.0]]),
        r"^sensors\[0\]\.R: expected a 1x1 matrix \(from sensors\[0\]\.H rows\), got 2x2$",
    ),
    ("R-not-pd", _set("sensors.1.R", [[0.0]]), r"^sensors\[1\]\.R: not positive definite$"),
    ("R-negative", _set("sensors.1.R", [[-30.0]]), r"^sensors\[1\]\.R: not positive definite$"),
    ("R-inf", _set("sensors.1.R", [[INF]]), r"^sensors\[1\]\.R: contains NaN or inf$"),
    (
        "R_true-not-pd",
        _set("sensors.2.R_true", [[-1.0]]),
        r"^sensors\[2\]\.R_true: not positive definite$",
    ),
    (
        "R_true-size",
        _set("sensors.2.R_true", [[1.0, 0.0]]),
        r"^sensors\[2\]\.R_true: expected a 1x1 matrix",
    ),
    ("every-zero", _set("sensors.0.every", 0), r"^sensors\[0\]\.every: must be >= 1"),
    ("offset-negative", _set("sensors.0.offset", -1), r"^sensors\[0\]\.offset: must be >= 0"),
    ("sensor-unknown-key", _set("sensors.1.bogus", 1), r"^sensors\[1\]\.bogus: unknown key$"),
    ("sensor-missing-R", _del("sensors.1.R"), r"^sensors\[1\]\.R: missing required key$"),
    ("sensor-duplicate", _dup_sensor, r"^sensors\[2\]\.name: duplicate sensor name 'pos1'$"),
    # --- private states
    (
        "private-F-shape",
        _set("sensors.0.private.F", [[0.99, 0.0]], with_private),
        r"^sensors\[0\]\.private\.F: expected a 1x1 matrix \(from sensors\[0\]\.private\.states\)",
    ),
    (
        "private-x0-length",
        _set("sensors.0.private.x0", [0.0, 1.0], with_private),
        r"^sensors\[0\]\.private\.x0: expected 1 value \(from sensors\[0\]\.private\.states\)",
    ),
    (
        "private-H-shape",
        _set("sensors.0.private.H", [[1.0], [1.0]], with_private),
        r"^sensors\[0\]\.private\.H: expected a 1x1 matrix \(from sensors\[0\]\.H rows",
    ),
    (
        "private-P0-not-pd",
        _set("sensors.0.private.P0", [[0.0]], with_private),
        r"^sensors\[0\]\.private\.P0: not positive definite$",
    ),
    (
        "private-Q-not-psd",
        _set("sensors.0.private.Q", [[-0.01]], with_private),
        r"^sensors\[0\]\.private\.Q: not positive semi-definite",
    ),
    (
        "private-state-clash",
        _set("sensors.0.private.states", ["v"], with_private),
        r"^sensors\[0\]\.private\.states\[0\]: 'v' is already a state of model\.states$",
    ),
    (
        "private-unknown-key",
        _set("sensors.0.private.G", [[1.0]], with_private),
        r"^sensors\[0\]\.private\.G: unknown key$",
    ),
    (
        "private-missing-H",
        _del("sensors.0.private.H", with_private),
        r"^sensors\[0\]\.private\.H: missing required key$",
    ),
    # --- faults
    (
        "fault-unknown-sensor",
        _set("faults.0.sensor", "pos9"),
        r"^faults\[0\]\.sensor: unknown sensor 'pos9' \(known: pos1, pos2, pos3\)$",
    ),
    (
        "fault-unknown-kind",
        _set("faults.0.kind", "drift"),
        r"^faults\[0\]\.kind: unknown value 'drift' \(expected one of: bias, ramp, noise-scale, "
        r"outage, stuck\)$",
    ),
    ("fault-negative-start", _set("faults.0.start", -1.0), r"^faults\[0\]\.start: must be >= 0"),
    (
        "fault-end-equal",
        _set("faults.0.end", 300.0),
        r"^faults\[0\]\.end: must be greater than start \(300\.0\)$",
    ),
    ("fault-end-before", _set("faults.0.end", 100.0), r"^faults\[0\]\.end: must be greater"),
    ("fault-end-inf", _set("faults.0.end", INF), r"^faults\[0\]\.end: is NaN or inf"),
    (
        "fault-magnitude-length",
        _set("faults.0.magnitude", [60.0, 1.0]),
        r"^faults\[0\]\.magnitude: expected 1 value \(from sensors\[0\]\.H rows\), got 2$",
    ),
    (
        "fault-magnitude-nan",
        _set("faults.0.magnitude", [NAN]),
        r"^faults\[0\]\.magnitude: contains NaN or inf$",
    ),
    (
        "fault-magnitude-missing",
        _del("faults.0.magnitude"),
        r"^faults\[0\]\.magnitude: required for kind 'bias'$",
    ),
    (
        "noise-scale-zero",
        _add_fault(kind="noise-scale", magnitude=[0.0]),
        r"^faults\[1\]\.magnitude: noise-scale factors must all be > 0$",
    ),
    (
        "noise-scale-negative",
        _add_fault(kind="noise-scale", magnitude=[-2.0]),
        r"^faults\[1\]\.magnitude: noise-scale",
    ),
    ("fault-unknown-key", _set("faults.0.sigma", 1.0), r"^faults\[0\]\.sigma: unknown key$"),
    # --- methods
    ("method-unknown-key", _set("methods.0.bogus", 1), r"^methods\[0\]\.bogus: unknown key$"),
    ("method-missing-name", _del("methods.1.name"), r"^methods\[1\]\.name: missing required"),
    (
        "method-duplicate",
        _dup_method,
        r"^methods\[1\]\.name: duplicate method name 'fkf-fault-factor'$",
    ),
    (
        "sharing-foo",
        _add_method(sharing="foo"),
        r"^methods\[2\]\.sharing: unknown value 'foo' \(expected one of: equal, fixed, "
        r"information, trace, eigen-trace, frobenius, inverse-trace\)$",
    ),
    *[
        (
            f"enum-{key}",
            _add_method(**settings),
            "^"
            + path.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")
            + r": unknown value 'foo' \(expected one of: ",
        )
        for key, (settings, path) in ENUMS.items()
    ],
    (
        "enum-not-string",
        _add_method(detector={"kind": 3}),
        r"^methods\[2\]\.detector\.kind: unknown value",
    ),
    (
        "rbf-without-model",
        _add_method(detector="rbf"),
        r"^methods\[2\]\.detector\.model: missing required key$",
    ),
    (
        "neural-without-model",
        _add_method(architecture="neural"),
        r"^methods\[2\]\.model: architecture 'neural' needs a trained model file "
        r"\(ftnav train-fusion\)$",
    ),
    (
        # a federated method has no model setting (the typed configuration refuses it)
        "model-unused",
        _add_method(model="x.npz"),
        r"^methods\[2\]\.model: not a setting of the federated architecture "
        r"\(a setting of neural\)$",
    ),
    (
        "threshold-above-1",
        _add_method(detector={"kind": "rbf", "model": "x.npz", "threshold": 1.5}),
        r"^methods\[2\]\.detector\.threshold: ",
    ),
    (
        "fixed-betas-count",
        _add_method(sharing="fixed", betas=[0.5, 0.5]),
        r"^methods\[2\]\.betas: expected 3 values \(one per sensor\)",
    ),
    (
        "fixed-betas-sum",
        _add_method(sharing="fixed", betas=[0.5, 0.3, 0.1]),
        r"^methods\[2\]\.betas: sum\(betas\) \+ master_share must equal 1",
    ),
    (
        "fixed-betas-sum-master",
        _add_method(sharing="fixed", betas=[0.5, 0.3, 0.2], master_share=0.1),
        r"^methods\[2\]\.betas: sum\(betas\) \+ master_share must equal 1",
    ),
    (
        "betas-negative",
        _add_method(sharing="fixed", betas=[1.5, -0.5, 0.0]),
        r"^methods\[2\]\.betas\[1\]: must be >= 0",
    ),
    (
        # betas are a setting of the fixed rule only: the typed configuration refuses them
        "betas-without-fixed",
        _add_method(sharing="equal", betas=[0.5, 0.3, 0.2]),
        r"^methods\[2\]\.betas: only read with sharing = 'fixed' \(sharing is 'equal'\)$",
    ),
    ("master-share-one", _add_method(master_share=1.0), r"^methods\[2\]\.master_share: must be <"),
    (
        "rescale-not-reconstructed",
        _add_method(architecture="distributed", mode="rescale"),
        r"^methods\[2\]\.mode: 'rescale' is a reconstruction \(spec §1\.5\); "
        r"set reconstructed = true to use it$",
    ),
    (
        "pfa-zero",
        _add_method(detector={"kind": "residual-chi2", "false_alarm_probability": 0.0}),
        r"^methods\[2\]\.detector\.false_alarm_probability: must be > 0",
    ),
    (
        "pfa-one",
        _add_method(detector={"kind": "residual-chi2", "false_alarm_probability": 1.0}),
        r"^methods\[2\]\.detector\.false_alarm_probability: must be < 1",
    ),
    (
        "pfa-nan",
        _add_method(detector={"kind": "residual-chi2", "false_alarm_probability": NAN}),
        r"^methods\[2\]\.detector\.false_alarm_probability: is NaN or inf",
    ),
    (
        "window-zero",
        _add_method(detector={"kind": "residual-chi2", "window": 0}),
        r"^methods\[2\]\.detector\.window: must be >= 1",
    ),
    (
        "quorum-without-keep",
        _add_method(common_mode_quorum=2),
        r"^methods\[2\]\.common_mode_quorum: only read with common_mode = 'keep'",
    ),
    (
        "quorum-one",
        _add_method(common_mode="keep", common_mode_quorum=1),
        r"^methods\[2\]\.common_mode_quorum: must be >= 2",
    ),
    (
        "quorum-above-sensors",
        _add_method(common_mode="keep", common_mode_quorum=4),
        r"^methods\[2\]\.common_mode_quorum: must be <= the number of sensors \(3\)",
    ),
    (
        "intersection-not-neural",
        _add_method(detector={"kind": "residual-chi2", "prior": "intersection"}),
        r"^methods\[2\]\.detector\.prior: 'intersection' is not available with the "
        r"federated architecture \(expected one of \['local', 'global'\]\)$",
    ),
    (
        "prior-unknown",
        _add_method(detector={"kind": "residual-chi2", "prior": "fused"}),
        r"^methods\[2\]\.detector\.prior: ",
    ),
    ("reset-interval-zero", _add_method(reset_interval=0), r"^methods\[2\]\.reset_interval: "),
    (
        "n_on-zero",
        _add_method(detector={"kind": "residual-chi2", "n_on": 0}),
        r"^methods\[2\]\.detector\.n_on: must be >= 1",
    ),
    (
        "n_off-zero",
        _add_method(detector={"kind": "residual-chi2", "n_off": 0}),
        r"^methods\[2\]\.detector\.n_off: must be >= 1",
    ),
    (
        "state-test-reset-small",
        _add_method(detector={"kind": "state-chi2", "reset": 4}),
        r"^methods\[2\]\.detector\.reset: must be >= 5",
    ),
    (
        "vb-rho-zero",
        _add_method(noise={"kind": "vb", "rho": 0.0}),
        r"^methods\[2\]\.noise\.rho: must be > 0",
    ),
    (
        "vb-rho-big",
        _add_method(noise={"kind": "vb", "rho": 1.5}),
        r"^methods\[2\]\.noise\.rho: must be <= 1",
    ),
    (
        "vb-iterations-zero",
        _add_method(noise={"kind": "vb", "iterations": 0}),
        r"^methods\[2\]\.noise\.iterations: ",
    ),
    (
        "vb-sensors-unknown",
        _add_method(noise={"kind": "vb", "sensors": ["pos1", "gps"]}),
        r"^methods\[2\]\.noise\.sensors\[1\]: unknown sensor 'gps' \(known: pos1, pos2, pos3\)$",
    ),
    (
        "vb-sensors-duplicate",
        _add_method(noise={"kind": "vb", "sensors": ["pos1", "pos1"]}),
        r"^methods\[2\]\.noise\.sensors\[1\]: duplicate sensor 'pos1'$",
    ),
    (
        "rescale-factor-one",
        _add_method(
            architecture="distributed", mode="rescale", reconstructed=True, rescale_factor=1.0
        ),
        r"^methods\[2\]\.rescale_factor: must be < 1",
    ),
    (
        "reconstructed-not-bool",
        _add_method(architecture="distributed", mode="rescale", reconstructed="yes"),
        r"^methods\[2\]\.reconstructed: expected true or false",
    ),
    (
        "method-model-not-string",
        _add_method(architecture="neural", model=3),
        r"^methods\[2\]\.model: expected a string",
    ),
    # --- evaluation
    (
        "skip-initial-too-long",
        _set("evaluation", {"skip_initial": 1200.0}),
        r"^evaluation\.skip_initial: must be less than dt\*steps",
    ),
    (
        "skip-initial-negative",
        _set("evaluation", {"skip_initial": -1.0}),
        r"^evaluation\.skip_initial: must be >= 0",
    ),
    ("grace-negative", _set("evaluation", {"grace": -1.0}), r"^evaluation\.grace: must be >= 0"),
    (
        "evaluation-unknown-key",
        _set("evaluation", {"warmup": 1.0}),
        r"^evaluation\.warmup: unknown key$",
    ),
]


@pytest.mark.parametrize(("mutate", "pattern"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_invalid_scenarios_name_the_field(mutate: Callable[[], dict], pattern: str) -> None:
    with pytest.raises(ScenarioError, match=pattern) as info:
        parse_scenario(mutate())
    message = str(info.value)
    assert "\n" not in message and "\r" not in message
    assert message == f"{info.value.path}: {info.value.reason}"


def test_mutation_table_does_not_touch_base() -> None:
    assert base() == base()
    parse_scenario(base())
    parse_scenario(with_private())


def test_top_level_not_a_table() -> None:
    with pytest.raises(ScenarioError, match=r"^here\.toml: expected a table"):
        parse_scenario([1, 2], origin="here.toml")  # type: ignore[arg-type]


def test_newline_in_user_text_never_reaches_the_message() -> None:
    d = base()
    d["faults"][0]["sensor"] = "pos\n9"
    d["methods"][0]["sharing"] = "a\nb"
    with pytest.raises(ScenarioError) as info:
        parse_scenario(d)
    assert "\n" not in str(info.value)
    d = base()
    d["bad\nkey"] = 1
    with pytest.raises(ScenarioError) as info:
        parse_scenario(d)
    assert "\n" not in str(info.value)


def test_error_is_a_value_error_and_picklable() -> None:
    with pytest.raises(ValueError) as info:
        parse_scenario(_set("model.Q.0.1", 1.0)())
    again = pickle.loads(pickle.dumps(info.value))
    assert isinstance(again, ScenarioError)
    assert str(again) == str(info.value) == "model.Q: not symmetric"


# ------------------------------------------------------------------ valid inputs


def test_base_parses_with_arrays_and_defaults() -> None:
    sc = parse_scenario(base())
    assert isinstance(sc, Scenario)
    assert sc.name == "example" and sc.description == "" and sc.dt == 1.0 and sc.steps == 1200
    m = sc.model
    assert m.states == ("s", "v", "a") and m.n == 3
    for a, shape in [
        (m.F, (3, 3)),
        (m.Q, (3, 3)),
        (m.x0, (3,)),
        (m.P0, (3, 3)),
        (m.Q_true, (3, 3)),
    ]:
        assert a.dtype == np.float64 and a.shape == shape
        assert not a.flags.writeable
    np.testing.assert_array_equal(m.F[0], [1.0, 0.05, 0.00125])
    np.testing.assert_array_equal(m.Q_true, m.Q)  # default Q_true = Q
    assert sc.sensor_names == ("pos1", "pos2", "pos3")
    for s, h in zip(sc.sensors, (1.0, 2.5, 0.5), strict=True):
        assert s.H.shape == (1, 3) and s.H[0, 0] == h and s.dim == 1
        assert s.R.shape == (1, 1) and s.R[0, 0] == 30.0
        np.testing.assert_array_equal(s.R_true, s.R)
        assert s.every == 1 and s.offset == 0 and s.private is None
    (f,) = sc.faults
    assert (f.sensor, f.kind, f.start, f.end) == ("pos1", "bias", 300.0, 500.0)
    assert f.magnitude.shape == (1,) and f.magnitude[0] == 60.0
    m0, m1 = sc.methods
    assert (m0.name, m0.sharing, m0.detector.kind) == (
        "fkf-fault-factor",
        "inverse-trace",
        "residual-chi2",
    )
    # every key not given takes the configuration's default
    assert isinstance(m0, FederatedConfig) and isinstance(m1, CentralizedConfig)
    assert m0.detector == ResidualChi2(kind="residual-chi2")
    default = CentralizedConfig(name="ckf")
    for name in CentralizedConfig.model_fields:
        assert getattr(m1, name) == getattr(default, name), name
    assert m0.betas == () and m1.noise == FixedNoise() and m1.model_file is None
    assert sc.evaluation.skip_initial == 0.0 and sc.evaluation.grace == 10.0


def _detector_file(d: dict, path: Path) -> Path:
    """A small RBF detector model file for the system of ``d`` (the scenario loads it)."""
    system = parse_scenario(d).system()
    rng = np.random.default_rng(0)
    N = system.n_sensors
    net = RBFNetwork(n_centres=2, n_init=1, kmeans_samples=2, random_state=0)
    net.fit(rng.normal(size=(8, N)), (rng.random((8, N)) > 0.5).astype(float))
    model = RBFModel(
        net, ("innovation",), "local", np.full(N, 0.5), 1, 5, compatibility(system), {}
    )
    return save_rbf_model(model, path)


def _fusion_file(d: dict, path: Path) -> Path:
    """A neuron fusion model file (healthy and pos1-faulty banks) for the system of ``d``."""
    sc = parse_scenario(d)
    system = sc.system()
    N, n = system.n_sensors, len(sc.model.states)
    patterns = np.zeros((2, N), dtype=bool)
    patterns[1, 0] = True
    model = NeuronModel(
        ("healthy", "pos1"),
        patterns,
        sc.sensor_names,
        sc.model.states,
        np.full((2, n, N), 1.0 / N),
        np.zeros((2, n)),
        compatibility(system),
        {},
    )
    return save_neuron_model(model, path)


def test_optional_parts_parse(tmp_path) -> None:
    d = with_private()
    d["description"] = "with everything"
    d["model"]["Q_true"] = [[1.0, 0, 0], [0, 0.0, 0], [0, 0, 0.0]]  # PSD is enough
    d["sensors"][1].update(R_true=[[60.0]], every=5, offset=2)
    d["faults"] += [
        {"sensor": "pos2", "kind": "outage", "start": 10.0, "end": 20.0},
        {"sensor": "pos3", "kind": "noise-scale", "start": 10, "end": 2000.0, "magnitude": [3.0]},
    ]
    # the distributed and the federated settings are settings of two methods now
    d["methods"].append(
        {
            "name": "everything",
            "architecture": "distributed",
            "mode": "rescale",
            "reconstructed": True,
            "detector": {"kind": "state-chi2"},
            "noise": {"kind": "vb-literal", "sensors": ["pos2"], "rho": 1.0},
            "increment": "difference",
            "rescale_factor": 0.0,
        }
    )
    d["methods"].append(
        {
            "name": "everything-federated",
            "architecture": "federated",
            "sharing": "fixed",
            "betas": [0.5, 0.25, 0.15],
            "master_share": 0.1,
            "detector": {"kind": "residual-chi2", "prior": "global"},
        }
    )
    d["methods"].append(
        {"name": "raw-trace", "architecture": "federated", "sharing": "trace", "trace_mode": "raw"}
    )
    d["evaluation"] = {"skip_initial": 50.0, "grace": 0.0}
    _detector_file(d, tmp_path / "detector.npz")
    d["methods"].append(
        {
            "name": "learned",
            "detector": {"kind": "rbf", "model": "detector.npz", "threshold": 0.6},
        }
    )
    # a fault starting after the run is refused (issue 13 point 10)
    late = copy.deepcopy(d)
    late["faults"].append({"sensor": "pos3", "kind": "stuck", "start": 5000.0, "end": 6000.0})
    with pytest.raises(ScenarioError, match=r"^faults\[3\]\.start: ") as info:
        parse_scenario(late, base=tmp_path)
    assert "\n" not in str(info.value)
    sc = parse_scenario(d, base=tmp_path)
    p = sc.sensors[0].private
    assert p is not None and p.names == ("b1",)
    assert p.F.shape == p.Q.shape == p.P0.shape == p.H.shape == (1, 1) and p.x0.shape == (1,)
    assert sc.sensors[1].R_true[0, 0] == 60.0 and sc.sensors[1].every == 5
    outage, noise = sc.faults[1:]
    np.testing.assert_array_equal(outage.magnitude, [0.0])
    assert noise.start == 10.0 and isinstance(noise.start, float)
    me, fed, raw = sc.methods[-4:-1]
    assert fed.betas == (0.5, 0.25, 0.15) and me.noise.sensors == ("pos2",)
    assert fed.master_share == 0.1 and fed.detector.prior == "global"
    assert raw.trace_mode == "raw" and me.detector.kind == "state-chi2"
    assert me.noise.kind == "vb-literal" and me.noise.rho == 1.0
    assert me.increment == "difference" and me.rescale_factor == 0.0
    assert me.reconstructed and me.mode == "rescale" and me.model_file is None
    learned = sc.methods[-1]
    assert learned.detector.model == "detector.npz" and learned.detector.threshold == 0.6
    assert sc.evaluation.skip_initial == 50.0 and sc.description == "with everything"


def test_multi_row_sensor_and_nearly_symmetric_matrix() -> None:
    d = base()
    d["sensors"].append(
        {"name": "pv", "H": [[1.0, 0, 0], [0, 1.0, 0]], "R": [[4.0, 1.0], [1.0 + 1e-12, 9.0]]}
    )
    d["faults"].append(
        {"sensor": "pv", "kind": "ramp", "start": 0.0, "end": 1.0, "magnitude": [1.0, -1.0]}
    )
    sc = parse_scenario(d)
    R = sc.sensors[-1].R
    assert R.shape == (2, 2) and np.array_equal(R, R.T)
    assert sc.faults[-1].magnitude.shape == (2,)


def _assert_same(a: Any, b: Any, where: str = "scenario") -> None:
    """Field-by-field equality of the frozen dataclasses (arrays compared exactly)."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.shape == b.shape and a.dtype == b.dtype, where
        np.testing.assert_array_equal(a, b, err_msg=where)
    elif hasattr(a, "__dataclass_fields__"):
        assert type(a) is type(b), where
        for fl in fields(a):
            _assert_same(getattr(a, fl.name), getattr(b, fl.name), f"{where}.{fl.name}")
    elif isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{where}[{i}]")
    else:
        assert type(a) is type(b) and a == b, where


@pytest.mark.parametrize("make", [base, with_private], ids=["base", "private"])
def test_round_trip(make: Callable[[], dict]) -> None:
    sc = parse_scenario(make())
    d = scenario_to_dict(sc)
    assert json.loads(json.dumps(d)) == d  # plain JSON types only
    again = parse_scenario(copy.deepcopy(d))
    _assert_same(sc, again)
    assert scenario_to_dict(again) == d
    # an unset optional setting is left out (no TOML null)
    assert "common_mode_quorum" not in d["methods"][0]


def test_round_trip_all_options(tmp_path) -> None:
    d = with_private()
    d["methods"].append(
        {
            "name": "x",
            "sharing": "fixed",
            "betas": [0.2, 0.3, 0.5],
            "noise": {"kind": "vb", "sensors": ["pos1"]},
        }
    )
    d["methods"].append(
        {
            "name": "quorum",
            "detector": "residual-chi2",
            "common_mode": "keep",
            "common_mode_quorum": 2,
        }
    )
    d["model"]["Q_true"] = [[2.0, 0, 0], [0, 0.0, 0], [0, 0, 0.0]]
    _fusion_file(d, tmp_path / "m.npz")
    d["methods"].append(
        {
            "name": "learned",
            "architecture": "neural",
            "model": "m.npz",
            "uncovered": "pos1",
            "detector": {"kind": "residual-chi2", "prior": "intersection"},
        }
    )
    sc = parse_scenario(d, base=tmp_path)
    _assert_same(sc, parse_scenario(scenario_to_dict(sc), base=tmp_path))


# ---------------------------------------------------------------------- files

EXAMPLE_TOML = """
name = "example"
description = ""
dt = 1.0
steps = 1200

[model]
states = ["s", "v", "a"]
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]

[[sensors]]
name = "pos1"
H = [[1.0, 0.0, 0.0]]
R = [[30.0]]

[sensors.private]
states = ["b1"]
F = [[0.99]]
Q = [[0.01]]
x0 = [0.0]
P0 = [[1.0]]
H = [[1.0]]

[[sensors]]
name = "pos2"
H = [[2.5, 0, 0]]
R = [[30]]
every = 2
offset = 1

[[faults]]
sensor = "pos1"
kind = "bias"
start = 300.0
end = 500.0
magnitude = [60.0]

[[methods]]
name = "fkf-fault-factor"
sharing = "inverse-trace"
detector = { kind = "residual-chi2" }

[evaluation]
skip_initial = 10.0
"""


def test_load_scenario_from_file(tmp_path) -> None:
    path = tmp_path / "scenario.toml"
    path.write_text(EXAMPLE_TOML, encoding="utf-8")
    for source in (path, str(path)):
        sc = load_scenario(source)
        assert sc.sensor_names == ("pos1", "pos2")
        assert sc.sensors[0].private is not None
        assert sc.sensors[1].H.dtype == np.float64 and sc.sensors[1].every == 2
        assert sc.evaluation.skip_initial == 10.0


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ("dt = nan", r"^dt: is NaN or inf"),
        ("dt = inf", r"^dt: is NaN or inf"),
        ("[model]\nx0 = [0.0, nan, 0.0]", r"^model\.x0: contains NaN or inf$"),
        ("[model]\nQ = [[5.0, 0, 0], [0, -inf, 0], [0, 0, 3.0]]", r"^model\.Q: contains NaN"),
    ],
    ids=["dt-nan", "dt-inf", "x0-nan", "Q-inf"],
)
def test_toml_nan_and_inf_literals(tmp_path, text: str, pattern: str) -> None:
    # keys after a table header override; rebuild the document with the bad key replaced
    doc = EXAMPLE_TOML
    key, _, value = text.splitlines()[-1].partition(" = ")
    lines = doc.splitlines()
    section = "" if "\n" not in text else text.splitlines()[0]
    in_section = section == ""
    for i, line in enumerate(lines):
        if line.startswith("["):
            in_section = line == section
        if in_section and line.split("=")[0].strip() == key:
            lines[i] = f"{key} = {value}"
            break
    else:
        raise AssertionError("key not found")
    path = tmp_path / "bad.toml"
    path.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(ScenarioError, match=pattern) as info:
        load_scenario(path)
    assert "\n" not in str(info.value)
    assert info.value.origin == str(path)


def test_toml_syntax_error_names_file_and_line(tmp_path) -> None:
    path = tmp_path / "scenario.toml"
    path.write_text('name = "x"\ndt = 1.0\nsteps = = 3\n', encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert message.startswith(f"{path}: TOML syntax error at line 3, column ")
    assert "\n" not in message


def test_toml_syntax_error_at_end_of_document(tmp_path) -> None:
    path = tmp_path / "cut.toml"
    path.write_text('name = "x"\nsteps = [1,', encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"cut\.toml: TOML syntax error") as info:
        load_scenario(path)
    assert "\n" not in str(info.value)


def test_missing_file_names_file(tmp_path) -> None:
    path = tmp_path / "nope.toml"
    with pytest.raises(ScenarioError, match=r"nope\.toml: file not found$") as info:
        load_scenario(path)
    assert "\n" not in str(info.value)


def test_directory_and_binary_files(tmp_path) -> None:
    with pytest.raises(ScenarioError, match=r"is a folder, not a file"):
        load_scenario(tmp_path)
    path = tmp_path / "binary.toml"
    path.write_bytes(b'name = "\xff\xfe"\n')
    with pytest.raises(ScenarioError, match=r"binary\.toml: not valid UTF-8"):
        load_scenario(path)


def test_validation_error_from_file_keeps_field_path(tmp_path) -> None:
    path = tmp_path / "scenario.toml"
    path.write_text(EXAMPLE_TOML.replace('kind = "bias"', 'kind = "glitch"'), encoding="utf-8")
    with pytest.raises(ScenarioError, match=r"^faults\[0\]\.kind: unknown value 'glitch'"):
        load_scenario(path)


# --------------------------------------------------------------------- schema


def test_json_schema() -> None:
    schema = scenario_json_schema()
    assert isinstance(schema, dict)
    assert schema["oneOf"] == [
        {"$ref": "#/$defs/ScenarioFile"},
        {"$ref": "#/$defs/InsScenarioFile"},
    ]
    linear = schema["$defs"]["ScenarioFile"]
    props = linear["properties"]
    for key in ("name", "dt", "steps", "model", "sensors", "faults", "methods", "evaluation"):
        assert key in props, key
    assert linear.get("additionalProperties") is False
    assert "kind" not in props  # a linear file has no kind: the branches cannot overlap
    text = json.dumps(schema)
    assert "inverse-trace" in text and "noise-scale" in text
    assert json.loads(text) == schema
    assert set(linear["required"]) >= {"name", "dt", "steps", "model", "sensors", "methods"}
    model = schema["$defs"]["ModelFile"]
    assert {"F", "Q", "F_c", "Q_c", "Q_c_true"} <= set(model["properties"])


def test_json_schema_covers_integrated_files() -> None:
    schema = scenario_json_schema()
    ins = schema["$defs"]["InsScenarioFile"]
    assert ins["properties"]["kind"]["const"] == "integrated"
    assert set(ins["required"]) >= {"kind", "name", "profile", "filter", "aids"}
    assert ins.get("additionalProperties") is False
    for key in ("filter", "aids", "faults", "methods", "terrain", "imu"):
        assert key in ins["properties"], key
    # both kinds share the method table (one configuration per architecture)
    items = schema["$defs"]["ScenarioFile"]["properties"]["methods"]["items"]
    assert ins["properties"]["methods"]["items"] == items
    assert items["oneOf"] == [
        {"$ref": f"#/$defs/{entry.config.__name__}"} for entry in ARCHITECTURES.values()
    ]
    text = json.dumps(schema)
    assert "gyro-bias" in text and "duration_s" in text


def test_method_defaults_match_dataclass() -> None:
    """The file format's method defaults are the defaults of each architecture's
    configuration (and of the detector and noise settings)."""
    schema = scenario_json_schema()
    models = [entry.config for entry in ARCHITECTURES.values()]
    models += [ResidualChi2, StateChi2, RbfDetector, VbNoise]
    for model in models:
        props = schema["$defs"][model.__name__]["properties"]
        for name, fl in model.model_fields.items():
            if fl.is_required():
                continue
            default = props[name].get("default")
            expected = fl.default
            if isinstance(expected, BaseModel):
                expected = expected.model_dump()
            if isinstance(expected, tuple):
                expected = list(expected)
            assert default == expected or (
                isinstance(default, float) and math.isclose(default, expected)
            ), f"{model.__name__}.{name}"


def test_documented_example_is_valid(tmp_path) -> None:
    """The full example in docs/scenario-format.md parses (keeps the docs honest)."""
    from pathlib import Path

    doc = Path(__file__).resolve().parents[2] / "docs" / "scenario-format.md"
    if not doc.exists():
        pytest.skip("docs not available")
    text = doc.read_text(encoding="utf-8")
    example = text.split("## Full example")[1].split("```toml\n")[1].split("```")[0]
    path = tmp_path / "example.toml"
    path.write_text(example, encoding="utf-8")
    sc = load_scenario(path)
    assert sc.sensor_names == ("pos1", "pos2", "pos3")
    assert [m.name for m in sc.methods] == ["fkf-fault-factor", "fkf-fixed", "ckf"]
    assert sc.sensors[0].private is not None and sc.methods[1].betas == (0.2, 0.6, 0.2)


# ------------------------------------------------------- continuous-time model (F_c, Q_c)


def continuous() -> dict[str, Any]:
    """base() with the double integrator in continuous time instead of F and Q."""
    d = base()
    m = d["model"]
    del m["F"], m["Q"]
    m["states"], m["x0"] = ["s", "v"], [0.0, 0.0]
    m["P0"] = [[100.0, 0.0], [0.0, 100.0]]
    m["F_c"] = [[0.0, 1.0], [0.0, 0.0]]
    m["Q_c"] = [[0.0, 0.0], [0.0, 2.0]]
    for sensor in d["sensors"]:
        sensor["H"] = [sensor["H"][0][:2]]
    return d


CONTINUOUS_BAD: list[tuple[str, Callable[[], dict], str]] = [
    (
        "F-and-F_c",
        _set("model.F", [[1.0, 1.0], [0.0, 1.0]], continuous),
        r"^model\.F: not used with F_c and Q_c .*give either F or F_c$",
    ),
    (
        "Q-and-Q_c",
        _set("model.Q", [[1.0, 0.0], [0.0, 1.0]], continuous),
        r"^model\.Q: not used with F_c and Q_c .*give either Q or Q_c$",
    ),
    (
        "F_c-without-Q_c",
        _del("model.Q_c", continuous),
        r"^model\.Q_c: missing required key \(F_c makes a continuous-time model\)$",
    ),
    (
        "Q_c-without-F_c",
        _del("model.F_c", continuous),
        r"^model\.F_c: missing required key \(Q_c makes a continuous-time model\)$",
    ),
    (
        "neither-F-nor-F_c",
        _del("model.F"),
        r"^model\.F: missing required key \(or F_c and Q_c for a continuous-time model\)$",
    ),
    (
        "Q_c_true-with-F",
        _set("model.Q_c_true", [[1.0, 0.0, 0.0]] * 3),
        r"^model\.Q_c_true: only used with F_c and Q_c",
    ),
    (
        "Q_true-and-Q_c_true",
        _set(
            "model.Q_c_true",
            [[0.0, 0.0], [0.0, 1.0]],
            lambda: _set("model.Q_true", [[1.0, 0.0], [0.0, 1.0]], continuous)(),
        ),
        r"^model\.Q_c_true: give either Q_true \(discrete\) or Q_c_true",
    ),
    (
        "Q_c-not-psd",
        _set("model.Q_c", [[0.0, 0.0], [0.0, -2.0]], continuous),
        r"^model\.Q_c: not positive semi-definite",
    ),
    (
        "Q_c-shape",
        _set("model.Q_c", [[2.0]], continuous),
        r"^model\.Q_c: expected a 2x2 matrix \(from model.states\), got 1x1$",
    ),
    (
        "Q_c-nan",
        _set("model.Q_c", [[0.0, 0.0], [0.0, NAN]], continuous),
        r"^model\.Q_c: contains NaN or inf$",
    ),
    (
        "F_c-string",
        _set("model.F_c", [[0.0, "x"], [0.0, 0.0]], continuous),
        r"^model\.F_c\[0\]\[1\]: expected a number",
    ),
    (
        "Q_c-reaches-no-state",
        _set("model.Q_c", [[0.0, 0.0], [0.0, 0.0]], continuous),
        r"^model\.Q_c: its discrete Q over dt = 1.0 s is not positive definite",
    ),
    (
        "F_c-overflows",
        _set("model.F_c", [[1e6, 0.0], [0.0, 0.0]], continuous),
        r"^model\.F_c: the discretization over dt = 1.0 s overflows",
    ),
]


@pytest.mark.parametrize(
    ("mutate", "pattern"), [b[1:] for b in CONTINUOUS_BAD], ids=[b[0] for b in CONTINUOUS_BAD]
)
def test_invalid_continuous_models_name_the_field(mutate, pattern) -> None:
    with pytest.raises(ScenarioError, match=pattern) as info:
        parse_scenario(mutate())
    assert "\n" not in str(info.value)


def test_continuous_model_round_trips_as_its_discrete_form() -> None:
    sc = parse_scenario(continuous())
    again = parse_scenario(scenario_to_dict(sc))
    np.testing.assert_array_equal(again.model.F, sc.model.F)
    np.testing.assert_array_equal(again.model.Q, sc.model.Q)
    np.testing.assert_array_equal(sc.model.Q_true, sc.model.Q)  # default: Q_c
    assert not sc.model.F.flags.writeable and not sc.model.Q.flags.writeable
