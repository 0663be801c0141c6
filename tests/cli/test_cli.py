"""The ftnav command on small inputs: outputs, contract, and bad input (exit 2, one line)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from output_problems import SMALL

from ftnav.cli import main


@pytest.fixture
def small(tmp_path) -> Path:
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


def test_run_writes_the_metrics_contract_and_estimates(small, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        [
            "run",
            str(small),
            "--runs",
            "3",
            "--seed",
            "7",
            "--out",
            str(out),
            "--save-estimates",
            "--quiet",
        ]
    )
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
    assert ds["x_hat"].dims == ("method_name", "run", "time", "state")
    assert ds["x_hat"].shape == (3, 3, 60, 3)
    assert ds["truth"].dims == ("run", "time", "state")
    assert ds["fault_flag"].dims == ("method_name", "run", "time", "sensor")
    assert int(ds["fault_flag"].sel(method_name="ckf").max()) == -1
    assert int(ds["fault_flag"].sel(method_name="fkf").max()) == 1
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
    np.testing.assert_array_equal(a.results["fkf"].estimate, b.results["fkf"].estimate)
    alone = simulate(sc, 1, seed=3, first_run=2)
    np.testing.assert_array_equal(alone.truth.states[0], a.truth.states[2])
    np.testing.assert_array_equal(alone.stream.z[0][0], a.stream.z[0][2])


def test_list_and_schema(capsys, tmp_path):
    assert main(["list"]) == 0
    assert "seed000" in capsys.readouterr().out
    assert main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    branches = [schema["$defs"][ref["$ref"].split("/")[-1]] for ref in schema["oneOf"]]
    assert [b["title"] for b in branches] == ["ftnav scenario", "ftnav integrated scenario"]
    out = tmp_path / "sub" / "schema.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == schema


def test_schema_branches_hold_the_top_level_keys_of_every_built_in():
    import tomllib

    from ftnav.io.scenario_file import scenario_json_schema
    from ftnav.scenarios import builtin_names, builtin_path

    schema = scenario_json_schema()
    linear, integrated = (schema["$defs"][r["$ref"].split("/")[-1]] for r in schema["oneOf"])
    for name in builtin_names():
        doc = tomllib.loads(builtin_path(name).read_text())
        branch = integrated if doc.get("kind") == "integrated" else linear
        other = linear if branch is integrated else integrated
        assert set(doc) <= set(branch["properties"]), name
        assert set(branch["required"]) <= set(doc), name
        assert not set(other["required"]) <= set(doc) or not set(doc) <= set(other["properties"])


BAD = [
    (
        "F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]",
        "F  = [[1.0, 0.05], [0.0, 1.0]]",
        "model.F",
    ),
    (
        "Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]",
        "Q  = [[5.0, 1.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]",
        "model.Q",
    ),
    (
        "Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]",
        "Q  = [[5.0, 0.0, 0.0], [0.0, -2.0, 0.0], [0.0, 0.0, 3.0]]",
        "model.Q",
    ),
    ("R = [[30.0]]\n[[sensors]]", "R = [[-30.0]]\n[[sensors]]", r"sensors\[0\].R"),
    ("P0 = [[100.0, 0.0, 0.0]", "P0 = [[nan, 0.0, 0.0]", "model.P0"),
    ("x0 = [0.0, 0.0, 0.0]", "x0 = [0.0, inf, 0.0]", "model.x0"),
    ('sensor = "pos1"', 'sensor = "pos9"', r"faults\[0\].sensor"),
    ("start = 20.0", "start = -5.0", r"faults\[0\].start"),
    ("end = 40.0", "end = 10.0", r"faults\[0\].end"),
    ('sharing = "inverse-trace"', 'sharing = "inverse-trace"\nbogus = 1', r"methods\[1\].bogus"),
    ('architecture = "distributed"', 'architecture = "hierarchical"', r"methods\[2\].architecture"),
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


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "no-such-scenario"],
        ["run", "seed000", "--runs", "0"],
        ["run", "seed000", "--seed", "x"],
        ["frobnicate"],
    ],
)
def test_bad_arguments_exit_2_with_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftnav: error: ") and err.count("\n") == 1


def test_console_script_bad_input_has_no_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(SMALL.replace("R = [[30.0]]", "R = [[30.0, 1.0]]", 1))
    proc = subprocess.run(
        [sys.executable, "-m", "ftnav.cli", "run", str(p)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert "sensors[0].R" in proc.stderr


def test_nan_measurement_is_missing_and_counted(small):
    from ftnav.engine.driver import run
    from ftnav.engine.linear import LinearModel
    from ftnav.fusion import registry
    from ftnav.fusion.config import NOTHING_LEARNED
    from ftnav.io.scenario_file import load_scenario
    from ftnav.sim.linear import simulate

    sc = load_scenario(small)
    system = sc.system()
    stream = simulate(sc, 3, seed=1).stream
    z0 = stream.z[0].copy()
    z0[1, 10] = np.nan
    z0[2, 30:33] = np.inf
    bad = stream._replace(z=(z0,) + stream.z[1:])
    skipped = stream._replace(available=stream.available.copy())
    skipped.available[1, 10, 0] = False
    skipped.available[2, 30:33, 0] = False

    def run_filter(m, data):
        filt = registry.build(system, m, sc.learned_for(m.name) or NOTHING_LEARNED)
        return run(LinearModel(system), data, {m.name: filt}, sc.steps)[m.name]

    for m in sc.methods:
        r = run_filter(m, bad)
        ref = run_filter(m, skipped)
        assert np.isfinite(r.x).all() and np.isfinite(r.P_diag).all()
        assert r.nan_count[:, 0].tolist() == [0, 1, 3]
        np.testing.assert_array_equal(r.x, ref.x)  # NaN == missing measurement


# ------------------------------------------------- exit status: bad input, bugs, --debug


def test_type_errors_name_the_option_once(capsys):
    assert main(["run", "seed000", "--runs", "0"]) == 2
    assert capsys.readouterr().err == "ftnav: error: --runs: must be >= 1, got 0\n"
    assert main(["train-detector", "seed000", "--out", "m.npz", "--centres", "1"]) == 2
    assert capsys.readouterr().err == "ftnav: error: --centres: must be >= 2, got 1\n"
    assert main(["run", "seed000", "--seed", "-1"]) == 2
    assert capsys.readouterr().err == "ftnav: error: --seed: must be >= 0, got -1\n"


def test_version_and_help_exit_0(capsys):
    from ftnav import __version__

    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"ftnav {__version__}\n"
    assert main(["run", "--help"]) == 0
    assert capsys.readouterr().out.startswith("usage: ftnav run")


def test_bare_command_prints_the_help_and_exits_2(capsys):
    assert main([]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("usage: ftnav") and "train-detector" in captured.err


def _crash(*args, **kwargs):
    raise RuntimeError("boom\nsecond line")


def test_an_error_during_the_computation_is_an_internal_error(small, tmp_path, capsys, monkeypatch):
    import ftnav.cli as cli

    monkeypatch.setattr(cli, "run_scenario", _crash)
    assert main(["run", str(small), "--runs", "2", "--out", str(tmp_path / "o"), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err == (
        "ftnav: internal error, please report: RuntimeError: boom second line "
        "(run again with --debug for the traceback)\n"
    )


def test_a_value_error_during_the_computation_is_not_the_users_fault(
    small, tmp_path, capsys, monkeypatch
):
    import ftnav.cli as cli

    def bug(*args, **kwargs):
        raise ValueError("x: a bug that looks like bad input")

    monkeypatch.setattr(cli, "run_scenario", bug)
    assert main(["run", str(small), "--runs", "2", "--out", str(tmp_path / "o"), "--quiet"]) == 1
    assert capsys.readouterr().err.startswith(
        "ftnav: internal error, please report: ValueError: x: a bug"
    )


def test_a_value_error_while_building_the_filters_is_bad_input(
    small, tmp_path, capsys, monkeypatch
):
    import ftnav.cli as cli

    def refuse(scenario, system, methods, **kw):
        raise ValueError(f"methods[{methods[0].name}].sharing: not for this system")

    monkeypatch.setattr(cli, "build_filters", refuse)
    assert main(["run", str(small), "--runs", "2", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert capsys.readouterr().err == "ftnav: error: methods[ckf].sharing: not for this system\n"
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("where", ["before", "after"])
def test_debug_shows_the_traceback_of_both_kinds(small, tmp_path, capsys, monkeypatch, where):
    import ftnav.cli as cli

    def argv(*rest):
        head = ["--debug", "run"] if where == "before" else ["run"]
        tail = [] if where == "before" else ["--debug"]
        return [*head, *rest, *tail]

    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL.replace('sensor = "pos1"', 'sensor = "pos9"', 1))
    assert main(argv(str(bad), "--out", str(tmp_path / "o"), "--quiet")) == 2
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err
    assert err.splitlines()[-1].startswith(f"ftnav: error: {bad}:")
    assert " faults[0].sensor: unknown sensor" in err.splitlines()[-1]
    monkeypatch.setattr(cli, "run_scenario", _crash)
    assert main(argv(str(small), "--runs", "2", "--out", str(tmp_path / "o"), "--quiet")) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and "in _crash" in err
    assert (
        err.splitlines()[-1]
        == "ftnav: internal error, please report: RuntimeError: boom second line"
    )


def test_console_script_internal_error_is_one_line(tmp_path):
    """A bug in a subprocess (the real entry point): exit 1, one line, no traceback."""
    code = (
        "import sys, ftnav.eval.montecarlo as mc\n"
        "def crash(*a, **k): raise KeyError('lost')\n"
        "mc.run_scenario = crash\n"
        "from ftnav.cli import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "run",
            str(p),
            "--runs",
            "2",
            "--quiet",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1
    assert proc.stderr == (
        "ftnav: internal error, please report: KeyError: 'lost' (run again "
        "with --debug for the traceback)\n"
    )
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["run", "train-detector", "train-fusion"])
def test_a_recording_given_to_a_scenario_command_is_refused_in_one_line(tmp_path, capsys, command):
    out = tmp_path / ("out" if command == "run" else "m.npz")
    assert main([command, "rtklib-walk", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is a recording" in err[0] and "ftnav process" in err[0]
    assert not out.exists()
