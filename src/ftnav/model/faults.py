"""Fault and anomaly injection (spec §9.6), one module for linear and integrated simulation.

A fault acts on one sensor's measurement errors over ``[start, end)`` (the epochs at
``t_k`` inside): ``bias`` adds an offset, ``ramp`` an offset growing linearly from 0 to
``magnitude`` over the window, ``noise-scale`` multiplies the white-noise σ, ``noise-ramp``
multiplies it by a factor growing from 1 to ``magnitude`` at ``end``, ``outage`` removes
the output, ``stuck`` freezes it at its last value before the window (its first value
when the window starts at the first epoch).  Every fault but an outage is labelled
(nothing to detect in an outage).  The simulators form

    measurement error = coloured + white · scale + offset,

then the device output, then apply outages and stuck windows to it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ftnav.model.scenario import Fault

__all__ = ["FaultEffect", "fault_effect", "hold_stuck"]


class FaultEffect(NamedTuple):
    """What one sensor's faults do at its epochs (K of them), measurement rows m.

    Attributes
    ----------
    offset : (K, m) added to the error.
    scale : (K, m) factor on the white noise.
    outage : (K,) bool, no output.
    stuck : windows (K,) bool whose output is frozen.
    label : (K,) bool, inside a detectable fault window.
    """

    offset: np.ndarray
    scale: np.ndarray
    outage: np.ndarray
    stuck: tuple[np.ndarray, ...]
    label: np.ndarray


def _window(t: np.ndarray, f: Fault) -> np.ndarray:
    return (t >= f.start) & (t < f.end)


def fault_effect(faults: Sequence[Fault], sensor: str, t: np.ndarray, m: int) -> FaultEffect:
    """The effect of the faults of ``sensor`` at the times ``t`` (K,) (module docstring)."""
    offset = np.zeros((t.size, m))
    scale = np.ones((t.size, m))
    outage = np.zeros(t.size, dtype=bool)
    label = np.zeros(t.size, dtype=bool)
    stuck = []
    for f in faults:
        if f.sensor != sensor:
            continue
        w = _window(t, f)
        frac = np.clip((t - f.start) / max(f.end - f.start, 1e-12), 0.0, 1.0)
        if f.kind == "bias":
            offset[w] += f.magnitude
        elif f.kind == "ramp":
            offset[w] += frac[w, None] * f.magnitude
        elif f.kind == "noise-scale":
            scale[w] *= f.magnitude
        elif f.kind == "noise-ramp":
            scale[w] *= (1.0 + (float(f.magnitude[0]) - 1.0) * frac[w])[:, None]
        elif f.kind == "outage":
            outage |= w
        elif f.kind == "stuck":
            stuck.append(w)
        if f.kind != "outage":
            label |= w
    return FaultEffect(offset, scale, outage, tuple(stuck), label)


def hold_stuck(values: np.ndarray, effect: FaultEffect) -> np.ndarray:
    """(B, K, ...) ``values`` frozen in every stuck window at their last value before it."""
    for w in effect.stuck:
        if not w.any():
            continue
        k0 = int(np.argmax(w))
        held = values[:, max(k0 - 1, 0)].copy()
        values = np.where(w.reshape((1, -1) + (1,) * (values.ndim - 2)), held[:, None], values)
    return values
