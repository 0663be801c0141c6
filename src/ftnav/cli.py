"""Command-line interface: ``ftnav run | list | schema | trajectory | train-*``.

Exit status, and what goes to standard error:

* 0: done.
* 2: bad input, found before anything is computed or written: one line
  ``ftnav: error: <field>: <reason>`` (a malformed scenario, an unknown built-in, an
  impossible option, a model file that does not fit the scenario, a run that needs
  more memory than the machine has available).  A bare ``ftnav`` (no command) prints
  the help and exits 2 as well: argparse's status for a usage error.
* 3: a method diverged (its estimate became NaN or inf, or its covariance stopped
  being symmetric positive definite; checked at every epoch of every run): one line
  ``ftnav: error: methods[NAME]: diverged at epoch K (t = T s): <reason>; nothing
  written``.  A model that cannot be computed is not a result.
* 1: anything else, which is a bug: one line ``ftnav: internal error, please report:
  <ExceptionType>: <message> (run again with --debug for the traceback)``.
* 130: interrupted.

A warning (a modelling approximation of the scenario, e.g. an IMU error its filter
model cannot represent) is one line ``ftnav: warning: <message>`` and does not
change the exit status.  A reader that closes the pipe early (``ftnav list | head``)
changes nothing either: the rest of the printed output is discarded and the command
finishes its work.

``--debug`` (before or after the command name) prints the full traceback of either
kind before the line.

Outputs.  A command writes nothing before its input is validated and its
computation has succeeded, and never replaces a file that is not its own
(:mod:`ftnav.io.output_folder`): the ``--out`` target is claimed first (locked: a
second command on it refuses at once; a file of an output's name that no ftnav
manifest lists is refused, naming it; what a killed command left is rolled back),
the files are written into a hidden staging folder next to the target
(``.<name>.ftnav-partial-*``) and then moved in as a whole, so a refused, crashed or
interrupted command leaves no folder (nor the parents it would have created) and an
earlier run's results stay complete.  A folder written by ``ftnav run``,
``process`` or ``trajectory`` holds :data:`MANIFEST`, the list of the files ftnav
wrote there; the next run into the same folder replaces those files (and only
those), so no figure or ``estimates.nc`` of an earlier run is left behind.

Signals.  SIGINT (exit 130), SIGTERM and SIGHUP (exit 128 + the signal) unwind the
command: its worker processes are killed and its staging folder removed.  Workers
also end by themselves when ``ftnav`` dies (:func:`ftnav.parallel.end_with_parent`).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from tqdm import tqdm

from ftnav.engine.driver import Diverged
from ftnav.eval import resources
from ftnav.eval.evaluate import evaluate, metrics_to_json
from ftnav.eval.integrity import GRAVE, MethodWatch
from ftnav.eval.montecarlo import ScenarioResult, build_filters, join_results, run_scenario
from ftnav.eval.resources import (
    format_bytes,
    kernels_compiled,
    mark_kernels_compiled,
    trajectory_memory_bytes,
)
from ftnav.eval.stopping import check_target, parse_target, run_until
from ftnav.fdi.rbf import KMEANS_SAMPLES
from ftnav.io.common import ScenarioError, read_toml
from ftnav.io.learned import save_neuron_model, save_rbf_model
from ftnav.io.model_file import ModelFileError
from ftnav.io.output_folder import MANIFEST, Output, OutputRefused
from ftnav.io.profile_file import resolve_profile
from ftnav.io.recording_file import recording_json_schema
from ftnav.io.results import write_estimates, write_metrics
from ftnav.io.scenario_file import load_scenario, scenario_json_schema
from ftnav.io.shards import (
    SHARD,
    ShardHeader,
    check_shards,
    read_shard,
    scenario_digest,
    write_shard,
)
from ftnav.io.solution_file import (
    write_solution_csv,
    write_trace_netcdf,
    write_track_geojson,
    write_track_kml,
)
from ftnav.io.trajectory_files import write_imu_csv, write_truth_csv
from ftnav.model.imu import imu_preset
from ftnav.parallel import ClusterError, check_scheduler_address, default_workers
from ftnav.pipeline import Outages, prepare_recording, resolve_recording
from ftnav.recordings import recording_names
from ftnav.report.claims import check_claims
from ftnav.report.recorded import recording_metrics, recording_report, recording_table
from ftnav.report.summary import detector_table, markdown_report, results_table
from ftnav.scenarios import builtin_names, builtin_path
from ftnav.sim.fault_family import fault_variants
from ftnav.sim.imu import simulate_imu_errors
from ftnav.sim.trajectory import Unflyable, generate
from ftnav.training.detector import (
    DetectorTraining,
    default_method,
    held_out_table,
    train_detector,
)
from ftnav.training.fusion import FusionTraining, check_training, fusion_table, train_fusion
from ftnav.training.ins_fusion import check_ins_training, ins_configurations, train_ins_fusion
from ftnav.version import __version__

__all__ = ["MANIFEST", "main"]

#: Said on standard error before a run that compiles the numba kernels, with the
#: seconds it took on the 2-core reference machine per kind of run (cold cache).
COMPILING = "ftnav: compiling the numerical kernels on first use (about {} s, once)"
_COMPILE_S = {
    "linear": 15,
    "integrated": 40,
    "trajectory": 5,
    "train-linear": 20,
    "train-integrated": 40,
}


class UsageError(Exception):
    """Bad command-line input; reported on one line with exit status 2."""


class _Exit(Exception):
    """argparse has finished (``--help``, ``--version``): exit with ``status``."""

    def __init__(self, status: int) -> None:
        super().__init__(status)
        self.status = status


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split())


def _argparse_message(message: str) -> str:
    """argparse's message as ``<field>: <reason>`` (it prefixes ``argument <name>: ``)."""
    text = " ".join(message.split())
    named = re.fullmatch(r"argument (\S+?)(?:/\S+)?: (.*)", text)
    if named:
        return f"{named[1]}: {named[2]}"
    missing = re.fullmatch(r"the following arguments are required: (.*)", text)
    if missing:
        return f"{missing[1]}: required"
    return text


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, status 2, no usage dump
        raise UsageError(_argparse_message(message))

    def exit(self, status=0, message=None):  # --help, --version: main() returns the status
        if message:
            sys.stderr.write(message)
        raise _Exit(status)


def _out_path(text: str) -> Path:
    """``--out``: a non-empty path (``Path("")`` would silently be the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must be a path, got an empty string")
    if "\0" in text:
        raise argparse.ArgumentTypeError("must not contain a NUL character")
    return Path(text)


class _Once(argparse.Action):
    """An option given at most once (a second ``--until`` dropped the first in silence:
    the rule stops on one target)."""

    def __call__(self, parser, namespace, values, option_string=None):  # type: ignore[no-untyped-def]
        if getattr(namespace, self.dest, None) is not None:
            raise argparse.ArgumentError(self, "given twice: the rule stops on one target")
        setattr(namespace, self.dest, values)


def _out_file(text: str) -> Path:
    """``--out`` of a command that writes one file: a path that does not end in a folder
    separator (``newdir/`` wrote a file named ``newdir``)."""
    path = _out_path(text)
    if text.endswith(("/", os.sep)):
        raise argparse.ArgumentTypeError(f"{text!r} names a folder; give a file name")
    return path


def _name_list(text: str | None, option: str) -> list[str] | None:
    """A comma-separated ``--methods``/``--aids`` list with no empty name (a name given
    twice is :func:`ftnav.pipeline.prepare_recording`'s to refuse)."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",")]
    if not text.strip() or "" in names:
        raise UsageError(f"{option}: expected comma-separated names, got {text!r}")
    return names


def _at_least(low: int):
    """argparse type: an integer >= ``low`` (argparse names the option in the message)."""

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value

    return parse


_positive = _at_least(1)
_seed = _at_least(0)


class _Runs(NamedTuple):
    """``--runs`` of ``ftnav run``: runs ``first .. first + count - 1``; ``shard``: given as
    A:B (a shard of a campaign, written with shard.npz for ``ftnav merge``)."""

    first: int
    count: int
    shard: bool = False


def _run_range(text: str) -> _Runs:
    """``--runs``: N (runs 0..N-1) or a shard A:B (runs A..B-1, ``ftnav merge``)."""
    if ":" not in text:
        return _Runs(0, _positive(text))
    a, _, b = text.partition(":")
    first, end = _seed(a), _positive(b)
    if end <= first:
        raise argparse.ArgumentTypeError(f"shard {text!r}: B must be greater than A")
    return _Runs(first, end - first, True)


def _scheduler(text: str) -> str:
    """``--scheduler``: a Dask scheduler's address, its form checked before anything runs."""
    try:
        check_scheduler_address(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--scheduler: ")) from None
    return text


def _seconds(strict: bool):
    """argparse type: a finite number of seconds, > 0 (``strict``) or >= 0."""

    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
        if not math.isfinite(value) or value < 0 or (strict and value == 0):
            raise argparse.ArgumentTypeError(f"must be {'>' if strict else '>='} 0, got {text}")
        return value

    return parse


def _bad_input(e: Exception) -> str:
    """The one line of a bad input: a scenario file's field named with the file and its
    line where it can be told (``file.toml:43: faults[0].end: ...``)."""
    line = _one_line(e)
    if isinstance(e, ScenarioError) and e.where is not None and not line.startswith(e.origin):
        return f"{e.where}: {line}"
    return line


@contextmanager
def _checking() -> Iterator[None]:
    """The validation phase: a ValueError raised here is the input's fault (exit 2).

    Outside it, a ValueError is a bug like any other exception (exit 1); only
    :class:`UsageError`, ``ScenarioError`` and ``ModelFileError`` are bad input anywhere.
    """
    try:
        yield
    except (UsageError, KeyboardInterrupt):
        raise
    except ValueError as e:
        if isinstance(e, ScenarioError | ModelFileError):
            raise
        raise UsageError(_one_line(e)) from e


def _parser() -> _Parser:

    debug = argparse.ArgumentParser(add_help=False)
    debug.add_argument(
        "--debug",
        action="store_true",
        default=argparse.SUPPRESS,
        help="show the full traceback of an error",
    )
    p = _Parser(
        prog="ftnav",
        description="Fault-tolerant multi-sensor navigation fusion.",
        epilog="exit status: 0 done, 2 bad input (one line naming the field), "
        "3 a method diverged (nothing written), 4 the Dask cluster failed (no scheduler at "
        "--scheduler, or lost mid-run: nothing written), 130 interrupted, 143 terminated, "
        "1 internal error (a bug: please report it)",
    )
    p.add_argument("--version", action="version", version=f"ftnav {__version__}")
    p.add_argument("--debug", action="store_true", help="show the full traceback of an error")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    def command(name, **kw):
        return sub.add_parser(name, parents=[debug], **kw)

    r = command("run", help="run a scenario's methods over Monte Carlo runs")
    r.add_argument("scenario", help="built-in scenario name (see `ftnav list`) or a TOML path")
    r.add_argument(
        "--runs",
        type=_run_range,
        default=_Runs(0, 100),
        metavar="N|A:B",
        help="Monte Carlo runs (default 100); A:B runs A..B-1 only and writes shard.npz "
        "for 'ftnav merge' (a job array's shard)",
    )
    r.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    r.add_argument(
        "--out",
        type=_out_path,
        default=None,
        help="output folder (default results/<scenario name>)",
    )
    r.add_argument(
        "--save-estimates",
        action="store_true",
        help="also write estimates.nc (NetCDF) with every estimate",
    )
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument(
        "--workers",
        type=_positive,
        default=None,
        help="worker processes (default: FTNAV_WORKERS, else the CPUs available); "
        "the results do not depend on it",
    )
    r.add_argument(
        "--until",
        action=_Once,
        default=None,
        metavar="METHOD.METRIC:rel=F",
        help="add runs (from --runs) until the metric's 95 %% interval has this half-width, "
        "e.g. ckf.rmse.s:rel=0.02 or fkf-chi2.detection.gnss.rate:abs=0.01 (docs/campaigns.md)",
    )
    r.add_argument(
        "--max-runs", type=_positive, default=None, help="with --until: at most this many runs"
    )
    r.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        metavar="tcp://HOST:PORT",
        help="run the batches on this Dask scheduler's workers (pip install 'ftnav[cluster]'; "
        "docs/campaigns.md); the results do not depend on it",
    )
    g = command("merge", help="merge the shards of 'ftnav run --runs A:B' into one campaign")
    g.add_argument("shards", nargs="+", type=_out_path, help="output folders of the shards")
    g.add_argument("--out", type=_out_path, required=True, help="output folder of the campaign")
    g.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    g.add_argument(
        "--save-estimates",
        action="store_true",
        help="also write estimates.nc (NetCDF) with every estimate",
    )
    w = command("sweep", help="a Monte Carlo campaign at every point of a grid of settings")
    w.add_argument("scenario", help="built-in scenario name or a TOML path")
    w.add_argument(
        "--set",
        dest="sets",
        action="append",
        required=True,
        metavar="KEY=V1,V2,...",
        help="a dotted key of the scenario file and its values (KEY*=F1,F2 scales it); "
        "repeat for a cartesian grid, e.g. faults.0.magnitude=10,20,40",
    )
    w.add_argument("--runs", type=_positive, default=20, help="runs per point (default 20)")
    w.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    w.add_argument(
        "--out", type=_out_path, default=None, help="output folder (default results/<name>-sweep)"
    )
    w.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    w.add_argument("--quiet", action="store_true", help="no progress bar")
    w.add_argument("--workers", type=_positive, default=None, help="worker processes (as for run)")
    w.add_argument(
        "--scheduler",
        type=_scheduler,
        default=None,
        metavar="tcp://HOST:PORT",
        help="a Dask scheduler (as for run)",
    )
    t = command("trajectory", help="generate a flight's truth and IMU increments")
    t.add_argument("profile", help="built-in profile (seed001, seed002) or a profile TOML path")
    t.add_argument("--out", type=_out_path, required=True, help="output folder")
    t.add_argument(
        "--imu", default=None, help="IMU error preset (ideal increments if omitted), e.g. seed001"
    )
    t.add_argument(
        "--seed", type=_seed, default=None, help="random seed of the IMU errors (with --imu; 1)"
    )
    t.add_argument("--no-figure", action="store_true", help="skip trajectory.png")
    d = command(
        "train-detector", help="train the RBF fault detector (paper 000) on a scenario's system"
    )
    d.add_argument("scenario", help="built-in scenario name or a TOML path")
    d.add_argument("--out", type=_out_file, required=True, help="model file to write (.npz)")
    d.add_argument(
        "--runs", type=_positive, default=8, help="training runs per typical fault (default 8)"
    )
    d.add_argument(
        "--holdout", type=_positive, default=4, help="held-out runs per typical fault (default 4)"
    )
    d.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    d.add_argument(
        "--method",
        default=None,
        help="scenario method whose filters produce the features (default: the "
        "first with detector 'rbf', else federated inverse-trace)",
    )
    d.add_argument("--centres", type=_at_least(2), default=60, help="hidden RBF units (default 60)")
    d.add_argument("--no-figure", action="store_true", help="skip the ROC/confusion figure")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    f = command(
        "train-fusion", help="train the neuron fusion centre (paper 001) on a scenario's system"
    )
    f.add_argument("scenario", help="built-in scenario name or a TOML path")
    f.add_argument("--out", type=_out_file, required=True, help="model file to write (.npz)")
    f.add_argument(
        "--runs", type=_positive, default=4, help="training runs per typical fault (default 4)"
    )
    f.add_argument(
        "--holdout", type=_positive, default=2, help="held-out runs per typical fault (default 2)"
    )
    f.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    f.add_argument(
        "--projection",
        choices=("simplex", "seed"),
        default="simplex",
        help="weight constraint: exact simplex projection or the paper's "
        "clip-and-renormalize (default simplex)",
    )
    f.add_argument(
        "--free-input",
        action="store_true",
        help="add the free propagation (no measurements) as an input",
    )
    f.add_argument(
        "--method",
        default=None,
        help="integrated scenarios: the neural method trained for (its correction; "
        "default: the first neural method)",
    )
    f.add_argument("--no-figure", action="store_true", help="skip the RMSE/weights figure")
    f.add_argument("--quiet", action="store_true", help="no progress bar")
    r = command("process", help="process a recorded sensor log through its methods")
    r.add_argument(
        "recording",
        help=f"a built-in recording ({', '.join(recording_names())}) or a recording file",
    )
    r.add_argument(
        "--out", type=_out_path, default=None, help="output folder (default results/NAME)"
    )
    r.add_argument("--methods", default=None, help="comma-separated method names (default all)")
    r.add_argument("--aids", default=None, help="comma-separated aid names (default all)")
    r.add_argument(
        "--outage-length", type=_seconds(True), default=None, help="GNSS outage length, s"
    )
    r.add_argument(
        "--outage-every", type=_seconds(True), default=None, help="outage spacing, s (60)"
    )
    r.add_argument(
        "--outage-start",
        type=_seconds(False),
        default=None,
        help="first outage, s after the first GNSS epoch (40)",
    )
    r.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="SENSOR:KIND:START:END[:MAGNITUDE]",
        help="inject a fault into a recorded aid (repeatable); START, END on the recording's "
        "time base; a bias or ramp MAGNITUDE in metres on the north position (m/s on the "
        "north velocity of an aid that measures velocity only); a noise-scale "
        "MAGNITUDE the factor (>= 1) on the aid's noise σ; stuck and outage take none; "
        "or sins:gyro-bias:START:END:X,Y,Z, "
        "a gyro bias step in deg/h about the body axes (x right, y forward, z up)",
    )
    r.add_argument(
        "--smooth",
        action="store_true",
        help="also write the forward-backward (RTS) smoothed solution (smoothed*.csv)",
    )
    r.add_argument("--quiet", action="store_true", help="no progress bar (shown after 2 s)")
    r.add_argument(
        "--no-figures",
        action="store_true",
        help="skip the figures (track.png, errors.png, innovations.png)",
    )
    command("list", help="list built-in scenarios and their methods")
    s = command("schema", help="print the JSON schema of scenario files (linear and integrated)")
    s.add_argument("--out", type=_out_file, default=None, help="write to a file instead")
    s.add_argument("--recording", action="store_true", help="the schema of recording files instead")
    return p


def _resolve(spec: str, models: bool = True):
    """The built-in scenario or scenario file ``spec``; ``models=False`` for training."""
    return load_scenario(_scenario_path(spec), models)


def _scenario_path(spec: str) -> Path:
    """The file of the built-in scenario or scenario file ``spec``."""
    if not spec.strip():  # Path("") is the current folder: '.: is a folder' named nothing
        raise UsageError("scenario: an empty name; give a built-in scenario or a file")
    if spec in builtin_names():
        return builtin_path(spec)
    path = Path(spec)
    if spec in recording_names() or _is_recording(path):
        raise UsageError(
            f"scenario: {spec!r} is a recording: run it with 'ftnav process'; this command "
            "takes a simulated scenario (no ftnav command trains a model on a recording yet: "
            "docs/recording-format.md, learned models on recordings)"
        )
    if path.suffix == ".toml" or path.exists():
        return path
    raise UsageError(
        f"scenario: {spec!r} is neither a built-in scenario "
        f"({', '.join(builtin_names())}) nor a TOML file"
    )


def _is_recording(path: Path) -> bool:
    """Whether ``path`` is a readable TOML file with ``kind = "recording"``."""
    try:
        return read_toml(path).get("kind") == "recording"
    except ValueError:  # unreadable, special or not TOML: the loader says why
        return False


def _integrated(sc) -> bool:
    return getattr(sc, "kind", "linear") == "integrated"


# ------------------------------------------------------------------ checks before a run


def _build_filters(sc) -> None:
    """Build every method's filter once, as the runner will, before anything is simulated
    (the settings and model files were checked when the scenario was loaded)."""
    if not sc.methods:
        raise UsageError("methods: a run needs at least one method")
    build_filters(sc, sc.system(), sc.methods)


def _check_memory(sc, runs: int, **options) -> None:
    """Refuse a run whose estimated peak memory exceeds what the machine has available
    (:func:`ftnav.eval.resources.check_memory`, the runs named as the option)."""
    try:
        resources.check_memory(sc, runs, **options)
    except ValueError as e:
        raise UsageError(str(e).replace("runs: ", "--runs: ", 1)) from None


def _check_training_memory(sc, runs: int, per_run: int, held_out: int = 0) -> None:
    """Refuse a training whose batch (``runs`` and ``held_out`` runs, each ``per_run``
    simulated at once: the fault variants or configurations) needs more memory than the
    machine has available (``--runs 1e12`` ended in an internal MemoryError)."""
    available = resources.available_memory_bytes()
    if available is None:
        return
    need = resources.run_memory_bytes(sc, (runs + held_out) * per_run)
    if need <= available:
        return
    fit = max(resources.max_runs_within(sc, available) // max(per_run, 1) - held_out, 0)
    extra = f" and {held_out} held out" if held_out else ""
    raise UsageError(
        f"--runs: {runs} training runs{extra} of {sc.name} ({per_run} simulated at once "
        f"each) need about {resources.format_bytes(need)}, more than the "
        f"{resources.format_bytes(available)} available (at most {fit} would fit)"
    )


def _compile_note(kind: str, quiet: bool) -> None:
    if not quiet and not kernels_compiled(kind):
        print(COMPILING.format(_COMPILE_S[kind]), file=sys.stderr, flush=True)


# ------------------------------------------------------------------------ output files


#: targets claimed by the command now running; released when it ends
_claimed: list[Output] = []


def _claim(out: Path, *, folder: bool, names: Iterable[str] = ()) -> Output:
    """Check, lock and recover ``--out`` before anything is computed
    (:mod:`ftnav.io.output_folder`); ``names``: files the command will write."""
    output = Output(out, folder=folder)
    output.claim(names)
    _claimed.append(output)
    return output


# ------------------------------------------------------------------------------ commands


def _cmd_list(args) -> int:
    for name in builtin_names():
        sc = load_scenario(builtin_path(name))
        print(f"{name}: {sc.description}")
        print(
            f"  {sc.steps} epochs x {sc.dt} s, states {', '.join(sc.metric_states)}; sensors "
            f"{', '.join(sc.sensor_names)}; {len(sc.faults)} fault(s)"
        )
        for m in sc.methods:
            detail = m.architecture
            if m.architecture == "federated":
                detail += f" {m.mode}/{m.reset_interval} {m.sharing}"
            if m.detector.kind != "none":
                detail += f", detector {m.detector.kind}"
            if m.noise.kind != "none":
                detail += f", noise {m.noise.kind}"
            print(f"    {m.name:28s} {detail}")
    print("architectures: centralized | federated | distributed | neural")
    print(
        "sharing rules: equal | fixed | information | trace | eigen-trace | frobenius | "
        "inverse-trace"
    )
    print(
        "detectors: none | oracle | residual-chi2 | state-chi2 | cusum | glr | separation | rbf"
        " (which an architecture offers: docs/scenario-format.md)"
    )
    return 0


def _cmd_schema(args) -> int:
    output = _claim(args.out, folder=False, names=[args.out.name]) if args.out else None
    schema = recording_json_schema() if args.recording else scenario_json_schema()
    text = json.dumps(schema, indent=2)
    if args.out is None:
        print(text)
        return 0
    assert output is not None
    with output.staged() as stage:
        (stage / args.out.name).write_text(text + "\n", encoding="utf-8")
    return 0


def _cmd_sweep(args) -> int:
    from ftnav.report.sweep import sweep_report, sweep_table
    from ftnav.sweep import grid, parse_set, run_sweep, sweep_dataset, sweep_work

    with _checking():
        source = _scenario_path(args.scenario)
        axes = [parse_set(s) for s in args.sets]
        keys = [a.key for a in axes]
        if len(set(keys)) != len(keys):
            raise UsageError(f"--set: a key is swept twice ({', '.join(keys)})")
        for a in keys:  # a key and a part of it: the later setting overwrites the other
            for b in keys:
                if b.startswith(a + "."):
                    raise UsageError(
                        f"--set: {b} is a part of {a}, swept too: one would overwrite the "
                        "other at every point"
                    )
        points = grid(source, axes)
        sc = points[0][1]
        out = args.out if args.out is not None else Path("results") / f"{sc.name}-sweep"
        output = _claim(out, folder=True, names=["sweep.nc", "report.md", "report.html"])
        workers = default_workers() if args.workers is None else args.workers
        _check_memory(sc, args.runs, workers=workers)
        for _, point in points:
            _build_filters(point)
    kind = "integrated" if _integrated(sc) else "linear"
    _compile_note(kind, args.quiet)
    total = sweep_work(points, axes)
    t0 = time.perf_counter()
    with tqdm(
        total=total,
        disable=True if args.quiet else None,
        unit="epoch",
        desc=f"{sc.name} sweep of {len(points)} points x{args.runs}",
        file=sys.stderr,
        mininterval=0.5,
    ) as bar:
        sweep = run_sweep(points, axes, args.runs, args.seed, workers, bar.update, args.scheduler)
    elapsed = time.perf_counter() - t0
    mark_kernels_compiled(kind)
    ds = sweep_dataset(sweep)
    command = "ftnav sweep " + " ".join(
        [args.scenario, *(f"--set {s}" for s in args.sets), f"--runs {args.runs}"]
    )
    with output.staged() as stage:
        ds.to_netcdf(stage / "sweep.nc", engine="scipy")
        figures = []
        if not args.no_figures:
            from ftnav.plot.sweep import save_sweep_figures

            figures = [p.name for p in save_sweep_figures(ds, stage)]
        (stage / "report.md").write_text(sweep_report(ds, command, figures), encoding="utf-8")
        written = ["sweep.nc", "report.md", *figures]
        title = f"ftnav sweep: {sc.name}"
        table = ("sweep.nc", ds.to_dataframe().dropna(how="all").to_csv())
        sources = [("Scenario swept", source)]
        written.append(_write_html(stage, args, title, sources, args.seed, table))
    print(f"{sc.name}: {len(points)} points x {args.runs} runs, seed {args.seed}, {elapsed:.1f} s")
    print(sweep_table(ds))
    print(f"Results written to {out}/: {', '.join(written)}")
    return 0


def _cmd_run(args) -> int:
    first_run, n_runs, shard = args.runs
    with _checking():
        sc = _resolve(args.scenario)
        out = args.out if args.out is not None else Path("results") / sc.name
        names = ["metrics.json", "report.md", "report.html"] + ([SHARD] if shard else [])
        output = _claim(out, folder=True, names=names)
        workers = default_workers() if args.workers is None else args.workers
        target = None
        if args.until is not None:
            if shard:
                raise UsageError("--until: a shard (--runs A:B) has a fixed set of runs")
            target = parse_target(args.until, [m.name for m in sc.methods])
            check_target(target, sc)
        elif args.max_runs is not None:
            raise UsageError("--max-runs: it bounds --until, which is not given")
        max_runs = args.max_runs or 10 * n_runs
        if max_runs < n_runs:
            raise UsageError(f"--max-runs: {max_runs} is fewer than --runs {n_runs}")
        most = n_runs if target is None else max_runs
        _check_memory(sc, most, save_estimates=args.save_estimates, workers=workers)
        _build_filters(sc)
        header = None
        if shard:
            path = _scenario_path(args.scenario)
            header = ShardHeader(
                sc.name,
                str(path.resolve()),
                scenario_digest(path),
                args.seed,
                first_run,
                n_runs,
                tuple(m.name for m in sc.methods),
            )
    integrated = _integrated(sc)
    kind = "integrated" if integrated else "linear"
    _compile_note(kind, args.quiet)
    # one unit per method and epoch (the fault-free twin runs in the same batch)
    total = len(sc.methods) * sc.steps
    t0 = time.perf_counter()
    runs_text = f"{first_run}:{first_run + n_runs}" if shard else str(n_runs)
    with tqdm(
        total=None if target is not None else total,
        disable=True if args.quiet else None,
        unit="epoch",
        desc=f"{sc.name} x{runs_text}" + (f" until {target.text}" if target else ""),
        file=sys.stderr,
        mininterval=0.5,
    ) as bar:
        if target is None:
            result = run_scenario(
                sc,
                n_runs,
                args.seed,
                progress=bar.update,
                workers=workers,
                scheduler=args.scheduler,
                first_run=first_run,
            )
        else:
            stopped = run_until(
                sc,
                args.seed,
                target,
                n_runs,
                max_runs,
                workers=workers,
                progress=bar.update,
                scheduler=args.scheduler,
            )
            result = stopped.result
    runs = result.runs
    second = None
    if integrated and sc.test_profile is not None:
        # learned methods are also scored on a flight they were not trained on
        sc2 = _second_scenario(sc)
        with tqdm(
            total=len(sc2.methods) * sc2.steps,
            disable=True if args.quiet else None,
            unit="epoch",
            desc=f"{sc2.name} x{runs_text}",
            file=sys.stderr,
            mininterval=0.5,
        ) as bar:
            second = run_scenario(
                sc2, runs, args.seed, progress=bar.update, workers=workers, first_run=first_run
            )
    elapsed = time.perf_counter() - t0
    mark_kernels_compiled(kind)
    extra: dict[str, Any] = {}
    stop_line = None
    if target is not None:
        i = stopped.interval
        extra["stopping"] = {
            "until": target.text,
            "max_runs": max_runs,
            "runs": runs,
            "parts": stopped.parts,
            "reached": stopped.reached,
            "value": i.value,
            "lo": i.lo,
            "hi": i.hi,
            "half_width": i.half_width,
            "target_half_width": target.half_width(i),
        }
        stop_line = (
            f"--until {target.text}: "
            + ("reached" if stopped.reached else f"NOT reached within --max-runs {max_runs}")
            + f" after {runs} runs in {stopped.parts} part(s): {i.value:.4g} "
            f"[{i.lo:.4g}, {i.hi:.4g}], half-width {i.half_width:.3g} "
            f"(target {target.half_width(i):.3g})"
        )
    if shard:
        extra["shard"] = {"first_run": first_run, "runs": n_runs}
    source = _scenario_path(args.scenario)
    return _write_run(
        args, out, output, result, second, elapsed, extra, stop_line, header, first_run, source
    )


def _second_scenario(sc):
    """The scenario on its test flight (learned methods scored off their training flight)."""
    return replace(
        sc, name=f"{sc.name}@{sc.test_profile.name}", profile=sc.test_profile, test_profile=None
    )


def _write_run(
    args,
    out: Path,
    output: Output,
    result,
    second_result,
    elapsed: float | None,
    extra: dict[str, Any],
    stop_line: str | None,
    header: ShardHeader | None,
    first_run: int,
    source: Path,
) -> int:
    """Score a campaign and write its folder (``run`` and ``merge``): metrics.json,
    report.md, the figures, estimates.nc and a shard's shard.npz; print its tables."""
    sc, runs = result.scenario, result.runs
    integrated = _integrated(sc)
    metrics = evaluate(result)
    second = None if second_result is None else (second_result, evaluate(second_result))
    claims = check_claims(result, metrics, second)
    with output.staged() as stage:
        figures = []
        if not args.no_figures:
            if integrated:
                from ftnav.plot.integrated import save_integrated

                figures = [p.name for p in save_integrated(result, stage, second_result)]
            else:
                from ftnav.plot.figures import save_all

                figures = [p.name for p in save_all(result, stage)]
        doc = metrics_to_json(result, metrics, claims)
        if first_run:
            doc["first_run"] = first_run
        if second is not None:
            doc["second_trajectory"] = metrics_to_json(*second)
        doc.update(extra)
        write_metrics(doc, stage / "metrics.json")
        md = markdown_report(result, metrics, claims, figures)
        if stop_line is not None:  # the stopping rule's verdict under the title
            head, _, rest = md.partition("\n\n")
            md = f"{head}\n\n{stop_line}\n\n{rest}"
        (stage / "report.md").write_text(md, encoding="utf-8")
        written = ["metrics.json", "report.md", *figures]
        if header is not None:
            write_shard(stage / SHARD, header, result, second_result)
            written.append(SHARD)
        title = f"ftnav run: {sc.name}"
        written.append(_write_html(stage, args, title, [("Scenario as run", source)], result.seed))
        if args.save_estimates:
            written += [p.name for p in write_estimates(result, stage)]
    first = f"runs {first_run}:{first_run + runs}" if first_run else f"{runs} runs"
    took = (
        f"{elapsed:.1f} s" if elapsed is not None else f"merged from {len(extra['merged'])} shards"
    )
    print(f"{sc.name}: {first}, seed {result.seed}, {len(sc.methods)} methods, {took}")
    if stop_line is not None:
        print(stop_line)
    print(results_table(result, metrics))
    if second is not None:
        print(f"\nSame methods on a flight not used for training ({second[0].scenario.name}):")
        print(results_table(*second))
    detectors = detector_table(result, metrics)
    if detectors:
        print("\nDetectors side by side (learned and statistical):")
        print(detectors)
    for c in claims:
        if c.get("checked", True):
            verdict = {True: "holds", False: "DOES NOT HOLD", None: "undecided"}[c["holds"]]
            note = f" ({c['note']})" if c["holds"] is None and c.get("intervals") else ""
            print(f"[{verdict}] {c['source']}: {c['claim']}{note}")
        else:
            print(f"[not checked] {c['source']}: {c['claim']} ({c['note']})")
    print(f"Results written to {out}/: {', '.join(written)}")
    if stop_line is not None and not extra["stopping"]["reached"]:
        print(f"ftnav: warning: {stop_line}", file=sys.stderr)
    _integrity_warnings(m.integrity for m in metrics.values())
    return 0


def _write_html(
    stage: Path,
    args,
    title: str,
    sources: list[tuple[str, Path]],
    seed: int | None,
    data: tuple[str, str] | None = None,
) -> str:
    """``report.html`` beside ``report.md`` in ``stage`` (:mod:`ftnav.report.html`): the
    report with its figures embedded, the files as run, metrics.json, version and
    command."""
    from ftnav.report.html import html_report

    md = (stage / "report.md").read_text(encoding="utf-8")
    texts = []
    for heading, path in sources:
        try:
            texts.append((f"{heading}: {path.name}", path.read_text(encoding="utf-8")))
        except (OSError, UnicodeDecodeError) as e:
            texts.append((f"{heading}: {path.name}", f"(not readable now: {e})"))
    metrics = stage / "metrics.json"
    if data is None and metrics.exists():
        data = ("metrics.json", metrics.read_text(encoding="utf-8"))
    command = "ftnav " + " ".join(getattr(args, "argv", []))
    footer = f"ftnav {__version__}" + ("" if seed is None else f" · root seed {seed}")
    page = html_report(
        md,
        stage,
        title=title,
        sources=texts,
        data=data,
        footer=f"{footer} · `{command}`",
    )
    (stage / "report.html").write_text(page, encoding="utf-8")
    return "report.html"


def _cmd_merge(args) -> int:
    with _checking():
        out = args.out.resolve()
        for folder in args.shards:  # the merged result would replace that shard's files
            if (folder if folder.is_dir() else folder.parent).resolve() == out:
                raise UsageError(
                    f"--out: {args.out} is the folder of the shard {folder}: the merge would "
                    "replace it (its runs could not be merged again); choose another folder"
                )
        output = _claim(args.out, folder=True, names=["metrics.json", "report.md", "report.html"])
        loaded = []
        for folder in args.shards:
            path = folder / SHARD if folder.is_dir() else folder
            if not path.exists():
                raise UsageError(f"shards: {folder}: no {SHARD} (run with --runs A:B)")
            try:
                loaded.append((str(folder), *read_shard(path)))
            except ValueError as e:
                raise UsageError(f"shards: {e}") from None
        try:
            order = check_shards([(w, h) for w, h, _ in loaded])
        except ValueError as e:
            raise UsageError(f"shards: {e}") from None
        where, h0, _ = loaded[order[0]]
        path = Path(h0.scenario_path)
        if not path.exists() or scenario_digest(path) != h0.scenario_sha256:
            state = "changed since" if path.exists() else "gone since"
            raise UsageError(f"shards: the scenario file {path} has {state} {where} was run")
        sc = _resolve(str(path))
    sc2 = _second_scenario(sc) if _integrated(sc) and sc.test_profile is not None else None

    def joined(scenario, which: int):
        parts = [
            ScenarioResult(
                scenario, loaded[i][1].runs, h0.seed, loaded[i][2][which], loaded[i][2][which + 1]
            )
            for i in order
        ]
        return join_results(parts)

    result = joined(sc, 0)
    second = joined(sc2, 2) if sc2 is not None and len(loaded[order[0]][2]) == 4 else None
    first = h0.first_run
    extra = {
        "merged": [
            {"shard": loaded[i][0], "first_run": loaded[i][1].first_run, "runs": loaded[i][1].runs}
            for i in order
        ]
    }
    return _write_run(args, args.out, output, result, second, None, extra, None, None, first, path)


#: integrity findings printed in all; past it, per method, before the rest is left to
#: metrics.json
MAX_FINDINGS, MAX_FINDINGS_EACH = 12, 2


def _integrity_warnings(watches: Iterable[MethodWatch | None]) -> None:
    """Every method's integrity findings (what it watched of itself) as warning lines,
    each method's grave ones (a lock-out, a σ past its bound) first: all of them up to
    ``MAX_FINDINGS``, else ``MAX_FINDINGS_EACH`` per method and the count of the rest,
    which ``metrics.json`` holds.  (The first twelve of all methods were printed: a
    method 30 times worse than the plain filter, listed last, had none printed.)"""
    each = [
        sorted(w.findings, key=lambda f: not any(g in f for g in GRAVE))
        for w in watches
        if w is not None
    ]
    cap = MAX_FINDINGS if sum(map(len, each)) <= MAX_FINDINGS else MAX_FINDINGS_EACH
    rest = 0
    for lines in each:
        for line in lines[:cap]:
            print(f"ftnav: warning: {_one_line(line)}", file=sys.stderr)
        rest += max(0, len(lines) - cap)
    if rest:
        print(
            f"ftnav: warning: {rest} more integrity finding(s) in metrics.json "
            "(methods.<name>.integrity.findings)",
            file=sys.stderr,
        )


def _cmd_process(args) -> int:
    with _checking():
        outages = None
        if args.outage_length is not None:
            given = {"every": args.outage_every, "start": args.outage_start}
            outages = Outages(
                args.outage_length, **{k: v for k, v in given.items() if v is not None}
            )
        else:
            for option in ("every", "start"):
                if getattr(args, f"outage_{option}") is not None:
                    raise UsageError(
                        f"--outage-{option}: given without --outage-length (no outage would "
                        "be made)"
                    )
        prepared = prepare_recording(
            args.recording,
            methods=_name_list(args.methods, "--methods"),
            aids=_name_list(args.aids, "--aids"),
            outages=outages,
            faults=list(args.fault),
            smooth=args.smooth,
            fields={
                "faults": "--fault",
                "outages": "--outage-length",
                "methods": "--methods",
                "aids": "--aids",
            },
        )
        rec = prepared.recording
        out = args.out if args.out is not None else Path("results") / rec.name
        solutions = (
            ["solution.csv"]
            if len(rec.methods) == 1
            else [f"solution-{m.name}.csv" for m in rec.methods]
        )
        if args.smooth:
            solutions += [n.replace("solution", "smoothed", 1) for n in solutions]
        fixed = ["metrics.json", "trace.nc", "track.geojson", "track.kml", "report.md"]
        fixed.append("report.html")
        output = _claim(out, folder=True, names=[*solutions, *fixed])
    loaded = prepared.loaded
    for note in loaded.warnings:  # after every check: a refusal comes alone
        print(f"ftnav: warning: {_one_line(note)}", file=sys.stderr)
    # the engine reports one step per method and epoch, for the whole batch at once
    # (one run per interleaved outage schedule): the bar counts epochs x methods x runs
    runs = loaded.stream.batch
    with _bar(prepared.work, args.quiet, f"process {rec.name}", delay=2.0) as bar:
        result = prepared.run(bar.update)
    with output.staged() as stage:
        tables = {nm: result.solution(nm) for nm in result.traces}
        written = []
        for nm, tab in tables.items():
            name = "solution.csv" if len(tables) == 1 else f"solution-{nm}.csv"
            written.append(write_solution_csv(tab, stage / name).name)
        if result.smoothed is not None:
            for nm in result.smoothed:
                name = "smoothed.csv" if len(tables) == 1 else f"smoothed-{nm}.csv"
                written.append(
                    write_solution_csv(result.solution(nm, smoothed=True), stage / name).name
                )
        written.append(
            write_track_geojson(tables, loaded.reference_p, stage / "track.geojson").name
        )
        kml = write_track_kml(tables, loaded.reference_p, stage / "track.kml", rec.name)
        written.append(kml.name)
        written.append(write_trace_netcdf(loaded, result.traces, stage / "trace.nc").name)
        if not args.no_figures:
            from ftnav.plot.recorded import save_recording_figures

            written += [p.name for p in save_recording_figures(loaded, result.traces, stage)]
        figures = [w for w in written if w.endswith(".png")]
        written += ["metrics.json", "report.md", "report.html"]
        doc = recording_metrics(loaded, result.scores, result.elapsed_s, written)
        write_metrics(doc, stage / "metrics.json")
        findings = [
            line
            for m in result.scores.values()
            for line in (() if m.integrity is None else m.integrity.findings)
        ]
        report = recording_report(loaded, result.scores, figures, findings)
        (stage / "report.md").write_text(report, encoding="utf-8")
        source = resolve_recording(args.recording)
        title = f"ftnav process: {rec.name}"
        _write_html(stage, args, title, [("Recording as run", source)], None)
    print(
        f"{rec.name}: {rec.steps} epochs of {rec.dt:.4g} s from {rec.t_start:.3f} s, "
        f"{len(rec.methods)} methods"
        + (f" x {runs} runs (interleaved outage schedules)" if runs > 1 else "")
        + f", {result.elapsed_s:.1f} s"
    )
    print(recording_table(result.scores))
    print(f"Results written to {out}/: {', '.join(written)}")
    for note in result.warnings[len(loaded.warnings) :]:  # the scores' own
        print(f"ftnav: warning: {_one_line(note)}", file=sys.stderr)
    _integrity_warnings(m.integrity for m in result.scores.values())
    return 0


def _cmd_trajectory(args) -> int:
    with _checking():
        profile = resolve_profile(args.profile)
        errors = None
        if args.imu is not None:
            try:
                errors = imu_preset(args.imu)
            except ValueError as e:  # named as the option the user gave
                raise UsageError(str(e).replace("imu.preset: ", "--imu: ", 1)) from None
        elif args.seed is not None:
            raise UsageError("--seed: given without --imu (the ideal IMU has no errors to draw)")
        out = Path(args.out)
        output = _claim(out, folder=True, names=["truth.csv", "imu.csv"])
        need = trajectory_memory_bytes(profile, errors is not None)
        available = resources.available_memory_bytes()
        if available is not None and need > available:
            raise UsageError(
                f"profile: {profile.duration:g} s at {profile.imu_rate:g} Hz "
                f"needs about {format_bytes(need)}, more than the "
                f"{format_bytes(available)} available"
            )
    _compile_note("trajectory", False)
    traj = generate(profile)
    dtheta, dv = traj.dtheta, traj.dv
    if errors is not None:
        seed = 1 if args.seed is None else args.seed
        dtheta, dv, _ = simulate_imu_errors(dtheta, dv, traj.dt, errors, seed=seed)
    mark_kernels_compiled("trajectory")
    with output.staged() as stage:
        written = [
            write_truth_csv(traj, stage / "truth.csv").name,
            write_imu_csv(traj.t[1:], dtheta, dv, stage / "imu.csv").name,
        ]
        if not args.no_figure:
            from ftnav.plot.navigation import trajectory_figure

            fig = trajectory_figure(traj, title=f"{profile.name}: {profile.duration:g} s")
            fig.savefig(stage / "trajectory.png", dpi=110)
            written.append("trajectory.png")
    imu = f"IMU errors '{args.imu}', seed {seed}" if errors is not None else "ideal IMU"
    print(
        f"{profile.name}: {profile.duration:g} s at {profile.imu_rate:g} Hz, "
        f"{len(profile.segments)} segments, {imu}"
    )
    print(f"Written to {out}/: {', '.join(written)}")
    return 0


def _bar(total: int, quiet: bool, desc: str, delay: float = 0.0):
    """A progress bar on stderr: never with ``quiet``, only on a terminal otherwise, and
    not before ``delay`` seconds (a short run shows none)."""
    return tqdm(
        total=total,
        disable=True if quiet else None,
        delay=delay,
        unit="epoch",
        desc=desc,
        file=sys.stderr,
        mininterval=0.5,
    )


def _cmd_train_detector(args) -> int:
    with _checking():
        sc = _resolve(args.scenario, models=False)
        out = args.out
        output = _claim(out, folder=False, names=[out.name, out.with_suffix(".png").name])
        if _integrated(sc):
            raise UsageError(
                f"scenario: {sc.name} is an integrated scenario; the RBF "
                "detector is trained on linear scenarios"
            )
        method = default_method(sc)
        if args.method is not None:
            named = {m.name: m for m in sc.methods}
            if args.method not in named:
                raise UsageError(
                    f"--method: {args.method!r} is not a method of {sc.name} ({', '.join(named)})"
                )
            method = named[args.method]
        if method.architecture not in ("federated", "distributed"):
            raise UsageError(
                f"methods[{method.name}].architecture: the RBF detector's "
                "features need local filters (federated or distributed)"
            )
        settings = DetectorTraining(
            runs=args.runs, holdout_runs=args.holdout, seed=args.seed, n_centres=args.centres
        )
        n_var = len(fault_variants(sc, settings.family, np.random.default_rng(0)))
        _check_training_memory(sc, args.runs, n_var, args.holdout)
        # every training run, variant and epoch is one sample at most, and k-means reads
        # at most KMEANS_SAMPLES of them: more centres than that ended in an internal
        # error after the training
        samples = min(args.runs * n_var * sc.steps, KMEANS_SAMPLES)
        if args.centres > samples:
            raise UsageError(
                f"--centres: {args.centres} hidden units need at least as many training "
                f"samples; {args.runs} run(s) of {n_var} fault variants over {sc.steps} "
                f"epochs give at most {samples} (k-means reads {KMEANS_SAMPLES} at most)"
            )
    _compile_note("train-linear", args.quiet)
    total = sc.steps * n_var * (args.runs * (1 + settings.closed_loop) + 2 * args.holdout)
    t0 = time.perf_counter()
    with _bar(total, args.quiet, f"train-detector {sc.name}") as bar:
        model, report = train_detector(sc, settings, method, progress=bar.update)
    mark_kernels_compiled("train-linear")
    written = [str(out)]
    with output.staged() as stage:
        save_rbf_model(model, stage / out.name)
        if not args.no_figure:
            from ftnav.plot.learning import detector_figure

            fig = detector_figure(report, f"{sc.name}: RBF detector vs chi-square, held-out runs")
            fig.savefig(stage / out.with_suffix(".png").name, dpi=110)
            written.append(str(out.with_suffix(".png")))
    print(
        f"{sc.name}: RBF detector for method {method.name!r} ({method.architecture}), "
        f"{n_var} fault variants x {args.runs} training runs, {report.train_samples} "
        f"samples, {time.perf_counter() - t0:.1f} s"
    )
    print(f"thresholds per output: {', '.join(f'{t:.3g}' for t in model.threshold)}")
    print(held_out_table(report))
    print(f"Written: {', '.join(written)}")
    return 0


def _cmd_train_fusion(args) -> int:
    with _checking():
        sc = _resolve(args.scenario, models=False)
        out = args.out
        output = _claim(out, folder=False, names=[out.name, out.with_suffix(".png").name])
        if not _integrated(sc):
            settings = FusionTraining(
                runs=args.runs,
                holdout_runs=args.holdout,
                seed=args.seed,
                projection=args.projection,
                free_input=args.free_input,
            )
            n_var = len(fault_variants(sc, settings.family, np.random.default_rng(0)))
            _check_training_memory(sc, args.runs, n_var, args.holdout)
            check_training(sc, settings)
            if args.method is not None:
                raise UsageError(
                    "--method: for an integrated scenario's neural methods; a linear "
                    "scenario's centre is trained on its system alone"
                )
        else:
            check_ins_training(sc)
            _check_training_memory(sc, args.runs, len(ins_configurations(sc)))
    if _integrated(sc):
        return _train_ins_fusion(sc, output, args)
    _compile_note("train-linear", args.quiet)
    total = sc.steps * n_var * (args.runs + 4 * args.holdout)
    t0 = time.perf_counter()
    with _bar(total, args.quiet, f"train-fusion {sc.name}") as bar:
        model, report = train_fusion(sc, settings, progress=bar.update)
    mark_kernels_compiled("train-linear")
    written = [str(out)]
    with output.staged() as stage:
        save_neuron_model(model, stage / out.name)
        if not args.no_figure:
            from ftnav.plot.learning import fusion_figure

            fig = fusion_figure(model, report, f"{sc.name}: neuron fusion centre, held-out runs")
            fig.savefig(stage / out.with_suffix(".png").name, dpi=110)
            written.append(str(out.with_suffix(".png")))
    print(
        f"{sc.name}: neuron fusion centre, configurations {', '.join(model.configurations)}; "
        f"inputs {', '.join(model.inputs)}; {time.perf_counter() - t0:.1f} s"
    )
    print(fusion_table(model, report))
    print(f"Written: {', '.join(written)}")
    return 0


def _train_ins_fusion(sc, output: Output, args) -> int:
    """``train-fusion`` on an integrated scenario (paper 001's five configurations)."""
    out = output.out
    _compile_note("train-integrated", args.quiet)
    t0 = time.perf_counter()
    total = sc.steps * len(ins_configurations(sc))
    neural = [m for m in sc.methods if m.architecture == "neural"]
    if args.method is not None:
        named = {m.name: m for m in neural}
        if args.method not in named:
            raise UsageError(
                f"--method: {args.method!r} is not a neural method of {sc.name} "
                f"({', '.join(named) or 'none'})"
            )
        neural = [named[args.method]]
    correction = (neural[0].correction if neural else None) or sc.correction
    with _bar(total, args.quiet, f"train-fusion {sc.name}") as bar:
        model = train_ins_fusion(
            sc, runs=args.runs, seed=args.seed, progress=bar.update, correction=correction
        )
    mark_kernels_compiled("train-integrated")
    with output.staged() as stage:
        save_neuron_model(model, stage / out.name)
    print(
        f"{sc.name}: neuron fusion centre ({correction} correction), configurations "
        f"{', '.join(model.configurations)}; inputs {', '.join(model.inputs)}; "
        f"{time.perf_counter() - t0:.1f} s"
    )
    print("weights of the position neurons (" + ", ".join(model.inputs) + "):")
    for j, st in ((6, "dL"), (7, "dlambda"), (8, "dh")):
        for c, w in zip(model.configurations, model.weights[:, j], strict=True):
            print(f"  {st:8s} {c:8s} " + " ".join(f"{v:.3f}" for v in w))
    print(f"Written: {out}")
    return 0


_COMMANDS = {
    "process": _cmd_process,
    "list": _cmd_list,
    "schema": _cmd_schema,
    "run": _cmd_run,
    "merge": _cmd_merge,
    "sweep": _cmd_sweep,
    "trajectory": _cmd_trajectory,
    "train-detector": _cmd_train_detector,
    "train-fusion": _cmd_train_fusion,
}


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning (e.g. a scenario's modelling approximation) as one line on stderr."""
    print(f"ftnav: warning: {_one_line(message)}", file=sys.stderr)


class _Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP: unwinds like Ctrl-C (workers ended, staging folder removed)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _terminate(signum: int, frame: object) -> None:
    raise _Terminated(signum)


@contextmanager
def _signals_unwind() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`_Terminated` while the command runs (main
    thread only), so that ``finally`` blocks run: worker processes are ended and a
    half-written output is removed (:mod:`ftnav.io.output_folder`)."""
    import signal

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.signal(s, _terminate) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


class _PipeSafe:
    """``sys.stdout`` that outlives its reader: once the reader has closed the pipe
    (``ftnav list | head -3``) further output is discarded, and the command finishes
    its work (its output folder included) instead of ending in a BrokenPipeError."""

    def __init__(self, inner: Any):
        self._inner = inner
        self.gone = False

    def write(self, text: str) -> int:
        if not self.gone:
            if self._inner is None:  # stdout closed (``ftnav list >&-``): nowhere to write
                self.gone = True
                return len(text)
            try:
                return int(self._inner.write(text))
            except OSError:  # the reader closed the pipe, or /dev/full: the rest discarded
                self._close()
        return len(text)

    def flush(self) -> None:
        if not self.gone and self._inner is not None:
            try:
                self._inner.flush()
            except OSError:
                self._close()

    def _close(self) -> None:
        self.gone = True
        try:  # the interpreter's last flush at exit then writes nowhere, silently
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._inner.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ftnav`` command; returns the exit status (module docstring)."""
    debug = False
    stdout = sys.stdout
    sys.stdout = _PipeSafe(stdout)  # type: ignore[assignment]
    for stream in (stdout, sys.stderr):  # a terminal that cannot show σ or ±: escaped
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="backslashreplace")
    try:
        parser = _parser()
        args = parser.parse_args(argv)
        args.argv = list(sys.argv[1:] if argv is None else argv)
        debug = args.debug
        if args.command is None:
            parser.print_help(sys.stderr)
            return 2
        # floating-point overflow is caught where it matters (a diverged method: exit 3),
        # not as NumPy's RuntimeWarning lines
        with warnings.catch_warnings(), _signals_unwind(), np.errstate(all="ignore"):
            warnings.showwarning = _show_warning
            return _COMMANDS[args.command](args)
    except _Exit as e:
        return e.status
    except (UsageError, ScenarioError, ModelFileError, OutputRefused, Unflyable) as e:
        if debug:
            traceback.print_exception(e)
        print(f"ftnav: error: {_bad_input(e)}", file=sys.stderr)
        return 2
    except Diverged as e:
        if debug:
            traceback.print_exception(e)
        print(f"ftnav: error: {_one_line(e)}; nothing written", file=sys.stderr)
        return 3
    except ClusterError as e:
        if debug:
            traceback.print_exception(e)
        print(f"ftnav: error: {_one_line(e)}", file=sys.stderr)
        return 4
    except _Terminated as e:
        print(f"ftnav: terminated (signal {e.signum})", file=sys.stderr)
        return 128 + e.signum
    except KeyboardInterrupt:
        print("ftnav: interrupted", file=sys.stderr)
        return 130
    except Exception as e:
        if debug:
            traceback.print_exception(e)
        hint = "" if debug else " (run again with --debug for the traceback)"
        print(
            f"ftnav: internal error, please report: {type(e).__name__}: {_one_line(e)}{hint}",
            file=sys.stderr,
        )
        return 1
    finally:
        sys.stdout.flush()
        sys.stdout = stdout
        while _claimed:
            _claimed.pop().release()


if __name__ == "__main__":
    sys.exit(main())
