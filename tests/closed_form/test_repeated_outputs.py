"""``ftnav.model.streams.repeated``: a frozen sensor's signature, by hand.

An available output equal bit for bit to its run's previous *available* output (gaps
and NaN epochs between do not count) is a repeat; the first output of a run, a change
in any component, or an unavailable epoch is not.
"""

from __future__ import annotations

import numpy as np

from ftnav.model.streams import repeated


def test_repeats_are_against_the_previous_available_output_of_each_run():
    nan = np.nan
    values = np.array(
        [
            # run 0: a repeat across a gap; a change in one component; a NaN epoch
            [[1.0, 2.0], [nan, nan], [1.0, 2.0], [1.0, 2.5], [1.0, 2.5], [nan, nan]],
            # run 1: the same value, but its first output and one unavailable between
            [[3.0, 4.0], [3.0, 4.0], [3.0, 4.0], [3.0, 4.0], [0.0, 0.0], [0.0, 0.0]],
        ]
    )
    available = np.array(
        [
            [True, False, True, True, True, False],
            [True, True, False, True, True, True],
        ]
    )
    expected = np.array(
        [
            [False, False, True, False, True, False],
            [False, True, False, True, False, True],
        ]
    )
    np.testing.assert_array_equal(repeated(values, available), expected)


def test_a_noisy_output_never_repeats():
    rng = np.random.default_rng(1)
    values = rng.normal(size=(3, 500, 3))
    assert not repeated(values, np.ones((3, 500), bool)).any()
