"""What a run will need before it starts: peak memory, available memory, kernel compilation.

:func:`run_memory_bytes` estimates the peak memory of ``ftnav run`` from the
scenario's sizes alone (nothing is allocated), by counting the large arrays the
runners hold at their peak:

* linear scenarios (:func:`ftnav.eval.montecarlo.run_scenario`): the simulation
  (:func:`ftnav.sim.linear.simulate`: the per-run normal draws, truth ``(B, K, n)``,
  measurements and ideal measurements ``(B, K, m)`` per sensor), with faults its
  fault-free twin and the concatenated batch of ``2B`` runs; the per-epoch results
  of every method (``x`` and ``P_diag`` ``(2B, K, n_c)``, NEES ``(2B, K)``, sharing
  coefficients and detector outputs ``(2B, K, N)``, noise ``(2B, K, Σm)``);
* integrated scenarios (:func:`ftnav.eval.montecarlo.run_scenario`): per batch of
  :func:`~ftnav.eval.batching.chunk_runs` runs, the IMU increments ``(b, n_imu, 3)``
  at their peak in :func:`ftnav.sim.imu.simulate_imu_errors` (outputs, Markov drifts,
  one temporary), the fault-free twin and the concatenated batch; the results of every
  method, local tracks ``(2b, K, N, 3)`` included; every run's results are held until
  the batches are merged (a second copy); the true flight
  (:func:`ftnav.sim.trajectory.generate`) once;
* after the run: the metrics' temporaries, and with ``save_estimates`` the stacked
  arrays of ``estimates.nc``.

``workers`` worker processes (:mod:`ftnav.parallel`) each hold one task at a time: an
integrated batch (its simulation and results; batches are then no larger than an
even share of the runs), or for a linear run its own copy of the simulation for a
group of methods; the parent holds every result received, and merges the batches.
The estimate counts the arrays of the run only, not the interpreter and its
libraries (about 0.2 GiB resident before the run starts, already counted as used by
the operating system).  ``tests/reference/test_memory_estimate.py`` compares it with
the peak memory :mod:`tracemalloc` traces in a subprocess running the same command.

:func:`available_memory_bytes` is what the operating system can still give
(``MemAvailable`` on Linux, bounded by a cgroup limit).  :func:`kernels_compiled` and
:func:`mark_kernels_compiled` tell whether numba's on-disk cache already holds the
compiled kernels (``ftnav`` says so when a first run compiles them).
"""

from __future__ import annotations

import hashlib
import os
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypedDict, Unpack

from ftnav.eval.batching import PARALLEL_MIN_WORK, chunk_runs
from ftnav.fusion.guard import pull_blocks
from ftnav.model.scenario import InsScenario

if TYPE_CHECKING:
    from ftnav.fusion.config import Detector
    from ftnav.model.flight import Profile
    from ftnav.model.imu import ImuErrors
    from ftnav.model.scenario import Scenario

__all__ = [
    "available_memory_bytes",
    "check_memory",
    "format_bytes",
    "kernels_compiled",
    "mark_kernels_compiled",
    "max_runs_within",
    "run_memory_bytes",
    "trajectory_memory_bytes",
]

_F8 = 8  # bytes of a float64
#: (samples of the largest segment) x this: transient bytes per IMU sample of
#: :func:`ftnav.sim.trajectory.generate` (Gauss-Legendre nodes, DCMs, rates at the nodes)
_GENERATE_TRANSIENT = 1900
#: bytes per IMU sample of a :class:`~ftnav.sim.trajectory.Trajectory` (t, p, v, euler,
#: segment, dtheta, dv)
_TRAJECTORY_SAMPLE = 17 * _F8
#: copies of one local filter's (n, n) covariance alive within an epoch per run
#: (state, prior, posterior, gain and update temporaries, fused values)
_STATE_COPIES = 12
#: copies of the guard's pulls alive at once (the state, an epoch's mapped blocks, the
#: alternative's)
_GUARD_COPIES = 3


def format_bytes(n: float) -> str:
    """``23.4 GiB``, ``512 MiB``: binary units, three significant digits at most."""
    for unit, scale in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= scale:
            v = n / scale
            return f"{v:.1f} {unit}" if v < 100 else f"{v:.0f} {unit}"
    return f"{int(n)} B"


# ----------------------------------------------------------------------- memory estimate


class _Method(Protocol):
    """What the estimate reads of a method's configuration (:mod:`ftnav.fusion.config`)."""

    @property
    def architecture(self) -> str: ...

    @property
    def detector(self) -> Detector: ...


class _RunOptions(TypedDict, total=False):
    """The keyword options of :func:`run_memory_bytes` that :func:`max_runs_within` passes."""

    workers: int
    fault_free: bool
    save_estimates: bool
    chunk: int | None


def _result_bytes(
    method: _Method, B: int, K: int, nc: int, N: int, dims_sum: int, local: bool
) -> int:
    """Bytes of one method's per-epoch results over B runs (:class:`MethodResult`)."""
    floats = 2 * nc + 1 + dims_sum  # x, P_diag, nees, R_hat
    flags = 0
    if method.architecture == "federated":
        floats += N  # beta
    if method.detector.kind != "none":
        floats += 2 * N  # statistic, threshold
        flags += 2 * N  # raw, flag (bool)
    if local and method.architecture != "centralized":
        floats += 3 * N  # local position tracks (integrated runs)
    return B * K * (floats * _F8 + flags) + B * N * _F8


def _guard_bytes(methods: Sequence[Any], B: int, dt: float, aids: int, n: int) -> int:
    """Bytes of the isolation guard's tracked pulls over B runs (:mod:`ftnav.fusion.guard`,
    :func:`ftnav.fdi.separation.init_pulls`): per guarded method, each aid's J blocks of
    a vector and an n × n matrix, its rotation map, and the copies an epoch's update
    makes (left out before: an integrated campaign took about twice its estimate)."""
    total = 0
    for me in methods:
        g = getattr(me, "guard", None)
        if g is None or me.detector.kind in ("none", "oracle"):
            continue
        J = pull_blocks(g, dt)[3]
        total += _GUARD_COPIES * B * aids * (J + 2) * (n * n + n) * _F8
    return total


def _state_bytes(B: int, local_sizes: list[int]) -> int:
    """Bytes of the filters' state and one epoch's temporaries over B runs."""
    return B * _STATE_COPIES * _F8 * sum(n * n + n for n in local_sizes)


def _linear_bytes(
    sc: Scenario, runs: int, workers: int, fault_free: bool, save_estimates: bool
) -> int:
    K, B, N = int(sc.steps), int(runs), len(sc.sensors)
    nc = len(sc.model.states)
    dims = [int(s.dim) for s in sc.sensors]
    private = [0 if s.private is None else len(s.private.names) for s in sc.sensors]
    n = nc + sum(private)
    m = sum(dims)
    twin = fault_free and bool(sc.faults)
    # simulate(): kept data (truth, z, noise_free, available) and its peak
    data = B * K * ((n + 2 * m) * _F8 + N)
    draws = B * (n + K * n + K * m) * _F8
    temporaries = 2 * B * K * max(dims) * _F8
    one = data + draws + temporaries
    if twin:
        # sim kept while sim_ff is drawn; then sim, sim_ff and both (2B, oracle per run)
        simulation = max(data + one, 4 * data + 2 * K * B * N)
        held = 4 * data + 2 * K * B * N
        after = 2 * data
    else:
        simulation = one
        held = after = data
    Bf = 2 * B if twin else B
    results = sum(_result_bytes(me, Bf, K, nc, N, m, False) for me in sc.methods)
    state = _state_bytes(Bf, [nc + p for p in private])
    transient = 4 * B * K * nc * _F8  # errors and windows of the metrics, figures
    if save_estimates:
        M = len(sc.methods)
        per_condition = 2 * M * B * K * nc * _F8 + M * B * K * N * (_F8 + 1)
        # stacked into the dataset, then each variable and the truth copied big-endian
        # (netCDF-3) while written: about three times the stacked arrays (measured)
        transient = max(transient, 3 * per_condition + 2 * B * K * nc * _F8)
    if workers > 1 and len(sc.methods) * K >= PARALLEL_MIN_WORK:
        # run_scenario: the parent simulates and keeps both conditions, each worker
        # simulates its own copy for its group of methods (3 groups per worker, one at a
        # time); the parent receives every result
        group = -(-results // min(len(sc.methods), 3 * workers))
        worker = max(simulation, held + group + state)
        return after + results + workers * worker + transient
    return max(simulation, held + results + state, after + results + transient)


def _imu_arrays(imu: ImuErrors) -> int:
    """(b, n_imu, 3) arrays alive at the peak of :func:`simulate_imu_errors`."""
    import numpy as np

    markov = int(bool(np.any(imu.gyro_markov_sd))) + int(bool(np.any(imu.accel_markov_sd)))
    return 2 + markov + 1  # dtheta, dv, Markov drifts, one temporary (lfilter, scale terms)


def _integrated_chunk_bytes(sc: InsScenario, b: int, twin: bool) -> tuple[int, int, int]:
    """(simulation peak, held data, per-epoch temporaries) of one batch of b runs."""
    K, N = int(sc.steps), len(sc.aids)
    n_imu = sc.samples_per_epoch * K
    A = b * n_imu * 3 * _F8  # one (b, n_imu, 3) array
    dims = sum(int(a.dim) for a in sc.aids)
    # simulate_ins() keeps dtheta, dv, the Markov truth at the epochs, raw outputs, masks
    data = 2 * A + b * K * ((6 + dims) * _F8 + N)
    one = data - 2 * A + _imu_arrays(sc.imu) * A + n_imu * (_F8 + 1)
    if twin:
        simulation = max(data + one, 4 * data)  # data kept, twin drawn; then concatenated
        held = 3 * data  # data and the concatenated batch
    else:
        simulation = one
        held = data
    Bf = 2 * b if twin else b
    n = int(sc.error_model.n)
    sizes = [n + (0 if a.sensor.private is None else len(a.sensor.private.names)) for a in sc.aids]
    # every method's SINS, Φ, Q and H per run, plus each method's filters
    M = max(1, len(sc.methods))
    temporaries = M * _state_bytes(Bf, sizes) + M * Bf * 4 * n * n * _F8
    temporaries += _guard_bytes(sc.methods, Bf, float(sc.dt), N, max(sizes, default=n))
    return simulation, held, temporaries


def _integrated_bytes(
    sc: InsScenario,
    runs: int,
    workers: int,
    fault_free: bool,
    save_estimates: bool,
    chunk: int | None,
) -> int:
    twin = fault_free and bool(sc.faults)
    b = min(int(runs), chunk_runs(sc, twin) if chunk is None else int(chunk))
    if workers > 1:  # as run_ins_scenario: no more runs per batch than share the workers
        b = min(b, -(-runs // workers))
    K, N = int(sc.steps), len(sc.aids)
    dims = sum(int(a.dim) for a in sc.aids)
    Bf_total = 2 * runs if twin else runs
    results = sum(_result_bytes(me, Bf_total, K, 9, N, dims, True) for me in sc.methods)
    zeros = (2 if twin else 1) * runs * K * 9 * _F8
    Bf = 2 * b if twin else b
    chunk_results = sum(_result_bytes(me, Bf, K, 9, N, dims, True) for me in sc.methods)
    simulation, held, temporaries = _integrated_chunk_bytes(sc, b, twin)
    per_batch = max(simulation, held + chunk_results + temporaries)
    transient = 4 * runs * K * 11 * _F8  # metrics: errors, windows, position norms
    if save_estimates:
        M = len(sc.methods)
        per_condition = 2 * M * runs * K * 9 * _F8 + M * runs * K * N * (_F8 + 1)
        transient = max(transient, 3 * per_condition + 2 * runs * K * 9 * _F8)
    merged = runs > b or workers > 1
    if merged:
        # batches run one after the other (or one per worker); every result is held,
        # then concatenated into a second copy
        run_peak = max(workers, 1) * per_batch + results
        final = 2 * results + zeros
        after = results + zeros + transient
    else:
        run_peak = per_batch + results - chunk_results
        final = held + results + zeros
        after = held + results + zeros + transient
    kept, generating = _flight_bytes(sc.profile)
    return max(generating, kept + max(run_peak, final, after))


def _flight_bytes(profile: Profile) -> tuple[int, int]:
    """The true flight of :func:`ftnav.sim.trajectory.generate`: (kept, peak while generated)."""
    samples = round(profile.duration * profile.imu_rate)
    largest = max(round(s.duration * profile.imu_rate) for s in profile.segments)
    kept = samples * _TRAJECTORY_SAMPLE
    return kept, kept + largest * _GENERATE_TRANSIENT


def run_memory_bytes(
    scenario: Scenario | InsScenario,
    runs: int,
    *,
    workers: int = 1,
    fault_free: bool = True,
    save_estimates: bool = False,
    chunk: int | None = None,
) -> int:
    """Estimated peak memory (bytes) of running ``scenario`` over ``runs`` Monte Carlo runs.

    Parameters
    ----------
    scenario : :class:`ftnav.model.scenario.Scenario` or, ``kind == "integrated"``,
        :class:`ftnav.model.ins_scenario.InsScenario`.
    runs : number of Monte Carlo runs (>= 1).
    workers : worker processes, each holding one batch of runs at a time (>= 1).
    fault_free : the fault-free twin runs beside the faults (what ``ftnav run`` does).
    save_estimates : ``estimates.nc`` is written after the run.
    chunk : runs per batch of an integrated run (default
        :func:`ftnav.eval.batching.chunk_runs`).

    Returns
    -------
    bytes : the arrays of the run at its peak (module docstring), within a factor of
        about 1.5 of the measured peak (0.97-1.13 on the test's runs); a test with a
        measured oracle checks the factor.  A second flight (``test_profile``)
        runs after the first, whose results stay held.
    """
    runs, workers = int(runs), int(workers)
    if runs < 1:
        raise ValueError(f"runs: must be >= 1, got {runs}")
    if workers < 1:
        raise ValueError(f"workers: must be >= 1, got {workers}")
    if not isinstance(scenario, InsScenario):  # kind "integrated"
        return _linear_bytes(scenario, runs, workers, fault_free, save_estimates)
    total = _integrated_bytes(scenario, runs, workers, fault_free, save_estimates, chunk)
    if scenario.test_profile is not None:
        from dataclasses import replace

        second = replace(scenario, profile=scenario.test_profile, test_profile=None)
        total += _integrated_bytes(second, runs, workers, fault_free, save_estimates, chunk)
    return total


def max_runs_within(
    scenario: Scenario | InsScenario, budget: float, **options: Unpack[_RunOptions]
) -> int:
    """The most runs whose :func:`run_memory_bytes` stays within ``budget`` bytes (0: none)."""
    if run_memory_bytes(scenario, 1, **options) > budget:
        return 0
    lo, hi = 1, 2
    while run_memory_bytes(scenario, hi, **options) <= budget:
        lo, hi = hi, 2 * hi
        if hi > 1 << 62:
            return lo
    while hi - lo > 1:  # run_memory_bytes grows with runs
        mid = (lo + hi) // 2
        if run_memory_bytes(scenario, mid, **options) <= budget:
            lo = mid
        else:
            hi = mid
    return lo


def trajectory_memory_bytes(profile: Profile, imu_errors: bool) -> int:
    """Estimated peak memory (bytes) of ``ftnav trajectory`` (one flight, one IMU run).

    The flight at its peak (:func:`ftnav.sim.trajectory.generate`), then with IMU
    errors the corrupted increments of one run at the peak of
    :func:`~ftnav.sim.imu.simulate_imu_errors` (at most five (n, 3) arrays), and the
    text of the CSV files' rows.
    """
    samples = round(profile.duration * profile.imu_rate)
    errors = 5 * samples * 3 * _F8 if imu_errors else 0
    kept, generating = _flight_bytes(profile)
    return max(generating, kept + errors + samples * 3 * _F8)


# ------------------------------------------------------------------- available memory


def _cgroup_headroom() -> int | None:
    """Bytes a cgroup v2 memory limit leaves this process (None without a limit)."""
    root = Path("/sys/fs/cgroup")
    try:
        limit = (root / "memory.max").read_text().strip()
        if limit == "max":
            return None
        used = int((root / "memory.current").read_text().strip())
        return max(0, int(limit) - used)
    except (OSError, ValueError):
        return None


def check_memory(scenario: Scenario | InsScenario, runs: int, **options: Any) -> None:
    """Refuse (ValueError naming ``runs``, or the run's length when one run does not fit)
    a campaign whose estimated peak memory (:func:`run_memory_bytes`) exceeds what the
    machine has available; nothing where that is unknown."""
    available = available_memory_bytes()
    if available is None:
        return
    need = run_memory_bytes(scenario, runs, **options)
    if need <= available:
        return
    have = f"more than the {format_bytes(available)} available"
    fit = max_runs_within(scenario, available, **options)
    if fit == 0:
        field = "filter.duration_s" if isinstance(scenario, InsScenario) else "steps"
        one = run_memory_bytes(scenario, 1, **options)
        raise ValueError(
            f"{field}: one run of {scenario.name} ({scenario.steps} epochs of "
            f"{scenario.dt:g} s) needs about {format_bytes(one)}, {have}"
        )
    raise ValueError(
        f"runs: {runs} runs of {scenario.name} need about {format_bytes(need)}, {have} "
        f"(at most {fit} would fit)"
    )


def available_memory_bytes() -> int | None:
    """Memory the operating system can still give a process (bytes), or None if unknown.

    Linux: ``MemAvailable`` of ``/proc/meminfo`` (free memory plus the page cache and
    reclaimable memory that can be dropped), bounded by the headroom of a cgroup v2
    memory limit (containers).  Elsewhere: ``os.sysconf`` free physical pages.
    """
    value = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    value = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        value = None
    if value is None:
        try:
            value = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (AttributeError, ValueError, OSError):
            value = None
        if value is not None and value <= 0:
            value = None
    headroom = _cgroup_headroom()
    if headroom is not None:
        value = headroom if value is None else min(value, headroom)
    return value


# --------------------------------------------------------------- compiled-kernel cache


_NUMBA_IMPORT = re.compile(r"^(import numba|from numba)", re.MULTILINE)


def _kernel_sources() -> list[Path]:
    """The package's modules with cached numba kernels (numba imported, ``cache=True``)."""
    root = Path(__file__).resolve().parents[1]
    found = []
    for path in sorted(root.rglob("*.py")):
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            continue
        if "cache=True" in text and _NUMBA_IMPORT.search(text):
            found.append(path)
    return found


def _marker_folder() -> Path:
    """Where numba keeps its cache: ``NUMBA_CACHE_DIR``, else the package's ``__pycache__``."""
    cache = os.environ.get("NUMBA_CACHE_DIR")
    return Path(cache) if cache else Path(__file__).resolve().parents[1] / "__pycache__"


def _marker(kind: str) -> Path:
    """The marker file that records compiled kernels for ``kind`` of run.

    Its name hashes what invalidates numba's cache: the kernel modules' paths, sizes
    and modification times, the numba and Python versions, and the cache folder,
    where it lives (:func:`_marker_folder`).
    """
    import numba

    folder = _marker_folder()
    h = hashlib.sha256()
    h.update(f"{kind}|{numba.__version__}|{sys.version}|{folder}".encode())
    for path in _kernel_sources():
        st = path.stat()
        h.update(f"|{path}:{st.st_size}:{st.st_mtime_ns}".encode())
    return folder / f"ftnav-kernels-{kind}-{h.hexdigest()[:16]}.done"


def kernels_compiled(kind: str) -> bool:
    """Whether a run of ``kind`` (e.g. ``"linear"``) found numba's kernels compiled on disk.

    True once :func:`mark_kernels_compiled` was called after such a run with the
    same kernel sources, numba, Python and cache folder; a kernel module edited since
    (numba then compiles it again) makes it False.  True when the check fails or the
    marker could not be written (a read-only install): the message it drives would
    otherwise repeat on every run.
    """
    try:
        path = _marker(kind)
        if path.exists():
            return True
        folder = path.parent
        while not folder.exists():
            folder = folder.parent
        return not os.access(folder, os.W_OK)
    except (OSError, ImportError):
        return True


def mark_kernels_compiled(kind: str) -> None:
    """Record that a run of ``kind`` compiled (or loaded) its kernels; silent on failure."""
    try:
        path = _marker(kind)
        path.parent.mkdir(parents=True, exist_ok=True)
        for old in path.parent.glob(f"ftnav-kernels-{kind}-*.done"):
            old.unlink(missing_ok=True)
        path.touch()
    except (OSError, ImportError):
        pass
