"""Figures of Monte Carlo results: errors per state, β, fault flags (and integrated runs).

The functions live in :mod:`ftnav.plot.figures` (linear runs) and
:mod:`ftnav.plot.integrated` (integrated navigation), which import matplotlib; they are
loaded lazily here so that ``import ftnav`` and ``import ftnav.plot`` never import
matplotlib.  A run draws the scenario's ``[[figures]]`` or, without any,
:func:`default_figures`; no axes holds more than
:data:`~ftnav.model.scenario.MAX_FIGURE_METHODS` method lines.

Functions
---------
error_figure, sharing_figure, fault_flag_figure, draw_figure, default_figures,
method_groups, save_all
"""

from __future__ import annotations

__all__ = [
    "default_figures",
    "draw_figure",
    "error_figure",
    "fault_flag_figure",
    "method_groups",
    "save_all",
    "sharing_figure",
]


def __getattr__(name: str):
    if name in __all__:
        from ftnav.plot import figures

        return getattr(figures, name)
    raise AttributeError(f"module 'ftnav.plot' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
