"""The states a jump taken moves (:func:`ftnav.fusion.guard._carrier`), in closed form.

A sole source's jump taken past its patience moves the estimate by the jump in the
measured quantity (docs/integrity.md §1.3).  Oracle: the move must reproduce the jump
exactly (``H M = I``), leave a state that sees the row only through a small coupling (an
attitude through a 5 cm lever arm) untouched, and share a row between states of
comparable σ as the minimum-norm move in their own σ does,
``Δx_j = P_jj H_j J / Σ_i P_ii H_i²`` for one row.
"""

from __future__ import annotations

import numpy as np

from ftnav.fusion.guard import _carrier


def test_a_height_jump_moves_the_height_not_the_roll():
    # states: roll (rad), height (m); the row: 5 cm lever arm on the roll, the height
    H = np.array([[[0.05, 1.0]]])
    P = np.diag([3e-3**2, 0.2**2])[None]
    M = _carrier(H, P)
    np.testing.assert_allclose(H @ M, [[[1.0]]], rtol=0, atol=1e-12)
    jump = np.array([10.0])
    move = M[0] @ jump
    assert move[0] == 0.0  # the plain pseudo-inverse put 0.5 rad (28°) there
    np.testing.assert_allclose(move[1], 10.0, rtol=0, atol=1e-12)


def test_a_row_of_two_states_of_comparable_sigma_is_shared_by_their_variances():
    # a position (m) and a receiver error state (m, H −1) of σ 2 and 1 m, a lever-arm
    # coupled heading far below both
    H = np.array([[[1.0, -1.0, 0.05]]])
    var = np.array([4.0, 1.0, 1e-4])
    P = np.diag(var)[None]
    M = _carrier(H, P)
    J = 5.0
    move = M[0, :, 0] * J
    total = 4.0 + 1.0
    np.testing.assert_allclose(move[:2], [4.0 * J / total, -1.0 * J / total], rtol=1e-12)
    assert move[2] == 0.0
    np.testing.assert_allclose((H @ M)[0], [[1.0]], rtol=0, atol=1e-12)


def test_three_rows_on_radian_positions_reproduce_the_jump():
    # the drive's GNSS rows on a 15-state error model: attitude 0-2, latitude and
    # longitude in radians (metres per radian 6.4e6, 4.9e6), height; lever-arm couplings
    rng = np.random.default_rng(0)
    H = np.zeros((1, 3, 9))
    H[0, 0, 7], H[0, 1, 6], H[0, 2, 8] = 4.887e6, 6.364e6, 1.0
    H[0, 0, 1:3] = [-7.4e-4, -5.0e-2]
    H[0, 1, [0, 2]] = [7.4e-4, 2.4e-3]
    H[0, 2, :2] = [5.0e-2, -2.4e-3]
    sd = np.array([3e-3, 3e-3, 4e-2, 0.05, 0.05, 0.01, 1.4e-8, 1.7e-8, 0.04])
    P = np.diag(sd**2)[None]
    M = _carrier(H, P)
    np.testing.assert_allclose(H @ M, np.eye(3)[None], rtol=0, atol=1e-9)
    move = M[0] @ np.array([1000.0, -1000.0, 10.0]) + 0 * rng.random()
    np.testing.assert_array_equal(move[:6], 0.0)  # no attitude, no velocity
    np.testing.assert_allclose(move[[7, 6, 8]] * [4.887e6, 6.364e6, 1.0], [1000, -1000, 10])
