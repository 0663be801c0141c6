"""``ftnav run --until`` (issue 23 item 4): runs added until an interval is narrow enough.

Oracles: the campaign in parts equals the campaign of as many runs run at once, bit for
bit (each run's noise depends on its index only); the rule stops as soon as the interval
meets its target, or at ``--max-runs`` and says so; a bad target is one line, exit 2.
"""

from __future__ import annotations

import json

import pytest
from seed000_copy import seed000_copy

from ftnav.cli import main
from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import run_scenario
from ftnav.eval.stopping import metric_interval, parse_target, run_until
from ftnav.io.scenario_file import load_scenario

KEEP = ("ckf", "fkf-inverse-trace-chi2")


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    return seed000_copy(tmp_path_factory.mktemp("stop") / "small.toml", KEEP)


def test_parts_equal_the_whole_and_the_rule_stops_at_its_target(small):
    sc = load_scenario(small)
    target = parse_target("fkf-inverse-trace-chi2.rmse.s:rel=0.02", list(KEEP))
    stopped = run_until(sc, 1, target, 4, 200)
    runs = stopped.result.runs
    assert stopped.parts >= 2 and 4 < runs <= 200
    assert stopped.reached and target.met(stopped.interval)
    whole = evaluate(run_scenario(sc, runs, 1))
    for m in KEEP:
        assert stopped.metrics[m].rmse == whole[m].rmse
        assert stopped.metrics[m].anees == whole[m].anees
        assert stopped.metrics[m].intervals == whole[m].intervals
    assert metric_interval(whole, target) == stopped.interval


def test_max_runs_bounds_it_and_says_so(small, tmp_path, capsys):
    out = tmp_path / "o"
    args = ["run", str(small), "--runs", "3", "--max-runs", "6", "--no-figures", "--quiet"]
    code = main([*args, "--until", "ckf.rmse.s:rel=0.0001", "--out", str(out)])
    assert code == 0
    stop = json.loads((out / "metrics.json").read_text())["stopping"]
    assert stop["runs"] == 6 and not stop["reached"]
    assert stop["half_width"] > stop["target_half_width"]
    captured = capsys.readouterr()
    assert "NOT reached within --max-runs 6 after 6 runs" in captured.out
    # a target not reached is a warning, and report.md says it under its title
    assert "ftnav: warning: --until ckf.rmse.s:rel=0.0001: NOT reached" in captured.err
    assert "NOT reached within --max-runs 6" in (out / "report.md").read_text()


@pytest.mark.parametrize(
    ("until", "says"),
    [
        ("ckf.rmse.s", "expected METHOD.METRIC:rel=F"),
        ("nobody.rmse.s:rel=0.1", "no method of the scenario starts it"),
        ("ckf.speed:rel=0.1", "the metric is rmse.<state>"),
        ("ckf.rmse.s:rel=-1", "the target must be a positive number"),
        ("ckf.detection.pos1.rate:abs=0.1", "ckf has no detector"),
        ("fkf-inverse-trace-chi2.detection.gps.rate:abs=0.1", "no sensor 'gps'"),
        ("ckf.rmse.pos_E_m:rel=0.1", "no state 'pos_E_m' (states: s, v, a)"),
        # ran to --max-runs and printed nan (found by a user's try)
        ("fkf-inverse-trace-chi2.detection.pos2.rate:abs=0.1", "pos2 has no fault in the"),
    ],
)
def test_a_bad_target_is_one_line_before_anything_runs(small, tmp_path, capsys, until, says):
    out = tmp_path / "o"
    code = main(["run", str(small), "--runs", "2", "--until", until, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert says in err and len(err.strip().splitlines()) == 1
