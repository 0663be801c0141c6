"""Third-party synthetic data with an exact truth: NaveGo's ADIS16405 and ADIS16488 sets.

Oracles: the data set's 200 Hz truth (position, velocity, attitude) and its README's
error model (white noise, static bias nominal ± 10 %, Gauss-Markov bias of 100 s): the
known biases are derived from the data independently of any filter (the IMU minus the
error-free IMU computed from the truth, :mod:`ftnav.recorded.truth`); the filter's NEES
against its own covariance (χ²(9) band); pyins 1.0's anchor on ADIS16488 from the issue
(horizontal RMSE 0.56 m, velocity ≈ 0.015 m/s, heading 0.24°) as a sanity scale.
The data are read from ``$FTNAV_NAVEGO_DIR`` or ``<repo>/../shared/data/navego_synthetic``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io as sio
from recording_runs import process

from ftnav.io.recording_file import load_recording
from ftnav.io.recording_readers import read_navego_imu, read_navego_truth
from ftnav.nav.attitude import euler_to_dcm
from ftnav.recorded.truth import ideal_imu
from ftnav.recordings import navego_dir, recording_path

DATA = navego_dir()
pytestmark = pytest.mark.skipif(
    not all((DATA / f).is_file() for f in ("imu1.mat", "imu2.mat", "gnss.mat", "ref.mat")),
    reason=f"NaveGo data absent: put imu1.mat, imu2.mat, gnss.mat, ref.mat in {DATA} "
    "(or set FTNAV_NAVEGO_DIR)",
)


def _process(name):
    loaded, _, scores = process(recording_path(name), nav_covariance=True, methods=["ckf"])
    return loaded, scores["ckf"]


@pytest.fixture(scope="module")
def adis16488():
    return _process("navego-adis16488")


@pytest.fixture(scope="module")
def adis16405():
    return _process("navego-adis16405")


def test_the_reference_dcm_is_the_frame_converted_roll_pitch_yaw():
    ref = sio.loadmat(DATA / "ref.mat", squeeze_me=True, struct_as_record=False)["ref"]
    tr = read_navego_truth(DATA / "ref.mat")
    k = np.arange(0, ref.t.size, 97)
    # ftnav [pitch, roll, yaw ccw] from NaveGo's roll, pitch, yaw (NED, clockwise yaw)
    C = euler_to_dcm(np.stack([ref.pitch[k], ref.roll[k], -ref.yaw[k]], -1))
    assert np.abs(C - tr.C[k]).max() < 1e-9
    # level at the start, heading 15 deg west of north: the body's forward axis (y) in ENU
    assert np.allclose(tr.C[0] @ [0, 1, 0], [-np.sin(np.radians(15)), np.cos(np.radians(15)), 0])


def test_the_imu_matches_the_error_free_imu_from_the_truth_up_to_its_noise():
    tr = read_navego_truth(DATA / "ref.mat")
    w, f = ideal_imu(tr.t[:2001], tr.p[:2001], tr.v[:2001], tr.C[:2001])
    imu = read_navego_imu(DATA / "imu2.mat")
    m = sio.loadmat(DATA / "imu2.mat", squeeze_me=True, struct_as_record=False)["imu2"]
    dg, da = imu.gyro[1:2001] - w, imu.accel[1:2001] - f
    # the static bias: positive on NaveGo's every axis, so [+, +, -] in ftnav's (z up)
    assert np.all(np.sign(dg.mean(0)) == [1, 1, -1]) and np.all(np.sign(da.mean(0)) == [1, 1, -1])
    assert np.all(np.abs(np.abs(dg.mean(0)) / m.gb_sta - 1) < 0.15)
    assert np.all(np.abs(np.abs(da.mean(0)) / m.ab_sta - 1) < 0.15)
    # what is left is the noise and, on the accelerometers, the generator's approximation
    # at the 4 m/s² start (README); a wrong axis would leave the motion (m/s², deg/s)
    assert np.all(dg.std(0) < 2.0 * m.g_std) and np.all(da.std(0) < 10.0 * m.a_std)
    assert np.all(da.std(0) < 0.05 * f.std(0).max())


def test_adis16488_biases_within_20_percent_of_the_truth(adis16488):
    _, s = adis16488
    b = {"gyro": s.truth.gyro_bias, "accel": s.truth.accel_bias}
    for key in ("gyro", "accel"):
        err = np.abs(b[key].error_percent_of_truth)
        assert np.all(err < 20.0), (key, err)


def test_adis16488_errors_against_the_truth_on_pyins_scale(adis16488):
    _, s = adis16488
    r = s.truth.rmse
    assert s.truth.epochs > 4000 and s.nan_epochs == 0
    assert 0.1 < r.horizontal_m < 1.0  # pyins 0.56 m; GNSS σ 5 m
    assert max(r.velocity_enu_mps) < 0.03  # pyins ≈ 0.015 m/s
    assert r.heading_deg < 1.0 and r.roll_deg < 0.2 and r.pitch_deg < 0.2


@pytest.mark.xfail(
    strict=True,
    reason="measured: NEES inside the 95 % chi2(9) band for 73 % of the epochs after 60 s "
    "(mean 14.5, 27 % above); the filter holds the README's error model, but the data's "
    "IMU departs from it: against the error-free IMU from the truth its forward "
    "accelerometer has 10 s means up to 0.43 mg (the model: Gauss-Markov 0.1 mg) that "
    "follow the vertical specific force (the generator's smoothed differences); with an "
    "IMU simulated exactly to the README's model on the same truth and GNSS the same "
    "filter gives 86-88 %",
)
def test_adis16488_nees_inside_its_chi2_band_after_convergence(adis16488):
    _, s = adis16488
    assert s.truth.nees.fraction_inside >= 0.80


def test_adis16405_biases_and_nees(adis16405):
    _, s = adis16405
    b = {"gyro": s.truth.gyro_bias, "accel": s.truth.accel_bias}
    for key in ("gyro", "accel"):
        assert np.all(np.abs(b[key].error_percent_of_truth) < 20.0), key
        assert np.all(np.abs(np.array(b[key].truth))), key
    assert s.truth.nees.fraction_inside >= 0.80
    assert s.truth.rmse.horizontal_m < 1.5


def test_a_missing_data_file_says_where_to_put_it(tmp_path, monkeypatch):
    from ftnav.io.common import ScenarioError

    monkeypatch.setenv("FTNAV_NAVEGO_DIR", str(tmp_path / "nowhere"))
    with pytest.raises(ScenarioError) as exc:
        load_recording(recording_path("navego-adis16488"))
    msg = str(exc.value)
    assert "FTNAV_NAVEGO_DIR" in msg and str(tmp_path / "nowhere") in msg and "\n" not in msg
    assert Path(recording_path("navego-adis16488")).is_file()


def test_ftnav_process_writes_the_truth_scores(tmp_path, capsys):
    """Through the CLI: metrics.json carries the RMSE, the NEES and the biases, and the
    printed table the truth scores (the same numbers as the engine run above)."""
    import json

    from ftnav.cli import main

    out = tmp_path / "out"
    argv = ["process", "navego-adis16488", "--methods", "ckf", "--out", str(out)]
    assert main(argv + ["--no-figures", "--quiet"]) == 0
    t = json.loads((out / "metrics.json").read_text())["methods"]["ckf"]["truth"]
    assert t["nees"]["dof"] == 9 and 0.0 < t["nees"]["fraction_inside"] <= 1.0
    assert len(t["biases"]["gyro"]["estimate_dps"]) == 3
    assert "against the truth" in capsys.readouterr().out


def _model_exact_imu(folder: Path, seed: int = 1) -> Path:
    """imu2.mat rebuilt from the truth with exactly the data set's error model (the SI
    values in the file: white noise, static bias nominal ± 10 %, Gauss-Markov bias), in
    NaveGo's layout (body x forward, y right, z down)."""
    from ftnav.core.markov import gauss_markov
    from ftnav.io.recording_readers import FRD_TO_RFU as M
    from ftnav.recorded.truth import ideal_imu

    raw = sio.loadmat(DATA / "imu2.mat", squeeze_me=True, struct_as_record=False)["imu2"]
    truth = read_navego_truth(DATA / "ref.mat")
    w, f = ideal_imu(truth.t, truth.p, truth.v, truth.C)
    w, f = w @ M, f @ M  # to NaveGo's body axes (M is its own inverse)
    dt = float(np.median(np.diff(truth.t)))
    rng = np.random.default_rng(seed)
    K = w.shape[0]

    def errors(std, static, dyn, corr):
        std, static, dyn, corr = (
            np.broadcast_to(np.asarray(x, float), (3,)) for x in (std, static, dyn, corr)
        )
        bias = static * (1.0 + rng.uniform(-0.1, 0.1, 3))
        return (
            bias
            + gauss_markov(rng.standard_normal((K, 3)), dyn, corr, dt)
            + std * rng.standard_normal((K, 3))
        )

    wb = w + errors(raw.g_std, raw.gb_sta, raw.gb_dyn, raw.gb_corr)
    fb = f + errors(raw.a_std, raw.ab_sta, raw.ab_dyn, raw.ab_corr)
    fields = {k: getattr(raw, k) for k in raw._fieldnames}
    fields.update(t=truth.t[1:], wb=wb, fb=fb)  # each sample ends its interval
    path = folder / "imu2.mat"
    sio.savemat(path, {"imu2": fields})
    return path


def test_the_filter_is_consistent_on_a_model_exact_imu_of_the_same_truth(tmp_path):
    """The oracle behind the strict xfail above: the same truth, the same GNSS file and
    the same filter, with the IMU built exactly by the data set's stated error model,
    give a NEES inside its 95 % band for at least 80 % of the epochs after convergence.
    What the real file adds is its IMU's departure from that model (module docstring)."""
    imu = _model_exact_imu(tmp_path)
    src = recording_path("navego-adis16488")
    text = src.read_text().replace(
        "${FTNAV_NAVEGO_DIR:-../../../../shared/data/navego_synthetic}", str(DATA)
    )
    text = text.replace(f"{DATA}/imu2.mat", str(imu))
    path = tmp_path / "model-exact.toml"
    path.write_text(text)
    _, _, scores = process(path, nav_covariance=True, methods=["ckf"])
    s = scores["ckf"].truth
    assert s.nees.fraction_inside >= 0.80, s.nees
