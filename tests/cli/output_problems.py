"""Small runs shared by the CLI tests (:data:`SMALL`) and by the tests of the per-state
tables, figures and estimates.nc.

* :func:`north_ramp_run`: a linear scenario with East and North states and a ramp fault
  on the North row of one of two position sensors (the East row is clean), so the fault
  reaches the North state only.
* :func:`integrated_run`: a 60 s SINS/GNSS/ADS flight with a GNSS noise step, a
  centralized, a federated (chi-square isolation) and a VB-adaptive distributed method.
"""

from __future__ import annotations

import tomllib
from functools import cache

#: a 60-epoch linear scenario (three states, two position sensors, a bias on one, the
#: centralized, a federated and a distributed method): the CLI tests' small run
SMALL = """
name = "small"
dt = 1.0
steps = 60
[model]
states = ["s", "v", "a"]
F  = [[1.0, 0.05, 0.00125], [0.0, 1.0, 0.05], [0.0, 0.0, 1.0]]
Q  = [[5.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
x0 = [0.0, 0.0, 0.0]
P0 = [[100.0, 0.0, 0.0], [0.0, 100.0, 0.0], [0.0, 0.0, 100.0]]
[[sensors]]
name = "pos1"
H = [[1.0, 0.0, 0.0]]
R = [[30.0]]
[[sensors]]
name = "pos2"
H = [[2.5, 0.0, 0.0]]
R = [[30.0]]
every = 2
[[faults]]
sensor = "pos1"
kind = "bias"
start = 20.0
end = 40.0
magnitude = [60.0]
[[methods]]
name = "ckf"
architecture = "centralized"
[[methods]]
name = "fkf"
architecture = "federated"
sharing = "inverse-trace"
detector = { kind = "residual-chi2", prior = "global" }
[[methods]]
name = "dkf"
architecture = "distributed"
detector = { kind = "state-chi2" }
"""

NORTH_RAMP = """
name = "my-north-ramp"
description = "My own scenario: a ramp on the North row of gnss"
dt = 1.0
steps = 120

[model]
states = ["E", "N"]
F = [[1.0, 0.0], [0.0, 1.0]]
Q = [[1.0, 0.0], [0.0, 1.0]]
x0 = [0.0, 0.0]
P0 = [[100.0, 0.0], [0.0, 100.0]]

[[sensors]]
name = "gnss"
H = [[1.0, 0.0], [0.0, 1.0]]
R = [[4.0, 0.0], [0.0, 4.0]]

[[sensors]]
name = "aux"
H = [[1.0, 0.0], [0.0, 1.0]]
R = [[4.0, 0.0], [0.0, 4.0]]

[[faults]]
sensor = "gnss"
kind = "ramp"
start = 40.0
end = 90.0
magnitude = [0.0, 60.0]

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-equal"
sharing = "equal"

[[methods]]
name = "fkf-trace"
sharing = "trace"

[[methods]]
name = "fkf-inverse-trace"
sharing = "inverse-trace"

[[methods]]
name = "fkf-oracle"
detector = { kind = "oracle" }

[[methods]]
name = "fkf-chi2"
detector = { kind = "residual-chi2", prior = "global" }

[[methods]]
name = "dkf"
architecture = "distributed"
"""

INTEGRATED = """
kind = "integrated"
name = "my-flight"
description = "My own flight: GNSS noise step"
profile = "seed002"
imu = "seed001"

[filter]
dt = 1.0
duration_s = 60.0

[[aids]]
type = "gnss"
pos_markov_sigma_m = 0.0
vel_markov_sigma_m_s = 0.0
pos_white_sigma_m = 1.4
vel_white_sigma_m_s = 0.3

[[aids]]
type = "ads"

[[faults]]
sensor = "gnss"
kind = "noise-scale"
start = 30.0
end = 50.0
magnitude = [5.0]

[evaluation]
skip_initial = 10.0

[[methods]]
name = "ckf"
architecture = "centralized"

[[methods]]
name = "fkf-chi2"
architecture = "federated"
detector = { kind = "residual-chi2", prior = "global" }
isolation = "time-update"

[[methods]]
name = "dkf-vb"
architecture = "distributed"
noise = { kind = "vb", sensors = ["gnss"] }
"""


def linear_scenario(text: str = NORTH_RAMP):
    from ftnav.io.scenario_file import parse_scenario

    return parse_scenario(tomllib.loads(text))


def integrated_scenario(text: str = INTEGRATED):
    from ftnav.io.ins_scenario_file import parse_ins_scenario

    return parse_ins_scenario(tomllib.loads(text))


@cache
def north_ramp_run():
    """(ScenarioResult, metrics) of :data:`NORTH_RAMP`, 4 runs, seed 2."""
    from ftnav.eval.evaluate import evaluate
    from ftnav.eval.montecarlo import run_scenario

    result = run_scenario(linear_scenario(), runs=4, seed=2)
    return result, evaluate(result)


@cache
def integrated_run():
    """(ScenarioResult, metrics) of :data:`INTEGRATED`, 2 runs, seed 3."""
    from ftnav.eval.evaluate import evaluate
    from ftnav.eval.montecarlo import run_scenario

    result = run_scenario(integrated_scenario(), runs=2, seed=3)
    return result, evaluate(result)
