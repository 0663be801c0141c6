"""A continuous-time ``[model]`` (``F_c``, ``Q_c``) against the double-integrator formulas.

Closed form worked by hand: for ``dx/dt = [[0, 1], [0, 0]] x + w``, ``w`` white with
spectral density ``diag(0, q)``, over a step ``dt``::

    F = [[1, dt], [0, 1]]        Q = q [[dt³/3, dt²/2], [dt²/2, dt]]

and a constant-acceleration (triple integrator) model likewise gives
``F = [[1, dt, dt²/2], [0, 1, dt], [0, 0, 1]]`` and
``Q = q [[dt⁵/20, dt⁴/8, dt³/6], [dt⁴/8, dt³/3, dt²/2], [dt³/6, dt²/2, dt]]``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.io.scenario_file import parse_scenario


def _scenario(F_c, Q_c, dt, **extra):
    n = len(F_c)
    model = {
        "states": [f"x{i}" for i in range(n)],
        "F_c": F_c,
        "Q_c": Q_c,
        "x0": [0.0] * n,
        "P0": np.eye(n).tolist(),
        **extra,
    }
    return parse_scenario(
        {
            "name": "continuous",
            "dt": dt,
            "steps": 10,
            "model": model,
            "sensors": [{"name": "pos", "H": [[1.0] + [0.0] * (n - 1)], "R": [[1.0]]}],
            "methods": [{"name": "ckf", "architecture": "centralized"}],
        }
    )


@pytest.mark.parametrize(("q", "dt"), [(2.0, 1.0), (0.3, 0.1), (5.0, 2.5)])
def test_double_integrator(q, dt):
    sc = _scenario([[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [0.0, q]], dt)
    np.testing.assert_allclose(sc.model.F, [[1.0, dt], [0.0, 1.0]], rtol=0, atol=1e-14)
    Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    np.testing.assert_allclose(sc.model.Q, Q, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(sc.model.Q_true, sc.model.Q)


def test_triple_integrator_and_a_separate_true_density():
    q, q_true, dt = 3.0, 12.0, 0.5
    F_c = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]

    def density(v):
        return [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, v]]

    sc = _scenario(F_c, density(q), dt, Q_c_true=density(q_true))
    F = [[1.0, dt, dt**2 / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]]
    Q1 = np.array(
        [
            [dt**5 / 20, dt**4 / 8, dt**3 / 6],
            [dt**4 / 8, dt**3 / 3, dt**2 / 2],
            [dt**3 / 6, dt**2 / 2, dt],
        ]
    )
    np.testing.assert_allclose(sc.model.F, F, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sc.model.Q, q * Q1, rtol=1e-12, atol=0)
    np.testing.assert_allclose(sc.model.Q_true, q_true * Q1, rtol=1e-12, atol=0)
