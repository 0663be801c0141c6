"""Coarse-grained parallelism: whole tasks (groups of methods, chunks of runs) in processes.

Each task is minutes to seconds of independent work: a group of methods over every
run, or a chunk of runs under every method.  A worker process computes a task from
its own copy of the scenario and the root seed (it simulates its own runs, so no
simulated data crosses a process boundary) and sends back the per-epoch results.
There is no barrier inside a task, so a core taken by another process slows a run
at most in proportion, unlike a thread pool entered at every epoch (every call then
waits for its slowest, descheduled thread: a 20x collapse seen on a busy 2-core
machine, issue 13).  Runs are independent and each task runs the same serial
compiled code, so the results do not depend on the number of workers (tested bit
for bit in ``tests/equivalence/test_workers.py``).

Worker processes are started with ``spawn`` (a fresh interpreter: no inherited
thread state); as with :mod:`multiprocessing`, a script that asks for workers must
guard its top level with ``if __name__ == "__main__":`` (the ``ftnav`` command does).
The number of workers is the ``workers`` argument, else the environment variable
``FTNAV_WORKERS``, else the CPUs this process may run on.  Inside a worker
``FTNAV_WORKERS`` is 1, so nothing nests a second level of parallelism (the thread
pool of :func:`ftnav.sim.imu.simulate_imu_errors` included).  This module uses the
standard library only (a worker sets NumPy's error state when it starts), so every
layer may import it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import multiprocessing
import os
import queue
import re
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

from threadpoolctl import threadpool_info, threadpool_limits

__all__ = [
    "ClusterError",
    "available_cpus",
    "blas_threads",
    "check_scheduler_address",
    "default_workers",
    "run_on_cluster",
    "run_tasks",
    "signals_held",
    "split_even",
]

T = TypeVar("T")
R = TypeVar("R")

#: seconds between two progress messages of a worker
_FLUSH_S = 0.25


def available_cpus() -> int:
    """CPUs this process may run on (its affinity mask where the OS has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def default_workers() -> int:
    """``FTNAV_WORKERS`` if set (an integer ≥ 1), else :func:`available_cpus`.

    Raises
    ------
    ValueError
        ``"FTNAV_WORKERS: ..."`` for a value that is not an integer ≥ 1.
    """
    text = os.environ.get("FTNAV_WORKERS")
    if text is None or not text.strip():
        return available_cpus()
    try:
        value = int(text)
    except ValueError:
        raise ValueError(f"FTNAV_WORKERS: expected an integer >= 1, got {text!r}") from None
    if value < 1:
        raise ValueError(f"FTNAV_WORKERS: expected an integer >= 1, got {value}")
    return value


def split_even(items: Sequence[T], parts: int) -> list[list[T]]:
    """``items`` dealt round-robin into ``min(parts, len(items))`` non-empty groups."""
    parts = max(1, min(parts, len(items)))
    return [list(items[i::parts]) for i in range(parts)]


# ----------------------------------------------------------------------- worker side
_progress_queue: Any = None


#: seconds between two checks of a worker that its parent is alive
_WATCH_S = 0.5


#: environment variable that tells a starting worker its parent's process id
PARENT_PID = "FTNAV_PARENT_PID"
_watching = False


def end_with_parent() -> None:
    """End this worker process at once when its parent dies (SIGKILL included).

    Called as soon as a worker starts (by ``import ftnav``, when :data:`PARENT_PID` is
    set; the spawned interpreter imports ftnav first thing), so a parent killed while
    its workers are still importing leaves none behind.  Linux: the kernel sends
    SIGKILL to this process when its parent dies (``PR_SET_PDEATHSIG``), whatever it
    is computing.  Everywhere, a daemon thread also checks every :data:`_WATCH_S` s
    that the parent is still the one that started it (an orphan is re-parented) and
    ends the process if not.  Nothing is done outside a worker.
    """
    global _watching
    text = os.environ.pop(PARENT_PID, "")
    if _watching or not text.isdigit():
        return
    parent = int(text)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):  # pragma: no cover - no prctl
            pass
    if os.getppid() != parent:  # died before the line above
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(_WATCH_S)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="ftnav-parent-watch").start()
    _watching = True


def blas_threads() -> int | None:
    """The BLAS threads of this process (the most of its loaded BLAS libraries), or
    None where none is loaded."""
    counts = [int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
    return max(counts) if counts else None


#: the workers' BLAS thread limit (kept: the limit lasts while it is referenced)
_blas_limit: Any = None


def _init_worker(q, blas: int | None = None) -> None:
    global _progress_queue, _blas_limit
    _progress_queue = q
    os.environ["FTNAV_WORKERS"] = "1"
    # Ctrl-C reaches the whole process group: the parent alone decides, and ends the
    # workers itself (run_tasks)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # as in the ftnav command: a diverged method is reported by the engine, not as
    # NumPy's overflow warnings (NumPy is loaded by the tasks anyway)
    import numpy

    numpy.seterr(all="ignore")
    # the parent's BLAS thread count, whatever this process's environment says: a sum's
    # order depends on it (Dask's ``LocalCluster`` sets ``OPENBLAS_NUM_THREADS=1`` in
    # the process that starts it, and workers spawned after that, with one thread
    # beside a parent with two, differed from it in the last bits)
    if blas is not None:
        _blas_limit = threadpool_limits(limits=blas, user_api="blas")
    end_with_parent()  # done already by `import ftnav`; here in case it was not


class _Reporter:
    """A worker's progress callback: counts and sends at most every :data:`_FLUSH_S`."""

    def __init__(self, q):
        self.q = q
        self.pending = 0
        self.last = time.monotonic()

    def __call__(self, n: int = 1) -> None:
        self.pending += n
        now = time.monotonic()
        if now - self.last >= _FLUSH_S:
            self.flush()
            self.last = now

    def flush(self) -> None:
        if self.pending:
            self.q.put(self.pending)
            self.pending = 0


def _call(fn: Callable[..., R], task) -> R:
    reporter = _Reporter(_progress_queue) if _progress_queue is not None else None
    try:
        return fn(task, reporter)
    finally:
        if reporter is not None:
            reporter.flush()


# ----------------------------------------------------------------------- parent side
def _end_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel the queued tasks and kill the worker processes of ``pool``.

    ``ProcessPoolExecutor`` has no public way to stop a running task before Python
    3.14 (``terminate_workers``); its process table ``_processes`` is used instead.
    """
    processes = list((getattr(pool, "_processes", None) or {}).values())  # shutdown drops it
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        with contextlib.suppress(OSError, ValueError):
            p.kill()
    for p in processes:
        with contextlib.suppress(OSError, ValueError, AssertionError):
            p.join(timeout=5)


def run_tasks(
    fn: Callable[[T, Callable[[int], None] | None], R],
    tasks: Sequence[T],
    workers: int,
    progress: Callable[[int], None] | None = None,
    scheduler: str | None = None,
    units: Sequence[int] | None = None,
) -> list[R]:
    """``[fn(task, progress) for task in tasks]``, in up to ``workers`` processes, or on
    the Dask cluster at ``scheduler`` (:func:`run_on_cluster`).

    Parameters
    ----------
    fn : a module-level function ``fn(task, progress)`` (picklable by reference);
        ``progress(n)`` reports n units of work done, or is None.
    tasks : picklable task descriptions.
    workers : processes to use; 1 (or a single task) runs in this process.
    progress : called in this process with the units the tasks report.
    units : the units each task reports in all: on a cluster, where the tasks' own
        reports stay on the workers, ``progress`` is given a task's units when its
        result arrives (None: not fed there).

    Returns
    -------
    list : the results in the order of ``tasks``.  An exception of a task is raised
        here, with its own type and message.
    """
    if scheduler is not None:
        return run_on_cluster(fn, tasks, scheduler, progress, units)
    if workers <= 1 or len(tasks) <= 1:
        return [fn(t, progress) for t in tasks]
    ctx = multiprocessing.get_context("spawn")
    q = ctx.Queue() if progress is not None else None
    stop = threading.Event()

    def drain() -> None:
        while not stop.is_set() or not q.empty():
            try:
                progress(q.get(timeout=0.1))
            except queue.Empty:
                continue

    reader = None
    if q is not None:
        reader = threading.Thread(target=drain, daemon=True)
        reader.start()
    failed = False
    try:
        # the workers are started with SIGINT/SIGTERM held back: a signal arriving while
        # a worker is being spawned would leave it outside the pool's table, alive
        with signals_held(), _environment(PARENT_PID, str(os.getpid())):
            pool = ProcessPoolExecutor(
                min(workers, len(tasks)),
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(q, blas_threads()),
            )
            futures = [pool.submit(_call, fn, t) for t in tasks]
        with pool:
            try:
                return [f.result() for f in futures]
            except BaseException:
                # an error, Ctrl-C or SIGTERM: the other tasks' work is lost anyway,
                # so the workers are ended now rather than waited for
                failed = True
                _end_workers(pool)
                raise
    finally:
        stop.set()
        if reader is not None:  # a killed worker may have left half a message: no wait
            reader.join(timeout=1.0 if failed else None)


def _on_worker(fn: Callable[[T, Callable[[int], None] | None], R], task: T) -> R:
    """One task on a Dask worker: nothing nests a second level of parallelism."""
    os.environ["FTNAV_WORKERS"] = "1"
    return fn(task, None)


def run_on_cluster(
    fn: Callable[[T, Callable[[int], None] | None], R],
    tasks: Sequence[T],
    scheduler: str,
    progress: Callable[[int], None] | None = None,
    units: Sequence[int] | None = None,
) -> list[R]:
    """The tasks on an existing ``dask.distributed`` cluster (``tcp://HOST:PORT``).

    Each task is one Dask task (submitted with a key of its own, ``pure=False``); Dask
    recomputes a task whose worker is lost before its result reached this process, so a
    lost worker costs time, never a result, and no task is counted twice (the results
    are gathered by task, in order).  The tasks' per-epoch reports stay on the workers:
    ``progress`` is given ``units[i]`` as task i's result arrives (in the order they
    finish; a recomputed task once).  Dask moves tasks and results
    between this process and its workers by pickle: run it on workers you trust (your
    own machines), as with any Dask cluster; nothing a user's file names is unpickled.
    Dask is imported here only (the ``ftnav[cluster]`` extra).
    """
    try:
        from distributed import Client
    except ImportError:
        raise ValueError(
            "--scheduler: Dask is not installed (pip install 'ftnav[cluster]')"
        ) from None
    check_scheduler_address(scheduler)
    _answers_as_dask(scheduler)
    with _quiet_dask():
        try:
            client = Client(scheduler, timeout=10, set_as_default=False)
        except (OSError, ValueError, MemoryError) as exc:  # MemoryError: not Dask's protocol
            raise ClusterError(
                f"--scheduler: no Dask scheduler at {scheduler} "
                f"({type(exc).__name__}: {str(exc)[:120] or 'no answer'})"
            ) from None
        with client:
            try:
                futures = [client.submit(_on_worker, fn, t, pure=False) for t in tasks]
                if progress is not None and units is not None:
                    from distributed import as_completed

                    order = {f.key: i for i, f in enumerate(futures)}
                    with client.as_current():  # as_completed follows the current client
                        for f in as_completed(futures):
                            progress(units[order[f.key]])
                return list(client.gather(futures))
            except (
                TimeoutError,
                asyncio.CancelledError,
                concurrent.futures.CancelledError,
                OSError,
            ) as exc:
                # (distributed's CommClosedError is an OSError, its FutureCancelledError
                # a concurrent.futures CancelledError: the scheduler went away)
                raise ClusterError(
                    f"--scheduler: lost the Dask scheduler at {scheduler} during the "
                    f"campaign ({type(exc).__name__}); nothing written"
                ) from None


class ClusterError(Exception):
    """The Dask cluster failed: no scheduler at the address, or lost during a campaign
    (the command line's exit status 4, one line; nothing written)."""


#: a Dask scheduler's address: ``tcp://HOST:PORT`` (or ``tls://``)
_ADDRESS = re.compile(r"^(tcp|tls)://[^/:\s]+:(\d{1,5})$")


def check_scheduler_address(address: str) -> None:
    """ValueError naming ``--scheduler`` unless ``address`` is ``tcp://HOST:PORT`` or
    ``tls://HOST:PORT`` (an ``http://`` address or one without its port kept Dask's
    half-built client 20 s in its destructor, then ended in an internal error)."""
    m = _ADDRESS.match(address or "")
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise ValueError(
            f"--scheduler: {address!r} is no Dask scheduler address (tcp://HOST:PORT, as "
            "'dask scheduler' prints it)"
        )


#: seconds a Dask scheduler has to accept the connection and send its handshake
ANSWER_S = 10.0


def _answers_as_dask(address: str) -> None:
    """ClusterError unless something at ``address`` accepts a connection and, over
    ``tcp://``, speaks first within ``timeout`` seconds, as a Dask scheduler does (its
    handshake).  A server of another kind there (a web server waits for a request) kept
    Dask's client waiting for ever.  Over ``tls://`` the client speaks first: only the
    connection is checked.  ``timeout`` is :data:`ANSWER_S`."""
    timeout = ANSWER_S
    m = _ADDRESS.match(address)
    assert m is not None  # checked by check_scheduler_address
    host = address.split("://", 1)[1].rsplit(":", 1)[0].strip("[]")
    try:
        with socket.create_connection((host, int(m.group(2))), timeout=timeout) as sock:
            if m.group(1) == "tcp":
                sock.settimeout(timeout)
                if not sock.recv(1):
                    raise ConnectionResetError("closed without a word")
    except TimeoutError:
        raise ClusterError(
            f"--scheduler: no Dask scheduler at {address} (no answer within {timeout:g} s: "
            "another kind of server, or none)"
        ) from None
    except OSError as exc:
        raise ClusterError(
            f"--scheduler: no Dask scheduler at {address} "
            f"({type(exc).__name__}: {str(exc)[:120] or 'no answer'})"
        ) from None


@contextlib.contextmanager
def _quiet_dask() -> Iterator[None]:
    """Dask's own logging above CRITICAL during the block: a lost scheduler printed
    about 25 lines of tracebacks before ftnav's one-line message."""
    import logging

    loggers = [logging.getLogger(n) for n in ("distributed", "tornado", "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


@contextlib.contextmanager
def _environment(name: str, value: str) -> Iterator[None]:
    """``os.environ[name] = value`` during the block (the spawned workers inherit it)."""
    old = os.environ.get(name)
    os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


@contextlib.contextmanager
def signals_held() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP held back during the block, delivered after it.

    Only in the main thread (where Python runs signal handlers) and where the OS has
    ``pthread_sigmask``; elsewhere the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread() or not hasattr(
        signal, "pthread_sigmask"
    ):
        yield
        return
    held = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
