"""Plain frozen description of an integrated-navigation scenario (spec §8-§10).

A SINS flies a :class:`~ftnav.sim.trajectory.Profile`; aiding sensors
(:mod:`ftnav.sensors`) sample the truth at their own rates; faults and anomalies
(spec §9.6) corrupt any aid or the SINS over time windows; every method fuses the
local SINS/aid error-state filters.  TOML files are parsed and validated by
:mod:`ftnav.io.ins_scenario_file` and turned into these containers.

Time base: the filter epoch ``k = 1..steps`` is at ``t_k = k·dt`` s (``dt`` the
filter period, a whole number of IMU periods); aids with period ``every·dt``
measure at the epochs where ``(k − offset) mod every == 0``.  Fault windows are
``start <= t_k < end`` in seconds (SINS faults: IMU samples in the window).

The metric states are the navigation *output* errors (computed − true, spec §11):
position East/North/Up in metres, velocity East/North/Up in m/s, attitude φ
East/North/Up in arcmin.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal, NamedTuple

import numpy as np

from ftnav.model.flight import Profile
from ftnav.model.imu import ImuErrors
from ftnav.model.scenario import Evaluation, FigureSpec, Method, fault_window_mask
from ftnav.nav.error_model import ErrorModelParams

__all__ = [
    "InsFault",
    "AidSpec",
    "InsScenario",
    "METRIC_STATES",
    "POSITION_NORMS",
    "SINS",
    "INS_FAULT_KINDS",
    "StateNames",
]

#: Reported output-error states (spec §11), in this order.
METRIC_STATES = (
    "pos_E_m",
    "pos_N_m",
    "pos_U_m",
    "vel_E_m_s",
    "vel_N_m_s",
    "vel_U_m_s",
    "att_E_arcmin",
    "att_N_arcmin",
    "att_U_arcmin",
)

#: Derived metric quantities (m): horizontal sqrt(E² + N²) and 3-D position error (spec §11).
POSITION_NORMS = ("pos_horizontal_m", "pos_3d_m")

#: Name that addresses the inertial system in a fault.
SINS = "sins"

InsFaultKind = Literal["bias", "ramp", "noise-scale", "noise-ramp", "outage", "stuck", "gyro-bias"]
INS_FAULT_KINDS: tuple[str, ...] = (
    "bias",
    "ramp",
    "noise-scale",
    "noise-ramp",
    "outage",
    "stuck",
    "gyro-bias",
)
Correction = Literal["feedback", "output"]


class StateNames(NamedTuple):
    """What metric and report code reads as ``scenario.model.states``."""

    states: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class InsFault:
    """A fault on one aid (its name) or on the SINS (``"sins"``) over ``[start, end)`` s.

    ``magnitude`` is in the aid's metric measurement space (``sensor.components``):
    the offset for ``bias`` (the final value for ``ramp``), the noise-std factor for
    ``noise-scale`` (reached at ``end`` for ``noise-ramp``, which starts at 1),
    unused for ``outage`` and ``stuck``; for ``gyro-bias`` on the SINS, the (3,)
    body gyro-bias step in rad/s.
    """

    sensor: str
    kind: InsFaultKind
    start: float
    end: float
    magnitude: np.ndarray


@dataclass(frozen=True, slots=True)
class AidSpec:
    """One aid: its sensor model (:mod:`ftnav.sensors`) and its schedule."""

    sensor: object
    every: int = 1
    offset: int = 0

    @property
    def name(self) -> str:
        return self.sensor.name

    @property
    def dim(self) -> int:
        return self.sensor.dim

    def __post_init__(self):
        if getattr(self.sensor, "difference_factor", None) is not None and (
            self.every != 1 or self.offset != 0
        ):
            raise ValueError(
                f"{self.sensor.name}.markov: 'difference' needs the aid at every "
                f"filter epoch (every = 1, offset = 0), got every = {self.every}, "
                f"offset = {self.offset}"
            )

    def available(self, steps: int) -> np.ndarray:
        """(steps,) bool schedule mask of the epochs k = 1..steps."""
        k = np.arange(1, steps + 1)
        return ((k - self.offset) % self.every == 0) & (k >= self.offset)


@dataclass(frozen=True, slots=True)
class InsScenario:
    """A complete, validated integrated-navigation scenario.

    Attributes
    ----------
    profile : flight profile (the truth); its ``dt`` is the IMU period.
    imu : true IMU errors (simulator).  error_model : the filters' assumed model.
    initial_sigma : (18,) σ of the initial INS errors in state units (spec §8.3 order);
        each run draws its initial error from N(0, diag σ²) and the filters start
        from ``P0 = diag σ²``.
    dt : filter period (s).  steps : filter epochs.
    aids : the aiding sensors.  faults : injected faults.  methods : fusion methods.
    correction : ``"feedback"`` (closed loop: the fused navigation errors are fed back
        to the SINS and every local estimate is shifted by the same correction, spec
        §6.2, §8.5) or ``"output"`` (the SINS runs free; its output is corrected).
    discretization : ``"series"`` (order 5, PSINS kfc2d) or ``"van-loan"``.
    test_profile : optional second flight for the "different trajectory" evaluation of
        learned methods (paper 001).
    model_notes : the IMU errors the filters' error model cannot represent exactly, and
        what it does instead (:func:`ftnav.io.ins_scenario_file.filter_model`).
    figures : the figures a run draws (``[[figures]]``); empty = the default figures.
    """

    name: str
    profile: Profile
    imu: ImuErrors
    error_model: ErrorModelParams
    initial_sigma: np.ndarray
    dt: float
    steps: int
    aids: tuple[AidSpec, ...]
    faults: tuple[InsFault, ...] = ()
    methods: tuple[Method, ...] = ()
    evaluation: Evaluation = field(default_factory=Evaluation)
    correction: Correction = "feedback"
    discretization: Literal["series", "van-loan"] = "series"
    description: str = ""
    test_profile: Profile | None = None
    algorithm: str = "two-sample"
    figures: tuple[FigureSpec, ...] = ()
    model_notes: tuple[str, ...] = ()

    kind = "integrated"

    # -- the attributes the metric, report and plot code read from a scenario --------
    @property
    def model(self) -> StateNames:
        return StateNames(METRIC_STATES)

    @property
    def sensors(self) -> tuple[AidSpec, ...]:
        return self.aids

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.aids)

    @property
    def times(self) -> np.ndarray:
        """(steps,) filter epoch times t_k = k·dt (s)."""
        return self.dt * np.arange(1, self.steps + 1)

    @property
    def samples_per_epoch(self) -> int:
        return int(round(self.dt / self.profile.dt))

    def fault_mask(self, sensor: str | None = None, detectable_only: bool = False) -> np.ndarray:
        """(steps,) bool, epochs inside a fault window (of ``sensor`` if given)."""
        return fault_window_mask(self.times, self.faults, sensor, detectable_only)

    def without_faults(self) -> InsScenario:
        return replace(self, faults=())
