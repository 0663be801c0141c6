"""Learned models on a recording: the RBF detector and the neuron fusion centre on 30 s of
the vendored rtklibexplorer drive (issue 15, point 5).

No ftnav command trains a model for a recording (``train-detector`` and ``train-fusion``
take simulated scenarios; the drive has no labelled truth), so the models are built by
hand for the recording's own system and written with the project's save functions and
compatibility stamp (:func:`ftnav.io.learned.compatibility`).  Oracles, in closed form:

* a neuron bank with weight 1 on the GNSS local filter reproduces, fed back to the SINS,
  a distributed filter that has the GNSS aid alone (the other local filters carry no
  weight); equal weights give the mean of the local estimates;
* an RBF network whose output is a constant above its threshold raises its raw flag at
  exactly the epochs each aid has a measurement (the stream's availability), and the
  flag after one alarm (``n_on = 1``) stays set; a constant below the threshold never
  flags and leaves the solution bit for bit that of the method without a detector;
* a model stamped for another sensor set is refused by ``ftnav process``: exit 2, one
  line naming the method and the file, nothing written.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from recording_runs import traces_of

from ftnav.cli import main
from ftnav.fdi.rbf import RBFModel, RBFNetwork
from ftnav.fusion.neural_model import NeuronModel
from ftnav.io.learned import compatibility, save_neuron_model, save_rbf_model
from ftnav.io.recording_file import load_recording
from ftnav.recordings import recording_path

DATA = recording_path("rtklib-drive").parent / "data" / "rtklibexplorer" / "drive_0708"
EARTH_M = 6.4e6

#: 30 s of the drive after its 30 s static alignment: IMU, one GNSS aid (position and
#: velocity), the vehicle constraints; the upstream mounting, offsets and noise
RECORDING = f"""
kind = "recording"
name = "drive-30s"

[imu]
file = "{DATA / "imu_1934_gpst.csv"}"
time = {{ columns = ["t_gpst_unix_s"], unit = "s" }}
accel = {{ columns = ["acc_x_g", "acc_y_g", "acc_z_g"], unit = "g" }}
gyro = {{ columns = ["gyro_x_dps", "gyro_y_dps", "gyro_z_dps"], unit = "deg/s" }}
time_offset_s = -0.20
axes = ["+y", "-x", "+z"]
misalignment_deg = [-6.79, 0.0, -5.35]

[imu.errors]
gyro_arw = "0.0038 deg/s/sqrt(Hz)"
accel_vrw = "70 ug/sqrt(Hz)"
gyro_bias_sd = "0.05 deg/s"
accel_bias_sd = "20 mg"
gyro_markov_sd = "0.05 deg/s"
gyro_markov_tau = "60 s"
accel_markov_sd = "1 mg"
accel_markov_tau = "300 s"

[[aids]]
type = "gnss"
name = "gnss"
file = "{DATA / "gnss_1934_sf.pos"}"
quality = [1]
lever_arm_m = [-0.05, 0.0, 0.0]
pos_white_sigma_m = 0.05
vel_white_sigma_m_s = 0.1
{{constraints}}
[reference]
source = "gnss"
quality = [1]

[alignment]
static_s = 30.0
min_speed_mps = 1.0
attitude_sigma_deg = [1.0, 1.0, 10.0]

[filter]
states = 15
duration_s = 30

[[methods]]
name = "dkf"
architecture = "distributed"

[[methods]]
name = "fkf-rbf-always"
architecture = "federated"
mode = "fusion-reset"
sharing = "equal"
detector = {{ kind = "rbf", model = "always.npz" }}
guard = false  # the raw detector's flags, as the network raises them (no re-admission)

[[methods]]
name = "dkf-rbf-never"
architecture = "distributed"
detector = {{ kind = "rbf", model = "never.npz" }}

[[methods]]
name = "neural-gnss"
architecture = "neural"
model = "gnss.npz"

[[methods]]
name = "neural-mean"
architecture = "neural"
model = "mean.npz"
"""

CONSTRAINTS = """
[[aids]]
type = "nhc"
sigma_m_s = 0.1

[[aids]]
type = "zupt"
sigma_m_s = 0.05
window_s = 1.0
accel_std_mps2 = 0.1
gyro_std_dps = 1.5
"""

ABOVE, BELOW, THRESHOLD = 0.9, 0.1, 0.5


def _write(folder: Path, constraints: bool = True) -> Path:
    path = folder / "drive.toml"
    path.write_text(RECORDING.replace("{constraints}", CONSTRAINTS if constraints else ""))
    return path


def _rbf(system, stamp, output: float) -> RBFModel:
    """A network whose every output is ``output`` whatever the features: zero hidden-layer
    weights, the constant in the bias row (spec §4.2, ``y = Wᵀ [h(x); 1]``)."""
    N, M = system.n_sensors, 2
    F = sum(s.dim for s in system.sensors)  # the whitened innovations
    arrays = {
        "mean": np.zeros(F),
        "scale": np.ones(F),
        "centres": np.zeros((M, F)),
        "widths": np.ones(M),
        "weights": np.vstack([np.zeros((M, N)), np.full((1, N), output)]),
    }
    net = RBFNetwork.from_arrays(arrays, RBFNetwork(n_centres=M).get_params())
    tau = np.full(N, THRESHOLD)
    return RBFModel(net, ("innovation",), "local", tau, 1, 1, stamp, {"by": "hand"})


def _neuron(system, stamp, weights: np.ndarray) -> NeuronModel:
    """One (healthy) bank: ``weights`` (N,) on the local filters for every state."""
    nc, N = system.n_common, system.n_sensors
    W = np.broadcast_to(weights, (1, nc, N)).copy()
    return NeuronModel(
        ("healthy",),
        np.zeros((1, N), bool),
        tuple(s.name for s in system.sensors),
        tuple(system.model.states),
        W,
        np.zeros((1, nc)),
        stamp,
        {"by": "hand"},
    )


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The models for the recording's system, the recording, its traces; and the
    distributed filter on the GNSS aid alone."""
    folder = tmp_path_factory.mktemp("learned")
    path = _write(folder)
    system = load_recording(path, methods=["dkf"]).recording.system()
    stamp = compatibility(system)
    names = [s.name for s in system.sensors]
    assert names == ["gnss", "nhc", "zupt"]
    save_rbf_model(_rbf(system, stamp, ABOVE), folder / "always.npz")
    save_rbf_model(_rbf(system, stamp, BELOW), folder / "never.npz")
    save_neuron_model(_neuron(system, stamp, np.eye(3)[0]), folder / "gnss.npz")
    save_neuron_model(_neuron(system, stamp, np.full(3, 1 / 3)), folder / "mean.npz")

    loaded = load_recording(path)
    traces = traces_of(loaded)
    gnss_only = traces_of(load_recording(path, methods=["dkf"], aids=["gnss"]))
    return folder, loaded, traces, gnss_only["dkf"]


def _metres(p: np.ndarray, q: np.ndarray) -> float:
    """Largest position difference (lat, lon rad, h m) in metres."""
    scale = np.array([EARTH_M, EARTH_M * np.cos(p[..., 0]).max(), 1.0])
    return float((np.abs(p - q) * scale).max())


def test_a_neuron_weighting_only_the_gnss_filter_is_the_gnss_only_filter(drive):
    _, loaded, traces, gnss_only = drive
    nn = traces["neural-gnss"]
    assert loaded.recording.steps >= 300  # 30 s at the filter rate
    # the fused estimate is the GNSS local filter's, every epoch (n_nav states recorded)
    n = nn.local.shape[-1]
    np.testing.assert_array_equal(nn.x[..., :n], nn.local[:, :, 0, :])
    # fed back, it is the distributed filter that has the GNSS aid alone
    assert _metres(nn.solution.p, gnss_only.solution.p) < 1e-6
    # ... which the constraints' local filters would move: the oracle can fail
    assert _metres(traces["dkf"].solution.p, gnss_only.solution.p) > 0.01


def test_a_neuron_with_equal_weights_is_the_mean_of_the_local_filters(drive):
    _, _, traces, _ = drive
    nn = traces["neural-mean"]
    n = nn.local.shape[-1]
    # (w = 1/3 in floating point: agreement to the rounding of the largest estimate)
    atol = 1e-12 * np.abs(nn.local).max()
    np.testing.assert_allclose(nn.x[..., :n], nn.local.mean(2), rtol=0, atol=atol)
    assert np.abs(nn.local[:, :, 0] - nn.local[:, :, 1]).max() > 1e6 * atol  # not all equal
    assert np.isfinite(nn.solution.p).all()


def test_an_rbf_output_above_its_threshold_flags_every_tested_epoch(drive):
    _, loaded, traces, _ = drive
    t = traces["fkf-rbf-always"]
    available = np.stack([a.available for a in loaded.stream.aids], -1)  # (B, K, N)
    assert available[..., 0].sum() > 100 and available[..., 1].sum() > 100  # GNSS, NHC
    np.testing.assert_array_equal(t.raw_flag, available)
    np.testing.assert_array_equal(t.statistic, np.where(available, ABOVE, 0.0))
    # n_on = 1, and no pass to clear it: set from the first tested epoch on
    np.testing.assert_array_equal(t.flag, np.maximum.accumulate(available, axis=1))


def test_an_rbf_output_below_its_threshold_never_flags_and_changes_nothing(drive):
    _, _, traces, _ = drive
    t = traces["dkf-rbf-never"]
    assert not t.raw_flag.any() and not t.flag.any()
    np.testing.assert_array_equal(t.solution.p, traces["dkf"].solution.p)
    np.testing.assert_array_equal(t.x, traces["dkf"].x)


def test_ftnav_process_runs_the_learned_methods_and_scores_their_detection(drive, capsys):
    folder, loaded, _, _ = drive
    rec = loaded.recording
    t0 = rec.t_start + rec.times[0]
    fault = f"gnss:bias:{t0 + 10:.3f}:{t0 + 20:.3f}:5"
    out = folder / "out"
    methods = "fkf-rbf-always,dkf-rbf-never,neural-gnss"
    argv = ["process", str(folder / "drive.toml"), "--methods", methods]
    code = main([*argv, "--fault", fault, "--out", str(out), "--no-figures", "--quiet"])
    assert code == 0, capsys.readouterr().err
    doc = json.loads((out / "metrics.json").read_text())
    for m in methods.split(","):
        assert (out / f"solution-{m}.csv").is_file()
    assert doc["methods"]["fkf-rbf-always"]["detection"]["gnss"]["rate"] == 1.0
    assert doc["methods"]["dkf-rbf-never"]["detection"]["gnss"]["rate"] == 0.0


@pytest.mark.parametrize(
    "method,field,model",
    [
        ("fkf-rbf-always", "detector.model", "always.npz"),
        ("neural-gnss", "model", "gnss.npz"),
    ],
)
def test_a_model_for_another_sensor_set_is_refused(drive, tmp_path, capsys, method, field, model):
    folder, *_ = drive
    path = folder / "gnss-only" / "drive.toml"  # the same recording without nhc and zupt
    path.parent.mkdir(exist_ok=True)
    _write(path.parent, constraints=False)
    for name in ("always.npz", "gnss.npz"):  # the models of the three-aid recording
        (path.parent / name).write_bytes((folder / name).read_bytes())
    out = tmp_path / "out"
    code = main(["process", str(path), "--methods", method, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    import tomllib

    # the method's index in the file, whatever --methods chose
    i = [m["name"] for m in tomllib.loads(path.read_text())["methods"]].index(method)
    # the recording file and its line, then the field
    assert re.match(rf"ftnav: error: {re.escape(str(path))}:\d+: methods\[{i}\]\.", err), err
    assert f" methods[{i}].{field}: was trained for sensors = " in err, err
    assert "['gnss', 'nhc', 'zupt'], this scenario has ['gnss']" in err, err
    assert f"method {method!r}" in err and str(path.parent / model) in err, err
    assert not out.exists()
