"""Sequential tests for slow faults on whitened innovations (spec §3.3).

A slow fault (a drift, a small bias, a growing noise) hides in every single epoch's
χ² test and shows only in the accumulated evidence.  Both tests here read the
whitened innovation ``ν̄ = chol(S)⁻¹ ν`` of each aid, ``N(0, I_m)`` under H0
(:func:`ftnav.fdi.features.whitened_innovation`), and are set from a target mean
number of tests between false alarms, ``arl0`` (the average run length under H0).

**CUSUM** (Page 1954; spec §3.3).  Per whitened component ``j`` two one-sided
mean-shift CUSUMs, ``g⁺ = max(0, g⁺ + ν̄_j − k)``, ``g⁻ = max(0, g⁻ − ν̄_j − k)``, with
the drift ``k`` half the shift (in σ) to detect fastest; optionally a variance CUSUM
for ``S → c S`` with the log-likelihood-ratio increment
``−(m/2) ln c + ½ (1 − 1/c) ‖ν̄‖²``.  An alarm when any statistic exceeds its threshold
``h``.  The ``2m`` (+1) CUSUMs of an aid alarm nearly independently, so each is given
``ARL₀ = q · arl0`` (q of them) and its ``h`` solved from the Markov-chain ARL of Brook
& Evans (Biometrika 59, 1972), which :func:`siegmund_arl` (Siegmund 1985, eq. 2.54)
and the published table agree with (two-sided k = 0.5, h = 5: ARL₀ ≈ 465, 10.4 at a 1σ
shift, 38 at 0.5σ; Montgomery, *Introduction to SQC*, table 9.11).

**Windowed GLR** (Basseville & Nikiforov 1993, §2.4.3): the generalized likelihood
ratio of a mean shift of unknown size and direction that started within the last
``W`` tests, maximized over the window lengths ``w`` of a geometric set
``{1, 2, 4, …, W}``: ``λ = max_w ‖Σ_{last w} ν̄‖² / w``, each term ``χ²(m)`` under H0.
Its threshold is the ``χ²(m)`` quantile at ``1/(arl0 · |set|)`` (a per-test alarm
probability at most ``1/arl0``, Bonferroni over the windows, whose overlap makes the
realized ARL₀ larger: tests/statistical/test_sequential.py measures it).

**Correlated innovations** (real sensors).  A GNSS receiver's errors are correlated over
seconds to minutes, so the innovations of a filter that models them white are too, and
a window sum's variance is ``w τ_w`` with ``τ_w = 1 + 2 Σ_j (1 − j/w) ρ_j`` (the
long-run variance of the sequence; Newey & West, Econometrica 55, 1987), not ``w``:
each term above is then ``τ_w χ²(m)``, and the textbook threshold alarms at every
multipath episode (measured on the real drive: 18 isolations, 31 m with GNSS alone).
With ``memory`` set (the default), the GLR learns each window's null level
``τ̂_w`` as the running mean of ``term_w / m`` over the tests that did not alarm (the
mean of the first tests, then an exponential memory of ``memory`` tests) and divides
the term by ``max(τ̂_w, 1)``: never more sensitive than the white test, the threshold
valid for the innovations the aid really has.  A fault slower than the memory is
learned as normal: the memory is long (``50 W`` tests by default).  ``memory = 0`` is
the textbook test.

After an alarm an aid's statistics restart from zero (so a fault that persists alarms
again, and one that ended does not), and the hysteresis of spec §3.1 (``n_on``,
``n_off``) gives the flag.  Arrays carry the batch axis ``(B, N)`` (runs × aids);
components beyond an aid's dimension are padded and never tested.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2, norm

from ftnav.fdi.chi2 import DetectorOutput, apply_hysteresis

__all__ = [
    "CusumDetector",
    "CusumState",
    "GlrDetector",
    "GlrState",
    "cusum_arl",
    "cusum_threshold",
    "glr_threshold",
    "glr_windows",
    "siegmund_arl",
    "variance_cusum_arl",
    "variance_threshold",
]

#: states of the Brook–Evans chain (ARL within 0.1 % of the exact value for h ≤ 20)
CHAIN_STATES = 400


def markov_chain_arl(h: float, cdf: Callable[[np.ndarray], np.ndarray], states: int) -> float:
    """ARL from 0 of the one-sided CUSUM ``g = max(0, g + X)``, alarm at ``g > h``.

    Brook & Evans (1972): ``[0, h]`` cut into ``t`` cells of width ``w = 2h/(2t − 1)``
    (cell 0 is ``[0, w/2]``, cell i ``((i − ½) w, (i + ½) w]``, represented by ``i w``);
    ``P_ij = F((j + ½) w − i w) − F((j − ½) w − i w)``, ``P_i0 = F(w/2 − i w)``, the rest
    leaves the chain (an alarm); the ARLs solve ``(I − P) L = 1``.  ``cdf`` is the
    increment's distribution function (vectorized).
    """
    t = int(states)
    w = 2.0 * h / (2 * t - 1)
    i = np.arange(t)[:, None]
    j = np.arange(t)[None, :]
    upper = cdf((j + 0.5) * w - i * w)
    lower = np.where(j == 0, 0.0, cdf((j - 0.5) * w - i * w))
    P = upper - lower
    L = np.linalg.solve(np.eye(t) - P, np.ones(t))
    return float(L[0])


def cusum_arl(h: float, k: float, shift: float = 0.0, states: int = CHAIN_STATES) -> float:
    """ARL of a one-sided mean CUSUM with drift ``k`` and threshold ``h`` on ``N(shift, 1)``
    (Brook–Evans chain, :func:`markov_chain_arl`)."""
    return markov_chain_arl(h, lambda x: norm.cdf(x, loc=shift - k), states)


def siegmund_arl(h: float, k: float, shift: float = 0.0) -> float:
    """Siegmund's approximation of the one-sided CUSUM's ARL on ``N(shift, 1)``:
    ``(e^{−2Δb} + 2Δb − 1) / (2Δ²)`` with ``Δ = shift − k``, ``b = h + 1.166`` (``b²`` at
    ``Δ = 0``)."""
    d, b = shift - k, h + 1.166
    if abs(d) < 1e-12:
        return b * b
    return (math.exp(-2.0 * d * b) + 2.0 * d * b - 1.0) / (2.0 * d * d)


def variance_cusum_arl(
    h: float, ratio: float, m: int, actual: float = 1.0, states: int = CHAIN_STATES
) -> float:
    """ARL of the variance CUSUM for ``S → ratio · S`` on ``m`` whitened components whose
    true variance is ``actual`` (1 under H0): increments
    ``−(m/2) ln c + ½ (1 − 1/c) ‖ν̄‖²``, ``‖ν̄‖² / actual ~ χ²(m)``."""
    a = -0.5 * m * math.log(ratio)
    b = 0.5 * (1.0 - 1.0 / ratio) * actual
    return markov_chain_arl(h, lambda y: chi2.cdf((y - a) / b, m), states)


def _solve_h(arl: Callable[[float], float], target: float) -> float:
    """The threshold whose ARL₀ is ``target`` (ARL₀ grows with h)."""
    lo, hi = 1e-3, 1.0
    while arl(hi) < target:
        lo, hi = hi, hi * 2.0
        if hi > 1e3:
            raise ValueError(f"arl0: {target:g} is out of reach")
    return float(brentq(lambda h: arl(h) - target, lo, hi, xtol=1e-6))


@lru_cache(maxsize=256)
def cusum_threshold(arl0: float, k: float) -> float:
    """``h`` of a one-sided mean CUSUM (drift ``k``) whose ARL₀ is ``arl0``."""
    return _solve_h(lambda h: cusum_arl(h, k), float(arl0))


@lru_cache(maxsize=256)
def variance_threshold(arl0: float, ratio: float, m: int) -> float:
    """``h`` of the variance CUSUM (``ratio``, ``m`` components) whose ARL₀ is ``arl0``."""
    return _solve_h(lambda h: variance_cusum_arl(h, ratio, m), float(arl0))


def glr_windows(window: int) -> tuple[int, ...]:
    """The geometric set of window lengths ``1, 2, 4, …, W`` (``W`` included)."""
    w = [1]
    while w[-1] * 2 < window:
        w.append(w[-1] * 2)
    if w[-1] != window:
        w.append(int(window))
    return tuple(w)


@lru_cache(maxsize=256)
def glr_threshold(arl0: float, window: int, m: int) -> float:
    """``χ²(m)`` quantile at ``1 / (arl0 · |windows|)`` (module docstring)."""
    return float(chi2.isf(1.0 / (float(arl0) * len(glr_windows(window))), m))


def _check(arl0: float, n_on: int, n_off: int) -> None:
    if not (math.isfinite(arl0) and arl0 > 1.0):
        raise ValueError(f"arl0: must be a finite number > 1, got {arl0}")
    for name, value in (("n_on", n_on), ("n_off", n_off)):
        if int(value) < 1:
            raise ValueError(f"{name}: must be >= 1, got {value}")


def _padded(innovations: Sequence[np.ndarray], width: int) -> np.ndarray:
    """(B, N, width) whitened innovations, zero beyond each aid's dimension."""
    B = innovations[0].shape[0]
    out = np.zeros((B, len(innovations), width))
    for i, w in enumerate(innovations):
        out[:, i, : w.shape[-1]] = w
    return out


class CusumState(NamedTuple):
    """Running CUSUM statistics, (B, N, m_max) or (B, N), and the hysteresis."""

    up: np.ndarray
    down: np.ndarray
    var: np.ndarray
    on_count: np.ndarray
    off_count: np.ndarray
    flag: np.ndarray


class CusumDetector:
    """Two-sided mean CUSUMs per whitened component (+ a variance CUSUM), per aid.

    Parameters
    ----------
    dims : each aid's measurement dimension m_i.
    arl0 : target mean number of tests of an aid between false alarms (all its CUSUMs).
    drift : k, half the mean shift (σ of the whitened innovation) detected fastest.
    variance_ratio : c > 1 adds the variance CUSUM for ``S → c S``; None: none.
    n_on, n_off : hysteresis counts (spec §3.1).
    """

    def __init__(
        self,
        dims: Sequence[int],
        arl0: float,
        drift: float = 0.5,
        variance_ratio: float | None = None,
        n_on: int = 1,
        n_off: int = 5,
    ):
        _check(arl0, n_on, n_off)
        if not (math.isfinite(drift) and drift > 0):
            raise ValueError(f"drift: must be a finite number > 0, got {drift}")
        if variance_ratio is not None and not (
            math.isfinite(variance_ratio) and variance_ratio > 1
        ):
            raise ValueError(f"variance_ratio: must be a finite number > 1, got {variance_ratio}")
        self.dims = np.asarray(dims, dtype=int)
        self.m = int(self.dims.max(initial=1))
        self.drift = float(drift)
        self.ratio = variance_ratio
        self.n_on, self.n_off = int(n_on), int(n_off)
        q = 2 * self.dims + (variance_ratio is not None)
        self.h_mean = np.array([cusum_threshold(float(arl0 * qi), self.drift) for qi in q])
        self.h_var = (
            np.array(
                [
                    variance_threshold(float(arl0 * qi), variance_ratio, int(m))
                    for qi, m in zip(q, self.dims, strict=True)
                ]
            )
            if variance_ratio is not None
            else None
        )
        self.component = np.arange(self.m)[None, :] < self.dims[:, None]  # (N, m_max)

    def init(self, batch: int, n_filters: int) -> CusumState:
        z = np.zeros((batch, n_filters, self.m))
        zi = np.zeros((batch, n_filters), dtype=int)
        return CusumState(z, z.copy(), np.zeros((batch, n_filters)), zi, zi.copy(), zi.astype(bool))

    def step(
        self, state: CusumState, innovations: Sequence[np.ndarray], tested: np.ndarray
    ) -> tuple[CusumState, DetectorOutput]:
        """One epoch: ``innovations`` per aid (B, m_i) whitened, ``tested`` (B, N)."""
        nu = _padded(innovations, self.m)
        t3 = tested[..., None] & self.component[None]
        up = np.where(t3, np.maximum(0.0, state.up + nu - self.drift), state.up)
        down = np.where(t3, np.maximum(0.0, state.down - nu - self.drift), state.down)
        h = self.h_mean[None, :]
        ratio = np.maximum(up.max(-1), down.max(-1)) / h
        var = state.var
        if self.ratio is not None:
            assert self.h_var is not None
            c = self.ratio
            inc = -0.5 * self.dims * math.log(c) + 0.5 * (1.0 - 1.0 / c) * (nu**2).sum(-1)
            var = np.where(tested, np.maximum(0.0, state.var + inc), state.var)
            ratio = np.maximum(ratio, var / self.h_var[None, :])
        raw = tested & (ratio > 1.0)
        on, off, flag = apply_hysteresis(state, raw, tested, self.n_on, self.n_off)  # type: ignore[arg-type]
        # an alarm restarts the aid's statistics (module docstring)
        up = np.where(raw[..., None], 0.0, up)
        down = np.where(raw[..., None], 0.0, down)
        var = np.where(raw, 0.0, var)
        out = DetectorOutput(np.where(tested, ratio, 0.0), np.ones(raw.shape), raw, flag)
        return CusumState(up, down, var, on, off, flag), out


class GlrState(NamedTuple):
    """The last W tested whitened innovations (B, N, W, m_max), how many, the hysteresis,
    and each window's learned null level with its number of updates (B, N, |windows|)."""

    history: np.ndarray
    count: np.ndarray
    on_count: np.ndarray
    off_count: np.ndarray
    flag: np.ndarray
    level: np.ndarray
    seen: np.ndarray


class GlrDetector:
    """Windowed GLR of a mean shift in the whitened innovations, per aid (module docstring).

    Parameters
    ----------
    dims : each aid's measurement dimension m_i.
    arl0 : target mean number of tests of an aid between false alarms.
    window : W, the longest window (tests).
    n_on, n_off : hysteresis counts (spec §3.1).
    memory : tests over which each window's null level is learned (module docstring,
        correlated innovations); None: ``50 W``; 0: none (the textbook test).
    """

    def __init__(
        self,
        dims: Sequence[int],
        arl0: float,
        window: int = 64,
        n_on: int = 1,
        n_off: int = 5,
        memory: int | None = None,
    ):
        _check(arl0, n_on, n_off)
        if int(window) < 1:
            raise ValueError(f"window: must be >= 1, got {window}")
        memory = 50 * int(window) if memory is None else int(memory)
        if memory < 0:
            raise ValueError(f"memory: must be >= 0, got {memory}")
        self.memory = memory
        self.dims = np.asarray(dims, dtype=int)
        self.m = int(self.dims.max(initial=1))
        self.window = int(window)
        self.windows = glr_windows(self.window)
        self.n_on, self.n_off = int(n_on), int(n_off)
        self.h = np.array([glr_threshold(float(arl0), self.window, int(m)) for m in self.dims])

    def init(self, batch: int, n_filters: int) -> GlrState:
        zi = np.zeros((batch, n_filters), dtype=int)
        nw = len(self.windows)
        return GlrState(
            np.zeros((batch, n_filters, self.window, self.m)),
            zi,
            zi.copy(),
            zi.copy(),
            zi.astype(bool),
            np.ones((batch, n_filters, nw)),
            np.zeros((batch, n_filters, nw), dtype=int),
        )

    def terms(self, history: np.ndarray, count: np.ndarray) -> np.ndarray:
        """(B, N, |windows|) ``‖Σ_{last w} ν̄‖² / w`` (0 where the history is short)."""
        # newest last: the sum of the last w rows is a suffix sum
        suffix = np.cumsum(history[..., ::-1, :], axis=-2)  # (B, N, W, m)
        out = np.zeros(count.shape + (len(self.windows),))
        for i, w in enumerate(self.windows):
            out[..., i] = np.where(count >= w, (suffix[..., w - 1, :] ** 2).sum(-1) / w, 0.0)
        return out

    def statistic(
        self, history: np.ndarray, count: np.ndarray, level: np.ndarray | None = None
    ) -> np.ndarray:
        """(B, N) ``max_w term_w / max(τ̂_w, 1)`` over the windows the history fills
        (``level`` τ̂, default 1: the white test)."""
        terms = self.terms(history, count)
        if level is not None:
            terms = terms / np.maximum(level, 1.0)
        return np.asarray(terms.max(-1))

    def step(
        self, state: GlrState, innovations: Sequence[np.ndarray], tested: np.ndarray
    ) -> tuple[GlrState, DetectorOutput]:
        """One epoch: ``innovations`` per aid (B, m_i) whitened, ``tested`` (B, N)."""
        nu = _padded(innovations, self.m)
        t4 = tested[..., None, None]
        shifted = np.concatenate([state.history[..., 1:, :], nu[..., None, :]], -2)
        hist = np.where(t4, shifted, state.history)
        count = np.where(tested, np.minimum(state.count + 1, self.window), state.count)
        terms = self.terms(hist, count)
        level, seen = state.level, state.seen
        lam = (terms / np.maximum(level, 1.0)).max(-1)
        h = self.h[None, :]
        raw = tested & (lam > h)
        if self.memory > 0:  # the null level, learned from the tests that did not alarm
            full = count[..., None] >= np.asarray(self.windows)
            learn = (tested & ~raw)[..., None] & full
            seen = np.where(learn, seen + 1, seen)
            rate = 1.0 / np.minimum(np.maximum(seen, 1), self.memory)
            r = terms / np.maximum(self.dims, 1)[None, :, None]
            level = np.where(learn, level + rate * (r - level), level)
        on, off, flag = apply_hysteresis(state, raw, tested, self.n_on, self.n_off)  # type: ignore[arg-type]
        hist = np.where(raw[..., None, None], 0.0, hist)
        count = np.where(raw, 0, count)
        out = DetectorOutput(
            np.where(tested, lam, 0.0), np.broadcast_to(h, raw.shape).copy(), raw, flag
        )
        return GlrState(hist, count, on, off, flag, level, seen), out
