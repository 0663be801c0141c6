"""Numbers that cannot be written: a diverged method is reported, never written.

The engine checks every fused covariance at every epoch (symmetric, positive diagonal,
Cholesky) and raises :class:`Diverged` naming the method, the epoch and its time; the
writers refuse what slips past (a NaN estimate, a negative variance, an infinite
metric) with the same error, so ``metrics.json`` and ``estimates.nc`` never hold a
null RMSE or a negative variance.  Each case is worked by hand.
"""

from __future__ import annotations

import json
import pickle
from typing import Any

import numpy as np
import pytest

from ftnav.engine.driver import (
    Diverged,
    Trace,
    check_output,
    covariance_ok,
    iterate,
    run,
)
from ftnav.engine.linear import LinearModel
from ftnav.eval.montecarlo import run_scenario
from ftnav.fusion.protocol import StepOutput
from ftnav.io.results import write_metrics
from ftnav.io.scenario_file import parse_scenario
from ftnav.io.solution_file import solution_table
from ftnav.model.streams import MeasurementStream
from ftnav.nav.mechanization import InsState

SCENARIO: dict[str, Any] = {
    "name": "grow",
    "dt": 0.5,
    "steps": 40,
    "model": {"states": ["x"], "F": [[1.0]], "Q": [[1.0]], "x0": [0.0], "P0": [[1.0]]},
    "sensors": [{"name": "z", "H": [[1.0]], "R": [[1.0]]}],
    "methods": [{"name": "ckf", "architecture": "centralized"}],
}


class _Stub:
    """A filter whose fused covariance is ``P_at(k)`` at epoch k (1-based)."""

    def __init__(self, P_at):
        self.P_at = P_at

    def init(self, batch: int) -> int:
        return 0

    def step(self, k: int, epoch: Any) -> tuple[int, StepOutput]:
        k += 1
        P = np.asarray(self.P_at(k), float)[None]
        return k, StepOutput(
            np.zeros((1, P.shape[-1])), P, None, None, (np.ones((1, 1)),), np.zeros((1, 1), bool)
        )

    def local_estimates(self, state: int, n: int) -> None:
        return None

    def shift(self, state: int, delta: np.ndarray) -> int:
        return state


def _stream(steps: int) -> MeasurementStream:
    return MeasurementStream(
        (np.zeros((1, steps, 1)),), np.ones((1, steps, 1), bool), np.zeros((steps, 1), bool)
    )


def _model():
    return LinearModel(parse_scenario(SCENARIO).system())


def test_diverged_message_and_attributes():
    e = Diverged("ckf", 7, 3.5, "covariance not positive definite (check Q, R, P0)")
    assert str(e) == (
        "methods[ckf]: diverged at epoch 7 (t = 3.5 s): covariance not positive definite "
        "(check Q, R, P0)"
    )
    assert (e.method, e.epoch, e.time_s) == ("ckf", 7, 3.5)
    assert isinstance(e, FloatingPointError)
    again = pickle.loads(pickle.dumps(e))  # worker processes send it back
    assert str(again) == str(e) and again.epoch == 7


@pytest.mark.parametrize(
    ("P", "ok"),
    [
        ([[2.0, 1.0], [1.0, 2.0]], True),
        ([[1.0, 2.0], [2.0, 1.0]], False),  # |P01|² > P00 P11: indefinite
        ([[1.0, 0.0], [0.0, -1e-12]], False),  # a negative variance
        ([[1.0, 0.5], [0.4, 1.0]], False),  # not symmetric
        ([[0.0, 0.0], [0.0, 0.0]], False),
    ],
)
def test_covariance_ok_by_hand(P, ok):
    assert covariance_ok(np.asarray(P)[None]) is ok


def test_iterate_stops_at_the_first_indefinite_covariance():
    bad = [[1.0, 2.0], [2.0, 1.0]]
    stub = _Stub(lambda k: bad if k == 3 else np.eye(2))
    times = 0.5 * np.arange(1, 6)
    with pytest.raises(Diverged) as info:
        for _ in iterate(_model(), _stream(5), {"m": stub}, 5, times=times):
            pass
    assert str(info.value) == (
        "methods[m]: diverged at epoch 3 (t = 1.5 s): covariance not positive definite "
        "(check Q, R, P0)"
    )


def test_iterate_reports_nan_as_divergence():
    stub = _Stub(lambda k: [[np.nan]] if k == 2 else [[1.0]])
    with pytest.raises(
        Diverged, match=r"^methods\[m\]: diverged at epoch 2: estimate or covariance is NaN or inf"
    ):
        run(_model(), _stream(4), {"m": stub}, 4)


def test_the_check_can_be_turned_off():
    stub = _Stub(lambda k: [[-1.0]])
    traces = run(_model(), _stream(3), {"m": stub}, 3, check_spd=False)
    assert traces["m"].P_diag[0, :, 0].tolist() == [-1.0, -1.0, -1.0]


def test_check_output_names_the_first_bad_epoch():
    x = np.zeros((2, 5, 1))
    var = np.ones((2, 5, 1))
    var[1, 3, 0] = -1.0
    x[0, 4, 0] = np.nan
    with pytest.raises(Diverged, match=r"epoch 4 \(t = 4 s\): negative variance"):
        check_output("a", (x,), (var,), np.arange(1.0, 6.0))
    var[1, 3, 0] = 1.0
    with pytest.raises(Diverged, match=r"epoch 5 \(t = 5 s\): estimate or covariance is NaN"):
        check_output("a", (x,), (var,), np.arange(1.0, 6.0))
    check_output("a", (np.zeros((2, 5, 1)), None), (var,))


def test_a_run_that_diverges_is_reported_not_scored():
    """F = 1e10: the variance grows by 1e20 a step and overflows after about 16 steps."""
    data = json.loads(json.dumps(SCENARIO))
    data["model"]["F"] = [[1e10]]
    data["sensors"][0]["every"] = 1000  # never measured: nothing holds it back
    sc = parse_scenario(data)
    with pytest.raises(Diverged) as info:
        run_scenario(sc, 2, 1, fault_free=False)
    e = info.value
    assert e.method == "ckf" and 10 <= e.epoch <= 20 and e.time_s == 0.5 * e.epoch, str(e)


def test_write_metrics_refuses_an_infinite_metric(tmp_path):
    doc = {"methods": {"ckf": {"rmse": {"x": float("inf")}, "detection": float("nan")}}}
    with pytest.raises(
        Diverged, match=r"^methods\[ckf\]: diverged: rmse\.x is inf \(not written\)$"
    ):
        write_metrics(doc, tmp_path / "m.json")
    doc["methods"]["ckf"]["rmse"]["x"] = 1.0
    written = json.loads(write_metrics(doc, tmp_path / "m.json").read_text())
    assert written["methods"]["ckf"] == {"rmse": {"x": 1.0}, "detection": None}


def test_solution_table_refuses_a_negative_variance():
    K = 3
    P = np.full((1, K, 9), 1.0)
    P[0, 1, 7] = -1e-3
    sol = InsState(
        np.tile([1.0, 0, 0, 0], (1, K, 1)),
        np.zeros((1, K, 3)),
        np.full((1, K, 3), 0.5),
        np.zeros((1, K, 3)),
    )
    trace = Trace(
        x=np.zeros((1, K, 9)),
        P_diag=P,
        nan_count=np.zeros((1, 1)),
        solution=sol,
    )
    with pytest.raises(
        Diverged, match=r"^methods\[gnss-ins\]: diverged at epoch 2 \(t = 11 s\): negative variance"
    ):
        solution_table(trace, np.array([10.0, 11.0, 12.0]), method="gnss-ins")
    P[0, 1, 7] = 1.0
    assert np.isfinite(solution_table(trace, np.array([10.0, 11.0, 12.0]))).all()
