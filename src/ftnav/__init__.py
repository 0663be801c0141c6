"""ftnav: fault-tolerant multi-sensor Kalman fusion for integrated navigation."""

__version__ = "0.1.0"
