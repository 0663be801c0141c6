"""The default filter of every IMU is consistent: its error model is derived from the IMU.

Seed002's flight and aids (GNSS, star tracker, barometer), fault-free, centralized filter,
10 runs of 600 s, with the scenario's ``imu`` replaced and no filter setting given: the
filter's P0 and noise come from the IMU (:func:`ftnav.io.ins_scenario_file.filter_model`).

Bound (as in ``test_integrated_seed002.py::test_centralized_nees_is_consistent``, whose
derivation this reuses): for a consistent filter the run-averaged NEES of the 9
navigation states at one epoch lies in ``chi2_band(90, 10)`` = [6.56, 11.81] with
probability 0.95, and the ANEES, a time average of such variables, is at least as
concentrated.  Before the default was derived from the IMU the tactical preset gave
ANEES 156 and an IMU with a 1 mg accelerometer constant bias 280-760 (issue 13).  The
last case keeps Table 1's IMU and gives the GNSS aid every default (a 25 m, 100 s Markov
position error, augmented by default; folded into R it was overconfident).
"""

from __future__ import annotations

import tomllib
import warnings

import pytest

from ftnav.eval.metrics import chi2_band, nees_stats
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.ins_scenario_file import ScenarioWarning, parse_ins_scenario
from ftnav.model.imu import IMU_PRESETS
from ftnav.scenarios import builtin_path

#: a plain datasheet IMU: constant gyro and accelerometer biases, white noise
DATASHEET = {
    "gyro_bias_sd": "1 deg/h",
    "accel_bias_sd": "1 mg",
    "gyro_arw": "0.05 deg/sqrt(h)",
    "accel_vrw": "0.05 m/s/sqrt(h)",
}

CASES = [(name, states) for name in IMU_PRESETS for states in (18, 15)] + [
    ("datasheet", 18),
    ("datasheet", 15),
    ("default-gnss", 18),
]


def _scenario(imu, states: int, default_gnss: bool = False):
    data = tomllib.loads(builtin_path("seed002").read_text())
    if default_gnss:  # a GNSS aid with every default: the 25 m, 100 s Markov error
        data["aids"][0] = {"type": "gnss", "name": "gnss"}
    data.update(
        imu=imu, faults=[], methods=[{"name": "ckf", "architecture": "centralized"}], figures=[]
    )
    data["filter"].update(states=states, duration_s=600.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sc = parse_ins_scenario(data, base=builtin_path("seed002").parent)
    return sc, [str(w.message) for w in caught if issubclass(w.category, ScenarioWarning)]


@pytest.mark.parametrize(("imu", "states"), CASES, ids=[f"{i}-{s}" for i, s in CASES])
def test_centralized_anees_inside_the_band_with_the_default_filter(imu, states):
    sc, _ = _scenario(
        DATASHEET if imu == "datasheet" else "seed001" if imu == "default-gnss" else imu,
        states,
        default_gnss=imu == "default-gnss",
    )
    res = run_scenario(sc, 10, seed=1).results["ckf"]
    stats = nees_stats(res.nees, 9, sc.times >= sc.evaluation.skip_initial)
    lo, hi = chi2_band(90, 10)
    assert lo <= stats.anees <= hi, f"ANEES {stats.anees:.2f} outside [{lo:.2f}, {hi:.2f}]"


def test_an_error_the_model_cannot_represent_is_warned_about_with_the_reason():
    _, notes = _scenario("seed001", 18)
    assert notes == []  # Table 1's errors are exactly the 18-state model's
    _, notes = _scenario(DATASHEET, 18)
    assert len(notes) == 1 and "no accelerometer constant-bias state" in notes[0]
    assert "states = 15" in notes[0]
    _, notes = _scenario(DATASHEET, 15)
    assert notes == []  # random constants: exactly the 15-state model
    _, notes = _scenario("tactical", 18)
    text = " ".join(notes)
    assert "accelerometer scale factor and misalignment" in text
    assert "gyro scale factor and misalignment" in text
    assert all(n.startswith("<scenario>: imu: ") for n in notes)
