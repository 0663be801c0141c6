"""Learned-model input refused by the command line: a missing, truncated, edited, foreign
or wrong-kind model file named by a scenario method, and bad ``train-detector`` /
``train-fusion`` options; each gives one line ``ftnav: error: <field>: <reason>`` on
stderr and exit status 2, never a traceback."""

from __future__ import annotations

import contextlib
import io
import json
import re
import zipfile
from pathlib import Path

import pytest
from numpy.lib import format as npy_format
from threadpoolctl import threadpool_limits

from ftnav.cli import main

SENSOR = """
[[sensors]]
name = "{name}"
H = [[{h}, 0.0, 0.0]]
R = [[{r}]]
"""

HEAD = """
name = "{name}"
dt = 1.0
steps = 120

[model]
states = {states}
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]
"""

TAIL = """
[[faults]]
sensor = "{first}"
kind = "bias"
start = 40.0
end = 80.0
magnitude = [60.0]

[[methods]]
name = "ckf"
architecture = "centralized"
"""

FEDERATED = """
[[methods]]
name = "fkf-chi2"
architecture = "federated"
sharing = "inverse-trace"
detector = { kind = "residual-chi2", prior = "global" }
"""

RBF = """
[[methods]]
name = "fkf-rbf"
architecture = "federated"
sharing = "inverse-trace"
detector = {{ kind = "rbf", model = {model} }}
"""

NEURAL = """
[[methods]]
name = "neural"
architecture = "neural"
model = {model}
detector = {{ kind = "residual-chi2", prior = "global" }}
"""


def _scenario(
    path: Path,
    *,
    rbf=None,
    neural=None,
    sensors=("pos1", "pos2", "pos3"),
    r2=30.0,
    states=("s", "v", "a"),
) -> Path:
    """seed000's system (pos2's R and the names adjustable) with learned methods using
    the model files ``rbf`` / ``neural``."""
    text = HEAD.format(name=path.stem, states=json.dumps(list(states)))
    for name, h, r in zip(sensors, (1.0, 2.5, 0.5), (30.0, r2, 30.0), strict=True):
        text += SENSOR.format(name=name, h=h, r=r)
    text += TAIL.format(first=sensors[0])
    if rbf is None and neural is None:
        text += FEDERATED
    if rbf is not None:
        text += RBF.format(model=json.dumps(str(rbf)))
    if neural is not None:
        text += NEURAL.format(model=json.dumps(str(neural)))
    path.write_text(text)
    return path


@pytest.fixture(scope="module", autouse=True)
def _one_openmp_thread():
    # k-means (scikit-learn, OpenMP) is very slow when its threads share busy cores
    with threadpool_limits(limits=1, user_api="openmp"):
        yield


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """Tiny detector and fusion models trained once on the default system."""
    d = tmp_path_factory.mktemp("models")
    toml = _scenario(d / "base.toml")
    for argv in (
        ["train-detector", str(toml), "--out", str(d / "det.npz"), "--centres", "10"],
        ["train-fusion", str(toml), "--out", str(d / "fus.npz")],
    ):
        with (
            contextlib.redirect_stdout(io.StringIO()),
            contextlib.redirect_stderr(io.StringIO()) as err,
        ):
            code = main([*argv, "--runs", "1", "--holdout", "1", "--no-figure", "--quiet"])
        assert code == 0, err.getvalue()
    return {"det": d / "det.npz", "fus": d / "fus.npz"}


def _refused(argv, capsys, start: str) -> str:
    """Run the CLI; assert exit 2 and one ``ftnav: error: <start>...`` line; return it."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, err
    # a scenario file's field comes after the file and its line (the file given)
    m = re.match(r"ftnav: error: (?:(\S+\.toml):(\d+): )?(.*)", err)
    assert m is not None and m[3].startswith(start), err
    assert m[1] is None or m[1] in map(str, argv), err
    return err


#: the model setting of each learned method: the second method of a refused file (after ckf)
MODEL_FIELD = {"fkf-rbf": "methods[1].detector.model", "neural": "methods[1].model"}


def _run_refused(scenario, tmp_path, capsys, method: str) -> str:
    return _refused(
        ["run", scenario, "--runs", "1", "--out", tmp_path / "out", "--no-figures", "--quiet"],
        capsys,
        f"{MODEL_FIELD[method]}: ",
    )


# --- the model file itself ------------------------------------------------------------


def test_the_models_work(models, tmp_path, capsys):
    sc = _scenario(tmp_path / "ok.toml", rbf=models["det"], neural=models["fus"])
    code = main(
        ["run", str(sc), "--runs", "1", "--out", str(tmp_path / "out"), "--no-figures", "--quiet"]
    )
    assert code == 0, capsys.readouterr().err


@pytest.mark.parametrize("method", ["rbf", "neural"])
def test_missing_model_file(method, tmp_path, capsys):
    sc = _scenario(tmp_path / "missing.toml", **{method: "nosuch.npz"})
    name = {"rbf": "fkf-rbf", "neural": "neural"}[method]
    err = _run_refused(sc, tmp_path, capsys, name)
    assert "file not found" in err, err


def test_model_path_is_a_folder(tmp_path, capsys):
    (tmp_path / "det.npz").mkdir()
    sc = _scenario(tmp_path / "folder.toml", rbf="det.npz")
    err = _run_refused(sc, tmp_path, capsys, "fkf-rbf")
    assert "is a folder" in err, err


def test_truncated_model_file(models, tmp_path, capsys):
    data = models["det"].read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    sc = _scenario(tmp_path / "cut.toml", rbf="cut.npz")
    err = _run_refused(sc, tmp_path, capsys, "fkf-rbf")
    assert "truncated or not a ZIP archive" in err, err


def test_not_a_zip_file(tmp_path, capsys):
    (tmp_path / "text.npz").write_text("centres = [1, 2, 3]\n")
    sc = _scenario(tmp_path / "text.toml", neural="text.npz")
    err = _run_refused(sc, tmp_path, capsys, "neural")
    assert "truncated or not a ZIP archive" in err, err


def _members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as zf:
        return {name: zf.read(name) for name in zf.namelist()}


def _write_zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():
            zf.writestr(name, data)
    return path


def test_edited_array_with_old_metadata(models, tmp_path, capsys):
    members = _members(models["det"])
    weights = npy_format.read_array(io.BytesIO(members["weights.npy"]), allow_pickle=False)
    weights = weights.copy()
    weights[0, 0] += 1.0
    buf = io.BytesIO()
    npy_format.write_array(buf, weights, allow_pickle=False)
    members["weights.npy"] = buf.getvalue()
    _write_zip(tmp_path / "edited.npz", members)
    sc = _scenario(tmp_path / "edited.toml", rbf="edited.npz")
    err = _run_refused(sc, tmp_path, capsys, "fkf-rbf")
    assert "sha256 mismatch" in err, err
    assert "'weights'" in err


def test_edited_metadata(models, tmp_path, capsys):
    members = _members(models["fus"])
    meta = json.loads(members["metadata.json"])
    meta["compatibility"]["sensors"] = ["x", "y", "z"]  # checksum left as it was
    members["metadata.json"] = json.dumps(meta).encode()
    _write_zip(tmp_path / "edited.npz", members)
    sc = _scenario(tmp_path / "edited.toml", neural="edited.npz")
    err = _run_refused(sc, tmp_path, capsys, "neural")
    assert "checksum mismatch" in err, err


# --- a valid model used where it does not fit -----------------------------------------


@pytest.mark.parametrize("method,model", [("rbf", "det"), ("neural", "fus")])
def test_model_trained_for_another_scenario(models, method, model, tmp_path, capsys):
    # same names and sizes, pos2's R = 31 instead of 30: only the system hash differs
    sc = _scenario(tmp_path / "other.toml", r2=31.0, **{method: models[model]})
    name = {"rbf": "fkf-rbf", "neural": "neural"}[method]
    err = _run_refused(sc, tmp_path, capsys, name)
    assert "another scenario" in err, err
    assert "system hash" in err


def test_fusion_model_given_as_rbf_detector(models, tmp_path, capsys):
    sc = _scenario(tmp_path / "swap.toml", rbf=models["fus"])
    err = _run_refused(sc, tmp_path, capsys, "fkf-rbf")
    assert "is a 'neuron-fusion' model, expected 'rbf-detector'" in err, err


def test_detector_model_given_as_fusion_centre(models, tmp_path, capsys):
    sc = _scenario(tmp_path / "swap.toml", neural=models["det"])
    err = _run_refused(sc, tmp_path, capsys, "neural")
    assert "is a 'rbf-detector' model, expected 'neuron-fusion'" in err, err


@pytest.mark.parametrize("method,model", [("rbf", "det"), ("neural", "fus")])
def test_other_sensor_names(models, method, model, tmp_path, capsys):
    sc = _scenario(
        tmp_path / "names.toml", sensors=("gnss", "pos2", "pos3"), **{method: models[model]}
    )
    name = {"rbf": "fkf-rbf", "neural": "neural"}[method]
    # the first differing compatibility key (states, sensors, measurement_dims,
    # system_hash) is reported
    err = _run_refused(sc, tmp_path, capsys, name)
    assert (
        "was trained for sensors = ['pos1', 'pos2', 'pos3'], "
        "this scenario has ['gnss', 'pos2', 'pos3']"
    ) in err, err


def test_other_state_names(models, tmp_path, capsys):
    sc = _scenario(tmp_path / "states.toml", states=("p", "v", "a"), rbf=models["det"])
    err = _run_refused(sc, tmp_path, capsys, "fkf-rbf")
    assert "was trained for states = ['s', 'v', 'a']" in err, err


# --- training options -----------------------------------------------------------------


@pytest.fixture
def base(tmp_path) -> Path:
    return _scenario(tmp_path / "base.toml")


def test_train_detector_unknown_method(base, tmp_path, capsys):
    out = tmp_path / "det.npz"
    err = _refused(
        ["train-detector", base, "--out", out, "--method", "nosuch"], capsys, "--method: "
    )
    assert "'nosuch' is not a method" in err, err
    assert "fkf-chi2" in err  # lists the scenario's methods
    assert not out.exists()


@pytest.mark.parametrize("command", ["train-detector", "train-fusion"])
def test_train_out_is_a_folder(command, base, tmp_path, capsys):
    (tmp_path / "models").mkdir()
    err = _refused([command, base, "--out", tmp_path / "models"], capsys, "--out: ")
    assert "is a folder" in err, err


@pytest.mark.parametrize(
    "command,option,value",
    [
        ("train-fusion", "--runs", "0"),
        ("train-fusion", "--holdout", "-1"),
        ("train-detector", "--runs", "many"),
        ("train-detector", "--centres", "0"),
        ("train-detector", "--seed", "-3"),
    ],
)
def test_train_bad_numbers(command, option, value, base, tmp_path, capsys):
    out = tmp_path / "m.npz"
    err = _refused([command, base, "--out", out, option, value], capsys, "")
    assert option in err, err
    assert not out.exists()
    assert "usage" not in err


def test_train_unknown_scenario(tmp_path, capsys):
    err = _refused(
        ["train-detector", "nosuch-scenario", "--out", tmp_path / "m.npz"], capsys, "scenario: "
    )
    assert "neither a built-in scenario" in err, err


def test_train_detector_needs_out(base, capsys):
    err = _refused(["train-detector", base], capsys, "")
    assert "--out" in err, err
