"""``seed002`` with one fault nobody specified, shortened: the scenario the statistical
tests of the guard build (``tests/statistical/test_readmission_beside.py``,
``test_backing_ins_fault.py``), as ``benchmarks/seed002_faults.py`` and ``ftnav sweep``
build theirs (``read_toml`` + ``parse_ins_scenario``)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ftnav.eval.montecarlo import ScenarioResult, run_scenario
from ftnav.io.common import read_toml
from ftnav.io.ins_scenario_file import parse_ins_scenario
from ftnav.scenarios import builtin_path


def run_seed002(
    fault: dict[str, Any], duration: float, runs: int, methods: Sequence[str], label: str
) -> ScenarioResult:
    """``runs`` runs (seed 1) of ``seed002`` for ``duration`` s with ``fault`` instead of
    its own, the named methods only."""
    path = builtin_path("seed002")
    doc = read_toml(path)
    doc["filter"]["duration_s"] = duration
    doc["faults"] = [fault]
    sc = parse_ins_scenario(doc, f"seed002, {label}", Path(path).parent)
    keep = tuple(m for m in sc.methods if m.name in methods)
    return run_scenario(sc, runs, 1, methods=keep)
