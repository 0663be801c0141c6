"""A GNSS antenna on a lever arm: the centralized filter with and without the arm.

``seed001`` and ``seed002`` without their faults (4 runs of 600 s from seed 1, ``ckf``),
the GNSS antenna at the IMU and on the arm ``--arm`` (m, body right, forward, up), and on
the arm with the body's rotation left out of the velocity rows (the gyro rate given to
``measure`` as 0: what ftnav did before 2026-12-07, an ablation).  Printed: the
horizontal RMS from 60 s (m), the ANEES of the 9 navigation states, and the GNSS's mean
NIS.  With the arm modelled, the numbers are those of the antenna at the IMU up to the
gyro noise the arm's rotation reads (``tests/statistical/test_lever_arm.py``).

    python benchmarks/lever_arm.py                 # about 10 s
    python benchmarks/lever_arm.py --arm 2,-3,1
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from ftnav.eval.montecarlo import run_scenario
from ftnav.io.common import read_toml
from ftnav.io.ins_scenario_file import parse_ins_scenario
from ftnav.scenarios import builtin_path
from ftnav.sensors.gnss import Gnss


def _ckf(name: str, arm: list[float]) -> tuple[float, float, float]:
    path = builtin_path(name)
    doc = read_toml(path)
    doc["filter"]["duration_s"] = 600.0
    doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]
    doc["faults"] = []
    for key in ("figures", "claims"):
        doc.pop(key, None)
    for aid in doc["aids"]:
        if aid["type"] == "gnss":
            aid["lever_arm_m"] = arm
    scenario = parse_ins_scenario(doc, f"{name}, arm {arm}", Path(path).parent)
    res = run_scenario(scenario, 4, 1).results["ckf"]
    e = res.error[:, 60:]
    gnss = 0  # the first aid of both scenarios
    used = res.used[:, 60:, gnss]
    return (
        float(np.sqrt(np.mean(e[..., 0] ** 2 + e[..., 1] ** 2))),
        float(np.mean(res.nees[:, 60:])),
        float(np.mean(res.nis[:, 60:, gnss][used])),
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arm", default="0,3,1", help="the antenna from the IMU, m")
    arm = [float(x) for x in ap.parse_args().arm.split(",")]
    warnings.simplefilter("ignore")
    measure = Gnss.measure
    print("| scenario | antenna | horizontal RMS (m) | ANEES | GNSS mean NIS |")
    print("|---|---|---|---|---|")
    for name in ("seed001", "seed002"):
        for label, at, rotation in (
            ("at the IMU", [0.0, 0.0, 0.0], True),
            (f"on the arm {arm}", arm, True),
            (f"on the arm {arm}, its rotation left out", arm, False),
        ):
            if not rotation:  # an ablation: the rate the velocity rows read set to 0
                Gnss.measure = lambda self, q, v, p, raw, w_ib=None: measure(  # type: ignore[method-assign]
                    self, q, v, p, raw, None if w_ib is None else 0.0 * w_ib
                )
            try:
                rms, anees, nis = _ckf(name, at)
            finally:
                Gnss.measure = measure  # type: ignore[method-assign]
            print(f"| {name} | {label} | {rms:.3f} | {anees:.2f} | {nis:.2f} |")


if __name__ == "__main__":
    main()
