"""A GNSS antenna on a lever arm, simulated and filtered (``sensors/gnss.py``).

Oracle: the same runs with the antenna at the IMU.  The arm changes only where the
receiver is (``p + C l``) and how fast it moves (``v + C(ω_eb × l)``); a filter that
models both sees the same information, so its errors at the IMU and its ANEES are those
of the armless runs up to the gyro noise the arm's rotation reads (measured, 4 runs of
``seed001``'s 600 s with a 3.2 m arm: horizontal RMS 10.254 m against 10.263 m, ANEES
10.22 against 10.26).  What the test catches: before 2026-12-07 the simulated antenna
sat at the IMU while the filter compared the antenna (``seed002``, 3 m arm: 3.02 m
against 0.49 m, ANEES 236 against 9.3, with no warning); with the arm's rotation left
out of the velocity rows, ``seed001``'s turns gave ANEES 21.8.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from ftnav.eval.montecarlo import run_scenario
from ftnav.io.common import read_toml
from ftnav.io.ins_scenario_file import parse_ins_scenario
from ftnav.scenarios import builtin_path

ARM = [0.0, 3.0, 1.0]  # m: right, forward, up


def _ckf(arm: list[float]) -> tuple[float, float]:
    """Horizontal RMS (m) and ANEES of ``ckf`` on ``seed001`` without its faults, from 60 s."""
    path = builtin_path("seed001")
    doc = read_toml(path)
    doc["filter"]["duration_s"] = 600.0
    doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]
    doc["faults"] = []
    for key in ("figures", "claims"):
        doc.pop(key, None)
    for aid in doc["aids"]:
        if aid["type"] == "gnss":
            aid["lever_arm_m"] = arm
    scenario = parse_ins_scenario(doc, "seed001 with an arm", Path(path).parent)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_scenario(scenario, 4, 1).results["ckf"]
    e = res.error[:, 60:]
    return float(np.sqrt(np.mean(e[..., 0] ** 2 + e[..., 1] ** 2))), float(
        np.mean(res.nees[:, 60:])
    )


@pytest.fixture(scope="module")
def armless() -> tuple[float, float]:
    return _ckf([0.0, 0.0, 0.0])


def test_an_antenna_on_an_arm_is_filtered_as_well_as_one_at_the_imu(armless):
    rms, anees = _ckf(ARM)
    assert rms == pytest.approx(armless[0], rel=0.02), (rms, armless)
    assert anees == pytest.approx(armless[1], rel=0.05), (anees, armless)
