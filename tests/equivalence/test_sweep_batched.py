"""A sweep over fault and method settings runs its points in one batch (issue 23 item 3).

Oracle: each point's own campaign (:func:`ftnav.eval.montecarlo.run_scenario`, the
same scenario, runs and seed).  Runs are independent rows of one batch, so every
per-run, per-epoch array of every method, with and without the faults, must be equal
bit for bit, on a linear model (seed000) and an integrated one (seed002, shortened),
and with a point that has no fault (it gets no twin, as alone).  A sweep of method
settings runs the union of the points' methods once (each method is its own rows of
the batch, whatever runs beside it): each point's metrics must equal its campaign's.
"""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import (
    RESULT_FIELDS,
    MethodResult,
    ScenarioResult,
    run_points,
    run_scenario,
)
from ftnav.io.common import read_toml
from ftnav.scenarios import builtin_path
from ftnav.sweep import (
    faults_only,
    grid,
    parse_set,
    run_sweep,
    shared_methods,
    shares_model,
    sweep_work,
)


def _arrays(r: MethodResult) -> list[np.ndarray]:
    """Every per-run array of a method's result (the nested tuples flattened)."""
    return _flat([getattr(r, f) for f in RESULT_FIELDS])


def _flat(values) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for v in values:
        if isinstance(v, tuple):
            out.extend(_flat(v))
        elif v is not None:
            out.append(np.asarray(v))
    return out


def _differences(got: ScenarioResult, alone: ScenarioResult) -> list[str]:
    """Where ``got`` differs from ``alone``: run count, seed, methods, or any per-run
    array bit for bit (empty when they are the same)."""
    if got.runs != alone.runs or got.seed != alone.seed:
        return [f"runs/seed {got.runs, got.seed} != {alone.runs, alone.seed}"]
    out = []
    for which in ("results", "fault_free"):
        a, b = getattr(got, which), getattr(alone, which)
        if list(a) != list(b):
            out.append(f"{which}: methods {list(a)} != {list(b)}")
            continue
        for name in a:
            x, y = _arrays(a[name]), _arrays(b[name])
            if len(x) != len(y):
                out.append(f"{which}[{name}]: {len(x)} arrays != {len(y)}")
                continue
            out += [
                f"{which}[{name}] array {i}"
                for i, (u, v) in enumerate(zip(x, y, strict=True))
                if not np.array_equal(u, v, equal_nan=True)
            ]
    return out


def _text(metrics: dict) -> str:
    """The metrics as text (NaN compares equal to NaN there)."""
    return json.dumps({k: dataclasses.asdict(v) for k, v in metrics.items()}, default=str)


def _seed000(tmp_path: Path) -> Path:
    doc = tomllib.loads(builtin_path("seed000").read_text())
    keep = ("ckf", "fkf-inverse-trace-chi2", "fkf-inverse-trace-cusum")
    doc["methods"] = [m for m in doc["methods"] if m["name"] in keep]
    doc["steps"] = 600
    doc.pop("figures", None)
    path = tmp_path / "small.toml"
    path.write_text(tomli_w.dumps(doc))
    return path


def _seed002(tmp_path: Path) -> Path:
    doc = read_toml(builtin_path("seed002"))
    doc["filter"]["duration_s"] = 40.0
    doc["evaluation"]["skip_initial"] = 5.0
    doc["faults"] = [doc["faults"][0] | {"start": 10.0, "end": 30.0}]
    doc.pop("figures", None)
    path = tmp_path / "short.toml"
    path.write_text(tomli_w.dumps(doc))
    return path


def test_linear_points_in_one_batch_equal_their_own_campaigns(tmp_path):
    axes = [parse_set("faults.0.magnitude=5,20,80")]
    points = [sc for _, sc in grid(_seed000(tmp_path), axes)]
    stacked = run_points(points, 5, 3)
    assert len(stacked) == 3
    for got, sc in zip(stacked, points, strict=True):
        assert not _differences(got, run_scenario(sc, 5, 3))


def test_integrated_points_in_one_batch_equal_their_own_campaigns(tmp_path):
    axes = [parse_set("faults.0.magnitude=2,8")]
    points = [sc for _, sc in grid(_seed002(tmp_path), axes)]
    methods = tuple(m for m in points[0].methods if m.name in ("ckf", "fkf-chi2"))
    stacked = run_points(points, 2, 1, methods=methods)
    for got, sc in zip(stacked, points, strict=True):
        assert not _differences(got, run_scenario(sc, 2, 1, methods=methods))


def test_a_point_without_faults_gets_no_twin(tmp_path):
    (_, sc), *_ = grid(_seed000(tmp_path), [parse_set("faults.0.magnitude=20")])
    clean = sc.without_faults()
    got = run_points([sc, clean], 4, 2)
    assert got[1].fault_free == {}
    assert not _differences(got[0], run_scenario(sc, 4, 2))
    assert not _differences(got[1], run_scenario(clean, 4, 2))


def test_a_fault_sweep_gives_the_metrics_of_the_points_run_alone(tmp_path):
    axes = [parse_set("faults.0.magnitude=5,40"), parse_set("faults.0.start=100,200")]
    assert faults_only(axes) and not faults_only([parse_set("steps=100,200")])
    points = grid(_seed000(tmp_path), axes)
    sweep = run_sweep(points, axes, 4, 7, workers=1)
    for metrics, (_, sc) in zip(sweep.metrics, points, strict=True):
        alone = evaluate(run_scenario(sc, 4, 7))
        assert _text(metrics) == _text(alone)


def test_points_that_differ_in_more_than_their_faults_are_refused(tmp_path):
    (_, sc), *_ = grid(_seed000(tmp_path), [parse_set("faults.0.magnitude=20")])
    with pytest.raises(ValueError, match="points: the scenarios must differ in their faults"):
        run_points([sc, dataclasses.replace(sc, steps=sc.steps - 1)], 2, 1)


def test_a_method_sweep_runs_the_methods_it_does_not_touch_once(tmp_path):
    axes = [parse_set("methods.1.detector.false_alarm_probability=1e-3,1e-2,5e-2")]
    assert shares_model(axes) and not faults_only(axes)
    assert not shares_model([parse_set("steps=100,200")])
    points = grid(_seed000(tmp_path), axes)
    shared = shared_methods([sc for _, sc in points])
    names = [m.name for m in shared.methods]
    assert names == [
        "ckf",
        "fkf-inverse-trace-chi2",
        "fkf-inverse-trace-cusum",
        "fkf-inverse-trace-chi2@1",
        "fkf-inverse-trace-chi2@2",
    ]
    assert shared.names[2] == {
        "ckf": "ckf",
        "fkf-inverse-trace-chi2": "fkf-inverse-trace-chi2@2",
        "fkf-inverse-trace-cusum": "fkf-inverse-trace-cusum",
    }
    assert shared.methods[4].detector.false_alarm_probability == 5e-2
    # progress: the union once (five methods), not three points of three
    assert sweep_work(points, axes) == 5 * points[0][1].steps
    # the evaluation's settings change no run: four points, one campaign of three methods
    scoring = [parse_set("evaluation.grace=2,30"), parse_set("evaluation.skip_initial=0,100")]
    assert sweep_work(grid(_seed000(tmp_path), scoring), scoring) == 3 * points[0][1].steps


@pytest.mark.parametrize(
    "sets",
    [
        ["methods.1.detector.false_alarm_probability=1e-3,1e-2"],
        ["faults.0.magnitude=5,40", "methods.2.detector.arl0=1e3,1e4"],
        ["evaluation.grace=2,30", "evaluation.skip_initial=0,100"],
    ],
)
def test_a_method_sweep_gives_the_metrics_of_the_points_run_alone(tmp_path, sets):
    axes = [parse_set(s) for s in sets]
    points = grid(_seed000(tmp_path), axes)
    sweep = run_sweep(points, axes, 4, 7, workers=1)
    for metrics, (_, sc) in zip(sweep.metrics, points, strict=True):
        alone = evaluate(run_scenario(sc, 4, 7))
        assert list(metrics) == [m.name for m in sc.methods]
        assert _text(metrics) == _text(alone)


def test_an_integrated_method_sweep_gives_the_metrics_of_the_points_run_alone(tmp_path):
    doc = read_toml(_seed002(tmp_path))
    doc["methods"] = [m for m in doc["methods"] if m["name"] in ("ckf", "fkf-chi2")]
    path = tmp_path / "two.toml"
    path.write_text(tomli_w.dumps(doc))
    index = [m["name"] for m in doc["methods"]].index("fkf-chi2")
    axes = [parse_set(f"methods.{index}.detector.false_alarm_probability=1e-3,1e-2")]
    points = grid(path, axes)
    sweep = run_sweep(points, axes, 2, 1, workers=1)
    for metrics, (_, sc) in zip(sweep.metrics, points, strict=True):
        assert _text(metrics) == _text(evaluate(run_scenario(sc, 2, 1)))
