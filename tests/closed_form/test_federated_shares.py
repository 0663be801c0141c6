"""The federated filter's share floor on a batch mixing healthy and all-faulty runs.

Oracle worked by hand: with fixed betas (1e-7, 1 - 1e-7) the tiny share is raised to
MIN_SHARE and the other renormalized to 1 - MIN_SHARE; a run whose filters are all
faulty keeps zero shares.  The floor used to divide by the all-faulty run's zero sum
(a divide-by-zero warning and NaN shares, read as zero everywhere).
"""

from __future__ import annotations

import warnings

import numpy as np

from ftnav.fusion.federated import MIN_SHARE, FederatedFilter
from ftnav.fusion.registry import method_config
from ftnav.model.system import LinearModel, LinearSystem, Sensor


def test_all_faulty_run_beside_a_floored_share_stays_zero_without_warning():
    I1 = np.eye(1)
    model = LinearModel(("s",), I1, I1, np.zeros(1), I1, I1)
    sensors = tuple(Sensor(f"p{i}", I1, I1, I1) for i in range(2))
    filt = FederatedFilter(
        LinearSystem(model, sensors),
        method_config("federated", name="m", sharing="fixed", betas=(1e-7, 1.0 - 1e-7)),
    )
    P = np.broadcast_to(I1, (2, 2, 1, 1))
    r = np.array([[1.0, 1.0], [0.0, 0.0]])  # run 0 healthy, run 1 every filter faulty
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        beta = filt._sharing(P, r)
    np.testing.assert_allclose(beta[0], [MIN_SHARE, 1.0 - MIN_SHARE], rtol=1e-15)
    np.testing.assert_array_equal(beta[1], [0.0, 0.0])
