"""Result figures: files written, at most 4 method lines per axes, titles from the scenario.

Oracles: the PNG signature; the Line2D objects of every axes of the returned figures
(never more than MAX_FIGURE_METHODS method lines); the suptitle text; matplotlib stays
out of ``import ftnav``.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ftnav.eval.montecarlo import run_scenario
from ftnav.fusion.registry import method_config
from ftnav.model.scenario import MAX_FIGURE_METHODS, Fault, Scenario
from ftnav.model.system import LinearModel, Sensor

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _tiny_scenario() -> Scenario:
    F = np.array([[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]])
    Q = np.diag([5.0, 2.0, 3.0])
    model = LinearModel(("s", "v", "a"), F, Q, np.zeros(3), 100.0 * np.eye(3), Q)
    R = np.array([[30.0]])
    sensors = tuple(
        Sensor(f"pos{i + 1}", np.array([[h, 0.0, 0.0]]), R, R)
        for i, h in enumerate((1.0, 2.5, 0.5))
    )
    faults = (Fault("pos1", "bias", 30.0, 50.0, np.array([60.0])),)
    methods = (
        method_config("centralized", name="centralized"),
        method_config(
            "federated",
            name="fed-inverse-trace-chi2",
            sharing="inverse-trace",
            detector={"kind": "residual-chi2", "prior": "global"},
        ),
        method_config("federated", name="fed-trace", sharing="trace"),
    )
    return Scenario(
        name="tiny",
        dt=1.0,
        steps=100,
        model=model,
        sensors=sensors,
        faults=faults,
        methods=methods,
    )


@pytest.fixture(scope="module")
def result():
    return run_scenario(_tiny_scenario(), runs=3, seed=1)


def test_save_all_writes_valid_pngs(result, tmp_path):
    from ftnav.plot import save_all

    paths = save_all(result, tmp_path)
    names = ["error_no_fault.png", "error_fault.png", "sharing.png", "fault_flags.png"]
    assert [p.name for p in paths] == names
    for name in names:
        path = tmp_path / name
        assert path.is_file()
        data = path.read_bytes()
        assert data[:8] == PNG_SIGNATURE
        assert len(data) > 10_000


def test_figure_functions_return_figures(result):
    from matplotlib.figure import Figure

    from ftnav.plot import error_figure, fault_flag_figure, sharing_figure

    for ff in (False, True):
        fig = error_figure(result, fault_free=ff, states=[0])
        assert isinstance(fig, Figure)
        assert len(fig.axes) == 2  # run 0 and RMS of the one state
    assert len(error_figure(result).axes) == 6  # every state by default
    assert len(sharing_figure(result).axes) == 2  # the two federated methods
    assert len(fault_flag_figure(result).axes) == 1  # only one method has a detector
    with pytest.raises(ValueError, match="unknown method"):
        error_figure(result, methods=["nope"])
    with pytest.raises(ValueError, match="states"):
        error_figure(result, states=[3])
    with pytest.raises(ValueError, match="unknown state"):
        error_figure(result, states=["x"])


def test_import_ftnav_does_not_import_matplotlib():
    code = "import ftnav, ftnav.plot, sys; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ------------------------------------------------------ figures per state, few methods


def _method_lines(ax) -> int:
    return len(ax.get_lines())


def test_default_figures_split_the_methods_at_most_four_per_axes(tmp_path):
    from output_problems import north_ramp_run

    from ftnav.plot.figures import default_figures, draw_figure, method_groups, save_all

    result, _ = north_ramp_run()
    sc = result.scenario
    groups = method_groups(sc, list(result.results))
    assert groups == [
        ("ckf", "fkf-equal", "fkf-trace", "fkf-inverse-trace"),
        ("ckf", "fkf-oracle", "fkf-chi2", "dkf"),
    ]
    specs = default_figures(result)
    assert [s.name for s in specs] == [
        "error_no_fault",
        "error_fault",
        "error_no_fault_2",
        "error_fault_2",
    ]
    for spec in specs:
        fig = draw_figure(result, spec)
        assert len(fig.axes) == 2 * 2  # (run 0, RMS) x (E, N)
        for ax in fig.axes:
            assert _method_lines(ax) == len(spec.methods) <= MAX_FIGURE_METHODS
        title = fig.get_suptitle()
        assert "my-north-ramp" in title and "Paper" not in title
        assert sc.description in title
    names = [p.name for p in save_all(result, tmp_path)]
    assert names == [f"{s.name}.png" for s in specs] + ["sharing.png", "fault_flags.png"]


def test_error_figure_refuses_more_than_four_methods():
    from output_problems import north_ramp_run

    from ftnav.plot.figures import error_figure

    result, _ = north_ramp_run()
    with pytest.raises(ValueError, match="at most 4 methods"):
        error_figure(result, methods=list(result.results)[:5])
    fig = error_figure(result)  # default: the first group only
    assert all(_method_lines(ax) == 4 for ax in fig.axes)


def test_figure_section_names_methods_states_and_title(tmp_path):
    from dataclasses import replace

    from output_problems import north_ramp_run

    from ftnav.model.scenario import FigureSpec
    from ftnav.plot.figures import draw_figure, save_all

    result, _ = north_ramp_run()
    spec = FigureSpec("north", "North channel under the ramp", ("ckf", "fkf-oracle"), ("N",))
    result = result._replace(scenario=replace(result.scenario, figures=(spec,)))
    fig = draw_figure(result, spec)
    assert len(fig.axes) == 2
    assert [_method_lines(ax) for ax in fig.axes] == [2, 2]
    assert [line.get_label() for line in fig.axes[0].get_lines()] == ["ckf", "fkf-oracle"]
    assert fig.axes[0].get_title().startswith("N")
    assert fig.get_suptitle().startswith("North channel under the ramp\nscenario 'my-north-ramp'")
    paths = save_all(result, tmp_path)
    assert [p.name for p in paths] == ["north.png", "sharing.png", "fault_flags.png"]
    assert paths[0].read_bytes()[:8] == PNG_SIGNATURE


def test_builtin_seed000_figures_are_the_paper_comparisons():
    from ftnav.io.scenario_file import load_scenario
    from ftnav.scenarios import builtin_path

    sc = load_scenario(builtin_path("seed000"))
    figs = {f.name: f for f in sc.figures}
    assert list(figs) == [
        "paper000_fig3",
        "paper000_fig4a",
        "paper000_fig4b",
        "appendix_fig3_all_states",
        "appendix_fig4a_all_states",
        "appendix_fig4b_all_states",
        "other_architectures",
    ]
    # the paper's figures: its two methods, one panel (the displacement s)
    assert figs["paper000_fig3"].condition == "fault-free"
    assert figs["paper000_fig3"].methods == ("fkf-fr-eigen-trace", "fkf-fr-inverse-trace")
    assert figs["paper000_fig4a"].methods == ("fkf-fr10-trace", "fkf-fr10-inverse-trace")
    assert figs["paper000_fig4b"].methods == ("fkf-fr-eigen-trace", "fkf-inverse-trace-rbf")
    for name in ("paper000_fig3", "paper000_fig4a", "paper000_fig4b"):
        assert figs[name].states == ("s",), name
    # the appendix: every state
    assert all(figs[n].states == () for n in figs if n.startswith("appendix_"))
    assert all(len(f.methods) <= MAX_FIGURE_METHODS for f in sc.figures)
    assert figs["paper000_fig4a"].title.startswith("Paper 000 Fig. 4a")


def test_integrated_figures_per_state_and_titles_from_the_scenario(tmp_path):
    from output_problems import integrated_run

    from ftnav.plot.integrated import default_figures, draw_figure, save_integrated

    result, _ = integrated_run()
    specs = default_figures(result)
    names = [s.name for s in specs]
    assert names[:3] == ["errors_position", "errors_velocity", "errors_attitude"]
    assert "vb_noise_dkf-vb_gnss" in names and "local_fused_fkf-chi2" in names
    n_aids = len(result.scenario.sensor_names)
    for spec in specs:
        fig = draw_figure(result, spec)
        title = fig.get_suptitle()
        assert "my-flight" in title and "Paper" not in title, spec.name
        lines = [_method_lines(ax) for ax in fig.axes]
        if spec.kind == "errors":
            assert len(fig.axes) == len(spec.states)
            assert lines == [len(spec.methods)] * len(spec.states)
        elif spec.kind == "local-fused":
            locals_ = n_aids if result.results[spec.methods[0]].local is not None else 0
            assert lines == [locals_ + len(spec.methods)] * 2
        else:  # vb-noise: one panel per GNSS row, each method's sigma and the true sigma
            assert lines == [len(spec.methods) + 1] * 6
    assert [s.states for s in specs[:1]] == [("pos_E_m", "pos_N_m", "pos_U_m", "pos_horizontal_m")]
    paths = save_integrated(result, tmp_path)
    assert [p.name for p in paths] == [f"{n}.png" for n in names]


def test_integrated_local_fused_of_several_methods_and_bad_input():
    from output_problems import integrated_run

    from ftnav.plot.integrated import local_fused_figure, method_error_figure, vb_noise_figure

    result, _ = integrated_run()
    fig = local_fused_figure(result, ["fkf-chi2", "ckf", "dkf-vb"], states=["pos_N_m"])
    labels = [line.get_label() for line in fig.axes[0].get_lines()]
    assert labels == [
        "SINS/gnss local (fkf-chi2)",
        "SINS/ads local (fkf-chi2)",
        "fused (fkf-chi2)",
        "fused (ckf)",
        "fused (dkf-vb)",
    ]
    with pytest.raises(ValueError, match="at most 4"):
        local_fused_figure(result, ["ckf"] * 5)
    with pytest.raises(ValueError, match="position states"):
        local_fused_figure(result, "ckf", states=["vel_E_m_s"])
    with pytest.raises(ValueError, match="quantity"):
        method_error_figure(result, ["ckf"], "speed")
    with pytest.raises(ValueError, match="unknown sensor"):
        vb_noise_figure(result, "dkf-vb", "cns")
