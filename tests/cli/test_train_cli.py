"""``ftnav train-detector`` / ``ftnav train-fusion`` on a small linear scenario: files,
held-out tables, the trained models used by ``ftnav run``, and determinism of training."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from ftnav.cli import main
from ftnav.io.model_file import load_model

# seed000's system (model and sensors), 200 epochs, one +60 step on pos1 over [60, 120) s
SYSTEM = """
name = "small-learned"
dt = 1.0
steps = {steps}

[model]
states = ["s", "v", "a"]
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]

[[sensors]]
name = "pos1"
H = [[1.0, 0.0, 0.0]]
R = [[30.0]]

[[sensors]]
name = "pos2"
H = [[2.5, 0.0, 0.0]]
R = [[30.0]]

[[sensors]]
name = "pos3"
H = [[0.5, 0.0, 0.0]]
R = [[30.0]]

[[faults]]
sensor = "pos1"
kind = "bias"
start = 60.0
end = 120.0
magnitude = [60.0]

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-chi2"
architecture = "federated"
sharing = "inverse-trace"
detector = {{ kind = "residual-chi2", prior = "global" }}
"""

LEARNED = """
[[methods]]
name = "fkf-rbf"
architecture = "federated"
sharing = "inverse-trace"
detector = { kind = "rbf", model = "det.npz" }

[[methods]]
name = "neural"
architecture = "neural"
model = "fus.npz"
detector = { kind = "residual-chi2", prior = "global" }
"""


@pytest.fixture(scope="module", autouse=True)
def _one_openmp_thread():
    # k-means (scikit-learn, OpenMP) slows down by one to two orders of magnitude when
    # its threads share busy cores with other processes (e.g. pytest -n); training
    # results do not depend on the thread count, so keep it at one for stable timings
    with threadpool_limits(limits=1, user_api="openmp"):
        yield


def _main(argv):
    """``main(argv)`` with its standard output and error captured: (code, out, err)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The small scenario and both models trained once into its folder."""
    d = tmp_path_factory.mktemp("learned")
    toml = d / "small.toml"
    toml.write_text(SYSTEM.format(steps=200) + LEARNED)
    det = _main(
        [
            "train-detector",
            toml,
            "--out",
            d / "det.npz",
            "--runs",
            "1",
            "--holdout",
            "1",
            "--centres",
            "20",
            "--quiet",
        ]
    )
    fus = _main(
        ["train-fusion", toml, "--out", d / "fus.npz", "--runs", "1", "--holdout", "1", "--quiet"]
    )
    return {"dir": d, "toml": toml, "det": det, "fus": fus}


def test_train_detector_writes_model_figure_and_held_out_table(trained):
    code, out, err = trained["det"]
    assert code == 0, err
    d = trained["dir"]
    assert (d / "det.npz").is_file() and (d / "det.png").is_file()
    assert (d / "det.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "Pd rbf" in out and "Pd chi2" in out
    assert "false-alarm rate per epoch" in out
    # trained through the scenario's rbf method, one row per sensor x typical fault
    assert "method 'fkf-rbf'" in out
    for sensor in ("pos1", "pos2", "pos3"):
        assert f"\n{sensor} " in out
    assert str(d / "det.npz") in out
    model = load_model(d / "det.npz", "rbf-detector")
    assert model.compatibility["sensors"] == ["pos1", "pos2", "pos3"]
    assert model.compatibility["states"] == ["s", "v", "a"]
    assert model.arrays["centres"].shape[0] == 20
    assert model.arrays["weights"].shape[1] == 3  # one output per local filter


def test_train_fusion_writes_model_figure_and_weights(trained):
    code, out, err = trained["fus"]
    assert code == 0, err
    d = trained["dir"]
    assert (d / "fus.npz").is_file() and (d / "fus.png").is_file()
    assert (d / "fus.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "weights (pos1, pos2, pos3)" in out
    assert "configurations healthy, pos1, pos2, pos3" in out
    model = load_model(d / "fus.npz", "neuron-fusion")
    W = np.asarray(model.arrays["weights"])
    # weights are constrained to the simplex (default projection)
    assert W.min() >= 0.0
    np.testing.assert_allclose(W.sum(-1), 1.0, atol=1e-9)


def test_model_files_open_with_numpy_without_pickle(trained):
    d = trained["dir"]
    for name in ("det.npz", "fus.npz"):
        ours = load_model(d / name).arrays
        with np.load(d / name, allow_pickle=False) as npz:
            assert set(ours) <= set(npz.files)
            for key, value in ours.items():
                np.testing.assert_array_equal(npz[key], value)


def test_run_uses_the_trained_models(trained, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["run", str(trained["toml"]), "--runs", "4", "--out", str(out), "--no-figures", "--quiet"]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    doc = json.loads((out / "metrics.json").read_text())
    assert set(doc["methods"]) == {"ckf", "fkf-chi2", "fkf-rbf", "neural"}
    for name in ("fkf-rbf", "neural"):
        m = doc["methods"][name]
        assert all(np.isfinite(v) for v in m["rmse"].values())
        det = m["detection"]
        assert det is not None and set(det) == {"pos1", "pos2", "pos3"}
        assert {"rate", "false_alarm_rate", "mean_delay_s"} <= set(det["pos1"])
        # a 60 (about 11 sigma) step is found by both learned methods
        assert det["pos1"]["rate"] > 0.5
    assert "Detectors side by side" in captured.out


def test_relative_model_path_follows_the_scenario_folder(trained, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # det.npz / fus.npz do not exist here
    code = main(
        [
            "run",
            str(trained["toml"]),
            "--runs",
            "1",
            "--out",
            str(tmp_path / "o"),
            "--no-figures",
            "--quiet",
        ]
    )
    assert code == 0, capsys.readouterr().err


def _train_small_detector(folder: Path, toml: Path, name: str, seed: int):
    out = folder / name
    code, _, err = _main(
        [
            "train-detector",
            toml,
            "--out",
            out,
            "--runs",
            "1",
            "--holdout",
            "1",
            "--centres",
            "10",
            "--seed",
            seed,
            "--no-figure",
            "--quiet",
        ]
    )
    assert code == 0, err
    assert not out.with_suffix(".png").exists()  # --no-figure
    return load_model(out, "rbf-detector")


def test_detector_training_is_deterministic_and_seeded(tmp_path):
    toml = tmp_path / "tiny.toml"
    toml.write_text(SYSTEM.format(steps=120))  # no rbf method: federated inverse-trace
    a = _train_small_detector(tmp_path, toml, "a.npz", 3)
    b = _train_small_detector(tmp_path, toml, "b.npz", 3)
    c = _train_small_detector(tmp_path, toml, "c.npz", 4)
    assert set(a.arrays) == set(b.arrays) == set(c.arrays)
    for key in a.arrays:
        x, y = a.arrays[key], b.arrays[key]
        assert (x.dtype, x.shape) == (y.dtype, y.shape)
        assert x.tobytes() == y.tobytes(), key
    assert a.settings == b.settings
    assert a.arrays["centres"].shape == c.arrays["centres"].shape
    assert not np.array_equal(a.arrays["centres"], c.arrays["centres"])
