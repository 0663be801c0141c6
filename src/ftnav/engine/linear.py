"""The linear model of the engine: a measurement stream through a constant system.

Each epoch is the stream's measurements with the system's constant matrices
(:class:`~ftnav.model.system.Epoch` with ``lin = None``), or, for a time-varying model,
with the epoch's ``(Φ_k, Q_k)`` (:class:`~ftnav.model.system.Linearization`).  Nothing
is fed back: the filters' estimates are the output.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ftnav.model.streams import MeasurementStream, repeated
from ftnav.model.system import Epoch, Linearization, LinearSystem, TimeVarying

__all__ = ["LinearModel"]

#: the linear model's state between epochs: each sensor's (B, K) repeated outputs (None
#: where a caller steps the model without :meth:`LinearModel.start`: not known then)
Repeats = tuple[np.ndarray, ...] | None


class LinearModel:
    """A linear system's epochs from a :class:`MeasurementStream` (module docstring).

    Parameters
    ----------
    system : the filters' system (constant ``H``; constant ``F``, ``Q`` unless
        ``transitions`` gives them per epoch).
    transitions : optional per-epoch common transitions of a time-varying model.
    """

    feedback: bool = False
    per_method_rows: bool = False
    n_fed: int = 0
    n_local: int | None = None

    def __init__(self, system: LinearSystem, transitions: TimeVarying | None = None):
        self.system = system
        self.transitions = transitions
        if transitions is not None:  # the private blocks and every H stay constant
            self._H = tuple(system.local_H(i) for i in range(system.n_sensors))

    def start(self, stream: MeasurementStream, copies: int) -> Repeats:
        """Each sensor's (B, K) repeated outputs (a frozen sensor's signature)."""
        return tuple(repeated(z, stream.available[:, :, i]) for i, z in enumerate(stream.z))

    def navigation(self, state: Repeats) -> None:
        return None

    def correct(self, state: Repeats, fused: np.ndarray, rows: np.ndarray | None = None) -> Repeats:
        return state

    def compensated_bias(self, state: Repeats) -> None:
        return None

    def output(self, state: Repeats, fused: np.ndarray, rows: np.ndarray | None = None) -> None:
        return None

    def epoch(
        self,
        state: Repeats,
        stream: MeasurementStream,
        k: int,
        copies: int,
        local_copies: Any = None,
    ) -> tuple[Repeats, Epoch]:
        """The stream's epoch k (1-based) for ``copies`` methods (all see the same rows)."""
        lin = None
        if self.transitions is not None:
            B = stream.batch
            Phi = np.broadcast_to(
                self.transitions.Phi[k - 1], (B,) + self.transitions.Phi.shape[1:]
            )
            Q = np.broadcast_to(self.transitions.Q[k - 1], (B,) + self.transitions.Q.shape[1:])
            lin = Linearization(Phi, Q, tuple(np.broadcast_to(H, (B,) + H.shape) for H in self._H))
        z = tuple(zi[:, k - 1] for zi in stream.z)
        avail = stream.available[:, k - 1]
        rep = None if state is None else np.stack([r[:, k - 1] for r in state], 1)
        return state, Epoch(k, z, avail, stream.labels[k - 1], lin, rep)
