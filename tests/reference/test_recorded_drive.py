"""Real data with a reference: the vendored rtklibexplorer drive and walk (MEMS IMU + RTK).

Oracles: the RTK fixes (Q = 1, cm-level) as the reference of the horizontal error; the
exact-fusion equivalence (fusion-reset federated and distributed filters equal the
centralized one on the same linearization); pyins 1.0's published-in-the-issue anchor on
the same drive and outage schedule (RMS over outages of the maximum horizontal drift,
15 s outages every 60 s from 40 s: 6.9 m with a non-holonomic constraint), measured again
beside ftnav by ``benchmarks/bench_recorded.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from recording_runs import drive_copy, process, traces_of

from ftnav.io.recording_file import load_recording
from ftnav.model.scenario import Fault
from ftnav.recordings import recording_path


def _process(name, **kw):
    return process(recording_path(name), **kw)


@pytest.fixture(scope="module")
def drive():
    return _process("rtklib-drive", methods=["ckf", "fkf-fr", "dkf"])


def test_gnss_on_horizontal_error_against_the_rtk_fixes(drive):
    _, _, scores = drive
    assert scores["ckf"].horizontal_rms_m <= 0.10
    assert scores["ckf"].reference_epochs > 2000


def test_fusion_reset_federated_and_distributed_equal_the_centralized_filter(drive):
    _, traces, _ = drive
    p = traces["ckf"].solution.p[0]
    R = 6.4e6
    for name in ("fkf-fr", "dkf"):
        q = traces[name].solution.p[0]
        d = np.abs(p - q) * np.array([R, R * np.cos(p[:, 0]).max(), 1.0])
        assert d.max() < 1e-6, (name, d.max())


def test_15_s_outages_with_the_vehicle_constraints_beat_pyins_with_nhc():
    _, _, scores = _process("rtklib-drive", methods=["ckf"], outage=(15.0, 60.0, 40.0))
    o = scores["ckf"].outages
    assert o is not None and o.count == 8
    assert o.rms_max_error_m < 6.9


def test_the_walk_runs_every_method_with_its_repeated_rows_counted():
    loaded, traces, scores = _process("rtklib-walk")
    assert loaded.counts["imu"]["repeated_rows_dropped"] == 6958
    for name, tr in traces.items():
        assert np.isfinite(tr.solution.p).all() and scores[name].nan_epochs == 0
        assert scores[name].horizontal_rms_m < 0.5


def _step_5_m():
    t0 = 1752003400.0
    fault = Fault("gnss", "bias", t0, t0 + 60.0, np.array([0.0, 5.0, 0.0, 0.0, 0.0, 0.0]))
    _, traces, scores = _process("rtklib-drive", methods=["fkf-chi2"], faults=[fault])
    return scores["fkf-chi2"]


def test_a_5_m_gnss_step_is_detected_on_real_noise():
    """The receiver's positions and velocities are two aids (rtklib-drive.toml): the
    position aid's test isolates the step at once while the velocities keep the INS
    honest, and the aid is back once the step ends.  (With one 6-row aid the step was
    re-admitted after ~57 s of velocity-free dead reckoning, and the return to the true
    positions read as a second fault: false alarms 0.05.)"""
    score = _step_5_m()
    assert score.detection is not None
    d = score.detection["gnss"]
    assert d.event_rate == 1.0 and d.mean_delay_s <= 1.0
    assert d.mean_recovery_s <= 5.0 and d.false_alarm_rate <= 0.01 and d.readmitted == 1.0
    assert score.horizontal_rms_m <= 0.10


@pytest.mark.xfail(
    strict=True,
    reason=(
        "a lasting step beside aids of its rate only is taken after the patience (10 s): "
        "flagged for 18 % of the fault's epochs (docs/integrity.md §1.3, the due jump)"
    ),
)
def test_a_5_m_gnss_step_stays_isolated_for_its_60_s():
    """Held for the whole step, the fault would never reach the solution.  A lasting
    offset of the fixes beside their velocities, NHC and ZUPT is one the other aids
    cannot judge (a constant position offset has no rate): it looks the same as the end
    of a slow ramp the filter had followed, whose offset must be taken within the
    patience (the drive's 0.01 m/s ramp of 300 s held to the end of the run: 3.35 m
    after it against ``ckf``'s 0.17 m).  This step was held for its 60 s only while the
    hold's patience, ending between the fixes, released it with nothing taken (the
    same step east was taken 10 s in); now it is taken 10.7 s in as well (``ckf``, which
    follows it, 4.9 m during it; after it both back at 0.06 m)."""
    assert _step_5_m().detection["gnss"].rate >= 0.95


def test_without_a_fault_the_chi_square_test_rarely_isolates_an_aid(drive):
    """False alarms per epoch on real noise, every aid of the fault-free drive."""
    loaded, _, _ = drive
    _, traces, _ = _process("rtklib-drive", methods=["fkf-chi2"])
    flags = traces["fkf-chi2"].flag[0]
    names = loaded.recording.sensor_names
    rate = dict(zip(names, flags.mean(0), strict=True))
    assert rate["gnss"] <= 0.01 and rate["gnss-vel"] <= 0.01 and rate["nhc"] <= 0.01, rate


def test_the_receiver_as_two_aids_equals_the_receiver_as_one_for_the_centralized_filter(
    tmp_path,
):
    """Equivalence: independent rows (diagonal R) updated one aid after the other give
    the joint update, so ``rows = "position"`` + ``rows = "velocity"`` is the 6-row aid.
    Both halves at the antenna: the drive file leaves the velocities' 5 cm arm off
    (``rtklib-drive.toml``), and the one aid carries the positions' arm to its
    velocity rows (their rotation ``C(ω × l)``, 1 cm apart over the 60 s if not)."""

    def short(doc):
        doc["filter"]["duration_s"] = 60.0
        doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]
        doc["aids"][1]["lever_arm_m"] = doc["aids"][0]["lever_arm_m"]

    def one_aid(doc):
        short(doc)
        pos, vel = doc["aids"][0], doc["aids"][1]
        one = dict(pos, rows="position-velocity", vel_white_sigma_m_s=vel["vel_white_sigma_m_s"])
        doc["aids"] = [one] + doc["aids"][2:]

    sols = [
        traces_of(load_recording(drive_copy(tmp_path / f"{i}.toml", edit)))["ckf"].solution.p[0]
        for i, edit in enumerate((short, one_aid))
    ]
    d = np.abs(sols[0] - sols[1]) * np.array([6.4e6, 6.4e6, 1.0])
    assert d.max() < 1e-6, d.max()


def _short_drive(tmp_path, pos_text=None, per_epoch=False):
    """The drive's first 30 s of filtering, the centralized filter (a rewritten .pos
    when ``pos_text`` is given)."""

    def edit(doc):
        doc["filter"]["duration_s"] = 30.0
        doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]
        for a in doc["aids"][:2]:
            if pos_text is not None:
                pos = tmp_path / "gnss.pos"
                pos.write_text(pos_text)
                a["file"] = str(pos)
            a["per_epoch_sigma"] = per_epoch

    loaded = load_recording(drive_copy(tmp_path / f"short-{per_epoch}.toml", edit))
    return traces_of(loaded)["ckf"].solution.p[0]


def _pos_with_sigma(sd_pos: float, sd_vel: float) -> str:
    """The drive's .pos with every epoch's sdn, sde, sdu and sdvn, sdve, sdvu replaced."""
    src = recording_path("rtklib-drive").parent / "data/rtklibexplorer/drive_0708/gnss_1934_sf.pos"
    lines = []
    for ln in src.read_text().splitlines():
        f = ln.split()
        if not ln.startswith("%") and len(f) >= 21:
            f[7:10] = [f"{sd_pos:.4f}"] * 3
            f[18:21] = [f"{sd_vel:.4f}"] * 3
            ln = " ".join(f)
        lines.append(ln)
    return "\n".join(lines) + "\n"


def test_per_epoch_sigma_from_the_pos_file_is_the_configured_filter_when_they_agree(tmp_path):
    """Equivalence: a .pos whose σ columns equal the aids' configured σ (0.05 m, 0.1 m/s)
    gives the filter without per-epoch σ exactly; other σ change it."""
    same = _pos_with_sigma(0.05, 0.1)
    plain = _short_drive(tmp_path, same, per_epoch=False)
    np.testing.assert_array_equal(_short_drive(tmp_path, same, per_epoch=True), plain)
    other = _short_drive(tmp_path, _pos_with_sigma(0.5, 1.0), per_epoch=True)
    assert np.abs(other - plain).max() * 6.4e6 > 1e-3


# every rule but "information", which needs constant measurement matrices (refused for a
# linearized system in one line: tests/validation)
SHARING = ["equal", "trace", "eigen-trace", "frobenius", "inverse-trace"]


def test_every_architecture_mode_and_sharing_rule_runs_on_the_drive(tmp_path):
    """Point 5 of issue 15: every federated mode and sharing rule (fixed shares too),
    the distributed filter with VB and with chi-square isolation, a centralized chi-square
    filter, on 30 s of the real drive (four aids): finite, and every fusion that is
    exact with fusion reset at every epoch equals the centralized solution."""
    chi2 = {"kind": "residual-chi2", "false_alarm_probability": 1e-3}
    methods = [{"name": "ckf", "architecture": "centralized"}]
    methods += [
        {"name": f"fr-{s}", "architecture": "federated", "mode": "fusion-reset", "sharing": s}
        for s in SHARING
    ]
    methods += [
        {"name": f"nr-{s}", "architecture": "federated", "mode": "no-reset", "sharing": s}
        for s in SHARING
    ]
    fixed = {"sharing": "fixed", "betas": [0.4, 0.3, 0.2, 0.1]}
    methods += [
        {"name": "fr-fixed", "architecture": "federated", "mode": "fusion-reset", **fixed},
        {"name": "zr", "architecture": "federated", "mode": "zero-reset"},
        {"name": "zr-chi2", "architecture": "federated", "mode": "zero-reset", "detector": chi2},
        {"name": "dkf-vb", "architecture": "distributed", "noise": {"kind": "vb"}},
        {"name": "dkf-chi2", "architecture": "distributed", "detector": chi2},
        {"name": "ckf-chi2", "architecture": "centralized", "detector": chi2},
        {
            "name": "ckf-vb",
            "architecture": "centralized",
            "noise": {"kind": "vb", "sensors": ["gnss"]},
        },
    ]

    def edit(doc):
        doc["filter"]["duration_s"] = 30.0
        doc["methods"] = methods

    traces = traces_of(load_recording(drive_copy(tmp_path / "all.toml", edit)))
    assert len(traces) == len(methods)
    ckf = traces["ckf"].solution.p[0]
    for name, tr in traces.items():
        assert np.isfinite(tr.solution.p).all() and np.isfinite(tr.x).all(), name
        assert (tr.P_diag > 0).all(), name
        if name.startswith("fr-") or name == "zr":
            d = np.abs(tr.solution.p[0] - ckf) * np.array([6.4e6, 6.4e6, 1.0])
            assert d.max() < 1e-6, (name, d.max())
