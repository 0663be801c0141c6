"""The self-watch's lock-out finding (``ftnav.eval.integrity``): every aid that measured
left out for ``LOCKOUT_S`` or longer.

Oracle: hand-built traces whose longest coast is known by construction (found by a
user's try: a SINS gyro step of the drive left the χ² method holding every aid for 340 s,
390 km off at the end, with no finding that said the method had stopped using its aids).
"""

from __future__ import annotations

import numpy as np
import pytest

from ftnav.eval.integrity import LOCKOUT_S, watch

TIMES = np.arange(1.0, 201.0)  # 1 Hz


def _watch(used: np.ndarray, available: np.ndarray):
    B, K = used.shape
    nis = np.where(available, 1.0, 0.0)[..., None]
    return watch(
        "m",
        TIMES,
        ["gnss"],
        [1],
        nis,
        available[..., None],
        used[..., None],
        available[..., None],
    )


@pytest.mark.parametrize(("out_s", "locked"), [(20, False), (40, True)])
def test_a_coast_while_measurements_came_is_a_lock_out_past_its_length(out_s, locked):
    available = np.ones((1, TIMES.size), bool)
    used = available.copy()
    used[0, 50 : 50 + out_s] = False
    w = _watch(used, available)
    assert w.locked_out_s == pytest.approx(out_s - 1.0)  # first to last epoch left out
    assert w.locked_out is locked and (out_s - 1.0 >= LOCKOUT_S) is locked
    found = [f for f in w.findings if "every aid that measured was left out" in f]
    assert bool(found) is locked
    if locked:
        assert found[0].startswith(
            f"methods[m]: every aid that measured was left out for {out_s - 1} s from t = 51.0 s"
        )


def test_epochs_without_a_measurement_neither_count_nor_break_it():
    """An outage is no lock-out (nothing came), and the epochs between two fixes do not
    end a coast (a 4 Hz receiver under a 12 Hz filter)."""
    available = np.zeros((2, TIMES.size), bool)
    available[:, ::3] = True  # a measurement every third epoch
    used = available.copy()
    used[0, 30:120] = False  # run 0: left out for 90 s of measurements
    available[1, 30:120] = False  # run 1: an outage of 90 s
    used[1] = available[1]
    w = _watch(used, available)
    assert w.locked_out and 80.0 <= w.locked_out_s <= 90.0
    single = _watch(used[1:], available[1:])
    assert single.locked_out_s == 0.0 and not single.locked_out
