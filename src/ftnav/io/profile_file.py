"""Flight-profile files (TOML): validated with pydantic, returned as a frozen
:class:`ftnav.sim.trajectory.Profile` (spec §10.1).  Format: ``docs/scenario-format.md``
("Flight profiles").  Errors are one-line :class:`ScenarioError` s, ``<field>: <reason>``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ValidationError

from ftnav.io.common import STRICT, ScenarioError, number, read_toml, to_scenario_error
from ftnav.model.flight import Profile, Segment, Start
from ftnav.scenarios import builtin_profile_names, builtin_profile_path

__all__ = ["load_profile", "parse_profile", "resolve_profile"]


class StartFile(BaseModel):
    """``[start]``: initial position, speed and attitude (degrees, metres, m/s)."""

    model_config = STRICT
    lat_deg: float = number("latitude (deg)", ge=-90.0, le=90.0)
    lon_deg: float = number("longitude (deg)")
    h_m: float = number("height above the ellipsoid (m)")
    speed_m_s: float = number("speed along the velocity direction (m/s)", ge=0.0, default=0.0)
    pitch_deg: float = number("pitch θ (deg)", default=0.0)
    roll_deg: float = number("roll γ, right wing down positive (deg)", default=0.0)
    heading_deg: float = number("heading clockwise from North (deg)", default=0.0)


class SegmentFile(BaseModel):
    """``[[segments]]``: constant commands for ``duration_s`` seconds."""

    model_config = STRICT
    label: str = ""
    duration_s: float = number("duration (s), a whole number of IMU periods", gt=0.0)
    pitch_rate_deg_s: float = number("pitch rate θ̇ (deg/s)", default=0.0)
    roll_rate_deg_s: float = number("roll rate γ̇ (deg/s)", default=0.0)
    yaw_rate_deg_s: float | Literal["coordinated"] = 0.0
    accel_m_s2: float = number("along-track acceleration (m/s²)", default=0.0)


class ProfileFile(BaseModel):
    """A flight profile: IMU rate, start state and motion segments."""

    model_config = STRICT
    name: str
    imu_rate_hz: float = number("IMU sample rate (Hz)", gt=0.0, default=100.0)
    start: StartFile
    segments: list[SegmentFile]


def parse_profile(data: Mapping[str, Any], origin: str = "<profile>") -> Profile:
    """Validate a parsed profile dictionary and build the :class:`Profile`.

    Raises
    ------
    ScenarioError : the first problem, ``<field path>: <reason>``; includes segments
        that cannot be flown (negative speed, bank beyond the limit, ...).
    """
    try:
        f = ProfileFile.model_validate(dict(data))
    except ValidationError as exc:
        raise to_scenario_error(exc, origin) from None
    d = math.radians
    for i, s in enumerate(f.segments):
        if isinstance(s.yaw_rate_deg_s, float) and not math.isfinite(s.yaw_rate_deg_s):
            raise ScenarioError(f"segments[{i}].yaw_rate_deg_s", "is NaN or inf", origin)
    start = Start(
        (d(f.start.lat_deg), d(f.start.lon_deg), f.start.h_m),
        f.start.speed_m_s,
        (d(f.start.pitch_deg), d(f.start.roll_deg), -d(f.start.heading_deg)),
    )
    segments = tuple(
        Segment(
            s.duration_s,
            d(s.pitch_rate_deg_s),
            d(s.roll_rate_deg_s),
            None if s.yaw_rate_deg_s == "coordinated" else d(s.yaw_rate_deg_s),
            s.accel_m_s2,
            s.label,
        )
        for s in f.segments
    )
    try:
        return Profile(f.name, f.imu_rate_hz, start, segments)
    except ValueError as exc:
        path, _, reason = str(exc).partition(": ")
        raise ScenarioError(path, reason, origin) from None


def load_profile(source: str | Path) -> Profile:
    """Read and validate a profile TOML file."""
    return parse_profile(read_toml(source), origin=str(source))


def resolve_profile(name_or_path: str) -> Profile:
    """A built-in profile by name (``seed001``, ``seed002``) or a TOML file path."""
    if not name_or_path.strip():  # Path("") is the current folder
        raise ScenarioError("PROFILE", "an empty name; give a built-in profile or a file")
    if name_or_path in builtin_profile_names():
        return load_profile(builtin_profile_path(name_or_path))
    if not name_or_path.endswith(".toml") and not Path(name_or_path).exists():
        raise ScenarioError(
            "PROFILE",
            f"unknown profile {name_or_path!r} (built-in: "
            f"{', '.join(builtin_profile_names())}; or a .toml file)",
        )
    return load_profile(name_or_path)
