"""Plug-in aids of recordings (``ftnav.recorded.aids``): each type's own settings model
validates its keys at the boundary, once; the schema documents them.

Oracle: the registry itself — every key a plug-in's settings model declares is accepted for
that type and refused for the others with the owner named; a key nobody declares is
refused with the known ones listed; ``ftnav schema --recording`` carries each plug-in's
settings.  The drive with its NHC and ZUPT tables parsed by the plug-ins gives the same
stationary epochs as its settings say (a closed count from the IMU log).
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from recording_runs import drive_copy

from ftnav.io.common import ScenarioError
from ftnav.io.recording_file import AID_TYPES, load_recording, recording_json_schema
from ftnav.recorded.aids import RECORDING_AIDS


def _aid_edit(kind: str, **keys):
    def edit(doc: dict) -> None:
        doc["filter"] = {**doc.get("filter", {}), "duration_s": 60.0}
        for a in doc["aids"]:
            if a["type"] == kind:
                a.update(keys)

    return edit


def _error(path: Path) -> str:
    with pytest.raises(ScenarioError) as exc:
        load_recording(path, warn=False)
    text = str(exc.value)
    assert "\n" not in text, text
    return text


def test_every_plugin_is_an_aid_type_and_in_the_schema():
    assert set(AID_TYPES) == {"gnss", *RECORDING_AIDS}
    defs = recording_json_schema()["$defs"]
    for kind, plugin in RECORDING_AIDS.items():
        props = defs[f"aid-{kind}"]["properties"]
        assert set(props) == set(plugin.settings.model_fields), kind


def test_a_key_of_another_aid_names_its_owner(tmp_path):
    err = _error(drive_copy(tmp_path / "r.toml", _aid_edit("nhc", window_s=1.0)))
    assert "aids[2].window_s" in err and "a setting of zupt, not of nhc" in err


def test_an_unknown_key_lists_the_known_ones(tmp_path):
    err = _error(drive_copy(tmp_path / "r.toml", _aid_edit("zupt", windw_s=1.0)))
    assert "aids[3].windw_s" in err and "known: sigma_m_s" in err and "window_s" in err


def test_a_gnss_key_on_a_constraint_is_refused(tmp_path):
    err = _error(drive_copy(tmp_path / "r.toml", _aid_edit("nhc", quality=[1])))
    assert "aids[2].quality" in err and "a setting of gnss, not of nhc" in err


@pytest.mark.parametrize(("key", "value"), [("sigma_m_s", -0.1), ("gate_probability", 1.0)])
def test_a_value_out_of_range_names_the_key(tmp_path, key, value):
    err = _error(drive_copy(tmp_path / "r.toml", _aid_edit("zupt", **{key: value})))
    assert f"aids[3].{key}" in err


def test_zupt_fires_only_where_the_receiver_is_still(tmp_path):
    """Independent of the IMU statistics the plug-in reads: at every epoch where ZUPT
    fires, the RTK velocity says the car stands (below 0.3 m/s; the car creeps off)."""
    from ftnav.io.recording_readers import read_rtklib_pos

    path = drive_copy(tmp_path / "r.toml", lambda d: d.update(filter={"duration_s": 200.0}))
    loaded = load_recording(path, warn=False)
    rec = loaded.recording
    z = rec.sensor_names.index("zupt")
    aid = loaded.stream.aids[z]
    fired = rec.t_start + rec.times[aid.available[0]]
    assert loaded.counts["zupt"]["stationary_epochs"] == fired.size > 10
    src = tomllib_doc(path)["aids"][0]["file"]
    fix = read_rtklib_pos(Path(src))
    speed = np.linalg.norm(fix.v_neu, axis=1)
    at = np.searchsorted(fix.t, fired).clip(0, fix.t.size - 1)
    assert np.all(np.abs(fix.t[at] - fired) < 0.2)
    assert speed[at].max() < 0.3


def tomllib_doc(path: Path) -> dict:
    return tomllib.loads(path.read_text())
