"""The watch's consistency test holds its level and sees one window far beyond its band
(docs/integrity.md §4, ``ftnav.eval.integrity``).

Oracle: χ² — the NIS of a consistent filter drawn from χ²(m): the fraction of runs the
watch calls inconsistent stays within its ``probability`` (a binomial bound over 4 000
runs); a run of eight windows in which one window's NIS is far above its band (the end
of a ramp the filter had followed, on the drive: mean NIS 669 against a band of 3.4) is
inconsistent, where counting windows above the band alone could not say so (one window
of eight is never rare enough at 1 %).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import binom

from ftnav.eval.integrity import nis_band, watch

M, W = 3, 60


def _runs_inconsistent(nis: np.ndarray) -> int:
    B, K = nis.shape
    times = np.arange(1, K + 1, dtype=float)  # dt 1 s: 60 epochs a window
    every = np.ones((B, K, 1), bool)
    out = watch("m", times, ["gnss"], [M], nis[..., None], every, every, every)
    return out.aids[0].runs_inconsistent


def test_a_consistent_filter_is_called_inconsistent_within_its_probability():
    B, K = 4000, 15 * W
    nis = np.random.default_rng(11).chisquare(M, (B, K))
    flagged = _runs_inconsistent(nis)
    # at most 1 % of runs: the 99.9 % quantile of Binomial(B, 0.01)
    assert flagged <= binom.ppf(0.999, B, 0.01), flagged / B
    # and the test is not vacuous: chance alone flags some runs
    assert flagged > 0


def test_one_window_far_beyond_its_band_is_found_in_a_short_run():
    rng = np.random.default_rng(13)
    nis = rng.chisquare(M, (1, 8 * W))
    hi = nis_band(np.array([W]), M, 0.01)[1][0]
    assert (nis.reshape(8, W).mean(1) < hi).all()  # no other window above the band
    assert _runs_inconsistent(nis) == 0
    nis[0, 4 * W : 4 * W + 20] = 2000.0  # 20 epochs of a 15 m jump back, then consistent
    assert _runs_inconsistent(nis) == 1
