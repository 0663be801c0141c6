"""Typed method configuration: the settings every architecture shares, and their checks.

A method of a scenario file (``[[methods]]``) is validated once, at the boundary
(:mod:`ftnav.io.sections`), into the frozen configuration of its architecture: a
pydantic model per architecture (:mod:`ftnav.fusion.registry` lists them; the file
format is their discriminated union on ``architecture``).  Each holds only the
settings its architecture reads, so a setting another architecture reads is refused
(``methods[2].sharing: not a setting of the distributed architecture``); an unknown
key is refused with the closest valid one.  The detector and the noise adaptation are
nested settings of their own (``detector = {kind = "residual-chi2", ...}``, or the
kind alone: ``detector = "oracle"``).

Numerical code receives these frozen objects (and the trained models they name,
loaded at the boundary: :class:`Learned`); it never validates nor opens a file.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Annotated, Any, ClassVar, Literal, NamedTuple, TypeVar

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError

from ftnav.fdi.rbf import RBFModel
from ftnav.fusion.neural_model import NeuronModel

__all__ = [
    "CONFIG_ERROR",
    "Count",
    "Tuple",
    "Detector",
    "FixedNoise",
    "Learned",
    "NOTHING_LEARNED",
    "MethodBase",
    "Noise",
    "NoDetector",
    "OracleDetector",
    "RbfDetector",
    "ResidualChi2",
    "Settings",
    "StateChi2",
    "VbNoise",
    "config_error",
]

#: pydantic error type of the configuration checks (the message is the reason)
CONFIG_ERROR = "ftnav_check"  # the type ftnav.io.common reads as "<path>: <reason>"


def config_error(reason: str, *path: str | int) -> PydanticCustomError:
    """A validation error ``<path>: <reason>`` relative to the model being validated."""
    return PydanticCustomError(CONFIG_ERROR, "{reason}", {"reason": reason, "path": tuple(path)})


class Settings(BaseModel):
    """Frozen, strict, no unknown keys: the base of every configuration model."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


def _kind_alone(value: Any) -> Any:
    """``"oracle"`` is short for ``{kind = "oracle"}``."""
    return {"kind": value} if isinstance(value, str) else value


Probability = Annotated[float, Field(gt=0.0, lt=1.0, allow_inf_nan=False)]
Count = Annotated[int, Field(ge=1)]


def _as_tuple(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


T = TypeVar("T")
#: an immutable sequence given as a TOML array
Tuple = Annotated[tuple[T, ...], BeforeValidator(_as_tuple)]


# ------------------------------------------------------------------ detectors (spec §3-4)
class NoDetector(Settings):
    """No fault detection: every local filter is always fused."""

    kind: Literal["none"] = "none"


class OracleDetector(Settings):
    """The true fault windows of a simulated stream as the flags (the best isolation can do)."""

    kind: Literal["oracle"]


class ResidualChi2(Settings):
    """Residual chi-square test of each aid (spec §3.1), windowed, with hysteresis.

    ``prior`` is the reference the residual is tested against: the local filter's own
    prior, the fused (``global``) prior, or (neuron centre) the covariance
    ``intersection`` of the local priors.
    """

    kind: Literal["residual-chi2"]
    false_alarm_probability: Probability = 1e-3
    window: Count = 1
    n_on: Count = 1
    n_off: Count = 5
    prior: Literal["local", "global", "intersection"] = "local"


class StateChi2(Settings):
    """State chi-square test with the exact covariance Pˢ − P (spec §3.2)."""

    kind: Literal["state-chi2"]
    false_alarm_probability: Probability = 1e-3
    window: Count = 1
    n_on: Count = 1
    n_off: Count = 5
    reset: Annotated[int, Field(ge=5)] = 100


class RbfDetector(Settings):
    """Paper 000's RBF network (spec §4): a trained model file, its threshold and hysteresis."""

    kind: Literal["rbf"]
    model: str = Field(
        description="trained model file (ftnav train-detector); relative to the scenario file"
    )
    threshold: Annotated[float, Field(gt=0.0, lt=1.0, allow_inf_nan=False)] | None = None
    n_on: Count | None = None
    n_off: Count | None = None


Detector = Annotated[
    NoDetector | OracleDetector | ResidualChi2 | StateChi2 | RbfDetector,
    BeforeValidator(_kind_alone),
    Field(discriminator="kind"),
]


# ----------------------------------------------------------------- noise adaptation (§7)
class FixedNoise(Settings):
    """The measurement noise R the sensors declare, fixed."""

    kind: Literal["none"] = "none"


class VbNoise(Settings):
    """Variational-Bayes adaptation of each local filter's diagonal R (spec §7).

    ``vb``: Särkkä & Nummenmaa; ``vb-literal``: paper 002's printed form.  ``sensors``
    limits the adaptation to those aids (empty: every aid).
    """

    kind: Literal["vb", "vb-literal"]
    rho: Annotated[float, Field(gt=0.0, le=1.0, allow_inf_nan=False)] = 0.99
    iterations: Count = 3
    sensors: Tuple[str] = ()

    @property
    def variant(self) -> str:
        """``"sarkka"`` or ``"literal"`` (:func:`ftnav.core.vb.vb_update`)."""
        return "sarkka" if self.kind == "vb" else "literal"


Noise = Annotated[FixedNoise | VbNoise, BeforeValidator(_kind_alone), Field(discriminator="kind")]


# ------------------------------------------------------------------------------ methods
class MethodBase(Settings):
    """What every method has: a name, an architecture, a detector and a noise model.

    Subclasses (one per architecture) add their settings and narrow ``architecture``
    to a literal; :attr:`DETECTORS` and :attr:`NOISE` list the detector and noise kinds
    the architecture implements, :attr:`PRIORS` the residual test's references.
    """

    DETECTORS: ClassVar[tuple[str, ...]] = ("none", "oracle", "residual-chi2", "state-chi2", "rbf")
    NOISE: ClassVar[tuple[str, ...]] = ("none", "vb", "vb-literal")
    PRIORS: ClassVar[tuple[str, ...]] = ("local", "global")

    name: str = Field(min_length=1, description="unique method name")
    detector: Detector = NoDetector()
    noise: Noise = FixedNoise()
    correction: Literal["feedback", "output"] | None = Field(
        default=None,
        description=(
            "integrated navigation: this method's correction of its SINS (spec §8.5); "
            "default: the scenario's [filter] correction"
        ),
    )

    def check_pieces(self) -> None:
        """Refuse a detector, noise model or test reference the architecture lacks."""
        arch = self.architecture  # type: ignore[attr-defined]
        if self.detector.kind not in self.DETECTORS:
            raise config_error(
                f"{self.detector.kind!r} is not a detector of the {arch} "
                f"architecture (expected one of {list(self.DETECTORS)})",
                "detector",
                "kind",
            )
        if self.noise.kind not in self.NOISE:
            raise config_error(
                f"{self.noise.kind!r} is not available with the {arch} "
                f"architecture (expected one of {list(self.NOISE)})",
                "noise",
                "kind",
            )
        if isinstance(self.detector, ResidualChi2) and self.detector.prior not in self.PRIORS:
            raise config_error(
                f"{self.detector.prior!r} is not available with the {arch} "
                f"architecture (expected one of {list(self.PRIORS)})",
                "detector",
                "prior",
            )

    def check_sensors(self, sensors: Iterable[Any]) -> None:
        """System-dependent checks (at the boundary, once the sensors are known)."""
        names = [s.name for s in sensors]
        if isinstance(self.noise, VbNoise):
            for j, s in enumerate(self.noise.sensors):
                if s not in names:
                    raise config_error(
                        f"unknown sensor {s!r} (known: {', '.join(names)})", "noise", "sensors", j
                    )
                if s in self.noise.sensors[:j]:
                    raise config_error(f"duplicate sensor {s!r}", "noise", "sensors", j)

    @property
    def model_file(self) -> str | None:
        """The trained model file the method names (detector or fusion centre), or None."""
        return self.detector.model if isinstance(self.detector, RbfDetector) else None


class Learned(NamedTuple):
    """Trained models a method uses, loaded and checked at the boundary (:mod:`ftnav.io`)."""

    detector: RBFModel | None = None
    fusion: NeuronModel | None = None


#: no trained model (the default of every architecture's constructor)
NOTHING_LEARNED = Learned()
