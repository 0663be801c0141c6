"""Navigation solutions of a processed recording: ``solution.csv`` and a GeoJSON track.

``solution.csv`` (``docs/recording-format.md``) has exactly the columns
``time_s, lat_deg, lon_deg, height_m, v_east_mps, v_north_mps, v_up_mps, roll_deg,
pitch_deg, yaw_deg, sigma_east_m, sigma_north_m, sigma_up_m`` at every filter epoch
(every primary GNSS epoch and at least the recording's ``filter.rate_hz``); ``time_s`` is
on the recording's own time base; ``yaw_deg`` is the heading, clockwise from North in
[0, 360) (``docs/conventions.md``: −ψ); the σ are the filter's position σ, metres East,
North, Up.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ftnav.engine.driver import Trace, check_output
from ftnav.io.recording_file import LoadedRecording
from ftnav.io.results import METHOD_DIM, flag_attrs
from ftnav.model.scenario import SINS
from ftnav.nav import attitude
from ftnav.nav.earth import radii

__all__ = [
    "SOLUTION_COLUMNS",
    "error_state_units",
    "measurement_rows",
    "solution_table",
    "trace_dataset",
    "write_solution_csv",
    "write_trace_netcdf",
    "write_track_geojson",
    "write_track_kml",
]

SOLUTION_COLUMNS = (
    "time_s",
    "lat_deg",
    "lon_deg",
    "height_m",
    "v_east_mps",
    "v_north_mps",
    "v_up_mps",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "sigma_east_m",
    "sigma_north_m",
    "sigma_up_m",
)


def solution_table(trace: Trace, times: np.ndarray, run: int = 0, method: str = "?") -> np.ndarray:
    """(K, 13) rows of :data:`SOLUTION_COLUMNS` of one run of a trace.

    A NaN or inf solution, or a negative variance, raises
    :class:`~ftnav.engine.driver.Diverged` naming ``method``: it is never written.
    """
    sol = trace.solution
    assert sol is not None
    one = slice(run, run + 1)  # this run only: a table per run must not check them all
    check_output(
        method, (sol.p[one], sol.v[one], sol.q[one], trace.x[one]), (trace.P_diag[one],), times
    )
    p, v = sol.p[run], sol.v[run]
    euler = np.degrees(attitude.quat_to_euler(sol.q[run]))
    RM, RN = radii(p[:, 0], p[:, 2])
    sig = np.sqrt(trace.P_diag[run][:, 6:9])
    return np.column_stack(
        [
            times,
            np.degrees(p[:, 0]),
            np.degrees(p[:, 1]),
            p[:, 2],
            v,
            euler[:, 1],
            euler[:, 0],
            (-euler[:, 2]) % 360.0,
            sig[:, 1] * RN * np.cos(p[:, 0]),
            sig[:, 0] * RM,
            sig[:, 2],
        ]
    )


def write_solution_csv(table: np.ndarray, path: Path) -> Path:
    """Write :func:`solution_table` rows with a header line."""
    fmt = ["%.4f", "%.9f", "%.9f", "%.4f"] + ["%.4f"] * 3 + ["%.4f"] * 3 + ["%.4f"] * 3
    np.savetxt(path, table, fmt=fmt, delimiter=",", header=",".join(SOLUTION_COLUMNS), comments="")
    return path


def write_track_geojson(
    tracks: dict[str, np.ndarray], reference: np.ndarray | None, path: Path
) -> Path:
    """A GeoJSON FeatureCollection: one LineString per method (``(K, 13)`` solution
    tables) and the reference (``(K_r, 3)`` ``[lat, lon, h]`` rad, rad, m) if given."""
    features = []
    for name, tab in tracks.items():
        coords = np.round(tab[:, [2, 1, 3]], 9).tolist()
        features.append(
            {
                "type": "Feature",
                "properties": {"name": name, "kind": "solution"},
                "geometry": {"type": "LineString", "coordinates": coords},
            }
        )
    if reference is not None and len(reference):
        ll = np.column_stack([np.degrees(reference[:, 1]), np.degrees(reference[:, 0])])
        features.append(
            {
                "type": "Feature",
                "properties": {"name": "reference", "kind": "reference"},
                "geometry": {
                    "type": "LineString",
                    "coordinates": np.round(np.column_stack([ll, reference[:, 2]]), 9).tolist(),
                },
            }
        )
    text = json.dumps({"type": "FeatureCollection", "features": features})
    path.write_text(text, encoding="utf-8")
    return path


def write_track_kml(
    tracks: dict[str, np.ndarray], reference: np.ndarray | None, path: Path, name: str = "ftnav"
) -> Path:
    """A KML document: one ``LineString`` Placemark per method (``(K, 13)`` solution
    tables) and the reference (``(K_r, 3)`` ``[lat, lon, h]`` rad, rad, m) if given.

    Coordinates ``lon,lat,height`` in degrees and metres with ``altitudeMode``
    ``absolute`` (the heights are the solution's ellipsoidal heights, as in
    ``solution.csv``; KML's datum is WGS 84), written to the same decimals as
    ``solution.csv``.  Standard library only (:mod:`xml.etree.ElementTree`).
    """
    from xml.etree import ElementTree as ET

    ns = "http://www.opengis.net/kml/2.2"
    ET.register_namespace("", ns)

    def el(parent: ET.Element, tag: str, text: str | None = None) -> ET.Element:
        e = ET.SubElement(parent, f"{{{ns}}}{tag}")
        if text is not None:
            e.text = text
        return e

    root = ET.Element(f"{{{ns}}}kml")
    doc = el(root, "Document")
    el(doc, "name", name)
    lines = [(m, tab[:, [2, 1, 3]], "solution") for m, tab in tracks.items()]
    if reference is not None and len(reference):
        ref = np.column_stack(
            [np.degrees(reference[:, 1]), np.degrees(reference[:, 0]), reference[:, 2]]
        )
        lines.append(("reference", ref, "reference"))
    for i, (_, _, kind) in enumerate(lines):
        style = el(doc, "Style")
        style.set("id", f"line{i}")
        ls = el(style, "LineStyle")
        el(ls, "color", "ff999999" if kind == "reference" else _KML_COLORS[i % len(_KML_COLORS)])
        el(ls, "width", "1.5" if kind == "reference" else "2")
    for i, (label, coords, kind) in enumerate(lines):
        pm = el(doc, "Placemark")
        el(pm, "name", label)
        el(pm, "description", f"{kind}: {len(coords)} epochs")
        el(pm, "styleUrl", f"#line{i}")
        ls = el(pm, "LineString")
        el(ls, "altitudeMode", "absolute")
        el(ls, "coordinates", " ".join(f"{x:.9f},{y:.9f},{h:.4f}" for x, y, h in coords))
    tree = ET.ElementTree(root)
    ET.indent(tree)
    tree.write(path, encoding="utf-8", xml_declaration=True)
    return path


#: KML line colours (aabbggrr) of the methods: matplotlib's tab10 blue, orange, green, …
_KML_COLORS = ("ffb4771f", "ff0e7fff", "ff2ca02c", "ff2827d6", "ffbd6794", "ff4b568c")


def error_state_units(names: Sequence[str]) -> list[str]:
    """The unit of each error state of :data:`ftnav.nav.error_model.STATES_18` /
    ``STATES_15`` / ``STATES_21`` (spec §8.3; ``docs/conventions.md``); ``"1"`` for a
    scale factor (``sg_*``, ``sa_*``) and a name it does not know."""
    out = []
    for s in names:
        if s.startswith("phi_") or s in ("dL", "dlam"):
            out.append("rad")
        elif s.startswith("dv_"):
            out.append("m/s")
        elif s == "dh":
            out.append("m")
        elif s.startswith("eps_"):
            out.append("rad/s")
        elif s.startswith("nabla_"):
            out.append("m/s^2")
        else:
            out.append("1")
    return out


def _measurement_unit(component: str) -> str:
    """The unit of an aid's measurement row from its name (``pos_E`` m, ``vel_x`` m/s)."""
    if component.startswith("pos"):
        return "m"
    if component.startswith("vel"):
        return "m/s"
    return "aid units"


def measurement_rows(loaded: LoadedRecording) -> list[tuple[str, str, str]]:
    """``(aid, component, unit)`` of every measurement row, aid after aid (the rows of
    :attr:`Trace.R_hat` concatenated)."""
    rows = []
    for a in loaded.recording.aids:
        comps = getattr(a.sensor, "components", None) or tuple(f"z{j}" for j in range(a.dim))
        rows += [(a.name, c, _measurement_unit(c)) for c in comps]
    return rows


def trace_dataset(loaded: LoadedRecording, traces: Mapping[str, Trace]) -> Any:
    """The per-epoch trace of a processed recording as an xarray Dataset (``trace.nc``).

    Dimensions ``method_name``, ``run`` (the batch: one run, or one per interleaved
    outage schedule), ``time`` (the filter epochs, recording time base), ``state`` (the
    error states), ``sensor`` (the aids), ``measurement`` (every aid's measurement rows)
    and ``reference_epoch``.  Variables (every one with ``units`` and ``long_name``):

    * the solution, exactly the columns of ``solution.csv`` after ``time_s``
      (``lat_deg`` … ``sigma_up_m``), at full precision;
    * ``error_state`` and ``error_state_sigma``: the fused error-state estimate (after
      the feedback correction of a closed loop, so ≈ 0 there) and its σ, per state in
      the unit of the ``state_units`` coordinate;
    * ``detector_statistic``, ``detector_threshold`` (NaN where the aid did not measure,
      was not tested, or the method has no detector), ``raw_flag``, ``fault_flag``
      (int8: 1 flagged, 0 not, −1 no detector);
    * ``beta`` (the federated sharing coefficients, NaN otherwise);
    * ``R_hat``: the diagonal of each aid's measurement noise used (adapted under VB);
    * ``aid_available`` (run, time, sensor): the aid measured at the epoch (after the
      quality selection, outages and injected outage faults);
    * ``gnss_outage`` (run, time): the primary GNSS removed by the outage schedule;
      ``fault_active`` (time, sensor): an injected fault's window of an aid;
      ``sins_fault_active`` (time): an injected fault's window of the INS itself
      (``sins:gyro-bias``);
    * ``nan_count`` (method_name, run, sensor); ``reference_lat_deg``,
      ``reference_lon_deg``, ``reference_height_m``, ``reference_time`` (the reference).
    """
    import xarray as xr

    M = METHOD_DIM
    rec = loaded.recording
    names = list(traces)
    first = traces[names[0]]
    B, K, n = first.x.shape
    N = len(rec.sensor_names)
    times = rec.t_start + rec.times
    states = list(rec.error_model.names)
    if len(states) != n:
        states += [f"x{j}" for j in range(len(states), n)]
    sol = np.stack(
        [np.stack([solution_table(traces[m], times, b, m) for b in range(B)]) for m in names]
    )
    stat = np.full((len(names), B, K, N), np.nan)
    thr = np.full((len(names), B, K, N), np.nan)
    raw = np.full((len(names), B, K, N), -1, np.int8)
    flag = np.full((len(names), B, K, N), -1, np.int8)
    beta = np.full((len(names), B, K, N), np.nan)
    avail = np.stack([np.broadcast_to(a.available, (B, K)) for a in loaded.stream.aids], -1)
    for j, m in enumerate(names):
        tr = traces[m]
        if tr.statistic is not None and tr.threshold is not None:
            tested = np.isfinite(tr.threshold) & avail
            stat[j] = np.where(tested, tr.statistic, np.nan)
            thr[j] = np.where(tested, tr.threshold, np.nan)
        if tr.raw_flag is not None:
            raw[j] = tr.raw_flag
        if tr.flag is not None:
            flag[j] = tr.flag
        if tr.beta is not None:
            beta[j] = tr.beta
    rows = measurement_rows(loaded)
    R = np.stack([np.concatenate(traces[m].R_hat, axis=-1) for m in names])
    outage = np.zeros((B, K), np.int8)
    for b, windows in enumerate(loaded.outages[:B]):
        for s0, e0 in windows:
            outage[b, (rec.times >= s0) & (rec.times < e0)] = 1
    fault = np.zeros((K, N), np.int8)
    sins_fault = np.zeros(K, np.int8)  # a fault of the INS itself is no aid's
    for f in rec.faults:
        inside = (rec.times >= f.start) & (rec.times < f.end)
        if f.sensor == SINS:
            sins_fault[inside] = 1
        else:
            fault[inside, rec.sensor_names.index(f.sensor)] = 1
    dims4 = (M, "run", "time")
    solution_meta = {
        "lat_deg": ("degrees_north", "latitude (WGS 84)"),
        "lon_deg": ("degrees_east", "longitude (WGS 84)"),
        "height_m": ("m", "ellipsoidal height"),
        "v_east_mps": ("m/s", "velocity East"),
        "v_north_mps": ("m/s", "velocity North"),
        "v_up_mps": ("m/s", "velocity Up"),
        "roll_deg": ("degree", "roll"),
        "pitch_deg": ("degree", "pitch"),
        "yaw_deg": ("degree", "heading, clockwise from North in [0, 360)"),
        "sigma_east_m": ("m", "filter's position sigma East"),
        "sigma_north_m": ("m", "filter's position sigma North"),
        "sigma_up_m": ("m", "filter's position sigma Up"),
    }
    variables: dict[str, Any] = {
        col: (dims4, sol[..., i + 1], {"units": u, "long_name": f"navigation solution: {ln}"})
        for i, (col, (u, ln)) in enumerate(solution_meta.items())
    }
    gnss = next((i for i, a in enumerate(rec.aids) if type(a.sensor).__name__ == "Gnss"), 0)
    ref_t = times[loaded.reference_index]
    ref = loaded.reference_p
    variables |= {
        "error_state": (
            dims4 + ("state",),
            np.stack([traces[m].x for m in names]),
            {
                "units": "see state_units (one unit per state)",
                "long_name": "fused error-state estimate (computed - true), after the "
                "feedback correction of a closed loop",
            },
        ),
        "error_state_sigma": (
            dims4 + ("state",),
            np.sqrt(np.maximum(np.stack([traces[m].P_diag for m in names]), 0.0)),
            {"units": "see state_units (one unit per state)", "long_name": "its sigma"},
        ),
        "detector_statistic": (
            dims4 + ("sensor",),
            stat,
            {
                "units": "1",
                "long_name": "fault detector statistic of each aid (NaN: not tested or "
                "the method has no detector)",
            },
        ),
        "detector_threshold": (
            dims4 + ("sensor",),
            thr,
            {"units": "1", "long_name": "fault detector threshold of each aid (NaN as above)"},
        ),
        "raw_flag": (
            dims4 + ("sensor",),
            raw,
            flag_attrs("fault flag before hysteresis"),
        ),
        "fault_flag": (
            dims4 + ("sensor",),
            flag,
            flag_attrs("fault flag after hysteresis"),
        ),
        "beta": (
            dims4 + ("sensor",),
            beta,
            {
                "units": "1",
                "long_name": "federated sharing coefficient of each local filter "
                "(NaN: method without sharing)",
            },
        ),
        "R_hat": (
            dims4 + ("measurement",),
            R,
            {
                "units": "square of measurement_units (per row)",
                "long_name": "diagonal of the measurement noise covariance used (adapted under VB)",
            },
        ),
        "aid_available": (
            ("run", "time", "sensor"),
            avail.astype(np.int8),
            {"units": "1", "long_name": "1: the aid measured at this epoch"},
        ),
        "gnss_outage": (
            ("run", "time"),
            outage,
            {
                "units": "1",
                "long_name": f"1: the primary GNSS ({rec.sensor_names[gnss]}) removed by "
                "the outage schedule",
            },
        ),
        "fault_active": (
            ("time", "sensor"),
            fault,
            {"units": "1", "long_name": "1: inside an injected fault's window"},
        ),
        "sins_fault_active": (
            ("time",),
            sins_fault,
            {"units": "1", "long_name": "1: inside an injected fault of the INS itself"},
        ),
        "nan_count": (
            (M, "run", "sensor"),
            np.stack([traces[m].nan_count for m in names]).astype(np.int32),
            {"units": "1", "long_name": "scheduled measurements that were NaN or inf"},
        ),
        "reference_time": (
            ("reference_epoch",),
            ref_t,
            {"units": "s", "long_name": "time of the reference epoch (recording time base)"},
        ),
        "reference_lat_deg": (
            ("reference_epoch",),
            np.degrees(ref[:, 0]),
            {"units": "degrees_north", "long_name": "reference latitude"},
        ),
        "reference_lon_deg": (
            ("reference_epoch",),
            np.degrees(ref[:, 1]),
            {"units": "degrees_east", "long_name": "reference longitude"},
        ),
        "reference_height_m": (
            ("reference_epoch",),
            ref[:, 2],
            {"units": "m", "long_name": "reference ellipsoidal height"},
        ),
    }
    none = {"units": "none"}
    coords = {
        M: (M, names, {**none, "long_name": "fusion method (recording name)"}),
        "run": (
            "run",
            np.arange(B, dtype=np.int32),
            {"units": "1", "long_name": "run of the batch (interleaved outage schedule)"},
        ),
        "time": (
            "time",
            times,
            {"units": "s", "long_name": "epoch time on the recording's own time base"},
        ),
        "state": ("state", states, {**none, "long_name": "error state name (spec 8.3)"}),
        "state_units": (
            "state",
            error_state_units(states),
            {**none, "long_name": "unit of each error state"},
        ),
        "sensor": ("sensor", list(rec.sensor_names), {**none, "long_name": "aid name"}),
        "measurement": (
            "measurement",
            [f"{a}.{c}" for a, c, _ in rows],
            {**none, "long_name": "aid.row of each measurement row"},
        ),
        "measurement_units": (
            "measurement",
            [u for _, _, u in rows],
            {**none, "long_name": "unit of each measurement row"},
        ),
        "reference_epoch": (
            "reference_epoch",
            np.asarray(loaded.reference_index, np.int32),
            {"units": "1", "long_name": "0-based index of the reference epoch along time"},
        ),
    }
    return xr.Dataset(
        variables,
        coords=coords,
        attrs={
            "recording": rec.name,
            "description": rec.description,
            "t_start_s": rec.t_start,
            "t_first_gnss_s": rec.t_origin,
            "dt_s": rec.dt,
            "fault_flag": "1 flagged, 0 not flagged, -1 method has no detector",
            "conventions": "ftnav docs/recording-format.md (Outputs); errors computed - true",
        },
    )


def write_trace_netcdf(loaded: LoadedRecording, traces: Mapping[str, Trace], path: Path) -> Path:
    """Write :func:`trace_dataset` as netCDF-3 (scipy engine, like ``estimates.nc``)."""
    trace_dataset(loaded, traces).to_netcdf(path, engine="scipy")
    return path
