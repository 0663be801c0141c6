"""GNSS Markov-error handling in the closed loop: white, augmented, differenced (spec §9.1).

One GNSS (25 m, τ 100 s Markov position error; 0.05 m/s velocity) plus a barometer on
the seed002 flight, 900 s, 6 runs, centralized filter; the metrics skip the first 100 s.

Oracles:

* feedback and output correction give the same differenced filter (horizontal RMSE
  within 2 %): the correction fed back between two epochs must be removed from the
  previous measurement (``shift``; measured without it: the feedback run diverged to
  ~1e9 m);
* folding the Markov error into a white R makes the filter overconfident (ANEES far
  above the 9-state χ² band), augmenting it makes it consistent (inside the band), and
  differencing, which neglects the correlation of consecutive differenced noises, stays
  on the conservative side (ANEES below the band's upper edge);
* differencing removes the Markov error from the height (with the barometer): Up RMSE
  less than half of the white-R filter's.
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
name = "gnss-markov"
profile = "seed002"
imu = "seed001"
[filter]
dt = 1.0
duration_s = 900.0
correction = "{correction}"
[[aids]]
type = "gnss"
pos_markov_sigma_m = 25.0
pos_markov_tau_s = 100.0
vel_markov_sigma_m_s = 0.05
vel_markov_tau_s = 100.0
markov = "{markov}"
[[aids]]
type = "ads"
[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _run(markov: str, correction: str = "feedback"):
    sc = parse_ins_scenario(tomllib.loads(TEMPLATE.format(markov=markov, correction=correction)))
    res = run_scenario(sc, RUNS, seed=2)
    x = res.results["ckf"].error[:, 100:]
    return {
        "horizontal": float(np.sqrt(np.mean(x[..., 0] ** 2 + x[..., 1] ** 2))),
        "up": float(np.sqrt(np.mean(x[..., 2] ** 2))),
        "anees": evaluate(res)["ckf"].anees,
    }


@pytest.fixture(scope="module")
def results():
    return {m: _run(m) for m in ("white", "augment", "difference")}


def test_differencing_is_the_same_with_feedback_and_output_correction(results):
    out = _run("difference", "output")
    fb = results["difference"]
    assert abs(fb["horizontal"] - out["horizontal"]) <= 0.02 * out["horizontal"], (fb, out)
    assert fb["horizontal"] < 100.0


def test_consistency_white_overconfident_augment_consistent_difference_conservative(results):
    lo, hi = chi2_band(9 * RUNS, RUNS)
    assert results["white"]["anees"] > 5 * hi, results["white"]
    assert lo <= results["augment"]["anees"] <= hi, results["augment"]
    assert results["difference"]["anees"] <= hi, results["difference"]


def test_differencing_removes_the_markov_error_from_the_height(results):
    assert results["difference"]["up"] < 0.5 * results["white"]["up"], results
