"""Measurement streams: everything the engine consumes, and nothing it must not see.

A stream is what a source of measurements delivers — a simulator
(:mod:`ftnav.sim`) or, later, a recorded log — for B runs (or one recording, B = 1):

* :class:`MeasurementStream` for a linear model: each sensor's measurement at every
  epoch and whether it exists;
* :class:`InsStream` for integrated navigation: the IMU increments with their time
  stamps, each aid's time-stamped raw output, and the initial navigation solution
  (from an alignment, or the simulator's truth plus an initial error).

A stream never holds the truth; simulators return it beside the stream, and
evaluation (:mod:`ftnav.eval`) compares the engine's trace with it afterwards.  The
``labels`` of a simulated stream are its labelled fault windows, read by the
``oracle`` detector only (an idealized benchmark); a recorded stream has none.
"""

from __future__ import annotations

from typing import NamedTuple, cast, overload

import numpy as np

from ftnav.nav.mechanization import InsState

__all__ = [
    "repeated",
    "scheduled",
    "AidStream",
    "ImuStream",
    "InsStream",
    "MeasurementStream",
    "concat_streams",
]


class MeasurementStream(NamedTuple):
    """Measurements of a linear model for B runs and K epochs.

    Attributes
    ----------
    z : per sensor (B, K, m_i) measurements (garbage where not available).
    available : (B, K, N) bool, a measurement exists (schedule and outages).
    labels : (K, N) labelled fault windows, or (K, B, N) per run (a batch that
        concatenates streams).
    """

    z: tuple[np.ndarray, ...]
    available: np.ndarray
    labels: np.ndarray

    @property
    def batch(self) -> int:
        return int(self.available.shape[0])

    @property
    def epochs(self) -> int:
        return int(self.available.shape[1])


class ImuStream(NamedTuple):
    """IMU increments: ``dtheta`` (B, n, 3) rad and ``dv`` (B, n, 3) m/s over the
    intervals of ``dt`` s ending at ``t`` (n,) s (the first starts at ``t0``)."""

    t0: float
    dt: float
    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray


class AidStream(NamedTuple):
    """One aid's raw output at its time stamps ``t`` (K_a,) s: ``raw`` (B, K_a, ...), NaN
    where there is none, and ``available`` (B, K_a) bool."""

    t: np.ndarray
    raw: np.ndarray
    available: np.ndarray


class InsStream(NamedTuple):
    """What an integrated-navigation run consumes (module docstring).

    Attributes
    ----------
    imu : the IMU increments.
    aids : each aid's measurements, in the scenario's aid order.
    start : the initial navigation solution of each run at ``imu.t0``.
    labels : (K, N) labelled fault windows per filter epoch, or (K, B, N) per run.
    """

    imu: ImuStream
    aids: tuple[AidStream, ...]
    start: InsState
    labels: np.ndarray

    @property
    def batch(self) -> int:
        return int(self.start.q.shape[0])


def _per_run(labels: np.ndarray, batch: int) -> np.ndarray:
    if labels.ndim == 3:
        return labels
    return np.broadcast_to(labels[:, None, :], (labels.shape[0], batch, labels.shape[-1]))


@overload
def concat_streams(*streams: MeasurementStream) -> MeasurementStream: ...
@overload
def concat_streams(*streams: InsStream) -> InsStream: ...
@overload
def concat_streams(*streams: MeasurementStream | InsStream) -> MeasurementStream | InsStream: ...
def concat_streams(*streams: MeasurementStream | InsStream) -> MeasurementStream | InsStream:
    """The runs of each stream in turn as one stream (the labels become per run)."""
    labels = np.concatenate([_per_run(s.labels, s.batch) for s in streams], 1)
    first = streams[0]
    if isinstance(first, MeasurementStream):
        measured = cast("tuple[MeasurementStream, ...]", streams)
        return MeasurementStream(
            tuple(np.concatenate(p) for p in zip(*(s.z for s in measured), strict=True)),
            np.concatenate([s.available for s in measured]),
            labels,
        )
    inertial = cast("tuple[InsStream, ...]", streams)
    imu = first.imu._replace(
        dtheta=np.concatenate([s.imu.dtheta for s in inertial]),
        dv=np.concatenate([s.imu.dv for s in inertial]),
    )
    aids = tuple(
        x[0]._replace(
            raw=np.concatenate([a.raw for a in x]),
            available=np.concatenate([a.available for a in x]),
        )
        for x in zip(*(s.aids for s in inertial), strict=True)
    )
    start = InsState(*(np.concatenate(u) for u in zip(*(s.start for s in inertial), strict=True)))
    return InsStream(imu, aids, start, labels)


def scheduled(stream: MeasurementStream | InsStream, steps: int) -> np.ndarray:
    """(B, steps, N) bool: the epochs each aid was due (its schedule and outages), what
    its availability is measured against (:mod:`ftnav.eval.integrity`)."""
    if isinstance(stream, MeasurementStream):
        return np.asarray(stream.available[:, :steps], bool)
    return np.stack([np.asarray(a.available[:, :steps], bool) for a in stream.aids], -1)


def repeated(values: np.ndarray, available: np.ndarray) -> np.ndarray:
    """(B, K) True where an available output equals, bit for bit, its run's previous
    available output: a frozen sensor's signature (a real output's noise never repeats
    to the last bit; a quantized one may at a standstill, where nothing is lost by
    saying so).

    ``values`` (B, K, ...) the outputs, ``available`` (B, K) bool.
    """
    B, K = available.shape
    v = values.reshape(B, K, -1)
    idx = np.where(available, np.arange(K), -1)
    last = np.maximum.accumulate(idx, axis=1)
    prev = np.concatenate([np.full((B, 1), -1), last[:, :-1]], 1)
    before = np.take_along_axis(v, np.maximum(prev, 0)[..., None], 1)
    out: np.ndarray = available & (prev >= 0) & (before == v).all(-1)
    return out
