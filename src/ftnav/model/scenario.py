"""Plain frozen numerical description of a linear multi-sensor scenario.

These containers are what the inner code sees; TOML files are parsed and
validated at the boundary (:mod:`ftnav.io.scenario_file`) and turned into them.
Every matrix is a float64 ``numpy`` array with its shape already checked.

Time base: step ``k = 1..steps`` happens at ``t_k = k·dt`` seconds; the initial
state ``x_0`` is at ``t = 0``.  A sensor with ``every = e`` and ``offset = o``
measures at the steps where ``(k − o) mod e == 0``.  Fault windows are
``start <= t_k < end`` in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

FaultKind = Literal["bias", "ramp", "noise-scale", "outage", "stuck"]
Architecture = Literal["centralized", "federated", "distributed", "neural"]
Mode = Literal["no-reset", "fusion-reset", "zero-reset", "rescale"]
Sharing = Literal[
    "equal", "fixed", "information", "trace", "eigen-trace", "frobenius", "inverse-trace"
]
Detector = Literal["none", "residual-chi2", "state-chi2", "oracle", "rbf"]
AdaptiveNoise = Literal["none", "vb", "vb-literal"]
Prior = Literal["local", "global", "intersection"]
TraceMode = Literal["scaled", "raw"]
Increment = Literal["direct", "difference"]
Isolation = Literal["standalone", "time-update"]
CommonMode = Literal["isolate", "keep"]
FigureKind = Literal["errors", "local-fused", "vb-noise"]
FigureCondition = Literal["faults", "fault-free"]

#: Most methods one figure compares: one line per method in every axes.
MAX_FIGURE_METHODS = 4


@dataclass(frozen=True, slots=True)
class PrivateStates:
    """Sensor-specific states carried only by that sensor's local filter (spec §1.7).

    Attributes
    ----------
    names : names of the p private states.
    F : (p, p) transition block.  Q : (p, p) process noise.
    x0 : (p,) initial mean.  P0 : (p, p) initial covariance.
    H : (m, p) measurement columns acting on the private states.
    """

    names: tuple[str, ...]
    F: np.ndarray
    Q: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    H: np.ndarray


@dataclass(frozen=True, slots=True)
class Sensor:
    """One aiding sensor: ``z = H x + v``, ``v ~ N(0, R)`` (spec §1.1).

    ``R`` is what the filters assume; ``R_true`` is what the simulator draws
    (equal to ``R`` unless the scenario sets it), so mismatch studies need no
    code change.
    """

    name: str
    H: np.ndarray
    R: np.ndarray
    R_true: np.ndarray
    every: int = 1
    offset: int = 0
    private: PrivateStates | None = None

    @property
    def dim(self) -> int:
        """Measurement dimension m."""
        return int(self.H.shape[0])

    def available(self, steps: int) -> np.ndarray:
        """Boolean (steps,) mask of the steps k = 1..steps with a measurement."""
        k = np.arange(1, steps + 1)
        return ((k - self.offset) % self.every == 0) & (k >= self.offset)


@dataclass(frozen=True, slots=True)
class LinearModel:
    """Common-state model ``x_{k+1} = F x_k + w_k``, ``w ~ N(0, Q)``."""

    states: tuple[str, ...]
    F: np.ndarray
    Q: np.ndarray
    x0: np.ndarray
    P0: np.ndarray
    Q_true: np.ndarray

    @property
    def n(self) -> int:
        """Number of common states."""
        return len(self.states)


@dataclass(frozen=True, slots=True)
class Fault:
    """A fault injected on one sensor over ``[start, end)`` seconds (spec §9.6).

    ``magnitude`` (m,) is the additive offset for ``bias`` (its final value for
    ``ramp``, which grows linearly from 0 over the window), the standard-deviation
    scale factor for ``noise-scale``, and unused for ``outage`` and ``stuck``.
    """

    sensor: str
    kind: FaultKind
    start: float
    end: float
    magnitude: np.ndarray


@dataclass(frozen=True, slots=True)
class Method:
    """One fusion method to evaluate; every field has a documented default.

    See ``docs/scenario-format.md`` for the meaning of each field.
    """

    name: str
    architecture: Architecture = "federated"
    mode: Mode = "fusion-reset"
    reset_interval: int = 1
    sharing: Sharing = "equal"
    betas: tuple[float, ...] = ()
    master_share: float = 0.0
    trace_mode: TraceMode = "scaled"
    detector: Detector = "none"
    false_alarm_probability: float = 1e-3
    window: int = 1
    prior: Prior = "local"
    n_on: int = 1
    n_off: int = 5
    state_test_reset: int = 100
    adaptive_noise: AdaptiveNoise = "none"
    vb_rho: float = 0.99
    vb_iterations: int = 3
    vb_sensors: tuple[str, ...] = ()
    increment: Increment = "direct"
    reconstructed: bool = False
    rescale_factor: float = 0.5
    model: str | None = None
    threshold: float | None = None
    uncovered: str = "renormalize"
    isolation: Isolation = "standalone"
    common_mode: CommonMode = "isolate"
    common_mode_quorum: int | None = None


@dataclass(frozen=True, slots=True)
class FigureSpec:
    """One figure a scenario asks for (``[[figures]]``, ``docs/scenario-format.md``).

    Attributes
    ----------
    name : file name without extension (``<name>.png``).
    title : the figure's title; empty = the scenario's description (or name).
    methods : the methods compared, at most :data:`MAX_FIGURE_METHODS`, one line each per
        axes; ``local-fused`` draws the local filters of the first one.
    states : the states drawn, one panel each; empty = every state (kind's default).
    kind : ``errors`` (estimation error per state), ``local-fused`` (integrated: local and
        fused position errors, paper 001 Fig. 4-5) or ``vb-noise`` (integrated: VB noise σ
        of ``sensor``, paper 002 Fig. 3, 5).
    condition : ``faults`` (the run with the faults) or ``fault-free`` (its fault-free twin).
    sensor : ``vb-noise`` only: the aid whose noise σ is drawn.
    """

    name: str
    title: str
    methods: tuple[str, ...]
    states: tuple[str, ...] = ()
    kind: FigureKind = "errors"
    condition: FigureCondition = "faults"
    sensor: str = ""


@dataclass(frozen=True, slots=True)
class Evaluation:
    """Metric settings (spec §11): initial convergence period and post-fault grace."""

    skip_initial: float = 0.0
    grace: float = 10.0


@dataclass(frozen=True, slots=True)
class Scenario:
    """A complete, validated linear scenario.

    ``figures`` are the figures a run draws (``[[figures]]``); empty = the default figures.
    """

    name: str
    dt: float
    steps: int
    model: LinearModel
    sensors: tuple[Sensor, ...]
    faults: tuple[Fault, ...] = ()
    methods: tuple[Method, ...] = ()
    evaluation: Evaluation = field(default_factory=Evaluation)
    description: str = ""
    figures: tuple[FigureSpec, ...] = ()

    @property
    def times(self) -> np.ndarray:
        """(steps,) epoch times t_k = k·dt in seconds."""
        return self.dt * np.arange(1, self.steps + 1)

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    def fault_mask(self, sensor: str | None = None, detectable_only: bool = False) -> np.ndarray:
        """Boolean (steps,) mask of epochs inside a fault window.

        Parameters
        ----------
        sensor : restrict to faults of this sensor (all sensors if None).
        detectable_only : leave out outages (no data, nothing to detect).
        """
        return fault_window_mask(self.times, self.faults, sensor, detectable_only)

    def without_faults(self) -> Scenario:
        """The same scenario with no faults (the paper's Fig. 3 condition)."""
        return Scenario(
            self.name,
            self.dt,
            self.steps,
            self.model,
            self.sensors,
            (),
            self.methods,
            self.evaluation,
            self.description,
            self.figures,
        )


def fault_window_mask(
    times: np.ndarray, faults, sensor: str | None = None, detectable_only: bool = False
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
