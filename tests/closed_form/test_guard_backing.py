"""The other aids back a held aid (:meth:`ftnav.fusion.guard.Guard._support`), in closed form.

A sequential detector can flag a star tracker when the SINS's gyro bias stepped: the
aid is right, the estimate wrong (docs/integrity.md §1, "Backing").  Each witness that
responds to the held aid's rows weighs, epoch by epoch, its own innovation against the
estimate as it is and against the estimate updated by the held aid's measurement.
Oracle, by hand on a scalar east-velocity witness beside a held tilt (a tilt moves the
east velocity's rate by g; the prior correlates the two): the update moves the
velocity by ``K ν_a`` with ``K = p_vt / (p_tt + r_a)`` and leaves it the variance
``p_vv − p_vt² / (p_tt + r_a)``, so the witness's gain, twice its log-likelihood ratio
of "the held aid is right" against "the estimate is", is, with ``s₀ = p_vv + r_v`` and
``s₁ = p_vv − p_vt² / (p_tt + r_a) + r_v``,
``ν_v² / s₀ + ln s₀ − (ν_v − K ν_a)² / s₁ − ln s₁``.  The gains are summed over the hold
as Page's CUSUM (floored at zero) and back the aid above ``2 ln(1 / pfa)``.
"""

from __future__ import annotations

import numpy as np
from guard_models import unit_rows

from ftnav.fusion.config import GuardSettings
from ftnav.fusion.guard import Guard, GuardTest, _AidTest

N_STATES = 7  # pE, pN, pU, vE, vN, vU, tilt
G = 9.8
P_TT, P_VV, P_VT = 4e-6, 0.04, 2.0e-4  # tilt rad², east velocity (m/s)², their covariance
R_A, R_V = 1e-8, 0.01  # star tracker rad², velocity (m/s)²


AIDS = {
    "star tracker": (unit_rows(N_STATES, 6), R_A),
    "velocity east": (unit_rows(N_STATES, 3), R_V),
    "altimeter": (unit_rows(N_STATES, 2), 1.0),
}


def _setup(witness: str, nu_a: np.ndarray, nu_w: np.ndarray) -> tuple[Guard, GuardTest]:
    B = nu_a.shape[0]
    names = ["star tracker", witness]
    P = np.diag([4.0, 4.0, 4.0, P_VV, 0.01, 0.01, P_TT])
    P[3, 6] = P[6, 3] = P_VT
    P = np.broadcast_to(P, (B, N_STATES, N_STATES)).copy()
    F = np.eye(N_STATES)
    F[:3, 3:6] = np.eye(3)
    F[3, 6] = G
    Hs, aids = [], []
    for name, nu in zip(names, (nu_a, nu_w), strict=True):
        H, r = AIDS[name]
        Hb = np.broadcast_to(H, (B, *H.shape)).copy()
        A = Hb @ P @ np.swapaxes(Hb, -1, -2)
        R = np.full((B, 1, 1), r)
        Hs.append(Hb)
        zero = np.zeros(B)
        aids.append(
            _AidTest(
                nu[:, None],
                A,
                R,
                zero,
                zero,
                zero.astype(int),
            )
        )
    guard = Guard(GuardSettings(), [(0, 1)], [N_STATES], [1, 1])
    test = GuardTest((), (), tuple(aids), (P,), tuple(Hs), (F,))
    return guard, test


def _held(guard: Guard, B: int, jumps: int = 0, calm: int | None = None):
    """Aid 0 held, for the patience unless ``calm`` (epochs since the onset) is given."""
    state = guard.init(B)
    hold = np.zeros((B, 2), bool)
    hold[:, 0] = True
    calm = guard.patience if calm is None else calm
    return state._replace(hold=hold, jumps=np.where(hold, jumps, 0), calm=np.where(hold, calm, 0))


def _oracle_gain(nu_a: np.ndarray, nu_v: np.ndarray) -> np.ndarray:
    K = P_VT / (P_TT + R_A)
    s0, s1 = P_VV + R_V, P_VV - P_VT**2 / (P_TT + R_A) + R_V
    return nu_v**2 / s0 + np.log(s0) - (nu_v - K * nu_a) ** 2 / s1 - np.log(s1)


def test_the_gain_of_one_epoch_is_the_closed_form():
    nu_a = np.array([0.01, 0.01, -6e-3, 1e-5])  # 5σ, 5σ, 3σ of the tilt, none
    nu_v = np.array([0.5, -0.5, -0.3, 0.02])  # agreeing, opposing, agreeing, neither
    guard, test = _setup("velocity east", nu_a, nu_v)
    state = _held(guard, 4)
    support, backed = guard._support(state, test, np.ones((4, 2), bool))
    np.testing.assert_allclose(support[:, 0], np.maximum(0.0, _oracle_gain(nu_a, nu_v)), rtol=1e-9)
    assert support[1, 0] == 0.0  # the held aid's update moves the estimate away: no support
    assert not backed.any()  # one epoch is below 2 ln(1 / pfa)
    np.testing.assert_array_equal(support[:, 1], 0.0)  # the witness is not held


def test_a_witness_that_agrees_epoch_after_epoch_backs_the_held_aid():
    nu_a, nu_v = np.array([0.01, 0.01]), np.array([0.5, -0.5])
    guard, test = _setup("velocity east", nu_a, nu_v)
    state = _held(guard, 2)
    per_epoch = _oracle_gain(nu_a, nu_v)
    assert per_epoch[0] > 0 > per_epoch[1]
    threshold = 2.0 * np.log(1.0 / guard.pfa)  # Page's threshold, recomputed
    epochs = int(np.ceil(threshold / per_epoch[0])) + 1
    for _ in range(epochs):
        support, backed = guard._support(state, test, np.ones((2, 2), bool))
        state = state._replace(support=support)
    np.testing.assert_allclose(support[0, 0], epochs * per_epoch[0], rtol=1e-9)
    np.testing.assert_array_equal(backed[:, 0], [True, False])  # a faulty aid never
    # the same evidence before the hold has lasted the patience backs nothing yet
    early = _held(guard, 2, calm=guard.patience - 1)._replace(support=support)
    assert not guard._support(early, test, np.ones((2, 2), bool))[1].any()


def test_no_backing_from_an_aid_that_cannot_see_the_rows_nor_for_a_hold_with_a_jump():
    nu_a, nu_v = np.array([0.01]), np.array([0.5])
    guard, test = _setup("altimeter", nu_a, nu_v)  # an altimeter does not see a tilt
    state = _held(guard, 1)._replace(support=np.array([[100.0, 0.0]]))
    support, backed = guard._support(state, test, np.ones((1, 2), bool))
    assert support[0, 0] == 100.0 and not backed.any()  # unchanged, and not a candidate
    guard, test = _setup("velocity east", nu_a, nu_v)
    state = _held(guard, 1, jumps=1)._replace(support=np.array([[100.0, 0.0]]))
    assert not guard._support(state, test, np.ones((1, 2), bool))[1].any()
    # a held witness, or none measuring, gives nothing either
    state = _held(guard, 1)
    usable = np.array([[True, False]])
    assert guard._support(state, test, usable)[0][0, 0] == 0.0


def _both_held(guard: Guard, B: int, jumps: int, length: int):
    """Both aids held, each with ``jumps`` jumps, for ``length`` epochs since the onset
    and a jump at the last epoch (``calm`` 0)."""
    state = guard.init(B)
    hold = np.ones((B, 2), bool)
    return state._replace(
        hold=hold,
        jumps=np.full((B, 2), jumps),
        calm=np.zeros((B, 2), int),
        length=np.full((B, 2), length),
    )


def test_two_devices_held_at_once_back_each_other_despite_their_jumps():
    """A SINS fault flags the star tracker and the GNSS velocity together, each increment
    a jump (the estimate drifts).  One fault at a time: the held aids witness each other
    with the same closed-form gain, from the patience after the onset; a faulty pair
    (the velocity opposing) never; aids of one device never."""
    nu_a, nu_v = np.array([0.01, 0.01]), np.array([0.5, -0.5])
    guard, test = _setup("velocity east", nu_a, nu_v)
    guard.devices = ("StarTracker", "Gnss")
    per_epoch = _oracle_gain(nu_a, nu_v)
    threshold = 2.0 * np.log(1.0 / guard.pfa)
    epochs = int(np.ceil(threshold / per_epoch[0])) + 1
    state = _both_held(guard, 2, jumps=3, length=guard.patience)
    for _ in range(epochs):
        support, backed = guard._support(state, test, np.ones((2, 2), bool))
        state = state._replace(support=support)
    np.testing.assert_allclose(support[0, 0], epochs * per_epoch[0], rtol=1e-9)
    np.testing.assert_array_equal(backed[:, 0], [True, False])
    # before the patience since the onset: not yet
    early = state._replace(length=np.full((2, 2), guard.patience - 1))
    assert not guard._support(early, test, np.ones((2, 2), bool))[1][:, 0].any()
    # one device: the jumps are the aid's own, and a held aid is no witness
    guard.devices = ("Gnss", "Gnss")
    support, backed = guard._support(state, test, np.ones((2, 2), bool))
    assert not backed.any()
    np.testing.assert_array_equal(support, state.support)  # no candidate: unchanged
