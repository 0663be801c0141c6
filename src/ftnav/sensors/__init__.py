"""Aiding-sensor measurement models, z = INS − aid (spec §9).

Each sensor simulates its errors in its metric measurement space, produces the raw
output a real device would log, and linearizes ``z`` at the INS solution over the
18 common error states of spec §8.3 (and its own private states); the contract and
the sign conventions are in :mod:`ftnav.sensors.base`.

* :class:`Gnss` — position and velocity (§9.1);
* :class:`Tan` — SITAN radar altimeter over a terrain map (§9.2), with the surfaces
  :class:`AnalyticTerrain` and :class:`GridDem`;
* :class:`Doppler` — Doppler velocity (§9.3);
* :class:`StarTracker` — CNS attitude (§9.4);
* :class:`Barometer` — ADS barometric altitude (§9.5).
"""

from ftnav.sensors.ads import Barometer
from ftnav.sensors.base import (
    AidErrors,
    AidingSensor,
    AidTruth,
    Linearized,
    markov_errors,
    run_generator,
)
from ftnav.sensors.cns import StarTracker
from ftnav.sensors.dns import Doppler
from ftnav.sensors.gnss import Gnss
from ftnav.sensors.tan import Tan
from ftnav.sensors.terrain import AnalyticTerrain, GridDem, Terrain

__all__ = [
    "AidTruth",
    "AidErrors",
    "Linearized",
    "AidingSensor",
    "run_generator",
    "markov_errors",
    "Gnss",
    "Tan",
    "Doppler",
    "StarTracker",
    "Barometer",
    "AnalyticTerrain",
    "GridDem",
    "Terrain",
]
