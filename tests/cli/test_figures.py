"""Smoke test of the result figures: files written, valid PNGs, matplotlib imported lazily."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ftnav.eval.montecarlo import run_scenario
from ftnav.sim.scenario import Fault, LinearModel, Method, Scenario, Sensor

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _tiny_scenario() -> Scenario:
    F = np.array([[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]])
    Q = np.diag([5.0, 2.0, 3.0])
    model = LinearModel(("s", "v", "a"), F, Q, np.zeros(3), 100.0 * np.eye(3), Q)
    R = np.array([[30.0]])
    sensors = tuple(
        Sensor(f"pos{i + 1}", np.array([[h, 0.0, 0.0]]), R, R)
        for i, h in enumerate((1.0, 2.5, 0.5))
    )
    faults = (Fault("pos1", "bias", 30.0, 50.0, np.array([60.0])),)
    methods = (
        Method("centralized", architecture="centralized"),
        Method("fed-inverse-trace-chi2", sharing="inverse-trace", detector="residual-chi2",
               prior="global"),
        Method("fed-trace", sharing="trace"),
    )
    return Scenario("tiny", 1.0, 100, model, sensors, faults, methods)


@pytest.fixture(scope="module")
def result():
    return run_scenario(_tiny_scenario(), runs=3, seed=1)


def test_save_all_writes_valid_pngs(result, tmp_path):
    from ftnav.plot import save_all

    paths = save_all(result, tmp_path)
    names = ["error_no_fault.png", "error_fault.png", "sharing.png", "fault_flags.png"]
    assert [p.name for p in paths] == names
    for name in names:
        path = tmp_path / name
        assert path.is_file()
        data = path.read_bytes()
        assert data[:8] == PNG_SIGNATURE
        assert len(data) > 10_000


def test_figure_functions_return_figures(result):
    from matplotlib.figure import Figure

    from ftnav.plot import error_figure, fault_flag_figure, sharing_figure

    for ff in (False, True):
        fig = error_figure(result, fault_free=ff, state=0)
        assert isinstance(fig, Figure)
        assert len(fig.axes) >= 2
    assert len(sharing_figure(result).axes) == 2  # the two federated methods
    assert len(fault_flag_figure(result).axes) == 1  # only one method has a detector
    with pytest.raises(ValueError, match="unknown method"):
        error_figure(result, methods=["nope"])
    with pytest.raises(ValueError, match="state"):
        error_figure(result, state=3)


def test_import_ftnav_does_not_import_matplotlib():
    code = "import ftnav, ftnav.plot, sys; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"
