"""A VB local that takes a measurement without learning from it (``use`` and not
``adapt``, ``fusion/locals.py`` ``local_update``): a plain Kalman update with the
predicted noise ``R̂ = ρβ/(ρα)`` and the noise posterior only forgotten (spec §7.2's
predict), beside runs of the same batch that learn (``vb_update``) or only forget.

And a VB local whose prior departs from the fusion centre's while its aid agrees with
the centre (``learned_beside``): its noise learned against the centre's prior.

Oracle: the closed form ``kalman.update`` with ``R̂``, and ``vb.vb_update`` for the
learning runs, each run computed on its own.
"""

from __future__ import annotations

import numpy as np

from ftnav.core import kalman as kf
from ftnav.core import vb
from ftnav.core.kalman import Gaussian
from ftnav.fusion.config import VbNoise
from ftnav.fusion.locals import LocalBank, NoiseState, learned_beside, local_update
from ftnav.model.system import LinearModel, LinearSystem, Sensor


def test_a_used_measurement_not_learned_from_is_a_plain_update_with_the_predicted_noise():
    rng = np.random.default_rng(3)
    B, n, m = 4, 5, 3
    A = rng.normal(size=(B, n, n))
    P = A @ A.transpose(0, 2, 1) + n * np.eye(n)
    x = rng.normal(size=(B, n))
    z = rng.normal(size=(B, m)) * 4.0
    H = rng.normal(size=(m, n))
    R = np.diag([1.0, 2.0, 0.5])
    alpha = rng.uniform(2.0, 6.0, size=(B, m))
    beta = alpha * rng.uniform(0.5, 3.0, size=(B, m))
    settings = VbNoise(kind="vb", rho=0.97, iterations=3)
    use = np.array([True, True, False, False])
    adapt = np.array([True, False, True, False])
    got = local_update(x, P, z, use, H, R, NoiseState(alpha, beta), settings, adapt)

    a_pred, b_pred = 0.97 * alpha, 0.97 * beta
    # run 0 learns: the VB update
    up, a0, b0, R0 = vb.vb_update(x[:1], P[:1], z[:1], H, a_pred[:1], b_pred[:1], iterations=3)
    np.testing.assert_allclose(got.x[0], up.x[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.P[0], up.P[0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.noise.alpha[0], a0[0], rtol=1e-12)
    np.testing.assert_allclose(got.noise.beta[0], b0[0], rtol=1e-12)
    np.testing.assert_allclose(got.R[0], R0[0], rtol=1e-12)
    # run 1 takes the measurement with the predicted R̂ and learns nothing
    R_hat = np.diag(b_pred[1] / a_pred[1])
    plain = kf.update(x[1], P[1], z[1], H, R_hat)
    np.testing.assert_allclose(got.x[1], plain.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.P[1], plain.P, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.nis[1], plain.nis, rtol=1e-12)
    np.testing.assert_allclose(got.R[1], R_hat, rtol=1e-12)
    np.testing.assert_allclose(got.noise.alpha[1], a_pred[1], rtol=1e-12)
    np.testing.assert_allclose(got.noise.beta[1], b_pred[1], rtol=1e-12)
    # and it differs from what learning would have given (the test can fail)
    learned = vb.vb_update(x[1:2], P[1:2], z[1:2], H, a_pred[1:2], b_pred[1:2])[0]
    assert np.abs(learned.x[0] - plain.x).max() > 1e-3
    # run 2 learns without taking it (an isolated local: state only time-updated)
    _, a2, b2, _ = vb.vb_update(x[2:3], P[2:3], z[2:3], H, a_pred[2:3], b_pred[2:3])
    np.testing.assert_array_equal(got.x[2], x[2])
    np.testing.assert_array_equal(got.P[2], P[2])
    np.testing.assert_allclose(got.noise.beta[2], b2[0], rtol=1e-12)
    assert got.nis[2] == 0.0
    # run 3 neither: only forgotten
    np.testing.assert_array_equal(got.x[3], x[3])
    np.testing.assert_allclose(got.noise.alpha[3], a_pred[3], rtol=1e-12)
    np.testing.assert_allclose(got.noise.beta[3], b_pred[3], rtol=1e-12)


def _bank():
    n = 2
    model = LinearModel(("p", "v"), np.eye(n), 0.01 * np.eye(n), np.zeros(n), np.eye(n), None)
    H = np.array([[1.0, 0.0]])
    R = np.array([[1.0]])
    gnss = Sensor("gnss", H, R, R)
    return LocalBank(LinearSystem(model, (gnss,)), VbNoise(kind="vb", rho=0.98)), H


def test_a_vb_local_departed_from_the_centre_learns_against_it():
    """``learned_beside``: run 0's local prediction is 20 σ from the centre's and the
    measurement agrees with the centre at its declared noise: its noise is learned
    against the centre's prior (``vb_update`` there) and its measurement taken with that
    R̂ as a plain Kalman update; run 1 departs as far but the measurement agrees with the
    local (another aid's fault in the centre): its own VB update; run 2 does not depart:
    its own.  Oracle: ``vb_update`` and ``kalman.update`` run by hand."""
    bank, H = _bank()
    B = 3
    P = np.broadcast_to(np.eye(2) * 0.25, (B, 2, 2)).copy()
    x_local = np.array([[10.0, 0.0], [10.0, 0.0], [0.3, 0.0]])
    x_centre = np.zeros((B, 2))
    Pc = P * 0.5
    z = np.array([[0.4], [10.2], [0.2]])
    alpha, beta = np.full((B, 1), 3.0), np.full((B, 1), 3.0)
    noise = NoiseState(alpha, beta)
    use = adapt = np.ones(B, bool)
    own = bank.update(0, Gaussian(x_local, P), z, use, H, noise, adapt)
    got = learned_beside(
        bank, 0, Gaussian(x_local, P), Gaussian(x_centre, Pc), z, use, H, noise, adapt, own
    )
    a_pred, b_pred = 0.98 * alpha, 0.98 * beta
    _, a_c, b_c, _ = vb.vb_update(x_centre[:1], Pc[:1], z[:1], H, a_pred[:1], b_pred[:1])
    plain = kf.update(x_local[0], P[0], z[0], H, np.diag(b_c[0] / a_c[0]))
    np.testing.assert_allclose(got.x[0], plain.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.P[0], plain.P, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.noise.beta[0], b_c[0], rtol=1e-12)
    np.testing.assert_allclose(got.R[0], np.diag(b_c[0] / a_c[0]), rtol=1e-12)
    # the local's own VB would have learned the 10 m residual as noise (the test can fail)
    assert own.noise.beta[0, 0] > 5.0 * got.noise.beta[0, 0]
    for b in (1, 2):  # the measurement sides with the local, or no departure: its own
        np.testing.assert_array_equal(got.x[b], own.x[b])
        np.testing.assert_array_equal(got.noise.beta[b], own.noise.beta[b])
