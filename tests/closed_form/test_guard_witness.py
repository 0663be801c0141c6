"""Which aids can judge a held aid's jump (:meth:`ftnav.fusion.guard.Guard._unseen`,
:meth:`~ftnav.fusion.guard.Guard._unwitnessed`), in closed form.

A held aid's patience ends its hold as the plain filter would (the jump taken) only where
no other aid measuring can say which is right (docs/integrity.md §1.3).  An aid sees a
row of the held aid when one of its rows is carried by the quantity the row measures or
by that quantity's rate (``H`` and ``H D``, ``D = Φ − I``), and responds to it when that
state is among those of its own rows, their rates and the rates' rates (``H_j``,
``H_j D``, ``H_j D²``).  Oracle, by hand on a position / velocity / tilt model (a tilt
moves the east velocity's rate by g): an altimeter sees the GNSS height and nothing
else, a star tracker none of its rows, a velocity aid every row (their rates), an
odometer heading north the north row only; a held star tracker's tilt is seen by GNSS
velocities (their rate) and positions (their rate's rate), not by an altimeter.

The rows are not the directions (:meth:`~ftnav.fusion.guard.Guard._blind`): the vehicle
constraints of a car heading 45° read the east and the north velocity, so every GNSS
row's rate is carried by a state they respond to, yet the along-track velocity
(``sin ψ vE + cos ψ vN``) is outside the span of what they read at every heading.
Oracle, by hand: beside the constraints alone a direction of the GNSS is unseen at
every heading; beside the constraints and an odometer (the along-track motion of a car
heading north, or the north motion of one heading 45°: together they span both
horizontal velocities) or beside GNSS velocities, none.
"""

from __future__ import annotations

import numpy as np
import pytest
from guard_models import one_group_guard, unit_rows

from ftnav.fusion.guard import Guard, GuardTest

DT = 1.0
N_STATES = 7  # pE, pN, pU, vE, vN, vU, tilt
G = 9.8


def _constraints(heading_deg: float) -> np.ndarray:
    """NHC of a vehicle heading ``heading_deg`` from north: its lateral velocity
    (``cos ψ vE − sin ψ vN``) and its vertical velocity are zero."""
    psi = np.radians(heading_deg)
    H = np.zeros((2, N_STATES))
    H[0, 3], H[0, 4] = np.cos(psi), -np.sin(psi)
    H[1, 5] = 1.0
    return H


AIDS = {
    "gnss": unit_rows(N_STATES, 0, 1, 2),
    "altimeter": unit_rows(N_STATES, 2),
    "star tracker": unit_rows(N_STATES, 6),
    "velocity": unit_rows(N_STATES, 3, 4, 5),
    "odometer north": unit_rows(N_STATES, 4),
    "constraints heading 0": _constraints(0.0),
    "constraints heading 45": _constraints(45.0),
    "constraints heading 120": _constraints(120.0),
}


def _setup(names: list[str], B: int = 1) -> tuple[Guard, GuardTest]:
    Hs = [AIDS[k] for k in names]
    guard = one_group_guard(Hs, N_STATES, [k.startswith("constraints") for k in names])
    F = np.eye(N_STATES)
    F[:3, 3:6] = DT * np.eye(3)
    F[3, 6] = G * DT
    P = np.diag([4.0, 4.0, 4.0, 0.01, 0.01, 0.01, 1e-4])
    test = GuardTest(
        pulls=(),
        alternative=(),
        aids=(),
        P=(np.broadcast_to(P, (B, N_STATES, N_STATES)).copy(),),
        H=tuple(np.broadcast_to(h, (B, *h.shape)).copy() for h in Hs),
        F=(F,),
    )
    return guard, test


@pytest.mark.parametrize(
    ("witnesses", "unseen"),
    [
        ([], [True, True, True]),
        (["altimeter"], [True, True, False]),
        (["star tracker"], [True, True, True]),
        (["altimeter", "star tracker"], [True, True, False]),
        (["velocity"], [False, False, False]),
        (["odometer north"], [True, False, True]),
    ],
)
def test_the_gnss_rows_each_aid_sees(witnesses, unseen):
    guard, test = _setup(["gnss", *witnesses])
    usable = np.ones((1, 1 + len(witnesses)), bool)
    usable[:, 0] = False
    np.testing.assert_array_equal(guard._unseen(0, usable, test)[0], unseen)


@pytest.mark.parametrize(
    ("witness", "seen"),
    [("velocity", True), ("gnss", True), ("altimeter", False), ("odometer north", False)],
)
def test_a_star_tracker_tilt_is_seen_through_the_velocity(witness, seen):
    guard, test = _setup(["star tracker", witness])
    usable = np.array([[False, True]])
    assert guard._unseen(0, usable, test)[0, 0] == (not seen)


def test_an_aid_without_a_measurement_sees_nothing():
    guard, test = _setup(["gnss", "velocity"])
    np.testing.assert_array_equal(
        guard._unseen(0, np.array([[False, False]]), test)[0], [True, True, True]
    )


def _held(guard: Guard, jump: np.ndarray, cov: np.ndarray):
    state = guard.init(jump.shape[0])
    B, m = jump.shape
    jumps = list(state.jump)
    covs = list(state.jump_cov)
    jumps[0], covs[0] = jump, np.broadcast_to(cov, (B, m, m)).copy()
    return state._replace(jump=tuple(jumps), jump_cov=tuple(covs))


def _only(guard: Guard, usable: np.ndarray) -> np.ndarray:
    """No other aid measures (what ``Guard.decide`` passes as ``only``)."""
    return ~guard._witness_present(0, usable)


def test_a_north_step_beside_an_altimeter_and_a_star_tracker_is_unwitnessed():
    guard, test = _setup(["gnss", "altimeter", "star tracker"], B=4)
    cov = 2.0 * np.eye(3)  # one increment: 2R, R = 1 m²
    jump = np.array(
        [
            [0.3, 20.0, -0.5],  # a north step: the height they see did not move
            [0.3, 20.0, 12.0],  # the height moved too: the altimeter can judge it
            [0.3, 0.5, -0.5],  # nothing moved beyond chance
            [9.0, -14.0, 11.0],  # a noise increase moves every row
        ]
    )
    state = _held(guard, jump, cov)
    usable = np.ones((4, 3), bool)
    care = np.ones((4, 3), bool)
    got = guard._unwitnessed(0, usable, test, state, _only(guard, usable), care[:, 0])
    np.testing.assert_array_equal(got, [True, False, False, False])
    # beside GNSS velocities every row's rate is seen: never unwitnessed; alone, always
    guard_v, test_v = _setup(["gnss", "velocity"], B=4)
    state_v = _held(guard_v, jump, cov)
    usable_v = np.ones((4, 2), bool)
    only_v = _only(guard_v, usable_v)
    assert not guard_v._unwitnessed(0, usable_v, test_v, state_v, only_v, care[:, 0]).any()
    usable_v[:, 1] = False
    only_v = _only(guard_v, usable_v)
    assert guard_v._unwitnessed(0, usable_v, test_v, state_v, only_v, care[:, 0]).all()


@pytest.mark.parametrize(
    ("witnesses", "blind"),
    [
        (["constraints heading 45"], True),
        (["constraints heading 120"], True),
        (["constraints heading 45", "odometer north"], False),
        (["constraints heading 120", "odometer north"], False),
        (["velocity"], False),
        (["constraints heading 45", "velocity"], False),
    ],
)
def test_the_constraints_leave_the_along_track_direction_unseen(witnesses, blind):
    guard, test = _setup(["gnss", *witnesses])
    usable = np.ones((1, 1 + len(witnesses)), bool)
    usable[:, 0] = False
    # row by row every GNSS row is seen (its rate's states are read) ...
    assert not guard._unseen(0, usable, test)[0].any()
    # ... direction by direction the along-track one is not, beside the constraints alone
    # (gated pseudo-measurements: a sensor measuring beside them keeps the row rules)
    assert guard._blind(0, usable, test, np.array([True]))[0] == blind
    usable[:, 0] = True
    present = guard._witness_present(0, usable, test=test, care=np.array([True]))
    assert present[0] == (not blind)
    assert guard._witness_present(0, usable)[0]  # without the test: any aid measuring


def test_heading_north_the_row_rule_and_the_direction_agree():
    """A car heading north: its constraints read the east velocity, so the north row is
    unseen row by row, and the unseen direction is the north one; with no aid
    measuring beside the fix nothing is computed (the fix is alone anyway)."""
    guard, test = _setup(["gnss", "constraints heading 0"])
    usable = np.array([[False, True]])
    np.testing.assert_array_equal(guard._unseen(0, usable, test)[0], [False, True, False])
    assert guard._blind(0, usable, test, np.array([True]))[0]
    assert not guard._blind(0, np.array([[False, False]]), test, np.array([True]))[0]


def test_a_sensor_beside_the_constraints_keeps_the_row_rules():
    """An altimeter beside the constraints sees the height only, so a direction stays
    unseen; but a sensor measuring (held or not) keeps the rules by row
    (``Guard._constrained``): ``seed002``'s GNSS beside its star tracker and altimeter
    is judged so, and the drive's fixes beside their held velocities."""
    guard, test = _setup(["gnss", "constraints heading 45", "altimeter"])
    usable = np.array([[True, True, True]])
    assert guard._blind(0, usable, test, np.array([True]))[0]
    assert not guard._constrained(0, usable)[0]
    assert guard._witness_present(0, usable, test=test, care=np.array([True]))[0]
    usable[0, 2] = False  # the altimeter not measuring: the constraints alone
    assert guard._constrained(0, usable)[0]
    assert not guard._witness_present(0, usable, test=test, care=np.array([True]))[0]
