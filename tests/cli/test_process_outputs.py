"""What ``ftnav process`` writes (issue 15, point 7; docs/recording-format.md, Outputs).

The input is the first 60 s of the vendored drive after its alignment (the built-in
recording with absolute data paths and ``[filter] duration_s = 60``), run with a
centralized filter and a federated one with a chi-square detector, a 5 m GNSS step
and 10 s outages every 30 s (two interleaved runs).  Oracles: ``solution.csv`` as
written by the same command (the KML and the NetCDF trace must carry the same
numbers), the filter's own σ (``sigma_up_m`` is the σ of the ``dh`` state), the fault
and outage windows given on the command line, and the listing of the folder.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from ftnav import cli
from ftnav.cli import main
from ftnav.io.solution_file import SOLUTION_COLUMNS
from ftnav.nav.error_model import STATES_15
from ftnav.recordings import recording_path

KML = "{http://www.opengis.net/kml/2.2}"
METHODS = ["ckf", "fkf-chi2"]
FAULT = (1752003330.0, 1752003340.0)  # s, the drive's time base (GPST Unix seconds)
# two interleaved runs inside the 60 s span (outages clipped 30 s before its end)
OUTAGES = ["--outage-length", "5", "--outage-every", "20", "--outage-start", "40"]


def _recording(folder: Path) -> Path:
    src = recording_path("rtklib-drive")
    text = src.read_text().replace('file = "data/', f'file = "{src.parent.as_posix()}/data/')
    text, n = re.subn(r"^\[filter\]\n", "[filter]\nduration_s = 60.0\n", text, flags=re.M)
    assert n == 1
    path = folder / "drive60.toml"
    path.write_text(text)
    return path


def _argv(rec: Path, out: Path, *extra: str) -> list[str]:
    return ["process", str(rec), "--out", str(out), "--methods", ",".join(METHODS), *extra]


@pytest.fixture(scope="module")
def processed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("process")
    rec = _recording(folder)
    out = folder / "out"
    fault = f"gnss:bias:{FAULT[0]}:{FAULT[1]}:5"
    assert main(_argv(rec, out, "--quiet", "--fault", fault, *OUTAGES)) == 0
    return rec, out


def _csv(out: Path, method: str) -> np.ndarray:
    path = out / f"solution-{method}.csv"
    assert path.read_text().splitlines()[0].split(",") == list(SOLUTION_COLUMNS)
    return np.loadtxt(path, delimiter=",", skiprows=1)


def test_the_folder_holds_what_metrics_json_lists(processed):
    _, out = processed
    doc = json.loads((out / "metrics.json").read_text())
    on_disk = {p.name for p in out.iterdir() if not p.name.startswith(".")}
    assert set(doc["files"]) == on_disk
    expected = {"track.geojson", "track.kml", "trace.nc", "metrics.json"}
    expected |= {"report.md", "report.html"}
    expected |= {"track.png", "errors.png", "innovations.png"}
    expected |= {f"solution-{m}.csv" for m in METHODS}
    assert on_disk == expected
    assert doc["runs"] == 2 and set(doc["methods"]) == set(METHODS)
    for name in ("track.png", "errors.png", "innovations.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_kml_track_carries_the_solution_csv_coordinates(processed):
    _, out = processed
    doc = ET.parse(out / "track.kml").getroot().find(f"{KML}Document")
    marks = {pm.findtext(f"{KML}name"): pm for pm in doc.iter(f"{KML}Placemark")}
    assert set(marks) == {*METHODS, "reference"}
    for name, pm in marks.items():
        line = pm.find(f"{KML}LineString")
        assert line.findtext(f"{KML}altitudeMode") == "absolute"
        coords = np.array(
            [[float(v) for v in c.split(",")] for c in line.findtext(f"{KML}coordinates").split()]
        )
        if name == "reference":
            continue
        tab = _csv(out, name)
        assert coords.shape == (len(tab), 3)
        np.testing.assert_allclose(coords[:, 0], tab[:, 2], rtol=0, atol=1e-9)
        np.testing.assert_allclose(coords[:, 1], tab[:, 1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(coords[:, 2], tab[:, 3], rtol=0, atol=1e-4)
    import xarray as xr

    with xr.open_dataset(out / "trace.nc", engine="scipy") as ds:
        ref = marks["reference"].find(f"{KML}LineString").findtext(f"{KML}coordinates").split()
        ref = np.array([[float(v) for v in c.split(",")] for c in ref])
        np.testing.assert_allclose(ref[:, 0], ds.reference_lon_deg, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ref[:, 1], ds.reference_lat_deg, rtol=0, atol=1e-9)


def test_the_netcdf_trace_has_its_dimensions_units_and_the_csv_solution(processed):
    import xarray as xr

    _, out = processed
    with xr.open_dataset(out / "trace.nc", engine="scipy") as ds:
        tab = _csv(out, "ckf")
        assert list(ds.method_name.values) == METHODS
        assert ds.sizes["run"] == 2 and ds.sizes["time"] == len(tab)
        assert list(ds.state.values) == list(STATES_15)
        doc = json.loads((out / "metrics.json").read_text())
        assert list(ds.sensor.values) == doc["aids"] and "gnss" in doc["aids"]
        rows = [str(r).split(".") for r in ds.measurement.values]
        assert [a for a in doc["aids"] if any(r[0] == a for r in rows)] == doc["aids"]
        assert set(ds.measurement_units.values) <= {"m", "m/s"}
        for name in [*ds.data_vars, *ds.coords]:
            assert ds[name].attrs.get("units") and ds[name].attrs.get("long_name"), name
        assert ds.lat_deg.units == "degrees_north" and ds.time.units == "s"
        assert dict(zip(ds.state.values, ds.state_units.values, strict=True))["dh"] == "m"
        np.testing.assert_allclose(ds.time, tab[:, 0], rtol=0, atol=5e-5)
        for m in METHODS:
            tab = _csv(out, m)
            run0 = ds.sel(method_name=m).isel(run=0)
            for j, col in enumerate(SOLUTION_COLUMNS[1:], start=1):
                atol = 5e-10 if col in ("lat_deg", "lon_deg") else 5e-5
                np.testing.assert_allclose(run0[col], tab[:, j], rtol=0, atol=atol, err_msg=col)
            # the σ column is the filter's σ of the height error state
            np.testing.assert_allclose(
                run0.sigma_up_m, run0.error_state_sigma.sel(state="dh"), rtol=1e-12
            )
        ckf, fkf = ds.sel(method_name="ckf"), ds.sel(method_name="fkf-chi2")
        assert (ckf.fault_flag == -1).all() and ckf.detector_statistic.isnull().all()
        assert ckf.beta.isnull().all() and np.isfinite(fkf.beta).all()
        assert set(np.unique(fkf.fault_flag.values)) <= {0, 1}
        tested = np.isfinite(fkf.detector_statistic)
        # tested only where the aid measured; the threshold is given wherever it was
        assert not (tested & (ds.aid_available == 0)).any()
        assert (tested == np.isfinite(fkf.detector_threshold)).all()
        gnss = {"sensor": "gnss"}
        t = ds.time.values
        in_fault = (t >= FAULT[0]) & (t < FAULT[1])
        assert (ds.fault_active.sel(gnss).values.astype(bool) == in_fault).all()
        assert (ds.fault_active.drop_sel(gnss) == 0).all()
        # the step is flagged inside its window (where GNSS is not out)
        flagged = fkf.fault_flag.sel(gnss).values == 1
        assert flagged[:, in_fault].any()
        # each run's outages remove the primary GNSS, and nothing else does here
        outage = ds.gnss_outage.values.astype(bool)
        assert outage[0].any() and outage[1].any() and not (outage[0] & outage[1]).any()
        assert not (ds.aid_available.sel(gnss).values.astype(bool) & outage).any()
        t_origin = doc["time_base"]["t_first_gnss_s"]
        for run, windows in enumerate(doc["outages_s_after_first_gnss"]):
            expect = np.zeros(len(t), bool)
            for s, e in windows:
                expect |= (t >= t_origin + s) & (t < t_origin + e)
            assert (outage[run] == expect).all()


def test_no_figures_writes_no_png(processed, tmp_path, capsys):
    rec, _ = processed
    out = tmp_path / "o"
    assert main(_argv(rec, out, "--quiet", "--no-figures")) == 0
    names = {p.name for p in out.iterdir()}
    assert not any(n.endswith(".png") for n in names)
    assert {"track.kml", "trace.nc", "metrics.json"} <= names
    doc = json.loads((out / "metrics.json").read_text())
    assert not any(n.endswith(".png") for n in doc["files"])


def test_a_refused_run_writes_nothing(processed, tmp_path, capsys):
    rec, _ = processed
    before = sorted(tmp_path.rglob("*"))
    out = tmp_path / "new" / "o"
    # a fault after the 60 s processed
    argv = _argv(rec, out, "--quiet", "--fault", "gnss:bias:1752003500:1752003510:5")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftnav: error: --fault") and err.count("\n") == 1, err
    assert sorted(tmp_path.rglob("*")) == before and not (tmp_path / "new").exists()


class _Bar:
    made: list[_Bar] = []

    def __init__(self, total, disable, delay, **kw):
        self.total, self.disable, self.delay, self.n = total, disable, delay, 0
        _Bar.made.append(self)

    def update(self, n=1):
        self.n += n

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.mark.parametrize("quiet", [False, True])
def test_the_progress_bar_counts_epochs_methods_and_runs(processed, tmp_path, monkeypatch, quiet):
    rec, out = processed
    monkeypatch.setattr(cli, "tqdm", _Bar)
    _Bar.made.clear()
    flags = ["--quiet"] if quiet else []
    assert main(_argv(rec, tmp_path / "o", "--no-figures", *OUTAGES, *flags)) == 0
    (bar,) = _Bar.made
    epochs = len(_csv(out, "ckf"))
    assert bar.total == bar.n == epochs * len(METHODS) * 2
    if quiet:
        assert bar.disable is True
    else:  # shown on a terminal, after a delay (a short run shows none)
        assert bar.disable is None and bar.delay > 0


def test_a_fault_of_the_ins_itself_is_written_beside_the_aids_faults(tmp_path):
    """``--fault sins:gyro-bias:...``: the run went through and then ended in an internal
    error writing ``trace.nc`` (its window was looked up among the aids).  It is written
    as ``sins_fault_active`` (time), the aids' ``fault_active`` untouched."""
    import xarray as xr

    rec, out = _recording(tmp_path), tmp_path / "out"
    fault = f"sins:gyro-bias:{FAULT[0]}:{FAULT[1]}:0,0,1800"
    assert main(_argv(rec, out, "--quiet", "--no-figures", "--fault", fault)) == 0
    with xr.open_dataset(out / "trace.nc", engine="scipy") as ds:
        t = ds.time.values
        inside = (t >= FAULT[0]) & (t < FAULT[1])
        assert inside.any() and (~inside).any()
        np.testing.assert_array_equal(ds.sins_fault_active.values, inside.astype(np.int8))
        assert not ds.fault_active.values.any()
