"""The home test (``Guard._home``, docs/integrity.md §1.4 and §1.12) in closed form.

An aid re-admitted with a jump kept in its hold's sum comes home when its new increment
is a jump beyond chance that undoes the sum within their covariances.  A sum that is
itself within its own covariance holds no jump: it is a pile of noisy increments (an
aid whose noise a VB estimate had absorbed, so that no noise rule saw it), and any jump
beyond chance "undid" it.  On ``seed002``'s GNSS noise ramp the distributed VB method
came home on such a sum and moved its velocity 4.3 m/s.  Oracle: the χ²₁ quantile at
the guard's false-alarm probability, per row, on a one-aid model with ``H = I``.
"""

from __future__ import annotations

import numpy as np
import pytest
from guard_models import one_group_guard, unit_rows

from ftnav.core.kalman import Gaussian
from ftnav.fusion.guard import _threshold

R = 0.01  # the aid's noise variance per row


def _home(jump: list[float], jump_var: float, increment: list[float]) -> bool:
    """Whether a fix re-admitted with ``jump`` kept (its variance ``jump_var`` per row)
    comes home on ``increment`` (variance 2R per row, as a white noise's)."""
    H = unit_rows(2, 0, 1)
    guard = one_group_guard([H], 2, [False])
    state = guard.init(1)
    state = state._replace(
        jump=(np.array([jump]),),
        jump_cov=(jump_var * np.eye(2)[None],),
        jumps=np.ones((1, 1), int),
        since=np.ones((1, 1), int),
    )
    usable = np.ones((1, 1), bool)
    prior = Gaussian(np.zeros((1, 2)), np.eye(2)[None])
    z = np.array([increment])
    test = guard.test(state, [prior], [np.eye(2)[None]], [z], [H], [R * np.eye(2)[None]], usable)
    inc = ((np.array([increment]), 2 * R * np.eye(2)[None]),)
    return bool(guard._home(state, inc, np.zeros((1, 1), bool), usable, usable, test)[0, 0])


def test_a_jump_back_that_undoes_a_kept_jump_comes_home():
    assert _home([3.0, 0.0], 2 * R, [-3.0, 0.0])


def test_a_jump_that_does_not_undo_the_kept_one_is_not_home():
    assert not _home([3.0, 0.0], 2 * R, [3.0, 0.0])
    assert not _home([3.0, 0.0], 2 * R, [0.0, -3.0])


@pytest.mark.parametrize("sigmas", [0.5, 1.0, 3.0])
def test_a_kept_sum_within_its_own_covariance_holds_no_jump_to_come_home_from(sigmas):
    """The sum ``sigmas`` of its own σ away from zero (under the χ²₁ quantile, 3.3 σ at
    the default 1e-3); the increment undoes it exactly and is a jump beyond chance."""
    var = 100.0
    jump = sigmas * np.sqrt(var)
    assert jump**2 / var <= _threshold(1e-3, 1) < jump**2 / (2 * R)
    assert not _home([jump, 0.0], var, [-jump, 0.0])


def test_a_kept_sum_beyond_its_covariance_comes_home_with_the_same_noise():
    var = 100.0
    jump = 4.0 * np.sqrt(var)  # 4 σ: a jump
    assert _home([jump, 0.0], var, [-jump, 0.0])
