"""The 18-state SINS error model plugs into every fusion architecture (issue 3, item 6).

Φ_k, Q_k come from :func:`~ftnav.nav.error_model.discrete_model` evaluated along the
``seed001`` flight (1 s steps, 300 s from take-off through the climb and a turn) and
drive a time-varying linear model (:class:`~ftnav.model.system.TimeVarying` per-epoch
transitions, simulated by :func:`ftnav.sim.linear.simulate` and handed to the filters
with every epoch by :class:`ftnav.engine.linear.LinearModel`) with three aids of paper
002's kind: GNSS velocity (δv), star-tracker attitude (φ) and barometric height (δh).
Oracle: fusion-reset federated (any β), zero-reset and distributed filters equal the
centralized filter (spec §1.6, §6) within 1e-9, compared in units of the initial σ.
"""

from __future__ import annotations

import numpy as np
import pytest
from equivalence_problems import centralized, drive

from ftnav.fusion import registry
from ftnav.fusion.registry import method_config
from ftnav.io.profile_file import resolve_profile
from ftnav.model.scenario import Scenario
from ftnav.model.system import LinearModel, Sensor, TimeVarying
from ftnav.nav import attitude as at
from ftnav.nav.error_model import STATES_18, ErrorModelParams, NavState, discrete_model
from ftnav.sim.linear import simulate
from ftnav.sim.trajectory import generate

SECONDS = 300
ARCSEC = np.radians(1.0 / 3600.0)
DEG_H = np.radians(1.0) / 3600.0


@pytest.fixture(scope="module")
def problem():
    tr = generate(resolve_profile("seed001"))
    per_s = int(round(1.0 / tr.dt))
    starts = 9000 + per_s * np.arange(SECONDS)  # t = 90 s .. 390 s
    f_b = np.stack([tr.dv[s : s + per_s].sum(0) / (per_s * tr.dt) for s in starts])
    nav = NavState(
        tr.p[starts, 0],
        tr.p[starts, 1],
        tr.p[starts, 2],
        tr.v[starts],
        f_b,
        at.euler_to_dcm(tr.euler[starts]),
    )
    params = ErrorModelParams(  # paper 001 Table 1
        gyro_psd=(0.01 * np.radians(1.0) / 60.0) ** 2,
        gyro_markov_sigma=0.1 * DEG_H,
        gyro_markov_tau=7200.0,
        accel_markov_sigma=1e-4 * 9.80665,
        accel_markov_tau=1800.0,
    )
    Phi, Qk = discrete_model(*nav, params, 1.0)
    sig0 = (
        np.array([300, 300, 600] + [0.6] * 3 + [30, 30] + [5.0])
        * np.r_[[ARCSEC] * 3, [1.0] * 3, [ARCSEC] * 2, [1.0]]
    )
    sig0 = np.r_[sig0, [0.1 * DEG_H] * 6, [1e-4 * 9.80665] * 3]
    P0 = np.diag(sig0**2)
    model = LinearModel(STATES_18, Phi[0], Qk[0], np.zeros(18), P0, Qk[0])
    e = np.eye(18)
    sensors = (
        Sensor("gnss-vel", e[3:6], 0.05**2 * np.eye(3), 0.05**2 * np.eye(3)),
        Sensor("cns", e[0:3], (10 * ARCSEC) ** 2 * np.eye(3), (10 * ARCSEC) ** 2 * np.eye(3)),
        Sensor("baro", e[8:9], np.array([[25.0]]), np.array([[25.0]])),
    )
    sc = Scenario(name="ins18", dt=1.0, steps=SECONDS, model=model, sensors=sensors)
    system = sc.system()
    tv = TimeVarying(Phi, Qk)
    sim = simulate(sc, 2, 7, transitions=tv)
    return system, sim, sig0, tv, drive(centralized(system), sim, transitions=tv)


def _assert_same_scaled(traj, ref, sig0, rtol=1e-9):
    d = 1.0 / sig0
    np.testing.assert_allclose(traj.x * d, ref.x * d, rtol=0, atol=rtol)
    np.testing.assert_allclose(traj.P * d[:, None] * d, ref.P * d[:, None] * d, rtol=0, atol=rtol)


METHODS = {
    "FR equal": method_config("federated", name="fr", sharing="equal"),
    "FR inverse-trace + master": method_config(
        "federated", name="frm", sharing="inverse-trace", master_share=0.25
    ),
    "ZR": method_config("federated", name="zr", mode="zero-reset"),
    "distributed": method_config("distributed", name="dkf"),
}


@pytest.mark.parametrize("name", list(METHODS))
def test_fusion_on_the_sins_error_model_equals_ckf(problem, name):
    system, sim, sig0, tv, ref = problem
    filt = registry.build(system, METHODS[name])
    _assert_same_scaled(drive(filt, sim, transitions=tv), ref, sig0)


def test_the_aided_filter_is_consistent(problem):
    """The centralized filter's attitude/velocity errors stay within 4σ of its covariance."""
    system, sim, sig0, tv, ref = problem
    err = ref.x - sim.truth.states
    sd = np.sqrt(np.diagonal(ref.P, axis1=-2, axis2=-1))
    assert (np.abs(err[..., :9]) < 4.5 * sd[..., :9]).mean() > 0.99
