"""`ftnav run seed000 --runs 100 --seed 1` tells paper 000's story (issue 2 acceptance)."""

from __future__ import annotations

import json

from ftnav.cli import main


def test_seed000_story(tmp_path):
    out = tmp_path / "seed000"
    assert (
        main(
            [
                "run",
                "seed000",
                "--runs",
                "100",
                "--seed",
                "1",
                "--out",
                str(out),
                "--no-figures",
                "--quiet",
            ]
        )
        == 0
    )
    doc = json.loads((out / "metrics.json").read_text())
    m = doc["methods"]
    paper = m["fkf-inverse-trace-chi2"]
    in_fault = paper["rmse_fault"]["s"]
    fault_free = paper["fault_free"]["rmse_fault_window"]["s"]
    assert in_fault <= 1.2 * fault_free
    for name in (
        "ckf",
        "fkf-nr-equal",
        "fkf-fr-equal",
        "fkf-fr-trace",
        "fkf-fr-inverse-trace",
        "fkf-fr10-trace",
        "fkf-fr10-inverse-trace",
        "dkf",
    ):
        assert m[name]["rmse_fault"]["s"] >= 2.0 * fault_free, name
    # no fault: fusion-reset federated (every rule) and distributed equal the centralized filter
    for name in (
        "fkf-fr-equal",
        "fkf-fr-information",
        "fkf-fr-trace",
        "fkf-fr-eigen-trace",
        "fkf-fr-frobenius",
        "fkf-fr-inverse-trace",
        "dkf",
    ):
        assert m[name]["max_rel_diff_to_centralized"] <= 1e-9, name
    det = paper["detection"]["pos1"]
    assert det["rate"] >= 0.95 and det["mean_delay_s"] <= 1.0
    claims = {c["id"]: c for c in doc["claims"]}
    assert claims["p000-fig4b"]["holds"] and claims["p000-no-isolation"]["holds"]
    assert claims["p000-fig4a-reset10"]["holds"]
    assert claims["p000-fig4a-reset1"]["holds"] is False  # β-invariance, spec §1.6
    assert claims["p000-recovery"]["holds"]
    # issue 4: the RBF-driven fault factor (spec §4.3), side by side with the chi-square one
    rbf = m["fkf-inverse-trace-rbf"]
    d = rbf["detection"]["pos1"]
    assert d["rate"] >= 0.95 and d["false_alarm_rate"] <= 5e-3 and d["median_delay_s"] <= 2.0
    assert rbf["rmse_fault"]["s"] <= 1.2 * rbf["fault_free"]["rmse_fault_window"]["s"]
    assert claims["p000-rbf"]["holds"]
    # the neuron fusion centre isolates the faulty input through its pos1 bank
    neural = m["neural-chi2"]
    assert neural["rmse_fault"]["s"] <= 1.2 * neural["fault_free"]["rmse_fault_window"]["s"]
    assert neural["rmse_fault"]["s"] <= 0.5 * m["fkf-nr-equal"]["rmse_fault"]["s"]
    report = (out / "report.md").read_text()
    assert "## Detectors side by side" in report and "fkf-inverse-trace-rbf | rbf | pos1" in report
