"""Shards of a campaign (issue 23 item 5): ``ftnav run --runs A:B`` and ``ftnav merge``.

Oracle: the campaign run at once.  Run ``i`` depends on the root seed and ``i`` only,
so shards merged must give the whole campaign's ``metrics.json`` exactly (every RMSE,
ANEES, detection number, interval and claim), for a linear scenario through the CLI
and for an integrated one (guard, local filters, VB noise) through the shard file.
Merging shards that do not make one campaign is refused in one line, exit 2.
"""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest
from seed000_copy import seed000_copy

from ftnav.cli import main
from ftnav.eval.evaluate import evaluate
from ftnav.eval.montecarlo import RESULT_FIELDS, ScenarioResult, join_results, run_scenario
from ftnav.io.scenario_file import load_scenario
from ftnav.io.shards import SHARD, ShardHeader, read_shard, write_shard
from ftnav.scenarios import builtin_path

KEEP = ("ckf", "fkf-inverse-trace-chi2", "fkf-inverse-trace-cusum")
FAST = ["--no-figures", "--quiet", "--workers", "1"]


@pytest.fixture(scope="module")
def shards(tmp_path_factory):
    root = tmp_path_factory.mktemp("shards")
    sc = seed000_copy(root / "small.toml", KEEP, steps=400)
    for runs, out in (("0:2", "a"), ("2:5", "b"), ("5", "whole")):
        assert main(["run", str(sc), "--runs", runs, "--out", str(root / out), *FAST]) == 0
    return root, sc


def _doc(path):
    return json.loads((path / "metrics.json").read_text())


def test_shards_merged_equal_the_whole_run(shards):
    root, _ = shards
    assert (root / "a" / SHARD).exists() and not (root / "whole" / SHARD).exists()
    merge = ["merge", str(root / "b"), str(root / "a"), "--out", str(root / "m"), "--no-figures"]
    assert main(merge) == 0
    merged, whole = _doc(root / "m"), _doc(root / "whole")
    assert [s["first_run"] for s in merged.pop("merged")] == [0, 2]
    assert merged == whole
    assert (root / "m" / "report.md").read_text() == (root / "whole" / "report.md").read_text()


@pytest.mark.parametrize(
    ("folders", "says"),
    [
        (["a", "a"], "overlap"),
        (["b"], None),  # one shard alone is a campaign of its runs (2..4)
        (["a", "gap"], "are in no shard"),
        (["a", "seed"], "another seed"),
        (["a", "whole"], "no shard.npz"),
    ],
)
def test_shards_that_are_not_one_campaign_are_refused(shards, folders, says, capsys):
    root, sc = shards
    extra = {"gap": ("3:5", []), "seed": ("2:3", ["--seed", "7"])}
    for f in folders:
        if f in extra and not (root / f).exists():
            runs, more = extra[f]
            main(["run", str(sc), "--runs", runs, "--out", str(root / f), *FAST, *more])
    capsys.readouterr()
    out = root / f"m-{'-'.join(folders)}"
    code = main(["merge", *(str(root / f) for f in folders), "--out", str(out)])
    err = capsys.readouterr().err
    if says is None:
        assert code == 0 and _doc(out)["first_run"] == 2 and _doc(out)["runs"] == 3
        return
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_changed_scenario_file_is_refused(tmp_path, capsys):
    sc = seed000_copy(tmp_path / "s.toml", KEEP[:1], steps=400)
    assert main(["run", str(sc), "--runs", "0:1", "--out", str(tmp_path / "a"), *FAST]) == 0
    sc.write_text(sc.read_text().replace("steps = 400", "steps = 401"))
    capsys.readouterr()
    assert main(["merge", str(tmp_path / "a"), "--out", str(tmp_path / "m")]) == 2
    assert "has changed since" in capsys.readouterr().err


def test_runs_a_to_b_must_be_a_range(tmp_path, capsys):
    sc = seed000_copy(tmp_path / "s.toml", KEEP[:1], steps=400)
    assert main(["run", str(sc), "--runs", "3:3", "--out", str(tmp_path / "a")]) == 2
    assert "B must be greater than A" in capsys.readouterr().err
    assert not (tmp_path / "a").exists()


@pytest.mark.parametrize("kind", ["npy", "text", "npz", "broken zip"])
def test_a_file_that_is_no_shard_is_refused_without_unpickling_advice(tmp_path, capsys, kind):
    """A file that is no shard: one line, exit 2.  An .npy ended in an internal error, and
    a text file in NumPy's advice to load it with ``allow_pickle`` or ``pickle.load()``:
    ftnav never unpickles what a user names, nor suggests it."""
    path = tmp_path / "shard.npz"
    if kind == "npy":
        with path.open("wb") as f:
            np.save(f, np.zeros(3))
    elif kind == "text":
        path.write_text("runs,rmse\n1,2\n")
    elif kind == "npz":
        np.savez(path, x=np.zeros(2))
    else:
        path.write_bytes(b"PK\x03\x04not a zip")
    capsys.readouterr()
    assert main(["merge", str(path), "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"ftnav: error: shards: {path}: not a shard written by"), err
    assert "pickle" not in err
    assert not (tmp_path / "m").exists()


def test_an_integrated_shard_file_round_trips_and_joins_to_the_whole(tmp_path):
    sc = load_scenario(builtin_path("seed002"))
    keep = tuple(m for m in sc.methods if m.name in ("ckf", "fkf-chi2", "dkf-vb"))
    sc = replace(sc, steps=90, methods=keep)
    names = tuple(m.name for m in keep)
    parts = []
    for first, runs in ((0, 1), (1, 2)):
        path = tmp_path / f"{first}.npz"
        header = ShardHeader(sc.name, "x", "0" * 64, 1, first, runs, names)
        write_shard(path, header, run_scenario(sc, runs, 1, first_run=first))
        got, (results, fault_free) = read_shard(path)
        assert got == header
        parts.append(ScenarioResult(sc, runs, 1, results, fault_free))
    joined, whole = join_results(parts), run_scenario(sc, 3, 1)
    for which in ("results", "fault_free"):
        a, b = getattr(joined, which), getattr(whole, which)
        assert list(a) == list(b)
        for name in a:
            for field in RESULT_FIELDS:
                x, y = getattr(a[name], field), getattr(b[name], field)
                if isinstance(y, tuple):
                    assert len(x) == len(y), field
                    for u, v in zip(x, y, strict=True):
                        np.testing.assert_array_equal(u, v, err_msg=field)
                elif y is None:
                    assert x is None, field
                else:
                    np.testing.assert_array_equal(x, y, err_msg=field)
    e1, e2 = evaluate(joined), evaluate(whole)
    assert {n: m.rmse for n, m in e1.items()} == {n: m.rmse for n, m in e2.items()}


def test_a_merge_into_one_of_its_shards_is_refused(shards, capsys):
    """The merged result would replace that shard's files: its runs could not be merged
    again with a later shard (found by a user's try: exit 0, ``shard.npz`` gone)."""
    root, _ = shards
    before = (root / "a" / SHARD).read_bytes()
    capsys.readouterr()
    assert main(["merge", str(root / "a"), str(root / "b"), "--out", str(root / "a")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is the folder of the shard" in err, err
    assert (root / "a" / SHARD).read_bytes() == before


def _damaged(src, dst, edit) -> None:
    """A copy of the shard ``src`` with its header (a dict) or arrays changed by ``edit``."""
    with np.load(src, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    doc = json.loads(arrays["header.json"].tobytes().decode())
    edit(doc, arrays)
    arrays["header.json"] = np.frombuffer(json.dumps(doc).encode(), np.uint8)
    dst.mkdir()
    np.savez(dst / SHARD, **arrays)


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (lambda d, a: d.update(runs="3"), r"runs: '3' is not a whole number"),
        (lambda d, a: d.update(runs=4), r"holds 3 runs, its header 4"),
        (lambda d, a: d.update(first_run=-2), r"first_run: -2 is below 0"),
        (lambda d, a: d.update(seed=1.0), r"seed: 1.0 is not a whole number"),
        (lambda d, a: d.update(methods="ckf"), r"not the fields of a shard"),
        (
            lambda d, a: a.update({"results/ckf/error": a["results/ckf/error"][:1]}),
            r"results/ckf/error holds 1 runs, its header 3",
        ),
    ],
)
def test_a_shard_with_a_damaged_header_or_runs_is_refused(shards, edit, says, capsys, tmp_path):
    """A header field of the wrong type ended in an internal error; a run count or a
    first run that the arrays do not hold merged silently (a campaign of 5 runs from 4,
    methods averaged over different runs)."""
    root, _ = shards
    _damaged(root / "b" / SHARD, tmp_path / "bad", edit)
    capsys.readouterr()
    merge = ["merge", str(root / "a"), str(tmp_path / "bad"), "--out", str(tmp_path / "m")]
    assert main(merge) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and re.search(says, err), err
    assert not (tmp_path / "m").exists()
