"""Training and held-out evaluation of the RBF fault detector (spec §4.2-§4.3).

Pipeline (:func:`train_detector`):

1. A :class:`~ftnav.sim.fault_family.FaultFamily` of typical faults becomes one
   scenario variant per fault; ``runs`` runs of each are simulated as one batch.
2. The method the detector is trained for runs over the batch with the true
   fault windows as fault factors (``detector = "oracle"``), so the faulty
   filter is isolated as it will be when detection works, and reports the
   spec §4.1 features every epoch; each epoch is labelled by the true windows.
3. An :class:`~ftnav.fdi.rbf.RBFNetwork` is fitted to (features, labels).
4. Closed loop (``closed_loop`` passes, default 1): the method runs again on the
   training batch with the fitted detector in the loop; the epochs it sees
   there (e.g. a filter still isolated after its fault cleared) are added and
   the network is refitted.  The oracle pass never visits those states.
5. Whole held-out runs (run indices from
   :data:`~ftnav.sim.fault_family.HOLDOUT_OFFSET`) are run with the detector in
   the loop and, on the same data, with the residual chi-square test; per-fault
   detection rate, event rate, delay and false-alarm rate are reported for both.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ftnav.engine.driver import Trace, run
from ftnav.engine.linear import LinearModel
from ftnav.eval.metrics import detection_stats
from ftnav.fdi.features import FEATURE_KINDS
from ftnav.fdi.rbf import RBFModel, RBFNetwork
from ftnav.fusion import registry
from ftnav.fusion.config import (
    NOTHING_LEARNED,
    Learned,
    MethodBase,
    OracleDetector,
    RbfDetector,
    ResidualChi2,
)
from ftnav.io.learned import compatibility
from ftnav.model.scenario import Scenario
from ftnav.model.streams import MeasurementStream
from ftnav.model.system import LinearSystem
from ftnav.sim.fault_family import (
    HOLDOUT_OFFSET,
    FaultFamily,
    FaultVariant,
    fault_variants,
    simulate_variants,
    window_masks,
)

__all__ = [
    "DetectorTraining",
    "DetectorReport",
    "train_detector",
    "default_method",
    "held_out_table",
]

#: spawn-key component of the generator that draws the family's fault windows
_WINDOW_STREAM = 0x4642


@dataclass(frozen=True, slots=True)
class DetectorTraining:
    """Settings of :func:`train_detector` (defaults from spec §4.2).

    Attributes
    ----------
    runs, holdout_runs : Monte Carlo runs per fault variant for training and
        held-out evaluation.
    seed : root seed (windows, noise, k-means).
    family : the typical faults.
    features : feature kinds (spec §4.1).
    prior : prior the innovations are whitened against.
    n_centres, width, ridge, n_init, class_weight : network hyper-parameters.
    threshold, n_on, n_off : decision rule stored with the model.
    false_alarm_target : if set, each output's threshold is raised above
        ``threshold`` until its per-epoch false-alarm rate on the clean training
        epochs (label 0, outside the post-fault grace) is at most this
        (Neyman-Pearson calibration); None keeps ``threshold`` for all.
    closed_loop : refits with the detector in the loop.
    chi2_pfa : false-alarm probability of the chi-square test it is compared with.
    """

    runs: int = 8
    holdout_runs: int = 4
    seed: int = 1
    family: FaultFamily = field(default_factory=FaultFamily)
    features: tuple[str, ...] = FEATURE_KINDS
    prior: str = "global"
    n_centres: int = 60
    width: str = "global"
    ridge: float = 1e-6
    n_init: int = 10
    class_weight: str = "none"
    threshold: float = 0.5
    false_alarm_target: float | None = None
    n_on: int = 1
    n_off: int = 3
    closed_loop: int = 1
    chi2_pfa: float = 1e-3

    def __post_init__(self):
        for name in ("runs", "holdout_runs"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name}: must be >= 1, got {getattr(self, name)}")
        if self.closed_loop < 0:
            raise ValueError(f"closed_loop: must be >= 0, got {self.closed_loop}")
        if self.prior not in ("local", "global"):
            raise ValueError(f"prior: expected 'local' or 'global', got {self.prior!r}")


@dataclass(frozen=True)
class DetectorReport:
    """Held-out results of the trained detector and of the chi-square test.

    ``rows`` hold one dict per (sensor, fault kind, size) group with, for each
    detector ``d`` in ``("rbf", "chi2")``: ``{d}_rate`` (per-epoch Pd),
    ``{d}_event_rate``, ``{d}_median_delay`` (epochs); ``false_alarm`` maps
    detector → per-epoch false-alarm rate on clean epochs of every held-out run.
    ``roc`` maps sensor → (labels, rbf outputs, chi2 statistics) of held-out
    epochs for ROC curves; ``confusion`` maps sensor → 2x2 epoch counts.
    """

    rows: list[dict]
    false_alarm: dict[str, float]
    roc: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    confusion: dict[str, np.ndarray]
    train_samples: int


def default_method(scenario: Scenario) -> MethodBase:
    """The method a detector is trained for: the scenario's first RBF method, else
    paper 000's federated filter (fusion-reset, inverse-trace sharing)."""
    for m in scenario.methods:
        if isinstance(m.detector, RbfDetector):
            return m
    return registry.method_config(
        "federated", name="fkf-inverse-trace-rbf", sharing="inverse-trace"
    )


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(_WINDOW_STREAM,)))


def _with_detector(method: MethodBase, detector: Any) -> MethodBase:
    """The method with ``detector`` and without the guard (issue 20): the network is
    trained on, and its report measures, the detector's own flags; the guard's
    re-admission acts on top of them in the scenario's runs."""
    return method.model_copy(update={"detector": detector, "guard": None})


def _rbf(s: DetectorTraining) -> RbfDetector:
    return RbfDetector(kind="rbf", model="(in memory)", n_on=s.n_on, n_off=s.n_off)


def _run(
    system: LinearSystem,
    method: MethodBase,
    stream: MeasurementStream,
    steps: int,
    progress: Callable[[int], None] | None,
    learned: Learned = NOTHING_LEARNED,
    **kw: Any,
) -> Trace:
    filt = registry.build(system, method, learned, **kw)
    return run(LinearModel(system), stream, {method.name: filt}, steps, progress)[method.name]


def _collect(system, method, stream, steps, kinds, prior, progress):
    """The method with the true fault windows as fault factors, reporting the features."""
    trace = _run(
        system,
        _with_detector(method, OracleDetector(kind="oracle")),
        stream,
        steps,
        progress,
        features=kinds,
        feature_prior=prior,
    )
    labels = np.swapaxes(np.asarray(stream.labels, dtype=bool), 0, 1)  # (B, K, N)
    return trace, labels


def train_detector(
    scenario: Scenario,
    settings: DetectorTraining = DetectorTraining(),
    method: MethodBase | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[RBFModel, DetectorReport]:
    """Train an RBF detector for ``method`` on ``scenario``'s system (spec §4.2).

    Parameters
    ----------
    scenario : the system (model and sensors); its own faults are not used.
    settings : training settings.
    method : the method whose filters produce the features (default
        :func:`default_method`); federated or distributed.
    progress : called with the number of epochs processed.

    Returns
    -------
    model : the trained detector (save it with :func:`ftnav.io.learned.save_rbf_model`).
    report : held-out metrics beside the chi-square test on the same runs.
    """
    method = default_method(scenario) if method is None else method
    if (
        method.architecture not in ("federated", "distributed")
        or getattr(method, "mode", None) == "zero-reset"
    ):
        raise ValueError(
            f"methods[{method.name}].architecture: the RBF detector's features "
            "need local filters with priors (federated or distributed, not zero-reset)"
        )
    s = settings
    system = scenario.system()
    K = scenario.steps
    kinds = tuple(s.features)
    variants = fault_variants(scenario, s.family, _rng(s.seed))
    sim, _ = simulate_variants(scenario, variants, s.runs, s.seed)
    res, labels = _collect(system, method, sim.stream, K, kinds, s.prior, progress)
    X = [res.features.reshape(-1, res.features.shape[-1])]
    Y = [labels.reshape(-1, labels.shape[-1])]
    net = RBFNetwork(s.n_centres, s.width, s.ridge, s.n_init, s.class_weight, random_state=s.seed)
    net.fit(np.concatenate(X), np.concatenate(Y))
    compat = compatibility(system)
    provenance = {
        "scenario": scenario.name,
        "method": method.name,
        "architecture": method.architecture,
        "mode": getattr(method, "mode", None),
        "sharing": getattr(method, "sharing", None),
        "runs_per_variant": s.runs,
        "seed": s.seed,
        "variants": [v.label for v in variants],
        "closed_loop": s.closed_loop,
        "family": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(s.family).items()},
    }

    clean = ~window_masks(scenario, variants, s.runs, scenario.evaluation.grace).reshape(
        -1, system.n_sensors
    )  # (B·K, N) epochs where an alarm of output i is false

    def model_of(network):
        return RBFModel(
            network,
            kinds,
            s.prior,
            _calibrate(network, X, clean, s),
            s.n_on,
            s.n_off,
            compat,
            provenance,
        )

    loop = _with_detector(method, _rbf(s))
    for _ in range(s.closed_loop):
        res_loop = _run(system, loop, sim.stream, K, progress, Learned(detector=model_of(net)))
        X.append(res_loop.features.reshape(X[0].shape[0], -1))
        Y.append(Y[0])
        clean = np.concatenate([clean, clean[: Y[0].shape[0]]])
        net = RBFNetwork(
            s.n_centres, s.width, s.ridge, s.n_init, s.class_weight, random_state=s.seed
        )
        net.fit(np.concatenate(X), np.concatenate(Y))
    report = _held_out(
        scenario,
        system,
        method,
        variants,
        s,
        model_of(net),
        progress,
        train_samples=sum(x.shape[0] for x in X),
    )
    summary = {
        "false_alarm": report.false_alarm,
        "rows": [
            {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in r.items()}
            for r in report.rows
        ],
    }
    final = model_of(net)
    return replace(final, training={**provenance, "held_out": summary}), report


def _calibrate(network, X, clean, s: DetectorTraining) -> np.ndarray:
    """Per-output thresholds (N,): at least ``s.threshold``, false alarms <= the target."""
    N = clean.shape[1]
    tau = np.full(N, float(s.threshold))
    if s.false_alarm_target is None:
        return tau
    y = network.decision_function(np.concatenate(X))
    for i in range(N):
        q = np.quantile(y[clean[:, i], i], 1.0 - s.false_alarm_target)
        tau[i] = max(tau[i], float(q))
    return tau


def _held_out(
    scenario,
    system,
    method,
    variants: list[FaultVariant],
    s: DetectorTraining,
    model: RBFModel,
    progress,
    train_samples: int,
) -> DetectorReport:
    sim, vidx = simulate_variants(scenario, variants, s.holdout_runs, s.seed, HOLDOUT_OFFSET)
    rbf = _with_detector(method, _rbf(s))
    chi2 = _with_detector(
        method,
        ResidualChi2(
            kind="residual-chi2",
            prior="global",
            false_alarm_probability=s.chi2_pfa,
            n_on=s.n_on,
            n_off=5,
        ),
    )
    K = scenario.steps
    results = {
        "rbf": _run(system, rbf, sim.stream, K, progress, Learned(detector=model)),
        "chi2": _run(system, chi2, sim.stream, K, progress),
    }
    return _report(scenario, variants, vidx, sim.stream, results, s.holdout_runs, train_samples)


def _report(
    scenario,
    variants,
    vidx,
    stream: MeasurementStream,
    results,
    runs_per_variant: int,
    train_samples: int,
) -> DetectorReport:
    t = scenario.times
    dt = scenario.dt
    labels = np.swapaxes(np.asarray(stream.labels, dtype=bool), 0, 1)  # (B, K, N)
    names = scenario.sensor_names
    rows = []
    groups: dict[tuple, list[int]] = {}
    for j, v in enumerate(variants):
        if v.sensor is not None:
            groups.setdefault((v.sensor, v.kind, v.size), []).append(j)
    grace = scenario.evaluation.grace
    for (sensor, kind, size), members in groups.items():
        i = names.index(sensor)
        row = {"sensor": sensor, "kind": kind, "size": size}
        for d, res in results.items():
            stats = []
            for j in members:
                runs = vidx == j
                (fault,) = variants[j].faults
                stats.append(
                    detection_stats(res.flag[runs, :, i], t, [(fault.start, fault.end)], grace)
                )
            rate = np.mean([x.rate for x in stats])
            event = np.mean([x.event_rate for x in stats])
            delays = [x.median_delay_s for x in stats if not math.isnan(x.median_delay_s)]
            row[f"{d}_rate"] = float(rate)
            row[f"{d}_event_rate"] = float(event)
            row[f"{d}_median_delay"] = float(np.median(delays) / dt) if delays else float("nan")
        rows.append(row)
    # false alarms: every held-out run's clean epochs of each output (outside its
    # variant's window and grace period), as in spec §11
    clean = ~window_masks(scenario, variants, runs_per_variant, grace)
    false_alarm = {
        d: float((res.flag & clean).sum() / clean.sum()) if clean.any() else float("nan")
        for d, res in results.items()
    }
    roc, confusion = {}, {}
    for i, sensor in enumerate(names):
        y = labels[..., i].ravel()
        roc[sensor] = (
            y,
            results["rbf"].statistic[..., i].ravel(),  # network outputs
            results["chi2"].statistic[..., i].ravel(),
        )
        f = results["rbf"].flag[..., i].ravel()
        confusion[sensor] = np.array(
            [[np.sum(~y & ~f), np.sum(~y & f)], [np.sum(y & ~f), np.sum(y & f)]]
        )
    return DetectorReport(rows, false_alarm, roc, confusion, int(train_samples))


def held_out_table(report: DetectorReport) -> str:
    """Plain-text table of the held-out metrics, RBF beside chi-square."""
    head = (
        f"{'sensor':10s} {'fault':14s} {'Pd rbf':>7s} {'Pd chi2':>7s} {'ev rbf':>7s} "
        f"{'ev chi2':>7s} {'delay rbf':>9s} {'delay chi2':>10s}"
    )
    lines = [head, "-" * len(head)]

    def f(v, fmt):
        return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v)

    for r in report.rows:
        fault = f"{r['kind']} {r['size']:g}" + ("σ" if r["kind"] != "noise-scale" else "x")
        lines.append(
            f"{r['sensor']:10s} {fault:14s} {f(r['rbf_rate'], '{:.3f}'):>7s} "
            f"{f(r['chi2_rate'], '{:.3f}'):>7s} {f(r['rbf_event_rate'], '{:.2f}'):>7s} "
            f"{f(r['chi2_event_rate'], '{:.2f}'):>7s} "
            f"{f(r['rbf_median_delay'], '{:.1f}'):>9s} "
            f"{f(r['chi2_median_delay'], '{:.1f}'):>10s}"
        )
    lines.append(
        f"false-alarm rate per epoch: rbf {report.false_alarm['rbf']:.4%}, "
        f"chi2 {report.false_alarm['chi2']:.4%}"
    )
    return "\n".join(lines)
