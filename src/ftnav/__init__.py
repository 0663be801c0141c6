"""ftnav: fault-tolerant multi-sensor Kalman fusion for integrated navigation."""

import os as _os

from ftnav.version import __version__

__all__ = ["__version__", "process_recording", "run_scenario"]


def __getattr__(name: str) -> object:
    """``ftnav.process_recording`` (:mod:`ftnav.pipeline`) and ``ftnav.run_scenario``
    (:mod:`ftnav.eval.montecarlo`), imported when first used."""
    if name == "process_recording":
        from ftnav.pipeline import process_recording

        return process_recording
    if name == "run_scenario":
        from ftnav.eval.montecarlo import run_scenario

        return run_scenario
    raise AttributeError(f"module 'ftnav' has no attribute {name!r}")


def __dir__() -> list[str]:
    """The module's names with the lazy ones (``dir(ftnav)``, tab completion)."""
    return sorted(set(globals()) | set(__all__))


if _os.environ.get("FTNAV_PARENT_PID"):
    # a worker process of ftnav.parallel, still starting: from here on it ends with
    # its parent, even one killed by SIGKILL while this worker imports the rest
    from ftnav.parallel import end_with_parent as _end_with_parent

    _end_with_parent()
