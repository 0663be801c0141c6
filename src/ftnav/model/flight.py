"""Flight profiles: a start state and declarative segments (spec §10).

The description the trajectory generator (:func:`ftnav.sim.trajectory.generate`)
turns into truth and ideal IMU increments; validated on construction
(:func:`check_profile`), so an impossible flight is refused before anything runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["MAX_BANK_DEG", "MAX_PITCH_DEG", "Profile", "Segment", "Start", "check_profile"]

#: largest bank angle of a coordinated turn (load factor 1/cos 75° ≈ 3.9 g)
MAX_BANK_DEG = 75.0
#: largest |pitch| (the Euler angles are singular at ±90°)
MAX_PITCH_DEG = 85.0


@dataclass(frozen=True, slots=True)
class Segment:
    """One motion segment (spec §10.1), SI units (s, rad/s, m/s²).

    ``yaw_rate`` None means a coordinated turn, ``ψ̇ = −g tan γ / V``.
    """

    duration: float
    pitch_rate: float = 0.0
    roll_rate: float = 0.0
    yaw_rate: float | None = 0.0
    accel: float = 0.0
    label: str = ""


@dataclass(frozen=True, slots=True)
class Start:
    """Initial state: position ``[L, λ, h]`` (rad, rad, m), speed (m/s), ``[θ, γ, ψ]`` (rad)."""

    position: tuple[float, float, float]
    speed: float
    euler: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class Profile:
    """A named flight profile: IMU rate (Hz), start and segments."""

    name: str
    imu_rate: float
    start: Start
    segments: tuple[Segment, ...]

    def __post_init__(self) -> None:
        check_profile(self)

    @property
    def duration(self) -> float:
        return float(sum(s.duration for s in self.segments))

    @property
    def dt(self) -> float:
        return 1.0 / self.imu_rate


def check_profile(pr: Profile) -> None:
    """Raise ``ValueError('<field>: <reason>')`` for a profile that cannot be flown."""
    if not (math.isfinite(pr.imu_rate) and pr.imu_rate > 0):
        raise ValueError(f"imu_rate_hz: must be a positive rate, got {pr.imu_rate!r}")
    L, lam, h = pr.start.position
    if not all(math.isfinite(x) for x in (L, lam, h, pr.start.speed, *pr.start.euler)):
        raise ValueError("start: contains NaN or inf")
    if abs(L) > math.pi / 2:
        raise ValueError(f"start.lat_deg: latitude must be within ±90°, got {math.degrees(L):g}")
    if pr.start.speed < 0:
        raise ValueError(f"start.speed_m_s: must be >= 0, got {pr.start.speed:g}")
    if not pr.segments:
        raise ValueError("segments: must have at least 1 entry")
    V, (theta, gamma, _) = pr.start.speed, pr.start.euler
    if abs(theta) > math.radians(MAX_PITCH_DEG):
        raise ValueError(f"start.pitch_deg: |pitch| must be <= {MAX_PITCH_DEG:g}°")
    if abs(gamma) > math.radians(MAX_BANK_DEG):
        raise ValueError(
            f"start.roll_deg: bank angle beyond the {MAX_BANK_DEG:g}° that can be flown"
        )
    for i, s in enumerate(pr.segments):
        where = f"segments[{i}]"
        rates = (s.pitch_rate, s.roll_rate, s.accel) + (() if s.yaw_rate is None else (s.yaw_rate,))
        if not (math.isfinite(s.duration) and all(math.isfinite(r) for r in rates)):
            raise ValueError(f"{where}: contains NaN or inf")
        if s.duration <= 0:
            raise ValueError(f"{where}.duration_s: must be > 0, got {s.duration:g}")
        n = s.duration * pr.imu_rate
        if abs(n - round(n)) > 1e-6:
            raise ValueError(
                f"{where}.duration_s: must be a whole number of IMU periods "
                f"(1/{pr.imu_rate:g} s), got {s.duration:g}"
            )
        V_end = V + s.accel * s.duration
        if V_end < -1e-9:
            raise ValueError(
                f"{where}.accel_m_s2: speed would become negative "
                f"({V_end:.3g} m/s at the end of the segment)"
            )
        theta_end = theta + s.pitch_rate * s.duration
        if abs(theta_end) > math.radians(MAX_PITCH_DEG):
            raise ValueError(
                f"{where}.pitch_rate_deg_s: pitch would reach "
                f"{math.degrees(theta_end):.1f}°, beyond ±{MAX_PITCH_DEG:g}°"
            )
        gamma_end = gamma + s.roll_rate * s.duration
        if abs(gamma_end) > math.radians(MAX_BANK_DEG):
            raise ValueError(
                f"{where}.roll_rate_deg_s: bank angle would reach "
                f"{math.degrees(gamma_end):.1f}°, beyond the {MAX_BANK_DEG:g}° "
                "that can be flown"
            )
        if s.yaw_rate is None:
            if s.roll_rate != 0:
                raise ValueError(
                    f"{where}.yaw_rate_deg_s: a coordinated turn needs "
                    "roll_rate_deg_s = 0 (roll in and out in separate segments)"
                )
            if min(V, V_end) < 1.0:
                raise ValueError(
                    f"{where}.yaw_rate_deg_s: a coordinated turn needs a speed "
                    f"of at least 1 m/s, got {min(V, V_end):.3g} m/s"
                )
        V, theta, gamma = max(V_end, 0.0), theta_end, gamma_end
