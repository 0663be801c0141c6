"""Boundary I/O: scenario files (TOML) validated into the frozen objects of ftnav.sim."""
