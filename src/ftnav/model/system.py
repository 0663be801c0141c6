"""Linear multi-sensor system as the filters see it (spec §1.1, §1.7).

The *augmented* state is ``[x_c; x_s1; x_s2; ...]``: the ``n_c`` common states
followed by each sensor's private states (if any).  The centralized and the
distributed filters work on the augmented state; local filter ``i`` of the
federated filter carries ``[x_c; x_si]`` and fuses only ``x_c``.

A model may be time-varying: :meth:`LinearSystem.transition` receives the step
index ``k`` (1-based) and returns the matrices for the step ``k−1 → k``.  This
class is the constant case; linearized INS error models provide the same
interface.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.linalg import block_diag

from ftnav.model.scenario import LinearModel, Scenario, Sensor

__all__ = ["LinearSystem", "LocalModel", "TimeVaryingSystem", "Linearization"]


class Linearization(NamedTuple):
    """One epoch's matrices of an error-state model linearized per run (spec §6.2, §8.4).

    An integrated-navigation filter linearizes the SINS error model and every aid's
    measurement at each run's own INS solution, so the matrices carry the batch axis.
    Every architecture accepts it in ``step(..., lin=...)``; all local filters and the
    fusion centre then use the *same* matrices (identical linearization, spec §6.2).

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


@dataclass(frozen=True, slots=True)
class LocalModel:
    """Model of one local filter over ``[x_c; x_si]`` (dimension ``n_c + p_i``)."""

    H: np.ndarray  # (m, n_c + p)
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
    """Constant linear system built from a scenario's model and sensors."""

    model: LinearModel
    sensors: tuple[Sensor, ...]

    def __post_init__(self):
        # constant model: build the block matrices once
        blocks = []
        for i in range(len(self.sensors)):
            lm = self.local(i)
            blocks.append(
                (block_diag(self.model.F, lm.F_private), block_diag(self.model.Q, lm.Q_private))
            )
        object.__setattr__(self, "_blocks", tuple(blocks))
        aug = {}
        for true in (False, True):
            Q = self.model.Q_true if true else self.model.Q
            aug[true] = (
                block_diag(self.model.F, *self._private_blocks("F")),
                block_diag(Q, *self._private_blocks("Q")),
            )
        object.__setattr__(self, "_aug", aug)

    @classmethod
    def from_scenario(cls, scenario: Scenario) -> LinearSystem:
        return cls(scenario.model, scenario.sensors)

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

    def compatibility(self) -> dict:
        """What a learned model trained on this system records and later checks.

        State and sensor names, measurement sizes and ``system_hash``, a SHA-256
        fingerprint of the filters' model (F, Q, x0, P0, every H, R and private
        block).  Faults, methods and the simulator's true noise are left out, so
        a model trained on one scenario serves any scenario of the same system.
        """
        from ftnav.io.model_file import system_hash

        parts = {
            "states": list(self.model.states),
            "F": self.model.F,
            "Q": self.model.Q,
            "x0": self.model.x0,
            "P0": self.model.P0,
        }
        for s in self.sensors:
            parts[f"sensor:{s.name}"] = {
                "H": s.H,
                "R": s.R,
                "every": s.every,
                "offset": s.offset,
                "private": None
                if s.private is None
                else {
                    "names": list(s.private.names),
                    "F": s.private.F,
                    "Q": s.private.Q,
                    "x0": s.private.x0,
                    "P0": s.private.P0,
                    "H": s.private.H,
                },
            }
        return {
            "states": list(self.model.states),
            "sensors": [s.name for s in self.sensors],
            "measurement_dims": [s.dim for s in self.sensors],
            "system_hash": system_hash(parts),
        }

    # -- common / augmented matrices ---------------------------------------------
    def transition(self, k: int, lin: Linearization | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Common-state ``(F, Q)`` for the step ``k−1 → k`` (filter's assumed Q)."""
        if lin is not None:
            return lin.Phi, lin.Q
        return self.model.F, self.model.Q

    def augmented_transition(
        self, k: int, true: bool = False, lin: Linearization | None = None
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
        index = self.local(i).aug_index
        if lin is not None:
            Hl = lin.H[i]
            H = np.zeros(Hl.shape[:-1] + (self.n_aug,))
            H[..., index] = Hl
            return H
        H = np.zeros((s.dim, self.n_aug))
        H[:, : self.n_common] = s.H
        if s.private is not None:
            H[:, index[self.n_common :]] = s.private.H
        return H

    def local_H(self, i: int, lin: Linearization | None = None) -> np.ndarray:
        """Local filter i's measurement matrix: (m, n_i), or the epoch's (B, m, n_i)."""
        return self.local(i).H if lin is None else lin.H[i]

    def local(self, i: int) -> LocalModel:
        """Local filter i's model over ``[x_c; x_si]``."""
        s = self.sensors[i]
        nc = self.n_common
        offset = nc
        for j in range(i):
            if self.sensors[j].private is not None:
                offset += len(self.sensors[j].private.names)
        if s.private is None:
            p = 0
            H, x0, P0 = s.H, self.model.x0, self.model.P0
            Fp = Qp = np.zeros((0, 0))
        else:
            p = len(s.private.names)
            H = np.hstack([s.H, s.private.H])
            x0 = np.concatenate([self.model.x0, s.private.x0])
            P0 = block_diag(self.model.P0, s.private.P0)
            Fp, Qp = s.private.F, s.private.Q
        index = np.concatenate([np.arange(nc), np.arange(offset, offset + p)]).astype(int)
        return LocalModel(H, s.R, x0, P0, Fp, Qp, index)

    def _local_blocks(self, i: int, k: int) -> tuple[np.ndarray, np.ndarray]:
        return self._blocks[i]

    def local_transition(
        self, i: int, k: int, common_scale=None, lin: Linearization | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Local ``(F_i, Q_i)``; the common block of Q is multiplied by ``common_scale``.

        ``common_scale`` (B,) is ``1/β_i`` for a sharing local filter (spec §1.2)
        and 1 for a standalone one; the private process noise is never shared.
        """
        if lin is not None:
            Fi, Qi = _with_batch_common(*self._blocks[i], lin)
        else:
            Fi, Qi = self._local_blocks(i, k)
        if common_scale is None:
            return Fi, Qi
        nc = self.n_common
        if Qi.shape[-1] == nc:  # no private states: the whole Q is shared
            return Fi, Qi * np.asarray(common_scale, dtype=float)[..., None, None]
        mask = np.zeros_like(Qi)
        mask[:nc, :nc] = 1.0
        scale = np.asarray(common_scale, dtype=float)[..., None, None]
        return Fi, Qi * (1.0 + mask * (scale - 1.0))


@dataclass(frozen=True)
class TimeVaryingSystem(LinearSystem):
    """Linear system whose common ``(Φ_k, Q_k)`` change every step (spec §8.4).

    ``Phi[k−1]``, ``Qk[k−1]`` (each ``(K, n_c, n_c)``) drive the step ``k−1 → k``, e.g.
    the discretized SINS error model evaluated along a trajectory
    (:class:`ftnav.nav.error_model.SinsErrorModel`).  ``Qk`` is both the filters' and
    the simulator's process noise.  Sensors, private states and every filter are used
    unchanged: this is how the inertial error models plug into the estimation core.
    """

    Phi: np.ndarray | None = None
    Qk: np.ndarray | None = None

    def __post_init__(self):
        n = self.model.n
        if self.Phi is None or self.Qk is None:
            raise ValueError("Phi, Qk: a time-varying system needs both")
        Phi, Qk = np.asarray(self.Phi, dtype=float), np.asarray(self.Qk, dtype=float)
        if Phi.ndim != 3 or Phi.shape[1:] != (n, n) or Qk.shape != Phi.shape:
            raise ValueError(
                f"Phi, Qk: expected (K, {n}, {n}) each, got {Phi.shape} and {Qk.shape}"
            )
        if not (np.isfinite(Phi).all() and np.isfinite(Qk).all()):
            raise ValueError("Phi, Qk: contain NaN or inf")
        object.__setattr__(self, "Phi", Phi)
        object.__setattr__(self, "Qk", Qk)
        LinearSystem.__post_init__(self)

    @property
    def steps(self) -> int:
        return int(self.Phi.shape[0])

    def transition(self, k: int, lin: Linearization | None = None) -> tuple[np.ndarray, np.ndarray]:
        if lin is not None:
            return lin.Phi, lin.Q
        return self.Phi[k - 1], self.Qk[k - 1]

    def _with_common(self, F: np.ndarray, Q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Constant blocks (private states) with the common corner replaced by step k's."""
        nc = self.n_common
        F, Q = F.copy(), Q.copy()
        F[:nc, :nc], Q[:nc, :nc] = self.Phi[k - 1], self.Qk[k - 1]
        return F, Q

    def augmented_transition(
        self, k: int, true: bool = False, lin: Linearization | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        if lin is not None:
            return _with_batch_common(*self._aug[False], lin)
        return self._with_common(*self._aug[False], k)

    def _local_blocks(self, i: int, k: int) -> tuple[np.ndarray, np.ndarray]:
        return self._with_common(*self._blocks[i], k)


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
