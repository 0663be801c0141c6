"""Test-session settings.

Under ``pytest -n`` the test processes already use the cores: the runs of ``ftnav``
inside them use no worker processes of their own (``FTNAV_WORKERS=1``).  The worker
path itself is tested in ``tests/equivalence/test_workers.py`` with an explicit
``workers`` argument.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

# helper modules next to the tests (e.g. tests/reference/pyins_peer.py) are importable
sys.path.insert(0, str(Path(__file__).parent / "reference"))

if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ["FTNAV_WORKERS"] = "1"
