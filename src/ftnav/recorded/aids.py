"""The aids of a recording as plug-ins: one registry line per aid type (issue 22).

A recording's ``[[aids]]`` table names its ``type``; the GNSS receiver (the primary aid:
it times the filter epochs, aligns the heading and is the reference) is read by
:mod:`ftnav.io.recording_file`, every other type is a :class:`RecordingAid` found in
:data:`RECORDING_AIDS`.  A plug-in has its own settings model (pydantic, validated once
at the boundary; ``ftnav schema --recording`` documents it) and ``prepare``: from the
validated settings and the recording's epochs (:class:`AidContext`) it returns the
sensor model and the aid's readings on the filter grid (:class:`PreparedAid`).

A new aid for recordings is its sensor model (:mod:`ftnav.sensors`, with ``measure``:
spec §8.6) and a plug-in here, plus one line in :data:`RECORDING_AIDS`.  An aid with a
log of its own reads it through ``AidContext.read_columns`` (the boundary's strict reader,
errors with file:line), so this module parses nothing itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from ftnav.recorded.imu import ImuLog, stationary
from ftnav.sensors.base import AidingSensor
from ftnav.sensors.vehicle import Nhc, Zupt

__all__ = [
    "RECORDING_AIDS",
    "AidContext",
    "ColumnReader",
    "NhcSettings",
    "PreparedAid",
    "RecordingAid",
    "ZuptSettings",
]

_DEG = math.pi / 180.0


class ColumnReader(Protocol):
    """The boundary's strict reader of an aid's own log (:class:`AidContext`)."""

    def __call__(
        self, file: str, columns: Sequence[str | int], header: bool = True, delimiter: str = ","
    ) -> np.ndarray:
        """(rows, len(columns)) float: ``columns`` (names, or 0-based numbers) of ``file``."""
        ...


class AidContext(NamedTuple):
    """What a plug-in may read to place its aid on the filter grid.

    Attributes
    ----------
    name : the aid's name (``name``, else its type).
    dt : filter period, s.
    times : (K,) the filter epochs' times on the recording's time base, s.
    primary : the epochs (0-based) of the primary GNSS's period: a constraint applies
        there, not more often (its error is correlated over that period; applying it at
        every epoch would overweight it).
    log : the IMU log (the static gyro bias removed).
    read_columns : ``read_columns(file, columns, header=True, delimiter=",") -> (rows, n)``:
        an aid's own log, read by the boundary's strict reader (the file relative to the
        recording file; errors with file:line).
    """

    name: str
    dt: float
    times: np.ndarray
    primary: np.ndarray
    log: ImuLog
    read_columns: ColumnReader | None = None


@dataclass(frozen=True, slots=True)
class PreparedAid:
    """An aid ready for the stream: its sensor model, the epochs it measures (0-based),
    its readings there (rows, dim), which of them an injected fault altered (rows,), and
    the counts reported in ``metrics.json`` (``data.<name>``)."""

    sensor: AidingSensor
    index: np.ndarray
    raw: np.ndarray
    labels: np.ndarray
    counts: Mapping[str, Any]


class RecordingAid(Protocol):
    """An aid type of recordings (module docstring)."""

    @property
    def settings(self) -> type[BaseModel]:
        """The pydantic model of the aid's own keys."""
        ...

    def prepare(self, settings: Any, ctx: AidContext) -> PreparedAid:
        """The sensor model and the aid's readings on the filter grid."""
        ...


_STRICT = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


class NhcSettings(BaseModel):
    """``type = "nhc"``: the non-holonomic constraint of a wheeled vehicle (no lateral and
    no vertical body velocity), applied at the primary GNSS's epochs."""

    model_config = _STRICT
    sigma_m_s: float = Field(default=0.1, gt=0, description="σ of each row, m/s")
    gate_probability: float = Field(
        default=1e-3, ge=0, lt=1, description="innovation gate (0: none)"
    )
    lever_arm_m: list[float] = Field(
        default=[0.0, 0.0, 0.0],
        min_length=3,
        max_length=3,
        description="the point the constraint holds for (a car's rear axle centre) from "
        "the IMU, m, body frame right, forward, up; 0: the IMU (sensors/vehicle.py)",
    )


class ZuptSettings(BaseModel):
    """``type = "zupt"``: a zero-velocity update wherever the IMU is still (the spread of
    its samples within ±``window_s`` below both thresholds)."""

    model_config = _STRICT
    sigma_m_s: float = Field(default=0.02, gt=0, description="σ of each row, m/s")
    gate_probability: float = Field(
        default=1e-3, ge=0, lt=1, description="innovation gate (0: none)"
    )
    window_s: float = Field(
        default=0.5, gt=0, description="stationarity half-window (the span is ±window_s)"
    )
    accel_std_mps2: float = Field(default=0.25, gt=0, description="accel std threshold")
    gyro_std_dps: float = Field(default=0.25, gt=0, description="gyro std threshold")


def _constraint(
    cls: type[Nhc] | type[Zupt],
    settings: NhcSettings | ZuptSettings,
    ctx: AidContext,
    **own: Any,
) -> Nhc | Zupt:
    """A vehicle constraint's sensor model from its settings (``own``: its class's own)."""
    return cls(
        name=ctx.name,
        dt=ctx.dt,
        sigma_m_s=settings.sigma_m_s,
        gate_probability=settings.gate_probability,
        **own,
    )


def _no_readings(sensor: AidingSensor, index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((index.size, sensor.dim)), np.zeros(index.size, bool)


class _NhcAid:
    settings = NhcSettings

    def prepare(self, settings: NhcSettings, ctx: AidContext) -> PreparedAid:
        arm = (settings.lever_arm_m[0], settings.lever_arm_m[1], settings.lever_arm_m[2])
        sensor = _constraint(Nhc, settings, ctx, lever_arm_m=arm)
        return PreparedAid(sensor, ctx.primary, *_no_readings(sensor, ctx.primary), {})


class _ZuptAid:
    settings = ZuptSettings

    def prepare(self, settings: ZuptSettings, ctx: AidContext) -> PreparedAid:
        sensor = _constraint(Zupt, settings, ctx)
        rest = stationary(
            ctx.log,
            ctx.times[ctx.primary],
            settings.window_s,
            settings.accel_std_mps2,
            settings.gyro_std_dps * _DEG,
        )
        index = ctx.primary[rest]
        counts = {"stationary_epochs": int(index.size)}
        return PreparedAid(sensor, index, *_no_readings(sensor, index), counts)


#: every aid type of a recording besides the GNSS receiver: a new one is one line here
RECORDING_AIDS: dict[str, RecordingAid] = {
    "nhc": _NhcAid(),
    "zupt": _ZuptAid(),
}
