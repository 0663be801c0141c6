"""Multi-rate aids and ``ftnav train-fusion`` on small integrated files.

Oracles: the schedule of an aid with ``every = 2`` (measurements on every second
epoch only, the filters still run every epoch); the neuron model's own invariants
(every weight row on the simplex, the paper 001 configurations and their flag
patterns) and the model file round trip through ``ftnav run``.
"""

from __future__ import annotations

import json

import numpy as np

from ftnav.cli import main
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.learned import load_neuron_model
from ftnav.io.scenario_file import load_scenario

SMALL001 = """
kind = "integrated"
name = "small001"
profile = "seed001"
imu = "seed001"

[filter]
dt = 1.0
duration_s = {duration}

[[aids]]
type = "gnss"
name = "gps"
every = {every}

[[aids]]
type = "dns"
name = "dns"

{faults}
[[methods]]
name = "ckf"
architecture = "centralized"
{extra}
"""


# the configurations to train (GPS, SINS); train-fusion places its own windows
FAULTS = """
[[faults]]
sensor = "gps"
kind = "bias"
start = 30.0
end = 40.0
magnitude = [150.0, 150.0, 0.0, 0.0, 0.0, 0.0]

[[faults]]
sensor = "sins"
kind = "gyro-bias"
start = 45.0
end = 55.0
magnitude_deg_h = [10.0, 10.0, 10.0]
"""


def _write(tmp_path, duration=40.0, every=1, extra="", faults=FAULTS):
    path = tmp_path / "small001.toml"
    path.write_text(SMALL001.format(duration=duration, every=every, extra=extra, faults=faults))
    return path


def test_aid_every_second_epoch(tmp_path):
    sc = load_scenario(_write(tmp_path, duration=8.0, every=2, faults=""))
    result = run_scenario(sc, 1, 3, fault_free=False)
    avail = result.stream.aids[0].available[0, :]
    np.testing.assert_array_equal(avail, np.arange(1, 9) % 2 == 0)
    assert np.isfinite(result.results["ckf"].error).all()


def test_train_fusion_then_run(tmp_path, capsys):
    path = _write(tmp_path, duration=220.0)
    out = tmp_path / "m.npz"
    assert main(["train-fusion", str(path), "--out", str(out), "--runs", "1", "--quiet"]) == 0
    model = load_neuron_model(out)
    assert model.configurations == ("healthy", "gps", "sins")
    np.testing.assert_array_equal(model.patterns, [[False, False], [True, False], [True, True]])
    assert (model.weights >= 0).all()
    np.testing.assert_allclose(model.weights.sum(-1), 1.0, atol=1e-9)
    extra = (
        '[[methods]]\nname = "neural"\narchitecture = "neural"\n'
        'detector = { kind = "residual-chi2", prior = "global" }\nmodel = "m.npz"\n'
    )
    path = _write(tmp_path, duration=60.0, extra=extra)
    assert (
        main(
            [
                "run",
                str(path),
                "--runs",
                "1",
                "--out",
                str(tmp_path / "r"),
                "--quiet",
                "--no-figures",
            ]
        )
        == 0
    )
    doc = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert np.isfinite(doc["methods"]["neural"]["rmse"]["pos_N_m"])
