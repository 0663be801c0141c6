"""The ftnav command on small inputs: outputs, contract, and bad input (exit 2, one line)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ftnav.cli import main

SMALL = """
name = "small"
dt = 1.0
steps = 60
[model]
states = ["s", "v", "a"]
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]
[[sensors]]
name = "pos1"
H = [[1.0, 0.0, 0.0]]
R = [[30.0]]
[[sensors]]
name = "pos2"
H = [[2.5, 0.0, 0.0]]
R = [[30.0]]
every = 2
[[faults]]
sensor = "pos1"
kind = "bias"
start = 20.0
end = 40.0
magnitude = [60.0]
[[methods]]
name = "ckf"
architecture = "centralized"
[[methods]]
name = "fkf"
architecture = "federated"
sharing = "inverse-trace"
detector = "residual-chi2"
prior = "global"
[[methods]]
name = "dkf"
architecture = "distributed"
detector = "state-chi2"
"""


@pytest.fixture
def small(tmp_path) -> Path:
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


def test_run_writes_the_metrics_contract_and_estimates(small, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["run", str(small), "--runs", "3", "--seed", "7", "--out", str(out),
                 "--save-estimates", "--quiet"])
    assert code == 0
    doc = json.loads((out / "metrics.json").read_text())
    assert (doc["scenario"], doc["runs"], doc["seed"]) == ("small", 3, 7)
    for name in ("ckf", "fkf", "dkf"):
        m = doc["methods"][name]
        for key in ("rmse", "rmse_fault", "rmse_nofault"):
            assert set(m[key]) == {"s", "v", "a"}
            assert all(np.isfinite(v) for v in m[key].values())
        assert np.isfinite(m["anees"])
    for name in ("fkf", "dkf"):
        det = doc["methods"][name]["detection"]
        assert set(det) == {"pos1", "pos2"}
        assert {"rate", "false_alarm_rate", "mean_delay_s"} <= set(det["pos1"])
    assert doc["methods"]["ckf"]["detection"] is None
    xr = pytest.importorskip("xarray")
    ds = xr.open_dataset(out / "estimates.nc")
    assert ds["x_hat"].dims == ("method", "run", "time", "state")
    assert ds["x_hat"].shape == (3, 3, 60, 3)
    assert ds["truth"].dims == ("run", "time", "state")
    assert ds["fault_flag"].dims == ("method", "run", "time", "sensor")
    # `method` is also a keyword of DataArray.sel: select the dimension with a dict
    assert int(ds["fault_flag"].sel({"method": "ckf"}).max()) == -1
    assert int(ds["fault_flag"].sel({"method": "fkf"}).max()) == 1
    ds.close()
    assert (out / "report.md").read_text().startswith("# ftnav run: small")
    table = capsys.readouterr().out
    assert "fkf" in table and "Results written to" in table


def test_run_is_reproducible_and_run_i_is_the_same_alone(small, tmp_path):
    from ftnav.eval.montecarlo import run_scenario
    from ftnav.io.scenario_file import load_scenario
    from ftnav.sim.linear import simulate

    sc = load_scenario(small)
    a = run_scenario(sc, 4, seed=3, fault_free=False)
    b = run_scenario(sc, 4, seed=3, fault_free=False)
    np.testing.assert_array_equal(a.results["fkf"].x, b.results["fkf"].x)
    alone = simulate(sc, 1, seed=3, first_run=2)
    np.testing.assert_array_equal(alone.truth[0], a.simulation.truth[2])
    np.testing.assert_array_equal(alone.z[0][0], a.simulation.z[0][2])


def test_list_and_schema(capsys, tmp_path):
    assert main(["list"]) == 0
    assert "seed000" in capsys.readouterr().out
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert "methods" in schema["properties"]


BAD = [
    ('F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]',
     'F  = [[1.0, 0.05], [0.0, 1.0]]', "model.F"),
    ('Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]',
     'Q  = [[5.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]', "model.Q"),
    ('Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]',
     'Q  = [[5.0, 0.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, 3.0]]', "model.Q"),
    ('R = [[30.0]]\n[[sensors]]', 'R = [[-30.0]]\n[[sensors]]', r"sensors\[0\].R"),
    ('P0 = [[100.0, 0.0, 0.0]', 'P0 = [[nan, 0.0, 0.0]', "model.P0"),
    ('x0 = [0.0, 0.0, 0.0]', 'x0 = [0.0, inf, 0.0]', "model.x0"),
    ('sensor = "pos1"', 'sensor = "pos9"', r"faults\[0\].sensor"),
    ('start = 20.0', 'start = -5.0', r"faults\[0\].start"),
    ('end = 40.0', 'end = 10.0', r"faults\[0\].end"),
    ('sharing = "inverse-trace"', 'sharing = "inverse-trace"\nbogus = 1', r"methods\[1\].bogus"),
    ('architecture = "distributed"', 'architecture = "hierarchical"',
     r"methods\[2\].architecture"),
    ('kind = "bias"', 'kind = "drift"', r"faults\[0\].kind"),
]


@pytest.mark.parametrize(("old", "new", "field"), BAD)
def test_bad_scenario_exits_2_with_one_line_naming_the_field(tmp_path, capsys, old, new, field):
    assert old in SMALL
    p = tmp_path / "bad.toml"
    p.write_text(SMALL.replace(old, new, 1))
    code = main(["run", str(p), "--runs", "2", "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert pytest.importorskip("re").search(field, err), err


@pytest.mark.parametrize("argv", [
    ["run", "no-such-scenario"],
    ["run", "seed000", "--runs", "0"],
    ["run", "seed000", "--seed", "x"],
    ["frobnicate"],
])
def test_bad_arguments_exit_2_with_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftnav: error: ") and err.count("\n") == 1


def test_console_script_bad_input_has_no_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(SMALL.replace('R = [[30.0]]', 'R = [[30.0, 1.0]]', 1))
    proc = subprocess.run([sys.executable, "-m", "ftnav.cli", "run", str(p)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert "sensors[0].R" in proc.stderr


def test_nan_measurement_is_missing_and_counted(small):
    from ftnav.eval.montecarlo import build_filter, run_filter
    from ftnav.fusion.system import LinearSystem
    from ftnav.io.scenario_file import load_scenario
    from ftnav.sim.linear import simulate

    sc = load_scenario(small)
    system = LinearSystem.from_scenario(sc)
    sim = simulate(sc, 3, seed=1)
    z0 = sim.z[0].copy()
    z0[1, 10] = np.nan
    z0[2, 30:33] = np.inf
    bad = sim._replace(z=(z0,) + sim.z[1:])
    skipped = sim._replace(available=sim.available.copy())
    skipped.available[1, 10, 0] = False
    skipped.available[2, 30:33, 0] = False
    for m in sc.methods:
        r = run_filter(build_filter(system, m), bad, 3)
        ref = run_filter(build_filter(system, m), skipped, 3)
        assert np.isfinite(r.x).all() and np.isfinite(r.P_diag).all()
        assert r.nan_count[:, 0].tolist() == [0, 1, 3]
        np.testing.assert_array_equal(r.x, ref.x)  # NaN == missing measurement
