"""What a local filter's flag does: the isolation policy of the distributed architectures.

* ``standalone`` (spec §1.8): a flagged local filter keeps processing its own
  measurements, out of the fusion (its fault factor ``r_i = 0``).
* ``time-update`` (spec §6.3): a flagged local filter discards its measurement, so its
  estimate is its last healthy one propagated; nothing of the fault enters it.
* The common-mode rule (``common_mode = "keep"``): when at least a quorum of the aids
  (by default every one) is flagged at once, the shared reference (the SINS) failed,
  not the aids, so none is isolated.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np

from ftnav.core.kalman import Gaussian
from ftnav.fusion.protocol import select

__all__ = ["IsolationPolicy"]


class IsolationPolicy:
    """The isolation mode and the common-mode rule of one method (module docstring).

    Parameters
    ----------
    isolation : ``"standalone"`` or ``"time-update"``.
    common_mode : ``"isolate"`` or ``"keep"``.
    quorum : with ``keep``, flagged aids that make a common-mode event (None: all).
    n_filters : N, the local filters.
    """

    def __init__(
        self,
        isolation: Literal["standalone", "time-update"] = "standalone",
        common_mode: Literal["isolate", "keep"] = "isolate",
        quorum: int | None = None,
        n_filters: int = 1,
    ):
        self.isolation = isolation
        self.keep = common_mode == "keep" and n_filters > 1
        self.quorum = n_filters if quorum is None else quorum

    @property
    def time_update(self) -> bool:
        return self.isolation == "time-update"

    def flags(self, flag: np.ndarray) -> np.ndarray:
        """(B, N) flags after the common-mode rule."""
        if not self.keep:
            return flag
        common = np.sum(flag, axis=1, keepdims=True) >= self.quorum
        return np.asarray(flag & ~common, dtype=bool)

    def discard(
        self, flag: np.ndarray, priors: Sequence[Gaussian], posts: Sequence[Gaussian]
    ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Each local's estimate after its flag: its prior where flagged under time-update."""
        xs = [p[0] for p in posts]
        Ps = [p[1] for p in posts]
        if self.time_update:
            xs = [select(flag[:, i], priors[i][0], xs[i]) for i in range(len(posts))]
            Ps = [select(flag[:, i], priors[i][1], Ps[i]) for i in range(len(posts))]
        return xs, Ps
