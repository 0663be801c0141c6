"""Plain frozen descriptions of a scenario: linear (spec §1, §9.6) or integrated (§8-§10).

These containers are what the inner code sees; TOML files are parsed and validated at
the boundary (:mod:`ftnav.io.scenario_file`, :mod:`ftnav.io.ins_scenario_file`) and
turned into them.  Every matrix is a float64 ``numpy`` array with its shape checked.

Time base: step ``k = 1..steps`` happens at ``t_k = k·dt`` seconds; the initial state
is at ``t = 0``.  A sensor with ``every = e`` and ``offset = o`` measures at the steps
where ``(k − o) mod e == 0``.  Fault windows are ``start <= t_k < end`` in seconds.

Both kinds answer what evaluation and reporting read (:class:`ScenarioBase`): the
names of the reported states (``metric_states``), the sensors, the epoch times, the
fault windows.  A linear scenario reports its model's states (estimate − truth); an
integrated one the navigation *output* errors (computed − true, spec §11): position
East/North/Up in metres, velocity East/North/Up in m/s, attitude φ East/North/Up in
arcmin.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar, Literal, Self

import numpy as np

from ftnav.model.flight import Profile
from ftnav.model.imu import ImuErrors
from ftnav.model.system import LinearModel, LinearSystem, Sensor
from ftnav.nav.error_model import ErrorModelParams

__all__ = [
    "AidSpec",
    "Evaluation",
    "Fault",
    "FigureSpec",
    "INS_FAULT_KINDS",
    "InsScenario",
    "LINEAR_FAULT_KINDS",
    "MAX_FIGURE_METHODS",
    "METRIC_STATES",
    "POSITION_NORMS",
    "Recording",
    "SINS",
    "Scenario",
    "ScenarioBase",
    "fault_window_mask",
    "SinsScenario",
]

FaultKind = Literal["bias", "ramp", "noise-scale", "noise-ramp", "outage", "stuck", "gyro-bias"]
#: fault kinds of a linear scenario (spec §9.6)
LINEAR_FAULT_KINDS: tuple[str, ...] = ("bias", "ramp", "noise-scale", "outage", "stuck")
#: fault kinds of an integrated scenario: those, a noise ramp, and the SINS gyro-bias step
INS_FAULT_KINDS: tuple[str, ...] = (
    "bias",
    "ramp",
    "noise-scale",
    "noise-ramp",
    "outage",
    "stuck",
    "gyro-bias",
)
FigureKind = Literal["errors", "local-fused", "vb-noise"]
FigureCondition = Literal["faults", "fault-free"]
Correction = Literal["feedback", "output"]

#: Most methods one figure compares: one line per method in every axes.
MAX_FIGURE_METHODS = 4

#: Reported output-error states of an integrated run (spec §11), in this order.
METRIC_STATES = (
    "pos_E_m", "pos_N_m", "pos_U_m",
    "vel_E_m_s", "vel_N_m_s", "vel_U_m_s",
    "att_E_arcmin", "att_N_arcmin", "att_U_arcmin",
)  # fmt: skip

#: Derived metric quantities (m): horizontal sqrt(E² + N²) and 3-D position error (spec §11).
POSITION_NORMS = ("pos_horizontal_m", "pos_3d_m")

#: Name that addresses the inertial system in a fault.
SINS = "sins"


@dataclass(frozen=True, slots=True)
class Fault:
    """A fault injected on one sensor (or the SINS) over ``[start, end)`` seconds (§9.6).

    ``magnitude`` is in the sensor's measurement space (an aid's ``components``): the
    additive offset for ``bias`` (its final value for ``ramp``, which grows linearly
    from 0 over the window), the noise-std factor for ``noise-scale`` (reached at
    ``end`` for ``noise-ramp``, which starts at 1), unused for ``outage`` and
    ``stuck``; for ``gyro-bias`` on the SINS the (3,) body gyro-bias step in rad/s.
    """

    sensor: str
    kind: FaultKind
    start: float
    end: float
    magnitude: np.ndarray


@dataclass(frozen=True, slots=True)
class FigureSpec:
    """One figure of a run (``[[figures]]``), validated against the scenario.

    Attributes
    ----------
    name : file stem (``<name>.png``).
    title : figure title (empty: the scenario's description or name).
    methods : the methods it compares, at most :data:`MAX_FIGURE_METHODS`.
    states : one panel per state (empty: every state).
    kind : ``errors`` (estimation error per state), ``local-fused`` (integrated: local and
        fused position errors, paper 001 Fig. 4-5) or ``vb-noise`` (integrated: VB noise σ
        of ``sensor``, paper 002 Fig. 3, 5).
    condition : ``faults`` (the run with the faults) or ``fault-free`` (its fault-free twin).
    sensor : ``vb-noise`` only: the aid whose noise σ is drawn.
    flight : ``first`` (the scenario's profile) or ``second`` (its ``test_profile``: the
        flight the learned methods were not trained on, paper 001 Fig. 5).
    """

    name: str
    title: str
    methods: tuple[str, ...]
    states: tuple[str, ...] = ()
    kind: FigureKind = "errors"
    condition: FigureCondition = "faults"
    sensor: str = ""
    flight: Literal["first", "second"] = "first"


@dataclass(frozen=True, slots=True)
class Evaluation:
    """Metric settings (spec §11): initial convergence period and post-fault grace; what
    the method watches itself against (:mod:`ftnav.eval.integrity`): the NIS window and
    the probability outside its band, the bound on the horizontal position σ (None: no
    bound), the least availability and use of an aid."""

    skip_initial: float = 0.0
    grace: float = 10.0
    watch_window_s: float = 60.0
    watch_probability: float = 0.01
    sigma_bound_m: float | None = None
    min_availability: float = 0.5


def fault_window_mask(
    times: np.ndarray,
    faults: Sequence[Fault],
    sensor: str | None = None,
    detectable_only: bool = False,
) -> np.ndarray:
    """Boolean mask of the ``times`` inside a fault window ``[start, end)``.

    ``sensor`` restricts to that sensor's faults; ``detectable_only`` leaves out
    outages (no data, nothing to detect).
    """
    mask = np.zeros(times.shape, dtype=bool)
    for f in faults:
        if sensor is not None and f.sensor != sensor:
            continue
        if detectable_only and f.kind == "outage":
            continue
        mask |= (times >= f.start) & (times < f.end)
    return mask


@dataclass(frozen=True, kw_only=True)
class ScenarioBase:
    """What both kinds of scenario have and what evaluation and reporting read.

    ``methods`` are the methods' frozen configurations (:mod:`ftnav.fusion.config`);
    ``learned`` the trained models some of them use, ``(method name,``
    :class:`~ftnav.fusion.config.Learned` ``)`` pairs loaded and checked at the boundary.
    """

    name: str
    dt: float
    steps: int
    faults: tuple[Fault, ...] = ()
    methods: tuple[Any, ...] = ()
    evaluation: Evaluation = field(default_factory=Evaluation)
    description: str = ""
    figures: tuple[FigureSpec, ...] = ()
    learned: tuple[tuple[str, Any], ...] = ()
    builtin: str | None = None
    """The built-in scenario this was read from (its file, unchanged, wherever it lies),
    whose paper claims apply to it (:func:`ftnav.report.claims.papers_of`); None for
    every other scenario, whatever its name and methods."""

    kind: ClassVar[str] = "linear"

    @property
    def times(self) -> np.ndarray:
        """(steps,) epoch times t_k = k·dt in seconds."""
        return self.dt * np.arange(1, self.steps + 1)

    @property
    def sensor_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def metric_states(self) -> tuple[str, ...]:
        """Names of the reported states (the columns of every per-state metric)."""
        raise NotImplementedError

    def learned_for(self, method: str) -> Any:
        """The trained models of method ``method`` (None when it uses none)."""
        return dict(self.learned).get(method)

    def system(self) -> LinearSystem:
        """The filters' system: the common model and the sensors (spec §1.1, §1.7)."""
        raise NotImplementedError

    def fault_mask(self, sensor: str | None = None, detectable_only: bool = False) -> np.ndarray:
        """Boolean (steps,) mask of epochs inside a fault window.

        Parameters
        ----------
        sensor : restrict to faults of this sensor (all sensors if None).
        detectable_only : leave out outages (no data, nothing to detect).
        """
        return fault_window_mask(self.times, self.faults, sensor, detectable_only)

    def without_faults(self) -> Self:
        """The same scenario with no faults (paper 000 Fig. 3 condition)."""
        return replace(self, faults=())


@dataclass(frozen=True, kw_only=True)
class Scenario(ScenarioBase):
    """A complete, validated linear scenario: a model, sensors, faults and methods."""

    model: LinearModel
    sensors: tuple[Sensor, ...]

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    @property
    def metric_states(self) -> tuple[str, ...]:
        return self.model.states

    def system(self) -> LinearSystem:
        return LinearSystem(self.model, self.sensors)


@dataclass(frozen=True, slots=True)
class AidSpec:
    """One aid of an integrated scenario: its sensor model (:mod:`ftnav.sensors`), its
    schedule in filter epochs."""

    sensor: Any
    every: int = 1
    offset: int = 0

    @property
    def name(self) -> str:
        return str(self.sensor.name)

    @property
    def dim(self) -> int:
        return int(self.sensor.dim)

    def __post_init__(self) -> None:
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


@dataclass(frozen=True, kw_only=True)
class SinsScenario(ScenarioBase):
    """What an integrated scenario and a recording share: a SINS aided by sensors.

    Attributes
    ----------
    error_model : the filters' assumed SINS error model.
    initial_sigma : (n,) σ of the initial INS errors in state units (spec §8.3 order);
        the filters start from ``P0 = diag σ²`` (a simulated run also draws its initial
        error from N(0, diag σ²)).
    aids : the aiding sensors.
    correction : ``"feedback"`` (closed loop: the fused navigation errors are fed back
        to the SINS and every local estimate is shifted by the same correction, spec
        §6.2, §8.5) or ``"output"`` (the SINS runs free; its output is corrected).
    discretization : ``"series"`` (order 5, PSINS kfc2d) or ``"van-loan"``.
    algorithm : the strapdown algorithm (:mod:`ftnav.nav.mechanization`).
    bias_compensation : with feedback, the estimated IMU biases are fed back too and
        subtracted from the increments before the mechanization
        (:class:`ftnav.engine.ins.InsModel`); recordings default to it, scenarios not
        (the papers feed back the navigation errors only).
    """

    error_model: ErrorModelParams
    initial_sigma: np.ndarray
    aids: tuple[AidSpec, ...]
    correction: Correction = "feedback"
    discretization: Literal["series", "van-loan"] = "series"
    algorithm: str = "two-sample"
    bias_compensation: bool = False

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.aids)

    @property
    def metric_states(self) -> tuple[str, ...]:
        return METRIC_STATES

    def system(self) -> LinearSystem:
        """The local SINS/aid filters' system: the error states (spec §8.3), ``P0 = diag σ²``,
        each aid's noise and private states; Φ, Q and H come with every epoch."""
        n = self.error_model.n
        P0 = np.diag(np.asarray(self.initial_sigma[:n], float) ** 2)
        model = LinearModel(self.error_model.names, None, None, np.zeros(n), P0, None)
        sensors = tuple(
            Sensor(
                a.name,
                None,
                a.sensor.R,
                a.sensor.R,
                a.every,
                a.offset,
                a.sensor.private,
                getattr(a.sensor, "gate_probability", 0.0) or None,
                type(a.sensor).__name__,  # one receiver's position and velocity aids
            )
            for a in self.aids
        )
        return LinearSystem(model, sensors)


@dataclass(frozen=True, kw_only=True)
class InsScenario(SinsScenario):
    """A complete, validated integrated-navigation scenario (a simulated flight).

    Attributes
    ----------
    profile : flight profile (the truth); its ``dt`` is the IMU period.
    imu : true IMU errors (simulator).
    test_profile : optional second flight for the "different trajectory" evaluation of
        learned methods (paper 001).
    model_notes : the IMU errors the filters' error model cannot represent exactly, and
        what it does instead (:func:`ftnav.io.ins_scenario_file.filter_model`).
    The rest as :class:`SinsScenario`.
    """

    profile: Profile
    imu: ImuErrors
    test_profile: Profile | None = None
    model_notes: tuple[str, ...] = ()

    kind: ClassVar[str] = "integrated"

    @property
    def samples_per_epoch(self) -> int:
        return int(round(self.dt / self.profile.dt))


@dataclass(frozen=True, kw_only=True)
class Recording(SinsScenario):
    """A recorded sensor log as the engine runs it (:mod:`ftnav.recorded`).

    Times: ``dt·k`` after ``t_start`` (the first filter epoch is ``t_start + dt``), on
    the recording's own time base; ``t_origin`` is its first GNSS epoch (outage
    schedules count from it).  ``faults`` are injected into the recorded aids, on
    times relative to ``t_start`` like :attr:`times`.

    Attributes
    ----------
    t_start, t_origin : s, recording time base.
    samples_per_epoch : IMU increments per filter epoch (the log resampled exactly).
    The rest as :class:`SinsScenario`.
    """

    t_start: float
    t_origin: float
    samples_per_epoch: int

    kind: ClassVar[str] = "recorded"
