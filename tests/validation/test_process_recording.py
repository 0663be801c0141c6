"""``ftnav.process_recording`` at its boundary: the file read once, arguments refused
with their names, results that say what they hold.

Oracles: a count of the file reads; the refusal messages (each names its argument); the
result's own arrays (the DataFrame's rows are the solution table's, the times the
recording's epochs).
"""

from __future__ import annotations

import numpy as np
import pytest
from recording_runs import drive_copy

import ftnav
import ftnav.io.recording_file as recording_file
from ftnav.io.recording_file import load_recording
from ftnav.pipeline import ProcessingError, RecordingResult, process_recording


def _short(doc: dict) -> None:
    doc["filter"] = {**doc.get("filter", {}), "duration_s": 40.0}
    doc["methods"] = [m for m in doc["methods"] if m["name"] == "ckf"]


@pytest.fixture(scope="module")
def short_drive(tmp_path_factory):
    return drive_copy(tmp_path_factory.mktemp("drive") / "drive.toml", _short)


def test_one_call_reads_the_file_once_and_returns_a_typed_result(short_drive, monkeypatch):
    reads = []
    real = recording_file.read_toml
    monkeypatch.setattr(recording_file, "read_toml", lambda src: reads.append(src) or real(src))
    r = ftnav.process_recording(short_drive)
    assert isinstance(r, RecordingResult) and len(reads) == 1
    df = r.to_dataframe()
    np.testing.assert_array_equal(df["time_s"].to_numpy(), r.times)
    np.testing.assert_array_equal(df.drop(columns="method").to_numpy(), r.solution("ckf"))
    assert r.scores_frame().loc["ckf", "reference_epochs"] > 0
    assert r.scores["ckf"].horizontal_rms_m is not None and r.scores["ckf"].prediction is not None
    # the errors the scores come from: at the antenna (the reference's lever arm), not
    # at the IMU the solution table gives
    e = r.errors("ckf")
    assert e.shape == (len(r.reference.index), 3)
    h = np.hypot(e[:, 0], e[:, 1])
    rms = np.sqrt(np.mean(h**2))  # no fault, no outage: every reference epoch
    assert rms == pytest.approx(r.scores["ckf"].horizontal_rms_m, rel=1e-12)
    assert np.any(r.reference.lever_arm)
    with pytest.raises(KeyError, match="'dkf'"):
        r.solution("dkf")
    with pytest.raises(KeyError, match="'dkf'"):
        r.errors("dkf")
    with pytest.raises(IndexError, match="run 1"):
        r.errors("ckf", run=1)
    with pytest.raises(ValueError, match="smooth=True"):
        r.to_dataframe(smoothed=True)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"outages": (60, 60, 10)}, r"^outages: 60 s outages every 60 s leave no GNSS fix"),
        ({"outages": (-1, 60, 10)}, r"^outages: length and spacing must be positive"),
        ({"faults": ["gnss:bias:1:2"]}, r"^faults: a bias needs a MAGNITUDE"),
        ({"faults": ["nhc:bias:1:2:3"]}, r"^faults: 'nhc' is not a GNSS aid"),
        ({"faults": ["gnss:bias:1e12:2e12:3"]}, r"^faults: \[.*not within the processed span"),
        ({"faults": ["gnss:bias:1:2:inf"]}, r"^faults: MAGNITUDE must be finite"),
        ({"faults": ["gnss:stuck:1:2:3"]}, r"^faults: a stuck takes no MAGNITUDE"),
        ({"methods": []}, r"^methods: an empty list chooses nothing"),
        ({"methods": ["ckf", "ckf"]}, r"^methods: 'ckf' given twice"),
        ({"aids": "gnss"}, r"^aids: expected a list of names, got 'gnss'"),
        ({"outages": 15}, r"^outages: expected \(length\[, every\[, start\]\]\) in seconds"),
        ({"outages": (15, 60, "a")}, r"^outages: expected \(length"),
        ({"faults": "gnss:bias:1:2:3"}, r"^faults: expected a list of faults"),
        ({"faults": [3]}, r"^faults: expected a list of faults"),
    ],
)
def test_arguments_are_refused_by_name(short_drive, kw, message):
    with pytest.raises(ProcessingError, match=message):
        process_recording(short_drive, **kw)


def test_an_unknown_recording_is_refused_by_name():
    with pytest.raises(ProcessingError, match=r"^recording: 'no-such-drive' is neither"):
        process_recording("no-such-drive")
    # a built-in simulated scenario's name says where it runs
    with pytest.raises(ProcessingError, match=r"simulated scenario: run it with 'ftnav run'\)$"):
        process_recording("seed000")
    for wrong in (None, 123):
        with pytest.raises(ProcessingError, match=r"^recording: expected a built-in recording"):
            process_recording(wrong)  # a TypeError of os.fspath before


def test_load_recording_takes_a_built_in_name_as_process_recording_does():
    """``load_recording("rtklib-walk")`` said ``rtklib-walk: file not found``."""
    loaded = load_recording("rtklib-walk", methods=["ckf"])
    assert loaded.recording.name == "rtklib-walk"


def test_the_errors_figure_draws_the_errors_the_scores_use(short_drive):
    """``errors.png`` plots the horizontal error at the antenna, as the scores (it plotted
    the IMU's against the antenna's fixes: a 5 cm offset turning with the heading)."""
    from ftnav.plot.recorded import errors_figure

    r = process_recording(short_drive)
    fig = errors_figure(r.loaded, r.traces)
    drawn = fig.axes[0].lines[0].get_ydata()
    e = r.errors("ckf")
    np.testing.assert_allclose(drawn, np.maximum(np.hypot(e[:, 0], e[:, 1]), 1e-4), rtol=1e-12)


def test_the_smoothed_scores_have_no_prediction_and_the_table_shows_them(short_drive):
    """A smoothed solution has no prediction: the forward filter's was scored as its
    own (bit-identical ``prediction_horizontal_rms_m``), and the table's smoothed column
    showed '-' without outages (found by a user's try)."""
    from ftnav.report.recorded import recording_table

    r = ftnav.process_recording(short_drive, smooth=True)
    s = r.scores["ckf"]
    assert s.prediction is not None and s.smoothed is not None
    assert s.smoothed.prediction is None
    assert "prediction_horizontal_rms_m" not in s.smoothed.as_dict()
    frame = r.scores_frame()  # the smoothed scores too (left out before)
    assert frame.loc["ckf", "smoothed_horizontal_rms_m"] == s.smoothed.horizontal_rms_m
    row = recording_table(r.scores).splitlines()[1].split()
    assert row[4] == "-" and float(row[5]) == pytest.approx(s.smoothed.horizontal_rms_m, abs=5e-4)


def test_a_fault_to_the_end_covers_the_last_epoch(short_drive):
    """A window is [START, END): the refusal's advice, END the span's last time, left
    the last fix clean, and that one epoch was scored (0.101 m against 0.027 on the
    drive, found by a user's try).  END one epoch past the last is accepted and covers
    it; beyond that is refused with the END to give."""
    r0 = ftnav.process_recording(short_drive)
    rec = r0.recording
    end = rec.t_start + rec.times[-1] + rec.dt
    start = rec.t_start + rec.times[-1] - 10.0
    r = ftnav.process_recording(short_drive, faults=[f"gnss:bias:{start:.6f}:{end:.6f}:5"])
    e = np.hypot(*r.errors("ckf")[:, :2].T)
    assert e[-1] > 1.0  # the last fix is the fault's: the filter followed it there
    with pytest.raises(ProcessingError, match=rf"to the end: END {end:.3f}, one epoch past"):
        ftnav.process_recording(short_drive, faults=[f"gnss:bias:{start:.6f}:{end + 1:.6f}:5"])


def test_a_score_on_a_handful_of_epochs_is_a_warning(short_drive):
    """A fault over the whole drive left one reference epoch, scored 0.000 m, and said
    nothing (found by a user's try)."""
    r0 = ftnav.process_recording(short_drive)
    assert not [w for w in r0.warnings if "reference epochs" in w]
    rec = r0.recording
    end = rec.t_start + rec.times[-1] + rec.dt
    r = ftnav.process_recording(short_drive, faults=[f"gnss:outage:{rec.t_start}:{end:.6f}"])
    (thin,) = [w for w in r.warnings if "reference epochs" in w]
    n = r.scores["ckf"].reference_epochs
    assert thin.startswith(f"methods[ckf]: scored on {n} of the {len(r.reference.index)}"), thin


def test_the_gnss_on_prediction_leaves_out_the_first_fix_after_an_outage():
    """The prior at the first fix after an outage is the coast (the outage scores hold
    it): counted as a GNSS-on prediction it made the drive's 0.04 m about 0.79 m with
    15 s outages (found by a user's try).  Oracle: the RMS recomputed from the trace."""
    from ftnav.eval.recorded import reference_errors

    r = process_recording(
        "rtklib-drive", methods=["ckf"], aids=["gnss", "gnss-vel"], outages=(15, 60, 40)
    )
    t = r.recording.times[r.reference.index]
    ep = reference_errors(r.traces["ckf"].prediction, r.reference)
    keep = np.ones(t.size, bool)
    for s, e in r.loaded.outages[0]:
        keep &= ~((t >= s) & (t < e))
        keep[np.searchsorted(t, e)] = False
    want = np.sqrt(np.mean(np.hypot(ep[keep, 0], ep[keep, 1]) ** 2))
    got = r.scores["ckf"].prediction.horizontal_rms_m
    assert got == pytest.approx(want, rel=1e-12) and got < 0.1


def test_an_unknown_method_or_aid_is_a_processing_error_naming_the_argument(short_drive):
    """It was the loader's ScenarioError naming the CLI's ``--methods`` (found by a user
    following the docs, which promise a ProcessingError naming the argument)."""
    with pytest.raises(ProcessingError, match=r"^methods: no method 'nope' \(known: ckf\)$"):
        process_recording(short_drive, methods=["nope"])
    with pytest.raises(ProcessingError, match=r"^aids: no aid 'odometer'"):
        process_recording(short_drive, aids=["odometer"])
