"""The claims of issue 16: paper 000 Fig. 4a's mechanism, paper 001 Figs. 4-5 on the
neuron output, paper 002 Fig. 5 (VB tracking of the ramp), the up velocity of Figs. 2/4
and the distributed VB filter with chi-square isolation.

Oracles: small runs of the built-ins (the β of a linear filter cannot depend on the
measurements, so the mechanism claim must report bit-identical histories), and results
built by hand whose answer is known (a fused error below or above every local's, a VB
estimate that is the true σ delayed by a known lag).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import MethodResult, ScenarioResult, run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.report.claims import _neural_fig4, _neural_fig5, _vb_tracking, check_claims
from ftnav.scenarios import builtin_path


def _builtin(name):
    return load_scenario(builtin_path(name))


def _by_id(claims):
    return {c["id"]: c for c in claims}


# --- paper 000 Fig. 4a: beta of the faulty filter with and without the fault ---------------


@pytest.fixture(scope="module")
def seed000_beta():
    sc = _builtin("seed000")
    keep = ("fkf-fr-inverse-trace", "fkf-fr10-inverse-trace", "fkf-fr10-trace")
    sc = replace(sc, steps=600, methods=tuple(m for m in sc.methods if m.name in keep))
    result = run_scenario(sc, 2, 1)
    return result, evaluate(result)


def test_beta_mechanism_reports_identical_histories_in_the_linear_model(seed000_beta):
    result, metrics = seed000_beta
    c = _by_id(check_claims(result, metrics))["p000-fig4a-beta"]
    assert c["checked"] and c["holds"] is False
    assert set(c["measured"]) == {"fkf-fr-inverse-trace", "fkf-fr10-inverse-trace"}
    for v in c["measured"].values():
        assert v["bit_identical"] and v["max_abs_difference_any_epoch"] == 0.0
        assert v["relative_drop"] == 0.0
        assert 0.0 < v["beta_in_window_with_fault"] < 1.0
    assert "bit-identical" in c["note"]


def test_beta_mechanism_holds_when_the_faulty_beta_drops(seed000_beta):
    result, metrics = seed000_beta
    t = result.scenario.times
    w = (t >= 300.0) & (t < 500.0)
    lowered = {}
    for name, res in result.results.items():
        beta = res.beta.copy()
        beta[:, w, 0] *= 0.5  # pos1, the faulty sensor, loses half its share in the window
        lowered[name] = replace(res, beta=beta)
    c = _by_id(check_claims(result._replace(results=lowered), metrics))["p000-fig4a-beta"]
    assert c["holds"] is True
    for v in c["measured"].values():
        assert v["relative_drop"] == pytest.approx(0.5)
        assert not v["bit_identical"]


# --- paper 001 Figs. 4 and 5: the neuron output (results built by hand) --------------------


def _fake(sc, errors, local=None, free_errors=None, free_local=None) -> ScenarioResult:
    """A ScenarioResult of ``sc`` whose methods have the given (B, K, 9) errors."""

    def mr(e, loc):
        B, K, n = e.shape
        return MethodResult(
            error=e,
            P_diag=np.ones_like(e),
            nees=np.ones((B, K)),
            nan_count=np.zeros((B, 3), int),
            local=loc,
        )

    results = {n: mr(e, (local or {}).get(n)) for n, e in errors.items()}
    free = {n: mr(e, (free_local or {}).get(n)) for n, e in (free_errors or errors).items()}
    return ScenarioResult(sc, 2, 1, results, free)


def _seed001(steps=300):
    return replace(_builtin("seed001"), steps=steps)


def test_fig4_compares_the_fault_free_neuron_output_with_its_own_locals():
    sc = _seed001()
    B, K = 2, sc.steps
    local = np.zeros((B, K, 3, 3))
    local[..., 0, :2] = 3.0  # gps: 3 m East and North
    local[..., 1, :2] = 10.0
    local[..., 2, :2] = 50.0
    better = np.zeros((B, K, 9))
    better[..., :2] = 2.0
    worse = better.copy()
    worse[..., 1] = 4.0  # North (latitude) worse than the GPS local's 3 m
    faulty = np.full((B, K, 9), 100.0)  # the run with faults must not be used
    c = _neural_fig4(
        _fake(sc, {"neural-chi2": faulty}, None, {"neural-chi2": better}, {"neural-chi2": local})
    )[0]
    assert c["id"] == "p001-fig4" and c["holds"] is True
    assert c["measured"]["fused_horizontal_rmse_m"] == pytest.approx(np.hypot(2.0, 2.0))
    assert c["measured"]["local_latitude_rmse_m"] == pytest.approx(
        {"gps": 3.0, "tan": 10.0, "dns": 50.0}
    )
    c = _neural_fig4(
        _fake(sc, {"neural-chi2": faulty}, None, {"neural-chi2": worse}, {"neural-chi2": local})
    )[0]
    assert c["holds"] is False and c["measured"]["fused_latitude_rmse_m"] == pytest.approx(4.0)


def test_fig5_measures_longitude_in_the_dns_window_of_the_second_flight():
    sc = replace(_seed001(), name="seed001@seed001b")
    B, K = 2, sc.steps
    t = sc.times
    dns = next(f for f in sc.faults if f.sensor == "dns")
    w = (t >= dns.start + 10.0) & (t < dns.end)

    def east(inside, outside=1.0):
        e = np.zeros((B, K, 9))
        e[..., 0] = outside
        e[:, w, 0] = inside
        return e

    free = {"neural-chi2": east(2.0), "fkf-nr-chi2": east(2.0)}
    ok = _fake(sc, {"neural-chi2": east(2.5), "fkf-nr-chi2": east(2.0)}, None, free)
    c = _neural_fig5((ok, None))[0]
    assert c["id"] == "p001-fig5" and c["holds"] is True
    assert c["measured"]["window_s"] == [dns.start + 10.0, dns.end]
    assert c["measured"]["ratio_to_fault_free"] == pytest.approx(1.25)
    bad = _fake(sc, {"neural-chi2": east(4.0), "fkf-nr-chi2": east(2.0)}, None, free)
    c = _neural_fig5((bad, None))[0]
    assert c["holds"] is False and c["measured"]["ratio_to_federated"] == pytest.approx(2.0)
    # no second flight, no claim
    assert _neural_fig5(None) == []


# --- paper 002: VB tracking of the ramp (closed form), up velocity, VB with chi-square -------


def test_vb_tracking_finds_a_known_lag_and_error():
    sc = _builtin("seed002")
    ramp = next(f for f in sc.faults if f.kind == "noise-ramp")
    t = sc.times
    sigma = 1.0 + 4.0 * np.clip((t - ramp.start) / (ramp.end - ramp.start), 0.0, 1.0)
    sigma[t >= ramp.end] = 1.0
    truth = np.stack([sigma, 2.0 * sigma], axis=1)
    lag = 37
    est = np.vstack([np.repeat(truth[:1], lag, 0), truth[:-lag]])  # truth delayed by 37 s
    got = _vb_tracking(sc, est, truth, ramp, rho=0.99)
    assert got["lag_s"] == [37.0, 37.0]
    w = (t >= ramp.start) & (t < ramp.end)
    expected = np.mean(np.abs(est[w, 0] / truth[w, 0] - 1.0))
    assert got["mean_relative_error"][0] == pytest.approx(expected)
    assert got["mean_relative_error"][1] == pytest.approx(expected)
    # a step has no lag reported
    step = next(f for f in sc.faults if f.kind == "noise-scale")
    assert "lag_s" not in _vb_tracking(sc, truth, truth, step, rho=0.99)


@pytest.fixture(scope="module")
def ramp002():
    """seed002 cut to 3200 s (both anomalies inside), 2 runs, the four compared methods."""
    sc = _builtin("seed002")
    keep = ("ckf", "fkf-chi2", "dkf-vb", "dkf-vb-chi2")
    sc = replace(sc, steps=3200, methods=tuple(m for m in sc.methods if m.name in keep))
    result = run_scenario(sc, 2, 1)
    return result, evaluate(result)


def test_seed002_new_claims_are_measured(ramp002):
    result, metrics = ramp002
    claims = _by_id(check_claims(result, metrics))
    for kind in ("noise-scale", "noise-ramp"):
        c = claims[f"p002-up-velocity-{kind}"]
        assert c["checked"], c
        m = c["measured"]
        assert m["fkf_up_velocity_growth"] == pytest.approx(
            m["up_velocity_rmse_m_s"]["fkf-chi2"] / m["up_velocity_rmse_fault_free_m_s"]["fkf-chi2"]
        )
        assert c["holds_point"] is (m["fkf_up_velocity_growth"] <= 3.0)
        # the verdict is the interval's (issue 23): with 2 runs it decides only what the
        # interval decides, and never against the point estimate
        (ci,) = c["intervals"]
        assert ci["value"] == pytest.approx(m["fkf_up_velocity_growth"])
        assert ci["runs"] == 2
        bounded = math.isfinite(ci["lo"]) and math.isfinite(ci["hi"])  # Fieller may not be
        assert not bounded or ci["lo"] <= ci["value"] <= ci["hi"]
        decided = None
        if bounded:
            decided = True if ci["hi"] < 3.0 else False if ci["lo"] > 3.0 else None
        assert c["holds"] is decided and decided in (None, c["holds_point"])
    assert claims["p002-up-velocity-noise-scale"]["source"] == "paper 002 §2.3, Fig. 2"
    assert claims["p002-up-velocity-noise-ramp"]["source"] == "paper 002 §2.3, Fig. 4"
    vb = claims["p002-vb-ramp"]
    assert vb["checked"] and vb["source"].startswith("paper 002 §2.3, Fig. 5")
    assert len(vb["measured"]["lag_s"]) == 6 and vb["measured"]["vb_memory_s"] == 100.0
    assert vb["holds"] is bool(
        max(vb["measured"]["mean_relative_error"]) <= 0.25 and max(vb["measured"]["lag_s"]) <= 100
    )
    c = claims["p002-dkf-vb-chi2"]
    assert c["checked"] and set(c["measured"]) == {"noise-scale", "noise-ramp"}
    for v in c["measured"].values():
        assert 0.0 <= v["gnss_flag_rate_in_window"] <= 1.0
        assert set(v["horizontal_rmse_m"]) == {"dkf-vb-chi2", "dkf-vb", "fkf-chi2"}
        # a flagged VB local keeps adapting its R-hat, so GNSS comes back: never locked out
        # (before: flagged 100 % of the window, never re-admitted, 83.6 m / 350 m)
        assert v["runs_never_readmitted"] == 0 and v["gnss_flag_rate_in_window"] < 0.5, v
        rmse = v["horizontal_rmse_m"]
        assert rmse["dkf-vb-chi2"] <= 1.5 * rmse["dkf-vb"], rmse
    assert claims["p002-vb-sigma"]["source"] == "paper 002 §2.3, Fig. 3; spec §7"


def test_the_neuron_intent_claim_checks_best_local_federated_and_each_fault_window():
    """Issue 16 point 2, with known answers: fault-free 2.83 m against a best local of
    4.24 m and a federated 2.83 m holds; a fault window 2x its fault-free level, or a
    fused error above 1.5x the federated filter's, does not."""
    from ftnav.report.claims import _neuron_intent

    sc = _seed001(700)
    B, K = 2, sc.steps
    local = np.zeros((B, K, 3, 3))
    local[..., 0, :2] = 3.0  # gps: 4.24 m horizontal
    local[..., 1, :2] = 10.0
    local[..., 2, :2] = 50.0
    base = np.zeros((B, K, 9))
    base[..., :2] = 2.0  # 2.83 m horizontal
    errors = {"neural-chi2": base, "fkf-nr-chi2": base}
    locals_ = {"neural-chi2": local}
    (c,) = _neuron_intent(_fake(sc, errors, locals_, errors, locals_))
    assert c["id"] == "p001-intent-neural-chi2" and c["holds"] is True
    m = c["measured"]
    assert m["best_local_horizontal_rmse_m"] == pytest.approx(np.hypot(3.0, 3.0))
    assert set(m["in_fault_windows"]) == {"dns", "gps", "tan"}
    faulty = base.copy()
    gps = next(f for f in sc.faults if f.sensor == "gps")
    faulty[:, (sc.times >= gps.start) & (sc.times < gps.end), :2] = 4.0  # 2x in the window
    (c,) = _neuron_intent(_fake(sc, {**errors, "neural-chi2": faulty}, locals_, errors, locals_))
    assert c["holds"] is False
    assert c["measured"]["in_fault_windows"]["gps"]["rmse_m"] == pytest.approx(np.hypot(4, 4))
    good_fkf = {"neural-chi2": base, "fkf-nr-chi2": base / 2}  # federated 1.41 m: 2x better
    (c,) = _neuron_intent(_fake(sc, good_fkf, locals_, good_fkf, locals_))
    assert c["holds"] is False
