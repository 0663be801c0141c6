"""Model files at the boundary: a model that does not fit, a ZIP that inflates too far.

A model file whose network does not fit the scenario (outputs, features, inputs) is
refused when the scenario is read, before anything runs, in one line naming the
method's field; a member that declares more than a model may hold is refused before it
is inflated.  Nothing is ever unpickled.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import tomllib
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.lib import format as npy_format

from ftnav.cli import main
from ftnav.fdi.rbf import RBFNetwork
from ftnav.io.common import ScenarioError
from ftnav.io.learned import (
    load_neuron_model,
    load_rbf_model,
    save_neuron_model,
    save_rbf_model,
)
from ftnav.io.model_file import ModelFileError, load_model, save_model
from ftnav.io.scenario_file import parse_scenario
from ftnav.scenarios import builtin_path

MODELS = builtin_path("seed000").parent / "models"


def _seed000_with(method: dict) -> dict:
    """seed000 (its system: the models' compatibility) with one method."""
    data = tomllib.loads(builtin_path("seed000").read_text())
    data["methods"] = [method]
    data.pop("figures", None)
    return data


def _refused(method: dict, field: str) -> str:
    with pytest.raises(ScenarioError) as info:
        parse_scenario(_seed000_with(method), base=MODELS.parent)
    msg = str(info.value)
    assert msg.startswith(f"{field}: ") and "\n" not in msg, msg
    return msg


def _rbf_method(path: Path) -> dict:
    return {
        "name": "fkf-rbf",
        "architecture": "federated",
        "sharing": "inverse-trace",
        "detector": {"kind": "rbf", "model": str(path)},
    }


def test_the_builtin_models_fit():
    sc = parse_scenario(_seed000_with(_rbf_method(MODELS / "seed000-rbf.npz")), base=MODELS.parent)
    assert [n for n, _ in sc.learned] == ["fkf-rbf"]
    neural = {"name": "nn", "architecture": "neural", "model": str(MODELS / "seed000-neural.npz")}
    sc = parse_scenario(_seed000_with(neural), base=MODELS.parent)
    assert [n for n, _ in sc.learned] == ["nn"]


def test_an_rbf_detector_with_other_outputs_is_refused_at_load(tmp_path):
    model = load_rbf_model(MODELS / "seed000-rbf.npz")
    arrays = dict(model.network.to_arrays())
    arrays["weights"] = arrays["weights"][:, :2]  # two outputs for three sensors
    net = RBFNetwork.from_arrays(arrays, model.network.get_params())
    bad = dataclasses.replace(model, network=net, threshold=model.threshold[:2])
    path = save_rbf_model(bad, tmp_path / "two-outputs.npz")
    msg = _refused(_rbf_method(path), "methods[0].detector.model")
    assert "has 2 outputs (one per local filter), this scenario has 3 sensors" in msg


def test_an_rbf_detector_with_other_features_is_refused_at_load(tmp_path):
    model = load_rbf_model(MODELS / "seed000-rbf.npz")
    bad = dataclasses.replace(model, features=("innovation",))
    path = save_rbf_model(bad, tmp_path / "features.npz")
    msg = _refused(_rbf_method(path), "methods[0].detector.model")
    assert "takes 12 features, its feature kinds ['innovation'] give 3" in msg


def test_a_neuron_bank_with_other_inputs_is_refused_at_load(tmp_path):
    model = load_neuron_model(MODELS / "seed000-neural.npz")
    bad = dataclasses.replace(model, inputs=("pos2", "pos1", "pos3"))
    path = save_neuron_model(bad, tmp_path / "inputs.npz")
    method = {"name": "nn", "architecture": "neural", "model": str(path)}
    msg = _refused(method, "methods[0].model")
    assert "has the inputs ['pos2', 'pos1', 'pos3']" in msg


def test_the_cli_refuses_a_misfit_model_before_running(tmp_path, capsys):
    model = load_rbf_model(MODELS / "seed000-rbf.npz")
    path = save_rbf_model(dataclasses.replace(model, features=("innovation",)), tmp_path / "m.npz")
    scenario = tmp_path / "s.toml"
    data = _seed000_with(_rbf_method(path))
    scenario.write_text(_toml(data))
    out = tmp_path / "out"
    assert main(["run", str(scenario), "--runs", "1", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    where = re.escape(str(scenario))
    assert re.match(rf"ftnav: error: {where}:\d+: methods\[0\]\.detector\.model: ", err)
    assert err.count("\n") == 1
    assert not out.exists()


def _toml(data: dict) -> str:
    """A tiny TOML writer for the scenario dictionaries of these tests."""
    lines, tables = [], []
    for key, value in data.items():
        if isinstance(value, dict):
            tables.append((f"[{key}]", value))
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            tables.extend((f"[[{key}]]", v) for v in value)
        else:
            lines.append(f"{key} = {json.dumps(value)}")
    for header, table in tables:
        lines.append(header)
        for k, v in table.items():
            if isinstance(v, dict):
                inner = ", ".join(f"{a} = {json.dumps(b)}" for a, b in v.items())
                lines.append(f"{k} = {{{inner}}}")
            else:
                lines.append(f"{k} = {json.dumps(v)}")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------- inflation bounds


def _with_member(path: Path, name: str, entry: dict, write: Callable[[Any], None]) -> Path:
    """A valid model file with one more array member ``name``, listed as ``entry`` in a
    re-checksummed metadata (what anyone can do), its bytes written by ``write(file)``."""
    from ftnav.io.model_file import _canonical, _sha256_text

    arrays = {"a": np.zeros(3)}
    base = save_model(path.with_suffix(".base.npz"), "test", arrays, compatibility={}, settings={})
    with zipfile.ZipFile(base) as zf:
        meta = json.loads(zf.read("metadata.json"))
        members = {n: zf.read(n) for n in zf.namelist() if n != "metadata.json"}
    meta["arrays"][name] = entry
    body = {k: v for k, v in meta.items() if k != "checksum"}
    meta["checksum"] = _sha256_text(_canonical(body))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("metadata.json", json.dumps(meta))
        for n, raw in members.items():
            zf.writestr(n, raw)
        with zf.open(name + ".npy", "w", force_zip64=True) as fh:
            write(fh)
    return path


def test_a_member_that_inflates_too_far_is_refused_before_inflating(tmp_path):
    n = 80 * 2**20 // 8  # 80 MiB of zeros: a few hundred kB compressed

    def zeros(fh):
        npy_format.write_array_header_2_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (n,)}
        )
        chunk = bytes(2**20)
        for _ in range(80):
            fh.write(chunk)

    entry = {"dtype": "<f8", "shape": [n], "sha256": "0" * 64}
    bomb = _with_member(tmp_path / "bomb.npz", "big", entry, zeros)
    assert bomb.stat().st_size < 2**20
    with pytest.raises(ModelFileError, match=r"array 'big' declares \d+ bytes, more than the"):
        load_model(bomb)


def test_a_header_that_disagrees_with_the_metadata_is_refused_before_reading(tmp_path):
    def header_only(fh):
        npy_format.write_array_header_1_0(
            fh, {"descr": "<f8", "fortran_order": False, "shape": (5,)}
        )
        fh.write(bytes(8 * 5))

    entry = {"dtype": "<f8", "shape": [4], "sha256": "0" * 64}
    bad = _with_member(tmp_path / "shape.npz", "x", entry, header_only)
    with pytest.raises(ModelFileError, match=r"array 'x' has shape \[5\], the metadata says \[4\]"):
        load_model(bad)


def test_an_object_array_is_refused_never_unpickled(tmp_path):
    def objects(fh):
        npy_format.write_array_header_1_0(
            fh, {"descr": "|O", "fortran_order": False, "shape": (1,)}
        )
        fh.write(b"\x80\x04N.")  # a pickle of None

    entry = {"dtype": "|O", "shape": [1], "sha256": "0" * 64}
    bad = _with_member(tmp_path / "obj.npz", "o", entry, objects)
    with pytest.raises(ModelFileError, match=r"object arrays would need unpickling"):
        load_model(bad)


def test_a_model_file_that_is_a_fifo_is_refused(tmp_path):
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    with pytest.raises(ModelFileError, match=r"is a FIFO"):
        load_model(fifo)
