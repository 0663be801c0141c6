"""Command-line interface: ``ftnav run | list | schema | trajectory | train-*``.

Bad input (a malformed scenario, an unknown built-in, an impossible option)
prints one line ``ftnav: error: <field>: <reason>`` on stderr and exits with
status 2; it never prints a traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

__all__ = ["main"]


class UsageError(Exception):
    """Bad command-line input; reported on one line with exit status 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, status 2, no usage dump
        raise UsageError(message.replace("\n", " "))


def _positive_int(name):
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name}: expected an integer, got {text!r}") \
                from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"{name}: must be >= 1, got {value}")
        return value
    return parse


def _seed(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--seed: expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"--seed: must be >= 0, got {value}")
    return value


def _parser() -> _Parser:
    p = _Parser(prog="ftnav", description="Fault-tolerant multi-sensor navigation fusion.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("run", help="run a scenario's methods over Monte Carlo runs")
    r.add_argument("scenario", help="built-in scenario name (see `ftnav list`) or a TOML path")
    r.add_argument("--runs", type=_positive_int("--runs"), default=100,
                   help="Monte Carlo runs (default 100)")
    r.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    r.add_argument("--out", type=Path, default=None,
                   help="output folder (default results/<scenario name>)")
    r.add_argument("--save-estimates", action="store_true",
                   help="also write estimates.nc (NetCDF) with every estimate")
    r.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    t = sub.add_parser("trajectory", help="generate a flight's truth and IMU increments")
    t.add_argument("profile", help="built-in profile (seed001, seed002) or a profile TOML path")
    t.add_argument("--out", type=Path, required=True, help="output folder")
    t.add_argument("--imu", default=None,
                   help="IMU error preset (ideal increments if omitted), e.g. seed001")
    t.add_argument("--seed", type=_seed, default=1, help="random seed of the IMU errors")
    t.add_argument("--no-figure", action="store_true", help="skip trajectory.png")
    d = sub.add_parser("train-detector",
                       help="train the RBF fault detector (paper 000) on a scenario's system")
    d.add_argument("scenario", help="built-in scenario name or a TOML path")
    d.add_argument("--out", type=Path, required=True, help="model file to write (.npz)")
    d.add_argument("--runs", type=_positive_int("--runs"), default=8,
                   help="training runs per typical fault (default 8)")
    d.add_argument("--holdout", type=_positive_int("--holdout"), default=4,
                   help="held-out runs per typical fault (default 4)")
    d.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    d.add_argument("--method", default=None,
                   help="scenario method whose filters produce the features (default: the "
                        "first with detector 'rbf', else federated inverse-trace)")
    d.add_argument("--centres", type=_positive_int("--centres"), default=60,
                   help="hidden RBF units (default 60)")
    d.add_argument("--no-figure", action="store_true", help="skip the ROC/confusion figure")
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    f = sub.add_parser("train-fusion",
                       help="train the neuron fusion centre (paper 001) on a scenario's system")
    f.add_argument("scenario", help="built-in scenario name or a TOML path")
    f.add_argument("--out", type=Path, required=True, help="model file to write (.npz)")
    f.add_argument("--runs", type=_positive_int("--runs"), default=4,
                   help="training runs per typical fault (default 4)")
    f.add_argument("--holdout", type=_positive_int("--holdout"), default=2,
                   help="held-out runs per typical fault (default 2)")
    f.add_argument("--seed", type=_seed, default=1, help="root random seed (default 1)")
    f.add_argument("--projection", choices=("simplex", "seed"), default="simplex",
                   help="weight constraint: exact simplex projection or the paper's "
                        "clip-and-renormalize (default simplex)")
    f.add_argument("--free-input", action="store_true",
                   help="add the free propagation (no measurements) as an input")
    f.add_argument("--no-figure", action="store_true", help="skip the RMSE/weights figure")
    f.add_argument("--quiet", action="store_true", help="no progress bar")
    sub.add_parser("list", help="list built-in scenarios and their methods")
    s = sub.add_parser("schema", help="print the JSON schema of scenario files")
    s.add_argument("--out", type=Path, default=None, help="write to a file instead")
    return p


def _resolve(spec: str):
    from ftnav.io.scenario_file import load_scenario
    from ftnav.scenarios import builtin_names, builtin_path

    if spec in builtin_names():
        return load_scenario(builtin_path(spec))
    path = Path(spec)
    if path.suffix == ".toml" or path.exists():
        return load_scenario(path)
    raise UsageError(f"scenario: {spec!r} is neither a built-in scenario "
                     f"({', '.join(builtin_names())}) nor a TOML file")


def _cmd_list() -> int:
    from ftnav.io.scenario_file import load_scenario
    from ftnav.scenarios import builtin_names, builtin_path

    for name in builtin_names():
        sc = load_scenario(builtin_path(name))
        print(f"{name}: {sc.description}")
        print(f"  {sc.steps} epochs x {sc.dt} s, states {', '.join(sc.model.states)}; sensors "
              f"{', '.join(sc.sensor_names)}; {len(sc.faults)} fault(s)")
        for m in sc.methods:
            detail = m.architecture
            if m.architecture == "federated":
                detail += f" {m.mode}/{m.reset_interval} {m.sharing}"
            if m.detector != "none":
                detail += f", detector {m.detector}"
            print(f"    {m.name:28s} {detail}")
    print("architectures: centralized | federated | distributed | neural")
    print("sharing rules: equal | fixed | information | trace | eigen-trace | frobenius | "
          "inverse-trace")
    print("detectors: none | residual-chi2 | state-chi2 | oracle | rbf")
    return 0


def _cmd_schema(out: Path | None) -> int:
    from ftnav.io.scenario_file import scenario_json_schema

    text = json.dumps(scenario_json_schema(), indent=2)
    if out is None:
        print(text)
    else:
        Path(out).write_text(text + "\n")
    return 0


def _cmd_run(args) -> int:
    from tqdm import tqdm

    from ftnav.eval.evaluate import evaluate, metrics_to_json
    from ftnav.eval.montecarlo import run_scenario
    from ftnav.io.results import write_estimates, write_metrics
    from ftnav.report.claims import check_claims
    from ftnav.report.summary import detector_table, markdown_report, results_table

    sc = _resolve(args.scenario)
    out = args.out if args.out is not None else Path("results") / sc.name
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out: cannot create {str(out)!r}: {e.strerror}") from None
    passes = 2 if sc.faults else 1
    total = len(sc.methods) * sc.steps * passes
    integrated = getattr(sc, "kind", "linear") == "integrated"
    t0 = time.perf_counter()
    with tqdm(total=total, disable=True if args.quiet else None, unit="epoch",
              desc=f"{sc.name} x{args.runs}", file=sys.stderr, mininterval=0.5) as bar:
        if integrated:
            from ftnav.eval.integrated import run_ins_scenario

            total = len(sc.methods) * sc.steps
            bar.total = total
            ir = run_ins_scenario(sc, args.runs, args.seed, progress=bar.update)
            result = ir.result
        else:
            result = run_scenario(sc, args.runs, args.seed, progress=bar.update)
    second = None
    if integrated and sc.test_profile is not None:
        # learned methods are also scored on a flight they were not trained on
        from dataclasses import replace

        sc2 = replace(sc, name=f"{sc.name}@{sc.test_profile.name}", profile=sc.test_profile,
                      test_profile=None)
        with tqdm(total=len(sc2.methods) * sc2.steps, disable=True if args.quiet else None,
                  unit="epoch", desc=f"{sc2.name} x{args.runs}", file=sys.stderr,
                  mininterval=0.5) as bar:
            ir2 = run_ins_scenario(sc2, args.runs, args.seed, progress=bar.update)
        second = (ir2.result, evaluate(ir2.result))
    elapsed = time.perf_counter() - t0
    metrics = evaluate(result)
    claims = check_claims(result, metrics, ir.local if integrated else None, second)
    figures = []
    if not args.no_figures:
        if integrated:
            from ftnav.plot.integrated import save_integrated

            figures = [p.name for p in save_integrated(ir, out)]
        else:
            from ftnav.plot.figures import save_all

            figures = [p.name for p in save_all(result, out)]
    doc = metrics_to_json(result, metrics, claims)
    if second is not None:
        doc["second_trajectory"] = metrics_to_json(*second)
    write_metrics(doc, out / "metrics.json")
    (out / "report.md").write_text(markdown_report(result, metrics, claims, figures))
    written = ["metrics.json", "report.md", *figures]
    if args.save_estimates:
        written += [p.name for p in write_estimates(result, out)]
    print(f"{sc.name}: {args.runs} runs, seed {args.seed}, {len(sc.methods)} methods, "
          f"{elapsed:.1f} s")
    print(results_table(result, metrics))
    if second is not None:
        print(f"\nSame methods on a flight not used for training ({second[0].scenario.name}):")
        print(results_table(*second))
    detectors = detector_table(result, metrics)
    if detectors:
        print("\nDetectors side by side (learned and statistical):")
        print(detectors)
    for c in claims:
        verdict = {True: "holds", False: "DOES NOT HOLD", None: "undecided"}[c["holds"]]
        print(f"[{verdict}] {c['source']}: {c['claim']}")
    print(f"Results written to {out}/: {', '.join(written)}")
    return 0


def _cmd_trajectory(args) -> int:
    from ftnav.io.profile_file import resolve_profile
    from ftnav.io.trajectory_files import write_imu_csv, write_truth_csv
    from ftnav.sim.trajectory import generate

    profile = resolve_profile(args.profile)
    errors = None
    if args.imu is not None:
        from ftnav.sim.imu import imu_preset

        errors = imu_preset(args.imu)
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out: cannot create {str(out)!r}: {e.strerror}") from None
    traj = generate(profile)
    dtheta, dv = traj.dtheta, traj.dv
    if errors is not None:
        from ftnav.sim.imu import simulate_imu_errors

        dtheta, dv, _ = simulate_imu_errors(dtheta, dv, traj.dt, errors, seed=args.seed)
    written = [write_truth_csv(traj, out / "truth.csv").name,
               write_imu_csv(traj.t[1:], dtheta, dv, out / "imu.csv").name]
    if not args.no_figure:
        from ftnav.plot.navigation import trajectory_figure

        fig = trajectory_figure(traj, title=f"{profile.name}: {profile.duration:g} s")
        fig.savefig(out / "trajectory.png", dpi=110)
        written.append("trajectory.png")
    imu = f"IMU errors '{args.imu}', seed {args.seed}" if errors is not None else "ideal IMU"
    print(f"{profile.name}: {profile.duration:g} s at {profile.imu_rate:g} Hz, "
          f"{len(profile.segments)} segments, {imu}")
    print(f"Written to {out}/: {', '.join(written)}")
    return 0


def _output_file(path: Path) -> Path:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out: cannot create {str(path.parent)!r}: {e.strerror}") from None
    if path.is_dir():
        raise UsageError(f"--out: {str(path)!r} is a folder; give a model file name")
    return path


def _bar(total: int, quiet: bool, desc: str):
    from tqdm import tqdm

    return tqdm(total=total, disable=True if quiet else None, unit="epoch", desc=desc,
                file=sys.stderr, mininterval=0.5)


def _cmd_train_detector(args) -> int:
    from ftnav.fdi.training import DetectorTraining, default_method, held_out_table, train_detector
    from ftnav.sim.fault_family import fault_variants

    if args.centres < 2:
        raise UsageError(f"--centres: must be >= 2, got {args.centres}")
    sc = _resolve(args.scenario)
    out = _output_file(args.out)
    method = default_method(sc)
    if args.method is not None:
        named = {m.name: m for m in sc.methods}
        if args.method not in named:
            raise UsageError(f"--method: {args.method!r} is not a method of {sc.name} "
                             f"({', '.join(named)})")
        method = named[args.method]
    settings = DetectorTraining(runs=args.runs, holdout_runs=args.holdout, seed=args.seed,
                                n_centres=args.centres)
    import numpy as np

    n_var = len(fault_variants(sc, settings.family, np.random.default_rng(0)))
    total = sc.steps * n_var * (args.runs * (1 + settings.closed_loop) + 2 * args.holdout)
    t0 = time.perf_counter()
    with _bar(total, args.quiet, f"train-detector {sc.name}") as bar:
        model, report = train_detector(sc, settings, method, progress=bar.update)
    model.save(out)
    written = [str(out)]
    if not args.no_figure:
        from ftnav.plot.learning import detector_figure

        fig = detector_figure(report, f"{sc.name}: RBF detector vs chi-square, held-out runs")
        fig.savefig(out.with_suffix(".png"), dpi=110)
        written.append(str(out.with_suffix(".png")))
    print(f"{sc.name}: RBF detector for method {method.name!r} ({method.architecture}), "
          f"{n_var} fault variants x {args.runs} training runs, {report.train_samples} "
          f"samples, {time.perf_counter() - t0:.1f} s")
    print(f"thresholds per output: {', '.join(f'{t:.3g}' for t in model.threshold)}")
    print(held_out_table(report))
    print(f"Written: {', '.join(written)}")
    return 0


def _cmd_train_fusion(args) -> int:
    from ftnav.fusion.neural_training import FusionTraining, fusion_table, train_fusion
    from ftnav.sim.fault_family import fault_variants

    sc = _resolve(args.scenario)
    out = _output_file(args.out)
    if getattr(sc, "kind", "linear") == "integrated":
        return _train_ins_fusion(sc, out, args)
    settings = FusionTraining(runs=args.runs, holdout_runs=args.holdout, seed=args.seed,
                              projection=args.projection, free_input=args.free_input)
    import numpy as np

    n_var = len(fault_variants(sc, settings.family, np.random.default_rng(0)))
    total = sc.steps * n_var * (args.runs + 4 * args.holdout)
    t0 = time.perf_counter()
    with _bar(total, args.quiet, f"train-fusion {sc.name}") as bar:
        model, report = train_fusion(sc, settings, progress=bar.update)
    model.save(out)
    written = [str(out)]
    if not args.no_figure:
        from ftnav.plot.learning import fusion_figure

        fig = fusion_figure(model, report, f"{sc.name}: neuron fusion centre, held-out runs")
        fig.savefig(out.with_suffix(".png"), dpi=110)
        written.append(str(out.with_suffix(".png")))
    print(f"{sc.name}: neuron fusion centre, configurations {', '.join(model.configurations)}; "
          f"inputs {', '.join(model.inputs)}; {time.perf_counter() - t0:.1f} s")
    print(fusion_table(model, report))
    print(f"Written: {', '.join(written)}")
    return 0


def _train_ins_fusion(sc, out: Path, args) -> int:
    """``train-fusion`` on an integrated scenario (paper 001's five configurations)."""
    from ftnav.eval.ins_training import ins_configurations, train_ins_fusion

    t0 = time.perf_counter()
    total = sc.steps * len(ins_configurations(sc))
    with _bar(total, args.quiet, f"train-fusion {sc.name}") as bar:
        try:
            model = train_ins_fusion(sc, runs=args.runs, seed=args.seed, progress=bar.update)
        except ValueError as e:
            raise UsageError(" ".join(str(e).split())) from None
    model.save(out)
    print(f"{sc.name}: neuron fusion centre, configurations {', '.join(model.configurations)}; "
          f"inputs {', '.join(model.inputs)}; {time.perf_counter() - t0:.1f} s")
    print("weights of the position neurons (" + ", ".join(model.inputs) + "):")
    for j, st in ((6, "dL"), (7, "dlambda"), (8, "dh")):
        for c, w in zip(model.configurations, model.weights[:, j], strict=True):
            print(f"  {st:8s} {c:8s} " + " ".join(f"{v:.3f}" for v in w))
    print(f"Written: {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ftnav`` command; returns the exit status."""
    from ftnav.io.scenario_file import ScenarioError

    try:
        args = _parser().parse_args(argv)
        if args.command == "list":
            return _cmd_list()
        if args.command == "schema":
            return _cmd_schema(args.out)
        if args.command == "trajectory":
            return _cmd_trajectory(args)
        if args.command == "train-detector":
            return _cmd_train_detector(args)
        if args.command == "train-fusion":
            return _cmd_train_fusion(args)
        return _cmd_run(args)
    except (UsageError, ScenarioError, ValueError) as e:
        msg = " ".join(str(e).split("\n"))
        print(f"ftnav: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ftnav: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
