"""ftnav: fault-tolerant multi-sensor Kalman fusion for integrated navigation."""

import os as _os

__version__ = "0.1.0"

if _os.environ.get("FTNAV_PARENT_PID"):
    # a worker process of ftnav.parallel, still starting: from here on it ends with
    # its parent, even one killed by SIGKILL while this worker imports the rest
    from ftnav.parallel import end_with_parent as _end_with_parent

    _end_with_parent()
