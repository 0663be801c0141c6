"""The filter watches itself: consistency, trust and availability from its own outputs.

Nothing here reads a truth: every number comes from what a method reported while it ran
(:class:`~ftnav.engine.driver.Trace`, :class:`~ftnav.eval.montecarlo.MethodResult`), so a
user's recording is watched exactly as a simulation is.  Per method and aid:

* **consistency** — the NIS of every finite measurement against the method's own
  prediction (``nis``), averaged over consecutive windows of ``window_s`` (after
  ``skip_initial``): under a consistent filter the sum of ``n`` NIS of dimension ``m``
  is ``χ²(n m)``, so a window's mean lies above ``χ²_{nm}(1 − p/2) / n`` with probability
  ``p/2``, independently from window to window (the innovations are white).  A run in
  which more windows than that lie above it (a binomial tail below ``p/2``), or one
  window whose NIS sum alone lies beyond chance among the run's windows (its χ² tail
  times the number of windows below ``p/2``: a fault's end the filter had followed,
  one window 200 times the band, in a run of eight), is *inconsistent* with that aid
  (its covariance is optimistic, or the aid is faulty and in use): together at most
  one run in ``1/p`` of a consistent filter (``tests/statistical/test_integrity_level.py``);
  reported from the end of the first window that decided it.  Judged again without
  the epochs the guard held the aid: if that is consistent, the finding says the
  disagreement came only while the aid was held (a faulty aid left out, or the estimate
  drifting without a healthy one; still a finding: a lock-out looks the same).  Windows
  holding fewer than ``MIN_SAMPLES`` measurements are
  not judged;
* **availability** — the fraction of the aid's scheduled epochs at which it had a
  finite measurement (an aid gated off outside its terrain, a receiver in an outage),
  and the fraction of those the method used (not gated, not isolated);
* **isolation** — what the guard did: held epochs, rollbacks, rollbacks undone,
  relaxed re-admissions, time isolated with the aid's quantity unheld; an aid isolated
  and re-admitted again and again (``TOGGLES`` times in a run) with a large NIS while
  held is what a noise increase looks like, which an adaptive noise (``noise = "vb"``)
  takes without losing the aid: said so;
* **trust** — the fused horizontal position σ against ``sigma_bound_m`` (an alert limit;
  integrated models only): a solution whose σ passes it, once it had met it, no longer
  meets the bound (it diverged, or coasted too long).

:func:`watch` returns a :class:`MethodWatch` with one-line findings (method, aid, time)
that the command line prints as ``ftnav: warning:`` lines and ``metrics.json`` records
under ``integrity``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from scipy.stats import binom, chi2

__all__ = ["MIN_SAMPLES", "AidWatch", "MethodWatch", "WatchSettings", "nis_band", "watch"]

#: a window holding fewer measurements than this is not judged
MIN_SAMPLES = 10
#: isolations of one aid in one run that suggest a noise increase, not a fault
TOGGLES = 10
#: every aid that measured left out this long (s) is a lock-out finding
LOCKOUT_S = 30.0
#: the words of the findings that say a method's numbers are a coast's or past its
#: bound (printed first, :func:`ftnav.cli`'s warnings)
LOCKED_OUT, OVER_BOUND = "every aid that measured was left out", "the horizontal position σ passed"
GRAVE = (LOCKED_OUT, OVER_BOUND)


class WatchSettings(NamedTuple):
    """What the watch judges against (``[watch]`` of a scenario or recording file).

    Attributes
    ----------
    window_s : the window of the NIS mean (s).
    probability : the two-sided probability outside the NIS band of a consistent filter,
        and the probability that a consistent filter's run is reported inconsistent.
    sigma_bound_m : the bound on the fused horizontal position σ (m), or None.
    availability : an aid whose availability or use falls below this fraction is reported.
    skip_initial : the initial transient (s) the consistency is not judged over.
    """

    window_s: float = 60.0
    probability: float = 0.01
    sigma_bound_m: float | None = None
    availability: float = 0.5
    skip_initial: float = 0.0


class AidWatch(NamedTuple):
    """One aid of one method over every run (fractions over runs and epochs).

    Attributes
    ----------
    name : the aid.
    availability : finite measurements / scheduled epochs.
    used : measurements the method used / finite measurements.
    mean_nis : mean NIS / dimension over the finite measurements (1: consistent).
    inconsistent : fraction of the runs inconsistent with the aid (module docstring);
        runs_inconsistent : how many; first_inconsistent_s : the earliest such time.
    isolated : fraction of the finite measurements the guard held.
    isolations : times the aid was isolated, summed over the runs.
    rollbacks, undone, relaxed : counts over the runs.
    taken : re-admissions that took the aid's jump as its new value (the only aid
        measuring, held past its patience), counted over the runs.
    unobservable_s : seconds isolated with the aid's quantity unheld, summed over runs.
    noisy : measurements held but used with the noise they showed (the only aid
        measuring, its noise above its R), counted over the runs.
    """

    name: str
    availability: float
    used: float
    mean_nis: float
    inconsistent: float
    runs_inconsistent: int
    first_inconsistent_s: float | None
    isolated: float
    isolations: int
    rollbacks: int
    undone: int
    relaxed: int
    taken: int
    unobservable_s: float
    noisy: int = 0


class MethodWatch(NamedTuple):
    """One method's watch (module docstring).

    Attributes
    ----------
    aids : per aid.
    runs : how many runs were watched.
    max_sigma_h_m : the largest fused horizontal position σ (m), None for a linear model.
    runs_over_bound : runs whose σ passed ``sigma_bound_m``; first_over_bound_s : when.
    findings : one line each (method, aid, time), for ``ftnav: warning:``.
    locked_out_s : the longest time over which every aid that measured was left out
        (isolated or gated: the solution coasted although measurements came), s.
    """

    aids: tuple[AidWatch, ...]
    runs: int
    max_sigma_h_m: float | None
    runs_over_bound: int
    first_over_bound_s: float | None
    findings: tuple[str, ...]
    locked_out_s: float = 0.0

    @property
    def locked_out(self) -> bool:
        """Every aid that measured left out for :data:`LOCKOUT_S` or longer."""
        return self.locked_out_s >= LOCKOUT_S

    @property
    def trusted(self) -> bool:
        """No finding: consistent with every aid, every aid available, within the bound."""
        return not self.findings

    def aid(self, name: str) -> AidWatch:
        """The watch of the aid ``name``.

        Raises
        ------
        KeyError
            No aid of that name was watched.
        """
        for a in self.aids:
            if a.name == name:
                return a
        raise KeyError(name)

    def as_dict(self) -> dict[str, Any]:
        """The JSON form (``metrics.json``'s ``integrity``)."""
        return {
            "trusted": self.trusted,
            "runs": self.runs,
            "max_sigma_h_m": self.max_sigma_h_m,
            "runs_over_sigma_bound": self.runs_over_bound,
            "first_over_sigma_bound_s": self.first_over_bound_s,
            "locked_out_s": self.locked_out_s,
            "aids": {
                a.name: {k: v for k, v in a._asdict().items() if k != "name"} for a in self.aids
            },
            "findings": list(self.findings),
        }


def _when(times: np.ndarray, mask: np.ndarray) -> str:
    """``t = T s`` of the first epoch of ``mask`` (B, K), with ``in N of B runs`` for
    several runs."""
    B = mask.shape[0]
    runs = int(mask.any(1).sum())
    return f"t = {_first(times, mask):.1f} s" + (f" in {runs} of {B} runs" if B > 1 else "")


def nis_band(n: np.ndarray, m: int, probability: float) -> tuple[np.ndarray, np.ndarray]:
    """The two-sided band of the mean of ``n`` NIS of dimension ``m`` (module docstring)."""
    dof = np.maximum(n, 1) * m
    lo = chi2.ppf(probability / 2, dof) / np.maximum(n, 1)
    hi = chi2.isf(probability / 2, dof) / np.maximum(n, 1)
    return lo, hi


def _inconsistent(
    times: np.ndarray, q: np.ndarray, av: np.ndarray, m: int, w: int, probability: float
) -> tuple[np.ndarray, float | None]:
    """(B,) runs inconsistent with an aid and the earliest time one is (module docstring).

    ``q`` (B, K) the NIS where ``av``, windows of ``w`` epochs from the first judged one.
    """
    B, K = q.shape
    start = int(np.argmax(av.any(0))) if av.any() else K
    n_win = (K - start) // w
    if n_win < 1:
        return np.zeros(B, bool), None
    sl = slice(start, start + n_win * w)
    n = av[:, sl].reshape(B, n_win, w).sum(-1)
    s = np.where(av, q, 0.0)[:, sl].reshape(B, n_win, w).sum(-1)
    _, hi = nis_band(n, m, probability)
    full = n >= MIN_SAMPLES
    above = full & (s / np.maximum(n, 1) > hi)
    judged = full.sum(1)
    count = above.sum(1)
    # P(X >= count) for X ~ Binomial(judged windows, p/2): more windows above than chance
    tail = binom.sf(count - 1, judged, probability / 2)
    many = (count > 0) & (tail < probability / 2)
    # one window whose NIS sum alone is beyond chance among the run's windows (Bonferroni)
    p_win = chi2.sf(s, np.maximum(n, 1) * m)
    extreme = full & (p_win * np.maximum(judged, 1)[:, None] < probability / 2)
    bad = many | extreme.any(1)
    first = None
    if bad.any():
        which = np.where(many[:, None], above, extreme)
        ends = times[start + (np.argmax(which, 1) + 1) * w - 1]
        first = float(ends[bad].min())
    return bad, first


def _longest_coast(times: np.ndarray, present: np.ndarray, out: np.ndarray) -> tuple[float, float]:
    """The longest span (s) and its start over which every epoch with a measurement
    (``present``, (B, K)) had it left out (``out``); epochs without one do not end it."""
    best, start = 0.0, float("nan")
    for p, o in zip(present, out, strict=True):
        k = np.flatnonzero(p)
        if k.size == 0:
            continue
        bad = o[k]
        # runs of consecutive present epochs all left out
        edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            span = float(times[k[b - 1]] - times[k[a]])
            if span > best:
                best, start = span, float(times[k[a]])
    return best, start


def _first(times: np.ndarray, mask: np.ndarray) -> float | None:
    hit = mask.any(0)
    return float(times[np.argmax(hit)]) if hit.any() else None


def _after_first(ok: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """(B, K) ``bad`` from the first epoch of each run where ``ok`` held on (a bound the
    solution met, an aid it had: losing it is news, not having it from the start)."""
    return bad & (np.cumsum(ok, 1) > 0)


def watch(
    name: str,
    times: np.ndarray,
    sensors: Sequence[str],
    dims: Sequence[int],
    nis: np.ndarray,
    available: np.ndarray,
    used: np.ndarray,
    scheduled: np.ndarray,
    guard: Any = None,
    sigma_h: np.ndarray | None = None,
    settings: WatchSettings | None = None,
    adaptive: Sequence[bool] | None = None,
) -> MethodWatch:
    """Watch one method (module docstring).

    Parameters
    ----------
    name : the method (in the findings).
    times : (K,) epoch times (s).
    sensors, dims : the aids' names and measurement dimensions.
    nis, available, used : (B, K, N) what the method reported.
    scheduled : (B, K, N) bool, the epochs each aid was due (its schedule and outages).
    guard : the guard's trace (:class:`~ftnav.engine.driver.GuardTrace`), or None.
    sigma_h : (B, K) the fused horizontal position σ (m), or None.
    settings : what to judge against (default :class:`WatchSettings`).
    adaptive : per aid, whether the method adapts its noise (VB): no noise advice then.
    """
    settings = WatchSettings() if settings is None else settings
    adaptive = [False] * len(sensors) if adaptive is None else list(adaptive)
    B, K, N = nis.shape
    dt = float(times[1] - times[0]) if K > 1 else 1.0
    w = max(1, int(round(settings.window_s / dt)))
    judged = times >= settings.skip_initial
    findings: list[str] = []
    aids = []
    for i, (sensor, m) in enumerate(zip(sensors, dims, strict=True)):
        av, us, sc = available[..., i], used[..., i], scheduled[..., i]
        n_av = int(av.sum())
        q = np.where(av, nis[..., i], 0.0)
        over, first = _inconsistent(times, q, av & judged[None], m, w, settings.probability)
        availability = float(av.sum() / max(sc.sum(), 1))
        used_frac = float(us.sum() / max(n_av, 1))
        held = rollbacks = undone = relaxed = taken = isolations = 0
        unobs_s = 0.0
        noisy = 0
        toggling = 0
        if guard is not None:
            hold = guard.hold[..., i]
            held = int((hold & av).sum())
            starts = hold[:, 1:] & ~hold[:, :-1]
            isolations = int(starts.sum())
            held_nis = q[hold & av].mean() / m if (hold & av).any() else 0.0
            toggling = int((starts.sum(1) >= TOGGLES).sum()) if held_nis > 2.0 else 0
            rollbacks = int(guard.rollback[..., i].sum())
            undone = int(guard.undone[..., i].sum())
            relaxed = int(guard.relaxed[..., i].sum())
            taken = int(guard.taken[..., i].sum())
            unobs_s = float(guard.unobservable[..., i].sum() * dt)
            noisy = int(guard.noisy[..., i].sum())
        aw = AidWatch(
            sensor,
            availability,
            used_frac,
            float(q.sum() / max(n_av * m, 1)),
            float(over.mean()),
            int(over.sum()),
            first,
            float(held / max(n_av, 1)),
            isolations,
            rollbacks,
            undone,
            relaxed,
            taken,
            unobs_s,
            noisy,
        )
        aids.append(aw)
        runs = f" in {aw.runs_inconsistent} of {B} runs" if B > 1 else ""
        # judged again on the measurements the guard did not hold: consistent there, the
        # disagreement was the isolation's (a faulty aid left out, or the estimate
        # drifting without a healthy one: both said, neither dismissed)
        only_held = False
        if first is not None and guard is not None:
            kept = av & ~guard.hold[..., i] & judged[None]
            only_held = _inconsistent(times, q, kept, m, w, settings.probability)[1] is None
        if first is not None:
            why = (
                "only while the guard held it: the aid was faulty there (left out), or the "
                "estimate drifted without it"
                if only_held
                else "the filter's covariance is optimistic or the aid is faulty and in use"
            )
            findings.append(
                f"methods[{name}]: inconsistent with aid {sensor!r} from t = {first:.1f} s"
                f"{runs}: its mean NIS over {settings.window_s:g} s windows above the "
                f"{100 * (1 - settings.probability / 2):g} % bound more often than chance, "
                f"or once far beyond it "
                f"(mean NIS/dof {aw.mean_nis:.3g}), {why}"
            )
        if sc.any() and availability < settings.availability:
            t_gone = _first(times, _after_first(av, sc & ~av)) or _first(times, sc & ~av)
            findings.append(
                f"methods[{name}]: aid {sensor!r} had a measurement at only "
                f"{100 * availability:.0f} % of its epochs (first missing at t = "
                f"{t_gone:.1f} s): the solution runs without it there"
            )
        elif n_av and used_frac < settings.availability:
            t_out = _first(times, av & ~us)
            findings.append(
                f"methods[{name}]: aid {sensor!r} used at only {100 * used_frac:.0f} % of its "
                f"measurements (gated or isolated; first left out at t = {t_out:.1f} s)"
            )
        if toggling and not adaptive[i]:
            findings.append(
                f"methods[{name}]: aid {sensor!r} isolated and re-admitted {TOGGLES} times or "
                f"more in {toggling} of {B} run(s), its NIS large while isolated: a noise "
                f"increase looks like this, which an adaptive noise (noise = 'vb') takes "
                f"without losing the aid"
            )
        if taken and guard is not None:
            when = _when(times, guard.taken[..., i])
            faded = int(guard.faded[..., i].sum())
            widened = (
                f"; {faded} of these, or their ends, with the whole covariance widened: the "
                f"other aids see it only as a bias the estimate learned from its old level"
                if faded
                else ""
            )
            findings.append(
                f"methods[{name}]: aid {sensor!r}, where no other aid measuring could judge "
                f"its jump, jumped and was taken back with its jump as its new value after "
                f"the guard's patience (first at {when}; {taken} time(s){widened}): a step "
                f"of it that lasts is followed from there, as the plain filter follows it"
            )
        if noisy and guard is not None:
            when = _when(times, guard.noisy[..., i])
            findings.append(
                f"methods[{name}]: aid {sensor!r}, the only aid measuring, was held for a "
                f"noise far above its R and used with the noise it showed (from {when}; "
                f"{noisy} measurement(s)): the solution is as noisy as the aid there; an "
                f"adaptive noise (noise = 'vb') takes this without the hold"
            )
        if unobs_s > 0 and guard is not None:
            t_u = _first(times, guard.unobservable[..., i])
            n_unobs = int(guard.unobservable[..., i].any(1).sum())
            per_run = (
                f" in {n_unobs} of {B} runs, {unobs_s / max(n_unobs, 1):.1f} s each"
                if B > 1
                else f" {unobs_s:.1f} s"
            )
            findings.append(
                f"methods[{name}]: aid {sensor!r} isolated while the rest of the system "
                f"does not hold what it measures (from t = {t_u:.1f} s{per_run}; "
                f"{relaxed} re-admission(s) with the covariance inflated): a fault of it "
                f"cannot be told apart from drift for long there"
            )
    if guard is not None and guard.device.any():
        whole = [s for i, s in enumerate(sensors) if guard.device[..., i].any()]
        findings.append(
            f"methods[{name}]: aids {', '.join(map(repr, whole))}, held with no other "
            f"sensor measuring or none that could judge them, were taken back (a device "
            f"consistent with itself, or past the longest coast) while the estimate had "
            f"drifted from them "
            f"(first at {_when(times, guard.device.any(-1))}; "
            f"{int(guard.device.any(-1).sum())} time(s)): the INS or its model, not the "
            f"aid, failed there, and the covariance was widened to re-learn from the aid"
        )
    present = np.asarray(available.any(-1), bool)
    coast, coast_from = _longest_coast(times, present, present & ~np.asarray(used.any(-1), bool))
    if coast >= LOCKOUT_S:
        findings.append(
            f"methods[{name}]: {LOCKED_OUT} for {coast:.0f} s from "
            f"t = {coast_from:.1f} s (isolated or gated): the solution coasted on its "
            "model alone while measurements came, a lock-out unless every aid was faulty "
            "at once; its numbers there are a coast's"
        )
    max_sigma = runs_over = first_over = None
    n_over = 0
    if sigma_h is not None:
        max_sigma = float(np.nanmax(sigma_h))
        if settings.sigma_bound_m is not None:
            # once met: an initial uncertainty above the bound is not a divergence
            over_b = _after_first(
                sigma_h <= settings.sigma_bound_m, sigma_h > settings.sigma_bound_m
            )
            n_over = int(over_b.any(1).sum())
            first_over = _first(times, over_b)
            if first_over is not None:
                runs_over = f" in {n_over} of {B} runs" if B > 1 else ""
                findings.append(
                    f"methods[{name}]: {OVER_BOUND} "
                    f"{settings.sigma_bound_m:g} m at t = {first_over:.1f} s{runs_over} "
                    f"(up to {max_sigma:.3g} m): the solution no longer meets its bound"
                )
    return MethodWatch(tuple(aids), B, max_sigma, n_over, first_over, tuple(findings), coast)
