"""Covariance intersection (Julier & Uhlmann, ACC 1997) against its defining bound.

``kf.intersect`` is the reference of the neuron centre's χ² flags
(:mod:`ftnav.fusion.neural`, ``prior = "intersection"``): it must be consistent for
any correlation between the local estimates, which the oracle below checks against the
exact error covariance of the same linear combination.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from ftnav.core import kalman as kf
from ftnav.fusion.config import Learned
from ftnav.fusion.neural import NeuralFusion
from ftnav.fusion.neural_model import NeuronModel
from ftnav.fusion.protocol import with_common
from ftnav.fusion.registry import method_config
from ftnav.io.learned import compatibility
from ftnav.io.scenario_file import load_scenario
from ftnav.model.system import Epoch
from ftnav.scenarios import builtin_path
from ftnav.sim.linear import simulate


def _random_joint(rng, B, N, n):
    """(B, N·n, N·n) SPD joint error covariances with arbitrary cross-correlation."""
    A = rng.standard_normal((B, N * n, N * n)) * rng.uniform(0.1, 10.0, (B, 1, N * n))
    return A @ np.swapaxes(A, 1, 2) + 1e-3 * np.eye(N * n)


@pytest.mark.parametrize("N, n", [(2, 1), (3, 4), (4, 6)])
def test_intersection_bounds_the_true_error_covariance_for_any_correlation(N, n):
    """P_CI − Cov(Σ K_i e_i) ⪰ 0, with K_i = P_CI ω_i P_i⁻¹ and the exact joint Σ."""
    rng = np.random.default_rng(N * 10 + n)
    B = 300
    S = _random_joint(rng, B, N, n)
    blocks = np.stack([S[:, i * n : (i + 1) * n, i * n : (i + 1) * n] for i in range(N)], 1)
    omega = rng.dirichlet(np.ones(N), B)
    x = rng.standard_normal((B, N, n))
    ci = kf.intersect(x, blocks, omega)
    K = np.concatenate(
        [ci.P @ (omega[:, i, None, None] * np.linalg.inv(blocks[:, i])) for i in range(N)], 2
    )  # (B, n, N·n)
    true = K @ S @ np.swapaxes(K, 1, 2)
    gap = np.linalg.eigvalsh(ci.P - true)
    scale = np.linalg.eigvalsh(ci.P)[:, -1]
    assert (gap[:, 0] >= -1e-9 * scale).all(), gap[:, 0].min()
    # the estimate is that same combination of the inputs
    np.testing.assert_allclose(
        ci.x, np.einsum("bij,bj->bi", K, x.reshape(B, N * n)), rtol=1e-9, atol=1e-9
    )


def test_naive_information_fusion_fails_the_same_bound():
    """Negative control: Σ P_i⁻¹ (weights 1) of two estimates with the same error is
    overconfident by 2×, and the bound check above catches it."""
    rng = np.random.default_rng(7)
    A = rng.standard_normal((3, 3))
    P1 = A @ A.T + np.eye(3)
    S = np.block([[P1, P1], [P1, P1]])[None]  # identical errors
    P = np.stack([P1, P1])[None]
    naive = kf.fuse(np.zeros((1, 2, 3)), P, np.ones((1, 2)))
    K = np.concatenate([naive.P @ np.linalg.inv(P1)] * 2, 2)
    gap = np.linalg.eigvalsh(naive.P - K @ S @ np.swapaxes(K, 1, 2))
    assert gap[0, 0] < -0.1 * np.linalg.eigvalsh(P1)[0] / 2
    ci = kf.intersect(np.zeros((1, 2, 3)), P)
    np.testing.assert_allclose(ci.P[0], P1, rtol=1e-10)


def test_intersection_in_closed_form():
    rng = np.random.default_rng(3)
    S = _random_joint(rng, 5, 3, 2)
    P = np.stack([S[:, 2 * i : 2 * i + 2, 2 * i : 2 * i + 2] for i in range(3)], 1)
    x = rng.standard_normal((5, 3, 2))
    ci = kf.intersect(x, P)  # equal weights
    Y = np.linalg.inv(P).sum(1) / 3.0
    np.testing.assert_allclose(ci.P, np.linalg.inv(Y), rtol=1e-10)
    y = np.einsum("bkij,bkj->bi", np.linalg.inv(P), x) / 3.0
    np.testing.assert_allclose(ci.x, np.linalg.solve(Y, y[..., None])[..., 0], rtol=1e-9)
    # identical inputs: the intersection is that input (no information is double counted)
    same = kf.intersect(np.repeat(x[:, :1], 3, 1), np.repeat(P[:, :1], 3, 1))
    np.testing.assert_allclose(same.P, P[:, 0], rtol=1e-10)
    np.testing.assert_allclose(same.x, x[:, 0], rtol=1e-10, atol=1e-12)
    with pytest.raises(ValueError, match="^omega: covariance intersection needs weights"):
        kf.intersect(x, P, np.full((5, 3), 0.5))


def test_with_common_replaces_the_common_block_and_zeroes_the_cross_terms():
    rng = np.random.default_rng(4)
    A = rng.standard_normal((2, 5, 5))
    P = A @ np.swapaxes(A, 1, 2)
    x = rng.standard_normal((2, 5))
    xc, Pc = rng.standard_normal((2, 3)), np.broadcast_to(np.eye(3) * 7.0, (2, 3, 3))
    xg, Pg = with_common((x, P), xc, Pc)
    np.testing.assert_array_equal(xg, np.concatenate([xc, x[:, 3:]], 1))
    np.testing.assert_array_equal(Pg[:, :3, :3], Pc)
    np.testing.assert_array_equal(Pg[:, 3:, 3:], P[:, 3:, 3:])
    assert not Pg[:, :3, 3:].any() and not Pg[:, 3:, :3].any()
    full = with_common((xc, Pc), x[:, :3], P[:, :3, :3])  # full-state local: the reference
    np.testing.assert_array_equal(full[0], x[:, :3])
    np.testing.assert_array_equal(full[1], P[:, :3, :3])


def _chi2(prior: str) -> dict:
    return {"kind": "residual-chi2", "prior": prior}


def test_prior_checks():
    """The residual test's reference is checked when the configuration is built."""
    method_config("federated", name="f", detector=_chi2("global"))
    with pytest.raises(
        ValueError,
        match=r"^methods\[f\]\.detector\.prior: 'intersection' is not "
        r"available with the federated architecture",
    ):
        method_config("federated", name="f", detector=_chi2("intersection"))


def test_single_local_filter_intersection_is_its_own_prior():
    """N = 1: the intersection of one prior is that prior, so the χ² statistics equal
    ``prior = "local"`` exactly (the oracle of the wiring in the neuron centre)."""
    sc = load_scenario(builtin_path("seed000"))
    sc = replace(sc, steps=40, sensors=sc.sensors[:1], faults=())
    system = sc.system()
    model = NeuronModel(
        ("healthy", "pos1"),
        np.array([[False], [True]]),
        ("pos1",),
        tuple(system.model.states),
        np.ones((2, 3, 1)),
        np.ones((2, 3)),
        compatibility(system),
        {},
    )
    sim = simulate(sc, 4, seed=2)
    stats = {}
    for prior in ("local", "intersection"):
        filt = NeuralFusion(
            system,
            method_config("neural", name="n", detector=_chi2(prior)),
            Learned(fusion=model),
        )
        state, rows = filt.init(4), []
        stream = sim.stream
        for k in range(1, sc.steps + 1):
            epoch = Epoch(
                k,
                tuple(z[:, k - 1] for z in stream.z),
                stream.available[:, k - 1],
                np.zeros(1, bool),
            )
            state, out = filt.step(state, epoch)
            rows.append(out.detection.statistic)
        stats[prior] = np.array(rows)
    assert stats["local"].max() > 0
    np.testing.assert_allclose(stats["intersection"], stats["local"], rtol=1e-9, atol=1e-12)
