"""Bias compensation in the strapdown (issue 22 item 5; ``engine/ins.py`` step 5).

Oracles:

* equivalence with the mechanization's own bias arguments: an epoch of the engine's
  SINS with fed-back biases ``b`` equals :func:`ftnav.nav.mechanization.integrate` of the
  raw increments with ``gyro_bias``/``accel_bias = b`` (a separate code path: the biases
  subtracted sample by sample inside the strapdown);
* the closed-loop form against the open loop: with compensation the biases fed back so
  far (the running sum of the fused bias estimates) plus nothing else equal the bias
  states the uncompensated filter holds, to a small fraction of their σ over a short
  simulated flight (the error model is linear in the bias; what differs is second order);
* the trace's record of the compensated biases (``Trace.bias``) is that running sum;
* the settings refuse what cannot be compensated (a nav-frame bias; output correction).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftnav.engine import navigation_model
from ftnav.engine.driver import run
from ftnav.eval.montecarlo import build_filters
from ftnav.io.scenario_file import load_scenario
from ftnav.nav.mechanization import integrate
from ftnav.scenarios import builtin_path
from ftnav.sim.ins import simulate_ins

STEPS = 60


@pytest.fixture(scope="module")
def seed002():
    sc = load_scenario(builtin_path("seed002"))
    ckf = [m for m in sc.methods if m.architecture == "centralized"][:1]
    return replace(sc, steps=STEPS, methods=tuple(ckf), faults=())


def test_an_epoch_subtracts_the_fed_back_biases_as_the_strapdown_does(seed002):
    sc = replace(seed002, bias_compensation=True)
    sim = simulate_ins(sc, range(3), 5)
    model = navigation_model(sc)
    assert model.n_fed == sc.error_model.n
    state = model.start(sim.stream, 1)
    rng = np.random.default_rng(1)
    b = np.column_stack([rng.normal(0, 1e-4, (3, 3)), rng.normal(0, 1e-2, (3, 3))])
    state = state._replace(bias=b)
    after, _ = model.epoch(state, sim.stream, 1, 1)
    spe, imu = model.spe, sim.stream.imu
    expected, _ = integrate(
        state.ins,
        imu.dtheta[:, :spe],
        imu.dv[:, :spe],
        imu.dt,
        algorithm=model.algorithm,
        gyro_bias=b[:, :3],
        accel_bias=b[:, 3:],
    )
    for u, v in zip(after.ins, expected, strict=True):
        np.testing.assert_allclose(u, v, rtol=0, atol=1e-12)


def test_the_fed_back_biases_are_the_open_loop_bias_estimates(seed002):
    sim = simulate_ins(seed002, range(4), 11)
    traces = {}
    for on in (False, True):
        sc = replace(seed002, bias_compensation=on)
        system = sc.system()
        model = navigation_model(sc, system)
        (traces[on],) = run(
            model, sim.stream, build_filters(sc, system, sc.methods), STEPS
        ).values()
    n = seed002.error_model.n
    fed = np.cumsum(traces[True].x[..., 9:n], axis=1)  # fed back after every epoch
    open_loop = traces[False].x[..., 9:n]
    sigma = np.sqrt(traces[False].P_diag[..., 9:n])
    assert np.abs(open_loop).max() > 0  # the biases were estimated at all
    np.testing.assert_array_less(np.abs(fed - open_loop), 0.05 * sigma + 1e-15)
    # the trace's record of what the SINS subtracts is that running sum (18 states:
    # ε_b + ε_r, then ∇); without compensation there is none
    assert n == 18 and traces[False].bias is None
    expected = np.concatenate([fed[..., 0:3] + fed[..., 3:6], fed[..., 6:9]], -1)
    np.testing.assert_allclose(traces[True].bias, expected, rtol=1e-9, atol=1e-18)


def test_bias_compensation_needs_feedback_in_the_body_frame(tmp_path):
    import tomllib

    import tomli_w

    from ftnav.io.common import ScenarioError

    data = tomllib.loads(builtin_path("seed002").read_text())
    data["profile"] = str(builtin_path("seed002").parent / "profiles" / f"{data['profile']}.toml")
    data.pop("test_profile", None)
    data["filter"]["bias_compensation"] = True
    data["filter"]["correction"] = "output"
    path = tmp_path / "s.toml"
    path.write_text(tomli_w.dumps(data))
    with pytest.raises(ScenarioError, match="filter.bias_compensation"):
        load_scenario(path)
