"""Plausibility of a recorded IMU against physics: the unit a log was declared in.

A unit slip is silent: an accelerometer logged in g and declared m/s² still levels
(the direction of ``f̄`` is right) but the INS then falls at 9 m/s²; a gyro logged in
°/s and declared rad/s turns 57 times too fast.  Two physical references expose them
without a truth:

* **gravity** — a still IMU reads ``|f| = g(L, h)`` (normal gravity,
  :func:`ftnav.nav.earth.gravity`) up to its bias; over a drive the median ``|f|``
  stays within a few % of it (a car's accelerations add in quadrature: 0.3 g adds 4 %);
* **the GNSS course** — the rate about the vertical (the mean specific force's
  direction) equals the rate of the course ``ψ = atan2(−v_E, v_N)`` while the vehicle
  moves (a few % apart from the side slip); the fit ``ψ̇ = a + k ω_up`` over 1 s
  intervals has ``k ≈ 1`` (0.998 on the vendored drive, 0.94 on the walk, 1.16 on
  NaveGo's car), ``k ≈ π/180`` for °/s declared rad/s and ``k ≈ −1`` for a gyro
  turning the other way.  The course is the regressand: its noise (slow walking)
  leaves ``k`` unbiased.

Each check returns a :class:`Verdict`: nothing, a warning (legal but suspicious) or a
refusal, one line each.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple

import numpy as np

from ftnav.recorded.imu import ImuLog, increments

__all__ = [
    "ACCEL_UNITS",
    "Verdict",
    "course_rate_gain",
    "gyro_gain_verdict",
    "holds",
    "position_rate_verdict",
    "specific_force_verdict",
    "static_motion_verdict",
    "static_rate_verdict",
]

#: accelerometer units a slip confuses, m/s² per unit (``nav/units.py`` names)
ACCEL_UNITS = {"m/s^2": 1.0, "g": 9.80665, "mg": 9.80665e-3, "ft/s^2": 0.3048, "cm/s^2": 0.01}
#: gyro units, rad/s per unit
GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0, "deg/h": math.pi / 180.0 / 3600.0}
#: a specific force within this fraction of gravity is plausible (plus 3 σ of the bias)
F_WARN = 0.05
#: beyond this fraction (or 0.1 past the warning band) it is refused
F_REFUSE = 0.2
#: a static window is refused when more than this fraction of its GNSS fixes (and two at
#: least) move at the alignment's ``min_speed_mps`` or faster
MOVING_FRACTION = 0.05
#: the static rate refused above this (rad/s, 5.7 °/s) and 3 times the datasheet bias:
#: beyond the zero-rate offset of the worst MEMS gyros still sold for navigation
W_STATIC_MAX = 0.1


class Verdict(NamedTuple):
    """``level``: ``"ok"``, ``"warning"`` or ``"refusal"``; ``reason``: one line."""

    level: Literal["ok", "warning", "refusal"]
    reason: str = ""


def _likely(value_si: float, factor: float, units: dict[str, float], target: float) -> str | None:
    """The unit of ``units`` in which the file's numbers (``value_si / factor``) give
    ``target`` within 20 %, other than the declared one."""
    raw = value_si / factor
    for name, f in units.items():
        if not math.isclose(f, factor, rel_tol=1e-6) and abs(raw * f / target - 1.0) <= 0.2:
            return name
    return None


def specific_force_verdict(
    f_norm: float, g: float, factor: float, bias_sd: float, where: str
) -> Verdict:
    """The still (or median) specific force ``f_norm`` (m/s²) against gravity ``g``.

    ``factor`` is the declared unit in m/s² (0 for increments: no unit is named);
    ``bias_sd`` the datasheet's accelerometer bias σ (m/s²) widening the bands;
    ``where`` names the window in the message.
    """
    off = abs(f_norm / g - 1.0)
    warn = F_WARN + 3.0 * bias_sd / g
    if off <= warn:
        return Verdict("ok")
    text = (
        f"the specific force {where} is {f_norm:.3g} m/s², {f_norm / g:.3g} times the "
        f"local gravity {g:.4g} m/s²"
    )
    if off <= max(F_REFUSE, warn + 0.1):
        return Verdict("warning", f"{text}: a scale-factor error or a start that is not still?")
    unit = _likely(f_norm, factor, ACCEL_UNITS, g) if factor > 0 else None
    hint = f"is the unit {unit}?" if unit else "is the unit right, and the IMU still there?"
    return Verdict("refusal", f"{text}: {hint}")


def static_rate_verdict(w_norm: float, factor: float, bias_sd: float, static_s: float) -> Verdict:
    """The mean rate ``w_norm`` (rad/s) of a still IMU: the Earth rate plus its bias.

    Refused above :data:`W_STATIC_MAX` and 3 times ``bias_sd`` (the datasheet's bias σ
    of the three axes together, rad/s); ``factor`` is the declared unit in rad/s.
    """
    bound = max(W_STATIC_MAX, 3.0 * bias_sd)
    if w_norm <= bound:
        return Verdict("ok")
    smaller = [(f, n) for n, f in GYRO_UNITS.items() if f < factor * (1 - 1e-6)]
    fits = [n for f, n in sorted(smaller, reverse=True) if w_norm / factor * f <= bound]
    unit = fits[0] if fits else None
    hint = f"is the unit {unit}?" if unit else "is the unit right, and the IMU still there?"
    return Verdict(
        "refusal",
        f"the mean rate over the static {static_s:g} s is {w_norm:.3g} rad/s "
        f"({math.degrees(w_norm):.3g} deg/s); a still IMU reads the Earth rate "
        f"(7.3e-05 rad/s) plus its bias (at most {bound:.3g} rad/s here): {hint}",
    )


def static_motion_verdict(
    t: np.ndarray, v: np.ndarray, start: float, static_s: float, min_speed: float
) -> Verdict:
    """The GNSS fixes (times ``t``, ENU velocity ``v``) inside the static window
    ``[start, start + static_s)``: refused when more than :data:`MOVING_FRACTION` of those
    with a velocity, and two at least, move at ``min_speed`` or faster.  Levelled while
    accelerating, and with the turn rates removed as a gyro bias, the start is wrong
    whatever the filter does after it; an IMU log shifted in time against the GNSS looks
    the same."""
    inside = (t >= start) & (t < start + static_s) & np.isfinite(v[:, :2]).all(1)
    speed = np.hypot(v[inside, 0], v[inside, 1])
    fast = speed >= min_speed
    if speed.size == 0 or fast.sum() < 2 or fast.mean() <= MOVING_FRACTION:
        return Verdict("ok")
    first = float(t[inside][np.argmax(fast)] - start)
    return Verdict(
        "refusal",
        f"the GNSS moves during the static {static_s:g} s: {int(fast.sum())} of its "
        f"{speed.size} fixes there at {min_speed:g} m/s or faster (up to {speed.max():.3g} "
        f"m/s, the first {first:.3g} s into the window); the window must be still: shorten "
        "it, or check the logs' time bases (imu.time_offset_s)",
    )


#: the span (s) over which a GNSS file's displacement is compared with its velocities
POSITION_SPAN_S = 5.0


def position_rate_verdict(
    t: np.ndarray, p: np.ndarray, v: np.ndarray, min_speed: float = 1.0, radius: float = 6.371e6
) -> tuple[float, Verdict]:
    """A GNSS file's positions against its own velocities: the gain ``k`` (the median over
    spans of about :data:`POSITION_SPAN_S` s, every gap under 2 s, of the horizontal
    displacement over the integral of the horizontal velocity; NaN when fewer than 3
    spans move at ``min_speed``) and its verdict.  ``p`` is ``[L, λ, h]`` (rad, as the
    declared unit read it), ``v`` ENU m/s.  ``k`` within a factor 2 of ``π/180`` or
    ``180/π`` names the angle unit (refused); any other ``k`` outside [0.5, 2] is a
    warning (the positions' or the velocities' unit)."""
    order = np.argsort(t, kind="stable")
    t, p, v = t[order], p[order], v[order]
    ok = np.isfinite(v[:, :2]).all(1) & np.isfinite(p).all(1)
    ratios = []
    i = 0
    while i < t.size - 1:
        j = int(np.searchsorted(t, t[i] + POSITION_SPAN_S))
        if j >= t.size:
            break
        seg = slice(i, j + 1)
        if ok[seg].all() and np.all(np.diff(t[seg]) <= 2.0):
            dt = np.diff(t[seg])[:, None]
            moved = np.sum(0.5 * (v[i:j, :2] + v[i + 1 : j + 1, :2]) * dt, 0)
            dn = (p[j, 0] - p[i, 0]) * radius
            de = (p[j, 1] - p[i, 1]) * radius * math.cos(p[i, 0])
            along = float(np.hypot(*moved))
            if along >= min_speed * (t[j] - t[i]):
                ratios.append(math.hypot(de, dn) / along)
        i = j
    if len(ratios) < 3:
        return math.nan, Verdict("ok")
    k = float(np.median(ratios))
    if 0.5 <= k <= 2.0:
        return k, Verdict("ok")
    text = (
        f"the positions move {k:.3g} times as far as the file's own velocities say "
        f"(median over {len(ratios)} spans of {POSITION_SPAN_S:g} s)"
    )
    for unit, f in (("rad", 180.0 / math.pi), ("deg", math.pi / 180.0)):
        if 0.5 <= k * f <= 2.0:  # the east part scales by the cosines of two latitudes too
            return k, Verdict("refusal", f"{text}: is the latitude's and longitude's unit {unit}?")
    return k, Verdict("warning", f"{text}: check the positions' and the velocities' units")


class CourseFit(NamedTuple):
    """``ψ̇ = a + k ω_up`` over ``n`` intervals of motion turning ``turn`` rad in all;
    ``r`` the correlation."""

    k: float
    r: float
    n: int
    turn: float


def course_rate_gain(
    log: ImuLog, t: np.ndarray, v: np.ndarray, min_speed: float, span: float = 1.0
) -> CourseFit | None:
    """Fit the GNSS course rate to the gyro's vertical rate (module docstring) over
    intervals of about ``span`` s between GNSS epochs ``t`` (velocity ``v`` ENU) within
    the IMU log at which the horizontal speed is at least ``min_speed``; None when too
    few (fewer than 10 intervals)."""
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.isfinite(v[:, :2]).all(1) & (t > log.t[0]) & (t < log.t[-1])
    t, v = t[keep], v[keep]
    first = np.r_[True, np.diff(t) > 0] if t.size else np.zeros(0, bool)
    t, v = t[first], v[first]
    if t.size < 11:
        return None
    step = max(1, int(round(span / float(np.median(np.diff(t))))))
    t, v = t[::step], v[::step]
    if t.size < 11:
        return None
    up = log.accel.mean(0)
    if not np.linalg.norm(up) > 0:
        return None
    up = up / np.linalg.norm(up)
    dth, _ = increments(log, t)
    dt = np.diff(t)
    x = (dth @ up) / dt
    psi = np.arctan2(-v[:, 0], v[:, 1])
    dpsi = (np.diff(psi) + np.pi) % (2 * np.pi) - np.pi
    speed = np.hypot(v[:, 0], v[:, 1])
    m = (speed[1:] >= min_speed) & (speed[:-1] >= min_speed) & (dt <= 3.0 * span)
    if m.sum() < 10 or np.ptp(x[m]) == 0:
        return None
    x, y = x[m], dpsi[m] / dt[m]
    A = np.c_[np.ones(x.size), x]
    (_, k), *_ = np.linalg.lstsq(A, y, rcond=None)
    r = float(np.corrcoef(x, y)[0, 1]) if np.std(y) > 0 else 0.0
    return CourseFit(float(k), r, int(x.size), float(np.abs(dpsi[m]).sum()))


def holds(fit: CourseFit | None) -> bool:
    """The fit says something: ``|r|`` ≥ 0.5 over at least 90° of turns."""
    return fit is not None and abs(fit.r) >= 0.5 and fit.turn >= math.pi / 2


def gyro_gain_verdict(fit: CourseFit | None, factor: float) -> Verdict:
    """A gain ``k`` of :func:`course_rate_gain`; judged when the fit holds (``r`` ≥ 0.5
    in magnitude, at least 90° of turns): ``k`` near ``π/180`` or ``180/π`` names the unit
    (refused), ``k`` near −1 a gyro turning the other way (refused), any other ``k``
    outside [0.5, 2] is a warning."""
    if fit is None or not holds(fit):
        return Verdict("ok")
    k = fit.k
    if 0.5 <= k <= 2.0:
        return Verdict("ok")
    text = (
        f"the GNSS course turns {k:.3g} times as fast as the gyros read about the "
        f"vertical ({fit.n} intervals of motion, {math.degrees(fit.turn):.0f} deg of turns)"
    )
    for name, f in GYRO_UNITS.items():
        if not math.isclose(f, factor, rel_tol=1e-6) and 0.5 <= k * factor / f <= 2.0:
            return Verdict("refusal", f"{text}: is the unit {name}?")
    if -2.0 <= k <= -0.5:
        return Verdict(
            "refusal", f"{text}: the gyros turn the other way (is an axis or a sign flipped?)"
        )
    return Verdict(
        "warning",
        f"{text}: check the gyro's unit and axes, and the two logs' time bases "
        "(imu.time_offset_s: the logs shifted against each other also turn at other times)",
    )
