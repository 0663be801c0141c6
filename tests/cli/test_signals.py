"""Interruption and concurrency of ``ftnav run``: no process left, no output lost.

Oracles: the process table (``/proc``: every descendant of the killed command is gone
within 5 s), the listing and bytes of ``--out`` before and after, and the exit status
and message of a second command on the same ``--out``.  Linux only (``/proc``).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from output_problems import SMALL

from ftnav.io.output_folder import MANIFEST, PARTIAL

pytestmark = pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc")

#: long enough that the workers are still computing when the signal comes (minutes)
LONG = SMALL.replace("steps = 60", "steps = 5000")


def _default_interrupts() -> None:
    """In the child before exec: SIGINT and SIGQUIT back to their default action.

    A test run started in the background by a non-interactive shell (``make test &``,
    CI runners) inherits SIGINT ignored, and Python then keeps it ignored (POSIX), so
    ``ftnav`` would be right to ignore the Ctrl-C this test sends.  The test is about
    a Ctrl-C from a terminal, so it gives the command a terminal's dispositions.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)


def _ftnav(*args: str | Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "ftnav.cli", *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_default_interrupts,  # noqa: PLW1509 (no threads started by then)
    )


def _children(pid: int) -> set[int]:
    out: set[int] = set()
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for t in tasks:
        try:
            text = Path(f"/proc/{pid}/task/{t}/children").read_text()
        except OSError:
            continue
        for c in text.split():
            out.add(int(c))
            out |= _children(int(c))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))}


def _wait_for_workers(proc: subprocess.Popen[str], n: int) -> set[int]:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        kids = _children(proc.pid)
        if len(kids) >= n:
            time.sleep(0.5)
            return _children(proc.pid)
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    raise AssertionError("the workers did not start")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL, signal.SIGINT])
def test_killed_run_leaves_no_process_and_the_earlier_result(sig, tmp_path) -> None:
    scenario = tmp_path / "long.toml"
    scenario.write_text(LONG)
    out = tmp_path / "out"
    small = tmp_path / "small.toml"
    small.write_text(SMALL)
    first = _ftnav("run", small, "--runs", "2", "--out", out, "--quiet", "--no-figures")
    assert first.wait(120) == 0, first.communicate()
    before = _snapshot(out)

    proc = _ftnav(
        "run", scenario, "--runs", "400", "--workers", "2", "--out", out, "--quiet", "--no-figures"
    )
    try:
        workers = _wait_for_workers(proc, 3)  # the resource tracker and two workers
        proc.send_signal(sig)
        status = proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    left = [p for p in workers if _alive(p)]
    for p in left:  # do not leave them to the next test either
        os.kill(p, signal.SIGKILL)
    assert left == [], f"processes left 5 s after {sig.name}: {left}"
    err = proc.stderr.read() if proc.stderr else ""
    if sig == signal.SIGKILL:
        assert status == -signal.SIGKILL
    else:
        assert status == 128 + sig or status == 130, (status, err)
        assert err.startswith("ftnav: "), err
        assert "Traceback" not in err, err
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir() if PARTIAL in p.name] == []


def test_stale_staging_folder_is_rolled_back_by_the_next_run(tmp_path, capsys) -> None:
    """A run killed inside its commit (simulated: the journal as SIGKILL leaves it) is
    undone by the next command on the same --out, which then writes its own result."""
    from ftnav.cli import main

    small = tmp_path / "small.toml"
    small.write_text(SMALL)
    out = tmp_path / "out"
    argv = ["run", str(small), "--runs", "2", "--out", str(out), "--quiet", "--no-figures"]
    assert main(argv) == 0
    before = _snapshot(out)
    # the journal of a commit killed after moving one new file in
    stage = out / f".out{PARTIAL}deadbeef0000"
    (stage / ".previous").mkdir(parents=True)
    for name in ("metrics.json", MANIFEST):
        os.replace(out / name, stage / ".previous" / name)
    (out / "metrics.json").write_text('{"half": "written"}')
    (stage / "report.md").write_text("new, not yet moved")
    (stage / MANIFEST).write_text(
        json.dumps({"files": ["metrics.json", "report.md"], "last": ["metrics.json", "report.md"]})
    )
    from ftnav.io.output_folder import Output

    with Output(out, folder=True) as o:
        o.claim()
    assert _snapshot(out) == before  # the earlier result, complete; no stray folder
    assert main(argv) == 0
    assert [p.name for p in out.iterdir() if PARTIAL in p.name] == []
    capsys.readouterr()


def test_two_runs_on_one_out_one_refuses_the_other_completes(tmp_path) -> None:
    scenario = tmp_path / "mid.toml"
    scenario.write_text(SMALL.replace("steps = 60", "steps = 3000"))  # some seconds
    out = tmp_path / "out"
    argv = (
        "run",
        scenario,
        "--runs",
        "6",
        "--out",
        out,
        "--quiet",
        "--workers",
        "1",
        "--no-figures",
    )
    a, b = _ftnav(*argv), _ftnav(*argv)
    results = [(p.wait(300), *p.communicate()) for p in (a, b)]
    statuses = sorted(r[0] for r in results)
    assert statuses == [0, 2], results
    refused = next(r for r in results if r[0] == 2)
    assert refused[2].count("\n") == 1, refused[2]
    assert "is being written by another ftnav command" in refused[2], refused[2]
    manifest = json.loads((out / MANIFEST).read_text())
    assert {"metrics.json", "report.md"} <= set(manifest["files"])
    for name in manifest["files"]:
        assert (out / name).stat().st_size > 0
    json.loads((out / "metrics.json").read_text())
