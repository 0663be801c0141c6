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

from ftnav.engine import navigation_model
from ftnav.engine.driver import run
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import Reference, score_recording
from ftnav.io.recording_file import load_recording
from ftnav.model.scenario import Fault
from ftnav.recordings import recording_path


def _process(name, **kw):
    loaded = load_recording(recording_path(name), **kw)
    rec = loaded.recording
    traces = run(
        navigation_model(rec),
        loaded.stream,
        build_filters(rec, rec.system(), rec.methods),
        rec.steps,
    )
    ref = Reference(loaded.reference_index, loaded.reference_p)
    return loaded, traces, score_recording(rec, traces, ref, loaded.outages)


@pytest.fixture(scope="module")
def drive():
    return _process("rtklib-drive", methods=["ckf", "fkf-fr", "dkf"])


def test_gnss_on_horizontal_error_against_the_rtk_fixes(drive):
    _, _, scores = drive
    assert scores["ckf"]["horizontal_rms_m"] <= 0.10
    assert scores["ckf"]["reference_epochs"] > 2000


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
    o = scores["ckf"]["outages"]
    assert o["count"] == 8
    assert o["rms_max_error_m"] < 6.9


def test_the_walk_runs_every_method_with_its_repeated_rows_counted():
    loaded, traces, scores = _process("rtklib-walk")
    assert loaded.counts["imu"]["repeated_rows_dropped"] == 6958
    for name, tr in traces.items():
        assert np.isfinite(tr.solution.p).all() and scores[name]["nan_epochs"] == 0
        assert scores[name]["horizontal_rms_m"] < 0.5


@pytest.mark.xfail(
    strict=True,
    reason="measured: Pd 0.96 and re-admission 0.1 s, but false alarms 0.28 per epoch "
    "outside the fault: the federated chi-square test isolates GNSS in the parking lot "
    "(NIS mean 36 around t = 437 s) and does not re-admit it for ~50 s (issue 15 note)",
)
def test_a_5_m_gnss_step_is_detected_on_real_noise():
    t0 = 1752003400.0
    fault = Fault("gnss", "bias", t0, t0 + 60.0, np.array([0.0, 5.0, 0.0, 0.0, 0.0, 0.0]))
    _, _, scores = _process("rtklib-drive", methods=["fkf-chi2"], faults=[fault])
    d = scores["fkf-chi2"]["detection"]["gnss"]
    assert d["pd"] >= 0.95 and d["mean_recovery_s"] <= 5.0 and d["false_alarm_rate"] <= 0.01
