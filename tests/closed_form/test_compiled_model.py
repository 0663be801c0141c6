"""The compiled error-model and series kernels equal their plain NumPy forms (spec §8.3-§8.4).

Oracles: :func:`continuous_model_reference` (the spec §8.3 blocks written with NumPy
array operations) and :func:`series_reference` (the spec §8.4 series term by term).
The compiled kernels build the same matrices element by element (``Φ`` by Horner), so
they must agree to rounding on random INS solutions, every state size and both bias
frames.  The reference forms themselves are checked against finite differences of the
mechanization (``tests/finite_difference``) and against Van Loan (``test_discretize``).
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core.discretize import series, series_reference
from ftnav.nav.attitude import quat_to_dcm
from ftnav.nav.error_model import (
    ErrorModelParams,
    continuous_model,
    continuous_model_reference,
    discrete_model,
)

DEG, HOUR = np.pi / 180.0, 3600.0
VARIANTS = {
    "18-body": ErrorModelParams(
        gyro_psd=1e-12,
        gyro_markov_sigma=(1e-6, 2e-6, 3e-6),
        gyro_markov_tau=(100.0, 200.0, 300.0),
        accel_markov_sigma=(1e-4, 2e-4, 3e-4),
        accel_markov_tau=(50.0, 60.0, 70.0),
        accel_psd=1e-9,
    ),
    "18-nav": ErrorModelParams(
        gyro_psd=1e-12, gyro_markov_sigma=1e-6, accel_markov_sigma=1e-4, bias_frame="nav"
    ),
    "15-body": ErrorModelParams(states=15, gyro_bias_rw_psd=1e-14, accel_bias_rw_psd=1e-10),
    "21-body": ErrorModelParams(states=21, gyro_bias_rw_psd=1e-14, accel_bias_rw_psd=1e-10),
}
#: the body rate of :func:`nav`'s solutions (the 21-state model's scale-factor columns)
W_B = np.random.default_rng(1).standard_normal((7, 3)) * 0.3


def nav(B=7, seed=0):
    rng = np.random.default_rng(seed)
    return (
        rng.uniform(-1.3, 1.3, B),
        rng.uniform(-3, 3, B),
        rng.uniform(-400, 12000, B),
        rng.standard_normal((B, 3)) * 250.0,
        rng.standard_normal((B, 3)) * 3.0 + [0, 0, 9.8],
        quat_to_dcm(rng.standard_normal((B, 4))),
    )


@pytest.mark.parametrize("variant", VARIANTS)
def test_compiled_continuous_model_equals_the_numpy_form(variant):
    p = VARIANTS[variant]
    got = continuous_model(*nav(), p, w_b=W_B)
    ref = continuous_model_reference(*nav(), p, w_b=W_B)
    np.testing.assert_allclose(got.F, ref.F, rtol=1e-13, atol=1e-15 * np.abs(ref.F).max())
    np.testing.assert_array_equal(got.G, ref.G)
    np.testing.assert_array_equal(got.q, ref.q)
    # scalar (unbatched) inputs keep their shape
    one = continuous_model(*(a[0] for a in nav()), p, w_b=W_B[0])
    assert one.F.shape == (p.n, p.n) and one.G.shape == (p.n, 12)
    np.testing.assert_allclose(one.F, ref.F[0], rtol=1e-13, atol=1e-15 * np.abs(ref.F).max())


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("order", [1, 2, 5])
def test_compiled_discrete_model_equals_the_reference_series(variant, order):
    p = VARIANTS[variant]
    m = continuous_model_reference(*nav(), p, w_b=W_B)
    Phi_r, Q_r = series_reference(m.F, m.GQGt, 0.7, order)
    Phi, Q = discrete_model(*nav(), p, 0.7, "series", order, w_b=W_B)
    np.testing.assert_allclose(Phi, Phi_r, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(Q, Q_r, rtol=1e-12, atol=1e-13 * np.abs(Q_r).max())
    np.testing.assert_array_equal(Q, np.swapaxes(Q, -1, -2))


def test_compiled_series_broadcasts_like_the_reference():
    rng = np.random.default_rng(3)
    F = rng.standard_normal((4, 4)) * 0.3
    A = rng.standard_normal((3, 2, 4, 4))
    GQGt = A @ np.swapaxes(A, -1, -2)
    T = np.array([0.1, 1.0])
    for order in (1, 3, 6):
        got, ref = series(F, GQGt, T, order), series_reference(F, GQGt, T, order)
        assert got[0].shape == got[1].shape == (3, 2, 4, 4)
        np.testing.assert_allclose(got[0], ref[0], rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(got[1], ref[1], rtol=1e-12, atol=1e-13)


def test_discrete_model_rejects_bad_step_and_order():
    with pytest.raises(ValueError, match="T must be positive"):
        discrete_model(*nav(2), VARIANTS["18-body"], 0.0, "series", 5)
    with pytest.raises(ValueError, match="order"):
        discrete_model(*nav(2), VARIANTS["18-body"], 1.0, "series", 0)
