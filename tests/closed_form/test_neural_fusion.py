"""Neuron fusion centre (spec §5.2, §5.4) against hand computations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftnav.core import kalman as kf
from ftnav.fusion.config import Learned
from ftnav.fusion.neural import NeuralFusion
from ftnav.fusion.neural_model import NeuronModel, select_weights
from ftnav.fusion.registry import method_config
from ftnav.io.learned import compatibility, save_neuron_model
from ftnav.io.scenario_file import load_scenario
from ftnav.io.sections import resolve_methods
from ftnav.model.system import Epoch
from ftnav.scenarios import builtin_path
from ftnav.sim.linear import simulate


@pytest.fixture(scope="module")
def scenario():
    sc = load_scenario(builtin_path("seed000"))
    return replace(sc, steps=60)


def _model(system, weights, patterns=None, inputs=("pos1", "pos2", "pos3")):
    C = weights.shape[0]
    if patterns is None:
        patterns = np.vstack([np.zeros(3, bool), np.eye(3, dtype=bool)])[:C]
    return NeuronModel(
        ("healthy", "pos1", "pos2", "pos3")[:C],
        patterns,
        inputs,
        ("s", "v", "a"),
        weights,
        np.ones((C, 3)),
        compatibility(system),
        {},
    )


def _banks():
    rng = np.random.default_rng(0)
    W = rng.random((4, 3, 3)) + np.eye(3)[[0, 0, 1, 2]][:, None, :] * 0  # positive
    W[1, :, 0] = 0.0  # pos1 bank ignores input pos1, etc.
    W[2, :, 1] = 0.0
    W[3, :, 2] = 0.0
    return W / W.sum(-1, keepdims=True)


def test_selection_rules(scenario):
    system = scenario.system()
    W = _banks()
    model = _model(system, W)
    flags = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 1, 1]], bool)
    got = select_weights(model, flags, "renormalize")
    for b in range(4):
        np.testing.assert_array_equal(got[b], W[b])
    # two flags: the healthy bank with pos1 and pos2 zeroed -> all weight on pos3
    np.testing.assert_allclose(got[4], np.broadcast_to([0.0, 0.0, 1.0], (3, 3)))
    # every input flagged and no free input: nothing left to renormalize -> healthy bank
    np.testing.assert_array_equal(got[5], W[0])
    named = select_weights(model, flags, "pos3")
    np.testing.assert_array_equal(named[4], W[3])
    np.testing.assert_array_equal(named[5], W[3])


def test_fused_estimate_is_the_weighted_sum_of_independent_local_filters(scenario):
    system = scenario.system()
    W = _banks()
    model = _model(system, W)
    method = method_config("neural", name="n", detector="oracle")
    filt = NeuralFusion(system, method, Learned(fusion=model))
    stream = simulate(scenario, 3, seed=5).stream
    state = filt.init(3)
    x = [np.broadcast_to(system.model.x0, (3, 3)).copy() for _ in range(3)]
    P = [np.broadcast_to(system.model.P0, (3, 3, 3)).copy() for _ in range(3)]
    F, Q = system.transition()
    for k in range(1, scenario.steps + 1):
        labels = np.zeros(3, bool) if k < 30 else np.array([False, True, False])
        z = tuple(zi[:, k - 1] for zi in stream.z)
        state, out = filt.step(state, Epoch(k, z, stream.available[:, k - 1], labels))
        for i, s in enumerate(system.sensors):  # plain independent Kalman filters
            xp, Pp = kf.predict(x[i], P[i], F, Q)
            up = kf.update(xp, Pp, stream.z[i][:, k - 1], s.H, s.R)
            x[i], P[i] = up.x, up.P
        w = W[0] if k < 30 else W[2]
        u = np.stack(x, -1)  # (B, n, N)
        np.testing.assert_allclose(out.x, (w[None] * u).sum(-1), rtol=1e-12, atol=1e-12)
        sd = np.sqrt(np.stack([np.diagonal(p, axis1=1, axis2=2) for p in P], -1))
        np.testing.assert_allclose(
            np.diagonal(out.P, axis1=1, axis2=2), ((w[None] * sd).sum(-1)) ** 2, rtol=1e-12
        )
        assert np.all(out.P[:, 0, 1:] == 0.0)


def test_bound_covers_any_correlation():
    """(Σ w σ)² >= Var(Σ w e) for every correlation when w >= 0 (Cauchy-Schwarz)."""
    rng = np.random.default_rng(1)
    for _ in range(200):
        A = rng.standard_normal((4, 4))
        S = A @ A.T
        w = rng.random(4)
        w /= w.sum()
        assert w @ S @ w <= (w @ np.sqrt(np.diag(S))) ** 2 * (1 + 1e-12)


def test_model_validation(scenario, tmp_path):
    system = scenario.system()
    W = _banks()
    bad = W.copy()
    bad[0, 0] = [0.7, 0.7, -0.4]
    with pytest.raises(ValueError, match="^weights: every neuron"):
        _model(system, bad)
    with pytest.raises(ValueError, match="^configurations: the first must be the healthy"):
        _model(system, W, patterns=np.eye(4, 3, dtype=bool))
    with pytest.raises(ValueError, match="^weights: expected"):
        _model(system, W[:, :2])
    # the trained banks are loaded and checked against the method at the boundary
    path = save_neuron_model(_model(system, W), tmp_path / "banks.npz")
    with pytest.raises(ValueError, match=r"uncovered: expected 'renormalize' or one of"):
        resolve_methods(
            (method_config("neural", name="n", model=str(path), uncovered="sins"),),
            system,
            None,
            "<test>",
        )
    with pytest.raises(
        ValueError, match=r"^methods\[n\]\.detector\.kind: 'rbf' is not a detector of the neural"
    ):
        method_config("neural", name="n", detector={"kind": "rbf", "model": "x.npz"})


def test_the_convergence_gate_leaves_out_inputs_far_less_certain_and_renormalizes():
    """Closed form (``convergence_ratio``): per state, inputs whose σ exceed ratio × the
    smallest σ get weight 0, the rest keep their trained proportions (sum 1); kept inputs
    with no trained weight share equally."""
    from ftnav.fusion.neural import converged_only

    W = np.array([[[0.2, 0.5, 0.3], [0.0, 0.0, 1.0]]])  # (B=1, 2 states, 3 inputs)
    SD = np.array([[[10.0, 15.0, 100.0], [5.0, 9.0, 50.0]]])
    out = converged_only(W, SD, 2.0)
    np.testing.assert_allclose(out[0, 0], [0.2 / 0.7, 0.5 / 0.7, 0.0])
    np.testing.assert_allclose(out[0, 1], [0.5, 0.5, 0.0])  # only the gated input was weighted
    np.testing.assert_allclose(out.sum(-1), 1.0)
    np.testing.assert_array_equal(converged_only(W, SD, 100.0), W)  # everything kept
