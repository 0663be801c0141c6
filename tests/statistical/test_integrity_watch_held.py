"""The watch's consistency finding says when the disagreement came only while the guard
held the aid (docs/integrity.md §4).

Oracle: χ² — the NIS of a consistent filter drawn from χ²(m), with a faulty stretch of
NIS 100 m: the window test flags it whether the aid was held or not, and judged again
without the held epochs it is consistent exactly when the faulty stretch was held.
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.engine.driver import GuardTrace
from ftnav.eval.integrity import watch

K, M = 900, 2


def _guard(hold: np.ndarray) -> GuardTrace:
    z = np.zeros_like(hold)
    return GuardTrace(z.astype(float), hold, z, z, z, z, z, z, z)


def _watched(faulty: slice, held: slice | None, with_guard: bool = True) -> tuple[str, ...]:
    rng = np.random.default_rng(5)
    times = np.arange(1, K + 1, dtype=float)
    nis = rng.chisquare(M, (1, K, 1))
    nis[0, faulty, 0] = 100.0 * M
    every = np.ones((1, K, 1), bool)
    hold = np.zeros((1, K, 1), bool)
    if held is not None:
        hold[0, held, 0] = True
    used = every & ~hold
    guard = _guard(hold) if with_guard else None
    return watch("m", times, ["gnss"], [M], nis, every, used, every, guard).findings


def test_a_consistent_filter_has_no_finding():
    assert _watched(slice(0, 0), None) == ()


@pytest.mark.parametrize(
    ("faulty", "held", "guard", "said"),
    [
        (slice(300, 420), slice(300, 420), True, "only while the guard held it"),
        (slice(300, 420), None, True, "covariance is optimistic"),
        (slice(300, 480), slice(300, 360), True, "covariance is optimistic"),
        (slice(300, 420), slice(300, 420), False, "covariance is optimistic"),
    ],
)
def test_the_finding_says_whether_the_aid_was_held(faulty, held, guard, said):
    found = [f for f in _watched(faulty, held, guard) if "inconsistent with aid 'gnss'" in f]
    assert len(found) == 1 and said in found[0], found
