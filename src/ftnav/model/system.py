"""The multi-sensor system as the filters see it (spec §1.1, §1.7), and one epoch of it.

The *augmented* state is ``[x_c; x_s1; x_s2; ...]``: the ``n_c`` common states
followed by each sensor's private states (if any).  The centralized and the
distributed filters work on the augmented state; local filter ``i`` of the
federated filter carries ``[x_c; x_si]`` and fuses only ``x_c``.

A system is *constant* (a linear scenario: ``F``, ``Q`` and every sensor's ``H``
given) or *linearized* (integrated navigation: ``F``, ``Q`` and the sensors' ``H`` are
None and come with each :class:`Epoch` as a :class:`Linearization`, per run).  The
private states' blocks, the measurement noise and the initial covariance are constant
in both.  An :class:`Epoch` is what the engine hands every architecture once per step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.linalg import block_diag

__all__ = [
    "Epoch",
    "Linearization",
    "LinearModel",
    "LinearSystem",
    "LocalModel",
    "PrivateStates",
    "Sensor",
]


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
    code change.  ``H`` is None for a sensor linearized at every epoch.  ``gate`` (a
    probability, or None) makes it a pseudo-measurement used only where its innovation's
    χ² passes that gate: a vehicle constraint that does not hold at that epoch (a slip in
    a turn, a creep mistaken for a stop) is left out, neither used nor tested.
    ``device`` names the instrument the aid comes from where several aids share one (a
    receiver's positions and velocities); None: the aid is its own.
    """

    name: str
    H: np.ndarray | None
    R: np.ndarray
    R_true: np.ndarray
    every: int = 1
    offset: int = 0
    private: PrivateStates | None = None
    gate: float | None = None
    device: str | None = None

    @property
    def dim(self) -> int:
        """Measurement dimension m."""
        return int(self.R.shape[0])

    def available(self, steps: int) -> np.ndarray:
        """Boolean (steps,) mask of the steps k = 1..steps with a measurement."""
        k = np.arange(1, steps + 1)
        return ((k - self.offset) % self.every == 0) & (k >= self.offset)


@dataclass(frozen=True, slots=True)
class LinearModel:
    """Common-state model ``x_{k+1} = F x_k + w_k``, ``w ~ N(0, Q)``.

    ``F``, ``Q`` and ``Q_true`` are None for a model linearized at every epoch.
    """

    states: tuple[str, ...]
    F: np.ndarray | None
    Q: np.ndarray | None
    x0: np.ndarray
    P0: np.ndarray
    Q_true: np.ndarray | None

    @property
    def n(self) -> int:
        """Number of common states."""
        return len(self.states)


class Linearization(NamedTuple):
    """One epoch's matrices of an error-state model linearized per run (spec §6.2, §8.4).

    An integrated-navigation filter linearizes the SINS error model and every aid's
    measurement at each run's own INS solution, so the matrices carry the batch axis;
    all local filters and the fusion centre use the *same* matrices (identical
    linearization, spec §6.2).

    Attributes
    ----------
    Phi : (B, n_c, n_c) common-state transition over the step ``k−1 → k``.
    Q : (B, n_c, n_c) its discrete process noise.
    H : per sensor, (B, m_i, n_c + p_i) local measurement matrix (common columns, then
        the sensor's private states).
    """

    Phi: np.ndarray
    Q: np.ndarray
    H: tuple[np.ndarray, ...]


class TimeVarying(NamedTuple):
    """Per-epoch common ``(Φ_k, Q_k)`` (K, n_c, n_c) each of a time-varying linear model."""

    Phi: np.ndarray
    Q: np.ndarray


class Epoch(NamedTuple):
    """Everything an architecture receives for the step ``k−1 → k``.

    Attributes
    ----------
    k : epoch index (1-based), at ``t_k``.
    z : per sensor (B, m_i) measurement (NaN or garbage where not available).
    available : (B, N) bool, a measurement is scheduled (schedule and outages).
    labels : (N,) or (B, N) bool, labelled fault windows of a simulated stream (read
        by the ``oracle`` detector only; all False for a recorded stream).
    lin : the epoch's per-run matrices of a linearized system, None for a constant one.
    repeated : (B, N) bool, the sensor's output repeats its previous one bit for bit
        (:func:`ftnav.model.streams.repeated`), or None (not known).
    """

    k: int
    z: tuple[np.ndarray, ...]
    available: np.ndarray
    labels: np.ndarray
    lin: Linearization | None = None
    repeated: np.ndarray | None = None


@dataclass(frozen=True, slots=True)
class LocalModel:
    """Model of one local filter over ``[x_c; x_si]`` (dimension ``n_c + p_i``)."""

    H: np.ndarray | None  # (m, n_c + p), None when linearized per epoch
    R: np.ndarray  # (m, m)
    x0: np.ndarray  # (n_c + p,)
    P0: np.ndarray  # (n_c + p, n_c + p)
    F_private: np.ndarray  # (p, p)
    Q_private: np.ndarray  # (p, p)
    aug_index: np.ndarray  # positions of the local states inside the augmented state

    @property
    def n(self) -> int:
        return int(self.x0.shape[0])


@dataclass(frozen=True)
class LinearSystem:
    """The filters' system: the common model and the sensors (constant or linearized)."""

    model: LinearModel
    sensors: tuple[Sensor, ...]
    _blocks: tuple[tuple[np.ndarray, np.ndarray], ...] = field(init=False, repr=False)
    _aug: dict[bool, tuple[np.ndarray, np.ndarray]] = field(init=False, repr=False)
    _locals: tuple[LocalModel, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = self.model.n
        # a linearized model's common corner is replaced by the epoch's (Φ, Q)
        F = np.zeros((n, n)) if self.model.F is None else self.model.F
        Q = np.zeros((n, n)) if self.model.Q is None else self.model.Q
        Q_true = Q if self.model.Q_true is None else self.model.Q_true
        locals_ = tuple(self._make_local(i) for i in range(len(self.sensors)))
        object.__setattr__(self, "_locals", locals_)
        object.__setattr__(
            self,
            "_blocks",
            tuple((block_diag(F, lm.F_private), block_diag(Q, lm.Q_private)) for lm in locals_),
        )
        object.__setattr__(
            self,
            "_aug",
            {
                true: (
                    block_diag(F, *self._private_blocks("F")),
                    block_diag(Q_true if true else Q, *self._private_blocks("Q")),
                )
                for true in (False, True)
            },
        )

    @property
    def linearized(self) -> bool:
        """True when Φ, Q and H come with every epoch (integrated navigation)."""
        return self.model.F is None

    @property
    def n_common(self) -> int:
        return self.model.n

    @property
    def n_sensors(self) -> int:
        return len(self.sensors)

    def _private_blocks(self, attr: str) -> list[np.ndarray]:
        return [getattr(s.private, attr) for s in self.sensors if s.private is not None]

    @property
    def n_aug(self) -> int:
        return self.n_common + sum(len(s.private.names) for s in self.sensors if s.private)

    @property
    def has_private(self) -> bool:
        return any(s.private is not None for s in self.sensors)

    # -- common / augmented matrices ---------------------------------------------
    def transition(self, lin: Linearization | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Common-state ``(F, Q)`` of the step (the filter's assumed Q)."""
        if lin is not None:
            return lin.Phi, lin.Q
        assert self.model.F is not None and self.model.Q is not None, "linearized system"
        return self.model.F, self.model.Q

    def augmented_transition(
        self, true: bool = False, lin: Linearization | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Augmented ``(F, Q)``; ``true=True`` gives the simulator's ``Q_true``."""
        if lin is not None:
            return _with_batch_common(*self._aug[False], lin)
        return self._aug[true]

    def augmented_initial(self) -> tuple[np.ndarray, np.ndarray]:
        """Augmented ``(x0, P0)``."""
        x0 = np.concatenate([self.model.x0, *self._private_blocks("x0")])
        return x0, block_diag(self.model.P0, *self._private_blocks("P0"))

    def augmented_H(self, i: int, lin: Linearization | None = None) -> np.ndarray:
        """Sensor i's measurement matrix over the augmented state, (m, n_aug).

        With ``lin``: the epoch's per-run matrix, (B, m, n_aug).
        """
        s = self.sensors[i]
        if lin is not None and self.n_aug == self.n_common:
            return lin.H[i]  # no private states: the augmented state is the common one
        index = self._locals[i].aug_index
        if lin is not None:
            Hl = lin.H[i]
            H = np.zeros(Hl.shape[:-1] + (self.n_aug,))
            H[..., index] = Hl
            return H
        assert s.H is not None, "linearized sensor"
        H = np.zeros((s.dim, self.n_aug))
        H[:, : self.n_common] = s.H
        if s.private is not None:
            H[:, index[self.n_common :]] = s.private.H
        return H

    def local_H(self, i: int, lin: Linearization | None = None) -> np.ndarray:
        """Local filter i's measurement matrix: (m, n_i), or the epoch's (B, m, n_i)."""
        if lin is not None:
            return lin.H[i]
        H = self._locals[i].H
        assert H is not None, "linearized sensor"
        return H

    def local(self, i: int) -> LocalModel:
        """Local filter i's model over ``[x_c; x_si]``."""
        return self._locals[i]

    def _make_local(self, i: int) -> LocalModel:
        s = self.sensors[i]
        nc = self.n_common
        offset = nc
        for j in range(i):
            prev = self.sensors[j].private
            if prev is not None:
                offset += len(prev.names)
        if s.private is None:
            p = 0
            H, x0, P0 = s.H, self.model.x0, self.model.P0
            Fp = Qp = np.zeros((0, 0))
        else:
            p = len(s.private.names)
            H = None if s.H is None else np.hstack([s.H, s.private.H])
            x0 = np.concatenate([self.model.x0, s.private.x0])
            P0 = block_diag(self.model.P0, s.private.P0)
            Fp, Qp = s.private.F, s.private.Q
        index = np.concatenate([np.arange(nc), np.arange(offset, offset + p)]).astype(int)
        return LocalModel(H, s.R, x0, P0, Fp, Qp, index)

    def local_transition(
        self, i: int, common_scale: np.ndarray | None = None, lin: Linearization | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Local ``(F_i, Q_i)``; the common block of Q is multiplied by ``common_scale``.

        ``common_scale`` (B,) is ``1/β_i`` for a sharing local filter (spec §1.2)
        and 1 for a standalone one; the private process noise is never shared.
        """
        if lin is not None:
            Fi, Qi = _with_batch_common(*self._blocks[i], lin)
        else:
            Fi, Qi = self._blocks[i]
        if common_scale is None:
            return Fi, Qi
        nc = self.n_common
        if Qi.shape[-1] == nc:  # no private states: the whole Q is shared
            return Fi, Qi * np.asarray(common_scale, dtype=float)[..., None, None]
        mask = np.zeros_like(Qi)
        mask[:nc, :nc] = 1.0
        scale = np.asarray(common_scale, dtype=float)[..., None, None]
        return Fi, Qi * (1.0 + mask * (scale - 1.0))


def _with_batch_common(
    F: np.ndarray, Q: np.ndarray, lin: Linearization
) -> tuple[np.ndarray, np.ndarray]:
    """Constant blocks (private states) under the epoch's per-run common corner."""
    nc = lin.Phi.shape[-1]
    if F.shape[-1] == nc:
        return lin.Phi, lin.Q
    B = lin.Phi.shape[0]
    F = np.broadcast_to(F, (B,) + F.shape).copy()
    Q = np.broadcast_to(Q, (B,) + Q.shape).copy()
    F[:, :nc, :nc], Q[:, :nc, :nc] = lin.Phi, lin.Q
    return F, Q
