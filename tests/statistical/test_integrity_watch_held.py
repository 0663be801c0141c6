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


def _guard(hold: np.ndarray, device: np.ndarray | None = None) -> GuardTrace:
    z = np.zeros_like(hold)
    device = z if device is None else device
    return GuardTrace(z.astype(float), hold, z, z, z, z, z, z, z, device, z)


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


def _held_from_300(n: int, until: int, seed: int):
    """The times, χ²_M NIS, availability and holds of ``n`` aids held over [300, until)."""
    times = np.arange(1, K + 1, dtype=float)
    nis = np.random.default_rng(seed).chisquare(M, (1, K, n))
    every = np.ones((1, K, n), bool)
    hold = np.zeros((1, K, n), bool)
    hold[0, 300:until] = True
    return times, nis, every, hold


def test_a_device_taken_back_from_a_drifted_estimate_is_said_once_with_its_time():
    """Both halves of a receiver re-admitted together at epoch 400 (the guard's device
    rule): one finding naming both aids and the time; none without it."""
    times, nis, every, hold = _held_from_300(2, 399, seed=2)
    device = np.zeros_like(hold)
    for dev, n in ((device, 0), (device.copy(), 1)):
        if n:
            dev[0, 399] = True
        found = watch(
            "m",
            times,
            ["gnss", "gnss-vel"],
            [M, M],
            nis,
            every,
            every & ~hold,
            every,
            _guard(hold, dev),
        ).findings
        said = [f for f in found if "a device consistent with itself" in f]
        assert len(said) == n, found
        if n:
            assert "'gnss', 'gnss-vel'" in said[0] and "t = 400.0 s" in said[0], said


@pytest.mark.parametrize("faded", [False, True])
def test_a_jump_taken_says_whether_the_covariance_was_widened(faded):
    """A star tracker held from epoch 300 and taken back with its jump at 340 (the
    guard's patience): one finding with the time; the widening said only where the
    guard faded the covariance (docs/integrity.md §1.9)."""
    times, nis, every, hold = _held_from_300(1, 339, seed=3)
    z = np.zeros_like(hold)
    taken, fade = z.copy(), z.copy()
    taken[0, 339] = True
    fade[0, 339] = faded
    guard = GuardTrace(z.astype(float), hold, z, z, z, z, z, taken, z, z, fade)
    found = watch("m", times, ["cns"], [M], nis, every, every & ~hold, every, guard).findings
    said = [f for f in found if "taken back with its jump" in f]
    assert len(said) == 1 and "t = 340.0 s" in said[0], found
    assert ("whole covariance widened" in said[0]) == faded, said
