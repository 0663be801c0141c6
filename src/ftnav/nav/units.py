"""Datasheet units to SI, white-noise PSD ↔ σ, Gauss-Markov intensity (spec §8.3, §8.4).

Every converter is a plain function whose name carries the unit it reads
(``deg_per_h(0.1)`` is 0.1 °/h in rad/s); ``to_*`` functions go back.  They
accept scalars or arrays and never check signs, since a fixed bias may be
negative.  SI units inside ftnav: rad, rad/s, m/s², s, m, m/s, and for random
walks rad/√s (angle) and m/s/√s (velocity).

``g`` in a datasheet unit (mg, µg, µg/√Hz) is the **standard gravity**
:data:`STANDARD_GRAVITY` = 9.80665 m/s² (CGPM 1901), never the local gravity
of :func:`ftnav.nav.earth.gravity`: it is a unit, not a physical field.

White noise (spec §8.3).  A continuous white noise of intensity ``q`` (the
two-sided PSD, unit²·s = unit²/Hz) sampled as averages over ``dt`` has
``σ = √(q/dt)``; its integral over ``dt`` has standard deviation ``√(q·dt)``.
An angle random walk ``N`` (rad/√s) is ``√q`` of the gyro rate noise, so
``1 °/√h = 60 °/h/√Hz``; a velocity random walk likewise for the accelerometer.
Datasheets that quote a one-sided PSD give ``2q``.

Gauss-Markov (spec §8.3, §8.4).  A first-order process with steady-state
standard deviation σ and correlation time τ, ``ḃ = −b/τ + w``, has driving
intensity ``q = 2σ²/τ`` (:func:`markov_q`).

:func:`parse_quantity` reads ``"<number> <unit>"`` strings (as a TOML table
gives them) for one expected unit family and raises a one-line
``ValueError`` that starts with the field name when the unit belongs to
another family, is unknown, or the value is not finite.
"""

from __future__ import annotations

import math
import numbers
import re
from typing import Literal, overload

import numpy as np

from ftnav.types import Array, ArrayLike, FloatOrArray

__all__ = [
    "STANDARD_GRAVITY",
    "FAMILIES",
    "deg_per_h",
    "deg_per_s",
    "deg_per_sqrt_h",
    "deg_per_h_per_sqrt_hz",
    "standard_g",
    "milli_g",
    "micro_g",
    "micro_g_per_sqrt_hz",
    "m_per_s_per_sqrt_h",
    "ppm",
    "percent",
    "arcsec",
    "arcmin",
    "m_per_h",
    "hours",
    "to_deg_per_h",
    "to_deg_per_s",
    "to_deg_per_sqrt_h",
    "to_milli_g",
    "to_micro_g",
    "to_m_per_s_per_sqrt_h",
    "to_ppm",
    "to_arcsec",
    "to_arcmin",
    "to_m_per_h",
    "psd_to_sigma",
    "sigma_to_psd",
    "markov_q",
    "parse_quantity",
]

STANDARD_GRAVITY = 9.80665  #: standard gravity g₀ (m/s²), the unit "g" of datasheets
_DEG = math.pi / 180.0
_HOUR = 3600.0
_SQRT_HOUR = 60.0
_FOOT = 0.3048
_KNOT = 1852.0 / 3600.0


def _scale(x: FloatOrArray, factor: float) -> FloatOrArray:
    scaled: FloatOrArray = np.multiply(x, factor)
    return scaled


def deg_per_h(x: FloatOrArray) -> FloatOrArray:
    """Angular rate in °/h → rad/s (× π/180/3600)."""
    return _scale(x, _DEG / _HOUR)


def deg_per_s(x: FloatOrArray) -> FloatOrArray:
    """Angular rate in °/s → rad/s (× π/180)."""
    return _scale(x, _DEG)


def deg_per_sqrt_h(x: FloatOrArray) -> FloatOrArray:
    """Angle random walk in °/√h → rad/√s (× π/180/60)."""
    return _scale(x, _DEG / _SQRT_HOUR)


def deg_per_h_per_sqrt_hz(x: FloatOrArray) -> FloatOrArray:
    """Gyro rate noise density in °/h/√Hz → angle random walk rad/√s (× π/180/3600)."""
    return _scale(x, _DEG / _HOUR)


def standard_g(x: FloatOrArray) -> FloatOrArray:
    """Acceleration in g (standard gravity) → m/s² (× 9.80665)."""
    return _scale(x, STANDARD_GRAVITY)


def milli_g(x: FloatOrArray) -> FloatOrArray:
    """Acceleration in mg → m/s² (× 9.80665e-3)."""
    return _scale(x, 1e-3 * STANDARD_GRAVITY)


def micro_g(x: FloatOrArray) -> FloatOrArray:
    """Acceleration in µg → m/s² (× 9.80665e-6)."""
    return _scale(x, 1e-6 * STANDARD_GRAVITY)


def micro_g_per_sqrt_hz(x: FloatOrArray) -> FloatOrArray:
    """Accelerometer noise density in µg/√Hz → velocity random walk m/s/√s (× 9.80665e-6)."""
    return _scale(x, 1e-6 * STANDARD_GRAVITY)


def m_per_s_per_sqrt_h(x: FloatOrArray) -> FloatOrArray:
    """Velocity random walk in m/s/√h → m/s/√s (÷ 60)."""
    return _scale(x, 1.0 / _SQRT_HOUR)


def ppm(x: FloatOrArray) -> FloatOrArray:
    """Parts per million → dimensionless (× 1e-6)."""
    return _scale(x, 1e-6)


def percent(x: FloatOrArray) -> FloatOrArray:
    """Percent → dimensionless (× 1e-2)."""
    return _scale(x, 1e-2)


def arcsec(x: FloatOrArray) -> FloatOrArray:
    """Angle in arc seconds → rad (× π/180/3600)."""
    return _scale(x, _DEG / 3600.0)


def arcmin(x: FloatOrArray) -> FloatOrArray:
    """Angle in arc minutes → rad (× π/180/60)."""
    return _scale(x, _DEG / 60.0)


def m_per_h(x: FloatOrArray) -> FloatOrArray:
    """Speed in m/h → m/s (÷ 3600)."""
    return _scale(x, 1.0 / _HOUR)


def hours(x: FloatOrArray) -> FloatOrArray:
    """Time in hours → s (× 3600)."""
    return _scale(x, _HOUR)


def to_deg_per_h(x: FloatOrArray) -> FloatOrArray:
    """Angular rate in rad/s → °/h."""
    return _scale(x, _HOUR / _DEG)


def to_deg_per_s(x: FloatOrArray) -> FloatOrArray:
    """Angular rate in rad/s → °/s."""
    return _scale(x, 1.0 / _DEG)


def to_deg_per_sqrt_h(x: FloatOrArray) -> FloatOrArray:
    """Angle random walk in rad/√s → °/√h."""
    return _scale(x, _SQRT_HOUR / _DEG)


def to_milli_g(x: FloatOrArray) -> FloatOrArray:
    """Acceleration in m/s² → mg."""
    return _scale(x, 1.0 / (1e-3 * STANDARD_GRAVITY))


def to_micro_g(x: FloatOrArray) -> FloatOrArray:
    """Acceleration in m/s² → µg."""
    return _scale(x, 1.0 / (1e-6 * STANDARD_GRAVITY))


def to_m_per_s_per_sqrt_h(x: FloatOrArray) -> FloatOrArray:
    """Velocity random walk in m/s/√s → m/s/√h."""
    return _scale(x, _SQRT_HOUR)


def to_ppm(x: FloatOrArray) -> FloatOrArray:
    """Dimensionless → parts per million."""
    return _scale(x, 1e6)


def to_arcsec(x: FloatOrArray) -> FloatOrArray:
    """Angle in rad → arc seconds."""
    return _scale(x, 3600.0 / _DEG)


def to_arcmin(x: FloatOrArray) -> FloatOrArray:
    """Angle in rad → arc minutes."""
    return _scale(x, 60.0 / _DEG)


def to_m_per_h(x: FloatOrArray) -> FloatOrArray:
    """Speed in m/s → m/h."""
    return _scale(x, _HOUR)


def _check_dt(dt: float) -> float:
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt: must be a finite number > 0, got {dt!r}")
    return dt


def _check_nonnegative(x: ArrayLike, name: str) -> Array:
    a = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(a)) or np.any(a < 0.0):
        raise ValueError(f"{name}: must be finite and >= 0, got {x!r}")
    return a


@overload
def psd_to_sigma(psd: float, dt: float) -> float: ...
@overload
def psd_to_sigma(psd: ArrayLike, dt: float) -> Array: ...
def psd_to_sigma(psd: ArrayLike, dt: float) -> float | Array:
    """White-noise sample σ = √(q/dt) from the intensity q (two-sided PSD), spec §8.3.

    Parameters
    ----------
    psd : float or array_like, unit²·s
        Intensity ``q`` of the continuous white noise (e.g. rad²/s for ARW²).
    dt : float, s
        Sampling interval (samples are averages over ``dt``).

    Returns
    -------
    sigma : float (for a float ``psd``) or ndarray, unit
        Standard deviation of one sample.
    """
    sigma: float | Array = np.sqrt(_check_nonnegative(psd, "psd") / _check_dt(dt))
    return sigma


@overload
def sigma_to_psd(sigma: float, dt: float) -> float: ...
@overload
def sigma_to_psd(sigma: ArrayLike, dt: float) -> Array: ...
def sigma_to_psd(sigma: ArrayLike, dt: float) -> float | Array:
    """Intensity q = σ²·dt of a white noise whose samples over ``dt`` have σ (spec §8.3).

    Inverse of :func:`psd_to_sigma`.  With ``sigma`` a rate noise (rad/s),
    ``√q`` is the equivalent angle random walk (rad/√s); this is how the
    literal reading of S1's "0.01 °/h white-noise drift" maps to an ARW.
    """
    s = _check_nonnegative(sigma, "sigma")
    q: float | Array = s * s * _check_dt(dt)
    return q


@overload
def markov_q(sigma: float, tau: float) -> float: ...
@overload
def markov_q(sigma: ArrayLike, tau: ArrayLike) -> Array: ...
def markov_q(sigma: ArrayLike, tau: ArrayLike) -> float | Array:
    """Driving intensity q = 2σ²/τ of a first-order Gauss-Markov process (spec §8.3).

    Parameters
    ----------
    sigma : float or array_like, unit
        Steady-state standard deviation.
    tau : float or array_like, s
        Correlation time, > 0.

    Returns
    -------
    q : float (for float ``sigma`` and ``tau``) or ndarray, unit²/s
        PSD of ``w`` in ``ḃ = −b/τ + w``.
    """
    s = _check_nonnegative(sigma, "sigma")
    t = np.asarray(tau, dtype=float)
    if not np.all(np.isfinite(t)) or np.any(t <= 0.0):
        raise ValueError(f"tau: must be finite and > 0, got {tau!r}")
    q: float | Array = 2.0 * s * s / t
    return q


# ---- quantity parser ------------------------------------------------------------------------

Family = Literal[
    "angular_rate",
    "angle_random_walk",
    "acceleration",
    "velocity_random_walk",
    "dimensionless",
    "angle",
    "time",
    "length",
    "velocity",
]

#: family -> (description, example)
FAMILIES: dict[str, tuple[str, str]] = {
    "angular_rate": ("an angular rate", "0.1 deg/h"),
    "angle_random_walk": ("an angle random walk", "0.01 deg/sqrt(h)"),
    "acceleration": ("an acceleration", "100 ug"),
    "velocity_random_walk": ("a velocity random walk", "0.01 m/s/sqrt(h)"),
    "dimensionless": ("a dimensionless ratio", "250 ppm"),
    "angle": ("an angle", "300 arcsec"),
    "time": ("a time", "7200 s"),
    "length": ("a length", "25 m"),
    "velocity": ("a velocity", "1000 m/h"),
}

_G = STANDARD_GRAVITY
#: normalized unit -> (family, factor to SI)
_UNITS: dict[str, tuple[str, float]] = {
    "rad/s": ("angular_rate", 1.0),
    "mrad/s": ("angular_rate", 1e-3),
    "deg/s": ("angular_rate", _DEG),
    "deg/h": ("angular_rate", _DEG / _HOUR),
    "rad/sqrt(s)": ("angle_random_walk", 1.0),
    "rad/s/sqrt(hz)": ("angle_random_walk", 1.0),
    "deg/sqrt(s)": ("angle_random_walk", _DEG),
    "deg/sqrt(h)": ("angle_random_walk", _DEG / _SQRT_HOUR),
    "deg/s/sqrt(hz)": ("angle_random_walk", _DEG),
    "deg/h/sqrt(hz)": ("angle_random_walk", _DEG / _HOUR),
    "m/s^2": ("acceleration", 1.0),
    "g": ("acceleration", _G),
    "mg": ("acceleration", 1e-3 * _G),
    "ug": ("acceleration", 1e-6 * _G),
    "m/s/sqrt(s)": ("velocity_random_walk", 1.0),
    "m/s^2/sqrt(hz)": ("velocity_random_walk", 1.0),
    "m/s/sqrt(h)": ("velocity_random_walk", 1.0 / _SQRT_HOUR),
    "ft/s/sqrt(h)": ("velocity_random_walk", _FOOT / _SQRT_HOUR),
    "g/sqrt(hz)": ("velocity_random_walk", _G),
    "mg/sqrt(hz)": ("velocity_random_walk", 1e-3 * _G),
    "ug/sqrt(hz)": ("velocity_random_walk", 1e-6 * _G),
    "": ("dimensionless", 1.0),
    "%": ("dimensionless", 1e-2),
    "ppm": ("dimensionless", 1e-6),
    "rad": ("angle", 1.0),
    "mrad": ("angle", 1e-3),
    "urad": ("angle", 1e-6),
    "deg": ("angle", _DEG),
    "arcmin": ("angle", _DEG / 60.0),
    "arcsec": ("angle", _DEG / 3600.0),
    "s": ("time", 1.0),
    "ms": ("time", 1e-3),
    "min": ("time", 60.0),
    "h": ("time", _HOUR),
    "m": ("length", 1.0),
    "km": ("length", 1e3),
    "ft": ("length", _FOOT),
    "m/s": ("velocity", 1.0),
    "m/h": ("velocity", 1.0 / _HOUR),
    "km/h": ("velocity", 1e3 / _HOUR),
    "ft/s": ("velocity", _FOOT),
    "kn": ("velocity", _KNOT),
}

_NUMBER = re.compile(
    r"^\s*([+-]?(?:(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?|nan|inf(?:inity)?))\s*(.*?)\s*$",
    re.IGNORECASE,
)
_WORD = r"(?<![a-z])({})(?![a-z])"
_SPELLINGS = [  # (pattern, replacement) applied in order to the lower-cased unit
    (r"\s+", ""),
    (r"arc-(sec|min)", r"arc\1"),
    (r"[µμ]", "u"),
    (r"°", "deg"),
    (r"″|''|\"", "arcsec"),
    (r"′|'", "arcmin"),
    (r"²", "^2"),
    (r"\*\*", "^"),
    (r"√\(([a-z]+)\)|√([a-z]+)", r"sqrt(\1\2)"),
    (_WORD.format(r"sqrt([a-z]+)"), r"sqrt(\2)"),
    (r"(?<![a-z])rt\(", "sqrt("),
    (_WORD.format(r"rt-?(h|hr|s|hz)"), r"sqrt(\2)"),
    (_WORD.format("degrees?"), "deg"),
    (_WORD.format("hours?|hrs?"), "h"),
    (_WORD.format("seconds?|secs?"), "s"),
    (_WORD.format("minutes?"), "min"),
    (_WORD.format("knots?|kts?"), "kn"),
    (_WORD.format("micro-?g"), "ug"),
    (_WORD.format("milli-?g"), "mg"),
    (r"/s/s(?![a-z])", "/s^2"),
    (r"/s2(?![a-z0-9])", "/s^2"),
]


def _normalize(unit: str) -> str:
    u = unit.lower()
    for pattern, repl in _SPELLINGS:
        u = re.sub(pattern, repl, u)
    return u


def parse_quantity(
    text: str | float,
    family: Family,
    field: str,
    *,
    constraint: Literal["any", "nonnegative", "positive"] = "any",
) -> float:
    """Read ``"<number> <unit>"`` in unit family ``family`` and return it in SI units.

    Accepted units per family (spaces, case, ``µ``/``u``, ``°``, ``√h``/``sqrt(h)``/
    ``rt(h)``, ``hr``, ``s^2``/``s²`` spellings are all equivalent):

    * ``angular_rate`` → rad/s: rad/s, mrad/s, deg/s, deg/h
    * ``angle_random_walk`` → rad/√s: rad/sqrt(s), rad/s/sqrt(Hz), deg/sqrt(s),
      deg/sqrt(h), deg/s/sqrt(Hz), deg/h/sqrt(Hz)
    * ``acceleration`` → m/s²: m/s^2, g, mg, ug (g = :data:`STANDARD_GRAVITY`)
    * ``velocity_random_walk`` → m/s/√s: m/s/sqrt(s), m/s^2/sqrt(Hz), m/s/sqrt(h),
      ft/s/sqrt(h), g/sqrt(Hz), mg/sqrt(Hz), ug/sqrt(Hz)
    * ``dimensionless`` → 1: no unit, %, ppm
    * ``angle`` → rad: rad, mrad, urad, deg, arcmin, arcsec (also ′ ″ ' ")
    * ``time`` → s: s, ms, min, h
    * ``length`` → m: m, km, ft
    * ``velocity`` → m/s: m/s, m/h, km/h, ft/s, kn

    A number without a unit is accepted only for ``dimensionless`` or when it is
    zero (zero is zero in every unit); a Python ``int``/``float`` is read the same way.

    Parameters
    ----------
    text : str or float
        The quantity, e.g. ``"0.1 deg/h"``, ``"1e-4 g"``, ``"0.25 %"``.
    family : str
        Expected unit family (one of :data:`FAMILIES`).
    field : str
        Name used at the start of every error message, e.g. ``"imu.gyro_bias"``.
    constraint : {"any", "nonnegative", "positive"}
        Sign the value must have (σ: ``"nonnegative"``; τ: ``"positive"``).

    Returns
    -------
    float
        The value in SI units.

    Raises
    ------
    ValueError
        One line ``"<field>: <reason>"``: wrong unit family, unknown unit,
        missing unit, unreadable or non-finite number, or wrong sign.

    Examples
    --------
    >>> parse_quantity("0.1 deg/h", "angular_rate", "imu.gyro_bias")  # doctest: +ELLIPSIS
    4.84813681...e-07
    """
    if family not in FAMILIES:
        raise ValueError(f"{field}: unknown unit family {family!r} (valid: {', '.join(FAMILIES)})")
    what, example = FAMILIES[family]
    if isinstance(text, bool) or not isinstance(text, str | numbers.Real):
        raise ValueError(
            f"{field}: expected {what} as a string with a unit (e.g. '{example}'), got {text!r}"
        )
    shown = text if isinstance(text, str) else repr(text)
    if isinstance(text, str):
        match = _NUMBER.match(text)
        if match is None:
            raise ValueError(
                f"{field}: cannot read a number in {text!r}; expected {what} (e.g. '{example}')"
            )
        number, unit = float(match.group(1)), match.group(2)
    else:
        number, unit = float(text), ""
    if not math.isfinite(number):
        raise ValueError(f"{field}: must be a finite number, got '{shown}'")
    key = _normalize(unit)
    if key not in _UNITS:
        accepted = ", ".join(u for u, (f, _) in _UNITS.items() if f == family and u)
        raise ValueError(
            f"{field}: unknown unit {unit!r} in '{shown}'; {what} takes one of: {accepted}"
        )
    unit_family, factor = _UNITS[key]
    if key == "" and number == 0.0:
        unit_family = family
    if unit_family != family:
        hint = "no unit" if key == "" else f"which is {FAMILIES[unit_family][0]}"
        raise ValueError(f"{field}: expected {what} (e.g. '{example}'), got '{shown}' ({hint})")
    value = number * factor
    if constraint == "nonnegative" and value < 0.0:
        raise ValueError(f"{field}: must be >= 0, got '{shown}'")
    if constraint == "positive" and value <= 0.0:
        raise ValueError(f"{field}: must be > 0, got '{shown}'")
    return value
