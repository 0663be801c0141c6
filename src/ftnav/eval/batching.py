"""How a campaign's runs are cut into batches: what :mod:`ftnav.eval.montecarlo` runs
and :mod:`ftnav.eval.resources` estimates, in one place below both."""

from __future__ import annotations

from typing import Any

__all__ = ["CHUNK_BYTES", "PARALLEL_MIN_WORK", "chunk_runs"]

#: smallest ``methods × epochs`` of a linear scenario worth worker processes (~2 s each)
PARALLEL_MIN_WORK = 10_000
#: memory budget of one batch's simulated IMU increments (bytes); the simulation's
#: temporaries roughly double it at its peak
CHUNK_BYTES = 2 << 30


def chunk_runs(sc: Any, twin: bool = True, points: int = 1) -> int:
    """Runs per batch of an integrated scenario so its IMU increments stay within
    :data:`CHUNK_BYTES` (a linear scenario runs in one batch).

    Per run and per SINS: the increments ``dθ``, ``Δv``, ``2 × 3`` float64 per IMU
    sample, for each of ``points`` streams (:func:`ftnav.eval.montecarlo.run_points`)
    and the fault-free
    twin.  A 3600 s flight at 100 Hz gives 62 runs per batch.
    """
    if sc.kind != "integrated":
        return 1 << 62
    per_run: int = sc.samples_per_epoch * sc.steps * 6 * 8 * (int(points) + bool(twin))
    return max(1, CHUNK_BYTES // per_run)
