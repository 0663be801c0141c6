"""Solution separation by tracked pulls: what one aid moved an estimate by, per window.

The *pull* of aid i over a window is the difference between an estimate and the same
filter without aid i's measurements of that window, to first order (the other aids'
gains held; Brenner, "Integrated GPS/inertial fault detection availability",
Navigation 43(2), 1996, solution separation; spec §3.2 with the exclusion filter in
place of the pure propagator):

* aid i's own update adds ``d = K ν`` to its pull and ``D = K S Kᵀ`` (the covariance
  reduction ``P⁻ − P⁺``) to its covariance;
* another aid j's update maps it by ``M_j = I − K_j H_j`` (both filters take ``z_j``):
  ``c ← M_j c``, ``Γ ← M_j Γ M_jᵀ``;
* the time update by Φ: ``c ← Φ c``, ``Γ ← Φ Γ Φᵀ`` (Q cancels in the difference).

Under H0 the innovations are white, so ``Γ = Cov(c)``, and for the optimal filter
``Γ = P_without − P`` (the exclusion filter's covariance less the filter's: the
orthogonality argument of spec §3.2).  A fault of aid i that the filter absorbs, a slow
ramp that no single epoch's test sees, accumulates in ``c`` while ``Γ`` grows only as
the rest of the system lets the aid's quantity drift: ``λ = (H c)ᵀ (H Γ Hᵀ)⁺ (H c)``,
the separation seen in aid i's own measurement space, is ``χ²(m)`` under H0 for any
window.  With a window of one epoch it is the NIS of spec §3.1.  And removing the pull,
``x − c``, ``P + Γ``, is the estimate of the filter that excluded the aid over the
window: the rollback of :mod:`ftnav.fusion.guard`.

Windows are kept as blocks, each accumulated and propagated on its own: ``nf`` fine
blocks of ``L`` epochs and the current partial one, and (optionally) ``nc`` coarse
blocks of ``nf · L`` epochs and a partial one, into which the fine blocks that leave
go.  Newest first, the windows are the cumulative sums: the current block, then one
more fine block each, then one more coarse block each; ``nc + nf + 2`` accumulators per
aid cover ``(nc + 1) · nf · L`` epochs, finely where it is recent.  The layout, oldest
first: ``[coarse full …, coarse partial, fine full …, current]``.  Arrays carry the
batch axis; ``A`` aids share one tracked estimate of dimension n.

Every closed block of an aid takes the same maps (Φ, and each other aid's ``I − K H``),
so :func:`init_pulls` keeps them in a *lazy* form: as they were at the last
:func:`rotate`, with one accumulated map ``T`` per aid (:class:`Pulls`); an epoch maps
the current block and ``T`` only (``O(n³)`` per aid instead of ``O(J n³)``), and the
blocks are formed where they are read (:func:`windows`) and at a rotation.  The
*explicit* form (every block as of now, ``Pulls(c, G)``) keeps the per-block kernels and
is the lazy form's oracle (``tests/closed_form/test_separation.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ftnav.core.linalg import JitOptions

#: compiled serially, cached, GIL released, sums reassociated (as
#: :mod:`ftnav.core.linalg`'s kernels: each run's row alone, so bit-identical for any
#: batch split)
_JIT: JitOptions = dict(
    cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"}
)

__all__ = [
    "Pulls",
    "clear",
    "explicit",
    "init_pulls",
    "map_others",
    "map_others_numpy",
    "propagate",
    "propagate_numpy",
    "rotate",
    "measured",
    "separation",
    "separation_of",
    "with_own",
    "windows",
]


class Pulls(NamedTuple):
    """Block accumulators of every aid of one estimate.

    Attributes
    ----------
    c : (B, A, J, n) pulls, oldest block first, the current partial block last.
    G : (B, A, J, n, n) their covariances under H0.
    T : (B, A, n, n) or None.  None: every block is as of now (the *explicit* form).
        Else the *lazy* form: the closed blocks (all but the current one) are stored as
        they were at the last :func:`rotate`, and ``T`` is the map every closed block of
        the aid has taken since (the time updates Φ and the other aids' ``I − K H``, in
        order), so a closed block now is ``T c``, ``T Γ Tᵀ``.  Every closed block takes
        the same maps, so one ``T`` per aid stands for all of them: an epoch costs one
        block and one ``T`` instead of J blocks.  :func:`explicit` forms the blocks.
    """

    c: np.ndarray
    G: np.ndarray
    T: np.ndarray | None = None


def init_pulls(batch: int, aids: int, blocks: int, n: int, coarse: int = 0) -> Pulls:
    """Empty accumulators: ``blocks`` fine blocks and the current one, and with ``coarse``
    that many coarse blocks and their partial one (``blocks = -1``: none at all); in the
    lazy form when there is a closed block (:class:`Pulls`)."""
    J = blocks + 1 + (coarse + 1 if coarse else 0)
    T = _identity(batch, aids, n) if J > 1 else None
    return Pulls(np.zeros((batch, aids, J, n)), np.zeros((batch, aids, J, n, n)), T)


def _identity(batch: int, aids: int, n: int) -> np.ndarray:
    """Each aid's map T at a rotation: the identity (B, A, n, n)."""
    return np.broadcast_to(np.eye(n), (batch, aids, n, n)).copy()


def _mapped(T: np.ndarray, c: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Blocks c (B, A, J, n), G (B, A, J, n, n) mapped by each aid's T (B, A, n, n): new
    arrays, ``T c`` and ``T Γ Tᵀ`` (exactly symmetric)."""
    c, G = np.array(c, dtype=np.float64), np.array(G, dtype=np.float64)
    _map_blocks(c, G, np.ascontiguousarray(T, dtype=np.float64), 0, c.shape[2])
    return c, G


@numba.njit(**_JIT)
def _map_blocks(
    c: np.ndarray, G: np.ndarray, T: np.ndarray, j0: int, j1: int
) -> None:  # pragma: no cover - compiled
    # in place: the blocks j0 .. j1 - 1 of aid a in run b by T[b, a]
    B, A, J, n = c.shape
    TX = np.empty((n, n))
    tmp = np.empty(n)
    for b in range(B):
        for a in range(A):
            for j in range(j0, j1):
                _sandwich(T[b, a], c[b, a, j], G[b, a, j], tmp, TX)


@numba.njit(**_JIT)
def _sandwich(
    M: np.ndarray, cv: np.ndarray, g: np.ndarray, tmp: np.ndarray, MX: np.ndarray
) -> None:  # pragma: no cover - compiled
    """In place: ``c ← M c``, ``Γ ← M Γ Mᵀ`` (M's zeros skipped in ``M Γ``, the upper
    triangle of ``(M Γ) Mᵀ`` formed and mirrored); ``tmp`` (n,), ``MX`` (n, n) scratch."""
    n = M.shape[0]
    for i in range(n):
        s = 0.0
        for k in range(n):
            s += M[i, k] * cv[k]
        tmp[i] = s
    for i in range(n):
        cv[i] = tmp[i]
    _times(M, g, MX)
    for i in range(n):
        for q in range(i, n):
            s = 0.0
            for k in range(n):
                s += MX[i, k] * M[q, k]
            g[i, q] = s
            g[q, i] = s


def explicit(p: Pulls) -> Pulls:
    """The explicit form of ``p``: every block as of now (new arrays; ``p`` itself when
    it is explicit already)."""
    if p.T is None:
        return p
    c, G = p.c.copy(), p.G.copy()
    _map_blocks(c, G, np.ascontiguousarray(p.T, dtype=np.float64), 0, c.shape[2] - 1)
    return Pulls(c, G)


def propagate(p: Pulls, F: np.ndarray, *, copy: bool = True) -> Pulls:
    """The time update ``c ← Φ c``, ``Γ ← Φ Γ Φᵀ``; F (n, n) or per run (B, n, n).

    One compiled serial loop over the runs and blocks (no BLAS call per small block; Φ's
    zeros skipped in ``Φ Γ``, half of ``(Φ Γ) Φᵀ`` formed and mirrored, so ``Γ`` comes out
    exactly symmetric).  :func:`propagate_numpy` is its oracle.  A lazy ``p`` takes the map
    in its current block and ``T`` only; ``copy=False`` does that in place, for a caller
    that owns ``p`` and does not read it again.
    """
    B = p.c.shape[0]
    Fb = np.ascontiguousarray(np.broadcast_to(F, (B,) + F.shape[-2:]), dtype=np.float64)
    if p.T is not None:  # the lazy form: the current block and T only
        c, G, T = (p.c.copy(), p.G.copy(), p.T.copy()) if copy else (p.c, p.G, p.T)
        _propagate_now(c, G, T, Fb)
        return Pulls(c, G, T)
    c, G = np.empty_like(p.c), np.empty_like(p.G)
    _propagate_rows(np.ascontiguousarray(p.c), np.ascontiguousarray(p.G), Fb, c, G)
    return Pulls(c, G)


@numba.njit(**_JIT)
def _times(F: np.ndarray, X: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """``out = F X`` row by row of X (F's zeros skipped); F (r, n), X (n, q)."""
    rows, n = F.shape
    cols = X.shape[1]
    for i in range(rows):
        for q in range(cols):
            out[i, q] = 0.0
        for k in range(n):
            f = F[i, k]
            if f != 0.0:
                for q in range(cols):
                    out[i, q] += f * X[k, q]


@numba.njit(**_JIT)
def _propagate_now(
    c: np.ndarray, G: np.ndarray, T: np.ndarray, F: np.ndarray
) -> None:  # pragma: no cover - compiled
    # in place: each aid's current block (c ← Φ c, Γ ← Φ Γ Φᵀ) and its T ← Φ T
    B, A, J, n = c.shape
    FX = np.empty((n, n))
    tmp = np.empty(n)
    for b in range(B):
        Fb = F[b]
        for a in range(A):
            _sandwich(Fb, c[b, a, J - 1], G[b, a, J - 1], tmp, FX)
            t = T[b, a]
            _times(Fb, t, FX)
            for i in range(n):
                for q in range(n):
                    t[i, q] = FX[i, q]


@numba.njit(**_JIT)
def _propagate_rows(
    c: np.ndarray, G: np.ndarray, F: np.ndarray, c_out: np.ndarray, G_out: np.ndarray
) -> None:  # pragma: no cover - compiled
    B, A, J, n = c.shape
    FG = np.empty((n, n))
    tmp = np.empty(n)
    for b in range(B):
        for a in range(A):
            for j in range(J):
                co, go = c_out[b, a, j], G_out[b, a, j]
                co[:] = c[b, a, j]
                go[:, :] = G[b, a, j]
                _sandwich(F[b], co, go, tmp, FG)


def propagate_numpy(p: Pulls, F: np.ndarray) -> Pulls:
    """:func:`propagate` as dense NumPy products on the explicit form: its oracle (equal
    to rounding; the result is explicit)."""
    p = explicit(p)
    if F.ndim == 2:
        c = p.c @ F.T
        G = F @ p.G @ F.T
    else:
        c = np.einsum("bij,bakj->baki", F, p.c)
        Fb = F[:, None, None]
        G = Fb @ p.G @ np.swapaxes(Fb, -1, -2)
    return Pulls(c, G)


def map_others(
    p: Pulls, aid: int, K: np.ndarray, H: np.ndarray, use: np.ndarray, *, copy: bool = True
) -> Pulls:
    """Aid ``aid``'s update maps every *other* aid's pulls by ``M = I − K H`` where ``use``:
    ``c ← c − K (H c)``, ``Γ ← Γ − K H Γ − (K H Γ)ᵀ + K (H Γ Hᵀ) Kᵀ`` (symmetrized).

    K (B, n, m), H (B, m, n) or (m, n), use (B,) bool.  One compiled serial loop over
    the runs (:mod:`ftnav.core.linalg`'s rule: no thread pool per epoch); the low-rank
    form costs ``O(n² m)`` per block instead of the ``O(n³)`` of ``M Γ Mᵀ``, and the lazy
    form maps the current block and ``T`` only (:class:`Pulls`).
    :func:`map_others_numpy` is its oracle.  ``copy=False`` maps ``p``'s (C-contiguous)
    arrays in place, for a caller that owns them.
    """
    A = p.c.shape[1]
    if A < 2 or not use.any():
        return p
    B = K.shape[0]
    Hb = np.ascontiguousarray(np.broadcast_to(H, (B,) + H.shape[-2:]), dtype=np.float64)
    c, G = (p.c.copy(), p.G.copy()) if copy else (p.c, p.G)
    Kc, u = np.ascontiguousarray(K, dtype=np.float64), np.ascontiguousarray(use)
    if p.T is None:
        _map_rows(c, G, Kc, Hb, u, aid, c.shape[2])
        return Pulls(c, G)
    T = p.T.copy() if copy else p.T
    _map_rows(c, G, Kc, Hb, u, aid, 1)  # the current block; the closed ones through T
    _map_T(T, Kc, Hb, u, aid)
    return Pulls(c, G, T)


@numba.njit(**_JIT)
def _map_T(
    T: np.ndarray, K: np.ndarray, H: np.ndarray, use: np.ndarray, aid: int
) -> None:  # pragma: no cover - compiled
    # T ← (I − K H) T for every aid but ``aid``, in the runs ``use``
    B, A, n, _ = T.shape
    m = K.shape[2]
    HT = np.empty((m, n))
    for b in range(B):
        if not use[b]:
            continue
        Kb, Hb = K[b], H[b]
        for a in range(A):
            if a == aid:
                continue
            t = T[b, a]
            _times(Hb, t, HT)
            for i in range(n):
                for r in range(m):
                    w = Kb[i, r]
                    for k in range(n):
                        t[i, k] -= w * HT[r, k]


@numba.njit(**_JIT)
def _map_rows(
    c: np.ndarray,
    G: np.ndarray,
    K: np.ndarray,
    H: np.ndarray,
    use: np.ndarray,
    aid: int,
    newest: int,
) -> None:  # pragma: no cover - compiled
    # Γ − K H Γ − (K H Γ)ᵀ + K S Kᵀ = Γ − K U − (K U)ᵀ with U = H Γ − ½ S Kᵀ (Γ, S
    # symmetric): one n × n product per block instead of three, exactly symmetric;
    # H's zeros skipped (a measurement reads few states).  The ``newest`` blocks only
    B, A, J, n = c.shape
    m = K.shape[2]
    Hc = np.empty(m)
    HG = np.empty((m, n))
    S = np.empty((m, m))
    U = np.empty((m, n))
    KU = np.empty((n, n))
    for b in range(B):
        if not use[b]:
            continue
        Kb, Hb = K[b], H[b]
        for a in range(A):
            if a == aid:
                continue
            for j in range(J - newest, J):
                cv, g = c[b, a, j], G[b, a, j]
                for r in range(m):  # c ← c − K (H c)
                    s = 0.0
                    for k in range(n):
                        h = Hb[r, k]
                        if h != 0.0:
                            s += h * cv[k]
                    Hc[r] = s
                for i in range(n):
                    s = 0.0
                    for r in range(m):
                        s += Kb[i, r] * Hc[r]
                    cv[i] -= s
                _times(Hb, g, HG)  # H Γ
                for r in range(m):  # S = H Γ Hᵀ
                    for q in range(m):
                        s = 0.0
                        for k in range(n):
                            h = Hb[q, k]
                            if h != 0.0:
                                s += HG[r, k] * h
                        S[r, q] = s
                for r in range(m):  # U = H Γ − ½ S Kᵀ
                    for k in range(n):
                        s = 0.0
                        for q in range(m):
                            s += S[r, q] * Kb[k, q]
                        U[r, k] = HG[r, k] - 0.5 * s
                for i in range(n):  # K U
                    for k in range(n):
                        KU[i, k] = 0.0
                    for r in range(m):
                        w = Kb[i, r]
                        for k in range(n):
                            KU[i, k] += w * U[r, k]
                for i in range(n):
                    for k in range(i, n):
                        v = g[i, k] - KU[i, k] - KU[k, i]
                        g[i, k] = v
                        g[k, i] = v


def map_others_numpy(p: Pulls, aid: int, K: np.ndarray, H: np.ndarray, use: np.ndarray) -> Pulls:
    """:func:`map_others` in NumPy einsums on the explicit form: the oracle of the compiled
    form (the same products, summed in another order: equal to rounding,
    ``tests/closed_form``; the result is explicit)."""
    p = explicit(p)
    A = p.c.shape[1]
    others = [a for a in range(A) if a != aid]
    if not others or not use.any():
        return p
    H = np.broadcast_to(H, (K.shape[0],) + H.shape[-2:])
    c, G = p.c.copy(), p.G.copy()
    co, Go = c[:, others], G[:, others]  # (B, A', J, n), (B, A', J, n, n)
    Hc = np.einsum("bmn,bajn->bajm", H, co)
    c_new = co - np.einsum("bnm,bajm->bajn", K, Hc)
    HG = np.einsum("bmn,bajnk->bajmk", H, Go)  # H Γ
    KHG = np.einsum("bnm,bajmk->bajnk", K, HG)  # K H Γ
    HGHt = np.einsum("bajmk,bqk->bajmq", HG, H)  # H Γ Hᵀ
    KHGHtKt = np.einsum("bnm,bajmq,bpq->bajnp", K, HGHt, K)
    G_new = Go - KHG - np.swapaxes(KHG, -1, -2) + KHGHtKt
    u4, u5 = use[:, None, None, None], use[:, None, None, None, None]
    c[:, others] = np.where(u4, c_new, co)
    G[:, others] = np.where(u5, 0.5 * (G_new + np.swapaxes(G_new, -1, -2)), Go)
    return Pulls(c, G)


def with_own(p: Pulls, aid: int, d: np.ndarray, D: np.ndarray, *, copy: bool = True) -> Pulls:
    """Aid ``aid``'s own update: ``d`` (B, n) and ``D`` (B, n, n) added to its current block
    (``copy=False``: in place, as :func:`map_others`)."""
    c, G = (p.c.copy(), p.G.copy()) if copy else (p.c, p.G)
    c[:, aid, -1] += d
    G[:, aid, -1] += D
    return Pulls(c, G, p.T)


def rotate(p: Pulls, coarse: int = 0, close_coarse: bool = False) -> Pulls:
    """The current block becomes the newest fine block; the oldest fine block goes into
    the coarse partial one (dropped without coarse blocks).  With ``close_coarse`` the
    coarse partial block then becomes the newest coarse block, the oldest dropped.  A lazy
    ``p`` is made explicit first and stays lazy (T = I from here)."""
    lazy = p.T is not None
    p = explicit(p)
    first = coarse + 1 if coarse else 0  # the oldest fine block
    out = []
    for a in (p.c, p.G):
        a = a if lazy else a.copy()  # explicit() gave new arrays
        if coarse:
            a[:, :, coarse] += a[:, :, first]
        a[:, :, first:-1] = a[:, :, first + 1 :].copy()
        a[:, :, -1] = 0.0
        if coarse and close_coarse:
            a[:, :, :coarse] = a[:, :, 1 : coarse + 1].copy()
            a[:, :, coarse] = 0.0
        out.append(a)
    if not lazy:
        return Pulls(out[0], out[1])
    B, A, _, n = out[0].shape
    return Pulls(out[0], out[1], _identity(B, A, n))


def windows(p: Pulls, aid: int, first: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(B, nb + 1, n), (B, nb + 1, n, n): the pull and its covariance of the windows
    "current block + the last j full blocks", j = 0..nb (shortest first); with
    ``first``, the ``first`` shortest only (the same sums: a prefix of the others)."""
    J = p.c.shape[2]
    k = J if first is None else min(first, J)
    c_b, G_b = p.c[:, aid, J - k :], p.G[:, aid, J - k :]  # the k newest blocks
    if p.T is not None and k > 1:  # the closed ones as of now
        cc, GG = _mapped(p.T[:, aid : aid + 1], c_b[:, None, :-1], G_b[:, None, :-1])
        c_b = np.concatenate([cc[:, 0], c_b[:, -1:]], axis=1)
        G_b = np.concatenate([GG[:, 0], G_b[:, -1:]], axis=1)
    return np.cumsum(c_b[:, ::-1], axis=1), np.cumsum(G_b[:, ::-1], axis=1)


def clear(p: Pulls, aid: int, where: np.ndarray, window: np.ndarray | None = None) -> Pulls:
    """Aid ``aid``'s accumulators zeroed in the runs ``where`` (B,): all of them, or those
    of the window ``window`` (B,) (index of :func:`windows`: its newest blocks) only."""
    if not where.any():
        return p
    c, G = p.c.copy(), p.G.copy()
    J = c.shape[2]
    w = np.full(where.shape, J - 1) if window is None else np.asarray(window)
    newest = np.arange(J)[None, :] >= (J - 1 - w)[:, None]
    m = where[:, None] & newest  # (B, J)
    c[:, aid] = np.where(m[..., None], 0.0, c[:, aid])
    G[:, aid] = np.where(m[..., None, None], 0.0, G[:, aid])
    return Pulls(c, G, p.T)


def measured(c: np.ndarray, G: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pulls of J windows as aid i measures them: ``H c`` (B, J, m) and ``H Γ Hᵀ``
    (B, J, m, m); c (B, J, n), G (B, J, n, n), H (B, m, n) or (m, n)."""
    H = np.broadcast_to(H, (c.shape[0],) + H.shape[-2:])
    e = np.einsum("bmn,bjn->bjm", H, c)
    HG = np.einsum("bmn,bjnk->bjmk", H, G)
    T = np.einsum("bjmk,bqk->bjmq", HG, H)
    return e, 0.5 * (T + np.swapaxes(T, -1, -2))


def separation(
    c: np.ndarray, G: np.ndarray, H: np.ndarray, rtol: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """``λ = (H c)ᵀ (H Γ Hᵀ)⁺ (H c)`` and its degrees of freedom (the rank).

    Parameters
    ----------
    c : (B, J, n) pulls of J windows.   G : (B, J, n, n) their covariances.
    H : (B, m, n) or (m, n) the aid's measurement matrix.

    Returns
    -------
    lam : (B, J).   dof : (B, J) int, the rank of ``H Γ Hᵀ`` (tolerance ``rtol`` of its
    largest eigenvalue; 0 for an empty window).
    """
    e, T = measured(c, G, H)
    return separation_of(e, T, rtol)


def separation_of(
    e: np.ndarray, T: np.ndarray, rtol: float = 1e-9
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`separation` from the measured pulls ``e`` (B, J, m), ``T`` (B, J, m, m)."""
    w, V = np.linalg.eigh(T)
    top = np.abs(w).max(-1, keepdims=True)
    keep = (w > rtol * top) & (top > 0)
    proj = np.einsum("bjmi,bjm->bji", V, e)
    lam = np.where(keep, proj**2 / np.where(keep, w, 1.0), 0.0).sum(-1)
    return lam, keep.sum(-1)
