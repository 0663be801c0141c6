"""Bad integrated scenario files: one-line ScenarioError naming the field; CLI exit 2.

Each case edits one line of a valid small file (seed002 flight, GNSS and TAN).
"""

from __future__ import annotations

import subprocess
import sys
import tomllib

import pytest

from ftnav.cli import main
from ftnav.io.common import ScenarioError
from ftnav.io.ins_scenario_file import parse_ins_scenario
from ftnav.io.scenario_file import load_scenario

GOOD = """
kind = "integrated"
name = "small"
profile = "seed002"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 120.0

[terrain]
kind = "analytic"

[[aids]]
type = "gnss"
pos_white_sigma_m = 1.4

[[aids]]
type = "tan"

[[faults]]
sensor = "gnss"
kind = "bias"
start = 60.0
end = 90.0
magnitude = [30.0, 30.0, 0.0, 0.0, 0.0, 0.0]

[[methods]]
name = "ckf"
architecture = "centralized"
"""

#: (id, old line, new line, field path the message must name)
BAD = [
    (
        "unknown aid parameter",
        "pos_white_sigma_m = 1.4",
        "pos_white_sigma_m = 1.4\nbogus_m = 3.0",
        "aids[0].bogus_m",
    ),
    (
        "negative sigma",
        "pos_white_sigma_m = 1.4",
        "pos_white_sigma_m = -1.4",
        "aids[0].pos_white_sigma_m",
    ),
    ("fault on unknown sensor", 'sensor = "gnss"', 'sensor = "radar"', "faults[0].sensor"),
    (
        "bias of the wrong length",
        "magnitude = [30.0, 30.0, 0.0, 0.0, 0.0, 0.0]",
        "magnitude = [30.0, 30.0]",
        "faults[0].magnitude",
    ),
    ("gyro-bias on an aid", 'kind = "bias"', 'kind = "gyro-bias"', "faults[0].kind"),
    ("dt not a whole number of IMU periods", "dt = 1.0", "dt = 0.015", "filter.dt"),
    ("dt an odd number of IMU periods", "dt = 1.0", "dt = 0.01", "filter.dt"),
    (
        "duration longer than the profile",
        "duration_s = 120.0",
        "duration_s = 5000.0",
        "filter.duration_s",
    ),
    ("grid terrain without path", 'kind = "analytic"', 'kind = "grid"', "terrain.path"),
    ("unknown profile", 'profile = "seed002"', 'profile = "seed999"', "profile"),
    (
        "unknown GNSS Markov handling",
        "pos_white_sigma_m = 1.4",
        'pos_white_sigma_m = 1.4\nmarkov = "ignore"',
        "aids[0].markov",
    ),
    (
        "differencing an aid that skips epochs",
        "pos_white_sigma_m = 1.4",
        'pos_white_sigma_m = 1.4\nmarkov = "difference"\nevery = 2',
        "aids[0].every",
    ),
    (
        "intersection prior outside the neuron centre",
        'architecture = "centralized"',
        'architecture = "centralized"\n'
        'detector = { kind = "residual-chi2", prior = "intersection" }',
        "methods[0].detector.prior",
    ),
    (
        "quorum without the common-mode rule",
        'architecture = "centralized"',
        'architecture = "federated"\ncommon_mode_quorum = 2',
        "methods[0].common_mode_quorum",
    ),
    ("TAN aid without a terrain", '[terrain]\nkind = "analytic"', "", "terrain"),
    (
        "fault after the end of the flight",
        "start = 60.0\nend = 90.0",
        "start = 500.0\nend = 600.0",
        "faults[0].start",
    ),
    ("unknown IMU preset", 'imu = "seed001"', 'imu = "navigation-grade"', "imu"),
    (
        "datasheet key of the wrong unit family",
        'imu = "seed001"',
        '[imu]\ngyro_arw = "0.1 deg/h"',
        "imu.gyro_arw",
    ),
    (
        "unknown datasheet key",
        'imu = "seed001"',
        '[imu]\ngyro_drift = "0.1 deg/h"',
        "imu.gyro_drift",
    ),
    ("unknown datasheet base", 'imu = "seed001"', '[imu]\nbase = "strategic"', "imu.base"),
    (
        "assumed IMU of the wrong unit family",
        "duration_s = 120.0",
        'duration_s = 120.0\n[filter.imu]\naccel_bias_sd = "1 deg/h"',
        "filter.imu.accel_bias_sd",
    ),
]


def _bad(old: str, new: str) -> str:
    assert GOOD.count(old) == 1, old
    return GOOD.replace(old, new)


def test_the_good_file_is_valid():
    sc = parse_ins_scenario(tomllib.loads(GOOD))
    assert sc.sensor_names == ("gnss", "tan") and sc.steps == 120


@pytest.mark.parametrize(("old", "new", "field"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_file_raises_one_line_scenario_error_naming_the_field(tmp_path, old, new, field):
    path = tmp_path / "bad.toml"
    path.write_text(_bad(old, new))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    err = info.value
    assert err.path == field
    assert "\n" not in str(err) and str(err).startswith(f"{field}: ")


@pytest.mark.parametrize(("old", "new", "field"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_cli_exits_2_with_one_line_on_stderr(tmp_path, capsys, old, new, field):
    path = tmp_path / "bad.toml"
    path.write_text(_bad(old, new))
    code = main(["run", str(path), "--runs", "2", "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert field in err, err
    assert not (tmp_path / "out" / "metrics.json").exists()


def test_console_script_reports_a_bad_file_without_traceback(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(_bad("pos_white_sigma_m = 1.4", "pos_white_sigma_m = -1.4"))
    proc = subprocess.run(
        [sys.executable, "-m", "ftnav.cli", "run", str(path), "--quiet"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and proc.stderr.count("\n") == 1
    assert "aids[0].pos_white_sigma_m" in proc.stderr


def test_imu_datasheet_table_and_base_preset_give_the_documented_errors():
    from ftnav.model.imu import imu_preset
    from ftnav.nav.units import deg_per_h, milli_g

    text = GOOD.replace(
        'imu = "seed001"',
        '[imu]\nbase = "tactical"\ngyro_bias_sd = "0.5 deg/h"\n'
        'accel_bias_sd = ["1 mg", "1 mg", "2 mg"]',
    )
    sc = parse_ins_scenario(tomllib.loads(text))
    tactical = imu_preset("tactical")
    assert sc.imu.gyro_bias_sd == pytest.approx([deg_per_h(0.5)] * 3)
    assert sc.imu.accel_bias_sd == pytest.approx([milli_g(1.0), milli_g(1.0), milli_g(2.0)])
    assert sc.imu.gyro_arw == pytest.approx(tactical.gyro_arw)  # from the base
    plain = parse_ins_scenario(
        tomllib.loads(GOOD.replace('imu = "seed001"', '[imu]\ngyro_arw = "0.1 deg/sqrt(h)"'))
    )
    assert plain.imu.gyro_bias_sd == pytest.approx([0.0] * 3)  # no base: zero elsewhere


def test_filter_imu_sets_what_the_filters_assume_and_not_the_truth():
    text = GOOD.replace(
        "duration_s = 120.0",
        'duration_s = 120.0\n[filter.imu]\nbase = "seed001"\ngyro_bias_sd = "1 deg/h"',
    )
    sc = parse_ins_scenario(tomllib.loads(text))
    truth = parse_ins_scenario(tomllib.loads(GOOD))
    assert sc.imu == truth.imu  # the simulator's IMU is unchanged
    assert sc.initial_sigma[9] == pytest.approx(10 * truth.initial_sigma[9])  # 1 vs 0.1 deg/h


def test_a_second_flight_figure_needs_a_test_profile():
    """``flight = "second"`` draws the run on the test profile; without one, one line."""
    import tomllib as _toml

    from ftnav.io.common import ScenarioError
    from ftnav.io.ins_scenario_file import parse_ins_scenario
    from ftnav.scenarios import builtin_path

    doc = _toml.loads(builtin_path("seed001").read_text())
    doc["profile"] = str(builtin_path("seed001").parent / "profiles" / "seed001.toml")
    doc.pop("test_profile")
    for m in doc["methods"]:
        m.pop("model", None)
    doc["methods"] = [m for m in doc["methods"] if m["architecture"] != "neural"]
    doc["figures"] = [{"name": "f", "methods": ["ckf"], "states": ["pos_E_m"], "flight": "second"}]
    with pytest.raises(ScenarioError, match=r"figures\[0\]\.flight: the scenario has no second"):
        parse_ins_scenario(doc)
