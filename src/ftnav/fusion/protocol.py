"""The one protocol every fusion architecture implements, and what a step returns.

An architecture is a thin, stateless object over the kernel (:mod:`ftnav.core`): it
holds the system and its frozen configuration; the running estimate is an explicit
state it takes in and returns (style §1, navlie).  The engine
(:func:`ftnav.engine.driver.run`) only ever calls these four members, so a new
architecture is one module that implements them plus one line in
:mod:`ftnav.fusion.registry`.
"""

from __future__ import annotations

from typing import NamedTuple, Protocol, TypeVar

import numpy as np

from ftnav.core.kalman import Gaussian
from ftnav.fdi.chi2 import DetectorOutput
from ftnav.fusion.guard import GuardOutput
from ftnav.model.system import Epoch

__all__ = ["Architecture", "StepOutput", "minus", "select", "with_common"]

S = TypeVar("S")


class StepOutput(NamedTuple):
    """What every architecture reports per epoch.

    Attributes
    ----------
    x : (B, n_c) fused estimate of the common states.
    P : (B, n_c, n_c) its covariance.
    beta : (B, N) sharing coefficients in effect (federated only) or None.
    detection : detector output (B, N) per local filter / sensor, or None.
    R_hat : per sensor (B, m_i) diagonal of the noise used (adapted under VB).
    nan : (B, N) bool, scheduled measurements that were NaN/inf (treated as missing).
    features : (B, F) learned-detector features of the epoch (spec §4.1), or None.
    guard : what the isolation guard did (:mod:`ftnav.fusion.guard`), or None.
    nis : (B, N) each aid's NIS against the method's own prediction of it (its fused
        prior, a neuron centre's bound), 0 where the aid has no finite measurement: what
        the filter watches its consistency with (:mod:`ftnav.eval.integrity`); or None.
    used : (B, N) bool, the aids whose measurement updated the method this epoch (after
        the gates and the isolation), or None.
    available : (B, N) bool, the aids with a finite measurement this epoch (before the
        gates and the isolation), or None.
    """

    x: np.ndarray
    P: np.ndarray
    beta: np.ndarray | None
    detection: DetectorOutput | None
    R_hat: tuple[np.ndarray, ...]
    nan: np.ndarray
    features: np.ndarray | None = None
    guard: GuardOutput | None = None
    nis: np.ndarray | None = None
    used: np.ndarray | None = None
    available: np.ndarray | None = None


class Architecture(Protocol[S]):
    """A fusion architecture: initial state, one epoch, the feedback shift, the locals."""

    @property
    def n_filters(self) -> int:
        """Local filters (or sensors, for the centralized filter)."""
        ...

    def init(self, batch: int) -> S:
        """The state of ``batch`` runs before the first epoch."""
        ...

    def step(self, state: S, epoch: Epoch) -> tuple[S, StepOutput]:
        """Advance one epoch: predict, update, test, fuse."""
        ...

    def shift(self, state: S, delta: np.ndarray) -> S:
        """Every estimate minus ``delta`` (B, d) on its first d states (spec §6.2, §8.5).

        Called after the fused error estimate was fed back to the SINS: the reference
        every filter linearizes about moved by ``delta``; covariances do not change.
        """
        ...

    def local_estimates(self, state: S, n: int) -> np.ndarray | None:
        """(B, N, n) the local filters' estimates of the first n states, or None."""
        ...


def select(mask: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` where ``mask`` (B,) else ``b``, broadcasting over trailing axes."""
    if mask.all():
        return a
    if not mask.any():
        return b
    m = np.asarray(mask).reshape(mask.shape + (1,) * (a.ndim - mask.ndim))
    return np.where(m, a, b)


def with_common(prior: Gaussian, xc: np.ndarray, Pc: np.ndarray) -> Gaussian:
    """A local prior ``(x, P)`` with its common block replaced by ``(xc, Pc)``.

    Private states keep their prior; their cross-covariance with the common block
    is set to zero.  This is the prior of a residual test against a fused
    reference (spec §3.1 with ``prior = "global"``).
    """
    nc = xc.shape[-1]
    x, P = prior
    if x.shape[-1] == nc:
        return Gaussian(xc, Pc)
    x_g = np.concatenate([xc, x[:, nc:]], 1)
    P_g = P.copy()
    P_g[:, :nc, :nc] = Pc
    P_g[:, :nc, nc:] = 0.0
    P_g[:, nc:, :nc] = 0.0
    return Gaussian(x_g, P_g)


def minus(x: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``x`` with ``delta`` (B, d) subtracted from its first d states (a copy)."""
    n = delta.shape[-1]
    out = x.copy()
    out[..., :n] -= delta
    return out
