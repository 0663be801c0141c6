"""Recorded sensor logs as a source of the engine's stream (beside :mod:`ftnav.sim`).

:mod:`ftnav.recorded.imu` cleans a logged IMU and integrates it onto the engine's grid;
:mod:`ftnav.recorded.stream` aligns the initial solution, places each aid's epochs on
the filter grid, removes GNSS over an outage schedule, injects faults into the
recorded aids and builds the :class:`~ftnav.model.streams.InsStream`.  Files are read
in :mod:`ftnav.io.recording_file`; nothing here reads a file.
"""
