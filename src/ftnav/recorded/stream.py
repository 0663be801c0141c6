"""A recording as the engine's stream: alignment, the epoch grid, aids, outages, faults.

The filter epochs are the primary GNSS's own epochs: ``t_k = t_start + k·dt`` with
``dt`` its period, so every GNSS fix is applied at its own time stamp and the IMU
increments are integrated up to it (:func:`ftnav.recorded.imu.increments`).

Initialization (:func:`align`, spec §8.5's error states start from it):

* roll and pitch from levelling the accelerometers averaged over the static window at
  the start (``f^b = C_n^b [0, 0, g]``: ``θ = asin(u_y)``, ``γ = atan2(−u_x, u_z)`` for
  the unit ``u = f̄/|f̄|``, body x right, y forward, z up);
* the gyro bias from the same window (the mean rate; the Earth rate, 15 °/h at most,
  stays in it — below a MEMS gyro's bias, above a navigation-grade one's, where
  gyro-compassing would be the better choice);
* heading from the GNSS course at the first fix, after the static window, whose
  horizontal speed reaches ``min_speed``: ``ψ = atan2(−v_E, v_N)`` (the forward axis
  along the track); position and velocity from that fix; the filter starts there.

A vehicle moving from the first sample has no static window: :func:`given` starts
from a given attitude (NaveGo's own initialization: the data set's true initial
attitude ``ini_align`` with its σ ``ini_align_err``), position and velocity from the
first GNSS fix within the IMU log, and removes no gyro bias.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ftnav.model.faults import fault_effect, hold_stuck
from ftnav.model.scenario import SINS, Fault
from ftnav.model.streams import AidStream, ImuStream, InsStream
from ftnav.nav import attitude
from ftnav.nav.attitude import euler_to_dcm
from ftnav.nav.earth import OMEGA_IE, omega_ie_n, radii
from ftnav.nav.mechanization import InsState
from ftnav.recorded.imu import ImuLog, increments

#: the faults a recorded GNSS aid can be given (:func:`gnss_raw`) and the SINS's gyro-bias
#: step (:func:`imu_with_faults`); a noise ramp has no recorded form
RECORDING_FAULT_KINDS: tuple[str, ...] = (
    "bias",
    "ramp",
    "noise-scale",
    "outage",
    "stuck",
    "gyro-bias",
)

__all__ = [
    "RECORDING_FAULT_KINDS",
    "Alignment",
    "GnssLog",
    "GridPlacement",
    "align",
    "given",
    "imu_with_faults",
    "gyrocompass",
    "gyrocompass_sigma",
    "level",
    "on_grid",
    "outage_schedule",
    "gnss_raw",
    "interleave",
    "recording_stream",
    "retime_velocity",
    "with_outages",
]


class GnssLog(NamedTuple):
    """A receiver's solution epochs.

    Attributes
    ----------
    t : (K,) s.  p : (K, 3) ``[L, λ, h]`` rad, rad, m.  v : (K, 3) ENU m/s (NaN: none).
    quality : (K,) int solution flag (RTKLIB: 1 fix, 2 float, 5 single).
    sigma : (K, 6) the file's own σ of the position E, N, U (m) and velocity E, N, U
        (m/s) per epoch (NaN: none), or None.
    """

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    quality: np.ndarray
    sigma: np.ndarray | None = None


class Alignment(NamedTuple):
    """The initial solution (module docstring).

    Attributes
    ----------
    t : s, the start (a GNSS epoch).  euler : ``[θ, γ, ψ]`` rad.
    p, v : the start fix's position and velocity.  gyro_bias : (3,) rad/s removed from
    the log (the static mean; less the Earth rate after gyrocompassing).
    static : (samples, mean specific force norm m/s²) of the static window.
    heading_from : ``"gnss-course"``, ``"gyrocompass"`` or ``"given"``.
    heading_sigma : rad, σ of the gyrocompass heading (NaN otherwise).
    """

    t: float
    euler: np.ndarray
    p: np.ndarray
    v: np.ndarray
    gyro_bias: np.ndarray
    static: tuple[int, float]
    heading_from: str = "gnss-course"
    heading_sigma: float = float("nan")


def level(f_mean: np.ndarray) -> tuple[float, float]:
    """Pitch θ and roll γ (rad) from the mean specific force of a still IMU."""
    u = np.asarray(f_mean, float) / np.linalg.norm(f_mean)
    return float(np.arcsin(np.clip(u[1], -1.0, 1.0))), float(np.arctan2(-u[0], u[2]))


def gyrocompass(f_mean: np.ndarray, w_mean: np.ndarray) -> tuple[float, float, float]:
    """Pitch θ, roll γ and heading ψ (rad) of a still IMU from its mean specific force
    and mean angular rate (the Earth rate): levelled, the rate reads
    ``C_b^n(θ, γ, 0) ω = R_z(ψ)ᵀ [0, Ω cos L, Ω sin L]``, whose horizontal part is
    ``Ω cos L [sin ψ, cos ψ]`` (ENU, ψ counter-clockwise), so ``ψ = atan2(ω_x, ω_y)``."""
    theta, gamma = level(f_mean)
    w_l = euler_to_dcm(np.array([theta, gamma, 0.0])) @ np.asarray(w_mean, float)
    return theta, gamma, float(np.arctan2(w_l[0], w_l[1]))


def gyrocompass_sigma(lat: float, bias_sd: float, arw: float, seconds: float) -> float:
    """σ (rad) of the gyrocompass heading: the horizontal gyro error (the bias σ and the
    ARW averaged over ``seconds``, rad/s and rad/√s) over the Earth rate's horizontal
    part ``Ω cos L``."""
    return float(np.hypot(bias_sd, arw / np.sqrt(seconds)) / (OMEGA_IE * np.cos(lat)))


def align(
    imu: ImuLog,
    gnss: GnssLog,
    static_s: float,
    min_speed: float,
    gyrocompass_sigma_rad: float | None = None,
) -> Alignment:
    """The initial solution from the static window and the first moving fix, or, with
    ``gyrocompass_sigma_rad`` (the predicted σ of :func:`gyrocompass_sigma`), from the
    static window alone: heading by gyrocompassing, the filter starting at the first fix
    after the window, the gyro bias the static mean less the Earth rate.

    Raises
    ------
    ValueError : ``"alignment.static_s: ..."`` when the window holds fewer than 10 IMU
        samples; ``"alignment.min_speed_mps: ..."`` when no fix after it moves that fast;
        ``"alignment.heading: ..."`` when the GNSS has no velocity to start from (the
        start fix's, or any for the course).
    """
    w = imu.t < imu.t[0] + static_s
    if w.sum() < 10:
        raise ValueError(f"alignment.static_s: {int(w.sum())} IMU samples in {static_s:g} s")
    f_mean = imu.accel[w].mean(0)
    theta, gamma = level(f_mean)
    if gyrocompass_sigma_rad is not None:
        after = np.flatnonzero(gnss.t >= imu.t[0] + static_s)
        if after.size == 0:
            raise ValueError("alignment.static_s: no GNSS fix after the static window")
        k = int(after[0])
        if not np.isfinite(gnss.v[k]).all():
            raise ValueError(
                f"alignment.heading: the start fix after the static window (t = "
                f"{gnss.t[k]:.3f} s) has no velocity: the initial velocity is unknown (give "
                "the GNSS file's velocity columns)"
            )
        w_mean = imu.gyro[w].mean(0)
        theta, gamma, psi = gyrocompass(f_mean, w_mean)
        C_bn = euler_to_dcm(np.array([theta, gamma, psi]))
        earth = C_bn.T @ omega_ie_n(gnss.p[k, 0])
        return Alignment(
            float(gnss.t[k]),
            np.array([theta, gamma, psi]),
            gnss.p[k].copy(),
            gnss.v[k].copy(),
            w_mean - earth,
            (int(w.sum()), float(np.linalg.norm(f_mean))),
            "gyrocompass",
            float(gyrocompass_sigma_rad),
        )
    if not np.isfinite(gnss.v).all(1).any():
        raise ValueError(
            "alignment.heading: the GNSS has no velocity: the heading from the GNSS course "
            "and the initial velocity need it (give the file's velocity columns)"
        )
    speed = np.hypot(gnss.v[:, 0], gnss.v[:, 1])
    moving = np.flatnonzero((gnss.t >= imu.t[0] + static_s) & (speed >= min_speed))
    if moving.size == 0:
        raise ValueError(
            f"alignment.min_speed_mps: no GNSS fix after the static window moves at "
            f"{min_speed:g} m/s or more (the heading comes from the GNSS course)"
        )
    k = int(moving[0])
    psi = float(np.arctan2(-gnss.v[k, 0], gnss.v[k, 1]))
    return Alignment(
        float(gnss.t[k]),
        np.array([theta, gamma, psi]),
        gnss.p[k].copy(),
        gnss.v[k].copy(),
        imu.gyro[w].mean(0),
        (int(w.sum()), float(np.linalg.norm(f_mean))),
    )


def given(imu: ImuLog, gnss: GnssLog, euler: np.ndarray) -> Alignment:
    """The initial solution of a vehicle moving from the start (module docstring):
    attitude ``euler`` ``[θ, γ, ψ]`` rad, position and velocity from the first GNSS fix
    at or after the first IMU sample; no gyro bias removed, no static window.

    Raises
    ------
    ValueError : ``"alignment.mode: ..."`` when no GNSS fix lies within the IMU log.
    """
    within = np.flatnonzero((gnss.t >= imu.t[0]) & (gnss.t < imu.t[-1]))
    if within.size == 0:
        raise ValueError("alignment.mode: no GNSS fix within the IMU log to start from")
    k = int(within[np.argmin(gnss.t[within])])
    v = gnss.v[k].copy()
    if not np.isfinite(v).all():
        raise ValueError(
            f"alignment.mode: the first GNSS fix (t = {gnss.t[k]:.3f} s) has no velocity "
            "to start from"
        )
    return Alignment(
        float(gnss.t[k]),
        np.asarray(euler, float).copy(),
        gnss.p[k].copy(),
        v,
        np.zeros(3),
        (0, float("nan")),
        "given",
    )


@dataclass(frozen=True, slots=True)
class GridPlacement:
    """Epochs of an aid placed on the filter grid: index per kept epoch, and counts."""

    index: np.ndarray
    kept: np.ndarray
    off_grid: int
    duplicated: int
    unsorted: int


def on_grid(t: np.ndarray, t0: float, dt: float, steps: int, tol: float = 1e-3) -> GridPlacement:
    """Place time stamps on the epochs ``t0 + k·dt`` (k = 1..steps).

    A stamp more than ``tol`` s from every epoch is dropped (off grid); a second stamp
    on the same epoch is dropped (duplicated); stamps out of order are sorted (counted).
    """
    order = np.argsort(t, kind="stable")
    unsorted = int(np.sum(order != np.arange(t.size)))
    k = np.rint((t - t0) / dt).astype(np.int64)
    ok = (np.abs(t - (t0 + k * dt)) <= tol) & (k >= 1) & (k <= steps)
    in_range = (k >= 1) & (k <= steps)
    off = int(np.sum(in_range & ~ok))
    kept = np.zeros(t.size, bool)
    seen: set[int] = set()
    dup = 0
    for i in order:
        if not ok[i]:
            continue
        if int(k[i]) in seen:
            dup += 1
            continue
        seen.add(int(k[i]))
        kept[i] = True
    return GridPlacement(k[kept] - 1, np.flatnonzero(kept), off, dup, unsorted)


def outage_schedule(
    length: float, every: float, start: float, last: float, margin: float = 30.0
) -> list[tuple[float, float]]:
    """GNSS outages ``[s, s + length)`` for ``s = start, start + every, …`` (seconds after
    the first GNSS epoch), every one ending at least ``margin`` s before ``last``."""
    if length <= 0 or every <= 0:
        raise ValueError("--outage-length and --outage-every must be > 0")
    out = []
    s = start
    while s + length <= last - margin + 1e-9:
        out.append((s, s + length))
        s += every
    return out


def interleave(
    outages: Sequence[tuple[float, float]], every: float, min_gap: float = 30.0
) -> list[list[tuple[float, float]]]:
    """The outages of a schedule split into runs that leave ``min_gap`` s of GNSS between
    two outages of one run: ``n = ⌈(length + min_gap)/every⌉`` interleaved schedules
    (one when the outages are short against their spacing), outage i in run ``i mod n``."""
    if not outages:
        return [[]]
    length = outages[0][1] - outages[0][0]
    n = max(1, math.ceil((length + min_gap) / every - 1e-9))
    return [list(outages[g::n]) for g in range(min(n, len(outages)))]


def with_outages(
    stream: InsStream,
    aid: int | Sequence[int],
    times: np.ndarray,
    runs: Sequence[Sequence[tuple[float, float]]],
) -> InsStream:
    """The one-run ``stream`` as a batch of ``len(runs)`` runs, the aid(s) ``aid`` (every
    aid of one receiver: its position and its velocity aid) removed over each run's outage
    windows ``[s, e)`` (times of the epochs ``times``)."""
    G = len(runs)
    removed = {aid} if isinstance(aid, int) else set(aid)

    def tile(a: np.ndarray) -> np.ndarray:
        return np.repeat(a, G, axis=0)

    def cut(x: AidStream) -> AidStream:
        raw, ok = tile(x.raw), tile(x.available)
        for g, windows in enumerate(runs):
            for s0, e0 in windows:
                w = (times >= s0) & (times < e0)
                raw[g, w] = np.nan
                ok[g, w] = False
        return AidStream(x.t, raw, ok)

    aids = tuple(
        cut(x) if i in removed else AidStream(x.t, tile(x.raw), tile(x.available))
        for i, x in enumerate(stream.aids)
    )
    imu = stream.imu._replace(dtheta=tile(stream.imu.dtheta), dv=tile(stream.imu.dv))
    start = InsState(*(tile(x) for x in stream.start))
    return InsStream(imu, aids, start, stream.labels)


def retime_velocity(log: GnssLog, offset: float) -> GnssLog:
    """The receiver's velocities moved onto its position stamps.

    A velocity stamped ``t`` describes the motion at ``t + offset`` (RTKLIB's Doppler
    velocities lag its positions: ``offset < 0``); the velocity at each position stamp
    ``t`` is the linear interpolation of the velocities at ``t − offset`` (held at the
    ends).  ``offset = 0`` returns the log unchanged.
    """
    if offset == 0.0 or log.t.size < 2:
        return log
    order = np.argsort(log.t, kind="stable")
    t = log.t[order]
    v = np.empty_like(log.v)
    for j in range(3):
        v[order, j] = np.interp(t - offset, t, log.v[order, j])
    return log._replace(v=v)


def imu_with_faults(log: ImuLog, faults: Sequence[Fault]) -> ImuLog:
    """The IMU log with the SINS's ``gyro-bias`` faults added: each fault's (3,) body
    rate (rad/s, x right, y forward, z up) on every sample whose stamp (the end of its
    interval) lies in ``[start, end)``, as the simulation adds it to its increments
    (:mod:`ftnav.sim.ins`).  ``start``/``end`` on the log's time base; the other faults
    are the aids' (:func:`gnss_raw`).  The log is not changed in place."""
    steps = [f for f in faults if f.sensor == SINS and f.kind == "gyro-bias"]
    if not steps:
        return log
    gyro = log.gyro.copy()
    for f in steps:
        window = (log.t >= f.start) & (log.t < f.end)
        gyro[window] += np.asarray(f.magnitude, float)
    return log._replace(gyro=gyro)


def gnss_raw(
    gnss: GnssLog, faults: Sequence[Fault], name: str, sigma: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The receiver's ``[L, λ, h, v_E, v_N, v_U]`` (K, 6) with the injected faults, and
    the fault labels (K,).  A fault's magnitude is in metres E, N, U, m/s E, N, U.

    A ``noise-scale`` fault of factor ``s`` makes the noise σ of each value ``s`` times
    ``sigma`` (K, 6), the σ the filter assumes (E, N, U m, m/s): the recording already
    holds noise of that σ, so independent white Gaussian noise of σ ``sigma·√(s² − 1)``
    is added (overlapping windows: the product of their factors).  The draws come from
    a generator seeded by the aid's name and its noise windows, so a run is reproducible
    and two aids' noise is independent.
    """
    effect = fault_effect(faults, name, gnss.t, 6)
    extra = np.sqrt(np.maximum(effect.scale**2 - 1.0, 0.0))
    offset = effect.offset
    if np.any(extra > 0):
        if sigma is None:
            raise ValueError(f"{name}: a noise-scale fault needs the aid's σ")
        windows = [(f.start, f.end) for f in faults if f.sensor == name and f.kind == "noise-scale"]
        seed = zlib.crc32(f"{name}:{windows!r}".encode())
        draws = np.random.default_rng(seed).standard_normal((gnss.t.size, 6))
        offset = offset + draws * np.broadcast_to(sigma, offset.shape) * extra
    RM, RN = radii(gnss.p[:, 0], gnss.p[:, 2])
    p = gnss.p.copy()
    p[:, 0] += offset[:, 1] / RM
    p[:, 1] += offset[:, 0] / (RN * np.cos(gnss.p[:, 0]))
    p[:, 2] += offset[:, 2]
    raw = np.concatenate([p, gnss.v + offset[:, 3:]], 1)
    raw = hold_stuck(raw[None], effect)[0]
    raw[effect.outage] = np.nan
    return raw, effect.label


def recording_stream(
    imu: ImuLog,
    start: Alignment,
    dt: float,
    steps: int,
    samples_per_epoch: int,
    aids: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]],
) -> InsStream:
    """The engine's stream of one recording (a batch of one run).

    ``aids`` are per aid ``(epoch index (K_a,), raw (K_a, …), labels (K_a,))`` of the
    epochs it has (:func:`on_grid`); the other epochs have no measurement.
    """
    T = dt / samples_per_epoch
    grid = start.t + T * np.arange(steps * samples_per_epoch + 1)
    dth, dv = increments(imu, grid)
    imu_stream = ImuStream(start.t, T, grid[1:], dth[None], dv[None])
    times = start.t + dt * np.arange(1, steps + 1)
    streams, labels = [], np.zeros((steps, len(aids)), bool)
    for i, (index, raw, lab) in enumerate(aids):
        full = np.full((steps,) + raw.shape[1:], np.nan)
        full[index] = raw
        ok = np.isfinite(full.reshape(steps, -1)).all(-1)
        streams.append(AidStream(times, full[None], ok[None]))
        labels[index, i] = lab
    q = attitude.euler_to_quat(start.euler)[None]
    solution = InsState(q, start.v[None], start.p[None], np.zeros((1, 3)))
    return InsStream(imu_stream, tuple(streams), solution, labels)
