"""The filter watches itself (issue 20, point 5): a run that turns wrong says so.

Scenario: a user's UAV over a real-shaped DEM with terrain, barometric and Doppler aids,
whose flight leaves the DEM (the terrain aid goes dark there, and its last clearances
come from the DEM's edge).  Before issue 20 such a run ended kilometres off with exit 0
and not a word.  Oracle: what the run itself records, in closed form from the stream —
the aid's availability is the fraction of its epochs that had a measurement, so a DEM
left for most of the flight must be reported as such — and the warnings the command
line prints from ``metrics.json``'s ``integrity`` section (one line per finding, method
and aid named, exit status still 0: the run is a result, and it is flagged untrusted).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ftnav.cli import main

SCENARIO = """
kind = "integrated"
name = "uav-dem-exit"
description = "A flight that leaves its DEM: the terrain aid goes dark"
profile = "seed001"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 300.0
correction = "feedback"

[terrain]
kind = "grid"
path = "dem.npz"

[[aids]]
type = "tan"

[[aids]]
type = "ads"

[[aids]]
type = "dns"

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-chi2"
architecture = "federated"
mode = "fusion-reset"
isolation = "time-update"
detector = { kind = "residual-chi2", prior = "global" }
"""


def _dem(path):
    """A 0.08° x 0.1° DEM of rolling hills (300 ± 120 m) around seed001's start (32° N,
    118° E; the flight heads north at ~70 m/s and leaves it at ~165 s)."""
    lat = np.arange(31.98, 32.06, 0.0005)
    lon = np.arange(117.95, 118.05, 0.0005)
    L, G = np.meshgrid(lat, lon, indexing="ij")
    h = (
        300.0
        + 80.0 * np.sin(2 * np.pi * (L - 32.0) / 0.01) * np.cos(2 * np.pi * (G - 118.0) / 0.013)
        + 40.0 * np.sin(2 * np.pi * (G - 118.0) / 0.007)
    )
    np.savez(path, height_m=h, lat_deg=lat, lon_deg=lon)


@pytest.fixture(scope="module")
def watched(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dem")
    _dem(folder / "dem.npz")
    (folder / "scen.toml").write_text(SCENARIO)
    out = folder / "out"
    argv = ["run", str(folder / "scen.toml"), "--runs", "1", "--no-figures", "--quiet"]
    return folder, out, argv


def test_a_run_off_its_dem_is_warned_about_and_flagged(watched, capsys):
    folder, out, argv = watched
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    warnings = [ln for ln in err if ln.startswith("ftnav: warning: methods[")]
    doc = json.loads((out / "metrics.json").read_text())
    for name in ("ckf", "fkf-chi2"):
        integrity = doc["methods"][name]["integrity"]
        assert integrity["trusted"] is False
        tan = integrity["aids"]["tan"]
        # airborne from ~120 s, off the DEM's north edge (32.06°) from ~165 s of 300
        assert tan["availability"] < 0.5
        # every finding is printed once, as one line naming the method
        for finding in integrity["findings"]:
            assert f"ftnav: warning: {finding}" in err
        assert any(f"methods[{name}]: aid 'tan' had a measurement at only" in w for w in warnings)
    # the fault-free twin's consistency is reported beside the faulty run's
    for name in ("ckf", "fkf-chi2"):
        assert "anees" in doc["methods"][name]


def test_past_twelve_findings_every_method_gets_its_grave_ones_printed(capsys):
    """Only the first twelve findings of all methods were printed: a neural method 30
    times worse than the plain filter, listed last, had none of its findings on the
    terminal (found by a user's try).  Past twelve, each method's first two, its
    lock-out or σ past its bound first."""
    from ftnav.cli import _integrity_warnings
    from ftnav.eval.integrity import MethodWatch

    def w(name: str, n: int, grave: bool = False) -> MethodWatch:
        lines = [f"methods[{name}]: finding {i}" for i in range(n)]
        if grave:
            lines.append(f"methods[{name}]: every aid that measured was left out for 90 s")
        return MethodWatch((), 1, None, 0, None, tuple(lines))

    _integrity_warnings([w("a", 10), w("b", 5), w("nn", 3, grave=True)])
    err = capsys.readouterr().err.splitlines()
    assert err[4] == "ftnav: warning: methods[nn]: every aid that measured was left out for 90 s"
    assert len(err) == 7 and err[-1].startswith("ftnav: warning: 13 more integrity finding")
    _integrity_warnings([w("a", 3), w("b", 2)])  # twelve or fewer: all of them
    assert len(capsys.readouterr().err.splitlines()) == 5
