"""Rauch–Tung–Striebel fixed-interval smoothing of the closed-loop error states.

The forward pass (:func:`ftnav.engine.driver.run` with ``smoothing=True``) keeps, per
method and epoch k = 1..K, the fused posterior ``x⁺_k`` before the feedback shift, its
full covariance ``P⁺_k`` and the epoch's linearization ``(Φ, Q)``
(:class:`~ftnav.engine.driver.SmoothingRecord`).  The backward pass here is the RTS
smoother (Rauch, Tung and Striebel, AIAA J. 3(8):1445-1450, 1965; Särkkä, *Bayesian
Filtering and Smoothing*, 2013, §8.2, Theorem 8.2) in the closed-loop form of an
error-state filter (spec §6.2, §8.5).  Below, ``Φ_k`` and ``Q_k`` are those of the step
``k → k+1`` (the record keeps them at epoch k+1):

* after the feedback at k the forward estimate refers to the corrected solution:
  ``x^r_k`` is ``x⁺_k`` with its first ``n_fed`` (fed-back) states zeroed, and the
  covariance is unchanged; the next prior is ``x⁻_{k+1} = Φ_k x^r_k``;
* ``P⁻_{k+1} = Φ_k P⁺_k Φ_kᵀ + Q_k`` and ``G_k = P⁺_k Φ_kᵀ (P⁻_{k+1})⁻¹`` (a Cholesky
  solve, :func:`ftnav.core.linalg.spd_solve`; never an explicit inverse);
* the smoothed estimate at k+1 in the frame before k+1's reset (the frame of
  ``x⁻_{k+1}``) is ``x^s_{k+1} + (x⁺_{k+1} − x^r_{k+1})``, and
  ``x^s_k = x^r_k + G_k (x^s_{k+1} + x⁺_{k+1} − x^r_{k+1} − Φ_k x^r_k)``,
  ``P^s_k = P⁺_k + G_k (P^s_{k+1} − P⁻_{k+1}) G_kᵀ`` (symmetrized), from
  ``x^s_K = x^r_K``, ``P^s_K = P⁺_K``;
* the smoothed navigation solution at k is the solution ``x^r_k`` refers to (the
  corrected one with feedback, the free SINS with output correction) with the smoothed
  navigation errors ``x^s_k[:9]`` removed (:func:`ftnav.nav.mechanization.apply_correction`).

With output correction nothing is fed back (``n_fed = 0``) and these are the plain RTS
equations.  With a linear error model the closed-loop and the open-loop smoothers give
the same estimate of the navigation solution (``tests/equivalence/test_smoother.py``).

What it is exact for: the centralized filter (and the distributed filter and the
fusion-reset federated filter on linear models, which equal it, spec §1.6, §6.1) with
no private states.  For the other architectures (federated without reset, zero-reset,
the neuron centre, and any isolation, VB adaptation or guard rollback), it smooths the
fused posterior with the common model as if it came from one Kalman filter: an
approximation.  Private states (e.g. a GNSS Markov error augmented, spec §1.7) are not
in the fused output; their correlation with the common states is lost, also an
approximation.  An aid with measurement differencing (GNSS ``markov = "difference"``)
is refused by the forward pass: its measurements correlate consecutive epochs, which
the plain RTS smoother does not cover.

Every array has a leading batch axis (runs); the loop is over epochs only.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.core.linalg import spd_solve
from ftnav.engine.driver import N_NAV, SmoothingRecord, Trace
from ftnav.nav.mechanization import InsState, apply_correction
from ftnav.types import Array

__all__ = ["SmoothedTrace", "rts_smoother", "smooth", "smoothed_trace"]


class SmoothedTrace(NamedTuple):
    """One method's smoothed outputs over B runs and K epochs.

    Attributes
    ----------
    solution : the smoothed navigation solution, q (B, K, 4), v (m/s), p (rad, rad, m)
        (B, K, 3) (``a`` zeros, as :attr:`~ftnav.engine.driver.Trace.solution`), or
        None for a linear model.
    x : (B, K, n_c) smoothed error-state estimate in the frame of
        :attr:`~ftnav.engine.driver.Trace.x` (before the epoch's feedback).
    P_diag : (B, K, n_c) its variances (diagonal of ``P^s_k``).
    P_nav : (B, K, 9, 9) the smoothed covariance of the navigation error states.
    """

    solution: InsState | None
    x: Array
    P_diag: Array
    P_nav: Array


def rts_smoother(x: Array, P: Array, Phi: Array, Q: Array, n_fed: int = 0) -> tuple[Array, Array]:
    """Closed-loop RTS backward pass (module docstring; Särkkä 2013 Theorem 8.2).

    Parameters
    ----------
    x : (B, K, n) forward posteriors ``x⁺_k`` before the feedback shift.
    P : (B, K, n, n) their covariances ``P⁺_k``.
    Phi, Q : (B, K, n, n) transition and process noise of the step ``k−1 → k`` at index
        k (index 0, the step from the initial state, is not used).
    n_fed : states fed back after every epoch (zeroed in the estimate after the reset);
        0 for output correction (the plain RTS smoother).

    Returns
    -------
    x_s : (B, K, n) smoothed estimates in the frame of ``x`` (before the reset).
    P_s : (B, K, n, n) their covariances (symmetric).
    """
    if x.ndim != 3 or P.shape != x.shape + x.shape[-1:]:
        raise ValueError(f"x (B, K, n) and P (B, K, n, n): got {x.shape} and {P.shape}")
    if Phi.shape != P.shape or Q.shape != P.shape:
        raise ValueError(f"Phi and Q must be {P.shape}: got {Phi.shape} and {Q.shape}")
    n = x.shape[-1]
    if not 0 <= n_fed <= n:
        raise ValueError(f"n_fed must be in [0, {n}]: got {n_fed}")
    K = x.shape[1]
    fed = np.zeros_like(x)
    fed[..., :n_fed] = x[..., :n_fed]
    x_r = x - fed  # the forward estimate after the reset
    x_s = np.empty_like(x)
    P_s = np.empty_like(P)
    x_s[:, K - 1], P_s[:, K - 1] = x_r[:, K - 1], P[:, K - 1]
    for k in range(K - 2, -1, -1):
        Pk, F = P[:, k], Phi[:, k + 1]
        x_prior, P_prior = kf.predict(x_r[:, k], Pk, F, Q[:, k + 1])
        G = kf.mT(spd_solve(P_prior, F @ Pk))  # P⁺ Φᵀ (P⁻)⁻¹, P⁺ and P⁻ symmetric
        ahead = x_s[:, k + 1] + fed[:, k + 1]  # smoothed at k+1 before its reset
        x_s[:, k] = x_r[:, k] + kf.mv(G, ahead - x_prior)
        P_s[:, k] = kf.symmetrize(Pk + G @ (P_s[:, k + 1] - P_prior) @ kf.mT(G))
    return x_s + fed, P_s


def smooth(trace: Trace) -> SmoothedTrace:
    """The smoothed estimate and solution of one method's trace (module docstring).

    ``trace`` must come from :func:`ftnav.engine.driver.run` with ``smoothing=True``
    (ValueError otherwise).  Memory: besides the record, the smoothed covariances,
    B·K·n² floats, for the time of the call.
    """
    rec: SmoothingRecord | None = trace.smoothing
    if rec is None:
        raise ValueError("smooth: the trace has no smoothing record (run(..., smoothing=True))")
    x_s, P_s = rts_smoother(rec.x, rec.P, rec.Phi, rec.Q, rec.n_fed)
    solution = None
    if rec.base is not None:
        m = min(rec.n_fed, N_NAV)
        d = x_s[..., :N_NAV].copy()
        d[..., :m] -= rec.x[..., :m]  # x^s_k after the reset: relative to the base
        B, K = d.shape[:2]
        q, v, p = apply_correction(
            rec.base.q.reshape(B * K, 4),
            rec.base.v.reshape(B * K, 3),
            rec.base.p.reshape(B * K, 3),
            d[..., 0:3].reshape(B * K, 3),
            d[..., 3:6].reshape(B * K, 3),
            d[..., 6:9].reshape(B * K, 3),
        )
        solution = InsState(
            q.reshape(B, K, 4), v.reshape(B, K, 3), p.reshape(B, K, 3), np.zeros((B, K, 3))
        )
    return SmoothedTrace(
        solution,
        x_s,
        np.diagonal(P_s, axis1=-2, axis2=-1).copy(),
        P_s[..., :N_NAV, :N_NAV].copy(),
    )


def smoothed_trace(trace: Trace, smoothed: SmoothedTrace) -> Trace:
    """``trace`` with its estimate, variances, navigation covariance (where kept) and
    solution replaced by the smoothed ones, so that what scores or writes a trace
    (:mod:`ftnav.eval.recorded`, :mod:`ftnav.io.solution_file`) takes it as it is; the
    detection, NIS and noise fields stay the forward filter's.  A smoothed solution has
    no prediction (the forward filter's was scored as the smoothed one's)."""
    return replace(
        trace,
        x=smoothed.x,
        P_diag=smoothed.P_diag,
        P_nav=None if trace.P_nav is None else smoothed.P_nav,
        solution=smoothed.solution,
        smoothing=None,
        prediction=None,
    )
