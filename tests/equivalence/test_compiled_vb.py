"""The compiled VB update equals its plain NumPy form (spec §7.2).

Oracle: :func:`ftnav.core.vb.vb_update_reference`, the Särkkä–Nummenmaa fixed point
written with NumPy operations on top of the Joseph update (itself checked against
closed forms in ``tests/statistical/test_vb.py`` and ``tests/closed_form``).
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.core import vb


def _problem(B=6, n=8, m=3, seed=0, shared_H=False):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((B, n, n))
    return (
        rng.standard_normal((B, n)),
        A @ np.swapaxes(A, -1, -2) + np.eye(n),
        rng.standard_normal((B, m)) * 3.0,
        rng.standard_normal((m, n) if shared_H else (B, m, n)),
        rng.uniform(1.0, 3.0, (B, m)),
        rng.uniform(0.5, 3.0, (B, m)),
    )


@pytest.mark.parametrize("iterations", [1, 3, 6])
@pytest.mark.parametrize("shared_H", [False, True])
def test_compiled_vb_update_equals_the_numpy_form(iterations, shared_H):
    args = _problem(shared_H=shared_H)
    got = vb.vb_update(*args, iterations=iterations)
    ref = vb.vb_update_reference(*args, iterations=iterations)
    for a, b in zip(got[0], ref[0], strict=True):  # x, P, ν, S, NIS
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12)
    for a, b in zip(got[1:], ref[1:], strict=True):  # α, β, R
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-12)


def test_literal_variant_and_indefinite_rows_use_the_numpy_form():
    args = _problem()
    lit = vb.vb_update(*args, variant="literal")
    ref = vb.vb_update_reference(*args, variant="literal")
    np.testing.assert_array_equal(lit[2], ref[2])
    x, P, z, H, a, b = _problem(B=3, n=2, m=2)
    H = np.broadcast_to(np.eye(2), (3, 2, 2)).copy()
    P[1] = np.diag([-5.0, 1.0])  # S = P + R is indefinite in run 1: Cholesky fails
    got = vb.vb_update(x, P, z, H, a, b, iterations=2)
    ref = vb.vb_update_reference(x, P, z, H, a, b, iterations=2)
    np.testing.assert_allclose(got[2], ref[2], rtol=1e-12)
    np.testing.assert_allclose(got[0].x, ref[0].x, rtol=1e-12)
