"""Malformed recordings are refused: exit 2, one line naming the file and line or the
field, nothing written to ``--out``; the problems a real log has are handled and counted.

The base is the first minute of the vendored drive (static start, first metres of
motion): it processes; each case breaks one thing.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.recording_file import load_recording
from ftnav.io.solution_file import SOLUTION_COLUMNS
from ftnav.model.scenario import Fault
from ftnav.pipeline import ProcessingError, prepare_recording
from ftnav.recordings import recording_path

DATA = recording_path("rtklib-drive").parent / "data" / "rtklibexplorer" / "drive_0708"
IMU_ROWS, POS_ROWS = 5600, 300  # 56 s of IMU, 75 s of GNSS

RECORDING = """
kind = "recording"
name = "mini-drive"

[imu]
file = "imu.csv"
time = {{ columns = ["t_gpst_unix_s"], unit = "s" }}
accel = {{ columns = ["acc_x_g", "acc_y_g", "acc_z_g"], unit = "{accel_unit}" }}
gyro = {{ columns = ["gyro_x_dps", "gyro_y_dps", "gyro_z_dps"], unit = "deg/s" }}
time_offset_s = -0.125
axes = {axes}
misalignment_deg = {misalignment}

[imu.errors]
gyro_arw = "0.0038 deg/s/sqrt(Hz)"
accel_vrw = "70 ug/sqrt(Hz)"
gyro_bias_sd = "0.05 deg/s"
accel_bias_sd = "20 mg"

[[aids]]
type = "gnss"
name = "gnss"
file = "gnss.pos"
lever_arm_m = {lever_arm}

[[aids]]
type = "nhc"
lever_arm_m = {nhc_arm}

[[methods]]
name = "ckf"
architecture = "centralized"
"""

GOOD = {
    "accel_unit": "g",
    "axes": '["+y", "-x", "+z"]',
    "misalignment": "[-6.79, 0.0, -5.35]",
    "lever_arm": "[-0.05, 0.0, 0.0]",
    "nhc_arm": "[0.0, 0.0, 0.0]",
}


def _imu_lines() -> list[str]:
    return (DATA / "imu_1934_gpst.csv").read_text().splitlines()[: IMU_ROWS + 1]


def _pos_lines() -> list[str]:
    lines = (DATA / "gnss_1934_sf.pos").read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("%")]
    return head + [ln for ln in lines if not ln.startswith("%")][:POS_ROWS]


def _write(folder: Path, imu=None, pos=None, **kw) -> Path:
    (folder / "imu.csv").write_text("\n".join(_imu_lines() if imu is None else imu) + "\n")
    (folder / "gnss.pos").write_text("\n".join(_pos_lines() if pos is None else pos) + "\n")
    path = folder / "rec.toml"
    path.write_text(RECORDING.format(**{**GOOD, **kw}))
    return path


def _refused(argv, capsys) -> str:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    # a field of the recording file comes after the file and its line
    line = err.strip().removeprefix("ftnav: error: ")
    where = re.match(r"(\S+\.toml):\d+: ", line)
    assert where is None or where[1] in map(str, argv), err
    return line if where is None else line[where.end() :]


def test_the_base_processes_and_writes_the_solution_columns(tmp_path, capsys):
    path = _write(tmp_path)
    assert main(["process", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    header = (tmp_path / "o" / "solution.csv").read_text().splitlines()[0]
    assert tuple(header.split(",")) == SOLUTION_COLUMNS
    doc = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert doc["data"]["imu"]["repeated_rows_dropped"] > 0
    assert doc["methods"]["ckf"]["nan_epochs"] == 0


def test_partial_first_and_last_lines_are_dropped_and_counted(tmp_path, capsys):
    imu = _imu_lines()
    imu[1] = imu[1][:12]
    imu[-1] = imu[-1][:20]
    path = _write(tmp_path, imu=imu)
    assert main(["process", str(path), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    doc = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert doc["data"]["imu"]["partial_lines_dropped"] == 2


def _imu_with(line: int, text: str) -> list[str]:
    imu = _imu_lines()
    imu[line - 1] = text
    return imu


CASES = [
    (
        "missing-column",
        {"imu": [_imu_lines()[0].replace("acc_y_g", "acc_q_g"), *_imu_lines()[1:]]},
        r"^imu\.accel\.columns: no column 'acc_y_g' in the file",
    ),
    ("unit-family", {"accel_unit": "deg/s"}, r"^imu\.accel\.unit: unit 'deg/s' is not one of"),
    ("unit-unknown", {"accel_unit": "furlong"}, r"^imu\.accel\.unit: unit 'furlong'"),
    (
        "time-backwards",
        {"imu": _imu_with(101, "1752003200.0,0.1,0.0,1.0,0.0,0.0,0.0,0")},
        r"imu\.csv:101: column time: time goes backwards",
    ),
    (
        "not-a-number",
        {"imu": _imu_with(50, "1752003262.3,abc,0,1,0,0,0,0")},
        r"imu\.csv:50: column",
    ),
    (
        "short-row-inside",
        {"imu": _imu_with(77, "1752003262.6,0.1,0.0")},
        r"imu\.csv:77: expected 8",
    ),
    ("empty-imu", {"imu": []}, r"imu\.csv: imu\.file: empty file"),
    (
        "pos-no-header",
        {"pos": [ln for ln in _pos_lines() if not ln.startswith("%")]},
        r"gnss\.pos: aids\[0\]\.file: no '%' header line",
    ),
    ("lever-arm-length", {"lever_arm": "[0.0, 0.1]"}, r"^aids\[0\]\.lever_arm_m: expected"),
    ("nhc-arm-length", {"nhc_arm": "[0.0, -1.2]"}, r"^aids\[1\]\.lever_arm_m: "),
    ("nhc-arm-text", {"nhc_arm": '["0", "0", "0"]'}, r"^aids\[1\]\.lever_arm_m\[0\]: "),
    ("mounting-angle", {"misalignment": "[0.0, 0.0, 350.0]"}, r"^imu\.misalignment_deg: "),
    ("axes-left-handed", {"axes": '["+y", "+x", "+z"]'}, r"^imu\.axes: .* not a right-handed"),
    ("axes-unknown", {"axes": '["+y", "-x", "up"]'}, r"^imu\.axes\[2\]: "),
]


@pytest.mark.parametrize(("kw", "pattern"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_recordings_are_refused(tmp_path, capsys, kw, pattern):
    path = _write(tmp_path, **kw)
    err = _refused(["process", path, "--out", tmp_path / "o"], capsys)
    assert re.search(pattern, err), err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("argv", "pattern"),
    [
        (["--fault", "nhc:bias:1752003300:1752003310:5"], r"^--fault: 'nhc' is not a GNSS aid"),
        (["--fault", "gnss:noise-ramp:1752003300:1752003310:5"], r"^--fault: kind 'noise-ramp'"),
        (
            ["--fault", "gnss:noise-scale:1752003300:1752003310:0.5"],
            r"^--fault: a noise-scale needs a MAGNITUDE, the factor on the noise σ, in \[1, ",
        ),
        (["--fault", "gnss:noise-scale:1752003300:1752003310"], r"^--fault: a noise-scale needs"),
        (["--fault", "gnss:bias:1752003300:1752003310"], r"^--fault: a bias needs a MAGNITUDE"),
        (["--fault", "gnss:bias:1:2:5"], r"^--fault: \[1\.000, 2\.000\) s is not within"),
        (["--fault", "sins:bias:1752003300:1752003310:5"], r"^--fault: 'gyro-bias' is the only"),
        (["--fault", "gnss:gyro-bias:1752003300:1752003310:0,0,1"], r"^--fault: 'gyro-bias' is"),
        (
            ["--fault", "sins:gyro-bias:1752003300:1752003310:1800"],
            r"^--fault: a gyro-bias needs X,Y,Z, the step in deg/h about the body axes",
        ),
        (
            ["--fault", "sins:gyro-bias:1752003300:1752003310:0,0,1e7"],
            r"^--fault: gyro-bias 1e\+07 deg/h is beyond a gyro's",
        ),
        (["--fault", "sins:gyro-bias:1:2:0,0,1"], r"^--fault: \[1\.000, 2\.000\) s is not within"),
        (["--outage-length", "-3"], r"^--outage-length: must be > 0"),
        (["--methods", "ckf,nope"], r"^--methods: no method 'nope'"),
        (["--aids", "gnss,odometer"], r"^--aids: no aid 'odometer'"),
    ],
)
def test_bad_protocol_options_are_refused(tmp_path, capsys, argv, pattern):
    path = _write(tmp_path)
    err = _refused(["process", path, "--out", tmp_path / "o", *argv], capsys)
    assert re.search(pattern, err), err
    assert not (tmp_path / "o").exists()


def test_a_velocity_aids_fault_is_in_m_s_and_bounded(tmp_path, capsys):
    """The built-in drive's receiver is a position aid and a velocity aid: a bias or ramp
    of the velocity aid is m/s on its north velocity (tests/closed_form/test_recorded.py),
    its MAGNITUDE bounded in m/s with the unit named."""
    argv = ["process", "rtklib-drive", "--fault", "gnss-vel:ramp:1752003300:1752003310:5e3"]
    err = _refused([*argv, "--out", tmp_path / "o"], capsys)
    assert err.startswith("--fault: MAGNITUDE 5000 m/s is beyond ±1000 m/s"), err
    assert not (tmp_path / "o").exists()
    argv = ["process", "rtklib-drive", "--fault", "gnss-vel:bias:1752003300:1752003310"]
    err = _refused([*argv, "--out", tmp_path / "o"], capsys)
    assert err.startswith("--fault: a bias needs a MAGNITUDE in m/s"), err


def test_a_fault_of_an_aid_left_out_is_refused(tmp_path, capsys):
    """``--aids gnss`` with a fault of the velocities: the fault would change nothing, and
    the run ended in an internal error when it wrote the trace (after the whole run).
    One line at the boundary, exit 2, nothing written; the same for a Python caller's
    :class:`Fault` of an aid the recording does not have."""
    argv = ["process", "rtklib-drive", "--aids", "gnss"]
    argv += ["--fault", "gnss-vel:bias:1752003400:1752003460:1", "--out", tmp_path / "o"]
    err = _refused(argv, capsys)
    assert err == (
        "--fault: 'gnss-vel' is not an aid processed (left out by the aids chosen); "
        "the aids processed are gnss"
    ), err
    assert not (tmp_path / "o").exists()
    bogus = Fault("odometer", "bias", 1752003400.0, 1752003460.0, np.zeros(6))
    with pytest.raises(ProcessingError, match=r"^faults: 'odometer' is not an aid processed;"):
        prepare_recording("rtklib-drive", methods=["ckf"], faults=[bogus])


def test_a_method_that_adapts_an_aid_left_out_is_refused_only_when_chosen():
    """The drive's ``dkf-vb`` adapts the noise of ``gnss``.  With ``--aids gnss-vel`` the
    plain filter alone was refused for it (``methods[3].noise.sensors[0]: unknown sensor
    'gnss'``, a method not asked for); it loads now, and all the methods are refused
    naming ``--aids`` and the method."""
    loaded = load_recording(recording_path("rtklib-drive"), methods=["ckf"], aids=["gnss-vel"])
    assert loaded.recording.sensor_names == ("gnss-vel",)
    with pytest.raises(ScenarioError) as err:
        load_recording(recording_path("rtklib-drive"), aids=["gnss-vel"])
    assert str(err.value).startswith(
        "--aids: method 'dkf-vb' adapts the noise of 'gnss', which the aids chosen leave out"
    ), str(err.value)


def test_the_information_sharing_rule_is_refused_on_a_recording(tmp_path, capsys):
    """The information rule needs constant measurement matrices; a recording's are
    linearized every epoch: one line naming the method's setting."""
    path = _write(tmp_path)
    path.write_text(
        path.read_text()
        + '\n[[methods]]\nname = "fkf-info"\narchitecture = "federated"\nsharing = "information"\n'
    )
    err = _refused(["process", path, "--out", tmp_path / "o"], capsys)
    assert err.startswith("methods[1].sharing: the information rule needs constant"), err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    "detector, field",
    [
        ('{ kind = "residual-chi2", window = 8 }', "methods[1].detector.window"),
        ('{ kind = "state-chi2" }', "methods[1].detector"),
        ('{ kind = "cusum" }', "methods[1].detector"),
    ],
)
def test_detectors_that_cannot_run_on_real_noise_are_refused(tmp_path, capsys, detector, field):
    """Issue 20: on the fault-free real drive they flag 19-77 % of the epochs; a
    recording refuses them in one line naming the setting and why."""
    path = _write(tmp_path)
    path.write_text(
        path.read_text()
        + f'\n[[methods]]\nname = "x"\narchitecture = "federated"\ndetector = {detector}\n'
    )
    err = _refused(["process", path, "--out", tmp_path / "o"], capsys)
    assert err.startswith(f"{field}: "), err
    assert "cannot run on real noise" in err
    assert not (tmp_path / "o").exists()


def test_a_fault_without_a_recorded_form_is_refused_from_python(tmp_path):
    """A ``Fault`` object given to ``process_recording`` is checked as a ``--fault`` is: a
    noise ramp has no recorded form and used to be ignored silently; a gyro-bias step is
    the SINS's alone."""
    from ftnav import process_recording
    from ftnav.io.common import ScenarioError
    from ftnav.model.scenario import Fault

    fault = Fault("gnss", "noise-ramp", 1752003300.0, 1752003310.0, np.full(6, 5.0))
    with pytest.raises(ScenarioError, match=r"faults\[0\]\.kind: 'noise-ramp' has no recorded"):
        process_recording(_write(tmp_path), methods=["ckf"], faults=[fault])
    fault = Fault("gnss", "gyro-bias", 1752003300.0, 1752003310.0, np.zeros(3))
    with pytest.raises(ScenarioError, match=r"faults\[0\]\.kind: 'gyro-bias' is the only fault"):
        process_recording(_write(tmp_path), methods=["ckf"], faults=[fault])


T_IN = 1752003400.0  # inside the drive


@pytest.mark.parametrize(
    ("fault", "says"),
    [
        (Fault("gnss", "bias", T_IN, T_IN + 60, np.array([0, 5, 0.0])), "of shape (3,)"),
        (Fault("gnss", "bias", T_IN, T_IN + 60, np.full(6, np.nan)), "must be finite"),
        (Fault("gnss", "bias", T_IN + 60, T_IN, np.zeros(6)), "end must be after start"),
        (Fault("gnss", "noise-scale", T_IN, T_IN + 60, np.full(6, 0.5)), "in [1, 1e+06]"),
        (Fault("gnss", "bias", T_IN, T_IN + 60, np.full(6, 1e12)), "beyond ±100000 m"),
        (Fault("gnss", "stuck", T_IN, T_IN + 60, np.ones(6)), "takes no magnitude"),
        (Fault("sins", "gyro-bias", T_IN, T_IN + 60, np.array(0.01)), "three rates"),
    ],
)
def test_a_fault_object_is_checked_like_a_fault_given_as_text(fault, says):
    """Found by a user's try: a :class:`Fault` given to ``process_recording`` skipped the
    checks of ``--fault`` (a (3,) magnitude ended in NumPy's broadcast error, a NaN or a
    reversed window ran silently, a noise factor 0.5 did nothing, 1e12 m diverged)."""
    with pytest.raises(ProcessingError) as err:
        prepare_recording("rtklib-drive", methods=["ckf"], faults=[fault])
    assert str(err.value).startswith(f"faults: Fault({fault.sensor!r}, {fault.kind!r}, ...)")
    assert says in str(err.value), err.value


def test_a_fault_object_of_one_number_is_every_row_and_outages_are_checked():
    one = Fault("gnss", "bias", T_IN, T_IN + 60, np.array(5.0))
    p = prepare_recording("rtklib-drive", methods=(m for m in ["ckf"]), faults=[one])
    assert list(p.filters) == ["ckf"]  # a generator of names is read once, not used up
    np.testing.assert_array_equal(p.loaded.recording.faults[0].magnitude, np.full(6, 5.0))
    with pytest.raises(ProcessingError, match=r"^outages: expected \(length\[, every"):
        prepare_recording("rtklib-drive", methods=["ckf"], outages="15")  # not (1, 5)
    with pytest.raises(ProcessingError, match=r"^outages: the first outage starts -100 s"):
        prepare_recording("rtklib-drive", methods=["ckf"], outages=(15, 60, -100))


@pytest.mark.parametrize("option", ["--outage-every", "--outage-start"])
def test_an_outage_option_without_its_length_is_refused(tmp_path, capsys, option):
    """It was ignored: the run had no outage, exit 0."""
    argv = ["process", "rtklib-drive", "--methods", "ckf", option, "20", "--out", tmp_path / "o"]
    err = _refused(argv, capsys)
    assert err == f"{option}: given without --outage-length (no outage would be made)", err
    assert not (tmp_path / "o").exists()
