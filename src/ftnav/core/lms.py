"""Constrained Widrow-Hoff (LMS) training of the neuron fusion centre (spec §5.1-5.5).

One linear neuron per (fused scalar state, fault configuration) pair computes
``y = Σ_i w_i u_i`` from the N local estimates ``u`` (spec §5.2).  Its weights
approximate the optimal linear fusion ``D`` of spec §5.1, which satisfies
``Σ_i D_i = 1``; the seed additionally keeps ``w >= 0`` (a heuristic restriction,
spec §5.1 [M]).  Training (spec §5.3) visits the M samples in a shuffled order,
epoch after epoch, and for each sample applies

    ε = t − wᵀu,   w ← w + η ε u,   then projects w back onto the constraint set

with one of two projections:

* ``"simplex"``: the Euclidean projection onto ``{w >= 0, Σw = 1}``
  (:func:`project_simplex`);
* ``"seed"``: the paper's clip-and-renormalize rule (:func:`clip_renormalize`).

Every function is batched over a leading "neuron" axis ``J``: one neuron is one
(fused state, fault configuration) pair, and all neurons of a batch share the
same sample count ``M`` and input count ``N``.

Step size and schedule
----------------------
* ``step="lms"``: ``η = μ / tr R`` with ``R = (1/M) Σ_m u⁽ᵐ⁾u⁽ᵐ⁾ᵀ`` the sample
  second-moment matrix of that neuron's inputs.  Because ``tr R >= λ_max(R)``,
  any ``μ < 2`` satisfies the spec's bound ``η < 2/λ_max`` (§5.3).  On raw,
  uncentred inputs ``tr R`` contains the squared offset, so η becomes tiny
  automatically (which is why the spec requires centred inputs).
* ``step="nlms"``: ``η_k = μ / (1e-12 + ‖u⁽ᵏ⁾‖²)`` per sample (normalized LMS).

With ``decay=True`` (default) the step of epoch ``e`` (0-based) is divided by
``1 + e``.  A constant step leaves the weights jittering around the minimiser
with a spread of order ``sqrt(η σ_ε² / 2)`` (LMS misadjustment); the decaying
(stochastic-approximation, Robbins-Monro) schedule shrinks that spread epoch
after epoch, so the projected iteration converges to the *constrained
least-squares* minimiser on the training samples.  Which least-squares problem
depends on the step rule:

* ``"lms"`` (a common η for all samples of a neuron) converges to the
  unweighted minimiser of ``Σ_m (t⁽ᵐ⁾ − wᵀu⁽ᵐ⁾)²`` over the constraint set;
* ``"nlms"`` (η_k ∝ 1/‖u⁽ᵏ⁾‖²) converges to the minimiser of the *weighted*
  sum ``Σ_m (t⁽ᵐ⁾ − wᵀu⁽ᵐ⁾)² / (1e-12 + ‖u⁽ᵐ⁾‖²)``, which in general differs.

The two projections agree while no weight is clipped (on inputs centred by
their mean, ``Σ_i ũ_i = 0``, so an update stays on ``Σw = 1`` and both
projections are the identity).  When a non-negativity constraint is active they
differ: the Euclidean projection converges to the constrained least-squares
minimiser (KKT: equal gradient components on the free weights), whereas the
seed rule's renormalization shrinks the free weights by a common *factor*, and
its limit satisfies ``d_i ∝ w_i`` for the mean update ``d = E[ε u]`` on the free
weights instead, whatever the step size (tested in
``tests/reference/test_lms_slsqp.py``).

Because both projections bound the weights (``0 <= w_i <= 1``), training cannot
diverge for finite inputs, even for a large μ.

Training stops when the largest change of any weight over one epoch,
``max |w_end − w_start|`` over all neurons, falls below ``tol`` (spec: 1e-6), or
after ``epochs`` epochs (spec: 200).  The sample order of each epoch is one
permutation drawn from the caller's ``numpy.random.Generator`` and shared by all
neurons, so a seed fixes the result bit for bit and a neuron's weights do not
depend on which other neurons share its batch.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np
import numpy.typing as npt

from ftnav.core.linalg import JitOptions
from ftnav.types import ArrayLike, BatchMatrix, BatchScalar, BatchVector, Vector

__all__ = ["LmsResult", "PROJECTIONS", "STEPS", "project_simplex", "clip_renormalize", "lms_train"]

#: projection rules applied after every update (spec §5.3)
PROJECTIONS = ("simplex", "seed")
#: step-size rules (spec §5.3)
STEPS = ("lms", "nlms")

#: compile options of every kernel (same as :mod:`ftnav.core.linalg`)
_JIT: JitOptions = dict(cache=True, nogil=True, error_model="numpy")

#: regularizer of the normalized-LMS step ``μ / (1e-12 + ‖u‖²)`` (spec §5.3)
_NLMS_EPS = 1e-12


class LmsResult(NamedTuple):
    """Result of :func:`lms_train`.

    Attributes
    ----------
    weights : ndarray, shape (J, N)
        Trained weights of each neuron (on the constraint set).
    epochs_run : int
        Number of epochs run.
    converged : bool
        True if training stopped because ``max |Δw| < tol`` over one epoch.
    min_weight : ndarray, shape (J,)
        Smallest weight seen after the projection of *any* update (>= 0 when the
        non-negativity constraint held throughout).
    max_sum_error : ndarray, shape (J,)
        Largest ``|Σ_i w_i − 1|`` seen after the projection of any update.
    mse : ndarray, shape (J,)
        Mean squared error ``mean_m (t⁽ᵐ⁾ − wᵀu⁽ᵐ⁾)²`` of the final weights on the
        training samples.
    """

    weights: BatchVector
    epochs_run: int
    converged: bool
    min_weight: BatchScalar
    max_sum_error: BatchScalar
    mse: BatchScalar


# --------------------------------------------------------------------------- projections


def project_simplex(w: ArrayLike) -> BatchVector:
    """Euclidean projection onto the probability simplex ``{w >= 0, Σ w = 1}``.

    Sort-based algorithm (Held, Wolfe & Crowder 1974; Duchi et al. 2008): with
    ``s`` the entries sorted in decreasing order and ``ρ`` the largest ``k`` with
    ``s_k − (Σ_{i<=k} s_i − 1)/k > 0``, the projection is
    ``max(w − θ, 0)`` with ``θ = (Σ_{i<=ρ} s_i − 1)/ρ``.

    Parameters
    ----------
    w : array_like, shape (..., N)
        Points to project; leading axes are batch axes.  N >= 1, entries finite.

    Returns
    -------
    ndarray, shape (..., N)
        The projections (float64).
    """
    v = np.asarray(w, dtype=np.float64)
    if v.ndim < 1 or v.shape[-1] < 1:
        raise ValueError(f"w: expected shape (..., N) with N >= 1, got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError("w: entries must be finite")
    N = v.shape[-1]
    s = -np.sort(-v, axis=-1)
    cs = np.cumsum(s, axis=-1) - 1.0
    k = np.arange(1, N + 1, dtype=np.float64)
    # ρ = the last k where the condition holds (it holds for k = 1 always; in exact
    # arithmetic it holds exactly for k = 1..ρ)
    cond = s - cs / k > 0.0
    rho = N - np.argmax(cond[..., ::-1], axis=-1)[..., None]
    theta = np.take_along_axis(cs, rho - 1, axis=-1) / rho
    projected: BatchVector = np.maximum(v - theta, 0.0)
    return projected


def clip_renormalize(w: ArrayLike) -> BatchVector:
    """The seed's projection (spec §5.3 ``"seed"``): clip negatives, then renormalize.

    ``w ← max(w, 0)``, then ``w ← w / Σ w``; where ``Σ w = 0`` (every entry was
    <= 0) the weights are reset to ``1/N``.

    Parameters
    ----------
    w : array_like, shape (..., N)
        Weights; leading axes are batch axes.  N >= 1, entries finite.

    Returns
    -------
    ndarray, shape (..., N)
        Non-negative weights summing to 1 (float64).
    """
    v = np.asarray(w, dtype=np.float64)
    if v.ndim < 1 or v.shape[-1] < 1:
        raise ValueError(f"w: expected shape (..., N) with N >= 1, got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError("w: entries must be finite")
    c = np.maximum(v, 0.0)
    s = c.sum(axis=-1, keepdims=True)
    zero = s == 0.0
    return np.where(zero, 1.0 / v.shape[-1], c / np.where(zero, 1.0, s))


# --------------------------------------------------------------------------- kernels


@numba.njit(**_JIT)
def _project_simplex_inplace(
    w: BatchVector, j: int, s: Vector
) -> None:  # pragma: no cover - compiled
    """Project row ``w[j] (N,)`` onto the simplex in place; ``s (N,)`` is scratch."""
    N = w.shape[1]
    for i in range(N):  # insertion sort, decreasing (N is small)
        x = w[j, i]
        p = i
        while p > 0 and s[p - 1] < x:
            s[p] = s[p - 1]
            p -= 1
        s[p] = x
    # θ = (Σ_{i<=ρ} s_i − 1)/ρ, ρ = largest k with s_k − (Σ_{i<=k} s_i − 1)/k > 0
    cs = 0.0
    theta = 0.0
    for k in range(N):
        cs += s[k]
        tk = (cs - 1.0) / (k + 1)
        if s[k] - tk > 0.0:
            theta = tk
    for i in range(N):
        x = w[j, i] - theta
        w[j, i] = x if x > 0.0 else 0.0


@numba.njit(**_JIT)
def _clip_renormalize_inplace(w: BatchVector, j: int) -> None:  # pragma: no cover - compiled
    """Seed rule in place on row ``w[j] (N,)``: clip at 0, divide by the sum (1/N if 0)."""
    N = w.shape[1]
    tot = 0.0
    for i in range(N):
        if not w[j, i] > 0.0:
            w[j, i] = 0.0
        tot += w[j, i]
    if tot == 0.0:
        for i in range(N):
            w[j, i] = 1.0 / N
    else:
        for i in range(N):
            w[j, i] /= tot


@numba.njit(**_JIT)
def _mean_sq_norm(U: BatchMatrix) -> BatchScalar:  # pragma: no cover - compiled
    """``tr R_j = (1/M) Σ_m ‖u⁽ᵐ⁾‖²`` for ``U (J, M, N)``, summed in a fixed order per neuron."""
    J, M, N = U.shape
    out = np.empty(J)
    for j in range(J):
        acc = 0.0
        for m in range(M):
            for i in range(N):
                acc += U[j, m, i] * U[j, m, i]
        out[j] = acc / M
    return out


@numba.njit(**_JIT)
def _lms_epoch(
    U: BatchMatrix,
    t: BatchVector,
    w: BatchVector,
    eta: BatchScalar,
    order: npt.NDArray[np.int64],
    simplex: bool,
    nlms: bool,
    min_w: BatchScalar,
    max_sum_err: BatchScalar,
) -> float:  # pragma: no cover
    """One epoch of projected LMS for every neuron; returns ``max |Δw|`` over all of them.

    ``U (J, M, N)``, ``t (J, M)``, ``w (J, N)`` updated in place, ``eta (J,)`` the
    step (``"lms"``) or the μ numerator (``"nlms"``) of this epoch, ``order (M,)``
    the sample order.  ``min_w``/``max_sum_err (J,)`` accumulate the constraint
    diagnostics after every projection.
    """
    J, M, N = U.shape
    w_start = np.empty(N)
    s = np.empty(N)
    dmax = 0.0
    for j in range(J):
        eta_j = eta[j]
        for i in range(N):
            w_start[i] = w[j, i]
        mw = min_w[j]
        se = max_sum_err[j]
        for k in range(M):
            m = order[k]
            y = 0.0
            for i in range(N):
                y += w[j, i] * U[j, m, i]
            eps = t[j, m] - y
            if nlms:
                nrm = 0.0
                for i in range(N):
                    nrm += U[j, m, i] * U[j, m, i]
                g = eta_j / (_NLMS_EPS + nrm) * eps
            else:
                g = eta_j * eps
            for i in range(N):
                w[j, i] += g * U[j, m, i]
            if simplex:
                _project_simplex_inplace(w, j, s)
            else:
                _clip_renormalize_inplace(w, j)
            tot = 0.0
            for i in range(N):
                if w[j, i] < mw:
                    mw = w[j, i]
                tot += w[j, i]
            e = abs(tot - 1.0)
            if e > se:
                se = e
        min_w[j] = mw
        max_sum_err[j] = se
        for i in range(N):
            d = abs(w[j, i] - w_start[i])
            if d > dmax:
                dmax = d
    return dmax


# --------------------------------------------------------------------------- training


def _check_scalar(name: str, x: float, lo: float, hi: float, lo_open: bool, hi_open: bool) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a real number, got {x!r}") from None
    ok = np.isfinite(v) and (v > lo if lo_open else v >= lo) and (v < hi if hi_open else v <= hi)
    if not ok:
        lb = "(" if lo_open else "["
        rb = ")" if hi_open else "]"
        raise ValueError(f"{name}: must be in {lb}{lo}, {hi}{rb}, got {x!r}")
    return v


def lms_train(
    U: ArrayLike,
    t: ArrayLike,
    *,
    projection: str = "simplex",
    step: str = "lms",
    mu: float = 0.1,
    epochs: int = 200,
    tol: float = 1e-6,
    decay: bool = True,
    w0: ArrayLike | None = None,
    rng: np.random.Generator,
) -> LmsResult:
    """Train J linear neurons by projected LMS (spec §5.3).

    Parameters
    ----------
    U : array_like, shape (J, M, N)
        Inputs: for neuron j and sample m, the N local estimates of its state.
        They should be centred by the caller (spec §5.3 conditioning:
        ``ũ_i = u_i − ū``, ``t̃ = t − ū``); M > N samples, finite.
    t : array_like, shape (J, M)
        Targets (the true state, centred the same way).
    projection : {"simplex", "seed"}
        Projection after every update: Euclidean projection onto the simplex, or
        the seed's clip-and-renormalize rule.
    step : {"lms", "nlms"}
        ``η = μ / tr R`` per neuron (R the sample second-moment matrix of its
        inputs) or ``η_k = μ / (1e-12 + ‖u⁽ᵏ⁾‖²)`` per sample.
    mu : float
        Step numerator, ``0 < μ < 2``.  The spread left after the last epoch
        scales like ``sqrt(μ / epochs)``: on the spec §5.5 data, the defaults
        (μ = 0.1, 200 epochs) end ~2e-3 from the constrained least-squares
        minimiser and μ = 0.005 ~1e-4.  On noisy data that spread also keeps
        ``max |Δw|`` above tol = 1e-6, so training runs all ``epochs``.
    epochs : int
        Maximum number of epochs (>= 1).
    tol : float
        Stop when ``max |Δw|`` over one epoch and all neurons is below ``tol`` (>= 0).
    decay : bool
        Divide the step of epoch ``e`` (0-based) by ``1 + e`` (see module notes).
    w0 : array_like, shape (N,) or (J, N), optional
        Initial weights, on the simplex; default ``1/N`` (spec §5.3).
    rng : numpy.random.Generator
        Source of the per-epoch sample permutations (one per epoch, shared by
        all neurons).

    Returns
    -------
    LmsResult
        Weights (J, N), epochs run, convergence flag and diagnostics.

    Raises
    ------
    ValueError
        On a bad shape or argument; the message starts with the argument's name.
    """
    Ua = np.asarray(U)
    if Ua.ndim != 3:
        raise ValueError(f"U: expected (J, M, N) array, got shape {Ua.shape}")
    J, M, N = Ua.shape
    if J < 1 or N < 1:
        raise ValueError(f"U: expected (J, M, N) with J >= 1 and N >= 1, got shape {Ua.shape}")
    if M <= N:
        raise ValueError(f"U: need more samples than inputs (M > N), got M = {M}, N = {N}")
    Ua = np.ascontiguousarray(Ua, dtype=np.float64)
    if not np.isfinite(Ua).all():
        raise ValueError("U: entries must be finite")
    ta = np.asarray(t)
    if ta.shape != (J, M):
        raise ValueError(f"t: expected shape (J, M) = {(J, M)}, got {ta.shape}")
    ta = np.ascontiguousarray(ta, dtype=np.float64)
    if not np.isfinite(ta).all():
        raise ValueError("t: entries must be finite")
    if projection not in PROJECTIONS:
        raise ValueError(f"projection: expected one of {PROJECTIONS}, got {projection!r}")
    if step not in STEPS:
        raise ValueError(f"step: expected one of {STEPS}, got {step!r}")
    mu = _check_scalar("mu", mu, 0.0, 2.0, True, True)
    if isinstance(epochs, bool) or not isinstance(epochs, (int, np.integer)) or epochs < 1:
        raise ValueError(f"epochs: must be an integer >= 1, got {epochs!r}")
    tol = _check_scalar("tol", tol, 0.0, np.inf, False, True)
    if not isinstance(decay, (bool, np.bool_)):
        raise ValueError(f"decay: must be a bool, got {decay!r}")
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")

    if w0 is None:
        w = np.full((J, N), 1.0 / N)
    else:
        w0a = np.asarray(w0, dtype=np.float64)
        if w0a.shape not in ((N,), (J, N)):
            raise ValueError(
                f"w0: expected shape (N,) = {(N,)} or (J, N) = {(J, N)}, got {w0a.shape}"
            )
        if not (
            np.isfinite(w0a).all()
            and (w0a >= 0.0).all()
            and (np.abs(w0a.sum(axis=-1) - 1.0) < 1e-9).all()
        ):
            raise ValueError("w0: must lie on the simplex (w >= 0, sum w = 1)")
        w = np.array(np.broadcast_to(w0a, (J, N)), dtype=np.float64)

    nlms = step == "nlms"
    if nlms:
        eta0 = np.full(J, mu)
    else:
        tr = _mean_sq_norm(Ua)
        if not (tr > 0.0).all():
            raise ValueError(
                "U: the inputs of a neuron are all zero (tr R = 0), the 'lms' step is undefined"
            )
        eta0 = mu / tr

    min_w = np.full(J, np.inf)
    max_sum_err = np.zeros(J)
    simplex = projection == "simplex"
    converged = False
    e = 0
    while e < epochs:
        order = rng.permutation(M)
        eta = eta0 / (1.0 + e) if decay else eta0
        dmax = _lms_epoch(Ua, ta, w, eta, order, simplex, nlms, min_w, max_sum_err)
        e += 1
        if dmax < tol:
            converged = True
            break

    r = ta - np.einsum("jmn,jn->jm", Ua, w)
    mse = np.mean(r * r, axis=1)
    return LmsResult(
        weights=w,
        epochs_run=e,
        converged=converged,
        min_weight=min_w,
        max_sum_error=max_sum_err,
        mse=mse,
    )
