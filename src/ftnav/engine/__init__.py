"""The navigation engine: one driver for every model and every fusion architecture.

A *stream* of measurements (:mod:`ftnav.model.streams`: simulated or recorded) goes
through a *model* (:mod:`ftnav.engine.linear`, :mod:`ftnav.engine.ins`) that turns it
into epochs, and every method's filter steps on each epoch (:func:`ftnav.engine.driver.run`).
No truth enters the engine.  :func:`smooth` runs the Rauch–Tung–Striebel smoother over a
trace recorded with ``run(..., smoothing=True)`` (:mod:`ftnav.engine.smoother`).
"""

from __future__ import annotations

from typing import Any

from ftnav.engine.driver import NavigationModel
from ftnav.engine.ins import InsModel, InsModelState
from ftnav.engine.linear import LinearModel, Repeats
from ftnav.engine.smoother import SmoothedTrace, smooth, smoothed_trace
from ftnav.model.system import LinearSystem

__all__ = ["SmoothedTrace", "navigation_model", "smooth", "smoothed_trace"]


def navigation_model(scenario: Any, system: LinearSystem | None = None) -> NavigationModel[Any]:
    """The engine's model of a scenario: its linear system, or the closed-loop SINS of an
    integrated scenario or a recording."""
    system = scenario.system() if system is None else system
    if scenario.kind == "linear":
        linear: NavigationModel[Repeats] = LinearModel(system)
        return linear
    ins: NavigationModel[InsModelState] = InsModel(
        system,
        scenario.error_model,
        [a.sensor for a in scenario.aids],
        scenario.dt,
        scenario.samples_per_epoch,
        scenario.correction,
        scenario.discretization,
        scenario.algorithm,
        scenario.bias_compensation,
    )
    return ins
