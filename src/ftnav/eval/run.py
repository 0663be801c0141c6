"""One entry point for a scenario of either kind: ``run(scenario, runs, seed)``.

A linear scenario goes to :func:`ftnav.eval.montecarlo.run_scenario`, an integrated one
(``kind == "integrated"``) to :func:`ftnav.eval.integrated.run_ins_scenario`; both return
a :class:`~ftnav.eval.montecarlo.ScenarioResult` that :func:`ftnav.eval.evaluate.evaluate`
reads.  Use :func:`~ftnav.eval.integrated.run_ins_scenario` directly for the local
filters' tracks of an integrated run.
"""

from __future__ import annotations

from collections.abc import Callable

from ftnav.eval.integrated import run_ins_scenario
from ftnav.eval.montecarlo import ScenarioResult, run_scenario

__all__ = ["run"]


def run(
    scenario,
    runs: int,
    seed: int,
    *,
    fault_free: bool = True,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
) -> ScenarioResult:
    """Simulate ``runs`` Monte Carlo runs from ``seed`` and run every method of ``scenario``.

    Parameters
    ----------
    scenario : a linear :class:`~ftnav.model.scenario.Scenario` or an integrated
        :class:`~ftnav.model.ins_scenario.InsScenario` (``load_scenario`` returns either).
    runs, seed : Monte Carlo runs and root seed (run i is the same in any batch).
    fault_free : also run the fault-free twin on identical noise (when there are faults).
    workers : worker processes (:mod:`ftnav.parallel`); 1 runs in this process.
    progress : called with the number of method-epochs done.
    """
    if getattr(scenario, "kind", "linear") == "integrated":
        return run_ins_scenario(
            scenario, runs, seed, fault_free=fault_free, workers=workers, progress=progress
        ).result
    return run_scenario(
        scenario, runs, seed, fault_free=fault_free, workers=workers, progress=progress
    )
