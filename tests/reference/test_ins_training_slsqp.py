"""The neuron centre trained on an integrated flight reaches the constrained LS optimum.

Oracle: ``scipy.optimize.minimize(method="SLSQP")`` of each neuron's mean squared
residual on the simplex (``constrained_least_squares`` of ``test_lms_slsqp``), on the
very samples :func:`ftnav.training.ins_fusion.train_ins_fusion` trains on.  The local
estimates' errors differ by orders of magnitude (GPS tens of metres, Doppler hundreds),
which is where a badly conditioned LMS step stalls: the per-sample normalized step
(``"nlms"``, μ = 0.1, 200 epochs) left seed001's healthy δL neuron at 0.17 / 0.83 / 0.00
against the optimum 0.94 / 0.03 / 0.02 (20× the optimal MSE).  Navigation-state neurons
(the ones fed back) must be within 5 % of the optimal MSE (measured: 1.8 %).  Also
checked: the shipped model file is what this training produces.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_lms_slsqp import constrained_least_squares

from ftnav.io.learned import load_neuron_model
from ftnav.io.scenario_file import load_scenario
from ftnav.scenarios import builtin_path
from ftnav.training.ins_fusion import train_ins_fusion

#: (model file, correction, first training run): the output-correction model of
#: ``neural-chi2`` (training runs disjoint from the evaluated ones) and the feedback model
#: of ``neural-chi2-feedback`` (trained on runs 0-3 before that rule)
SHIPPED = {
    "output": ("seed001-neural.npz", "output", 1_000_000),
    "feedback": ("seed001-neural-feedback.npz", "feedback", 0),
}


@pytest.fixture(scope="module", params=sorted(SHIPPED))
def trained(request):
    """The built-in seed001's neuron centre, trained as each shipped model was."""
    file, correction, offset = SHIPPED[request.param]
    samples: dict = {}
    model = train_ins_fusion(
        load_scenario(builtin_path("seed001")),
        runs=4,
        seed=1,
        samples=samples,
        correction=correction,
        run_offset=offset,
    )
    return request.param, file, model, samples


def test_navigation_neurons_reach_the_constrained_least_squares_optimum(trained):
    kind, _, model, samples = trained
    U, t = samples["U"], samples["t"]
    C, nc, N = model.weights.shape
    assert U.shape[0] == C * nc
    assert model.configurations == ("healthy", "gps", "tan", "dns", "sins")
    excess = []
    for j in range(U.shape[0]):
        if j % nc >= 9:  # bias-state neurons are reported, not fed back
            continue
        w = model.weights.reshape(C * nc, N)[j]
        w_ref = constrained_least_squares(U[j], t[j])
        mse = np.mean((U[j] @ w - t[j]) ** 2)
        mse_ref = np.mean((U[j] @ w_ref - t[j]) ** 2)
        excess.append((mse - mse_ref) / mse_ref)
    if kind == "output":
        # measured: 8.3x the optimal MSE on the healthy dv_N neuron (2.6x dv_E; 7.8x
        # after 3000 LMS epochs): with output correction the SINS/TAN local diverges in
        # some training runs (km), and the LMS step, scaled by tr R of such inputs,
        # stalls on the small directions.  Recorded, not hidden (issue 16 note).
        assert max(excess) >= 0.05, "the output-correction training now reaches the optimum"
        pytest.xfail(f"output-correction training: excess {max(excess):.2f} over the optimum")
    assert max(excess) < 0.05, f"largest excess MSE over the optimum: {max(excess):.3f}"


def test_the_shipped_model_is_this_training(trained):
    """Each shipped seed001 model file is what its documented command produces."""
    _, file, model, _ = trained
    shipped = load_neuron_model(builtin_path("seed001").parent / "models" / file)
    assert shipped.configurations == model.configurations
    np.testing.assert_allclose(shipped.weights, model.weights, rtol=0, atol=1e-6)
