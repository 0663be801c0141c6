"""The detector piece of an architecture: which test, on what, with which state (spec §3-4).

:class:`Detection` is built once from a method's detector settings (and, for the RBF
network, its trained model, loaded at the boundary) and runs one epoch of the test:

* ``residual-chi2`` thresholds, windows and debounces the residual statistic the
  architecture computed against the configured reference (spec §3.1);
* ``state-chi2`` the state statistic against a pure propagator per local filter,
  restarted every ``reset`` epochs (spec §3.2, :class:`StateTest`);
* ``cusum`` and ``glr`` the sequential tests of spec §3.3 on each aid's whitened
  innovation against the configured reference (:mod:`ftnav.fdi.sequential`), on the
  aids of a device only: a gated pseudo-measurement (a vehicle constraint,
  :class:`~ftnav.model.system.Sensor` ``gate``) is judged epoch by epoch by its gate.
  A sequential test sums evidence of a lasting shift of a device's error, and a
  constraint has no device: what shifts its innovation's mean is the vehicle (a turn's
  slip, the IMU's lever arm to the axle), which lasts as long as the turn and which
  isolating the constraint does not remove.  Where the constraint is the only aid
  (a GNSS outage) the isolation leaves the INS to coast: on the drive with 15 s
  outages the GLR's alarms on the NHC in turns made the error after the outages 1.55
  times the plain filter's (``docs/integrity.md`` §2);
* ``separation`` is the guard's own test (:mod:`ftnav.fusion.guard`): no output here;
* ``rbf`` evaluates the network on the epoch's features (spec §4);
* ``oracle`` returns the labelled fault windows of a simulated stream;
* ``none`` returns no output: every filter is fused.

The architectures differ in what they test and what they do with a flag (isolation,
fault factors, bank selection), not in this piece.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from ftnav.core.kalman import Gaussian
from ftnav.fdi.chi2 import ChiSquareDetector, DetectorOutput, state_statistic
from ftnav.fdi.features import detector_features, whitened_innovation
from ftnav.fdi.rbf import RBFDetector, RBFModel
from ftnav.fdi.sequential import CusumDetector, GlrDetector
from ftnav.fusion.config import (
    Cusum,
    Detector,
    Glr,
    RbfDetector,
    ResidualChi2,
    Separation,
    StateChi2,
)
from ftnav.fusion.locals import LocalBank, NoiseState
from ftnav.fusion.protocol import with_common
from ftnav.model.system import Epoch, Sensor

__all__ = ["Detection", "FeatureRequest", "StateTest", "epoch_features", "features_needed"]


class StateTest:
    """Pure propagators of the state chi-square test, one per local (spec §3.2).

    The propagator ``x̂ˢ = Φ x̂ˢ``, ``Pˢ = Φ Pˢ Φᵀ + Q`` restarts from the local
    posterior every ``reset`` epochs; the first 3 epochs after a restart are not
    tested because ``Pˢ − P`` is ill-conditioned then.
    """

    SKIP = 3

    def __init__(self, reset: int):
        self.reset = int(reset)

    def statistic(
        self, k: int, x: np.ndarray, P: np.ndarray, xs: np.ndarray, Ps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(statistic, dof, tested) at step k for posterior (x, P), propagator (xs, Ps)."""
        age = (k - 1) % self.reset + 1
        lam, dof = state_statistic(x, P, xs, Ps)
        tested = np.full(lam.shape, age > self.SKIP)
        return lam, dof, tested

    def restart(
        self, k: int, x: np.ndarray, P: np.ndarray, xs: np.ndarray, Ps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Restart the propagator from the posterior at the end of a period."""
        if k % self.reset == 0:
            return x, P
        return xs, Ps


class Detection:
    """One method's detector (module docstring).

    Parameters
    ----------
    config : the method's detector settings.
    model : the trained RBF model (``kind = "rbf"`` only).
    sensors : the aids, in the architecture's order: their measurement dimensions (the
        sequential tests' components), and which are gated pseudo-measurements, which
        the sequential tests leave out (module docstring).
    """

    def __init__(
        self, config: Detector, model: RBFModel | None = None, sensors: Sequence[Sensor] = ()
    ):
        self.config = config
        dims = [s.dim for s in sensors]
        #: (N,) the aids the sequential tests run on: a device's, not a gated constraint's
        self.devices = np.array([s.gate is None for s in sensors], dtype=bool)
        self.kind = config.kind
        self.chi2: ChiSquareDetector | None = None
        self.rbf: RBFDetector | None = None
        self.state_test: StateTest | None = None
        self.sequential: CusumDetector | GlrDetector | None = None
        if isinstance(config, Cusum):
            self.sequential = CusumDetector(
                dims, config.arl0, config.drift, config.variance_ratio, config.n_on, config.n_off
            )
        if isinstance(config, Glr):
            self.sequential = GlrDetector(
                dims, config.arl0, config.window, config.n_on, config.n_off, config.memory
            )
        if isinstance(config, ResidualChi2 | StateChi2):
            self.chi2 = ChiSquareDetector(
                config.false_alarm_probability, config.window, config.n_on, config.n_off
            )
        if isinstance(config, StateChi2):
            self.state_test = StateTest(config.reset)
        if isinstance(config, RbfDetector):
            assert model is not None, "an RBF detector needs its trained model"
            self.rbf = RBFDetector(model, config.threshold, config.n_on, config.n_off)

    @property
    def residual(self) -> bool:
        """Whether the architecture must compute the residual statistic (spec §3.1)."""
        return self.kind == "residual-chi2"

    @property
    def separation(self) -> Separation | None:
        """The separation detector's settings (the guard runs it), or None."""
        return self.config if isinstance(self.config, Separation) else None

    @property
    def whitened(self) -> bool:
        """Whether the architecture must compute each aid's whitened innovation (§3.3)."""
        return self.sequential is not None

    @property
    def prior(self) -> str:
        """Reference of the residual test (or of the RBF innovations): local | global | ..."""
        if self.rbf is not None:
            return self.rbf.model.prior
        if isinstance(self.config, ResidualChi2 | Cusum | Glr):
            return self.config.prior
        return "local"

    @property
    def features(self) -> tuple[str, ...] | None:
        """Feature kinds the RBF network reads (spec §4.1), None for other detectors."""
        return None if self.rbf is None else self.rbf.features

    def init(self, batch: int, n_filters: int) -> Any:
        detector = self.chi2 or self.rbf or self.sequential
        return None if detector is None else detector.init(batch, n_filters)

    def step(
        self,
        state: Any,
        statistic: np.ndarray,
        dof: np.ndarray,
        tested: np.ndarray,
        labels: np.ndarray,
        features: np.ndarray | None = None,
        innovations: Sequence[np.ndarray] | None = None,
    ) -> tuple[Any, DetectorOutput | None]:
        """One epoch of the test; ``labels`` (N,) or (B, N): the labelled fault windows;
        ``innovations`` per aid (B, m_i) whitened (the sequential tests)."""
        if self.sequential is not None:
            assert state is not None and innovations is not None
            return self.sequential.step(state, innovations, tested & self.devices)
        if self.rbf is not None:
            assert state is not None and features is not None
            return self.rbf.step(state, features, tested)
        if self.chi2 is not None:
            assert state is not None
            return self.chi2.step(state, statistic, dof, tested)
        if self.kind == "oracle":
            flag = np.broadcast_to(np.asarray(labels, dtype=bool), statistic.shape).copy()
            return state, DetectorOutput(
                np.zeros_like(statistic), np.full_like(statistic, np.inf), flag, flag
            )
        return state, None


class FeatureRequest(NamedTuple):
    """What the learned-detector features of an epoch need: their kinds and reference."""

    kinds: tuple[str, ...]
    prior: str


def features_needed(
    detection: Detection, extra: tuple[str, ...] | None, prior: str
) -> FeatureRequest | None:
    """The features an architecture must compute each epoch, or None.

    The RBF network's kinds and trained prior, or ``extra`` (training-data collection)
    with the method's test reference ``prior``.
    """
    if detection.rbf is not None:
        return FeatureRequest(
            tuple(extra) if extra else detection.rbf.features, detection.rbf.model.prior
        )
    return FeatureRequest(tuple(extra), prior) if extra else None


def epoch_features(
    request: FeatureRequest,
    bank: LocalBank,
    priors: Sequence[Gaussian],
    posts: Sequence[Gaussian],
    reference: Gaussian,
    epoch: Epoch,
    usable: np.ndarray,
    noise: Sequence[NoiseState | None],
    Hs: Sequence[np.ndarray],
) -> np.ndarray:
    """(B, F) spec §4.1 features: posterior − reference, whitened innovations.

    The innovations are whitened against each local prior, or with ``prior = "global"``
    against the prior with its common block replaced by the reference (the fused
    prior); the state differences use the reference's common states.
    """
    nc = bank.nc
    innov = []
    for i in range(bank.N):
        base = with_common(priors[i], *reference) if request.prior == "global" else priors[i]
        innov.append(
            whitened_innovation(*base, epoch.z[i], usable[:, i], Hs[i], bank.noise_now(i, noise[i]))
        )
    xl = np.stack([p[0][:, :nc] for p in posts], 1)
    vl = np.stack([np.diagonal(p[1], axis1=-2, axis2=-1)[:, :nc] for p in posts], 1)
    return detector_features(request.kinds, xl, vl, reference[0][:, :nc], innov)
