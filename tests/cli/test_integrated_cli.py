"""``ftnav run`` on small integrated-navigation files (seed002-like and seed001-like, 120 s).

Oracle: the metrics.json contract (metric states of spec §11, an RMSE per state and
method) and the paper figures the scenario's methods call for.
"""

from __future__ import annotations

import json

import numpy as np

from ftnav.cli import main
from ftnav.model.scenario import METRIC_STATES, POSITION_NORMS

SEED002_LIKE = """
kind = "integrated"
name = "small002"
profile = "seed002"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 120.0

[[aids]]
type = "gnss"
pos_markov_sigma_m = 0.0
vel_markov_sigma_m_s = 0.0
pos_white_sigma_m = 1.4
vel_white_sigma_m_s = 0.3

[[aids]]
type = "cns"
form = "euler"

[[aids]]
type = "ads"

[[faults]]
sensor = "gnss"
kind = "noise-scale"
start = 60.0
end = 100.0
magnitude = [5.0]

[evaluation]
skip_initial = 20.0

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-chi2"
architecture = "federated"
mode = "fusion-reset"
detector = { kind = "residual-chi2", prior = "global" }
isolation = "time-update"

[[methods]]
name = "dkf-vb"
architecture = "distributed"
noise = { kind = "vb", sensors = ["gnss"] }
"""

SEED001_LIKE = """
kind = "integrated"
name = "small001"
profile = "seed001"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 120.0

[terrain]
kind = "analytic"

[[aids]]
type = "gnss"
name = "gps"

[[aids]]
type = "tan"

[[aids]]
type = "dns"

[[faults]]
sensor = "dns"
kind = "bias"
start = 60.0
end = 90.0
magnitude = [1.0, 1.0]

[evaluation]
skip_initial = 20.0

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-nr"
architecture = "federated"
mode = "no-reset"
detector = { kind = "residual-chi2", prior = "global" }
isolation = "time-update"
"""

POSITION = ("pos_E_m", "pos_N_m", "pos_U_m")


def _run(tmp_path, text: str, name: str) -> tuple[dict, set[str]]:
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    out = tmp_path / "out"
    code = main(["run", str(path), "--runs", "2", "--seed", "3", "--out", str(out), "--quiet"])
    assert code == 0
    doc = json.loads((out / "metrics.json").read_text())
    return doc, {p.name for p in out.iterdir()}


def _check_metrics(doc: dict, name: str, methods: set[str], sensors: list[str]) -> None:
    assert (doc["scenario"], doc["runs"], doc["seed"]) == (name, 2, 3)
    assert doc["states"] == list(METRIC_STATES)
    assert set(POSITION) <= set(doc["states"])
    assert doc["sensors"] == sensors
    assert set(doc["methods"]) == methods
    for m, entry in doc["methods"].items():
        assert set(entry["rmse"]) == set(METRIC_STATES) | set(POSITION_NORMS), m
        for state in POSITION:
            assert np.isfinite(entry["rmse"][state]) and entry["rmse"][state] > 0.0, (m, state)


def test_run_seed002_like_writes_metrics_and_paper_002_figures(tmp_path, capsys):
    doc, files = _run(tmp_path, SEED002_LIKE, "small002")
    _check_metrics(doc, "small002", {"ckf", "fkf-chi2", "dkf-vb"}, ["gnss", "cns", "ads"])
    assert set(doc["methods"]["fkf-chi2"]["detection"]) == {"gnss", "cns", "ads"}
    assert doc["methods"]["ckf"]["detection"] is None
    assert {
        "metrics.json",
        "report.md",
        "errors_position.png",
        "errors_velocity.png",
        "errors_attitude.png",
        "vb_noise_dkf-vb_gnss.png",
    } <= files
    assert "Results written to" in capsys.readouterr().out


def test_run_seed001_like_writes_metrics_and_local_fused_figures(tmp_path):
    doc, files = _run(tmp_path, SEED001_LIKE, "small001")
    _check_metrics(doc, "small001", {"ckf", "fkf-nr"}, ["gps", "tan", "dns"])
    assert doc["methods"]["fkf-nr"]["detection"]["dns"]["events"] == 2
    assert {
        "errors_position.png",
        "local_fused_fkf-nr.png",
        "local_fused_fkf-nr_fault_free.png",
    } <= files
    assert not any(f.startswith("local_fused_ckf") for f in files)  # no locals in the CKF
