"""Command-line options at the boundary: each bad value is exit 2 and one line naming it.

Oracle: the exit status, the one line on stderr (``ftnav: error: <option>: ...``) and
an ``--out`` left unwritten.  Each case was once a silent wrong answer or a hang:
``--out ""`` wrote into the current folder, ``--methods ""`` ran every method,
``--methods ckf,ckf`` ran one twice, 10 s outages every 5 s never ended, a fault of
1e300 m overflowed the filter into an internal error, ``/dev/zero`` as a scenario
was read until the memory ran out.
"""

from __future__ import annotations

import pytest

from ftnav.cli import main

CASES = {
    "empty out": (["run", "seed000", "--runs", "1", "--out", ""], "--out: must be a path"),
    "device scenario": (["run", "/dev/zero", "--out", "{out}"], "/dev/zero: is a device"),
    "empty methods": (
        ["process", "rtklib-drive", "--methods", "", "--out", "{out}"],
        "--methods: expected comma-separated names",
    ),
    "methods with a hole": (
        ["process", "rtklib-drive", "--methods", "ckf,,fkf-glr", "--out", "{out}"],
        "--methods: expected comma-separated names",
    ),
    "repeated method": (
        ["process", "rtklib-drive", "--methods", "ckf,ckf", "--out", "{out}"],
        "--methods: 'ckf' given twice",
    ),
    "empty aids": (
        ["process", "rtklib-drive", "--aids", "", "--out", "{out}"],
        "--aids: expected comma-separated names",
    ),
    "outages longer than their spacing": (
        ["process", "rtklib-drive", "--outage-length", "10", "--outage-every", "5"],
        "--outage-length: 10 s outages every 5 s leave no GNSS fix",
    ),
    "huge bias": (
        ["process", "rtklib-drive", "--fault", "gnss:bias:1752003400:1752003460:1e300"],
        "--fault: MAGNITUDE 1e+300 m is beyond",
    ),
    "huge ramp": (
        ["process", "rtklib-drive", "--fault", "gnss:ramp:1752003400:1752003460:-1e30"],
        "--fault: MAGNITUDE -1e+30 m is beyond",
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_bad_option_is_one_line_and_exit_2(case, tmp_path, capsys) -> None:
    argv, message = CASES[case]
    out = tmp_path / "out"
    argv = [a.replace("{out}", str(out)) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ftnav: error: "), err
    assert message in err, err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_a_reader_that_closes_the_pipe_early_is_no_internal_error() -> None:
    """``ftnav list | head -3``: the reader closes the pipe while ftnav still writes.  It
    ended in ``internal error, please report: BrokenPipeError`` (exit 1); the rest of the
    output is now discarded and the command finishes as it would have (exit 0)."""
    import subprocess
    import sys

    code = "import sys; from ftnav.cli import main; sys.exit(main(['list']))"
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert proc.stdout is not None and proc.stderr is not None
    first = proc.stdout.readline()
    proc.stdout.close()  # the reader is gone; ftnav has most of the list still to write
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0, err
    assert first.startswith(b"seed000:")
    assert "internal error" not in err and "Broken" not in err, err


@pytest.mark.parametrize(
    ("env", "redirect"),
    [
        ({"PYTHONIOENCODING": "ascii"}, None),  # a terminal that cannot show σ or ±
        ({"LC_ALL": "C", "PYTHONUTF8": "0"}, None),  # report.md in the locale's encoding
        ({}, "closed"),  # ftnav list >&-
        ({}, "/dev/full"),  # no space left for stdout
    ],
)
def test_the_output_streams_environment_is_no_internal_error(tmp_path, env, redirect) -> None:
    """Each ended in ``internal error, please report`` (a UnicodeEncodeError, once after
    the whole campaign with nothing written; an AttributeError on a closed stdout, exit
    120; ENOSPC), found by a user's try.  Files are UTF-8 whatever the locale; what the
    terminal cannot show is escaped; a stdout gone is no error."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "cli"))
    from seed000_copy import seed000_copy

    sc = seed000_copy(tmp_path / "s.toml", ("ckf",), steps=400)
    out = tmp_path / "o"
    argv = ["run", str(sc), "--runs", "1", "--out", str(out), "--no-figures", "--quiet"]
    code = f"import sys; from ftnav.cli import main; sys.exit(main({argv!r}))"
    stdout: object = subprocess.PIPE
    if redirect == "closed":
        code = "import os; os.close(1); " + code
    elif redirect == "/dev/full":
        if not os.path.exists("/dev/full"):
            pytest.skip("no /dev/full here")
        stdout = open("/dev/full", "w")  # noqa: SIM115 - closed below
    proc = subprocess.run(
        [sys.executable, "-c", code],
        stdout=stdout,
        stderr=subprocess.PIPE,
        env={**os.environ, **env},
        timeout=300,
    )
    if redirect == "/dev/full":
        stdout.close()  # type: ignore[attr-defined]
    err = proc.stderr.decode("utf-8", "replace")
    assert proc.returncode == 0 and "internal error" not in err, err
    assert "±" in (out / "report.md").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        # an internal error after the training
        (["train-detector", "{sc}", "--out", "{tmp}/d.npz", "--runs", "1", "--holdout", "1",
          "--centres", "4000", "--no-figure", "--quiet"], "--centres: 4000 hidden units need"),
        # wrote a file named 'newdir'
        (["schema", "--out", "{tmp}/newdir/"], "--out: '{tmp}/newdir/' names a folder"),
        # ignored on a linear scenario
        (["train-fusion", "{sc}", "--out", "{tmp}/f.npz", "--method", "nope", "--quiet"],
         "--method: for an integrated scenario's neural methods"),
        # ignored with the ideal IMU
        (["trajectory", "seed001", "--out", "{tmp}/t", "--seed", "5"],
         "--seed: given without --imu"),
        # the first target dropped in silence
        (["run", "{sc}", "--until", "ckf.rmse.s:rel=0.5", "--until", "ckf.anees:rel=0.5",
          "--out", "{tmp}/u"], "--until: given twice"),
        # '.: is a folder, not a file', naming neither the argument nor the value
        (["run", ""], "scenario: an empty name"),
        (["process", ""], "recording: an empty name"),
        # blamed END
        (["process", "rtklib-drive", "--fault", "sins:gyro-bias:1752003400:1752003430:nan,0,0",
          "--out", "{tmp}/p"], "--fault: X,Y,Z must be finite"),
    ],
)  # fmt: skip
def test_an_option_ignored_or_misread_is_refused_by_name(tmp_path, capsys, argv, says) -> None:
    """Found by a user's try of every option: each was ignored, misread or an internal
    error; now one line naming the option, exit 2, nothing written."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "cli"))
    from seed000_copy import seed000_copy

    sc = seed000_copy(tmp_path / "s.toml", ("ckf", "fkf-inverse-trace-chi2"), steps=60)
    (tmp_path / "s.toml").write_text(
        (tmp_path / "s.toml")
        .read_text()
        .replace("start = 300.0", "start = 20.0")
        .replace("end = 500.0", "end = 50.0")
    )
    args = [a.format(sc=sc, tmp=tmp_path) for a in argv]
    before = set(tmp_path.iterdir())
    assert main(args) == 2
    err = capsys.readouterr().err
    (line,) = [ln for ln in err.splitlines() if not ln.startswith("ftnav: warning:")]
    assert says.format(tmp=tmp_path) in line and line.startswith("ftnav: error: "), err
    assert set(tmp_path.iterdir()) == before
