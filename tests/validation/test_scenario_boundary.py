"""Plausibility at the boundary: implausible numbers and unusable names in scenario files.

Each bad input is a one-line ScenarioError naming the field (``ftnav run`` exits 2),
never a run that ends in an internal error or writes nulls; a legal but unusual IMU
value is a warning.  The bounds are in ``docs/scenario-format.md`` ("What is checked").
"""

from __future__ import annotations

import copy
import re
import tomllib
import warnings
from pathlib import Path
from typing import Any

import pytest

from ftnav.cli import main
from ftnav.io.common import MAX_TOML_DEPTH, ScenarioError, field_line, read_toml
from ftnav.io.ins_scenario_file import ScenarioWarning, parse_ins_scenario
from ftnav.io.scenario_file import load_scenario, parse_scenario
from ftnav.scenarios import builtin_names, builtin_path

LINEAR: dict[str, Any] = {
    "name": "small",
    "dt": 1.0,
    "steps": 40,
    "model": {
        "states": ["s", "v"],
        "F": [[1.0, 1.0], [0.0, 1.0]],
        "Q": [[0.1, 0.0], [0.0, 0.1]],
        "x0": [0.0, 0.0],
        "P0": [[10.0, 0.0], [0.0, 10.0]],
    },
    "sensors": [
        {"name": "p1", "H": [[1.0, 0.0]], "R": [[4.0]]},
        {"name": "p2", "H": [[1.0, 0.0]], "R": [[4.0]]},
    ],
    "faults": [{"sensor": "p1", "kind": "bias", "start": 10.0, "end": 20.0, "magnitude": [5.0]}],
    "methods": [{"name": "ckf", "architecture": "centralized"}],
}

INTEGRATED = """
kind = "integrated"
name = "small"
profile = "seed002"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 60.0

[[aids]]
type = "gnss"
pos_markov_sigma_m = 0.0
vel_markov_sigma_m_s = 0.0
pos_white_sigma_m = 1.4

[[aids]]
type = "ads"

[[faults]]
sensor = "gnss"
kind = "bias"
start = 10.0
end = 20.0
magnitude = [30.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _linear(path: str, value: Any) -> dict[str, Any]:
    data = copy.deepcopy(LINEAR)
    *head, last = path.split(".")
    node: Any = data
    for key in head:
        node = node[int(key)] if key.isdigit() else node[key]
    node[int(last) if last.isdigit() else last] = value
    return data


def _refused_linear(path: str, value: Any) -> str:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(_linear(path, value))
    assert "\n" not in str(info.value)
    return str(info.value)


def _refused_integrated(old: str, new: str) -> str:
    assert old in INTEGRATED
    with pytest.raises(ScenarioError) as info:
        parse_ins_scenario(tomllib.loads(INTEGRATED.replace(old, new, 1)))
    assert "\n" not in str(info.value)
    return str(info.value)


def test_the_small_scenarios_are_valid():
    assert [m.name for m in parse_scenario(LINEAR).methods] == ["ckf"]
    assert [m.name for m in parse_ins_scenario(tomllib.loads(INTEGRATED)).methods] == ["ckf"]


# ------------------------------------------------------------------ case 1: fault sizes


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("faults.0.magnitude", [1e300], r"^faults\[0\]\.magnitude: implausibly large offset"),
        ("faults.0.magnitude", [-1e11], r"^faults\[0\]\.magnitude: implausibly large offset"),
    ],
)
def test_linear_fault_offsets_are_bounded(path, value, message):
    assert pytest.raises(ScenarioError, parse_scenario, _linear(path, value)).match(message)


def test_initial_means_are_bounded():
    err = _refused_linear("model.x0", [1e300, 0.0])
    assert err.startswith("model.x0: implausibly large value 1e+300"), err


def test_linear_noise_factor_is_bounded():
    fault = {"sensor": "p1", "kind": "noise-scale", "start": 1.0, "end": 2.0, "magnitude": [1e7]}
    err = _refused_linear("faults.0", fault)
    assert err.startswith("faults[0].magnitude: noise-scale factors must be at most")


@pytest.mark.parametrize(
    ("new", "field"),
    [
        ("magnitude = [1e300, 0.0, 0.0, 0.0, 0.0, 0.0]", "faults[0].magnitude[0]"),
        ("magnitude = [0.0, 0.0, 0.0, 0.0, 2e4, 0.0]", "faults[0].magnitude[4]"),
    ],
)
def test_integrated_fault_offsets_are_bounded(new, field):
    err = _refused_integrated("magnitude = [30.0, 0.0, 0.0, 0.0, 0.0, 0.0]", new)
    assert err.startswith(f"{field}: implausibly large offset"), err


def test_gyro_bias_step_is_bounded():
    err = _refused_integrated(
        'sensor = "gnss"\nkind = "bias"\nstart = 10.0\nend = 20.0\n'
        "magnitude = [30.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
        'sensor = "sins"\nkind = "gyro-bias"\nstart = 10.0\nend = 20.0\n'
        "magnitude_deg_h = [1e300, 0.0, 0.0]",
    )
    assert err.startswith("faults[0].magnitude_deg_h: implausibly large"), err


# ------------------------------------------------------------------- case 2: names

BAD_NAMES = ["a/b", "a\\b", "a\x00b", "tab\there", "new\nline", ".hidden", "..", "...", "x" * 101]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_method_names_must_be_file_names(name):
    err = _refused_linear("methods.0.name", name)
    assert err.startswith("methods[0].name: must be usable as a file name"), err


@pytest.mark.parametrize("name", BAD_NAMES)
def test_integrated_method_and_aid_names_must_be_file_names(name):
    quoted = tomllib.loads(f"x = {_toml_string(name)}")["x"]
    assert quoted == name
    err = _refused_integrated('name = "ckf"', f"name = {_toml_string(name)}")
    assert err.startswith("methods[0].name: must be usable as a file name"), err
    err = _refused_integrated('type = "ads"', f'type = "ads"\nname = {_toml_string(name)}')
    assert err.startswith("aids[1].name: must be usable as a file name"), err


@pytest.mark.parametrize("name", ["a/b", "../elsewhere", ".."])
def test_scenario_names_must_be_file_names(name):
    """The default output folder is ``results/<name>``: it must not leave ``results``."""
    err = _refused_linear("name", name)
    assert err.startswith("name: must be usable as a file name"), err


def _toml_string(text: str) -> str:
    return (
        '"'
        + "".join(c if c.isprintable() and c not in '"\\' else f"\\u{ord(c):04x}" for c in text)
        + '"'
    )


def test_duplicate_names_name_the_field():
    methods = [{"name": "ckf", "architecture": "centralized"}] * 2
    assert _refused_linear("methods", methods).startswith("methods[1].name: duplicate")
    sensors = [LINEAR["sensors"][0], LINEAR["sensors"][0]]
    assert _refused_linear("sensors", sensors).startswith("sensors[1].name: duplicate")
    err = _refused_integrated('type = "ads"', 'type = "ads"\nname = "gnss"')
    assert err.startswith("aids[1].name: duplicate"), err


# ----------------------------------------------------- case 3: noise matrices


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        (
            "model.Q",
            [[1e300, 0.0], [0.0, 1e300]],
            r"^model\.Q: variance \[0\]\[0\] = 1e\+300 is implausibly large",
        ),
        (
            "sensors.0.R",
            [[1e-300]],
            r"^sensors\[0\]\.R: variance \[0\]\[0\] = 1e-300 is implausibly small",
        ),
        ("sensors.1.R", [[1e21]], r"^sensors\[1\]\.R: variance .* implausibly large"),
        ("model.P0", [[1e10, 0.0], [0.0, 1e-5]], r"^model\.P0: ill-conditioned"),
        (
            "model.Q_true",
            [[0.0, 0.0], [0.0, 1e-25]],
            r"^model\.Q_true: variance \[1\]\[1\] .* small",
        ),
    ],
)
def test_noise_matrices_are_bounded(path, value, message):
    assert pytest.raises(ScenarioError, parse_scenario, _linear(path, value)).match(message)


def test_a_zero_variance_where_semi_definite_is_allowed():
    sc = parse_scenario(_linear("model.Q_true", [[0.0, 0.0], [0.0, 0.1]]))
    assert sc.model.Q_true.tolist() == [[0.0, 0.0], [0.0, 0.1]]


# -------------------------------------------------------------- case 4: deep TOML


@pytest.mark.parametrize(
    "text",
    [
        "x = " + "[" * 5000 + "]" * 5000,
        "x = " + "[" * (MAX_TOML_DEPTH + 1) + "]" * (MAX_TOML_DEPTH + 1),
        "x = " + "{a = " * 600 + "1" + "}" * 600,
        ".".join(["a"] * 5000) + " = 1",
    ],
    ids=["5000-arrays", "33-arrays", "600-inline-tables", "5000-dotted-keys"],
)
def test_deeply_nested_toml_is_refused(tmp_path, text, capsys):
    path = tmp_path / "deep.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=rf"nested more than {MAX_TOML_DEPTH} levels"):
        read_toml(path)
    assert main(["run", str(path), "--runs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftnav: error: ") and err.count("\n") == 1, err


# -------------------------------------------------------- case 7: sensor models


def test_implausible_gyro_bias_is_refused():
    err = _refused_integrated('imu = "seed001"', 'imu = {gyro_bias_sd = "1e30 deg/s"}')
    assert err.startswith(
        "imu.gyro_bias_sd: 1.75e+28 rad/s, beyond the 1 rad/s (57 deg/s) that no navigation "
        "IMU reaches"
    ), err


@pytest.mark.parametrize(
    ("table", "field"),
    [
        ('{accel_bias = "100 g"}', "imu.accel_bias"),
        ('{gyro_arw = "1000 deg/sqrt(h)"}', "imu.gyro_arw"),
        ('{gyro_markov_sd = "0.1 deg/h", gyro_markov_tau = "1e-6 s"}', "imu.gyro_markov_tau"),
        ('{accel_scale_sd = "2e6 ppm"}', "imu.accel_scale_sd"),
    ],
)
def test_imu_values_beyond_physics_are_refused(table, field):
    err = _refused_integrated('imu = "seed001"', f"imu = {table}")
    assert re.match(rf"^{re.escape(field)}: .*, (beyond|below) the ", err), err
    err = _refused_integrated("duration_s = 60.0", f"duration_s = 60.0\nimu = {table}")
    assert err.startswith(f"filter.{field}: "), err


def test_an_unusual_imu_value_is_a_warning():
    text = INTEGRATED.replace('imu = "seed001"', 'imu = {gyro_bias_sd = "8 deg/s"}')
    with pytest.warns(ScenarioWarning, match=r"imu\.gyro_bias_sd: .* beyond any real IMU"):
        parse_ins_scenario(tomllib.loads(text))


@pytest.mark.parametrize(
    ("new", "message"),
    [
        ("pos_white_sigma_m = 1e30", r"^aids\[0\]\.pos_white_sigma_m: implausibly large"),
        ("pos_white_sigma_m = 1e-30", r"^aids\[0\]\.pos_white_sigma_m: implausibly small σ"),
        ("pos_white_sigma_m = nan", r"^aids\[0\]\.pos_white_sigma_m: must be finite"),
        ("pos_white_sigma_m = inf", r"^aids\[0\]\.pos_white_sigma_m: must be finite"),
        (
            "pos_white_sigma_m = 0.0",
            r"^aids\[0\]: the measurement noise the filters assume is not positive definite "
            r"\(σ of pos_E, pos_N, pos_U is 0\)",
        ),
        (
            "pos_white_sigma_m = 1.4\npos_markov_tau_s = 1e-9",
            r"^aids\[0\]\.pos_markov_tau_s: implausibly small",
        ),
    ],
)
def test_aid_sigmas_are_bounded(new, message):
    err = _refused_integrated("pos_white_sigma_m = 1.4", new)
    assert re.match(message, err), err


def test_an_unusual_aid_sigma_is_a_warning():
    text = INTEGRATED.replace("pos_white_sigma_m = 1.4", "pos_white_sigma_m = 2e4")
    with pytest.warns(ScenarioWarning, match=r"aids\[0\]\.pos_white_sigma_m: σ 2e\+04 m"):
        parse_ins_scenario(tomllib.loads(text))


# --------------------------------------------------- cases 8, 9: σ = 0, NaN anywhere


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        (
            "duration_s = 60.0",
            "duration_s = 60.0\n[filter.initial]\nheight_m = nan",
            "filter.initial.height_m",
        ),
        (
            "duration_s = 60.0",
            "duration_s = 60.0\n[filter.initial]\nvelocity_m_s = [0.6, nan, 0.6]",
            "filter.initial.velocity_m_s[1]",
        ),
        (
            "duration_s = 60.0",
            "duration_s = 60.0\n[filter.initial]\nattitude_arcsec = [1e9, 300.0, 600.0]",
            "filter.initial.attitude_arcsec[0]",
        ),
        ("start = 10.0", "start = nan", "faults[0].start"),
        ("end = 20.0", "end = inf", "faults[0].end"),
        (
            'architecture = "centralized"',
            'architecture = "centralized"\n[evaluation]\ngrace = nan',
            "evaluation.grace",
        ),
        ('type = "ads"', 'type = "ads"\nsigma_m = nan', "aids[1].sigma_m"),
        ('type = "ads"', 'type = "ads"\nsigma_m = 0.0', "aids[1]"),
    ],
)
def test_nan_inf_and_zero_sigma_name_the_field(old, new, field):
    err = _refused_integrated(old, new)
    assert err.startswith(f"{field}: "), err


def test_terrain_nan_is_refused():
    text = INTEGRATED.replace('type = "ads"', 'type = "tan"') + "\n[terrain]\nh0_m = nan\n"
    with pytest.raises(ScenarioError, match=r"^terrain\.h0_m: is NaN or inf"):
        parse_ins_scenario(tomllib.loads(text))


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("evaluation", {"grace": float("nan")}, r"^evaluation\.grace: is NaN or inf"),
        ("model.Q", [[0.1, 0.0], [0.0, float("nan")]], r"^model\.Q: contains NaN or inf$"),
        ("sensors.0.R", [[0.0]], r"^sensors\[0\]\.R: not positive definite$"),
    ],
)
def test_linear_nan_and_zero_sigma(path, value, message):
    assert pytest.raises(ScenarioError, parse_scenario, _linear(path, value)).match(message)


# ------------------------------------------------------------------- CLI and built-ins


def test_the_cli_refuses_with_one_line(tmp_path, capsys):
    text = INTEGRATED.replace("pos_white_sigma_m = 1.4", "pos_white_sigma_m = 0.0")
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert main(["run", str(path), "--runs", "1", "--quiet", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    # the file and the line of the aid's table
    line = 1 + text.splitlines().index("[[aids]]")
    assert err.startswith(f"ftnav: error: {path}:{line}: aids[0]: "), err
    assert err.count("\n") == 1 and not (tmp_path / "o").exists()


@pytest.mark.parametrize("name", builtin_names())
def test_every_builtin_scenario_passes_the_checks(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ScenarioWarning)  # the documented model notes
        sc = load_scenario(builtin_path(name))
    assert sc.name == name
    assert Path(builtin_path(name)).exists()


def test_a_filter_period_longer_than_the_flight_is_refused(tmp_path):
    from ftnav.scenarios import builtin_path

    text = builtin_path("seed002").read_text().replace("dt = 1.0", "dt = 1e6", 1)
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"^filter\.dt: 1e\+06 s is longer than the flight"):
        load_scenario(path)


def test_a_fault_past_the_end_is_a_warning(tmp_path):
    from ftnav.io.ins_scenario_file import ScenarioWarning
    from ftnav.scenarios import builtin_path

    text = builtin_path("seed002").read_text().replace("end = 3000.0", "end = 9000.0", 1)
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.warns(ScenarioWarning, match=r"faults\[1\]\.end: 9000 s is after the end"):
        load_scenario(path)


def test_an_integer_choice_is_named_in_the_refusal(tmp_path):
    from ftnav.scenarios import builtin_path

    text = builtin_path("seed002").read_text().replace("states = 18", "states = 7", 1)
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"expected one of: 18, 15, 21\)$"):
        load_scenario(path)


def test_scale_factor_states_need_the_body_frame():
    err = _refused_integrated("[filter]", '[filter]\nstates = 21\nbias_frame = "nav"')
    assert "filter.states" in err and "bias_frame 'body'" in err


@pytest.mark.parametrize(
    ("runs", "seed", "options", "message"),
    [
        (0, 1, {}, r"^runs: must be an integer >= 1, got 0$"),
        (2, -5, {}, r"^seed: must be an integer >= 0, got -5$"),
        (2, 1.5, {}, r"^seed: must be an integer >= 0, got 1\.5$"),
        (2, True, {}, r"^seed: must be an integer >= 0, got True$"),
        (2, 1, {"workers": 0}, r"^workers: must be an integer >= 1, got 0$"),
        (2, 1, {"workers": 1.5}, r"^workers: must be an integer >= 1, got 1\.5$"),
        (2, 1, {"first_run": -2}, r"^first_run: must be an integer >= 0, got -2$"),
        # found by a user's try: a bare AttributeError, NumPy's concatenate, int('x'),
        # 0.5 truncated to 0
        (2, 1, {"methods": "ckf"}, r"^methods: expected a list of method names or settings"),
        (2, 1, {"methods": []}, r"^methods: an empty list chooses nothing"),
        (2, 1, {"methods": ["nope"]}, r"^methods: 'nope' is not a method of the scenario"),
        (2, 1, {"methods": ["ckf", "ckf"]}, r"^methods: 'ckf' given twice$"),
        (2, 1, {"chunk": "x"}, r"^chunk: must be an integer >= 1, got 'x'$"),
        (2, 1, {"chunk": 0.5}, r"^chunk: must be an integer >= 1, got 0\.5$"),
    ],
)
def test_run_scenarios_whole_numbers_are_refused_by_name(runs, seed, options, message):
    """From Python, a negative or fractional seed or first run ended in NumPy's own message
    (``expected non-negative integer``, ``SeedSequence expects int``) naming no argument,
    and ``workers=0`` or ``1.5`` ran as if 1."""
    from ftnav.eval.montecarlo import run_scenario

    sc = load_scenario(builtin_path("seed000"))
    with pytest.raises(ValueError, match=message):
        run_scenario(sc, runs, seed, **options)


def test_run_scenario_takes_method_names_and_refuses_a_path():
    import ftnav

    sc = ftnav.load_scenario("seed000")
    r = ftnav.run_scenario(sc, 1, 1, methods=["ckf", "fkf-fr-equal"], fault_free=False)
    assert list(r.results) == ["ckf", "fkf-fr-equal"]
    with pytest.raises(ValueError, match=r"^scenario: expected a loaded scenario"):
        ftnav.run_scenario("seed000.toml", 1, 1)


def test_load_scenario_takes_a_built_in_name_and_refuses_a_non_path():
    """``load_scenario("seed000")`` said ``seed000: file not found`` (the CLI resolves the
    name, Python did not); ``load_scenario(None)`` ended in os.fspath's TypeError."""
    sc = load_scenario("seed000")
    assert sc.name == load_scenario(builtin_path("seed000")).name and sc.builtin == "seed000"
    with pytest.raises(ScenarioError, match=r"^scenario: expected a built-in scenario's name"):
        load_scenario(None)  # type: ignore[arg-type]


# ------------------------------- legal but idle or too large (found by a user's try)


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        # a window between two epochs (k·dt: 10, 11, ...)
        ("faults.0.start", 10.2, r"faults\[0\]: no measurement of p1 falls in \[10\.2, 20\)"),
        ("sensors.0.every", 500, r"sensors\[0\]\.every: p1 measures every 500 steps"),
        ("faults.0.magnitude", [5000.0], r"faults\[0\]\.magnitude: 5e\+03 is 2\.5e\+03 times"),
    ],
)
def test_a_fault_that_never_acts_or_far_beyond_the_noise_is_a_warning(path, value, message):
    """Legal, but a fault between two measurements of its sensor, or on a sensor that
    never measures, was scored as a miss without a word; a bias a thousand σ off is
    seen by any test (a unit slip, most likely)."""
    data = _linear(path, value)
    if path == "faults.0.start":
        data["faults"][0]["end"] = 10.7
        message = message.replace(r"20\)", r"10\.7\)")
    with pytest.warns(ScenarioWarning, match=message):
        parse_scenario(data)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ScenarioWarning)
        parse_scenario(copy.deepcopy(LINEAR))  # the base: none


def test_an_integrated_bias_a_thousand_sigmas_off_is_a_warning():
    """A star tracker's 2 rad for 2 deg; here a GNSS bias of 5e4 m against its σ."""
    text = INTEGRATED.replace(
        "magnitude = [30.0, 0.0, 0.0, 0.0, 0.0, 0.0]", "magnitude = [5e4, 0.0, 0.0, 0.0, 0.0, 0.0]"
    )
    with pytest.warns(ScenarioWarning, match=r"faults\[0\]\.magnitude\[0\]: 5e\+04 m is .* times"):
        parse_ins_scenario(tomllib.loads(text))


@pytest.mark.parametrize("mode", ["fusion-reset", "no-reset", "zero-reset"])
def test_a_federated_method_takes_the_correction_of_every_method(mode):
    """``correction`` is a key of every method (docs); the federated modes refused it as
    'not a setting of the fusion-reset mode' (found by a user's try)."""
    text = INTEGRATED + (
        f'\n[[methods]]\nname = "f"\narchitecture = "federated"\nmode = "{mode}"\n'
        'correction = "output"\n'
    )
    sc = parse_ins_scenario(tomllib.loads(text))
    assert sc.methods[1].correction == "output"


def test_a_flight_over_the_pole_is_refused(tmp_path, capsys):
    """It gave latitude 90.097° in truth.csv, and a scenario on it ran 33 m off with a
    1 m GNSS, exit 0 (found by a user's try): the north-east-up frame is singular at the
    poles."""
    path = tmp_path / "prof.toml"
    path.write_text(
        'name = "polar"\nimu_rate_hz = 100.0\n'
        "[start]\nlat_deg = 89.4\nlon_deg = 179.9\nh_m = 5.0\nspeed_m_s = 200.0\n"
        "heading_deg = 0.0\n[[segments]]\nduration_s = 60.0\n"
    )
    out = tmp_path / "t"
    assert main(["trajectory", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("ftnav: error: profile: segments[0] reaches latitude 89.5"), err
    assert "singular at the poles" in err and not out.exists()


def test_training_the_neuron_centre_on_a_flight_too_short_is_refused(tmp_path, capsys):
    """A 120 s flight ended in the LMS's own 'need more samples than inputs' and an
    internal error (found by a user's try): the samples start 60 s after each
    configuration's fault at 150 s."""
    path = tmp_path / "s.toml"
    path.write_text(INTEGRATED)  # 60 s
    out = tmp_path / "m.npz"
    assert main(["train-fusion", str(path), "--out", str(out), "--runs", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("ftnav: error: filter.duration_s: the flight lasts 60 s;"), err
    assert not out.exists()


FIELD_LINES = """# a scenario
name = "demo"
kind = "integrated"

[filter]
dt = 1.0

[[aids]]
type = "gnss"
name = "gnss"

[[aids]]
type = "cns"
name = "cns"
  sigma_arcsec = -1.0

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf"
sharing = "equal"
detector = { kind = "residual-chi2", false_alarm_probability = 2.0 }
"""


@pytest.mark.parametrize(
    ("field", "line"),
    [
        ("name", 2),
        ("filter.dt", 6),
        ("filter", 5),
        ("aids[1].sigma_arcsec", 15),
        ("aids[0].name", 10),
        ("methods[fkf].sharing", 23),
        ("methods[1].detector.false_alarm_probability", 24),
        ("aids[2].name", None),
        ("faults[0].end", None),
        ("filter.duration_s", None),
    ],
)
def test_the_line_that_sets_a_field_is_found_by_hand(field, line):
    assert field_line(FIELD_LINES, field) == line


INLINE_LINES = """name = "r"
sensors = [
    { name = "a", R = [[1.0]] },
    { name = "b", R = [[-2.0]] },
]
"""


@pytest.mark.parametrize(
    ("field", "line"),
    [("sensors[1].R", 4), ("sensors[b]", 4), ("sensors[a].R", 3), ("sensors", 2), ("name", 1)],
)
def test_an_array_of_inline_tables_gives_each_its_line(field, line):
    assert field_line(INLINE_LINES, field) == line


def test_a_written_matrix_row_is_no_table_header():
    text = 'name = "x"\n[[sensors]]\nname = "a"\nH = [\n    [1.0, 0.0]\n]\nR = [[-1.0]]\n'
    assert field_line(text, "sensors[0].R") == 7
    assert field_line(text, "sensors[a].H") == 4


def test_a_field_error_names_the_file_and_its_line(tmp_path, capsys):
    src = builtin_path("seed002").read_text()
    bad = src.replace("sigma_arcsec = 10.0", "sigma_arcsec = -10.0", 1)
    path = tmp_path / "mine.toml"
    path.write_text(bad)
    line = 1 + bad.splitlines().index("sigma_arcsec = -10.0")
    assert main(["run", str(path), "--runs", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ftnav: error: {path}:{line}: aids[1].sigma_arcsec: "), err
    assert err.count("\n") == 1 and not (tmp_path / "o").exists()
