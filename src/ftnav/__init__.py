"""ftnav: fault-tolerant multi-sensor Kalman fusion for integrated navigation."""

import os as _os

from ftnav.version import __version__

__all__ = ["__version__", "load_scenario", "process_recording", "run_scenario"]

#: the public entry points, imported when first used: name -> (module, attribute)
_LAZY = {
    "load_scenario": ("ftnav.io.scenario_file", "load_scenario"),
    "process_recording": ("ftnav.pipeline", "process_recording"),
    "run_scenario": ("ftnav.eval.montecarlo", "run_scenario"),
}


def __getattr__(name: str) -> object:
    """``ftnav.load_scenario`` (:mod:`ftnav.io.scenario_file`), ``ftnav.process_recording``
    (:mod:`ftnav.pipeline`) and ``ftnav.run_scenario`` (:mod:`ftnav.eval.montecarlo`),
    imported when first used."""
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'ftnav' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names with the lazy ones (``dir(ftnav)``, tab completion)."""
    return sorted(set(globals()) | set(__all__))


if _os.environ.get("FTNAV_PARENT_PID"):
    # a worker process of ftnav.parallel, still starting: from here on it ends with
    # its parent, even one killed by SIGKILL while this worker imports the rest
    from ftnav.parallel import end_with_parent as _end_with_parent

    _end_with_parent()
