"""``metrics_frame`` (``ftnav.eval.evaluate``): the campaign's metrics as a DataFrame.

Oracle: the typed metrics it is made of.  Every cell equals the field it names, every
``_lo`` / ``_hi`` the bound of that field's interval, and a column a method does not have
(a detector's, for the plain filter) is NaN in its row.
"""

from __future__ import annotations

import math
from dataclasses import asdict, replace

import pytest

from ftnav.eval.evaluate import evaluate, metrics_frame
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path


@pytest.fixture(scope="module")
def metrics():
    sc = load_scenario(builtin_path("seed000"))
    keep = ("ckf", "fkf-inverse-trace-chi2")
    sc = replace(sc, steps=400, methods=tuple(m for m in sc.methods if m.name in keep))
    return evaluate(run_scenario(sc, 4, 1))


def _nan(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def _same(cell, value) -> bool:
    """Equal, or both undefined (None or NaN)."""
    return (_nan(cell) and _nan(value)) or cell == value


def test_every_cell_is_the_metric_it_names(metrics):
    frame = metrics_frame(metrics)
    assert list(frame.index) == list(metrics)
    for name, m in metrics.items():
        row, ci = frame.loc[name], m.intervals
        assert ci is not None
        assert row["architecture"] == m.architecture
        assert row["anees"] == m.anees
        assert (row["anees_lo"], row["anees_hi"]) == (ci.anees.lo, ci.anees.hi)
        for state, v in m.rmse.items():
            assert row[f"rmse.{state}"] == v
            assert row[f"rmse.{state}_lo"] == ci.rmse[state].lo
            assert row[f"rmse.{state}_hi"] == ci.rmse[state].hi
        for state, v in (m.rmse_fault or {}).items():
            assert row[f"rmse_fault.{state}"] == v
        assert m.fault_free is not None
        assert row["fault_free.anees"] == m.fault_free.anees
        for state, v in m.fault_free.rmse.items():
            assert row[f"fault_free.rmse.{state}"] == v


def test_detection_columns_hold_the_detector_and_its_intervals(metrics):
    frame = metrics_frame(metrics)
    m = metrics["fkf-inverse-trace-chi2"]
    assert m.detection and m.intervals is not None and m.intervals.detection
    for sensor, d in m.detection.items():
        ci = m.intervals.detection[sensor]
        for field, value in asdict(d).items():
            assert _same(frame.loc["fkf-inverse-trace-chi2", f"detection.{sensor}.{field}"], value)
        assert _same(frame.loc["fkf-inverse-trace-chi2", f"detection.{sensor}.rate_lo"], ci.rate.lo)
    faulty = "pos1"  # seed000's fault: its Pd has an interval
    assert not _nan(frame.loc["fkf-inverse-trace-chi2", f"detection.{faulty}.rate_lo"])
    for sensor in m.detection:
        # the plain filter has no detector: its detection cells are NaN
        assert math.isnan(frame.loc["ckf", f"detection.{sensor}.rate"])
