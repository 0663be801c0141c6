"""Test-session settings.

Under ``pytest -n`` every worker process runs its own kernels: numba's thread pool
in each would oversubscribe the cores (a parallel region waits for its slowest,
descheduled thread), so workers run the kernels on one thread.  The thread-pool
path itself is tested in ``tests/equivalence/test_batching.py``, which raises the
thread count for its own duration.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numba

# helper modules next to the tests (e.g. tests/reference/pyins_peer.py) are importable
sys.path.insert(0, str(Path(__file__).parent / "reference"))

if os.environ.get("PYTEST_XDIST_WORKER"):
    numba.set_num_threads(1)

