"""What the ftnav commands leave on disk: nothing when refused or crashed, no stale files.

Oracles: the listing and bytes of the target before and after.  Every command that
takes ``--out`` (run, trajectory, train-detector, train-fusion, schema) is refused for
bad input and made to crash in its computation: it writes nothing (no folder, none of
the parents it would have created) and an earlier result in the same place is left
byte for byte.  A re-run into a folder replaces exactly the files ftnav listed there.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from output_problems import SMALL

from ftnav.cli import MANIFEST, main

PROFILE = """
name = "short"
imu_rate_hz = 100.0
[start]
lat_deg = 32.0
lon_deg = 118.0
h_m = 500.0
speed_m_s = 80.0
heading_deg = 45.0
[[segments]]
duration_s = 4.0
[[segments]]
duration_s = 2.0
roll_rate_deg_s = 10.0
[[segments]]
duration_s = 4.0
yaw_rate_deg_s = "coordinated"
"""


def _snapshot(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.fixture
def inputs(tmp_path):
    scenario = tmp_path / "small.toml"
    scenario.write_text(SMALL)
    bad = tmp_path / "bad.toml"
    bad.write_text(SMALL.replace('sensor = "pos1"', 'sensor = "pos9"', 1))
    profile = tmp_path / "short.toml"
    profile.write_text(PROFILE)
    return {"scenario": scenario, "bad": bad, "profile": profile}


def _crash(*args, **kwargs):
    raise RuntimeError("crashed on purpose")


# command, target (folder or file below a new folder), refused argv, where to crash (the
# name the command calls, in the module that calls it)
COMMANDS = {
    "run": (
        "out",
        lambda i, o: ["run", i["bad"], "--out", o, "--quiet"],
        lambda i, o: ["run", i["scenario"], "--runs", "2", "--out", o, "--quiet"],
        ("ftnav.cli", "run_scenario"),
    ),
    "trajectory": (
        "out",
        lambda i, o: ["trajectory", i["profile"], "--out", o, "--imu", "x"],
        lambda i, o: ["trajectory", i["profile"], "--out", o],
        ("ftnav.cli", "generate"),
    ),
    "train-detector": (
        "out/det.npz",
        lambda i, o: ["train-detector", i["scenario"], "--out", o, "--method", "nope", "--quiet"],
        lambda i, o: ["train-detector", i["scenario"], "--out", o, "--quiet"],
        ("ftnav.cli", "train_detector"),
    ),
    "train-fusion": (
        "out/fus.npz",
        lambda i, o: ["train-fusion", i["bad"], "--out", o, "--quiet"],
        lambda i, o: ["train-fusion", i["scenario"], "--out", o, "--quiet"],
        ("ftnav.cli", "train_fusion"),
    ),
    "schema": (
        "out/schema.json",
        lambda i, o: ["schema", "--out", Path(o).parent],
        lambda i, o: ["schema", "--out", o],
        ("ftnav.cli", "scenario_json_schema"),
    ),
}


def _argv(items) -> list[str]:
    return [str(a) for a in items]


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_refused_command_creates_nothing(name, inputs, tmp_path, capsys):
    target, refused, _, _ = COMMANDS[name]
    out = tmp_path / "new" / "deeper" / target
    if name == "schema":  # refused because --out is an existing folder
        out.parent.mkdir(parents=True)
    before = _snapshot(tmp_path)
    assert main(_argv(refused(inputs, out))) == 2
    err = capsys.readouterr().err
    assert err.startswith("ftnav: error: ") and err.count("\n") == 1, err
    assert _snapshot(tmp_path) == before
    if name != "schema":
        assert not (tmp_path / "new").exists()
    else:
        assert [p.name for p in (tmp_path / "new").rglob("*")] == ["deeper", "out"]


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_crashed_command_creates_nothing(name, inputs, tmp_path, capsys, monkeypatch):
    import importlib

    target, _, good, (module, attr) = COMMANDS[name]
    monkeypatch.setattr(importlib.import_module(module), attr, _crash)
    out = tmp_path / "new" / "deeper" / target
    before = _snapshot(tmp_path)
    assert main(_argv(good(inputs, out))) == 1
    err = capsys.readouterr().err
    assert err.splitlines()[-1].startswith(
        "ftnav: internal error, please report: RuntimeError: crashed on purpose"
    )
    assert _snapshot(tmp_path) == before
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize("name", ["run", "trajectory"])
def test_refused_or_crashed_run_leaves_the_earlier_results(
    name, inputs, tmp_path, capsys, monkeypatch
):
    import importlib

    _, refused, good, (module, attr) = COMMANDS[name]
    out = tmp_path / "results"
    assert main(_argv(good(inputs, out))) == 0
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    assert main(_argv(refused(inputs, out))) == 2
    assert _snapshot(out) == before
    monkeypatch.setattr(importlib.import_module(module), attr, _crash)
    assert main(_argv(good(inputs, out))) == 1
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
    capsys.readouterr()


def test_crash_while_writing_keeps_the_earlier_results(inputs, tmp_path, monkeypatch, capsys):
    import ftnav.cli as cli

    out = tmp_path / "results"
    argv = _argv(["run", inputs["scenario"], "--runs", "2", "--out", out, "--quiet"])
    assert main(argv) == 0
    before = _snapshot(out)
    # the figures are written, then metrics.json fails
    monkeypatch.setattr(cli, "write_metrics", _crash)
    assert main(argv) == 1
    assert _snapshot(out) == before
    assert [p.name for p in out.iterdir() if ".ftnav-partial-" in p.name] == []
    capsys.readouterr()


def test_rerun_with_fewer_outputs_leaves_no_stale_file(inputs, tmp_path, capsys):
    out = tmp_path / "results"
    scenario = str(inputs["scenario"])
    assert (
        main(["run", scenario, "--runs", "2", "--out", str(out), "--quiet", "--save-estimates"])
        == 0
    )
    first = {p.name for p in out.iterdir()}
    assert {"estimates.nc", "sharing.png", MANIFEST} <= first
    (out / "notes.txt").write_text("my notes")
    (out / "mine.png").write_bytes(b"not ftnav's")
    assert main(["run", scenario, "--runs", "2", "--out", str(out), "--quiet", "--no-figures"]) == 0
    assert {p.name for p in out.iterdir()} == {
        "metrics.json",
        "report.md",
        "report.html",
        MANIFEST,
        "notes.txt",
        "mine.png",
    }
    assert (out / "notes.txt").read_text() == "my notes"
    files = json.loads((out / MANIFEST).read_text())["files"]
    assert sorted(files) == ["metrics.json", "report.html", "report.md"]
    assert "Results written to" in capsys.readouterr().out


def test_trajectory_rerun_without_figure_removes_it(inputs, tmp_path, capsys):
    out = tmp_path / "traj"
    assert main(["trajectory", str(inputs["profile"]), "--out", str(out)]) == 0
    assert (out / "trajectory.png").is_file()
    assert main(["trajectory", str(inputs["profile"]), "--out", str(out), "--no-figure"]) == 0
    assert {p.name for p in out.iterdir()} == {"truth.csv", "imu.csv", MANIFEST}
    capsys.readouterr()


def test_a_manifest_never_deletes_outside_its_folder_or_a_folder(inputs, tmp_path, capsys):
    out = tmp_path / "results"
    out.mkdir()
    (tmp_path / "outside.txt").write_text("keep")
    (out / "sub").mkdir()
    (out / "sub" / "f.txt").write_text("keep")
    (out / MANIFEST).write_text(
        json.dumps({"files": ["../outside.txt", "sub", "sub/f.txt", "/etc/passwd", 3]})
    )
    assert (
        main(
            [
                "run",
                str(inputs["scenario"]),
                "--runs",
                "2",
                "--out",
                str(out),
                "--quiet",
                "--no-figures",
            ]
        )
        == 0
    )
    assert (tmp_path / "outside.txt").read_text() == "keep"
    assert (out / "sub" / "f.txt").read_text() == "keep"
    capsys.readouterr()


def test_out_that_is_a_file_is_refused_before_running(inputs, tmp_path, capsys):
    out = tmp_path / "taken"
    out.write_text("a file")
    assert main(["run", str(inputs["scenario"]), "--out", str(out), "--quiet"]) == 2
    assert capsys.readouterr().err == f"ftnav: error: --out: {str(out)!r} is a file, not a folder\n"
    below = out / "sub"
    assert main(["trajectory", str(inputs["profile"]), "--out", str(below)]) == 2
    assert "is not a folder" in capsys.readouterr().err
    assert out.read_text() == "a file"


@pytest.mark.parametrize("mine", ["metrics.json", "report.md", "sharing.png"])
def test_a_users_file_with_an_outputs_name_is_never_replaced(mine, inputs, tmp_path, capsys):
    """No manifest lists the user's file: the run refuses, naming it, and writes nothing
    (``metrics.json`` is refused before computing; a figure's name when it is known)."""
    out = tmp_path / "results"
    out.mkdir()
    (out / mine).write_text("the user's own")
    (out / "log.csv").write_text("1,2,3")
    before = _snapshot(out)
    argv = ["run", str(inputs["scenario"]), "--runs", "2", "--out", str(out), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ftnav: error: --out: "), err
    assert f"{str(out / mine)!r} exists and no ftnav manifest lists it" in err
    assert _snapshot(out) == before
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_a_model_files_figure_of_the_users_is_never_replaced(inputs, tmp_path, capsys):
    out = tmp_path / "det.npz"
    (tmp_path / "det.png").write_bytes(b"the user's picture")
    argv = ["train-detector", str(inputs["scenario"]), "--out", str(out), "--quiet"]
    assert main([*argv, "--runs", "2", "--holdout", "1"]) == 2
    assert "det.png' exists and no ftnav manifest lists it" in capsys.readouterr().err
    assert not out.exists()
    assert (tmp_path / "det.png").read_bytes() == b"the user's picture"


def test_single_files_are_kept_by_a_folder_run_into_the_same_folder(inputs, tmp_path, capsys):
    """A schema written into a folder is listed as ``kept``: a later folder run there
    neither deletes it nor refuses; writing the schema again replaces it."""
    out = tmp_path / "results"
    assert main(["schema", "--out", str(out / "schema.json")]) == 0
    assert main(["schema", "--out", str(out / "schema.json")]) == 0
    argv = ["run", str(inputs["scenario"]), "--runs", "2", "--out", str(out), "--quiet"]
    assert main([*argv, "--no-figures"]) == 0
    assert main([*argv, "--no-figures"]) == 0
    manifest = json.loads((out / MANIFEST).read_text())
    assert manifest["kept"] == ["schema.json"]
    assert (out / "schema.json").is_file()
    capsys.readouterr()


def test_a_full_disk_is_a_one_line_refusal_and_the_earlier_result_stays(
    inputs, tmp_path, monkeypatch, capsys
):
    import errno

    import ftnav.cli as cli

    out = tmp_path / "results"
    argv = ["run", str(inputs["scenario"]), "--runs", "2", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    before = _snapshot(out)
    capsys.readouterr()

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cli, "write_metrics", full)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"ftnav: error: --out: cannot write {str(out)!r}: No space left on device\n"
    assert _snapshot(out) == before
    assert [p.name for p in out.iterdir() if ".ftnav-partial-" in p.name] == []


def test_a_broken_link_as_out_is_refused(inputs, tmp_path, capsys):
    out = tmp_path / "link"
    out.symlink_to(tmp_path / "nowhere")
    argv = ["run", str(inputs["scenario"]), "--runs", "2", "--out", str(out), "--quiet"]
    assert main(argv) == 2
    assert "is a broken symbolic link" in capsys.readouterr().err
    assert out.is_symlink() and not (tmp_path / "nowhere").exists()


def test_a_diverged_run_is_exit_3_one_line_and_writes_nothing(inputs, tmp_path, capsys):
    """F = 1e10 in a scenario: the variance overflows within some epochs; the run says
    which method diverged where, and no result is written (an earlier one stays)."""
    out = tmp_path / "results"
    argv = ["run", str(inputs["scenario"]), "--runs", "2", "--out", str(out), "--quiet"]
    assert main([*argv, "--no-figures"]) == 0
    before = _snapshot(out)
    capsys.readouterr()
    wild = tmp_path / "wild.toml"
    wild.write_text(SMALL.replace("F  = [[1.0, 0.05, 0.00125]", "F  = [[1e10, 0.05, 0.00125]", 1))
    assert main(["run", str(wild), "--runs", "2", "--out", str(out), "--quiet"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert re.match(
        r"ftnav: error: methods\[\w+\]: diverged at epoch \d+ \(t = [\d.]+ s\): .*; "
        r"nothing written\n$",
        err,
    ), err
    assert _snapshot(out) == before


def test_single_files_in_one_folder_are_all_kept_in_its_manifest(tmp_path, capsys):
    """Each commit updates the folder's manifest under a lock of its own, so files
    written by different commands into one folder are all listed (and replaceable)."""
    for name in ("a.json", "b.json", "a.json"):
        assert main(["schema", "--out", str(tmp_path / name)]) == 0
    assert json.loads((tmp_path / MANIFEST).read_text())["kept"] == ["a.json", "b.json"]
    capsys.readouterr()


def test_a_file_a_user_wrote_again_under_an_outputs_name_is_never_replaced(tmp_path, capsys):
    """ftnav listed ``s1.json`` as its own; the user deleted it and wrote notes under
    that name; ``ftnav schema --out s1.json`` replaced them, exit 0 (found by a user's
    try).  The manifest holds each file's size and modification time as written: a file
    that is no longer what ftnav wrote is the user's."""
    out = tmp_path / "s1.json"
    assert main(["schema", "--out", str(out)]) == 0
    assert main(["schema", "--out", str(out)]) == 0  # its own: replaced
    out.unlink()
    out.write_text("USER NOTES\n")
    capsys.readouterr()
    assert main(["schema", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "exists and no ftnav manifest lists it (or it changed since" in err, err
    assert out.read_text() == "USER NOTES\n"
