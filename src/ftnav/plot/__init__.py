"""Figures of Monte Carlo results (paper 000 Fig. 3 / Fig. 4 analogues, β, fault flags).

The functions live in :mod:`ftnav.plot.figures`, which imports matplotlib; they
are loaded lazily here so that ``import ftnav`` and ``import ftnav.plot`` never
import matplotlib.

Functions
---------
error_figure, sharing_figure, fault_flag_figure, save_all
"""

from __future__ import annotations

__all__ = ["error_figure", "fault_flag_figure", "save_all", "sharing_figure"]


def __getattr__(name: str):
    if name in __all__:
        from ftnav.plot import figures

        return getattr(figures, name)
    raise AttributeError(f"module 'ftnav.plot' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
