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

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from ftnav.fdi.rbf import RBFModel
from ftnav.fusion.neural_model import NeuronModel

__all__ = [
    "CONFIG_ERROR",
    "Count",
    "Tuple",
    "Detector",
    "Cusum",
    "FixedNoise",
    "Glr",
    "GuardSettings",
    "Learned",
    "NOTHING_LEARNED",
    "MethodBase",
    "Noise",
    "NoDetector",
    "OracleDetector",
    "RbfDetector",
    "ResidualChi2",
    "Separation",
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


ARL0 = Annotated[
    float,
    Field(
        gt=1.0,
        allow_inf_nan=False,
        description="mean number of tests of an aid between false alarms (ARL0)",
    ),
]


class Cusum(Settings):
    """Page's CUSUM on each aid's whitened innovation (spec §3.3, :mod:`ftnav.fdi.sequential`).

    Two one-sided mean CUSUMs per component with ``drift`` k (half the shift, in σ, it
    detects fastest), and with ``variance_ratio`` c a variance CUSUM for ``S → c S``; the
    thresholds are solved from ``arl0``.  ``prior`` as for ``residual-chi2``.
    """

    kind: Literal["cusum"]
    arl0: ARL0 = 1e4
    drift: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 0.5
    variance_ratio: Annotated[float, Field(gt=1.0, allow_inf_nan=False)] | None = None
    n_on: Count = 1
    n_off: Count = 5
    prior: Literal["local", "global", "intersection"] = "local"


class Glr(Settings):
    """Windowed GLR of a mean shift in each aid's whitened innovation (spec §3.3).

    Over the last ``window`` tests (geometric window lengths); threshold from ``arl0``;
    ``memory`` tests over which each window's null level is learned, for innovations
    correlated in time (real sensors: :mod:`ftnav.fdi.sequential`); default ``50 window``,
    0 the textbook test for white innovations.
    """

    kind: Literal["glr"]
    arl0: ARL0 = 1e4
    window: Count = 64
    memory: Annotated[int, Field(ge=0)] | None = None
    n_on: Count = 1
    n_off: Count = 5
    prior: Literal["local", "global", "intersection"] = "local"


class Separation(Settings):
    """Solution separation over windows of each aid's tracked pull (issue 20; the guard's
    test, :mod:`ftnav.fusion.guard`): the filter against the filter without the aid's
    measurements of the last seconds, which sees a slow fault the filter follows.

    ``false_alarm_probability`` per test of an aid over all its windows (Bonferroni),
    windows up to ``window_s``; re-admission is the guard's.
    """

    kind: Literal["separation"]
    false_alarm_probability: Probability = 1e-5
    window_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 30.0


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
    NoDetector | OracleDetector | ResidualChi2 | StateChi2 | Cusum | Glr | Separation | RbfDetector,
    BeforeValidator(_kind_alone),
    Field(discriminator="kind"),
]


# --------------------------------------------------------------------- guard (issue 20)
class GuardSettings(Settings):
    """Isolation that cannot lock out (:mod:`ftnav.fusion.guard`), on by default for
    every method with a detector (``guard = false`` turns it off).

    ``window_s`` is the longest window of an aid's tracked pull (what a rollback can
    remove: a slow fault as long as that), finely resolved over the last ``fine_s`` in
    ``blocks`` blocks, coarsely (blocks of ``fine_s``) before; ``false_alarm_probability``
    that of the guard's χ² tests; ``kappa`` the optimism allowed for a coasting
    covariance's growth; ``growth`` the growth of an isolated aid's predicted variance
    that reports it unobservable without the aid; ``n_off`` re-admission tests in a row
    (default the detector's ``n_off``, else 5), ``confirm`` those that undo a rollback;
    ``override`` passes after which the guard re-admits against a detector still
    alarming; ``patience_s`` the longest a sole source is held after its last jump once
    its increments are consistent again (past it, the jump is taken as the aid's new
    value, as the plain filter takes it; the jump back cancels it); ``lasting_s`` the
    longest an aid beside aids of its rate only is held at one constant offset from the
    estimate (past it, the offset is taken in the rows no other aid reads).
    """

    window_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 600.0
    fine_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 60.0
    blocks: Count = 12
    false_alarm_probability: Probability = 1e-4
    kappa: Annotated[float, Field(ge=1.0, allow_inf_nan=False)] = 1.5
    growth: Annotated[float, Field(gt=1.0, allow_inf_nan=False)] = 4.0
    n_off: Count | None = None
    confirm: Count = 20
    override: Count = 50
    patience_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 10.0
    lasting_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = 300.0

    @model_validator(mode="after")
    def _check(self) -> GuardSettings:
        if self.fine_s > self.window_s:
            raise config_error(
                f"must be at most window_s ({self.window_s:g} s), got {self.fine_s:g}", "fine_s"
            )
        return self


def _guard_switch(value: Any) -> Any:
    """``guard = true`` is the default settings, ``guard = false`` none."""
    if value is True:
        return {}
    if value is False:
        return None
    return value


Guard = Annotated[GuardSettings | None, BeforeValidator(_guard_switch)]


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

    DETECTORS: ClassVar[tuple[str, ...]] = (
        "none",
        "oracle",
        "residual-chi2",
        "state-chi2",
        "cusum",
        "glr",
        "rbf",
    )
    NOISE: ClassVar[tuple[str, ...]] = ("none", "vb", "vb-literal")
    PRIORS: ClassVar[tuple[str, ...]] = ("local", "global")

    name: str = Field(min_length=1, description="unique method name")
    detector: Detector = NoDetector()
    noise: Noise = FixedNoise()
    guard: Guard = Field(
        default=GuardSettings(),
        description=(
            "isolation that cannot lock out (rollback, re-admission, sole-source aids); "
            "read with a detector other than none and oracle; false: off"
        ),
    )
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
        if isinstance(self.detector, Separation) and self.guard is None:
            raise config_error(
                "the separation detector is the guard's test: it needs the guard", "guard"
            )
        if "guard" in self.model_fields_set and self.guard is not None and not self.guarded:
            raise config_error(
                f"only read with a detector that isolates (detector is {self.detector.kind!r})",
                "guard",
            )
        if (
            isinstance(self.detector, ResidualChi2 | Cusum | Glr)
            and self.detector.prior not in self.PRIORS
        ):
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
    def guarded(self) -> bool:
        """Whether the method's flags isolate aids through the guard (a real detector)."""
        return self.detector.kind not in ("none", "oracle")

    @property
    def guard_settings(self) -> GuardSettings | None:
        """The guard the method runs, or None (no detector, oracle, or ``guard = false``);
        its ``n_off`` resolved (the detector's, else 5)."""
        if not self.guarded or self.guard is None:
            return None
        if self.guard.n_off is not None:
            return self.guard
        n_off = getattr(self.detector, "n_off", None)
        return self.guard.model_copy(update={"n_off": 5 if n_off is None else int(n_off)})

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
