"""Per-state tables, the position-norm metrics and estimates.nc (issue 13, point 9).

Oracles: a North-only ramp reaches the North state and not the East one, so the
per-state ratio in fault / fault-free is well above 1 in the N column and about 1 in E;
the horizontal and 3-D errors are recomputed here from the estimates; estimates.nc is
read back with xarray.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from output_problems import integrated_run, north_ramp_run

from ftnav.eval.evaluate import split_unit
from ftnav.eval.metrics import error_stats
from ftnav.model.scenario import METRIC_STATES, POSITION_NORMS
from ftnav.report.summary import fault_states, markdown_report, results_table, summary_tables


def _table(tables, prefix):
    return next(t for t in tables if t.title.startswith(prefix))


def _row(table, method):
    return dict(zip([c.key for c in table.columns], dict(table.rows)[method], strict=True))


# ------------------------------------------------------------------------ tables


def test_north_ramp_shows_in_the_north_column_of_the_ratio():
    result, metrics = north_ramp_run()
    assert fault_states(result.scenario) == {"gnss": "N"}
    tables = summary_tables(result, metrics)
    assert [t.title.split(" ")[0] for t in tables] == [
        "RMSE",
        "RMSE",
        "RMSE",
        "Ratio",
        "Consistency",
    ]
    for t in tables[:4]:
        assert [c.key for c in t.columns] == ["E", "N"]
        assert [name for name, _ in t.rows] == list(metrics)
    ratio = _table(tables, "Ratio")
    ckf = _row(ratio, "ckf")
    assert ckf["N"] > 2.0  # the ramp (up to 30 sigma) leaks into the North estimate
    assert ckf["E"] < 1.2  # and not into the East one
    assert ratio.note == "The faults act on: state N (gnss)."
    oracle = _row(ratio, "fkf-oracle")  # isolation keeps N close to fault-free
    assert oracle["N"] < 0.5 * ckf["N"]
    m = metrics["ckf"]
    assert ckf["N"] == pytest.approx(m.rmse_fault["N"] / m.fault_free.rmse_fault_window["N"])


def test_terminal_table_shows_every_state_under_a_state_header():
    result, metrics = north_ramp_run()
    text = results_table(result, metrics)
    lines = text.splitlines()
    ratio_at = next(i for i, line in enumerate(lines) if line.startswith("Ratio"))
    header = next(i for i in range(ratio_at, len(lines)) if lines[i].startswith("method"))
    assert lines[header - 1].split() == ["state"]  # the group line over the state columns
    assert lines[header].split() == ["method", "E", "N"]
    ckf = next(line for line in lines[header:] if line.startswith("ckf ")).split()
    assert float(ckf[2]) > 2.0 and float(ckf[1]) < 1.2
    assert "RMSE s" not in text and "RMSE E" not in text
    assert max(len(line) for line in lines) <= 100


def test_markdown_report_has_every_state_and_the_ratio_per_state():
    result, metrics = north_ramp_run()
    md = markdown_report(result, metrics, [], ["f.png"])
    assert "| method | state E | state N |" in md
    ratio = md.split("**Ratio")[1].split("**Consistency")[0]
    ckf = next(line for line in ratio.splitlines() if line.startswith("| ckf |"))
    cells = [c.strip() for c in ckf.strip("|").split("|")]
    assert float(cells[2]) > 2.0 and float(cells[1]) < 1.2
    assert "The faults act on: state N (gnss)." in md


def test_detection_columns_per_faulty_sensor():
    result, metrics = north_ramp_run()
    det = _table(summary_tables(result, metrics), "Consistency")
    labels = ["ANEES", "fault-free", "Pd", "delay [s]", "false alarms"]
    assert [c.label for c in det.columns] == labels
    assert det.columns[1].group == "consistency"  # the fault-free twin's ANEES (issue 20)
    assert det.columns[2].group == "sensor gnss"
    row = dict(det.rows)
    # the values with their 95 % intervals over the runs (issue 23)
    anees_ff = row["ckf"][1]
    assert anees_ff.value == pytest.approx(metrics["ckf"].fault_free.anees)
    assert anees_ff.lo < anees_ff.value < anees_ff.hi and anees_ff.method == "t"
    assert row["ckf"][2] is None  # no detector
    pd = row["fkf-oracle"][2]
    assert pd.value == pytest.approx(1.0) and pd.method == "wilson-cluster"
    assert 0.0 < pd.lo < 1.0 == pd.hi


def test_integrated_tables_have_every_navigation_state_with_units():
    result, metrics = integrated_run()
    tables = summary_tables(result, metrics)
    keys = [c.key for c in tables[0].columns]
    assert keys == [*METRIC_STATES[:3], *POSITION_NORMS, *METRIC_STATES[3:]]
    groups = {c.group for c in tables[0].columns}
    assert groups == {"position [m]", "velocity [m/s]", "attitude [arcmin]"}
    assert fault_states(result.scenario) == {"gnss": "pos_horizontal_m"}
    assert "act on: pos_horizontal [m] (gnss)" in _table(tables, "Ratio").note
    text = results_table(result, metrics)
    assert max(len(line) for line in text.splitlines()) <= 100
    md = markdown_report(result, metrics, [], [])
    for label in ("pos_E [m]", "vel_N [m/s]", "att_U [arcmin]", "pos_horizontal [m]", "pos_3d [m]"):
        assert f"| {label} |" in md or f" {label} |" in md, label


def test_wide_tables_are_split_into_column_blocks():
    result, metrics = integrated_run()
    text = results_table(result, metrics, width=60)
    first = text.split("RMSE inside")[0].splitlines()
    assert max(len(line) for line in first) <= 60
    assert sum(line.startswith("method") for line in first) >= 2  # two or more blocks
    assert "att" not in first[0]


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("s", ("s", None)),
        ("pos_E_m", ("pos_E", "m")),
        ("vel_N_m_s", ("vel_N", "m/s")),
        ("att_U_arcmin", ("att_U", "arcmin")),
        ("pos_horizontal_m", ("pos_horizontal", "m")),
        ("m", ("m", None)),
        ("_m", ("_m", None)),
    ],
)
def test_split_unit_reads_the_unit_suffix(name, expected):
    assert split_unit(name) == expected


# ----------------------------------------------------------------- position norms


def test_evaluate_adds_horizontal_and_3d_position_errors():
    sr, metrics = integrated_run()
    sc = sr.scenario
    window = sc.times >= sc.evaluation.skip_initial
    in_fault = sc.fault_mask() & window
    for name, m in metrics.items():
        e = sr.results[name].error[..., :3]  # computed - true position
        horizontal = np.hypot(e[..., 0], e[..., 1])
        full = np.linalg.norm(e, axis=-1)
        for key, err in (("pos_horizontal_m", horizontal), ("pos_3d_m", full)):
            per_run = np.sqrt(np.mean(err[:, window] ** 2, axis=1))
            assert m.rmse[key] == pytest.approx(per_run.mean(), rel=1e-12), (name, key)
            inside = np.sqrt(np.mean(err[:, in_fault] ** 2, axis=1)).mean()
            assert m.rmse_fault[key] == pytest.approx(inside, rel=1e-12)
            assert m.max_abs_error[key] == pytest.approx(err[:, window].max())
        assert set(m.rmse_nofault) == set(METRIC_STATES) | set(POSITION_NORMS)
        ff = m.fault_free.rmse_fault_window
        e_ff = sr.fault_free[name].error[..., :3]
        h_ff = error_stats(np.hypot(e_ff[..., 0], e_ff[..., 1])[..., None], in_fault).rmse[0]
        assert ff["pos_horizontal_m"] == pytest.approx(h_ff, rel=1e-12)
        assert m.rmse["pos_horizontal_m"] <= m.rmse["pos_3d_m"]


def test_linear_metrics_have_no_position_norms():
    _, metrics = north_ramp_run()
    assert set(metrics["ckf"].rmse) == {"E", "N"}


# ------------------------------------------------------------------- estimates.nc


@pytest.mark.parametrize("which", ["linear", "integrated"])
def test_estimates_nc_has_units_and_a_method_name_dimension(which, tmp_path):
    xr = pytest.importorskip("xarray")
    from ftnav.io.results import write_estimates

    result = north_ramp_run()[0] if which == "linear" else integrated_run()[0]
    paths = write_estimates(result, tmp_path)
    assert [p.name for p in paths] == ["estimates.nc", "estimates_fault_free.nc"]
    # a linear run's estimate x_hat; an integrated run's output errors (computed - true)
    var, field = ("x_hat", "estimate") if which == "linear" else ("error", "error")
    with xr.open_dataset(paths[0]) as ds:
        assert ds[var].dims == ("method_name", "run", "time", "state")
        assert ds["fault_flag"].dims == ("method_name", "run", "time", "sensor")
        ckf = ds[var].sel(method_name="ckf")  # no clash with .sel(method=...)
        np.testing.assert_array_equal(ckf.values, getattr(result.results["ckf"], field))
        assert int(ds.fault_flag.sel(method_name="ckf").max()) == -1
        assert int(ds.fault_flag.sel(method_name="fkf-chi2").max()) == 1
        for name in [*ds.data_vars, *ds.coords]:
            attrs = ds[name].attrs
            assert attrs.get("units"), name
            assert attrs.get("long_name"), name
        units = dict(zip(ds.state.values, ds.state_units.values, strict=True))
        if which == "linear":
            assert units == {"E": "state units", "N": "state units"}
            assert "state units" in ds.x_hat.attrs["units"]
        else:
            assert units["pos_N_m"] == "m" and units["vel_E_m_s"] == "m/s"
            assert units["att_U_arcmin"] == "arcmin"
        assert ds.time.attrs["units"] == "s"
        assert ds.time.dtype == np.float64  # seconds stay numbers, not timedeltas
        assert math.isnan(float(ds.beta.sel(method_name="ckf").max()))
