"""Integrity on real noise: the vendored rtklibexplorer drive (MEMS IMU + RTK), issue 20.

Oracle: the RTK fixes (Q = 1, cm-level) as the reference, and the plain centralized
filter (``ckf``, no detector) on the same data as the bar a fault-tolerant method must
not fall below once a fault or an outage has ended.  Faults are injected into the
recorded GNSS positions (:class:`ftnav.model.scenario.Fault`), never tuned on: the
guard's settings are the defaults of :class:`ftnav.fusion.config.GuardSettings`.

* GNSS positions alone (``--aids gnss``): no other aid holds the position, so a lock-out
  is a drift without bound (3 367 m before the guard).  Every fault-tolerant built-in
  method must stay within 1.5 × ``ckf``'s horizontal RMS (the GLR method's false alarms
  in the turns cost 225 m before the guard judged a sole source by its own increments).
* A 60 s GNSS position ramp of 0.05 and of 0.2 m/s (every aid): the filter follows
  the slow ramp (no innovation test sees it), the fixes jump back when it ends; the
  aid must be re-admitted within 10 s of the end and the error after it within 1.5 ×
  ``ckf``'s over the same epochs.
* The GNSS position noise 10 times its σ for 60 s (every aid): isolated, re-admitted
  within 10 s of its end, the χ² method's error after it within 1.5 × ``ckf``'s; with the
  GNSS alone (10 and 100 times) used with the noise it shows, not coasted.
* Bursts of 3 m for 1 s every 2 s (an intermittent fault), every aid and GNSS alone: no
  worse than ``ckf`` over the window, within 1.5 × after it.
* 15 s GNSS outages every 60 s: the returning fixes re-admitted within 10 s (GNSS alone
  and every aid); every aid, the error after the outages within 1.5 × ``ckf``'s.
* GNSS positions alone under a 5 m step, a 0.2 m/s ramp (60 s) and a frozen receiver
  (30 s): the only aid is held out for at most its patience after its last jump, coasting
  on its own increments meanwhile (was 34 km, 42 km: a MEMS coast of 60 s, then a
  re-admission that never held); re-admitted within the patience + 1 s of the fault's
  end, the error after it never above the fault's size or ``ckf``'s (which follows the
  fault), and within 1.5 × ``ckf``'s from 5 s after the patience; a jump taken is a
  warning of the self-watch.  A 120 s freeze is coasted like an outage (its repeated
  fix passes no re-admission test: was 135 km) and recovered within 2 s of its end.

Each check runs the χ² and the GLR method (``fkf-chi2``, ``fkf-glr``).
"""

from __future__ import annotations

import numpy as np
import pytest
from recording_runs import drive_copy, horizontal, process

from ftnav.fusion.config import GuardSettings
from ftnav.io.recording_file import load_recording
from ftnav.model.scenario import SINS, Fault

T_FAULT = 100.0  # s after the recording's start
LENGTH = 60.0
SPAN = 260.0  # s of the drive processed for the ramps: the fault and 100 s after it


def _short(tmp_path, methods, span=SPAN):
    def edit(doc):
        doc["filter"]["duration_s"] = span
        doc["methods"] = [m for m in doc["methods"] if m["name"] in methods]

    return drive_copy(tmp_path / "drive.toml", edit)


def _flags(loaded, trace, aid="gnss"):
    return trace.flag[0, :, loaded.recording.sensor_names.index(aid)]


def _readmitted_after(times, flags, t_end):
    """Seconds from ``t_end`` until the flag is down (inf if never)."""
    after = times >= t_end
    down = ~flags[after]
    return float(times[after][np.argmax(down)] - t_end) if down.any() else np.inf


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    return drive_copy(tmp_path_factory.mktemp("drive") / "drive.toml")


TESTED = ("fkf-chi2", "fkf-glr")


@pytest.fixture(scope="module")
def gnss_only(drive):
    return process(drive, aids=["gnss"])  # every built-in method


def test_gnss_alone_every_fault_tolerant_method_stays_with_the_plain_filter(gnss_only):
    """Was 3 367 m against 0.074 m: the χ² test isolated the only position aid for good;
    the GLR method 225 m against 0.037 m (false alarms in turns, then coasts)."""
    _, _, scores = gnss_only
    ckf = scores["ckf"].horizontal_rms_m
    assert set(TESTED) <= set(scores)
    for name, s in scores.items():
        assert s.horizontal_rms_m <= 1.5 * ckf, (name, s.horizontal_rms_m, ckf)


def test_gnss_alone_no_method_is_left_untrusted_by_the_chi_square_test(gnss_only):
    """The self-watch: a fault-free drive gives no finding for ``ckf`` or ``fkf-chi2``."""
    _, _, scores = gnss_only
    for name in ("ckf", "fkf-chi2"):
        assert scores[name].integrity.findings == (), name


def _every_aid(tmp_path, fault_at, start=T_FAULT):
    """The drive up to 100 s after the fault (``start`` s after the recording's start,
    LENGTH s long) with every aid and the fault ``fault_at(t0)`` (``t0`` the recording's
    start): the loaded recording, the traces, the epochs' times, the fault's end, the RMS
    after it of a horizontal error at the fixes, and ``ckf``'s error."""
    path = _short(tmp_path, ("ckf",) + TESTED, span=start + LENGTH + 100.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    loaded, traces, _ = process(path, faults=[fault_at(t0)])
    t_end = start + LENGTH
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    after = t_ref >= t_end

    def rms(e):
        return float(np.sqrt(np.mean(e[after] ** 2)))

    return loaded, traces, loaded.recording.times, t_end, rms, ckf


def _recovery_from_north(tmp_path, kind, metres, start=T_FAULT, axis=1):
    """Every aid, a ``kind`` fault of the GNSS positions of ``metres`` north (``axis``
    1; east: 0) for LENGTH s from ``start``: per tested method, the seconds from its end
    to the re-admission, and the RMS error after it with ``ckf``'s."""
    north = np.zeros(6)
    north[axis] = metres
    loaded, traces, times, t_end, rms, ckf = _every_aid(
        tmp_path,
        lambda t0: Fault("gnss", kind, t0 + start, t0 + start + LENGTH, north),
        start,
    )
    out = {}
    for name in TESTED:
        _, err = horizontal(loaded, traces[name])
        back = _readmitted_after(times, _flags(loaded, traces[name]), t_end)
        out[name] = (back, rms(err), rms(ckf))
    return out


@pytest.mark.parametrize("rate", [0.05, 0.2])
def test_after_a_slow_ramp_the_gnss_is_readmitted_and_the_error_recovers(tmp_path, rate):
    """Was: not re-admitted for 68-300 s, 3.4 and 12.4 m after the fault against ckf's
    0.13 and 0.9 m."""
    for name, (back, err, ckf) in _recovery_from_north(tmp_path, "ramp", rate * LENGTH).items():
        assert back <= 10.0, name
        assert err <= 1.5 * ckf, (name, err, ckf)


@pytest.mark.parametrize("start", [150.0, 184.0, 250.0])
def test_after_a_slow_ramp_elsewhere_on_the_drive_the_rollback_finds_it(tmp_path, start):
    """A 0.05 m/s ramp ending at 210 and 244 s: the jump back at its end gains the
    rollback of its pull 16.5-17.4 in χ², short of a 3-D fix's 21.1 (the gain is a χ²₁
    variate by chance, ``Guard``): held for the patience 3 m off, 1.65-1.85 m after it
    against ``ckf``'s 0.11-0.12 m; now rolled back and re-admitted in 1.3 s.  Ending at
    310 s: the GLR alarmed on the offset the rollback left inside its covariance and
    held the fixes 8.3 s, 0.29 m after against 0.13 m; the guard's own χ² judges them
    after a rollback that explains the jump (0.16 m)."""
    for name, (back, err, ckf) in _recovery_from_north(tmp_path, "ramp", 3.0, start).items():
        assert back <= 10.0, name
        assert err <= 1.5 * ckf, (name, err, ckf)


@pytest.mark.parametrize(
    ("kind", "velocity"), [("bias", [0.5, 0.0, 0.0]), ("ramp", [0.0, 1.0, 0.0])]
)
def test_a_fault_of_the_receiver_velocities_never_costs_their_positions(tmp_path, kind, velocity):
    """The GNSS velocities 0.5 m/s east for 60 s (5 σ: the χ² flickers at its threshold),
    or ramped to 1 m/s north.  Held, they were let back in 10 s in by the patience at an
    epoch between the fixes, where no aid measures (the χ² method), or backed by their
    positions' per-epoch evidence 14 s in; the bias was then taken, the healthy positions
    were held and the estimate followed the velocities: 35 m (χ²) and 17.7 m (GLR) after
    the bias against ``ckf``'s 0.057 m, 15.7 m (GLR) after the ramp.  A velocity offset
    the positions integrate is theirs to judge: neither rule takes it now."""
    magnitude = np.array([0.0, 0.0, 0.0] + velocity)
    loaded, traces, times, t_end, rms, ckf = _every_aid(
        tmp_path,
        lambda t0: Fault("gnss-vel", kind, t0 + T_FAULT, t0 + T_FAULT + LENGTH, magnitude),
    )
    for name in TESTED:
        _, err = horizontal(loaded, traces[name])
        assert rms(err) <= 1.5 * rms(ckf), (name, rms(err), rms(ckf))
        for aid in ("gnss", "gnss-vel"):
            assert _readmitted_after(times, _flags(loaded, traces[name], aid), t_end) <= 10.0
        # the positions are never held for long beside a fault of their velocities
        held = _flags(loaded, traces[name], "gnss")
        assert held[times >= T_FAULT].mean() < 0.05, name


#: faults whose end the filter had followed, too long ago for a rollback window: a
#: 0.01 m/s ramp of the fixes for 300 s (3 m), and the fixes and velocities drifting
#: together (0.05 m/s for 60 s: consistent with each other)
_FOLLOWED = {
    "ramp-300-s": (100.0, 300.0, (("gnss", [0.0, 3.0, 0.0, 0.0, 0.0, 0.0], "ramp"),)),
    "receiver-drifting": (
        150.0,
        60.0,
        (
            ("gnss", [0.0, 3.0, 0.0, 0.0, 0.0, 0.0], "ramp"),
            ("gnss-vel", [0.0, 0.0, 0.0, 0.0, 0.05, 0.0], "bias"),
        ),
    ),
}


@pytest.mark.parametrize("case", list(_FOLLOWED))
def test_the_end_of_a_fault_too_long_to_roll_back_is_taken_at_the_next_fix(tmp_path, case):
    """Every aid: the filter follows the fault, no rollback window reaches back over it,
    and its end is held for the patience.  The patience ends between the fixes, where
    nothing can be taken; it was released there with nothing taken, the next fix started
    a new hold whose patience ended between the fixes again, and the fixes were held to
    the end of the run (the ramp: 3.35 m after it against ``ckf``'s 0.17 m; the drift:
    held 104 s, 1.88 m against 0.11 m).  The jump is now due at the next fix, taken once
    the fixes' offset has kept one level for the patience (``GuardState.due``)."""
    start, length, spec = _FOLLOWED[case]
    path = _short(tmp_path, ("ckf", "fkf-chi2"), span=start + length + 60.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    faults = [
        Fault(aid, kind, t0 + start, t0 + start + length, np.array(m)) for aid, m, kind in spec
    ]
    loaded, traces, _ = process(path, faults=faults)
    t_end = start + length
    times = loaded.recording.times
    flags = _flags(loaded, traces["fkf-chi2"])
    patience = GuardSettings().patience_s
    assert _readmitted_after(times, flags, t_end) <= patience + 1.0
    assert not flags[times >= t_end + patience + 1.0].any()
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    late = t_ref >= t_end + patience + 5.0
    rms, bar = (float(np.sqrt(np.mean(e[late] ** 2))) for e in (err, ckf))
    assert rms <= 1.5 * bar, (rms, bar)


def test_with_its_velocities_alone_a_ramp_of_the_fixes_is_rolled_back_past_a_refusal(drive):
    """The fixes with the receiver's velocities only (no NHC, no ZUPT), a 0.05 m/s ramp
    from 420 s: the best window's rollback (50 s of pulls) moved the velocity 0.24 m/s
    against the velocities, which refused it, and the fixes were held 3 m off for the
    patience (1.75 m after the ramp against ``ckf``'s 0.30, back in 10.2 s); the best
    window the velocities accept is taken now."""
    t0 = load_recording(drive, methods=["ckf"]).recording.t_start
    north = np.array([0.0, 3.0, 0.0, 0.0, 0.0, 0.0])
    start = 420.0
    fault = Fault("gnss", "ramp", t0 + start, t0 + start + LENGTH, north)
    loaded, traces, _ = process(
        drive, methods=["ckf", "fkf-chi2"], aids=["gnss", "gnss-vel"], faults=[fault]
    )
    t_end = start + LENGTH
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    after = t_ref >= t_end
    back = _readmitted_after(loaded.recording.times, _flags(loaded, traces["fkf-chi2"]), t_end)
    assert back <= 10.0
    rms, bar = (float(np.sqrt(np.mean(e[after] ** 2))) for e in (err, ckf))
    assert rms <= 1.5 * bar, (rms, bar)


def test_after_every_15_s_outage_the_gnss_is_readmitted_within_10_s(drive):
    loaded, traces, _ = process(
        drive, methods=list(TESTED), aids=["gnss"], outage=(15.0, 60.0, 40.0)
    )
    times = loaded.recording.times
    (schedule,) = loaded.outages
    assert len(schedule) == 8
    for name in TESTED:
        flags = _flags(loaded, traces[name])
        for _, end in schedule:
            assert _readmitted_after(times, flags, end) <= 10.0, (name, end)


def test_every_aid_after_the_15_s_outages_no_method_is_worse_than_the_plain_filter(drive):
    """Every aid (the NHC and ZUPT the only aids inside each outage): the GNSS back within
    10 s of every outage and the error from the first outage's end within 1.5 × ``ckf``'s.
    Was 1.55 × for the GLR method: its alarms on the NHC in turns inside the outages
    isolated the only aid measuring, and the INS coasted (a sequential test now runs on
    a device's aids only, not on a gated constraint: :mod:`ftnav.fusion.detection`)."""
    loaded, traces, _ = process(drive, methods=["ckf", *TESTED], outage=(15.0, 60.0, 40.0))
    times = loaded.recording.times
    (schedule,) = loaded.outages
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    after = t_ref >= schedule[0][1]
    bar = 1.5 * float(np.sqrt(np.mean(ckf[after] ** 2)))
    for name in TESTED:
        flags = _flags(loaded, traces[name])
        for _, end in schedule:
            assert _readmitted_after(times, flags, end) <= 10.0, (name, end)
        _, err = horizontal(loaded, traces[name])
        assert float(np.sqrt(np.mean(err[after] ** 2))) <= bar, name


@pytest.mark.parametrize(
    ("kind", "length", "metres"), [("bias", 60.0, 5.0), ("ramp", 60.0, 12.0), ("stuck", 30.0, 0.0)]
)
def test_gnss_alone_a_fault_of_the_only_aid_is_coasted_and_recovered(
    tmp_path, kind, length, metres
):
    path = _short(tmp_path, ("ckf", "fkf-chi2"))
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    magnitude = np.array([0.0, metres, 0.0, 0.0, 0.0, 0.0])
    fault = Fault("gnss", kind, t0 + T_FAULT, t0 + T_FAULT + length, magnitude)
    loaded, traces, scores = process(path, aids=["gnss"], faults=[fault])
    times = loaded.recording.times
    t_end = T_FAULT + length
    patience = GuardSettings().patience_s
    # a jump taken is said (a frozen output's coast is not one)
    watch = scores["fkf-chi2"].integrity
    said = [f for f in watch.findings if "taken back with its jump" in f]
    assert (watch.aid("gnss").taken > 0) == (kind != "stuck") == bool(said), watch
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    back = _readmitted_after(times, _flags(loaded, traces["fkf-chi2"]), t_end)
    assert back <= patience + 1.0, back
    rms = lambda e, at: float(np.sqrt(np.mean(e[at] ** 2)))  # noqa: E731
    after, late = t_ref >= t_end, t_ref >= t_end + patience + 5.0
    # never worse than following the fault: its size, or ckf's (a frozen output's jump)
    assert rms(err, after) <= max(metres, rms(ckf, after)), (rms(err, after), rms(ckf, after))
    assert rms(err, late) <= 1.5 * rms(ckf, late), (rms(err, late), rms(ckf, late))


@pytest.mark.parametrize("method", TESTED)
def test_gnss_alone_a_start_off_the_first_fixes_is_not_held(tmp_path, method):
    """The GNSS 5 m north from the recording's first fix to 30 s: the estimate starts
    from the alignment, 5 m off the fixes.  The guard held the first fix (nothing it
    could have jumped from), coasted an INS no aid had informed for the patience, and
    took the jump with the velocity it had coasted: 56.2 m over the drive, 50.6 m from
    10 s after the fault (``ckf`` 0.055 m).  An aid's first measurement is now never
    held (docs/integrity.md §1.16).  Oracle: ``ckf``, which follows the fixes."""
    path = _short(tmp_path, ("ckf", method), 60.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    north = np.array([0.0, 5.0, 0.0, 0.0, 0.0, 0.0])
    loaded, traces, _ = process(
        path, aids=["gnss"], faults=[Fault("gnss", "bias", t0, t0 + 30.0, north)]
    )
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces[method])
    rms = lambda e, at: float(np.sqrt(np.mean(e[at] ** 2)))  # noqa: E731
    late = t_ref >= 30.0 + GuardSettings().patience_s + 5.0
    assert rms(err, late) <= 1.5 * rms(ckf, late), (rms(err, late), rms(ckf, late))
    assert rms(err, t_ref >= 0.0) <= 5.0, rms(err, t_ref >= 0.0)  # never past the fault's size


@pytest.fixture(scope="module")
def height_ramp(tmp_path_factory):
    """GNSS positions alone, a 6 m height ramp over 60 s from 150 s: the times of the
    fixes, ``ckf``'s and the χ² method's horizontal errors, the ramp's end."""
    start = 150.0
    path = _short(tmp_path_factory.mktemp("height"), ("ckf", "fkf-chi2"), start + 160.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    up = np.array([0.0, 0.0, 6.0, 0.0, 0.0, 0.0])
    fault = Fault("gnss", "ramp", t0 + start, t0 + start + LENGTH, up)
    loaded, traces, _ = process(path, aids=["gnss"], faults=[fault])
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    return t_ref, ckf, err, start + LENGTH


def test_gnss_alone_a_height_ramp_is_not_rolled_back_into_thehorizontal(height_ramp):
    """The rollback that explained the jump back at the ramp's end removed a window of
    the only aid's pulls with their horizontal part (the MEMS INS's drift the fixes had
    corrected over it): 5.8 m sideways and a 1.2 m/s velocity error, inside the window's
    widened covariance, so the fixes were back at once and pulled it in over a minute:
    0.47 m after the ramp against ``ckf``'s 0.067 m (at the IMU).  A sole source's
    removal moves the quantity along the jump only now: from the patience's end (10 s
    after the ramp) 0.037 m against ``ckf``'s 0.040 at the antenna."""
    t_ref, ckf, err, t_end = height_ramp
    late = t_ref >= t_end + 10.0
    rms, bar = (float(np.sqrt(np.mean(e[late] ** 2))) for e in (err, ckf))
    assert rms <= 1.5 * bar, (rms, bar)


@pytest.mark.xfail(
    strict=True,
    reason=(
        "scored at the antenna: the fixes' jump back is held for the patience (10.6 s), "
        "0.21-0.28 m meanwhile; 0.089 m against ckf's 0.050 over the 100 s after the ramp "
        "(1.76 x); at the IMU the lever arm's 5 cm hid it (docs/integrity.md §5)"
    ),
)
def test_gnss_alone_after_a_height_ramp_the_error_is_within_the_bar(height_ramp):
    """The issue's bar over the whole 100 s after the ramp: within 1.5 × ``ckf``."""
    t_ref, ckf, err, t_end = height_ramp
    after = t_ref >= t_end
    rms, bar = (float(np.sqrt(np.mean(e[after] ** 2))) for e in (err, ckf))
    assert rms <= 1.5 * bar, (rms, bar)


def test_gnss_alone_a_long_freeze_of_the_only_aid_is_coasted_like_an_outage(tmp_path):
    """The receiver frozen for 120 s, GNSS alone: its repeated fix passed the growing
    coasting allowance 38 s in and was re-admitted, dragging the estimate back to where
    the car had been (375 m at once, then a 30 m/s velocity error): 135 km after the
    freeze.  A repeated output now passes no re-admission test, so the freeze is coasted
    like an outage of the same length, and the fresh fixes after it are taken back within
    2 s (the re-admission's passes); from 5 s after the end the error is within 1.5 x
    ``ckf``'s, which followed the frozen fix; the self-watch flags the run."""
    length = 120.0
    path = _short(tmp_path, ("ckf", "fkf-chi2"))
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    freeze = Fault("gnss", "stuck", t0 + T_FAULT, t0 + T_FAULT + length, np.zeros(6))
    outage = Fault("gnss", "outage", t0 + T_FAULT, t0 + T_FAULT + length, np.zeros(6))
    loaded, traces, scores = process(path, aids=["gnss"], faults=[freeze])
    _, coast, _ = process(path, methods=["fkf-chi2"], aids=["gnss"], faults=[outage])
    t_end = T_FAULT + length
    flags = _flags(loaded, traces["fkf-chi2"])
    times = loaded.recording.times
    held = (times >= T_FAULT) & (times < t_end)
    assert flags[held].all()  # never taken back on a repeated fix
    assert _readmitted_after(times, flags, t_end) <= 2.0
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    _, err_coast = horizontal(loaded, coast["fkf-chi2"])
    during = (t_ref >= T_FAULT) & (t_ref < t_end)
    # the freeze costs what an outage of the same length costs (the same coast)
    np.testing.assert_allclose(err[during], err_coast[during], rtol=1e-6, atol=1e-6)
    late = t_ref >= t_end + 5.0
    rms = lambda e: float(np.sqrt(np.mean(e[late] ** 2)))  # noqa: E731
    assert rms(err) <= 1.5 * rms(ckf), (rms(err), rms(ckf))
    assert not scores["fkf-chi2"].integrity.trusted


def _noise(t0, factor):
    """A noise-scale fault of the GNSS positions from T_FAULT for LENGTH s."""
    return Fault("gnss", "noise-scale", t0 + T_FAULT, t0 + T_FAULT + LENGTH, np.full(6, factor))


@pytest.fixture(scope="module")
def noise_minute(tmp_path_factory):
    """Every aid, the GNSS position noise 10 times its σ (0.5 m) for 60 s."""
    return _every_aid(tmp_path_factory.mktemp("noise"), lambda t0: _noise(t0, 10.0))


def test_after_a_noise_increase_the_gnss_is_readmitted_and_the_error_recovers(noise_minute):
    """The χ² and GLR methods isolate the noisy minute and re-admit the GNSS within 10 s
    of its end (measured 1.6 s); from 10 s after it the χ² method is at ``ckf``'s error
    (0.026 m at the antenna, as ``ckf``)."""
    loaded, traces, times, t_end, _, ckf = noise_minute
    for name in TESTED:
        flags = _flags(loaded, traces[name])
        assert flags[(times >= T_FAULT) & (times < t_end)].mean() > 0.5, name  # isolated
        assert _readmitted_after(times, flags, t_end) <= 10.0, name
    t_ref, err = horizontal(loaded, traces["fkf-chi2"])
    late = t_ref >= t_end + 10.0
    rms = lambda e: float(np.sqrt(np.mean(e[late] ** 2)))  # noqa: E731
    assert rms(err) <= 1.5 * rms(ckf), (rms(err), rms(ckf))


@pytest.mark.xfail(
    strict=True,
    reason=(
        "scored at the antenna, the re-admission after the 60 s coast costs 0.14 m over its "
        "first 5 s: 0.041 m against ckf's 0.024 over the 100 s after it, 1.68 x (1.19 x to "
        "the drive's end); at the IMU the lever arm's 5 cm hid it (docs/integrity.md §5)"
    ),
)
def test_after_a_noise_increase_the_error_from_its_end_is_within_the_bar(noise_minute):
    """The issue's bar over the whole 100 s after the noisy minute: the χ² method within
    1.5 × ``ckf``'s horizontal RMS."""
    loaded, traces, _, _, rms, ckf = noise_minute
    _, err = horizontal(loaded, traces["fkf-chi2"])
    assert rms(err) <= 1.5 * rms(ckf), (rms(err), rms(ckf))


@pytest.mark.parametrize("factor", [10.0, 100.0])
def test_gnss_alone_a_noise_increase_of_the_only_aid_is_used_not_coasted(tmp_path, factor):
    """GNSS positions alone, their noise 10 and 100 times its σ (0.5 and 5 m) for 60 s.
    The aid is held, but used with the noise its increments show: coasting the MEMS INS
    instead reached 148 m in the 10x minute and locked the aid out for good at 100x
    (215 km).  During the fault never worse than 1.5 x ``ckf`` (which uses the noisy
    fixes); re-admitted within 10 s of its end; after it within 1.5 x ``ckf`` at 10x
    (measured 0.063 against 0.061 m on the whole drive) and 2.5 x at 100x (0.18 against
    0.10 m: the last noisy fixes leave it 3 m off for the 1.1 s until re-admission)."""
    path = _short(tmp_path, ("ckf", "fkf-chi2"))
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    loaded, traces, scores = process(path, aids=["gnss"], faults=[_noise(t0, factor)])
    times = loaded.recording.times
    t_end = T_FAULT + LENGTH
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    rms = lambda e, at: float(np.sqrt(np.mean(e[at] ** 2)))  # noqa: E731
    during, after = (t_ref >= T_FAULT) & (t_ref < t_end), t_ref >= t_end
    assert rms(err, during) <= 1.5 * rms(ckf, during), (rms(err, during), rms(ckf, during))
    assert _readmitted_after(times, _flags(loaded, traces["fkf-chi2"]), t_end) <= 10.0
    bar = 1.5 if factor <= 10.0 else 2.5
    assert rms(err, after) <= bar * rms(ckf, after), (rms(err, after), rms(ckf, after))
    # the self-watch says the aid was used for its noise while held
    watch = scores["fkf-chi2"].integrity
    fixes = loaded.recording.times[loaded.reference_index]
    in_window = int(((fixes >= T_FAULT) & (fixes < t_end)).sum())
    gnss = watch.aid("gnss")
    assert gnss.noisy > 0.5 * in_window, (gnss, in_window)
    assert any("used with the noise it showed" in f for f in watch.findings), watch


@pytest.mark.parametrize("aids", [None, ["gnss"]], ids=["every aid", "GNSS alone"])
def test_an_intermittent_gnss_fault_costs_less_than_following_it(tmp_path, aids):
    """Bursts of +3 m north for 1 s every 2 s over 60 s (an intermittent fault): the
    χ² method holds each burst and takes the fixes back as each ends (the only aid: at
    once, its one jump undone; it coasted through every burst before, 20 m RMS over
    the window with the GNSS alone).  Over the window no worse than ``ckf``, which
    follows half of each burst (measured 0.08 and 0.19 m against 1.7 and 1.6 m); after
    it within 1.5 x ``ckf``."""
    path = _short(tmp_path, ("ckf", "fkf-chi2"))
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    north = np.array([0.0, 3.0, 0.0, 0.0, 0.0, 0.0])
    bursts = [
        Fault("gnss", "bias", t0 + T_FAULT + a, t0 + T_FAULT + a + 1.0, north)
        for a in np.arange(0.0, LENGTH, 2.0)
    ]
    loaded, traces, _ = process(path, aids=aids, faults=bursts)
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-chi2"])
    rms = lambda e, at: float(np.sqrt(np.mean(e[at] ** 2)))  # noqa: E731
    during, after = (t_ref >= T_FAULT) & (t_ref < T_FAULT + LENGTH), t_ref >= T_FAULT + LENGTH
    assert rms(err, during) <= rms(ckf, during), (rms(err, during), rms(ckf, during))
    assert rms(err, after) <= 1.5 * rms(ckf, after), (rms(err, after), rms(ckf, after))


def test_gnss_alone_a_fast_ramp_of_the_only_aid_does_not_lock_it_out(tmp_path):
    """A 1 m/s ramp of the only aid for 60 s (60 m): the filter follows it as ``ckf``
    does, and the fixes' jump back at its end is held, then taken.  A noisy-aid rule that
    cleared the hold's jump sum lost that jump and locked the aid out (83 km); the aid
    is back within the patience + 5 s.  Its error after the ramp, 10.5 m against
    ``ckf``'s 2.3 m, does not hold the 1.5 x bar (docs/integrity.md §5): only a lock-out
    is tested here."""
    path = _short(tmp_path, ("ckf", "fkf-chi2"))
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    north = np.array([0.0, 60.0, 0.0, 0.0, 0.0, 0.0])
    ramp = Fault("gnss", "ramp", t0 + T_FAULT, t0 + T_FAULT + LENGTH, north)
    loaded, traces, _ = process(path, aids=["gnss"], faults=[ramp])
    t_end = T_FAULT + LENGTH
    flags = _flags(loaded, traces["fkf-chi2"])
    assert _readmitted_after(loaded.recording.times, flags, t_end) <= (
        GuardSettings().patience_s + 5.0
    )
    t_ref, err = horizontal(loaded, traces["fkf-chi2"])
    late = t_ref >= t_end + 30.0
    assert np.sqrt(np.mean(err[late] ** 2)) < 1.0, np.sqrt(np.mean(err[late] ** 2))


def test_a_sins_gyro_step_in_an_outage_does_not_lock_the_returning_gnss_out(tmp_path):
    """A fault of the INS nobody else can see: a 0.5 °/s heading-gyro bias step 1.5 s
    into a 15 s GNSS outage, for 48 s (every aid).  The GNSS returns 11 m off the
    drifted INS; its positions and velocities are both held, and the NHC cannot see a
    heading error (it holds the INS's own velocity in the INS's own frame).  Was: held
    45 s, 32 m off at the fault's end against ``ckf``'s 0.05 m (a strict expected
    failure since 2026-12-05).  Letting the receiver's two halves back each other
    passed this but locked out a receiver whose two halves fail together; now the
    receiver consistent with itself (its positions' increments against its velocities,
    the NHC's updates between the fixes taken out) is taken back after the patience
    (the guard's device rule, docs/integrity.md §1.8).
    """
    path = _short(tmp_path, ("ckf",) + TESTED, span=340.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    start, end = 242.0, 290.0
    step = Fault(SINS, "gyro-bias", t0 + start, t0 + end, np.radians([0.0, 0.0, 0.5]))
    loaded, traces, _ = process(path, faults=[step], outage=(15.0, 60.0, 40.0))
    (schedule,) = loaded.outages
    (back_at,) = [e for s, e in schedule if s <= start < e]  # the fault starts in an outage
    times = loaded.recording.times
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    after = (t_ref >= end) & ~np.any([(t_ref >= s) & (t_ref < e) for s, e in schedule], 0)
    bar = float(np.sqrt(np.mean(ckf[after] ** 2)))
    patience = GuardSettings().patience_s
    for name in TESTED:
        for aid in ("gnss", "gnss-vel"):
            wait = _readmitted_after(times, _flags(loaded, traces[name], aid), back_at)
            assert wait <= patience + 3.0, (name, aid, wait)
        _, err = horizontal(loaded, traces[name])
        got = float(np.sqrt(np.mean(err[after] ** 2)))
        assert got <= 1.5 * bar, (name, got, bar)


def _after_rms(path, faults, after_s, **kw):
    """Per tested method, its horizontal RMS from ``after_s`` (s of the reference) under
    ``faults``, and the bar: 1.5 × ``ckf``'s, or 1.5 × the method's own level without
    the faults where that is higher (the GLR's on the drive, 1.7 × ``ckf``'s: its own
    expected failure)."""
    loaded, traces, _ = process(path, faults=faults, **kw)
    _, clean, _ = process(path, **kw)
    t_ref, _ = horizontal(loaded, traces["ckf"])
    after = t_ref >= after_s

    def rms(trace):
        return float(np.sqrt(np.mean(horizontal(loaded, trace)[1][after] ** 2)))

    bar = rms(traces["ckf"])
    return {name: (rms(traces[name]), 1.5 * max(bar, rms(clean[name]))) for name in TESTED}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("axis", "deg_s"), [(0, 1.0), (2, 2.0), (2, 10.0)], ids=["pitch-1", "heading-2", "heading-10"]
)
def test_after_a_large_sins_gyro_step_with_the_gnss_on_the_gnss_is_not_locked_out(
    tmp_path, axis, deg_s
):
    """Found by a newcomer's try (2026-12-07): a large gyro bias step of the SINS for 30 s
    with the GNSS on (every aid).  ``ckf`` keeps the fixes through it and is at its
    fault-free level after it; the χ² and GLR methods held both halves of the receiver
    as the tilt drove the INS off (the vehicle constraints gated by the same error),
    tested them only against that drifting INS, and never took them back: 164 km after
    a 1 °/s pitch step, 5.4 km after a 10 °/s heading step.  Now the receiver,
    consistent with itself (its positions' increments against its velocities), is taken
    back after the patience (the guard's device rule), within 1.5 × ``ckf`` after the
    fault, or of its own level without the fault where that is higher (the GLR's on
    the drive, 1.7 × ``ckf``'s: its own expected failure)."""
    path = _short(tmp_path, ("ckf",) + TESTED, span=300.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    start, end = 102.0, 132.0
    rate = np.zeros(3)
    rate[axis] = np.radians(deg_s)
    step = Fault(SINS, "gyro-bias", t0 + start, t0 + end, rate)
    for name, (got, bar) in _after_rms(path, [step], end + 30.0).items():
        assert got <= bar, (name, got, bar)


@pytest.mark.slow
@pytest.mark.parametrize(
    "deg_s",
    [
        pytest.param(1.0, id="pitch-1"),
        pytest.param(
            10.0,
            id="heading-10",
            marks=pytest.mark.xfail(
                strict=True,
                reason=(
                    "a 10 deg/s heading step with positions alone: back after the longest "
                    "coast (30 s), the heading then re-learned from positions only, 23.3 m "
                    "(GLR 124 m) after the step against ckf's 0.040 m (docs/integrity.md §5)"
                ),
            ),
        ),
    ],
)
def test_gnss_alone_after_a_large_sins_gyro_step_the_gnss_is_not_locked_out(tmp_path, deg_s):
    """Found 2026-12-07 trying the device rule on cases it was not built for: the large
    gyro steps of the test above with the GNSS positions as the only aid.  Positions alone
    have no rate half to test themselves against; every increment against the drifting
    INS was a jump, the patience never came: 126 km after a 1 °/s pitch step against
    ``ckf``'s 0.035 m.  Now an only aid held past the longest coast (three patiences)
    with fresh outputs is taken back, the covariance scaled to cover it (the guard's
    coast bound); the bar as above (``ckf``, or the method's own fault-free level)."""
    path = _short(tmp_path, ("ckf",) + TESTED, span=300.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    rate = np.radians([deg_s, 0.0, 0.0] if deg_s == 1.0 else [0.0, 0.0, deg_s])
    step = Fault(SINS, "gyro-bias", t0 + 102.0, t0 + 132.0, rate)
    for name, (got, bar) in _after_rms(path, [step], 162.0, aids=["gnss"]).items():
        assert got <= bar, (name, got, bar)


@pytest.mark.parametrize("metres", [1.0, 2.0])
def test_after_a_lasting_step_taken_back_through_the_allowance_the_gnss_comes_home(
    tmp_path, metres
):
    """Every aid, a north step of the GNSS positions for 60 s: it outlasts the coasting
    allowance, so the methods take the aid back with its step (as ``ckf`` follows it);
    when the step ends the fixes jump home.  Was: that jump held 40 s as a new fault, the
    estimate left on the step (2 m: 0.93 m after the fault against ``ckf``'s 0.10 m, both
    methods); now re-admitted within 2 s and within 1.5 × ``ckf``'s error after it."""
    for name, (back, err, ckf) in _recovery_from_north(tmp_path, "bias", metres).items():
        assert back <= 2.0, name
        assert err <= 1.5 * ckf, (name, err, ckf)


def test_a_step_taken_through_a_rollback_at_its_onset_comes_home_at_its_end(tmp_path):
    """Every aid, the fixes 3 m east for 60 s.  At the step's first fix a healthy
    window's pull (1.9 m east, 2.6 σ of its covariance: the MEMS INS's drift the fixes
    had corrected) happened to explain most of the jump, and its rollback moved the
    estimate toward the step (the chance fit of a "drag now over"); the fixes then agreed
    and were taken.  The rollback's move entered the held fixes' next increment as a
    jump back, so the hold's sum no longer undid the step: its end was a new fault, held
    for the patience (10.1 s, 3 m off: 0.13 m from 10 s after against ``ckf``'s 0.03 m,
    both methods).  A held aid's last innovation is now taken against the estimate as
    the rollback left it: the end comes home within 2 s, within 1.5 × ``ckf``'s error
    after it."""
    for name, (back, err, ckf) in _recovery_from_north(tmp_path, "bias", 3.0, axis=0).items():
        assert back <= 2.0, (name, back)
        assert err <= 1.5 * ckf, (name, err, ckf)


def test_fixes_back_off_after_an_outage_come_home_at_the_fault_end(tmp_path):
    """Every aid, a 60 s GNSS outage from 100 s, the fixes back 5 m north of the truth for
    30 s (a wrong fix after the receiver re-acquires) and right again.  The return's hold
    has no jump (the coast's drift allowance covers the increment over the gap), and
    after the patience its offset was taken by a relaxed re-admission that kept no jump
    sum: the jump back at 190 s was a new fault, held for the patience again (5 m off
    for 10.5 s: 0.20 m from 10 s after against ``ckf``'s 0.03 m, both methods).  The
    offset a relaxed re-admission takes beyond chance is now kept as the sum, taken, and
    the jump back comes home at once: re-admitted within 2 s of the fault's end, and
    within 1.5 × ``ckf``'s error from its end, or of the method's own level without the
    faults where that is higher (the GLR's)."""
    start, out_end, end = 100.0, 160.0, 190.0
    path = _short(tmp_path, ("ckf",) + TESTED, span=end + 60.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    north = np.array([0.0, 5.0, 0.0, 0.0, 0.0, 0.0])
    faults = [
        Fault("gnss", "outage", t0 + start, t0 + out_end, np.zeros(6)),
        Fault("gnss", "bias", t0 + out_end, t0 + end, north),
    ]
    loaded, traces, _ = process(path, faults=faults)
    _, clean, _ = process(path)
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    after = t_ref >= end

    def rms(trace):
        return float(np.sqrt(np.mean(horizontal(loaded, trace)[1][after] ** 2)))

    for name in TESTED:
        back = _readmitted_after(loaded.recording.times, _flags(loaded, traces[name]), end)
        assert back <= 2.0, (name, back)
        bar = 1.5 * max(rms(traces["ckf"]), rms(clean[name]))
        assert rms(traces[name]) <= bar, (name, rms(traces[name]), bar)


@pytest.mark.parametrize("metres", [5.0, 2.0])
def test_gnss_alone_a_false_alarm_during_a_long_step_keeps_its_jump_back(tmp_path, metres):
    """GNSS positions alone, a north step of ``metres`` from 100 s to 480 s: the step is
    followed (taken after the patience, or let back in through the allowance), and the
    GLR's false alarms in the turns (255, 266, 430 s) each held the fix for about a
    second.  Such a hold, with no jump of its own, used to clear the hold's jump sum, so
    the step's end was a new jump, held 10.1 s (5 m) and 5.8 s (2 m: 0.78 m after the
    step against ``ckf``'s 0.22 m): the patience.  The sum now outlives a false alarm's
    hold and the jump back cancels it."""
    end = 480.0
    path = _short(tmp_path, ("ckf", "fkf-glr"), span=549.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    step = Fault("gnss", "bias", t0 + T_FAULT, t0 + end, np.array([0.0, metres, 0, 0, 0, 0]))
    loaded, traces, _ = process(path, aids=["gnss"], faults=[step])
    times = loaded.recording.times
    assert _readmitted_after(times, _flags(loaded, traces["fkf-glr"]), end) <= 2.0
    t_ref, ckf = horizontal(loaded, traces["ckf"])
    _, err = horizontal(loaded, traces["fkf-glr"])
    after = t_ref >= end
    rms = lambda e: float(np.sqrt(np.mean(e[after] ** 2)))  # noqa: E731
    assert rms(err) <= 1.5 * rms(ckf), (rms(err), rms(ckf))


def test_positions_with_the_constraints_alone_the_glr_stays_with_the_plain_filter(drive):
    """The receiver's positions with NHC and ZUPT (no GNSS velocities: a receiver that
    gives none).  The constraints read the velocity across the track and up only: the
    along-track motion has no other source, and a hold of the fixes is a coast of the
    MEMS INS along the road.  Counted as witnesses, they let the GLR's false alarms in
    the turns roll the fixes' pulls back and hold them (0.94 m RMS, 9.4 m at most,
    against ``ckf``'s 0.061 m); the fixes are a sole source along the track now
    (``Guard._blind``: 0.063 m).  Fault-free, every fault-tolerant method must stay
    within 1.5 × ``ckf``'s horizontal RMS."""
    loaded, traces, _ = process(drive, methods=["ckf", *TESTED], aids=["gnss", "nhc", "zupt"])
    _, ckf = horizontal(loaded, traces["ckf"])
    bar = float(np.sqrt(np.mean(ckf**2)))
    for name in TESTED:
        _, err = horizontal(loaded, traces[name])
        rms = float(np.sqrt(np.mean(err**2)))
        assert rms <= 1.5 * bar, (name, rms, bar)


#: faults of the fixes beside the vehicle constraints only: (start s, length s, ENU m)
_BESIDE_CONSTRAINTS = {
    "ramp-300-s": (100.0, 300.0, [0.0, 3.0, 0.0]),
    "height-ramp": (150.0, 60.0, [0.0, 0.0, 6.0]),
}


@pytest.mark.parametrize(
    ("case", "method"),
    [(case, method) for case in _BESIDE_CONSTRAINTS for method in ("fkf-chi2", "fkf-glr")],
)
def test_beside_the_constraints_alone_the_fixes_fare_no_worse_than_alone(tmp_path, case, method):
    """The fixes beside NHC and ZUPT only (a receiver that gives no velocities).  The
    constraints read the velocity across the track and up, so row by row they counted
    as witnesses of every GNSS row's rate, and the fixes were judged as an aid with
    witnesses: a rollback they could not judge along the track was taken, and a
    re-admission's jump held afterwards (the 0.01 m/s ramp: 12.5 m after it, back in
    48 s; the height ramp: 3.2 m).  Oracle: the same method with the fixes alone, whose
    along-track motion has no other source either; a witness of part of the quantity
    must not leave the aid worse off than none (1.25 ×), and the fixes are back within
    the patience + 1 s of the fault's end (``Guard._blind``)."""
    start, length, enu = _BESIDE_CONSTRAINTS[case]
    path = _short(tmp_path, ("ckf", method), span=start + length + 60.0)
    t0 = load_recording(path, methods=["ckf"]).recording.t_start
    magnitude = np.array([*enu, 0.0, 0.0, 0.0])
    fault = Fault("gnss", "ramp", t0 + start, t0 + start + length, magnitude)
    t_end = start + length
    after = {}
    for aids in (["gnss", "nhc", "zupt"], ["gnss"]):
        loaded, traces, _ = process(path, aids=aids, faults=[fault])
        t_ref, err = horizontal(loaded, traces[method])
        after[len(aids)] = float(np.sqrt(np.mean(err[t_ref >= t_end] ** 2)))
        if len(aids) == 3:
            flags = _flags(loaded, traces[method])
            back = _readmitted_after(loaded.recording.times, flags, t_end)
            assert back <= GuardSettings().patience_s + 1.0, back
    assert after[3] <= 1.25 * after[1], after


@pytest.fixture(scope="module")
def every_aid(drive):
    """The whole fault-free drive, scored at the antenna (at the IMU the lever arm's 5 cm
    made every method's error alike: 0.056 m ``ckf``, 0.067 m the GLR)."""
    return process(drive, methods=["ckf", *TESTED])


@pytest.mark.slow
def test_every_aid_without_a_fault_the_chi_square_method_is_the_plain_filter(every_aid):
    """The whole fault-free drive, every aid: the χ² method isolates nothing that costs
    (0.027 m as ``ckf``)."""
    _, _, scores = every_aid
    ckf = scores["ckf"].horizontal_rms_m
    assert scores["fkf-chi2"].horizontal_rms_m <= 1.05 * ckf


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason=(
        "the GLR holds the receiver's velocities in turns (the MEMS INS's innovation mean "
        "shifts): 0.045 m against 0.027 m, 1.7 x (docs/integrity.md §1.7, §5)"
    ),
)
def test_every_aid_without_a_fault_the_glr_method_stays_with_the_plain_filter(every_aid):
    """The whole fault-free drive, every aid: the GLR method within 1.5 × ``ckf``'s
    horizontal RMS.  Was 2.0 × before a flag of a consistent half beside its held device
    mate stopped starting a hold (§1.7); the holds of the velocities themselves remain."""
    _, _, scores = every_aid
    ckf = scores["ckf"].horizontal_rms_m
    assert scores["fkf-glr"].horizontal_rms_m <= 1.5 * ckf
