"""Feedback of a fused error estimate to the SINS: shift every estimate (spec §6.2, §8.5).

When the fused estimate ``x̂_g`` of the navigation errors is fed back (the SINS is
corrected by it), the reference every local filter linearizes about moves by the
same amount; each local estimate becomes ``x̂^i − δ`` and the fused one ``x̂_g − δ``
(``δ`` the fed-back part).  Covariances do not change, and neither do the
information increments, so the distributed filter stays equal to the centralized
one.  A zero-reset federated local filter holds information ``(y, Y)``; its shift is
``y − Y δ``.
"""

from __future__ import annotations

import numpy as np

from ftnav.core import kalman as kf
from ftnav.fusion.centralized import CentralizedState
from ftnav.fusion.distributed import DistributedState
from ftnav.fusion.federated import FederatedState
from ftnav.fusion.neural import NeuralState

__all__ = ["shift_estimates", "local_estimates"]


def _minus(x: np.ndarray, delta: np.ndarray) -> np.ndarray:
    n = delta.shape[-1]
    out = x.copy()
    out[..., :n] -= delta
    return out


def _shift_gaussians(gs, delta):
    return None if gs is None else tuple(kf.Gaussian(_minus(g.x, delta), g.P) for g in gs)


def shift_estimates(state, delta: np.ndarray, information: bool = False):
    """Every estimate of ``state`` minus ``delta`` (B, d) on its first d states.

    ``information=True`` marks zero-reset federated locals, stored as ``(y, Y)``.
    """
    if isinstance(state, CentralizedState):
        return state._replace(x=_minus(state.x, delta))
    if isinstance(state, DistributedState):
        return state._replace(
            x=tuple(_minus(x, delta) for x in state.x),
            xg=_minus(state.xg, delta),
            propagator=_shift_gaussians(state.propagator, delta),
        )
    if isinstance(state, FederatedState):
        if information:
            d = delta.shape[-1]
            xs = tuple(y - kf.mv(Y[..., :d], delta) for y, Y in zip(state.x, state.P, strict=True))
        else:
            xs = tuple(_minus(x, delta) for x in state.x)
        master = (
            None
            if state.master is None
            else kf.Gaussian(_minus(state.master.x, delta), state.master.P)
        )
        return state._replace(
            x=xs,
            master=master,
            xg=_minus(state.xg, delta),
            propagator=_shift_gaussians(state.propagator, delta),
        )
    if isinstance(state, NeuralState):
        return state._replace(
            x=tuple(_minus(x, delta) for x in state.x),
            free=kf.Gaussian(_minus(state.free.x, delta), state.free.P),
            xf=_minus(state.xf, delta),
        )
    raise TypeError(f"state: no feedback rule for {type(state).__name__}")


def local_estimates(state, n: int) -> np.ndarray | None:
    """(B, N, n) the local filters' estimates of the first n states, or None."""
    if isinstance(state, FederatedState | DistributedState | NeuralState):
        return np.stack([x[:, :n] for x in state.x], 1)
    return None
