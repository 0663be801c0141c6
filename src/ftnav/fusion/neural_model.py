"""The trained neuron banks of paper 001's fusion centre (spec §5.2-§5.4): the data.

:class:`NeuronModel` holds one bank of linear neurons per fault configuration;
:func:`select_weights` picks a bank from the detector flags (spec §5.4).  The model
file (npz arrays + JSON) is read and written by :mod:`ftnav.io.learned`; training is
:mod:`ftnav.training.fusion` and :mod:`ftnav.training.ins_fusion`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["FREE_INPUT", "MODEL_KIND", "NeuronModel", "select_weights"]

#: ``kind`` of a neuron fusion model file.
MODEL_KIND = "neuron-fusion"
#: Name of the free-propagation input.
FREE_INPUT = "free"


@dataclass(frozen=True)
class NeuronModel:
    """Trained banks of neurons (spec §5.2-§5.4).

    Attributes
    ----------
    configurations : (C,) names, the first is the healthy one.
    patterns : (C, N) bool, the local filters flagged in each configuration
        (the selection key of spec §5.4).
    inputs : (N_in,) input names: the sensors' local filters, then optionally
        :data:`FREE_INPUT`.
    states : (n_c,) fused state names.
    weights : (C, n_c, N_in) neuron weights, each row on the simplex.
    rmse : (C, n_c) training RMSE of each neuron.
    compatibility, training : see :class:`ftnav.fdi.rbf.RBFModel`.
    """

    configurations: tuple[str, ...]
    patterns: np.ndarray
    inputs: tuple[str, ...]
    states: tuple[str, ...]
    weights: np.ndarray
    rmse: np.ndarray
    compatibility: dict[str, Any]
    training: dict[str, Any]

    def __post_init__(self) -> None:
        C, N = self.patterns.shape
        if self.weights.shape != (C, len(self.states), len(self.inputs)):
            raise ValueError(
                f"weights: expected {(C, len(self.states), len(self.inputs))}, "
                f"got {self.weights.shape}"
            )
        if len(self.configurations) != C or self.patterns[0].any():
            raise ValueError("configurations: the first must be the healthy one (no flag)")
        if (self.weights < 0).any() or np.abs(self.weights.sum(-1) - 1.0).max() > 1e-9:
            raise ValueError("weights: every neuron's weights must be >= 0 and sum to 1")
        if len({tuple(p) for p in self.patterns}) != C:
            raise ValueError("patterns: two configurations have the same flag pattern")

    @property
    def free_input(self) -> bool:
        return FREE_INPUT in self.inputs


def select_weights(model: NeuronModel, flags: np.ndarray, uncovered: str) -> np.ndarray:
    """Weights (B, n_c, N_in) for the detector flags (B, N) (spec §5.4 selection).

    ``uncovered`` is ``"renormalize"`` or a configuration name (see module doc).
    """
    flags = np.asarray(flags, dtype=bool)
    match = (flags[:, None, :] == model.patterns[None]).all(-1)  # (B, C)
    covered = match.any(1)
    W = model.weights[np.argmax(match, 1)]
    if covered.all():
        return np.asarray(W)
    if uncovered == "renormalize":
        keep = np.ones((flags.shape[0], len(model.inputs)))
        keep[:, : flags.shape[1]] = ~flags
        W0 = model.weights[0][None] * keep[:, None, :]
        total = W0.sum(-1, keepdims=True)
        fallback = np.where(total > 0, W0 / np.where(total > 0, total, 1.0), model.weights[0])
    else:
        fallback = np.broadcast_to(model.weights[model.configurations.index(uncovered)], W.shape)
    return np.asarray(np.where(covered[:, None, None], W, fallback))
