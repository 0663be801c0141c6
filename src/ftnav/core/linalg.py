"""Batched solves with symmetric positive-definite matrices.

``numpy.linalg.solve`` calls LAPACK once per matrix, which costs ~0.3 µs of
overhead per 3x3 system; a Monte Carlo batch of 1000 small covariances then
spends most of its time in call overhead (measured in
``benchmarks/bench_federated.py``).  Here the Cholesky factorization and the two
triangular solves run in one compiled loop over the batch.  A matrix that is not
numerically positive definite falls back to LU (``numpy.linalg.solve``), so the
result is never silently wrong.

Every kernel is one serial compiled loop over the batch (``_*_rows(lo, hi, ...)``
over rows ``lo..hi−1``, with its own scratch buffers).  A kernel call holds one
epoch's work, microseconds to a millisecond: far too little for a thread pool,
whose barrier at the end of every call waits for the slowest thread, so one core
taken by another process made whole runs many times slower.  Parallelism lives a
level up, around whole chunks of runs or methods in worker processes
(:mod:`ftnav.parallel`), where a busy core costs at most in proportion.
"""

from __future__ import annotations

from typing import Literal, TypedDict

import numba
import numpy as np

from ftnav.types import (
    Array,
    BatchMatrix,
    BatchScalar,
    BatchVector,
    BoolBatch,
    Matrix,
    Vector,
)

__all__ = [
    "spd_solve",
    "spd_inv",
    "predict_kernel",
    "update_kernel",
    "nis_kernel",
    "vb_kernel",
    "fuse_kernel",
    "flat",
    "batch_shape",
]


class JitOptions(TypedDict, total=False):
    """Keyword options of ``numba.njit`` that the compiled kernels set (typed for mypy)."""

    cache: bool
    nogil: bool
    error_model: Literal["python", "numpy"]
    fastmath: bool | set[str]


#: compile options of every kernel: cached, GIL released, NumPy error model
#: (no zero-division checks; a failed Cholesky is detected explicitly instead)
_JIT: JitOptions = dict(
    cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"}
)


@numba.njit(**_JIT)
def _chol(A: Matrix, L: Matrix) -> bool:  # pragma: no cover - compiled
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for p in range(j):
            s -= L[j, p] * L[j, p]
        if not s > 0.0:
            return False
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            s = A[i, j]
            for p in range(j):
                s -= L[i, p] * L[j, p]
            L[i, j] = s / d
    return True


@numba.njit(**_JIT)
def _chol_solve_rows(
    lo: int, hi: int, A: BatchMatrix, B: BatchMatrix, out: BatchMatrix, ok: BoolBatch
) -> None:  # pragma: no cover - compiled
    n = A.shape[1]
    k = B.shape[2]
    L = np.empty((n, n))
    for b in range(lo, hi):
        if not _chol(A[b], L):
            ok[b] = False
            continue
        for c in range(k):
            for i in range(n):  # forward: L y = b
                s = B[b, i, c]
                for p in range(i):
                    s -= L[i, p] * out[b, p, c]
                out[b, i, c] = s / L[i, i]
            for i in range(n - 1, -1, -1):  # backward: Lᵀ x = y
                s = out[b, i, c]
                for p in range(i + 1, n):
                    s -= L[p, i] * out[b, p, c]
                out[b, i, c] = s / L[i, i]


def _chol_solve(A: BatchMatrix, B: BatchMatrix, out: BatchMatrix) -> BoolBatch:
    M = A.shape[0]
    ok = np.ones(M, dtype=np.bool_)
    _chol_solve_rows(0, M, A, B, out, ok)
    return ok


def spd_solve(A: BatchMatrix, B: BatchMatrix) -> BatchMatrix:
    """Solve ``A X = B`` for SPD ``A (..., n, n)`` and ``B (..., n, k)``.

    Leading axes broadcast.  Uses a compiled Cholesky solve; any matrix whose
    factorization fails falls back to LU.
    """
    shape = batch_shape(A.shape[:-2], B.shape[:-2])
    n, k = A.shape[-1], B.shape[-1]
    A3, B3 = flat(A, shape, (n, n)), flat(B, shape, (n, k))
    if n == 1:
        return (B3 / A3).reshape(shape + (n, k))
    out = np.empty_like(B3)
    ok = _chol_solve(A3, B3, out)
    if not ok.all():
        bad = ~ok
        out[bad] = np.linalg.solve(A3[bad], B3[bad])
    return out.reshape(shape + (n, k))


@numba.njit(**_JIT)
def _gram_lower(Li: Matrix, out: Matrix) -> None:  # pragma: no cover - compiled
    """``out = Liᵀ Li`` for lower-triangular ``Li`` (= A⁻¹ when ``Li = L⁻¹``), mirrored."""
    n = Li.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = 0.0
            for p in range(i, n):
                s += Li[p, i] * Li[p, j]
            out[i, j] = s
            out[j, i] = s


@numba.njit(**_JIT)
def _inv_rows(
    lo: int, hi: int, A: BatchMatrix, out: BatchMatrix, ok: BoolBatch
) -> None:  # pragma: no cover - compiled
    n = A.shape[1]
    L = np.empty((n, n))
    Li = np.zeros((n, n))
    for b in range(lo, hi):
        if not _chol(A[b], L):
            ok[b] = False
            continue
        _tri_inv(L, Li)
        _gram_lower(Li, out[b])


def spd_inv(A: BatchMatrix) -> BatchMatrix:
    """Inverse of SPD ``A (..., n, n)``, symmetric by construction.

    ``A⁻¹ = L⁻ᵀ L⁻¹`` from the compiled Cholesky factor; a matrix whose factorization
    fails falls back to LU (``numpy.linalg.inv``), symmetrized.
    """
    n = A.shape[-1]
    batch = A.shape[:-2]
    A3 = flat(A, batch, (n, n))
    out = np.empty_like(A3)
    ok = np.ones(A3.shape[0], dtype=np.bool_)
    _inv_rows(0, A3.shape[0], A3, out, ok)
    if not ok.all():
        bad = ~ok
        X = np.linalg.inv(A3[bad])
        out[bad] = 0.5 * (X + np.swapaxes(X, -1, -2))
    return out.reshape(A.shape)


@numba.njit(**_JIT)
def _predict_rows(
    lo: int,
    hi: int,
    x: BatchVector,
    P: BatchMatrix,
    F: BatchMatrix,
    Q: BatchMatrix,
    x_out: BatchVector,
    P_out: BatchMatrix,
) -> None:  # pragma: no cover - compiled
    n = x.shape[1]
    FP = np.empty((n, n))
    for b in range(lo, hi):
        f = b if F.shape[0] > 1 else 0
        g = b if Q.shape[0] > 1 else 0
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += F[f, i, j] * x[b, j]
            x_out[b, i] = s
            # row i of F P as a sum of rows of P (contiguous; zeros of F skipped)
            for j in range(n):
                FP[i, j] = 0.0
            for p in range(n):
                a = F[f, i, p]
                if a != 0.0:
                    for j in range(n):
                        FP[i, j] += a * P[b, p, j]
        for i in range(n):
            for j in range(i + 1):
                s = 0.0
                for p in range(n):
                    s += FP[i, p] * F[f, j, p]
                v = s + 0.5 * (Q[g, i, j] + Q[g, j, i])
                P_out[b, i, j] = v
                P_out[b, j, i] = v


def predict_kernel(
    x: BatchVector,
    P: BatchMatrix,
    F: BatchMatrix,
    Q: BatchMatrix,
    x_out: BatchVector,
    P_out: BatchMatrix,
) -> None:
    """``x⁻ = F x``, ``P⁻ = F P Fᵀ + Q`` symmetrized, for flat batches (M, n[, n]).

    ``F`` and ``Q`` have a leading axis of M or of 1 (shared by the batch).
    """
    M = x.shape[0]
    _predict_rows(0, M, x, P, F, Q, x_out, P_out)


@numba.njit(**_JIT)
def _innovation(
    b: int,
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    R: BatchMatrix,
    PHt: Matrix,
    nu: Vector,
    S: Matrix,
) -> None:  # pragma: no cover - compiled
    """Row b: ``P Hᵀ`` (n, m), ``ν = z − H x`` (m,) and the symmetrized ``S = H P Hᵀ + R``."""
    n = x.shape[1]
    m = z.shape[1]
    h = b if H.shape[0] > 1 else 0
    e = b if R.shape[0] > 1 else 0
    for i in range(n):
        for c in range(m):
            s = 0.0
            for p in range(n):
                s += P[b, i, p] * H[h, c, p]
            PHt[i, c] = s
    for r in range(m):
        s = z[b, r]
        for p in range(n):
            s -= H[h, r, p] * x[b, p]
        nu[r] = s
        for c in range(r + 1):
            s = 0.5 * (R[e, r, c] + R[e, c, r])
            for p in range(n):
                s += 0.5 * (H[h, r, p] * PHt[p, c] + H[h, c, p] * PHt[p, r])
            S[r, c] = s
            S[c, r] = s


@numba.njit(**_JIT)
def _whitened_norm(L: Matrix, nu: Vector, w: Vector) -> float:  # pragma: no cover - compiled
    """``νᵀ S⁻¹ ν = |L⁻¹ ν|²`` for the Cholesky factor L of S (w: (m,) scratch)."""
    q = 0.0
    for r in range(nu.shape[0]):
        s = nu[r]
        for p in range(r):
            s -= L[r, p] * w[p]
        w[r] = s / L[r, r]
        q += w[r] * w[r]
    return q


@numba.njit(**_JIT)
def _update_rows(
    lo: int,
    hi: int,
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    R: BatchMatrix,
    x_out: BatchVector,
    P_out: BatchMatrix,
    nu_out: BatchVector,
    S_out: BatchMatrix,
    nis_out: BatchScalar,
    ok: BoolBatch,
) -> None:  # pragma: no cover - compiled
    n = x.shape[1]
    m = z.shape[1]
    PHt = np.empty((n, m))
    L = np.empty((m, m))
    K = np.empty((n, m))
    A = np.empty((n, m))
    AP = np.empty((n, n))
    KR = np.empty((n, m))
    w = np.empty(m)
    for b in range(lo, hi):
        h = b if H.shape[0] > 1 else 0
        e = b if R.shape[0] > 1 else 0
        _innovation(b, x, P, z, H, R, PHt, nu_out[b], S_out[b])
        if not _chol(S_out[b], L):
            ok[b] = False
            continue
        # K = P Hᵀ S⁻¹ : solve S Kᵀ = (P Hᵀ)ᵀ row by row
        for i in range(n):
            for r in range(m):
                s = PHt[i, r]
                for p in range(r):
                    s -= L[r, p] * w[p]
                w[r] = s / L[r, r]
            for r in range(m - 1, -1, -1):
                s = w[r]
                for p in range(r + 1, m):
                    s -= L[p, r] * w[p]
                w[r] = s / L[r, r]
            for r in range(m):
                K[i, r] = w[r]
        nis_out[b] = _whitened_norm(L, nu_out[b], w)
        # Joseph form (I − K H) P (I − K H)ᵀ + K R Kᵀ, with the products associated so
        # each costs O(n² m): A P = P − K (P Hᵀ)ᵀ and (A P) Aᵀ = A P − (A P Hᵀ) Kᵀ
        for i in range(n):
            s = x[b, i]
            for r in range(m):
                s += K[i, r] * nu_out[b, r]
            x_out[b, i] = s
            for c in range(m):
                s = 0.0
                for r in range(m):
                    s += K[i, r] * R[e, r, c]
                KR[i, c] = s
            for j in range(n):
                s = P[b, i, j]
                for r in range(m):
                    s -= K[i, r] * PHt[j, r]
                AP[i, j] = s
        for i in range(n):
            for c in range(m):
                s = 0.0
                for p in range(n):
                    s += AP[i, p] * H[h, c, p]
                A[i, c] = s  # (A P Hᵀ)[i, c]
        for i in range(n):
            for j in range(i + 1):
                s = AP[i, j]
                for c in range(m):
                    s += (KR[i, c] - A[i, c]) * K[j, c]
                # lower triangle only, mirrored: the symmetrized Joseph covariance
                P_out[b, i, j] = s
                P_out[b, j, i] = s


def update_kernel(
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    R: BatchMatrix,
    x_out: BatchVector,
    P_out: BatchMatrix,
    nu_out: BatchVector,
    S_out: BatchMatrix,
    nis_out: BatchScalar,
) -> BoolBatch:
    """Joseph-form update for flat batches; returns False where S is not SPD."""
    M = x.shape[0]
    ok = np.ones(M, dtype=np.bool_)
    _update_rows(0, M, x, P, z, H, R, x_out, P_out, nu_out, S_out, nis_out, ok)
    return ok


@numba.njit(**_JIT)
def _nis_rows(
    lo: int,
    hi: int,
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    R: BatchMatrix,
    nis_out: BatchScalar,
    ok: BoolBatch,
) -> None:  # pragma: no cover - compiled
    n = x.shape[1]
    m = z.shape[1]
    PHt = np.empty((n, m))
    S = np.empty((m, m))
    L = np.empty((m, m))
    nu = np.empty(m)
    w = np.empty(m)
    for b in range(lo, hi):
        _innovation(b, x, P, z, H, R, PHt, nu, S)
        if not _chol(S, L):
            ok[b] = False
            continue
        nis_out[b] = _whitened_norm(L, nu, w)


def nis_kernel(
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    R: BatchMatrix,
    nis_out: BatchScalar,
) -> BoolBatch:
    """``νᵀ S⁻¹ ν`` with ``ν = z − H x``, ``S = H P Hᵀ + R`` for flat batches.

    Returns False where S is not numerically SPD (the caller falls back).
    """
    M = x.shape[0]
    ok = np.ones(M, dtype=np.bool_)
    _nis_rows(0, M, x, P, z, H, R, nis_out, ok)
    return ok


@numba.njit(**_JIT)
def _vb_rows(
    lo: int,
    hi: int,
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    alpha_post: BatchVector,
    beta: BatchVector,
    iterations: int,
    x_out: BatchVector,
    P_out: BatchMatrix,
    nu_out: BatchVector,
    S_out: BatchMatrix,
    nis_out: BatchScalar,
    beta_out: BatchVector,
    R_out: BatchMatrix,
    ok: BoolBatch,
) -> None:  # pragma: no cover - compiled
    m = z.shape[1]
    n = x.shape[1]
    for b in range(lo, hi):
        h = b if H.shape[0] > 1 else 0
        for j in range(m):
            beta_out[b, j] = beta[b, j]
        for _ in range(iterations):
            for r in range(m):
                for c in range(m):
                    R_out[b, r, c] = beta_out[b, r] / alpha_post[b, r] if r == c else 0.0
            _update_rows(b, b + 1, x, P, z, H, R_out, x_out, P_out, nu_out, S_out, nis_out, ok)
            if not ok[b]:
                break
            for r in range(m):  # β = β⁻ + ½ (z − H x⁺)² + ½ (H P⁺ Hᵀ)_rr
                res = z[b, r]
                hph = 0.0
                for p in range(n):
                    res -= H[h, r, p] * x_out[b, p]
                    acc = 0.0
                    for q in range(n):
                        acc += P_out[b, p, q] * H[h, r, q]
                    hph += H[h, r, p] * acc
                beta_out[b, r] = beta[b, r] + 0.5 * res * res + 0.5 * hph


def vb_kernel(
    x: BatchVector,
    P: BatchMatrix,
    z: BatchVector,
    H: BatchMatrix,
    alpha_post: BatchVector,
    beta: BatchVector,
    iterations: int,
    x_out: BatchVector,
    P_out: BatchMatrix,
    nu_out: BatchVector,
    S_out: BatchMatrix,
    nis_out: BatchScalar,
    beta_out: BatchVector,
    R_out: BatchMatrix,
) -> BoolBatch:
    """Särkkä VB iterations (spec §7.2) for flat batches: each a Joseph update with
    ``R = diag(β/α)`` then ``β = β⁻ + ½ν⁺² + ½ diag(H P⁺ Hᵀ)``; False where S is not SPD."""
    M = x.shape[0]
    ok = np.ones(M, dtype=np.bool_)
    _vb_rows(
        0,
        M,
        x,
        P,
        z,
        H,
        alpha_post,
        beta,
        iterations,
        x_out,
        P_out,
        nu_out,
        S_out,
        nis_out,
        beta_out,
        R_out,
        ok,
    )
    return ok


def batch_shape(*shapes: tuple[int, ...]) -> tuple[int, ...]:
    """``numpy.broadcast_shapes`` of the leading (batch) shapes, with a fast path for the
    common case where every shape is ``()`` or one and the same batch shape."""
    first = max(shapes, key=len)
    if all(s == first or s == () for s in shapes):
        return first
    return np.broadcast_shapes(*shapes)


def flat(a: Array, batch: tuple[int, ...], core: tuple[int, ...], shared: bool = False) -> Array:
    """View ``a`` as ``(prod(batch),) + core`` float64 (broadcasting it to ``batch``).

    With ``shared=True`` an ``a`` without batch axes is returned as ``(1,) + core``
    (the compiled kernels read index 0 for every batch element) instead of copied.
    """
    if shared and a.ndim == len(core):
        return np.ascontiguousarray(a, dtype=np.float64).reshape((1,) + core)
    if a.shape == batch + core and a.dtype == np.float64 and a.flags.c_contiguous:
        return a.reshape((-1,) + core)  # fast path: nothing to broadcast or copy
    return np.ascontiguousarray(np.broadcast_to(a, batch + core), dtype=np.float64).reshape(
        (-1,) + core
    )


@numba.njit(**_JIT)
def _tri_inv(L: Matrix, out: Matrix) -> None:  # pragma: no cover - compiled
    """Inverse of the lower-triangular Cholesky factor ``L`` (lower triangle of ``out``)."""
    n = L.shape[0]
    for j in range(n):
        d = 1.0 / L[j, j]
        out[j, j] = d
        for i in range(j + 1, n):
            s = 0.0
            for p in range(j, i):
                s += L[i, p] * out[p, j]
            out[i, j] = -s / L[i, i]


@numba.njit(**_JIT)
def _add_inverse(
    Li: Matrix, w: float, x: Vector, Y: Matrix, y: Vector, u: Vector
) -> None:  # pragma: no cover - compiled
    """``Y += w Lᵢᵀ Lᵢ`` (lower triangle) and ``y += w Lᵢᵀ Lᵢ x`` for ``Lᵢ = L⁻¹``.

    ``u`` is an (n,) work buffer (no allocation inside the batch loop).
    """
    n = Li.shape[0]
    for p in range(n):
        s = 0.0
        for j in range(p + 1):
            s += Li[p, j] * x[j]
        u[p] = s
    for i in range(n):
        s = 0.0
        for p in range(i, n):
            s += Li[p, i] * u[p]
        y[i] += w * s
        for j in range(i + 1):
            s = 0.0
            for p in range(i, n):
                s += Li[p, i] * Li[p, j]
            Y[i, j] += w * s


@numba.njit(**_JIT)
def _fuse_rows(
    lo: int,
    hi: int,
    x: BatchVector,
    P: BatchMatrix,
    w: BatchVector,
    Y0: BatchMatrix,
    y0: BatchVector,
    x_out: BatchVector,
    P_out: BatchMatrix,
    ok: BoolBatch,
) -> None:  # pragma: no cover - compiled
    N, n = x.shape[1:]
    L = np.empty((n, n))
    Li = np.zeros((n, n))
    Y = np.empty((n, n))
    y = np.empty(n)
    u = np.empty(n)
    for b in range(lo, hi):
        for i in range(n):
            y[i] = y0[b, i]
            for j in range(i + 1):
                Y[i, j] = 0.5 * (Y0[b, i, j] + Y0[b, j, i])
        for k in range(N):
            if w[b, k] == 0.0:
                continue
            if not _chol(P[b, k], L):
                ok[b] = False
                break
            _tri_inv(L, Li)
            _add_inverse(Li, w[b, k], x[b, k], Y, y, u)
        if not ok[b]:
            continue
        for i in range(n):
            for j in range(i):
                Y[j, i] = Y[i, j]
        if not _chol(Y, L):
            ok[b] = False
            continue
        _tri_inv(L, Li)
        _gram_lower(Li, P_out[b])
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += P_out[b, i, j] * y[j]
            x_out[b, i] = s


def fuse_kernel(
    x: BatchVector,
    P: BatchMatrix,
    w: BatchVector,
    Y0: BatchMatrix,
    y0: BatchVector,
    x_out: BatchVector,
    P_out: BatchMatrix,
) -> BoolBatch:
    """``Y = Y0 + Σ w_i P_i⁻¹``, ``y = y0 + Σ w_i P_i⁻¹ x_i``, ``P = Y⁻¹``, ``x = P y``.

    Each inverse is ``L⁻ᵀ L⁻¹`` from the Cholesky factor (one triangular
    inversion, lower triangle only); the result is symmetric by construction.
    Returns False where a ``P_i`` or the total information is not SPD.
    """
    M = x.shape[0]
    ok = np.ones(M, dtype=np.bool_)
    _fuse_rows(0, M, x, P, w, Y0, y0, x_out, P_out, ok)
    return ok
