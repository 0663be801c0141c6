"""The one driver loop: any navigation model, any stream, every architecture.

:func:`iterate` steps every method on every epoch of a stream and yields what the
epoch produced (:class:`EpochRecord`); :func:`run` collects those records into one
:class:`Trace` per method.  The model (:class:`~ftnav.engine.linear.LinearModel`,
:class:`~ftnav.engine.ins.InsModel`) turns the stream into epochs and, with feedback,
takes the fused estimate back; the architectures (:mod:`ftnav.fusion.registry`)
implement one protocol (:class:`~ftnav.fusion.protocol.Architecture`).  No truth
enters: evaluation (:mod:`ftnav.eval`) reads the records or the trace afterwards.

The loop over epochs is in Python; everything inside is batched over runs (and, for
integrated navigation, over methods: every method's SINS is one batch).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, TypeVar

import numpy as np

from ftnav.core import kalman as kf
from ftnav.fusion.guard import GuardOutput
from ftnav.fusion.protocol import Architecture, StepOutput
from ftnav.model.system import Epoch, Linearization, LinearSystem
from ftnav.nav.mechanization import InsState

#: navigation error states (attitude, velocity, position; spec §8.3 order): those fed
#: back to a SINS and those of ``P_nav``
N_NAV = 9

__all__ = [
    "Diverged",
    "EpochRecord",
    "GuardTrace",
    "LocalCopies",
    "MethodOutputs",
    "NavigationModel",
    "SmoothingRecord",
    "Stream",
    "Trace",
    "check_output",
    "covariance_ok",
    "guard_trace",
    "iterate",
    "method_feedback",
    "run",
]

M = TypeVar("M")  # the model's own state between epochs


class Stream(Protocol):
    """What the driver needs of a measurement stream (:mod:`ftnav.model.streams`)."""

    @property
    def batch(self) -> int:
        """Runs in the stream (the leading axis of every array)."""
        ...


class NavigationModel(Protocol[M]):
    """What turns a stream into epochs, and (integrated) takes the fused estimate back.

    Attributes
    ----------
    system : the filters' system.
    feedback : the fused estimate is fed back after each epoch (closed loop).
    per_method_rows : an epoch holds every method's rows, method-major (each method
        has its own SINS); else all methods see the same rows.
    n_fed : states fed back (every filter is shifted by them).
    n_local : states of the local estimates to keep (None: the common states).
    """

    system: LinearSystem
    feedback: bool
    per_method_rows: bool
    n_fed: int
    n_local: int | None

    def start(self, stream: Any, copies: int) -> M:
        """The model's state before the first epoch, for ``copies`` methods."""
        ...

    def epoch(
        self,
        state: M,
        stream: Any,
        k: int,
        copies: int,
        local_copies: LocalCopies | None = None,
    ) -> tuple[M, Epoch]:
        """The epoch k (1-based) of the stream: measurements, availability, matrices;
        ``local_copies``: rows whose aids are measured at each local's own corrected
        copy of the SINS output (output correction, spec §8.5; paper 001 §3)."""
        ...

    def navigation(self, state: M) -> InsState | None:
        """Every method's navigation solution before the correction, or None (linear)."""
        ...

    def compensated_bias(self, state: M) -> np.ndarray | None:
        """(rows, 6) the IMU biases every method's SINS subtracts so far (gyro rad/s, then
        accelerometer m/s²), or None (no bias compensation, or linear)."""
        ...

    def correct(self, state: M, fused: np.ndarray, rows: np.ndarray | None = None) -> M:
        """Feed every method's fused estimate (rows, n) back (only the ``rows`` (rows,)
        that are True, when given)."""
        ...

    def output(
        self, state: M, fused: np.ndarray, rows: np.ndarray | None = None
    ) -> InsState | None:
        """The corrected navigation solution, or None (linear); ``rows`` as for
        :meth:`correct` (the others' output is corrected by their estimate)."""
        ...


class LocalCopies(NamedTuple):
    """Rows whose aid i is measured at local i's own copy of the SINS output.

    Attributes
    ----------
    rows : (rows,) bool, the SINS rows concerned (methods with output correction whose
        architecture keeps independent local copies: ``local_copies = True``).
    estimate : (rows, N, n_c) each local filter's posterior estimate of the common
        error states at the previous epoch (zeros elsewhere).
    """

    rows: np.ndarray
    estimate: np.ndarray


class EpochRecord(NamedTuple):
    """What one epoch produced.

    Attributes
    ----------
    k : the epoch (1-based).
    outputs : per method, its :class:`~ftnav.fusion.protocol.StepOutput`.
    local : per method, (B, N, n) its local filters' estimates after the step (before
        any feedback shift), or None (centralized, zero-reset).
    nav : every method's navigation solution before the correction (methods × runs rows,
        method-major), or None for a linear model.
    solution : the corrected navigation solution (same rows), or None.
    bias : (rows, 6) the IMU biases compensated after the epoch's feedback (same rows),
        or None (:meth:`NavigationModel.compensated_bias`).
    lin : the epoch's matrices as the model formed them (every method's rows,
        method-major, with ``per_method_rows``), or None for a constant system.
    """

    k: int
    outputs: tuple[StepOutput, ...]
    local: tuple[np.ndarray | None, ...]
    nav: InsState | None
    solution: InsState | None
    lin: Linearization | None = None
    bias: np.ndarray | None = None


def _part(epoch: Epoch, rows: slice) -> Epoch:
    """One method's rows of an epoch formed for every method's SINS at once."""
    lin = epoch.lin
    if lin is not None:
        lin = Linearization(lin.Phi[rows], lin.Q[rows], tuple(h[rows] for h in lin.H))
    rep = epoch.repeated
    return epoch._replace(
        z=tuple(z[rows] for z in epoch.z),
        available=epoch.available[rows],
        lin=lin,
        repeated=None if rep is None else rep[rows],
    )


#: Relative tolerance of the symmetry test of :func:`covariance_ok`.
SYMMETRY_RTOL = 1e-9


class Diverged(FloatingPointError):
    """A method's estimate stopped being a Gaussian: NaN or inf, or a covariance that is
    not positive definite (rounding that the model's Q, R and P0 amplify).

    The message is one line, ``methods[NAME]: diverged at epoch K (t = T s): REASON``.

    Attributes
    ----------
    method : the method's name.
    epoch : the epoch (1-based), or None when unknown.
    time_s : the epoch's time (s), or None when unknown.
    reason : what is wrong, e.g. ``covariance not positive definite (check Q, R, P0)``.
    """

    def __init__(self, method: str, epoch: int | None, time_s: float | None, reason: str):
        self.method, self.epoch, self.time_s, self.reason = method, epoch, time_s, reason
        where = "" if epoch is None else f" at epoch {epoch}"
        when = "" if time_s is None else f" (t = {time_s:g} s)"
        super().__init__(f"methods[{method}]: diverged{where}{when}: {reason}")

    def __reduce__(self) -> tuple[Any, ...]:  # picklable (worker processes): custom signature
        return (type(self), (self.method, self.epoch, self.time_s, self.reason))


#: the reasons of :class:`Diverged` the engine gives
NOT_FINITE = "estimate or covariance is NaN or inf (check Q, R, P0)"
NOT_SPD = "covariance not positive definite (check Q, R, P0)"


def covariance_ok(P: np.ndarray) -> bool:
    """Symmetric (``max|P − Pᵀ| <= 1e-9 max|P|``), positive diagonal and positive
    definite (Cholesky succeeds) for every run; (..., n, n).

    About 30 µs for 4 runs of 18 states (0.9 % of ``ftnav run seed002 --runs 2``): cheap
    enough for every epoch of every method.
    """
    scale = float(np.abs(P).max(initial=0.0))
    if (
        not scale > 0
        or float(np.abs(P - kf.mT(P)).max(initial=0.0)) > SYMMETRY_RTOL * scale
        or not (np.diagonal(P, axis1=-2, axis2=-1) > 0).all()
    ):
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True


def _checked(
    name: str,
    k: int,
    out: StepOutput,
    check_spd: bool,
    times: Sequence[float] | np.ndarray | None,
) -> None:
    if np.isfinite(out.x).all() and np.isfinite(out.P).all():
        if not check_spd or covariance_ok(out.P):
            return
        reason = NOT_SPD
    else:
        reason = NOT_FINITE
    raise Diverged(name, k, None if times is None else float(times[k - 1]), reason)


def check_output(
    method: str,
    values: Sequence[np.ndarray | None] = (),
    variances: Sequence[np.ndarray | None] = (),
    times: Sequence[float] | np.ndarray | None = None,
) -> None:
    """Refuse to report a diverged method: raise :class:`Diverged` at the first epoch
    where one of ``values`` is NaN or inf or one of ``variances`` is NaN, inf or negative.

    Every array is (B, K, ...), epochs on axis 1 (None: skipped).  The last guard
    before results are scored or written: what is written is a number, never a null.
    """
    first: tuple[int, str] | None = None
    for arrays, variance in ((values, False), (variances, True)):
        for a in arrays:
            if a is None or a.size == 0:
                continue
            bad = ~np.isfinite(a)
            if variance:
                bad |= np.isfinite(a) & (a < 0)
            per_epoch = bad.reshape(a.shape[0], a.shape[1], -1).any(axis=(0, 2))
            if per_epoch.any():
                k = int(np.argmax(per_epoch))
                reason = NOT_FINITE
                if variance and np.isfinite(a[:, k]).all():
                    reason = "negative variance (check Q, R, P0)"
                if first is None or k < first[0]:
                    first = (k, reason)
    if first is not None:
        k, reason = first
        raise Diverged(method, k + 1, None if times is None else float(times[k]), reason)


def iterate(
    model: NavigationModel[Any],
    stream: Stream,
    filters: Mapping[str, Architecture[Any]],
    steps: int,
    progress: Callable[[int], None] | None = None,
    check_spd: bool = True,
    times: Sequence[float] | np.ndarray | None = None,
) -> Iterator[EpochRecord]:
    """Step every method over ``steps`` epochs of ``stream``; yield each epoch's record.

    ``model`` turns the stream into epochs (``start``, ``epoch``; with
    ``per_method_rows`` an epoch holds every method's rows, method-major) and, when it
    feeds back (``model.feedback``), takes the fused estimates back (``correct``); each
    method's filter is then shifted by its own fused estimate of the first
    ``model.n_fed`` states.  ``model.n_local`` states of the local estimates are kept
    (None: the common states).  A NaN or inf output raises :class:`Diverged`, and so
    does a fused covariance that is not symmetric positive definite (``check_spd``, on
    by default: :func:`covariance_ok` costs 0.9 % of ``ftnav run seed002``).  ``times`` (steps,)
    are the epochs' times (s) the error names.
    """
    names = list(filters)
    M = len(names)
    B = stream.batch
    parts = [slice(j * B, (j + 1) * B) for j in range(M)]
    mstate = model.start(stream, M)
    states = [filters[nm].init(B) for nm in names]
    n_local = model.n_local or model.system.n_common
    fb = method_feedback(model, [filters[nm] for nm in names])
    rows = None if fb is None else np.repeat(fb, B)
    # output-corrected methods whose locals measure at their own SINS copies, whether the
    # method or the scenario chose output correction
    copies = [
        j
        for j, nm in enumerate(names)
        if model.per_method_rows
        and not (model.feedback if fb is None else fb[j])
        and getattr(filters[nm], "local_copies", False)
    ]
    local_copies = None
    for k in range(1, steps + 1):
        mstate, epoch = model.epoch(mstate, stream, k, M, local_copies)
        outputs, local = [], []
        for j, nm in enumerate(names):
            e_j = _part(epoch, parts[j]) if model.per_method_rows else epoch
            states[j], out = filters[nm].step(states[j], e_j)
            _checked(nm, k, out, check_spd, times)
            outputs.append(out)
            local.append(filters[nm].local_estimates(states[j], n_local))
            if progress is not None:
                progress(1)
        if copies:
            local_copies = _local_copies(model, filters, names, states, copies, B)
        nav = model.navigation(mstate)
        solution = None
        if nav is not None:
            fused = np.concatenate([o.x for o in outputs], 0)
            if model.feedback if rows is None else rows.any():
                for j, nm in enumerate(names):
                    if fb is None or fb[j]:
                        states[j] = filters[nm].shift(states[j], outputs[j].x[:, : model.n_fed])
                mstate = model.correct(mstate, fused, rows)
            solution = model.output(mstate, fused, rows)
        bias = model.compensated_bias(mstate)
        yield EpochRecord(k, tuple(outputs), tuple(local), nav, solution, epoch.lin, bias)


def method_feedback(
    model: NavigationModel[Any], filters: list[Architecture[Any]]
) -> np.ndarray | None:
    """(M,) whether each method feeds its fused estimate back to its SINS, when a method
    sets its own ``correction`` against the model's (spec §8.5); None when every method
    follows the model (its ``feedback``), or for a model without a SINS."""
    if not model.per_method_rows:
        return None
    own = [getattr(getattr(f, "config", None), "correction", None) for f in filters]
    if all(c is None for c in own):
        return None
    fb = np.array([model.feedback if c is None else c == "feedback" for c in own])
    if (fb == model.feedback).all():
        return None
    return fb


def _local_copies(
    model: NavigationModel[Any],
    filters: Mapping[str, Architecture[Any]],
    names: list[str],
    states: list[Any],
    copies: list[int],
    B: int,
) -> LocalCopies:
    """The local estimates of the methods whose locals keep their own SINS copies."""
    nc, N = model.system.n_common, model.system.n_sensors
    rows = np.zeros(len(names) * B, bool)
    est = np.zeros((len(names) * B, N, nc))
    for j in copies:
        local = filters[names[j]].local_estimates(states[j], nc)
        assert local is not None, "an architecture with local copies has local estimates"
        rows[j * B : (j + 1) * B] = True
        est[j * B : (j + 1) * B] = local
    return LocalCopies(rows, est)


#: What the isolation guard did, its per-epoch outputs stacked over the epochs: the fields
#: of :class:`~ftnav.fusion.guard.GuardOutput`, (B, K, N) each
GuardTrace = GuardOutput


#: the guard's per-epoch outputs as the recorder keys them
GUARD_KEYS = tuple(f"guard_{f}" for f in GuardTrace._fields)


class SmoothingRecord(NamedTuple):
    """What the forward pass keeps of one method for the Rauch–Tung–Striebel smoother
    (:mod:`ftnav.engine.smoother`), recorded only on request (``run``'s ``smoothing``).

    Memory: three (B, K, n_c, n_c) arrays, ``3·B·K·n_c²`` floats (about 11 MB per method
    for 6000 epochs of 15 states and one run), and the (B, K, 10) solution.

    Attributes
    ----------
    x : (B, K, n_c) fused posterior x⁺_k before the feedback shift (the array of
        :attr:`Trace.x`).
    P : (B, K, n_c, n_c) its full covariance P⁺_k.
    Phi, Q : (B, K, n_c, n_c) the transition Φ and process noise Q of the step
        ``k−1 → k`` (epoch k's linearization, spec §8.4); index 0 is the step from the
        initial state.
    n_fed : the first ``n_fed`` states were fed back after every epoch (and every
        estimate shifted by them, spec §6.2); 0 for output correction or a linear model.
    base : the navigation solution the estimate after the reset (x⁺_k with its first
        ``n_fed`` states zeroed) refers to: the corrected solution (feedback) or the
        free SINS (output correction), q (B, K, 4), v, p (B, K, 3) (``a`` zeros); None
        for a linear model.
    """

    x: np.ndarray
    P: np.ndarray
    Phi: np.ndarray
    Q: np.ndarray
    n_fed: int
    base: InsState | None


@dataclass(frozen=True, kw_only=True)
class MethodOutputs:
    """What one method says of itself over B runs and K epochs, with no reference: the
    fields that a recorded run's :class:`Trace` and a simulated run's scores
    (:class:`~ftnav.eval.montecarlo.MethodResult`) share, recorded once by
    :meth:`Recorder.method_outputs`.

    Attributes
    ----------
    beta : (B, K, N) sharing coefficients, or None (not federated).
    statistic, threshold : (B, K, N) detector statistic and threshold, or None.
    raw_flag, flag : (B, K, N) detector flags before/after hysteresis, or None.
    R_hat : per sensor (B, K, m_i) diagonal noise used (adapted under VB).
    nan_count : (B, N) scheduled measurements that were NaN/inf (treated as missing).
    features : (B, K, F) learned-detector features (spec §4.1), or None.
    nis : (B, K, N) each aid's NIS against the method's prediction (0: no measurement).
    used, available : (B, K, N) bool, the aids that updated the method, and those with a
        finite measurement.
    guard : what the isolation guard did, or None (a method without a detector).
    """

    nan_count: np.ndarray
    R_hat: tuple[np.ndarray, ...] = ()
    beta: np.ndarray | None = None
    statistic: np.ndarray | None = None
    threshold: np.ndarray | None = None
    raw_flag: np.ndarray | None = None
    flag: np.ndarray | None = None
    features: np.ndarray | None = None
    nis: np.ndarray | None = None
    used: np.ndarray | None = None
    available: np.ndarray | None = None
    guard: GuardTrace | None = None


@dataclass(frozen=True, kw_only=True)
class Trace(MethodOutputs):
    """Per-epoch outputs of one method over B runs and K epochs (no reference needed):
    :class:`MethodOutputs` and the estimate and solution.

    Attributes
    ----------
    x : (B, K, n_c) fused estimate (an integrated model's error-state estimate).
    P_diag : (B, K, n_c) its variances.
    solution : the corrected navigation solution (q (B, K, 4), v, p (B, K, 3)), or None.
    local : (B, K, N, n) local estimates, or None.
    P_nav : (B, K, 9, 9) the fused covariance of the 9 navigation error states
        (attitude, velocity, position), recorded only on request (``run``'s
        ``nav_covariance``: a truth's NEES needs it), else None.
    smoothing : what the RTS smoother needs (:class:`SmoothingRecord`), recorded only on
        request (``run``'s ``smoothing``), else None.
    prediction : the solution a user had before each epoch's aiding: the SINS propagated
        from the last corrected solution (q (B, K, 4), v, p (B, K, 3)), recorded only on
        request (``run``'s ``prediction``) and for methods that feed back, else None.
    bias : (B, K, 6) the IMU biases the SINS subtracts after each epoch's feedback, gyro
        (rad/s) then accelerometer (m/s²), body frame: with bias compensation, for a
        method that feeds back, the estimate of the whole bias (the bias states of ``x``
        hold only the residual that epoch fed back), else None.
    """

    x: np.ndarray
    P_diag: np.ndarray
    solution: InsState | None = None
    local: np.ndarray | None = None
    P_nav: np.ndarray | None = None
    smoothing: SmoothingRecord | None = None
    prediction: InsState | None = None
    bias: np.ndarray | None = None


def guard_trace(arrays: dict[str, np.ndarray]) -> GuardTrace | None:
    """The guard's arrays a :class:`Recorder` holds, or None."""
    if GUARD_KEYS[0] not in arrays:
        return None
    return GuardTrace(*(arrays[k] for k in GUARD_KEYS))


class Recorder:
    """One method's per-epoch arrays, allocated on first use and filled in place.

    The engine's :func:`run` records a whole :class:`Trace` with it; evaluation records
    the outputs that need no reference (:meth:`outputs`) beside its own scores.
    With ``smoothing`` it also keeps a :class:`SmoothingRecord` (``n_fed`` states fed
    back after every epoch).
    """

    def __init__(
        self, B: int, K: int, nav_covariance: bool = False, smoothing: bool = False, n_fed: int = 0
    ):
        self.B, self.K = B, K
        self.nav_covariance = nav_covariance
        self.smoothing, self.n_fed = smoothing, n_fed
        self.arrays: dict[str, np.ndarray] = {}
        self.nan: np.ndarray | None = None

    def put(self, key: str, k: int, value: np.ndarray | None, dtype: Any = float) -> None:
        if value is None:
            return
        if key not in self.arrays:
            self.arrays[key] = np.empty((self.B, self.K) + value.shape[1:], dtype=dtype)
        self.arrays[key][:, k - 1] = value

    def outputs(self, k: int, out: StepOutput) -> None:
        """Epoch k's sharing, detection, noise, NaN count and features."""
        self.put("beta", k, out.beta)
        d = out.detection
        if d is not None:
            self.put("statistic", k, d.statistic)
            self.put("threshold", k, d.threshold)
            self.put("raw_flag", k, d.raw, bool)
            self.put("flag", k, d.flag, bool)
        for i, r in enumerate(out.R_hat):
            self.put(f"R{i}", k, r)
        self.nan = out.nan.astype(int) if self.nan is None else self.nan + out.nan
        self.put("features", k, out.features)
        self.put("nis", k, out.nis)
        self.put("used", k, out.used, bool)
        self.put("available", k, out.available, bool)
        if out.guard is not None:
            for key, value in zip(GUARD_KEYS, out.guard, strict=True):
                self.put(key, k, value, float if key == "guard_statistic" else bool)

    def record(
        self,
        k: int,
        out: StepOutput,
        local: np.ndarray | None,
        solution: InsState | None,
        lin: Linearization | None = None,
        base: InsState | None = None,
        prior: InsState | None = None,
        bias: np.ndarray | None = None,
    ) -> None:
        """Epoch k's whole output of one method (:meth:`outputs`, estimate, solution);
        with ``smoothing`` also its covariance, the epoch's (Φ, Q) ``lin`` and the
        solution ``base`` its reset estimate refers to (:class:`SmoothingRecord`)."""
        self.put("x", k, out.x)
        self.put("P_diag", k, np.diagonal(out.P, axis1=-2, axis2=-1))
        if self.nav_covariance:
            self.put("P_nav", k, out.P[:, :N_NAV, :N_NAV])
        if self.smoothing:
            assert lin is not None, "smoothing needs the epoch's (Phi, Q)"
            self.put("smooth_P", k, out.P)
            self.put("smooth_Phi", k, lin.Phi)
            self.put("smooth_Q", k, lin.Q)
            if base is not None:
                for key in ("q", "v", "p"):
                    self.put(f"smooth_{key}", k, getattr(base, key))
        self.outputs(k, out)
        self.put("local", k, local)
        if solution is not None:
            for key in ("q", "v", "p"):
                self.put(f"nav_{key}", k, getattr(solution, key))
        if prior is not None:
            for key in ("q", "v", "p"):
                self.put(f"prior_{key}", k, getattr(prior, key))
        self.put("bias", k, bias)

    def method_outputs(self, n_sensors: int) -> dict[str, Any]:
        """The recorded :class:`MethodOutputs` fields, as keyword arguments of it or of a
        subclass (:class:`Trace`, :class:`~ftnav.eval.montecarlo.MethodResult`)."""
        a = self.arrays
        assert self.nan is not None, "no epoch recorded"
        return {
            "beta": a.get("beta"),
            "statistic": a.get("statistic"),
            "threshold": a.get("threshold"),
            "raw_flag": a.get("raw_flag"),
            "flag": a.get("flag"),
            "R_hat": tuple(a[f"R{i}"] for i in range(n_sensors)),
            "nan_count": self.nan,
            "features": a.get("features"),
            "nis": a.get("nis"),
            "used": a.get("used"),
            "available": a.get("available"),
            "guard": guard_trace(a),
        }

    def trace(self, n_sensors: int) -> Trace:
        a = self.arrays
        solution = None
        if "nav_q" in a:
            solution = InsState(a["nav_q"], a["nav_v"], a["nav_p"], np.zeros(a["nav_v"].shape))
        smoothing = None
        if self.smoothing:
            base = None
            if "smooth_q" in a:
                base = InsState(
                    a["smooth_q"], a["smooth_v"], a["smooth_p"], np.zeros(a["smooth_v"].shape)
                )
            smoothing = SmoothingRecord(
                a["x"], a["smooth_P"], a["smooth_Phi"], a["smooth_Q"], self.n_fed, base
            )
        return Trace(
            **self.method_outputs(n_sensors),
            x=a["x"],
            P_diag=a["P_diag"],
            solution=solution,
            local=a.get("local"),
            P_nav=a.get("P_nav"),
            smoothing=smoothing,
            prediction=None
            if "prior_q" not in a
            else InsState(a["prior_q"], a["prior_v"], a["prior_p"], np.zeros(a["prior_v"].shape)),
            bias=a.get("bias"),
        )


def run(
    model: NavigationModel[Any],
    stream: Stream,
    filters: Mapping[str, Architecture[Any]],
    steps: int,
    progress: Callable[[int], None] | None = None,
    nav_covariance: bool = False,
    check_spd: bool = True,
    times: Sequence[float] | np.ndarray | None = None,
    smoothing: bool = False,
    prediction: bool = False,
) -> dict[str, Trace]:
    """Run every method over the stream; one :class:`Trace` per method (module docstring).

    ``nav_covariance`` also records each method's 9 × 9 navigation covariance
    (:attr:`Trace.P_nav`; B·K·81 floats per method, so off by default).  ``smoothing``
    also records what the RTS smoother (:func:`ftnav.engine.smoother.smooth`) needs
    (:attr:`Trace.smoothing`: the full fused covariance and the epochs' Φ and Q,
    3·B·K·n_c² floats per method, so off by default; it changes nothing else) and
    raises ValueError for a model with a differenced aid.  ``check_spd`` and ``times``
    as for :func:`iterate` (a method that diverges raises :class:`Diverged`).
    ``prediction`` also records, for the methods that feed back, the solution before
    each epoch's aiding (:attr:`Trace.prediction`, B·K·10 floats per method): what a
    user of the filter had just before the fix it is scored at.
    """
    names = list(filters)
    B = stream.batch
    fb = method_feedback(model, [filters[nm] for nm in names])
    feeds = [model.feedback if fb is None else bool(fb[j]) for j in range(len(names))]
    fed = [False] * len(names)
    constant = None
    if smoothing:
        _check_smoothable(model)
        fed = feeds
        F, Q = model.system.model.F, model.system.model.Q
        if F is not None and Q is not None:  # a constant system: the same (Φ, Q) every epoch
            n = F.shape[0]
            constant = Linearization(
                np.broadcast_to(F, (B, n, n)), np.broadcast_to(Q, (B, n, n)), ()
            )
    rec = {
        nm: Recorder(B, steps, nav_covariance, smoothing, model.n_fed if fed[j] else 0)
        for j, nm in enumerate(names)
    }
    for r in iterate(model, stream, filters, steps, progress, check_spd, times):
        for j, nm in enumerate(names):
            rows = slice(j * B, (j + 1) * B)
            sol = None
            if r.solution is not None:
                sol = InsState(*(a[rows] for a in r.solution))
            lin, base = None, None
            if smoothing:
                lin = constant if r.lin is None else r.lin
                if lin is not None and model.per_method_rows:
                    lin = Linearization(lin.Phi[rows], lin.Q[rows], ())
                if r.nav is not None:  # the solution the reset estimate refers to
                    base = sol if fed[j] else InsState(*(a[rows] for a in r.nav))
            prior = None
            if prediction and r.nav is not None and feeds[j]:
                prior = InsState(*(a[rows] for a in r.nav))
            bias = None if r.bias is None or not feeds[j] else r.bias[rows]
            rec[nm].record(r.k, r.outputs[j], r.local[j], sol, lin, base, prior, bias)
    return {nm: rec[nm].trace(model.system.n_sensors) for nm in names}


def _check_smoothable(model: NavigationModel[Any]) -> None:
    """Refuse smoothing a model with a differenced aid (GNSS ``markov = "difference"``):
    its measurements depend on the previous epoch's state and noise, which the
    Rauch–Tung–Striebel smoother's model (white measurement noise) does not cover."""
    for i, psi in enumerate(getattr(model, "psi", ())):  # InsModel's differencing factors
        if psi is not None:
            name = model.system.sensors[i].name
            raise ValueError(
                f"smoothing: aid {name!r} uses measurement differencing (markov = "
                '"difference"), which the RTS smoother does not cover; use markov = "augment"'
            )
