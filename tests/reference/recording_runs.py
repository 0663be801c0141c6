"""Running a recording from the tests: load, run every method through the engine, score.

One place for what the recorded-log tests do between a recording file and its traces
(``ftnav process`` without its outputs), and for copies of the built-in drive (or another
built-in recording) with their data by absolute path.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from ftnav.engine import navigation_model
from ftnav.engine.driver import Trace, run
from ftnav.eval.montecarlo import build_filters
from ftnav.eval.recorded import reference_errors, score_recording
from ftnav.io.recording_file import LoadedRecording, load_recording
from ftnav.model.streams import scheduled
from ftnav.pipeline import reference_of
from ftnav.recordings import recording_path


def traces_of(loaded: LoadedRecording, nav_covariance: bool = False) -> dict[str, Trace]:
    """Every method of a loaded recording through the engine."""
    rec = loaded.recording
    filters = build_filters(rec, rec.system(), rec.methods)
    return run(
        navigation_model(rec), loaded.stream, filters, rec.steps, nav_covariance=nav_covariance
    )


def process(path: Path, nav_covariance: bool = False, **kw: Any):
    """``(loaded, traces, scores)`` of a recording file (``kw``: :func:`load_recording`'s),
    scored at the point the reference measures (the antenna), as ``ftnav process``."""
    loaded = load_recording(path, **kw)
    traces = traces_of(loaded, nav_covariance)
    scores = score_recording(
        loaded.recording,
        traces,
        reference_of(loaded),
        loaded.outages,
        truth=loaded.truth,
        scheduled=scheduled(loaded.stream, loaded.recording.steps),
    )
    return loaded, traces, scores


def drive_copy(
    path: Path, edit: Callable[[dict], None] | None = None, name: str = "rtklib-drive"
) -> Path:
    """The built-in drive (or recording ``name``) written to ``path`` with its data files
    by absolute path, after ``edit`` (a function changing the parsed document in place)."""
    src = recording_path(name)
    doc = tomllib.loads(src.read_text())
    doc["imu"]["file"] = str(src.parent / doc["imu"]["file"])
    for a in doc["aids"]:
        if "file" in a:
            a["file"] = str(src.parent / a["file"])
    if edit is not None:
        edit(doc)
    path.write_text(tomli_w.dumps(doc))
    return path


def horizontal(loaded: LoadedRecording, trace: Trace) -> tuple[np.ndarray, np.ndarray]:
    """(times of the reference epochs, horizontal error there) of the first run, at the
    point the reference measures (the antenna), as the scores."""
    e = reference_errors(trace.solution, reference_of(loaded))
    return loaded.recording.times[loaded.reference_index], np.hypot(e[:, 0], e[:, 1])
