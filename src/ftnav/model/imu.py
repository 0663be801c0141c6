"""True IMU error parameters in datasheet terms (spec §8.3; S1 Table 1): the description.

:class:`ImuErrors` holds every error term of the model in
:mod:`ftnav.sim.imu` (which simulates them) in SI units, built from datasheet
strings by :meth:`ImuErrors.from_datasheet` (units: :mod:`ftnav.nav.units`); the
named presets are :data:`IMU_PRESETS`.  The filters' default error model is
derived from the same description (:func:`ftnav.io.ins_scenario_file.filter_model`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ftnav.nav.units import (
    deg_per_h,
    deg_per_sqrt_h,
    m_per_s_per_sqrt_h,
    micro_g,
    milli_g,
    parse_quantity,
    ppm,
    standard_g,
)

__all__ = ["DATASHEET_KEYS", "IMU_PRESETS", "ImuErrors", "imu_preset"]

# field -> (unit family for from_datasheet, sign constraint)
_SPEC: dict[str, tuple[str, str]] = {
    "gyro_bias": ("angular_rate", "any"),
    "gyro_bias_sd": ("angular_rate", "nonnegative"),
    "gyro_markov_sd": ("angular_rate", "nonnegative"),
    "gyro_markov_tau": ("time", "positive"),
    "gyro_arw": ("angle_random_walk", "nonnegative"),
    "gyro_scale_sd": ("dimensionless", "nonnegative"),
    "gyro_misalignment_sd": ("angle", "nonnegative"),
    "accel_bias": ("acceleration", "any"),
    "accel_bias_sd": ("acceleration", "nonnegative"),
    "accel_markov_sd": ("acceleration", "nonnegative"),
    "accel_markov_tau": ("time", "positive"),
    "accel_vrw": ("velocity_random_walk", "nonnegative"),
    "accel_scale_sd": ("dimensionless", "nonnegative"),
    "accel_misalignment_sd": ("angle", "nonnegative"),
}

#: keys of an IMU datasheet table (:meth:`ImuErrors.from_datasheet`), in field order
DATASHEET_KEYS: tuple[str, ...] = tuple(_SPEC)


class _Range(NamedTuple):
    """Plausibility of one unit family, in SI: refused outside [low, high] (|x|; a σ or a
    bias may be 0), which no navigation IMU reaches (``text``: the bound in datasheet
    terms); warned outside [usual_low, usual_high], the span of real IMU grades from
    consumer MEMS to strategic (the low end: a nonzero value only), shown in ``unit``."""

    si_unit: str
    low: float
    high: float
    text: str
    unit: str
    per_si: float  # the display unit per SI unit
    usual_low: float
    usual_high: float


_DEG = np.pi / 180.0
_G0 = 9.80665
#: unit family -> plausible range (SI); docs/scenario-format.md, "What is checked"
RANGES: dict[str, _Range] = {
    # consumer MEMS gyros drift ~0.1-1 °/s and start with a bias of up to a few °/s
    # (ADIS16405: ±3 °/s initial bias, the NaveGo set); a drift of the rates flown is no gyro
    "angular_rate": _Range(
        "rad/s", 0.0, 1.0, "57 deg/s", "deg/h", 3600 / _DEG, 1e-5 * _DEG / 3600, 5 * _DEG
    ),
    "time": _Range("s", 1e-3, 1e9, "30 years", "s", 1.0, 0.0, np.inf),
    "angle_random_walk": _Range(
        "rad/sqrt(s)",
        0.0,
        0.1,
        "5.7 deg/s/sqrt(Hz)",
        "deg/sqrt(h)",
        60 / _DEG,
        1e-5 * _DEG / 60,
        10 * _DEG / 60,
    ),
    # consumer MEMS accelerometers: biases ~10-60 mg
    "acceleration": _Range("m/s^2", 0.0, 10.0, "1 g", "mg", 1e3 / _G0, 1e-7 * _G0, 0.1 * _G0),
    "velocity_random_walk": _Range(
        "m/s/sqrt(s)", 0.0, 1.0, "100 mg/sqrt(Hz)", "m/s/sqrt(h)", 60.0, 1e-4 / 60, 10 / 60
    ),
    "dimensionless": _Range("", 0.0, 0.5, "50 %", "ppm", 1e6, 0.0, 0.01),
    "angle": _Range("rad", 0.0, 0.5, "29 deg", "mrad", 1e3, 0.0, 0.01),
}


def _show(value) -> str:
    """One-line rendering of a bad input for an error message."""
    return np.array2string(value, separator=", ") if isinstance(value, np.ndarray) else repr(value)


def _axes(value, name: str, constraint: str, family: str) -> np.ndarray:
    """Validate one field: scalar or 3 finite values with the right sign, within the
    family's :data:`RANGES` -> read-only (3,)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(
            f"{name}: expected a number in SI units (strings with units go through "
            f"ImuErrors.from_datasheet), got {value!r}"
        ) from None
    if a.shape not in ((), (3,)):
        raise ValueError(f"{name}: expected a scalar or 3 values (x, y, z), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: must be finite, got {_show(value)}")
    if constraint == "nonnegative" and np.any(a < 0.0):
        raise ValueError(f"{name}: must be >= 0, got {_show(value)}")
    if constraint == "positive" and np.any(a <= 0.0):
        raise ValueError(f"{name}: must be > 0, got {_show(value)}")
    r = RANGES[family]
    big, small = float(np.abs(a).max()), float(np.abs(a).min())
    unit = f" {r.si_unit}" if r.si_unit else ""
    if big > r.high:
        raise ValueError(
            f"{name}: {big:.3g}{unit}, beyond the {r.high:g}{unit} ({r.text}) "
            "that no navigation IMU reaches (a unit slip?)"
        )
    if small < r.low:
        raise ValueError(
            f"{name}: {small:.3g} {r.si_unit}, below the {r.low:g} {r.si_unit} "
            "that a correlation time needs (a unit slip?)"
        )
    a = np.array(np.broadcast_to(a, (3,)))
    a.flags.writeable = False
    return a


@dataclass(frozen=True, slots=True)
class ImuErrors:
    """True IMU error parameters in SI units (spec §8.3); each a scalar or per-axis (3,).

    Every field is stored as a read-only float64 (3,) array (x, y, z body axes);
    a scalar is broadcast.  ``*_sd`` are standard deviations (≥ 0), ``*_tau``
    correlation times (> 0, unused while the matching σ is 0).  See the module
    docstring for the model and :meth:`from_datasheet` for datasheet units.

    Attributes
    ----------
    gyro_bias : (3,) rad/s, fixed constant drift added to every run (any sign).
    gyro_bias_sd : (3,) rad/s, σ of the random constant drift ε_b drawn per run.
    gyro_markov_sd : (3,) rad/s, steady-state σ of the Markov drift ε_r.
    gyro_markov_tau : (3,) s, its correlation time T_g.
    gyro_arw : (3,) rad/√s, angle random walk.
    gyro_scale_sd : (3,) dimensionless, σ of the scale-factor errors.
    gyro_misalignment_sd : (3,) rad, σ of the misalignment angles of each axis.
    accel_bias : (3,) m/s², fixed constant bias.
    accel_bias_sd : (3,) m/s², σ of the random constant bias.
    accel_markov_sd : (3,) m/s², steady-state σ of the Markov bias ∇.
    accel_markov_tau : (3,) s, its correlation time T_a.
    accel_vrw : (3,) m/s/√s, velocity random walk.
    accel_scale_sd : (3,) dimensionless.  accel_misalignment_sd : (3,) rad.

    Raises
    ------
    ValueError
        ``"imu.<field>: <reason>"`` for a negative σ, τ ≤ 0, NaN/inf, a value outside
        the plausible range of its unit family (:data:`RANGES`), a wrong shape or a
        non-numeric value.
    """

    gyro_bias: ArrayLike = 0.0
    gyro_bias_sd: ArrayLike = 0.0
    gyro_markov_sd: ArrayLike = 0.0
    gyro_markov_tau: ArrayLike = 3600.0
    gyro_arw: ArrayLike = 0.0
    gyro_scale_sd: ArrayLike = 0.0
    gyro_misalignment_sd: ArrayLike = 0.0
    accel_bias: ArrayLike = 0.0
    accel_bias_sd: ArrayLike = 0.0
    accel_markov_sd: ArrayLike = 0.0
    accel_markov_tau: ArrayLike = 3600.0
    accel_vrw: ArrayLike = 0.0
    accel_scale_sd: ArrayLike = 0.0
    accel_misalignment_sd: ArrayLike = 0.0

    def __post_init__(self):
        for name, (family, constraint) in _SPEC.items():
            value = _axes(getattr(self, name), f"imu.{name}", constraint, family)
            object.__setattr__(self, name, value)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ImuErrors):
            return NotImplemented
        return all(np.array_equal(getattr(self, n), getattr(other, n)) for n in _SPEC)

    def __hash__(self) -> int:
        return hash(tuple(getattr(self, n).tobytes() for n in _SPEC))

    def unusual(self) -> tuple[tuple[str, str], ...]:
        """``(field, why)`` for every value outside the span of real IMU grades
        (:data:`RANGES`): legal, but likely a unit mistake."""
        out = []
        for name, (family, _) in _SPEC.items():
            r = RANGES[family]
            a = np.abs(getattr(self, name))
            if (a > r.usual_high).any():
                out.append(
                    (
                        name,
                        f"{a.max() * r.per_si:.3g} {r.unit} is beyond any real IMU "
                        f"(above {r.usual_high * r.per_si:.3g} {r.unit}): a unit mistake?",
                    )
                )
            elif ((a > 0) & (a < r.usual_low)).any():
                out.append(
                    (
                        name,
                        f"{a[a > 0].min() * r.per_si:.3g} {r.unit} is better than any "
                        f"real IMU (below {r.usual_low * r.per_si:.3g} {r.unit}): a unit mistake?",
                    )
                )
        return tuple(out)

    @classmethod
    def from_datasheet(
        cls,
        table: Mapping[str, str | float | Sequence[str | float]],
        *,
        base: ImuErrors | None = None,
        field: str = "imu",
    ) -> ImuErrors:
        """Build from datasheet strings, e.g. a TOML table (units: :func:`parse_quantity`).

        Keys are the field names; each value is ``"<number> <unit>"`` of the field's
        family, or a list of three such strings (x, y, z).  A bare number is accepted
        only when it is 0 or the field is dimensionless.  Fields not given are taken
        from ``base`` (default: all zero, τ = 3600 s).

        Parameters
        ----------
        table : mapping
            E.g. ``{"gyro_bias_sd": "0.1 deg/h", "gyro_arw": "0.01 deg/sqrt(h)",
            "gyro_markov_sd": "0.1 deg/h", "gyro_markov_tau": "2 h",
            "accel_markov_sd": "100 ug", "accel_markov_tau": "1800 s"}``.
        base : ImuErrors, optional
            Values for the keys that ``table`` leaves out (e.g. a preset).
        field : str
            Path of the table, the prefix of error messages (``"imu.gyro_arw: ..."``).

        Raises
        ------
        ValueError
            ``"<field>.<key>: <reason>"``: unknown key, unit of the wrong family,
            unknown unit, NaN/inf, negative σ, τ ≤ 0, not 1 or 3 values.
        """
        if not isinstance(table, Mapping):
            raise ValueError(
                f"{field}: expected a table of '<number> <unit>' strings, "
                f"got {type(table).__name__}"
            )
        values = {}
        for key, raw in table.items():
            path = f"{field}.{key}"
            if key not in _SPEC:
                raise ValueError(f"{path}: unknown key; valid keys: {', '.join(_SPEC)}")
            family, constraint = _SPEC[key]
            if isinstance(raw, Sequence) and not isinstance(raw, str):
                if len(raw) != 3:
                    raise ValueError(f"{path}: expected one value or 3 (x, y, z), got {len(raw)}")
                values[key] = [
                    parse_quantity(v, family, f"{path}[{i}]", constraint=constraint)
                    for i, v in enumerate(raw)
                ]
            else:
                values[key] = parse_quantity(raw, family, path, constraint=constraint)
        if base is not None:
            values = {f.name: getattr(base, f.name) for f in fields(base)} | values
        try:
            return cls(**values)
        except ValueError as exc:  # name the field where the table is
            raise ValueError(re.sub(r"^imu\.", f"{field}.", str(exc))) from None


#: Named error sets (SI).  ``seed001`` is S1 Table 1 (spec §8.3); see :func:`imu_preset`.
IMU_PRESETS: dict[str, ImuErrors] = {
    "ideal": ImuErrors(),
    "seed001": ImuErrors(
        gyro_bias_sd=deg_per_h(0.1),
        gyro_markov_sd=deg_per_h(0.1),
        gyro_markov_tau=7200.0,
        gyro_arw=deg_per_sqrt_h(0.01),
        accel_markov_sd=standard_g(1e-4),
        accel_markov_tau=1800.0,
    ),
    "tactical": ImuErrors(
        gyro_bias_sd=deg_per_h(1.0),
        gyro_markov_sd=deg_per_h(0.3),
        gyro_markov_tau=3600.0,
        gyro_arw=deg_per_sqrt_h(0.1),
        gyro_scale_sd=ppm(150.0),
        gyro_misalignment_sd=0.5e-3,
        accel_bias_sd=milli_g(1.0),
        accel_markov_sd=micro_g(50.0),
        accel_markov_tau=3600.0,
        accel_vrw=m_per_s_per_sqrt_h(0.03),
        accel_scale_sd=ppm(300.0),
        accel_misalignment_sd=0.5e-3,
    ),
}


def imu_preset(name: str) -> ImuErrors:
    """The named IMU error set of :data:`IMU_PRESETS`.

    * ``"ideal"``: no error at all.
    * ``"seed001"``: S1 Table 1 (spec §8.3).  Gyro random constant drift σ 0.1 °/h;
      gyro Markov drift σ 0.1 °/h with T_g = 7200 s; gyro "white-noise drift 0.01 °/h"
      read as ARW 0.01 °/√h (spec §8.3 [A]; the literal reading is
      ``gyro_arw = √sigma_to_psd(deg_per_h(0.01), dt)``, negligible); accelerometer
      Markov bias σ 1e-4 g (standard g, 9.80665e-4 m/s²) with T_a = 1800 s.  Table 1
      gives no accelerometer constant bias, no accelerometer white noise, no scale
      factor and no misalignment, so these are zero.  The 0.1 °/h constant drift is
      a per-run random constant (its σ also initializes the filter's P₀, spec §8.3);
      for a fixed value use ``dataclasses.replace(p, gyro_bias=..., gyro_bias_sd=0)``.
    * ``"tactical"`` [A, typical tactical-grade IMU, order of magnitude of published
      FOG/MEMS tactical units]: gyro bias σ 1 °/h, Markov σ 0.3 °/h with τ = 3600 s,
      ARW 0.1 °/√h, scale 150 ppm, misalignment 0.5 mrad; accelerometer bias σ 1 mg,
      Markov σ 50 µg with τ = 3600 s, VRW 0.03 m/s/√h, scale 300 ppm,
      misalignment 0.5 mrad.

    Raises
    ------
    ValueError
        ``"imu.preset: unknown preset ...; valid: ..."``.
    """
    try:
        return IMU_PRESETS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"imu.preset: unknown preset {name!r}; valid: {', '.join(IMU_PRESETS)}"
        ) from None
