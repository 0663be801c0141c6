"""``states = 15`` runs every integrated built-in end to end (it crashed all of them, issue 13).

Each built-in is copied with ``[filter] states = 15`` and a 150 s flight; every method runs
through ``ftnav run`` (exit 0, finite metrics).  The shipped neuron model was trained for
the 18-state filters, so a 15-state copy that keeps the neuron method is refused with one
line naming its model (exit 2), not a crash.
"""

from __future__ import annotations

import json
import math
import re
import tomllib

import pytest
import tomli_w

from ftnav.cli import main
from ftnav.scenarios import builtin_path


def _copy(name: str, tmp_path, keep_neural: bool):
    data = tomllib.loads(builtin_path(name).read_text())
    base = builtin_path(name).parent
    data["filter"].update(states=15, duration_s=150.0)
    data["profile"] = str(base / "profiles" / f"{data['profile']}.toml")
    data.pop("test_profile", None)
    data.pop("figures", None)
    data["faults"] = [f for f in data["faults"] if f["start"] < 150.0]
    if not keep_neural:
        data["methods"] = [m for m in data["methods"] if m["architecture"] != "neural"]
    for m in data["methods"]:
        if "model" in m:
            m["model"] = str(base / m["model"])
    path = tmp_path / f"{name}-15.toml"
    path.write_text(tomli_w.dumps(data))
    return path, [m["name"] for m in data["methods"]]


@pytest.mark.parametrize("name", ["seed001", "seed002"])
def test_every_method_of_a_15_state_copy_runs(name, tmp_path, capsys):
    path, methods = _copy(name, tmp_path, keep_neural=False)
    out = tmp_path / "out"
    assert (
        main(["run", str(path), "--runs", "2", "--no-figures", "--quiet", "--out", str(out)]) == 0
    )
    capsys.readouterr()
    doc = json.loads((out / "metrics.json").read_text())
    assert list(doc["methods"]) == methods
    for m in doc["methods"].values():
        assert all(math.isfinite(v) for v in m["rmse"].values())
        assert math.isfinite(m["anees"])


def test_the_18_state_neuron_model_is_refused_by_a_15_state_copy(tmp_path, capsys):
    path, _ = _copy("seed001", tmp_path, keep_neural=True)
    code = main(
        ["run", str(path), "--runs", "1", "--no-figures", "--quiet", "--out", str(tmp_path / "out")]
    )
    lines = capsys.readouterr().err.splitlines()
    errors = [ln for ln in lines if ln.startswith("ftnav: error: ")]
    assert code == 2 and len(errors) == 1 and errors == lines[-1:]
    assert all(ln.startswith("ftnav: warning: ") for ln in lines[:-1])  # the 15-state note
    pattern = r"ftnav: error: \S+\.toml:\d+: methods\[\d+\]\.model: was trained for states = "
    assert re.match(pattern, errors[0])
    assert not (tmp_path / "out").exists()
