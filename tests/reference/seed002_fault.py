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


def gyro_step(start: float, end: float, deg_h: Sequence[float]) -> dict[str, Any]:
    """A step of the SINS's gyro biases over [start, end) s, deg/h about x, y, z (a
    scenario file's fault table)."""
    return {
        "sensor": "sins",
        "kind": "gyro-bias",
        "start": start,
        "end": end,
        "magnitude_deg_h": [float(v) for v in deg_h],
    }
