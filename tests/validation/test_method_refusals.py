"""Methods: a setting the chosen architecture, mode, detector or noise model does not read
is refused in one line naming it; an unknown key names itself with the closest valid key
(docs/scenario-format.md, "Methods").

Oracle: the configuration models themselves.  Every field that one architecture (mode,
detector kind, noise kind) declares and another does not is tried on the other, so a
setting added later is covered without editing this file.
"""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any, get_args

import pytest

from ftnav.fusion.config import MethodBase
from ftnav.fusion.federated import MODE_SETTINGS
from ftnav.fusion.registry import ARCHITECTURES
from ftnav.io.common import ScenarioError
from ftnav.io.scenario_file import parse_scenario

COMMON = {"name", "architecture", "detector", "noise", "correction", "guard"}


def _scenario(**method: Any) -> dict[str, Any]:
    return {
        "name": "refusals",
        "dt": 1.0,
        "steps": 10,
        "model": {
            "states": ["s", "v"],
            "F": [[1.0, 1.0], [0.0, 1.0]],
            "Q": [[0.1, 0.0], [0.0, 0.1]],
            "x0": [0.0, 0.0],
            "P0": [[10.0, 0.0], [0.0, 10.0]],
        },
        "sensors": [
            {"name": "a", "H": [[1.0, 0.0]], "R": [[1.0]]},
            {"name": "b", "H": [[1.0, 0.0]], "R": [[2.0]]},
        ],
        "methods": [{"name": "ckf", "architecture": "centralized"}, {"name": "m", **method}],
    }


def _refused(**method: Any) -> str:
    with pytest.raises(ScenarioError) as e:
        parse_scenario(_scenario(**method))
    text = str(e.value)
    assert "\n" not in text
    return text


def _fields(name: str) -> set[str]:
    return set(ARCHITECTURES[name].config.model_fields) - COMMON


def _value(key: str, arch: str | None = None) -> Any:
    """A valid value of ``key`` in ``arch`` (default: the first architecture declaring it)."""
    for name, entry in ARCHITECTURES.items():
        field = entry.config.model_fields.get(key)
        if arch is not None and name != arch:
            continue
        if field is not None:
            if field.default is not None and not callable(field.default):
                return list(field.default) if isinstance(field.default, tuple) else field.default
            return "x.npz"  # the model path of the neural architecture
    raise AssertionError(key)


FOREIGN = sorted(
    (arch, key)
    for arch in ARCHITECTURES
    for other in ARCHITECTURES
    for key in _fields(other) - _fields(arch)
)


def test_every_architecture_has_settings_of_its_own():
    assert len(FOREIGN) >= 10  # the premise of the next test: there is something to refuse


@pytest.mark.parametrize(("arch", "key"), FOREIGN)
def test_a_setting_of_another_architecture_is_refused(arch, key):
    msg = _refused(architecture=arch, **{key: _value(key)})
    assert msg.startswith(f"methods[1].{key}: not a setting of the {arch} architecture")


@pytest.mark.parametrize(
    ("settings", "expected"),
    [  # the cases of issue 14, exactly
        ({"sharing": "trace"}, "methods[1].sharing: not a setting of the distributed architecture"),
        ({"master_share": 0.5}, "methods[1].master_share: not a setting of the distributed"),
        ({"reset_interval": 3}, "methods[1].reset_interval: not a setting of the distributed"),
        ({"common_mode": "keep"}, "methods[1].common_mode: not a setting of the distributed"),
    ],
)
def test_distributed_refuses_the_federated_settings(settings, expected):
    assert _refused(architecture="distributed", **settings).startswith(expected)


def test_centralized_refuses_a_mode():
    msg = _refused(architecture="centralized", mode="zero-reset")
    assert msg.startswith("methods[1].mode: not a setting of the centralized architecture")


MODE_FOREIGN = sorted(
    (mode, key)
    for mode, keys in MODE_SETTINGS.items()
    for key in set().union(*MODE_SETTINGS.values()) - set(keys)
)


@pytest.mark.parametrize(("mode", "key"), MODE_FOREIGN)
def test_a_setting_another_federated_mode_reads_is_refused(mode, key):
    assert MODE_FOREIGN  # no-reset has no reset interval, zero-reset no sharing rule
    msg = _refused(architecture="federated", mode=mode, **{key: _value(key, "federated")})
    assert msg.startswith(f"methods[1].{key}: not a setting of the {mode} mode")


@pytest.mark.parametrize("key", ["reconstructed", "rescale_factor"])
def test_the_rescale_settings_need_the_rescale_mode(key):
    msg = _refused(architecture="distributed", **{key: _value(key, "distributed")})
    assert msg.startswith(f"methods[1].{key}: only read with mode = 'rescale'")


def _members(table: str) -> list[Any]:
    annotation = MethodBase.model_fields[table].annotation
    while get_args(annotation) and not any(isinstance(a, type) for a in get_args(annotation)):
        annotation = get_args(annotation)[0]
    return [m for m in get_args(annotation) if isinstance(m, type)]


def _kind(model: Any) -> str:
    return get_args(model.model_fields["kind"].annotation)[0]


NESTED = sorted(
    (table, _kind(m), key)
    for table in ("detector", "noise")
    for m in _members(table)
    for other in _members(table)
    for key in set(other.model_fields) - set(m.model_fields)
)


@pytest.mark.parametrize(("table", "kind", "key"), NESTED)
def test_a_setting_of_another_detector_or_noise_kind_is_refused(table, kind, key):
    assert len(NESTED) >= 5
    msg = _refused(architecture="federated", **{table: {"kind": kind, key: 1}})
    assert msg.startswith(f"methods[1].{table}.{key}: not a setting of the {kind!r} {table}")


@pytest.mark.parametrize(
    ("key", "table"),
    [("false_alarm_probability", "detector"), ("rho", "noise"), ("iterations", "noise")],
)
def test_a_flat_detector_or_noise_key_says_where_it_belongs(key, table):
    msg = _refused(architecture="federated", **{key: 1})
    assert msg.startswith(f"methods[1].{key}: a setting of the {table}: write {table} = {{kind")


def test_an_unknown_key_names_itself_and_the_closest_key():
    assert _refused(architecture="federated", sharnig="trace").startswith(
        "methods[1].sharnig: unknown key (did you mean 'sharing'?)"
    )
    assert _refused(noise={"kind": "vb", "rhoo": 0.9}).startswith(
        "methods[1].noise.rhoo: unknown key (did you mean 'rho'?)"
    )
    data = _scenario(architecture="federated")
    data["stpes"] = data.pop("steps")
    with pytest.raises(ScenarioError) as e:
        parse_scenario(data)
    assert str(e.value).startswith("stpes: unknown key (did you mean 'steps'?)")


def test_an_unknown_architecture_or_kind_suggests_the_closest():
    assert _refused(architecture="centralised").startswith(
        "methods[1].architecture: unknown value 'centralised' (did you mean 'centralized'?"
    )
    assert _refused(noise={"kind": "vbb"}).startswith(
        "methods[1].noise.kind: unknown value 'vbb' (did you mean 'vb'?"
    )


def test_a_valid_method_of_each_architecture_is_accepted():
    """The refusals are not blanket: each architecture with its own settings parses."""
    for arch in ("centralized", "federated", "distributed"):
        settings = {k: _value(k, arch) for k in _fields(arch) if k not in ("betas",)}
        if arch == "distributed":  # the reconstruction's settings: with mode = "rescale"
            settings.update(mode="rescale", reconstructed=True)
        if arch == "federated":
            settings = {k: v for k, v in settings.items() if k in MODE_SETTINGS["fusion-reset"]}
            settings.pop("trace_mode", None)
            settings.pop("common_mode_quorum", None)
        sc = parse_scenario(_scenario(architecture=arch, **settings))
        assert sc.methods[1].architecture == arch


def test_the_cli_exits_2_with_the_line(tmp_path):
    import tomli_w

    path = tmp_path / "s.toml"
    path.write_text(tomli_w.dumps(_scenario(architecture="distributed", sharing="trace")))
    out = tmp_path / "out"
    r = subprocess.run(
        [sys.executable, "-m", "ftnav.cli", "run", str(path), "--runs", "1", "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    # the line of the method's inline table (tomli_w writes the methods one a line)
    line = 1 + next(i for i, ln in enumerate(path.read_text().splitlines()) if '"trace"' in ln)
    assert r.stderr.strip().splitlines() == [
        f"ftnav: error: {path}:{line}: methods[1].sharing: not a setting "
        "of the distributed architecture "
        "(a setting of federated)"
    ]
    assert not out.exists()


def test_the_schema_shows_the_union_of_architectures():
    r = subprocess.run(
        [sys.executable, "-m", "ftnav.cli", "schema"], capture_output=True, text=True, check=True
    )
    schema = json.loads(r.stdout)
    text = json.dumps(schema)
    for name in ("CentralizedConfig", "FederatedConfig", "DistributedConfig", "NeuralConfig"):
        assert name in schema["$defs"]
    assert '"discriminator"' in text or '"oneOf"' in text
