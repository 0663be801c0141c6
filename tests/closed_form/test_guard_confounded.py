"""Which witnesses respond to a held aid's move only as states it does not read could
(:meth:`ftnav.fusion.guard.Guard._confounded`), and which departures lie in rows no
witness sees (:meth:`~ftnav.fusion.guard.Guard._unjudged`), in closed form.

A held aid whose rows the others respond to only as a state the aid does not measure
could make them respond, and whose rows went unheld, has its jump taken after the
patience (docs/integrity.md §1.9).  Oracle, by hand on a position / velocity / tilt /
east accelerometer bias model: the east velocity's rate is ``g·tilt + b``, so a tilt
move ``δ`` shows in the GNSS velocities' rate as ``g δ`` and in the positions' rate's
rate as ``g δ``, each exactly what a bias ``b = g δ`` would give (confounded); without
the bias state (its variance 0: no state carries it) the same responses are the tilt's
alone (judged).  A second star tracker reads the tilt itself (judged); an altimeter does
not respond to it (no witness: not confounded).  GNSS velocities held beside positions:
the positions' rate is the velocity itself, which nothing else moves (judged); GNSS
positions beside velocities: the velocities do not respond to a position (no witness).
The tilt's σ is 1e-4 rad and the bias's 1e-3 m/s², so each carries the rate's row by the
1 % rule (``g σ_tilt ≈ σ_b``), as a navigation-grade attitude and a MEMS bias do.
"""

from __future__ import annotations

import numpy as np
import pytest
from guard_models import one_group_guard, unit_rows

from ftnav.fusion.guard import Guard, GuardTest, _AidTest

DT = 1.0
N_STATES = 8  # pE, pN, pU, vE, vN, vU, tilt (east velocity's), accelerometer bias east
G = 9.8


AIDS = {
    "gnss": unit_rows(N_STATES, 0, 1, 2),
    "velocity": unit_rows(N_STATES, 3, 4, 5),
    "altimeter": unit_rows(N_STATES, 2),
    "star tracker": unit_rows(N_STATES, 6),
    "second star tracker": unit_rows(N_STATES, 6),
}


def _setup(names: list[str], bias_sigma: float, nu: np.ndarray) -> tuple[Guard, GuardTest]:
    Hs = [AIDS[k] for k in names]
    guard = one_group_guard(Hs, N_STATES, [False] * len(names))
    F = np.eye(N_STATES)
    F[:3, 3:6] = DT * np.eye(3)
    F[3, 6] = G * DT
    F[3, 7] = DT
    P = np.diag([4.0, 4.0, 4.0, 0.01, 0.01, 0.01, 1e-8, bias_sigma**2])
    aid = _AidTest(
        nu=nu[None],
        A=(Hs[0] @ P @ Hs[0].T)[None],
        R=np.eye(Hs[0].shape[0])[None],
        nis=np.zeros(1),
        ratio=np.zeros(1),
        window=np.zeros(1, int),
    )
    test = GuardTest(
        pulls=(),
        alternative=(),
        aids=(aid,) + (None,) * (len(names) - 1),  # type: ignore[arg-type]
        P=(P[None].copy(),),
        H=tuple(h[None].copy() for h in Hs),
        F=(F,),
    )
    return guard, test


@pytest.mark.parametrize(
    ("held", "witnesses", "bias_sigma", "confounded"),
    [
        ("star tracker", ["velocity"], 1e-3, True),
        ("star tracker", ["gnss"], 1e-3, True),
        ("star tracker", ["gnss", "velocity", "altimeter"], 1e-3, True),
        ("star tracker", ["velocity"], 0.0, False),
        ("star tracker", ["gnss"], 0.0, False),
        ("star tracker", ["velocity", "second star tracker"], 1e-3, False),
        ("star tracker", ["altimeter"], 1e-3, False),
        ("star tracker", [], 1e-3, False),
        ("velocity", ["gnss"], 1e-3, False),
        ("gnss", ["velocity"], 1e-3, False),
    ],
)
def test_which_witnesses_cannot_tell_the_move_from_a_state_it_does_not_read(
    held, witnesses, bias_sigma, confounded
):
    nu = {"star tracker": [3e-3], "velocity": [0.5, 0.0, 0.0], "gnss": [5.0, 0.0, 0.0]}[held]
    guard, test = _setup([held, *witnesses], bias_sigma, np.array(nu))
    usable = np.ones((1, 1 + len(witnesses)), bool)
    assert guard._confounded(0, usable, test)[0] == confounded


def test_a_witness_without_a_measurement_is_none():
    guard, test = _setup(["star tracker", "velocity"], 1e-3, np.array([3e-3]))
    assert guard._confounded(0, np.array([[True, True]]), test)[0]
    assert not guard._confounded(0, np.array([[True, False]]), test)[0]


@pytest.mark.parametrize(
    ("witnesses", "nu", "unjudged"),
    [
        (["altimeter"], [12.0, 0.0, 0.0], True),  # departs east; the height agrees
        (["altimeter"], [12.0, 0.0, 10.0], False),  # the height, which it sees, disagrees
        (["altimeter", "star tracker"], [12.0, -9.0, 1.0], True),
        (["velocity"], [12.0, 0.0, 0.0], False),  # the velocities read every row's rate
        (["altimeter"], [0.0, 0.0, 10.0], False),  # departs only where it is seen
        (["altimeter"], [5.0, 0.0, 0.0], False),  # east and north within chance
    ],
)
def test_a_departure_in_rows_no_witness_sees_is_unjudged(witnesses, nu, unjudged):
    """:meth:`Guard._unjudged`: the held GNSS's innovation departs from the estimate
    only in rows no witness responds to (an altimeter sees the height and its rate,
    not east or north; a star tracker the tilt only), each row's ``A + R`` = 5 m²: the
    east and north χ² beyond χ²₂'s quantile at the guard's 1e-3 (13.8: 12 m is 28.8,
    5 m is 5.0), the height's within χ²₁'s (10.8: 10 m is 20).  The others cannot
    judge the hold, as beside nothing (the longest coast, §1.8).  GNSS velocities
    respond to every position row's rate: always judged."""
    guard, test = _setup(["gnss", *witnesses], 1e-3, np.array(nu))
    usable = np.ones((1, 1 + len(witnesses)), bool)
    assert guard._unjudged(0, usable, test)[0] == unjudged
