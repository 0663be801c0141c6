"""Small linear models for the closed-form tests of the guard (``tests/closed_form/
test_guard_*.py``): unit measurement rows and a guard over one group of aids."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ftnav.fusion.config import GuardSettings
from ftnav.fusion.guard import Guard


def unit_rows(n: int, *cols: int) -> np.ndarray:
    """(len(cols), n) the rows reading the states ``cols`` one each."""
    H = np.zeros((len(cols), n))
    H[np.arange(len(cols)), list(cols)] = 1.0
    return H


def one_group_guard(Hs: Sequence[np.ndarray], n: int, pseudo: Sequence[bool]) -> Guard:
    """The default guard over aids ``Hs`` (their rows) sharing one estimate of ``n``
    states; ``pseudo`` marks the gated pseudo-measurements (vehicle constraints)."""
    return Guard(
        GuardSettings(), [tuple(range(len(Hs)))], [n], [h.shape[0] for h in Hs], pseudo=pseudo
    )
