"""Which claims a run checks: the built-ins' (not a user's scenario), shortened flights.

Oracles by construction: the built-in's file and its scenario shortened get its paper's
claims, a user's scenario none whatever its method names; a claim whose fault window
holds no epoch of the run (a shortened flight) is reported *not checked* with the
reason, never as a verdict drawn from a NaN; a claim whose window is cut by the end of
the run is checked on the part inside and says so.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from ftnav.cli import main
from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.report.claims import check_claims, papers_of
from ftnav.scenarios import builtin_path


def _builtin(name):
    return load_scenario(builtin_path(name))


def _never_nan_verdict(claims):
    for c in claims:
        undecided = c["checked"] and c["holds"] is None
        assert not undecided or (c["intervals"] and c["note"].startswith("undecided: ")), c
        assert c["checked"] is (c["holds"] is not None or undecided), c
        if not c["checked"]:
            assert c["note"].startswith("not checked: "), c
        else:
            assert not any(
                isinstance(v, float) and math.isnan(v) for v in _numbers(c["measured"])
            ), c


def _numbers(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _numbers(v)
    elif isinstance(obj, list | tuple):
        for v in obj:
            yield from _numbers(v)
    else:
        yield obj


def test_claims_go_with_the_builtin_not_with_names(tmp_path):
    """Issue 23: a built-in's file (wherever it lies) and its scenario shortened in
    Python get its paper's claims; a user's scenario gets none, even with the built-in's
    method names, and a built-in's name on another scenario does not bring them."""
    for name, paper in (("seed000", "000"), ("seed001", "001"), ("seed002", "002")):
        sc = _builtin(name)
        assert sc.builtin == name and papers_of(sc) == (paper,)
        assert papers_of(replace(sc, name="my-copy", steps=100)) == (paper,)
    copy = tmp_path / "copy.toml"
    copy.write_bytes(builtin_path("seed000").read_bytes())
    assert papers_of(load_scenario(copy, models=False)) == ("000",)
    edited = tmp_path / "edited.toml"
    edited.write_text(builtin_path("seed000").read_text() + "\n# my change\n")
    mine = load_scenario(edited, models=False)
    assert mine.builtin is None and papers_of(mine) == ()
    assert papers_of(replace(_builtin("slowramp"))) == ()
    seed002 = _builtin("seed002")
    assert papers_of(replace(seed002, builtin=None, name="seed002")) == ()


def test_shortened_seed000_copy_reports_not_checked_with_the_reason():
    sc = replace(_builtin("seed000"), name="short000", steps=200)  # fault on [300, 500) s
    result = run_scenario(sc, 2, 1)
    claims = {c["id"]: c for c in check_claims(result, evaluate(result))}
    _never_nan_verdict(claims.values())
    assert claims["exact-fusion"]["checked"] and claims["p000-fig3"]["checked"]
    for cid in (
        "p000-fig4a-reset1",
        "p000-fig4a-reset10",
        "p000-fig4b",
        "p000-no-isolation",
        "p000-recovery",
        "p000-rbf",
    ):
        c = claims[cid]
        assert not c["checked"] and c["holds"] is None, cid
        assert c["note"] == (
            "not checked: no epoch of the run (0, 200] s lies in a fault window ([300, 500) s)"
        ), c["note"]


def test_seed000_copy_ending_inside_the_grace_period_leaves_recovery_not_checked():
    sc = replace(_builtin("seed000"), name="short000", steps=505)  # grace ends at 510 s
    result = run_scenario(
        sc,
        2,
        1,
        methods=tuple(m for m in _builtin("seed000").methods if m.name == "fkf-inverse-trace-chi2"),
    )
    claims = {c["id"]: c for c in check_claims(result, evaluate(result))}
    assert claims["p000-fig4b"]["checked"]
    assert claims["p000-recovery"]["note"] == (
        "not checked: no epoch of the run (0, 505] s after the fault window and the grace "
        "period (500 + 10 s)"
    )


@pytest.fixture(scope="module")
def short002():
    """seed002 cut to 1000 s: the noise step [600, 1500) s is cut, the ramp lies outside."""
    sc = replace(_builtin("seed002"), name="short002", steps=1000)
    result = run_scenario(sc, 2, 1)
    return result, evaluate(result)


def test_shortened_seed002_copy_checks_the_cut_window_and_not_the_one_outside(short002):
    result, metrics = short002
    claims = {c["id"]: c for c in check_claims(result, metrics)}
    _never_nan_verdict(claims.values())
    for cid in (
        "p002-adaptive-noise-scale",
        "p002-fkf-isolates-noise-scale",
        "p002-height-noise-scale",
        "p002-vb-sigma",
    ):
        assert claims[cid]["checked"], claims[cid]
    assert claims["p002-adaptive-noise-scale"]["note"].endswith(
        "the window is cut at the end of the run (1000 s)"
    )
    for cid in (
        "p002-adaptive-noise-ramp",
        "p002-fkf-isolates-noise-ramp",
        "p002-height-noise-ramp",
    ):
        c = claims[cid]
        assert not c["checked"] and c["holds"] is None
        assert c["note"] == (
            "not checked: no epoch of the run (0, 1000] s lies in a fault window ([2100, 3000) s)"
        )


def test_vb_claim_needs_300_s_of_the_noise_step(short002):
    result, metrics = short002
    sc = result.scenario

    def vb_note(start, end):
        faults = tuple(
            replace(f, start=start, end=end) if f.kind == "noise-scale" else f for f in sc.faults
        )
        moved = result._replace(scenario=replace(sc, faults=faults))
        claims = {c["id"]: c for c in check_claims(moved, metrics)}
        return claims["p002-vb-sigma"]["note"]

    assert vb_note(900.0, 1500.0) == (
        "not checked: the run ends at 1000 s, before 300 s "
        "after the noise step begins (900 + 300 s)"
    )
    assert vb_note(600.0, 800.0) == (
        "not checked: the noise step [600, 800) s is over before 300 s have passed"
    )


def test_named_like_a_built_in_without_its_methods(tmp_path, capsys):
    path = tmp_path / "fake.toml"
    path.write_text(
        'kind = "integrated"\nname = "seed002"\nprofile = "seed002"\n'
        '[filter]\nduration_s = 10.0\n[[aids]]\ntype = "ads"\n'
        '[[methods]]\nname = "ckf"\narchitecture = "centralized"\n'
    )
    assert (
        main(
            [
                "run",
                str(path),
                "--runs",
                "1",
                "--out",
                str(tmp_path / "o"),
                "--no-figures",
                "--quiet",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "paper 002" not in out  # a user's file named seed002 is not the built-in
