"""Plain frozen descriptions of what ftnav runs: systems, sensors, faults, scenarios.

Above the numeric kernel (:mod:`ftnav.core`) and beside the inertial core
(:mod:`ftnav.nav`); the simulators, the filters and the engine read these
containers, the scenario files (:mod:`ftnav.io`) build them.
"""
