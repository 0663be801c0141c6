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


def test_the_engine_reads_no_repeat_in_a_constraint_and_one_in_a_frozen_fix():
    """The drive's NHC and ZUPT record 0 by design (``pseudo``): never a frozen sensor; a
    frozen GNSS (a ``stuck`` fault: its last value before the window) repeats inside the
    window only."""
    from ftnav.engine import navigation_model
    from ftnav.io.recording_file import load_recording
    from ftnav.model.scenario import Fault
    from ftnav.recordings import recording_path

    t0 = load_recording(recording_path("rtklib-drive"), methods=["ckf"]).recording.t_start
    stuck = Fault("gnss", "stuck", t0 + 100.0, t0 + 130.0, np.zeros(6))
    loaded = load_recording(recording_path("rtklib-drive"), methods=["ckf"], faults=[stuck])
    rec = loaded.recording
    state = navigation_model(rec).start(loaded.stream, 1)
    names = list(rec.sensor_names)
    for pseudo in ("nhc", "zupt"):
        assert not state.repeated[names.index(pseudo)].any(), pseudo
    gnss = state.repeated[names.index("gnss")][0]
    t = rec.times[gnss]
    assert gnss.sum() > 0 and t.min() >= 100.0 and t.max() < 130.0, (t.min(), t.max())
