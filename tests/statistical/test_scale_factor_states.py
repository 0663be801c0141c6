"""The 21-state model (15 + gyro and accelerometer scale factors, KF-GINS's) on a flight
whose IMU has scale-factor errors (:mod:`ftnav.nav.error_model`).

The seed002 flight (take-off, climbs, a 90° and a 180° coordinated turn at 150 m/s), 1 500 s,
an IMU whose only large errors are its scale factors (gyro 0.3 %, accelerometer 0.1 %,
drawn per run), GNSS positions and velocities at 1 Hz, centralized filter with the biases
and scale factors fed back and compensated; 6 runs, the metrics skip the first 100 s.

Oracles (the truth is the simulation's; the χ² band of the 9-state ANEES over 6 runs):

* a 15-state filter, which has no state for the scale factors, is overconfident: its
  ANEES lies above the band's upper edge (the turns' heading error, σ·rate, is
  unmodelled);
* the 21-state filter, whose model is the IMU's, is consistent: ANEES inside the band;
* its attitude error is smaller (heading RMSE at most half the 15-state filter's).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from ftnav.eval.evaluate import evaluate
from ftnav.eval.metrics import chi2_band
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.ins_scenario_file import parse_ins_scenario

RUNS = 6
TEMPLATE = """
kind = "integrated"
name = "scale-factors"
profile = "seed002"
[imu]
gyro_arw = "0.05 deg/sqrt(h)"
gyro_bias_sd = "0.01 deg/h"
gyro_scale_sd = "0.3 %"
accel_vrw = "0.02 m/s/sqrt(h)"
accel_bias_sd = "50 ug"
accel_scale_sd = "0.1 %"
[filter]
dt = 1.0
duration_s = 1500.0
states = {states}
bias_compensation = true
[[aids]]
type = "gnss"
pos_markov_sigma_m = 0.0
vel_markov_sigma_m_s = 0.0
pos_white_sigma_m = 1.0
vel_white_sigma_m_s = 0.05
[evaluation]
skip_initial = 100.0
[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _run(states: int) -> dict[str, float]:
    sc = parse_ins_scenario(tomllib.loads(TEMPLATE.format(states=states)))
    res = run_scenario(sc, RUNS, seed=5)
    heading = res.results["ckf"].error[:, 100:, 8]  # φ_U, arcmin
    return {"anees": evaluate(res)["ckf"].anees, "heading": float(np.sqrt(np.mean(heading**2)))}


@pytest.fixture(scope="module")
def results():
    return {n: _run(n) for n in (15, 21)}


def test_without_scale_factor_states_the_filter_is_overconfident(results):
    lo, hi = chi2_band(9 * RUNS, RUNS)
    assert results[15]["anees"] > hi, results


def test_with_scale_factor_states_the_filter_is_consistent_and_better(results):
    lo, hi = chi2_band(9 * RUNS, RUNS)
    assert lo <= results[21]["anees"] <= hi, (results, (lo, hi))
    assert results[21]["heading"] <= 0.5 * results[15]["heading"], results
