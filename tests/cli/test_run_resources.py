"""``ftnav`` checks what a run needs before it starts: memory, and says when it compiles.

Oracles: a run whose estimated peak memory (:func:`ftnav.eval.resources.run_memory_bytes`)
exceeds the available memory is refused with exit status 2 and one line naming the
field and the numbers, and writes nothing; the compile note appears exactly when the
kernel-cache marker is missing, and never with ``--quiet``.
"""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

import ftnav.eval.resources as resources
from ftnav.cli import COMPILING, main
from ftnav.eval.resources import format_bytes, max_runs_within, run_memory_bytes
from ftnav.io.scenario_file import load_scenario

SMALL = """
name = "small"
dt = 1.0
steps = {steps}
[model]
states = ["s", "v"]
F  = [[1.0, 1.0], [0.0, 1.0]]
Q  = [[0.5, 0.5], [0.5, 1.0]]
x0 = [0.0, 0.0]
P0 = [[100.0, 0.0], [0.0, 100.0]]
[[sensors]]
name = "pos1"
H = [[1.0, 0.0]]
R = [[30.0]]
[[sensors]]
name = "pos2"
H = [[1.0, 0.0]]
R = [[30.0]]
[[faults]]
sensor = "pos1"
kind = "bias"
start = 10.0
end = 20.0
magnitude = [60.0]
[[methods]]
name = "ckf"
architecture = "centralized"
[[methods]]
name = "fkf"
detector = {{ kind = "residual-chi2" }}
"""

INTEGRATED = """
kind = "integrated"
name = "short-ins"
profile = "seed002"
[filter]
duration_s = 20.0
[[aids]]
type = "ads"
[[methods]]
name = "ckf"
architecture = "centralized"
"""


def _write(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _refused(argv, capsys) -> str:
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err.strip()


def test_huge_runs_are_refused_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "out"
    err = _refused(["run", "seed000", "--runs", 10**12, "--out", out], capsys)
    assert re.fullmatch(
        r"ftnav: error: --runs: 1000000000000 runs of seed000 need about "
        r"[\d.]+ TiB, more than the [\d.]+ [GMT]iB available "
        r"\(at most \d+ would fit\)",
        err,
    ), err
    assert not out.exists()


@pytest.mark.parametrize(
    ("command", "scenario", "per_run"),
    [("train-detector", "seed000", 32), ("train-fusion", "seed000", 28),
     ("train-fusion", "seed001", 5)],
)  # fmt: skip
def test_huge_training_runs_are_refused_before_anything_is_written(
    tmp_path, capsys, command, scenario, per_run
):
    """A training simulates its runs times its fault variants (or configurations) at once:
    ``--runs 1e12`` ended in an internal MemoryError (exit 1)."""
    out = tmp_path / "model.npz"
    err = _refused([command, scenario, "--runs", 10**12, "--out", out], capsys)
    assert re.fullmatch(
        r"ftnav: error: --runs: 1000000000000 training runs( and \d+ held out)? of "
        rf"{scenario} \({per_run} simulated at once each\) need about [\d.]+ TiB, more "
        r"than the [\d.]+ [GMT]iB available \(at most \d+ would fit\)",
        err,
    ), err
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_huge_steps_are_refused_naming_steps(tmp_path, capsys):
    path = _write(tmp_path, SMALL.format(steps=10**10))
    out = tmp_path / "out"
    err = _refused(["run", path, "--runs", 1, "--out", out], capsys)
    assert re.fullmatch(
        r"ftnav: error: steps: one run of small \(10000000000 epochs of 1 s\) "
        r"needs about [\d.]+ TiB, more than the [\d.]+ [GMT]iB available",
        err,
    )
    assert not out.exists()


def test_console_script_refuses_huge_runs_in_one_line(tmp_path):
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "ftnav.cli",
            "run",
            "seed000",
            "--runs",
            "100000000",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.startswith("ftnav: error: --runs: 100000000 runs of seed000 need about ")
    assert proc.stderr.count("\n") == 1 and not (tmp_path / "o").exists()


def test_refusal_names_the_estimate_and_the_most_runs_that_fit(tmp_path, capsys, monkeypatch):
    path = _write(tmp_path, SMALL.format(steps=100))
    sc = load_scenario(path)
    available = 64 << 20
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: available)
    fit = max_runs_within(sc, available)
    assert fit > 1
    err = _refused(["run", path, "--runs", fit + 1, "--out", tmp_path / "o", "--quiet"], capsys)
    need = format_bytes(run_memory_bytes(sc, fit + 1))
    assert err == (
        f"ftnav: error: --runs: {fit + 1} runs of small need about {need}, more "
        f"than the 64.0 MiB available (at most {fit} would fit)"
    )
    assert (
        main(
            [
                "run",
                str(path),
                "--runs",
                str(fit),
                "--out",
                str(tmp_path / "o"),
                "--quiet",
                "--no-figures",
            ]
        )
        == 0
    )
    capsys.readouterr()


def test_estimates_nc_counts_in_the_check(tmp_path, capsys, monkeypatch):
    path = _write(tmp_path, SMALL.format(steps=100))
    sc = load_scenario(path)
    runs = 50
    plain, saved = run_memory_bytes(sc, runs), run_memory_bytes(sc, runs, save_estimates=True)
    assert saved > plain
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: (plain + saved) // 2)
    _refused(["run", path, "--runs", runs, "--out", tmp_path / "o", "--save-estimates"], capsys)


def test_integrated_flight_too_long_for_one_run_names_the_duration(tmp_path, capsys, monkeypatch):
    path = _write(tmp_path, INTEGRATED)
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 1 << 20)
    err = _refused(["run", path, "--out", tmp_path / "o"], capsys)
    assert err.startswith(
        "ftnav: error: filter.duration_s: one run of short-ins (20 epochs of 1 s) needs about "
    )
    assert not (tmp_path / "o").exists()


def test_trajectory_too_long_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 1 << 20)
    err = _refused(["trajectory", "seed002", "--out", tmp_path / "t"], capsys)
    assert err.startswith("ftnav: error: profile: 3600 s at 100 Hz needs about ")
    assert not (tmp_path / "t").exists()


def test_unknown_available_memory_runs_unchecked(tmp_path, capsys, monkeypatch):
    path = _write(tmp_path, SMALL.format(steps=30))
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: None)
    assert (
        main(
            [
                "run",
                str(path),
                "--runs",
                "2",
                "--out",
                str(tmp_path / "o"),
                "--quiet",
                "--no-figures",
            ]
        )
        == 0
    )
    capsys.readouterr()


# --------------------------------------------------------------- compile note, first use


@pytest.fixture
def cold_cache(tmp_path, monkeypatch):
    """The markers live in an empty folder (numba keeps its own, warm cache: setting
    NUMBA_CACHE_DIR here would make it compile everything again)."""
    folder = tmp_path / "markers"
    monkeypatch.setattr(resources, "_marker_folder", lambda: folder)
    return folder


def test_compile_note_on_first_use_only_and_never_when_quiet(tmp_path, capsys, cold_cache):
    path = _write(tmp_path, SMALL.format(steps=30))
    argv = ["run", str(path), "--runs", "2", "--out", str(tmp_path / "o"), "--no-figures"]
    note = COMPILING.format(15)
    assert main([*argv, "--quiet"]) == 0
    assert "compiling" not in capsys.readouterr().err  # quiet: no note, and now marked
    assert resources.kernels_compiled("linear")
    for marker in cold_cache.glob("ftnav-kernels-*"):
        marker.unlink()
    assert main(argv) == 0
    assert capsys.readouterr().err.count(note) == 1
    assert main(argv) == 0
    assert "compiling" not in capsys.readouterr().err


def test_marker_follows_the_kernel_sources(tmp_path, cold_cache, monkeypatch):
    source = tmp_path / "kernels.py"
    source.write_text("@numba.njit(cache=True)\n")
    monkeypatch.setattr(resources, "_kernel_sources", lambda: [source])
    assert not resources.kernels_compiled("linear")
    resources.mark_kernels_compiled("linear")
    assert resources.kernels_compiled("linear")
    assert not resources.kernels_compiled("integrated")  # per kind of run
    source.write_text("@numba.njit(cache=True)  # edited: numba compiles again\n")
    assert not resources.kernels_compiled("linear")
    resources.mark_kernels_compiled("linear")
    assert len(list(cold_cache.glob("ftnav-kernels-linear-*"))) == 1  # the old one is gone


def test_kernel_sources_are_the_modules_with_cached_kernels():
    names = {p.name for p in resources._kernel_sources()}
    assert {"linalg.py", "mechanization.py", "trajectory.py"} <= names
    assert "resources.py" not in names and "cli.py" not in names


def test_run_scenario_from_python_is_refused_by_its_memory_too(tmp_path, monkeypatch):
    """``ftnav.run_scenario(sc, 10**9, 1)`` ran 16 s and ended in NumPy's
    ``_ArrayMemoryError`` (found by a user's try): the CLI's estimate, refused naming
    ``runs`` before anything runs."""
    from ftnav.eval.montecarlo import run_scenario

    sc = load_scenario(_write(tmp_path, SMALL.format(steps=100)))
    available = 64 << 20
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: available)
    fit = max_runs_within(sc, available)
    with pytest.raises(
        ValueError,
        match=rf"^runs: {fit + 1} runs of small need about .* \(at most {fit} would fit\)$",
    ):
        run_scenario(sc, fit + 1, 1)


def test_the_integrated_estimate_holds_the_guards_pulls():
    """The guard's tracked pulls ((B, aids, J, n, n) per method with a detector: J = 23
    blocks at dt = 1 s) were left out: an integrated campaign of 100 runs took 1009 MiB
    against 358 MiB estimated (found by a user's try)."""
    from dataclasses import replace

    sc = load_scenario("seed002")
    guarded = tuple(m for m in sc.methods if m.detector.kind not in ("none", "oracle"))
    plain = replace(sc, methods=tuple(m for m in sc.methods if m not in guarded))
    assert guarded and plain.methods
    pulls = resources._guard_bytes(guarded, 200, float(sc.dt), len(sc.aids), sc.error_model.n)
    one = 3 * 200 * len(sc.aids) * (23 + 2) * (sc.error_model.n**2 + sc.error_model.n) * 8
    assert sc.dt == 1.0 and pulls == len(guarded) * one
    assert run_memory_bytes(sc, 100) - run_memory_bytes(plain, 100) >= pulls
