"""Isolation that cannot lock out: the guard every fault-tolerant method runs (issue 20).

A detector says *that* an aid disagrees with the filter; it cannot say whether the aid
or the filter is wrong.  Two things make a healthy aid look faulty for ever after its
fault ended: the filter absorbed a slow fault before anything saw it (it followed a
ramp, and the healthy measurements after the ramp look like a jump), or the filter
drifted while the aid was isolated faster than its covariance says.  The guard tracks,
for every aid, its *pull* on the estimate over windows of up to ``window_s``
(:mod:`ftnav.fdi.separation`: the estimate less the same filter without that aid's
measurements of the window, to first order, and the covariance of that difference),
and decides the method's isolation from its detector's flags:

1. **Rollback.**  At a new isolation, the aid's applied pull over a window is removed
   from the estimate (``x − c``, ``P + Γ``): the window whose removal makes the flagged
   (inconsistent) measurement the most consistent, by more than chance against the same
   widened covariance (the pull points at the jump: a ramp absorbed, now over, the
   measurement jumped back), else the window whose pull is the most significantly too
   large for its covariance (a slow fault still on), or, for an alarm of the separation
   detector, the window that raised it; and every other aid that sees what it moves
   must accept the rolled-back estimate (a wrong rollback would make them disagree).
   A pull merely too large for its covariance counts only where another aid sees the
   estimate: a sole source's pulls are as large as the model's optimism makes them on
   real noise (the drive's GNSS alone: a GLR false alarm in a turn rolled 4 m of its
   pulls back, and the coast from there reached 1 km).
   The estimate is then,
   to first order, the filter that never took the aid's measurements of that window.
   One aid at a time: no rollback while another aid is isolated (the pulls of one aid
   are measured against filters that hold every other).  The removed pull is kept as
   the *alternative* when the separation detector alone raised the isolation (the
   measurement itself agreeing with the filter: a model error can do that), and when a
   pull merely too large for its covariance was removed in rows no other aid responds
   to (:meth:`Guard._unseen`): nothing but the aid's own pull speaks for it (a false
   alarm 500 s after a SINS fault found the corrections the aid made then "too large").
   Such a rollback is *deferred* while the flagged measurement agrees with the
   estimate as it is: the estimate stays and the rolled-back one is the alternative,
   applied once the aid disagrees with the estimate and agrees with it (a drag over:
   the measurement jumped back), an ordinary doubtful rollback from then on
   (``seed002``'s receiver after a 1 °/h gyro step: a CUSUM false alarm at a fix that
   agreed rolled the estimate 332 m back for the 20 s until it was undone).  So is any
   rollback of the aid's pulls (too large, or a separation alarm's) over the fine window
   after its relaxed re-admission, where it agrees: those pulls are the re-convergence
   of a model the re-admission found wrong, not a drag (``GuardState.settling``).
   The rollback's move is the estimate's: where the hold began at a jump of the aid,
   its last innovation is taken against the estimate as the rollback left it, so its
   next increment (rule 3) holds the aid's own move only and the hold's jump sum keeps
   the jump the aid made (an alarm without a jump keeps the move in its sum, which the
   patience's taken jump then undoes).
2. **Re-admission.**  After ``n_off`` consecutive tests whose innovation passes its χ²
   against the estimate, with the method's detector quiet (the aid was faulty and its
   fault ended); or after ``confirm`` consecutive tests against the alternative, the
   estimate with the rollback undone, which every other aid that sees what the rollback
   moved accepts as well (the aid was right and a model error made its pull look
   wrong: the rollback is undone; a redundant aid witnesses against a wrong undo).  A
   fault still on fails both.  While the filter coasts without the aid its covariance
   may grow too slowly (nonlinearity, unmodelled scale factors, vibration), so the
   growth since the aid last informed the estimate (an outage's coasting included) is
   allowed ``kappa`` times its σ; an aid taken back only thanks to that allowance comes
   with the covariance inflated along its measurement (``P + γ P Hᵀ (H P Hᵀ)⁻¹ H P``, γ
   giving its innovation a χ² equal to its dimension) and its update at once
   (``relaxed``).  An output repeated bit for bit passes no re-admission test (a frozen
   receiver's stale fix passes as the allowance grows past the distance moved since),
   and its isolation rolls nothing back (the freeze is the aid's own fault).
   A detector that still alarms after ``override`` consecutive passes
   of the guard's tests is overruled until its own flag clears; the guard watches that
   aid with its own χ² meanwhile.  (The passes it counts are those with the detector
   quiet, so with ``n_off < override`` the aid is re-admitted first and the override
   never fires; counting every pass re-admitted the neuron centre's TAN of ``seed001``
   while its +40 m fault lasted, so it was left so.)  After a rollback that explains
   a jump (the fault ended) the detector is overruled at once: the offset the rollback
   left lies inside its covariance, and a sequential detector would take it for the
   mean shift it tests for.
3. **Sole source.**  When, isolated, the filter's predicted variance of the aid's
   measurement has grown ``growth`` times since the aid last informed it, the rest of
   the system does not hold that quantity (a GNSS that is the only position aid): the
   aid is reported (``unobservable``), its re-admission needs no quiet detector (the
   detector tests against the unallowed covariance), and an aid that returns so (after
   an outage) within the allowance is taken at once.  A fault of such an aid longer
   than the coasting can tell apart from drift comes back through the allowance: never
   silently.  Where the model is optimistic (a MEMS INS in a turn) the coast outgrows
   any allowance, so a sole source is also judged by its own **increments**: between
   two measurements ``Δk`` epochs apart a healthy aid's innovation moves from its last
   residual by its two noises and the estimate's drift over those epochs,
   ``2R + κ² Δk² H(Φ − I)P(Φ − I)ᵀHᵀ`` — what the drift accumulated before does not
   enter.  A hold that began without a rollback and without a jump (a *steady* hold:
   an alarm nothing explained) ends, relaxed, after ``n_off`` consistent increments
   once the aid is the sole source; a jump (a step, a frozen output of a moving vehicle,
   a noise increase) ends the steady hold, and the sum of the hold's jumps re-arms it
   when it cancels (the fault's end undid its onset).  Only where no other aid
   measures (the aid is the only one of the estimate): another aid that holds the
   quantity's rate (an odometer, NHC, GNSS velocities) keeps the coasting honest, and
   there a ramp of the aid must stay out (``slowramp``).  Where no other aid measures at
   all, held or not (a held healthy aid must not leave a faulty one the field): once
   ``n_off`` increments in a row were consistent, each consistent increment updates the
   estimate as a measurement of its drift (``Δk H(Φ − I)``, noise 2R: after a step the
   aid moves as the vehicle does, and the coast keeps the vehicle's velocity); an output
   repeated bit for bit (``repeated``: a frozen receiver, which at a crawl passes the
   increment test) is no measurement to the increments (untested, no reference, no
   jump: a freeze is an outage to them); and ``patience_s`` after the hold's last jump
   the jump is *taken* (the plain filter's choice: the estimate moves by the hold's jump
   sum in the measured quantity, carried by the states that are that quantity,
   :func:`_carrier`, the rest of the innovation relaxed), the
   only way back when the jump was the end of a fault the filter had followed (an IMU
   cannot see a constant velocity offset); the taken jump stays in the sum, so the jump
   back at a step's end cancels it.  The patience also ends a hold whose jump no other
   aid measuring can judge: it lies in rows none of them sees, neither the quantity nor
   its rate (a star tracker or an altimeter beside a GNSS that stepped north), and the
   rows they see moved by no more than chance (a noise increase moves them all); the
   jump is then taken in those rows only, the others' rows left to them.  Likewise
   where the others respond to its rows only as a state it does not read would make
   them respond (:meth:`Guard._confounded`: a star tracker's tilt beside GNSS, whose
   velocities' rate an accelerometer bias moves as the tilt does) and those rows went
   unheld (``unobservable``): the jump is taken with the whole covariance scaled to
   cover the aid (``faded``; the biases were learned from the old level).  And a held
   only aid whose last
   :data:`NOISE_WINDOW` increments show a noise variance above :data:`NOISE_RATIO` times
   its R in some component (from their median absolute deviation about their median:
   a jump and the estimate's drift do not move it) is *used with that noise* (per
   component the larger of it and R) where its innovation is consistent with it: a noise
   increase is no jump and no drift, and coasting would trade the aid's noise for the
   INS's drift (the drive's GNSS alone at 10 times its σ: a 148 m coast; at 100 times a
   lock-out).  Its jump sum stays (clearing it lost a followed fast ramp's end: a
   lock-out).  And an aid whose increment undoes the one jump its sum held (an
   intermittent fault's burst ending) is back at its old level and taken at once,
   relaxed — not a repeated output, nor an aid showing a noise increase (its sums cancel
   by chance).  A held aid beside others whose increments show such a noise passes only
   the strict χ², not the allowance, while they do (a noisy value that passes the
   allowance by chance would be taken whole, relaxed).  And an aid re-admitted with a
   jump its sum kept (the allowance took it back with its step) whose new jump undoes
   that sum in every row it moves, rows no other measuring aid reads directly, is
   *home* (:meth:`Guard._home`): the estimate follows the jump back in the measured
   quantity and takes the aid, relaxed (the drive's 2 m GNSS step for 60 s: its end was
   held 40 s, 0.93 m after the fault against ``ckf``'s 0.10 m; now 0.06 m).  A hold
   begun at an aid's first measurement after a gap of at least the patience (an outage)
   has no jump, whatever offset the aid came back with (the coast's drift allowance
   covers the increment over the gap); ended relaxed with its innovation beyond chance,
   it keeps that innovation, the offset the relaxed update takes, as its sum, taken, for
   the same jump back (the drive's fixes back 5 m off after a 60 s outage: the jump back
   was held for the patience).  And a held
   aid beside aids of its rate only (a position beside velocities, an odometer, the
   vehicle constraints) that keeps one constant offset from the estimate for
   ``lasting_s`` has its offset taken (:meth:`Guard._lasting`): its innovation compared
   with its level when its present run of consistent increments began, against its two
   noises and the coast's growth since, never departed from it, so the offset is neither
   the aid's ramp nor the estimate's drift; the estimate moves by it in the rows no
   other aid reads and the aid is re-admitted, relaxed, its jump sum kept for the jump
   back at a step's end.  The rate aids cannot tell one constant offset from another:
   without this a false alarm's rollback of the aid's pulls (an unmodelled manoeuvre's
   corrections found "too large") held it to the end.  ``lasting_s`` counts epochs,
   whatever the aid's rate.  And where the patience ends between the aid's measurements
   (no aid measures there, so every held aid is "only"), nothing can be taken: the jump
   is *due* (``GuardState.due``) and taken at the aid's next measurement, in every row,
   once its offset has kept one level for the patience (a ramp still running moves
   it) and while no other half of its device is held (the device is still failing).
   "No other aid measures" is read by direction beside the vehicle constraints alone
   (gated pseudo-measurements: every aid measuring beside it, held or not, is one,
   :meth:`Guard._constrained`): they read the
   velocity across the track and up, so row by row they respond to every GNSS row's
   rate, yet the along-track motion has no other source.  Where they leave a direction
   of the aid's quantity and of its rate mostly unseen (:meth:`Guard._blind`) the aid is
   a sole source, and its jump is taken in every row.  Counted as witnesses, they let a
   re-admission's jump be rolled back as a pull "too large" and the fixes held while
   the constrained INS ran along the road (the drive's fixes beside NHC and ZUPT only, a
   0.01 m/s ramp of 300 s: 12.5 m after it; fault-free, the GLR 0.94 m against
   ``ckf``'s 0.061).  Beside a sensor (a star tracker and an altimeter beside
   ``seed002``'s GNSS) the rows keep their rules: treated as a sole source there, its
   GNSS ramps ended 0.51 → 12.7 m (0.1 m/s) and 0.49 → 36.4 m (1 m/s).
4. **Separation detector** (``detector = "separation"``).  An aid whose pull over a
   window of up to the detector's ``window_s`` is too large for its covariance raises an
   alarm: the solution-separation test, which sees a ramp the filter follows and no
   innovation test can.  No alarm while another aid is isolated, and of simultaneous
   alarms only the largest counts (the single-fault hypothesis of FDE).
5. **Common mode.**  The method's common-mode rule sees every aid isolated or flagged:
   when a quorum disagrees at once, the shared reference failed, and every hold is
   released with the rest.
6. **Backing.**  A detector's alarm may be the estimate's fault, not the aid's: a gyro
   bias step of the SINS makes a star tracker disagree first (a sequential detector
   sees it before the bias states absorb it), and the isolation then lets the attitude
   run off.  While an aid is held without a jump, every other aid that measures, is not
   held and responds to its rows (:meth:`Guard._unseen`) weighs it by the likelihood of
   its own innovation under "the held aid is right" (against the estimate updated by
   the held aid's measurement) and under "the estimate is right".  The log-likelihood
   ratios are summed over the hold as Page's CUSUM; past ``ln(1/pfa)`` (the guard's
   false-alarm probability), once the hold has lasted the patience, the other aids back
   the held one, and it is re-admitted, relaxed.  Backed by aids not held, the whole
   covariance of the fused estimate is first faded to cover its innovation (as 7's
   device: the estimate drifted, and the biases that drove the drift must be learned,
   not only the quantity the aid measures; covered along the aid's rows only,
   ``seed002``'s star tracker under a 10 °/h pitch-gyro step was flagged again within
   10 s of each backing, five holds over the step, 0.85 and 1.36 m after it against
   ``ckf``'s 0.55 and 0.64).  Not where two held aids back each other: the other may be
   the faulty one, and a faded estimate follows it when it is let back (``slowramp``'s
   odometer 1 m/s off for 400 s held the healthy fix to the end).  A faulty aid's update
   moves the
   estimate away from what they measure (the sum stays at zero); an aid they cannot
   judge gets no backing (``seed002``'s GNSS beside its star tracker).  Where two
   aids of different devices are held at once (a SINS fault flags one after the other),
   a jump no longer says "the aid's own fault" (one fault at a time: the estimate is
   the common cause), so the held aids back each other too, from the patience after
   the hold's onset, and a backed jump is taken.  Not two aids of one device (a
   receiver's positions and velocities), which may fail together.  Independent locals
   (no-reset federated, ``common``): two held aids of different devices back each other
   across the locals, the other locals' aids witnessing through the shared states (a
   healthy fix held beside an odometer's ramp, whose fused reference followed the
   odometer 100 m off: re-admitted at the ramp's end); a single held aid's jump is its
   own (they keep no pulls; their increments and jump sums serve the noise rule and
   the home rule of 3 only).  And a detector's flag of an aid whose device mate is
   held, while the aid's own increment is consistent (3) and an aid of another device
   measures, starts no hold: the mate's hold left the estimate coasting, and the
   coast's drift (the MEMS INS in a turn) shifts this aid's innovations too (the
   drive's GLR held the GNSS velocities at 429 s and flagged the positions 0.25 s
   later: both halves out, the coast 0.7 m; docs/integrity.md §1.7).  Where the device
   is all that measures, the flag may be the only sign of its fault: held as before.
7. **A device consistent with itself.**  Where every aid of one device is held and no
   other sensor measures unheld (the vehicle constraints gated off by the same error),
   every test against the estimate is a test against its drift: a SINS gyro step made
   the receiver's positions and velocities disagree with the INS, and nothing took them
   back (the drive: 164 km).  A device whose rate half measures another half's rate
   (the velocities, the positions' rate: ``H_a(Φ − I) ≈ G H_b``, :meth:`Guard._own`)
   tests itself: the positions' increment less the trapezoid of the velocities over
   the same epochs, where the estimate's drift cancels to first order whatever it is.
   The other aids' updates since (the vehicle constraints between the fixes) are taken
   out of both innovations (``GuardState.moved``).  ``n_off`` such increments in a row
   consistent once the hold has lasted the patience (never a repeated output; a noise
   increase of the device fails its own test, its increments against the estimate
   cannot tell it from the estimate's drift) and the device is back whole, relaxed,
   with no jump taken, the whole covariance first scaled to cover its innovation (a
   fading factor, as a strong tracking filter's: the attitude and biases that drove
   the drift must be re-learned, not only the position).  A receiver fault both halves
   share consistently is followed from there, as the plain filter follows it; a step
   of one half fails the test once (from the flag's onset: ``GuardState.own_jump``),
   and that jump against itself is kept as the device's jump sum, taken, so the jump
   back at the step's end comes home at once (3); a noise larger than about twice the
   declared σ fails it almost always.  And an only aid with no such mate (GNSS positions
   alone), held past the longest coast (:data:`COAST_PATIENCES` patiences in which it
   was not used for its noise) with a fresh output, is taken back the same way: its
   increments against an estimate that drifts past the model are all jumps, and the
   patience after the last one never comes (the drive's positions alone under a 1 °/s
   pitch-gyro step: 126 km).  So is an aid held as long beside sensors that cannot
   judge it (:meth:`Guard._unjudged`: the rows they see agree with the estimate and it
   departs in rows none of them sees): seed002's GNSS
   beside its star tracker and altimeter, held on a CUSUM alarm while the estimate
   re-learned biases, its horizontal coast 74 m off at the run's end.
   The fused estimate only (independent locals keep their own rules).
8. **A first measurement.**  An aid's first measurement is never held on the fused
   estimate: it has nothing to have jumped from (no increment, no anchor), and the
   estimate's own start (its alignment, or a user's initial position) may be what is
   off.  Held, the drive's GNSS alone, whose first 30 s were 5 m off the alignment,
   coasted an INS no aid had informed for the patience and took the jump with the
   velocity it had coasted: 56 m over the drive against ``ckf``'s 0.14 m.  Independent
   locals keep the hold (``seed001``'s neuron centre fared worse without it).

The guard works on one or several tracked estimates ("groups"): the fused estimate with
every aid (centralized, distributed centre, fusion-reset federated, zero-reset), or, for
architectures whose local filters each hold only their own aid (no-reset federated, the
neuron centre), each local tested against the method's reference, without pulls (no
rollback, no separation detector).  An architecture calls :meth:`Guard.begin` on its
priors with its detector's output, updates with the returned flags, then
:meth:`Guard.finish` with the same priors; the returned :class:`Amend` per group is what
it removes from (or adds to) its estimate after the update.  Arrays carry the batch axis
``(B, N)`` (runs × aids).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.stats import chi2

from ftnav.core import kalman as kf
from ftnav.core.kalman import Gaussian
from ftnav.fdi import separation as sep
from ftnav.fdi.chi2 import DetectorOutput
from ftnav.fusion.config import GuardSettings, Separation
from ftnav.model.system import Sensor

__all__ = [
    "Amend",
    "Guard",
    "GuardOutput",
    "GuardState",
    "GuardTest",
    "Guarded",
    "devices_of",
    "pull_blocks",
    "inflation",
    "reduction",
]


def pull_blocks(config: GuardSettings, dt: float) -> tuple[int, int, int, int]:
    """How an aid's tracked pull is kept at a filter period ``dt``: ``(nb, L, nc, J)``,
    the fine blocks, the epochs of one, the coarse blocks (each ``nb`` fine blocks long)
    before them, and the blocks the pull holds in all (the current fine and coarse ones
    included)."""
    nb = int(config.blocks)
    fine = max(1, int(round(config.fine_s / dt)))
    L = max(1, int(math.ceil(fine / nb)))
    nc = max(0, int(math.ceil(config.window_s / dt / (L * nb))) - 1)
    return nb, L, nc, nb + 1 + (nc + 1 if nc else 0)


class GuardState(NamedTuple):
    """Pull accumulators per group and each aid's isolation bookkeeping, (B, N).

    Attributes
    ----------
    pulls : per group, the block accumulators of its aids.
    alternative : per group, each aid's rolled-back pull (one block), kept while it is
        isolated: the estimate with the rollback undone is the other hypothesis.
    anchor : per aid, (B, n, n) the estimate's covariance when the aid last informed it
        (its last update, or its rollback): the coasting growth is measured from it.
    hold : the aid is isolated (by any test) until the guard re-admits it.
    pending : an alternative (a rollback) exists.
    passes, passes_alt : consecutive re-admission tests passed while held, against the
        estimate and against the alternative.
    steady : the hold may end on the aid's own consistency (module docstring, 3): set
        at an isolation without a rollback whose onset's increment was consistent,
        cleared by the first inconsistent increment.
    steps : consecutive consistent increments of a steady hold.
    since : epochs since the aid's last measurement (-1: none yet).
    last : per aid, (B, m) its residual at its last measurement: against the posterior
        when the estimate used it, else its innovation.
    jump, jump_cov : per aid, the sum (B, m) of a hold's inconsistent increments (its
        jumps) and the sum (B, m, m) of their covariances: a steady hold is re-armed when
        the jumps cancel (the fault's end undid its onset).
    calm : epochs since the hold's last inconsistent increment (or its onset); set to
        the patience when the jumps cancel.
    taken : per aid, (B, m) the part of the jump sum the estimate has taken (a sole
        source's jump past its patience), cleared with the sum.
    spread : per aid, (B, W, m) its last :data:`NOISE_WINDOW` increments (NaN: none, or
        a repeated output's), oldest first: the noise it shows (module docstring, 3).
    jumps : how many jumps the jump sum holds.
    support : the other aids' backing of a held aid (module docstring, 6), zero where
        not held.
    length : epochs since the hold's onset (0 where not held).
    level, level_A : per aid, (B, m) a held aid's innovation when its present run of
        consistent increments began, and (B, m, m) ``H P Hᵀ`` then: the offset it keeps.
    level_age : epochs since that run began, counted while it keeps the level (-1:
        none; not held).
    due : a hold whose patience ended between the aid's measurements, its jump to be
        taken at the aid's next measurement (module docstring, 3).
    own : consecutive increments of a held aid consistent with its own device's rate
        half's measurements (its positions' increments against its velocities, over
        the same epochs: module docstring, 7); 0 where not held or untested.
    moved : per aid, (B, n) the estimate's corrections since the aid's measurement
        before (from its epoch on where the aid was held then, from the next where its
        residual is against the posterior), carried to the present by ``Φ``: what the
        other aids' updates added to its innovation (``ν + H moved`` is the innovation
        without them), for the device's own test.
    own_jump, own_cov : per aid, (B, m) the sum of its inconsistent increments against
        its own device (its jumps against itself: a step of the positions, not the
        estimate's drift) over the hold, and (B, m, m) their covariances; a device back
        whole keeps them as its jump sum, taken, so the jump back at a step's end comes
        home at once.
    inner : increments of a held aid whose rows measure a rate of its other rows (a
        receiver's positions beside its own velocities, one aid) tested against them
        since the hold began (:meth:`Guard._inner`); 0 where not held.
    inner_sum, inner_cov : per aid (B, m) and (B, m, m), those rows' disagreement
        with the trapezoid of their rate summed over the hold, and the rate noise's part
        of its covariance (the rows' own noise enters once: the increments telescope).
    coast : epochs a held aid has not been used for its noise (module docstring, 3):
        the coast the longest-coast rule bounds (module docstring, 7); 0 where not
        held.
    overruled : the detector's flag is ignored until it clears (an override re-admission).
    settling : epochs since the aid's last relaxed re-admission (-1: none): its pulls over
        the fine window after it are the re-convergence (module docstring, 1).
    age : epochs into the current coarse block (the fine one: modulo its length).
    gap : the hold began at the aid's first measurement after a gap of at least the
        patience (an outage); kept while it holds.
    """

    pulls: tuple[sep.Pulls, ...]
    alternative: tuple[sep.Pulls, ...]
    anchor: tuple[np.ndarray, ...]
    hold: np.ndarray
    pending: np.ndarray
    passes: np.ndarray
    passes_alt: np.ndarray
    overruled: np.ndarray
    age: int
    steady: np.ndarray
    steps: np.ndarray
    since: np.ndarray
    last: tuple[np.ndarray, ...]
    jump: tuple[np.ndarray, ...]
    jump_cov: tuple[np.ndarray, ...]
    calm: np.ndarray
    taken: tuple[np.ndarray, ...]
    spread: tuple[np.ndarray, ...]
    jumps: np.ndarray
    support: np.ndarray
    length: np.ndarray
    level: tuple[np.ndarray, ...]
    level_A: tuple[np.ndarray, ...]
    level_age: np.ndarray
    due: np.ndarray
    own: np.ndarray
    moved: tuple[np.ndarray, ...]
    own_jump: tuple[np.ndarray, ...]
    own_cov: tuple[np.ndarray, ...]
    coast: np.ndarray
    inner: np.ndarray
    inner_sum: tuple[np.ndarray, ...]
    inner_cov: tuple[np.ndarray, ...]
    deferred: np.ndarray
    applied: np.ndarray
    settling: np.ndarray
    gap: np.ndarray


class GuardOutput(NamedTuple):
    """What the guard did at one epoch, (B, N) each.

    Attributes
    ----------
    statistic : the largest separation over its threshold (> 1: a separation alarm),
        over the separation detector's windows (0 without that detector).
    hold : the aid isolated (the method's flag).
    alarm : a separation alarm.
    rollback : a window of the aid's pulls was removed from the estimate.
    undone : re-admitted with its rollback undone (the aid was right).
    unobservable : isolated, the aid's quantity drifts unheld (module docstring, 3).
    relaxed : re-admitted with the covariance inflated to cover its innovation.
    taken : re-admitted with its jump taken as its new value (the only aid measuring,
        past its patience: module docstring, 3); a relaxed re-admission as well.
    noisy : held, the only aid measuring, its increments showing a noise far above its
        R: used with that noise where its innovation is consistent with it (module
        docstring, 3).
    device : re-admitted with every aid of its device, the device consistent with itself
        while no other sensor measured: the estimate, not the device, had drifted
        (module docstring, 7); a relaxed re-admission as well.
    faded : re-admitted past its patience where the other sensors respond to its rows
        only as a state it does not read would make them (:meth:`Guard._confounded`)
        and those rows went unheld, or come home there, or backed by aids not held
        (module docstring, 6): the whole covariance faded to cover it (module
        docstring, 3); a relaxed re-admission too.
    """

    statistic: np.ndarray
    hold: np.ndarray
    alarm: np.ndarray
    rollback: np.ndarray
    undone: np.ndarray
    unobservable: np.ndarray
    relaxed: np.ndarray
    taken: np.ndarray
    noisy: np.ndarray
    device: np.ndarray
    faded: np.ndarray


class _AidTest(NamedTuple):
    """One aid's tests on its group's prior (B, …); J windows of its applied pulls."""

    nu: np.ndarray  # (B, m) innovation
    A: np.ndarray  # (B, m, m) H P Hᵀ
    R: np.ndarray  # (B, m, m)
    nis: np.ndarray  # (B,) against the prior
    ratio: np.ndarray  # (B,) separation alarm statistic over its threshold (0: none)
    window: np.ndarray  # (B,) int, the window of the largest ratio


class GuardTest(NamedTuple):
    """The epoch's tests before the decision."""

    pulls: tuple[sep.Pulls, ...]
    alternative: tuple[sep.Pulls, ...]
    aids: tuple[_AidTest, ...]
    P: tuple[np.ndarray, ...]  # each group's prior covariance
    H: tuple[np.ndarray, ...]  # each aid's (B, m, n)
    F: tuple[np.ndarray, ...]  # each group's transition over the epoch


class Guarded(NamedTuple):
    """One epoch between :meth:`Guard.begin` and :meth:`Guard.finish`.

    Attributes
    ----------
    before, after : the guard's state before and after the decision.
    test : the epoch's tests.   output : what the guard did.
    flags : (B, N) the aids the method isolates this epoch.
    detection : the detector's output with the final flags (and separation alarms).
    windows : (B, N) the window each rollback removes.
    rate : (B, N) the held sole sources whose increment informs the estimate's rate now
        (module docstring, 3).
    noise : per aid, (B, m, m) the noise a held only aid is used with now where
        ``output.noisy`` (its R elsewhere).
    home : (B, N) the aids back at their old level (:meth:`Guard._home`): the estimate
        moves by their jump back in the measured quantity before their relaxed update.
    increments : per aid, the epoch's increment ``(B, m)`` and its covariance
        ``(B, m, m)`` (:meth:`Guard._increments`): a home aid's jump back.
    lasting : per aid, (B, m) the rows of a lasting offset to take now (:meth:`Guard._lasting`;
        False elsewhere): the estimate moves by the aid's innovation there before its
        relaxed update.
    """

    before: GuardState
    after: GuardState
    test: GuardTest
    output: GuardOutput
    flags: np.ndarray
    detection: DetectorOutput
    windows: np.ndarray
    rate: np.ndarray
    noise: tuple[np.ndarray, ...]
    home: np.ndarray
    increments: tuple[tuple[np.ndarray, np.ndarray], ...]
    lasting: tuple[np.ndarray, ...]


class Amend(NamedTuple):
    """What a group's estimate takes after the update: ``x − dx``, ``P + dP`` where ``where``."""

    dx: np.ndarray
    dP: np.ndarray
    where: np.ndarray


#: increments a held only aid's noise is measured over (module docstring, 3)
NOISE_WINDOW = 16
#: a held only aid whose increments show a noise variance this many times its R (its σ
#: twice the declared) is used with that noise instead of coasted without it
NOISE_RATIO = 4.0
#: a state carries a jump taken (:func:`_carrier`) where its part of a measured row's
#: predicted variance is at least this share of the largest part (σ within a factor 10)
CARRIER_SHARE = 1e-2
#: 1 / Φ⁻¹(3/4): the standard deviation of a normal sample from its median absolute
#: deviation
MAD_SIGMA = 1.482602218505602

#: a witness refuses a rollback it finds 100× less likely than none (twice the log
#: ratio above χ²₁'s 0.99 quantile): a rollback changes the estimate, so it needs the
#: witnesses' consent more than an isolation does
WITNESS_LLR = float(chi2.isf(0.01, 1))
#: a direction of an aid's quantity that the others see less than this share of (of the
#: quantity and of its rate together) leaves the aid a sole source (:meth:`Guard._blind`)
BLIND_SHARE = 0.5
#: the witnesses' rows span the directions whose singular value is at least this share of
#: the largest (their rows scaled to unit length)
BLIND_RANK = 1e-3
#: an only aid held this many patiences with fresh outputs is taken back, the covariance
#: scaled to cover it (module docstring, 7): the longest a sole source coasts
COAST_PATIENCES = 3
#: a device mate measures an aid's rate where its rows fit the aid's one-epoch rate rows
#: ``H_a(Φ − I)`` but for this share of their weight (each state in its own σ)
RATE_FIT = 0.05

#: the share of a witness's response to a held aid's move that states the aid does not
#: read may leave unexplained, and the move still be theirs to it (:meth:`Guard._confounded`)
CONFOUNDED = 0.1


def devices_of(sensors: Sequence[Sensor]) -> tuple[str, ...]:
    """The device of each aid for the guard's backing (module docstring, 6): its
    ``device`` (an integrated aid's sensor model: one receiver's position and velocity
    aids are one device, and so are two sensors of one model), else the aid itself.
    Aids of one device may fail together, so they do not back each other."""
    return tuple(s.device if s.device is not None else f"aid:{s.name}" for s in sensors)


def _kept_as_taken(
    where: np.ndarray,
    J: Sequence[np.ndarray],
    C: Sequence[np.ndarray],
    count: np.ndarray | int,
    jump: tuple[np.ndarray, ...],
    jump_cov: tuple[np.ndarray, ...],
    jumps: np.ndarray,
    taken: tuple[np.ndarray, ...],
) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...], np.ndarray, tuple[np.ndarray, ...]]:
    """The hold's sums where ``where`` (B, N): each aid's jump sum ``J[a]`` (B, m) with its
    covariance ``C[a]`` (B, m, m) and ``count`` jumps, all of it taken (the estimate
    moved by it), so the jump back that undoes it comes home (module docstring, 3)."""
    N = where.shape[1]
    w = where[:, :, None]
    jump = tuple(np.where(w[:, a], J[a], jump[a]) for a in range(N))
    jump_cov = tuple(np.where(w[:, a, :, None], C[a], jump_cov[a]) for a in range(N))
    taken = tuple(np.where(w[:, a], J[a], taken[a]) for a in range(N))
    return jump, jump_cov, np.where(where, count, jumps), taken


@lru_cache(maxsize=1024)
def _threshold(pfa: float, dof: int) -> float:
    return float(chi2.isf(pfa, dof)) if dof > 0 else math.inf


def _thresholds(pfa: float, dof: np.ndarray) -> np.ndarray:
    table = np.array([_threshold(pfa, d) for d in range(int(dof.max(initial=0)) + 1)])
    out: np.ndarray = table[dof]
    return out


def _median(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The median over axis 1 of (B, W, m) ignoring NaN, and the count of values (B, m);
    NaN where there is none."""
    n = np.isfinite(x).sum(1)
    xs = np.sort(x, 1)  # NaN last
    lo = np.clip((n - 1) // 2, 0, x.shape[1] - 1)[:, None]
    hi = np.clip(n // 2, 0, x.shape[1] - 1)[:, None]
    med = 0.5 * (np.take_along_axis(xs, lo, 1) + np.take_along_axis(xs, hi, 1))[:, 0]
    return np.where(n > 0, med, np.nan), n


def _shown_noise(spread: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(B, m) the noise variance an aid's last increments (B, W, m) show, and (B,) whether
    at least half the window holds increments (:meth:`Guard._loud`)."""
    med, n = _median(spread)
    mad, _ = _median(np.abs(spread - med[:, None]))
    enough = (n >= spread.shape[1] // 2).all(-1)
    shown = 0.5 * (MAD_SIGMA * np.nan_to_num(mad)) ** 2
    return shown, enough


def _gain(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """K = P Hᵀ S⁻¹ (B, n, m) and A = H P Hᵀ (B, m, m)."""
    PHt = P @ kf.mT(H)
    A = kf.symmetrize(H @ PHt)
    K = kf.mT(np.linalg.solve(A + R, kf.mT(PHt)))
    return K, A


def reduction(K: np.ndarray, A: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The covariance reduction of an update, ``K S Kᵀ`` with ``S = A + R``."""
    return kf.symmetrize(K @ (A + R) @ kf.mT(K))


def _chi2(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """``νᵀ S⁻¹ ν`` over the leading axes."""
    out: np.ndarray = np.einsum("...i,...i->...", nu, np.linalg.solve(S, nu[..., None])[..., 0])
    return out


def _chi2_rows(nu: np.ndarray, S: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(B,) ``νᵀ S⁻¹ ν`` over the rows ``rows`` (B, m) only: the others' rows and columns
    of ``S`` replaced by the identity's, ``S`` by the identity where that block is not
    positive definite (0 where no row is kept)."""
    eye = np.eye(S.shape[-1])
    S_r = np.where(rows[:, :, None] & rows[:, None, :], S, eye)
    S_r = np.where(_pd_rows(S_r)[:, None, None], S_r, eye)
    return _chi2(np.where(rows, nu, 0.0), S_r)


def _psd(A: np.ndarray) -> np.ndarray:
    """The positive part of symmetric matrices (negative eigenvalues set to 0)."""
    w, V = np.linalg.eigh(A)
    out: np.ndarray = (V * np.maximum(w, 0.0)[..., None, :]) @ kf.mT(V)
    return out


#: the noise variance of a row left out of an update (:func:`_rows_only`)
LEFT_OUT = 1e12


def _rows_only(R: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(B, m, m) the diagonal noise ``R`` (B, m, m) in ``rows`` (B, m), the others left
    out of an update (variance :data:`LEFT_OUT`)."""
    d = np.where(rows, np.diagonal(R, axis1=-2, axis2=-1), LEFT_OUT)
    return np.asarray(d[..., None] * np.eye(R.shape[-1]))


def _pd_rows(P: np.ndarray) -> np.ndarray:
    """(B,) whether each matrix is positive definite."""
    return np.asarray(np.linalg.eigvalsh(P).min(-1) > 0)


def _rate_map(
    Ha: np.ndarray,
    Hb: np.ndarray,
    P: np.ndarray,
    F: np.ndarray,
    where: np.ndarray,
    own: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rows ``H_b`` that measure the rate of rows ``H_a``: ``G`` (B, m_a, m_b) fitting
    ``H_a(Φ − I) ≈ G H_b`` by least squares with each state in its own σ, and per row
    of ``H_a`` the fit's miss and the rate's whole weight (B, m_a), where ``where`` (B,)
    and the fit is defined (``fine``).  Without ``own`` (``H_b`` is ``H_a``) no row
    fits itself: ``G``'s diagonal is 0 (a rate by the other rows, not a row's level)."""
    D = Ha @ (np.broadcast_to(F, P.shape) - np.eye(P.shape[-1]))
    var = np.maximum(np.diagonal(P, axis1=-2, axis2=-1), 0.0)[:, None, :]
    HbW = Hb * var
    Gram = HbW @ kf.mT(Hb)
    fine = _pd_rows(Gram) & where
    Gram = np.where(fine[:, None, None], Gram, np.eye(Gram.shape[-1]))
    G = kf.mT(np.linalg.solve(Gram, HbW @ kf.mT(D)))
    if not own:
        G = G * (1.0 - np.eye(G.shape[-1]))
    sd = np.sqrt(var)
    miss = (((D - G @ Hb) * sd) ** 2).sum(-1)
    whole = ((D * sd) ** 2).sum(-1)
    return G, miss, whole, np.asarray(fine)


def _less_trapezoid(
    inc: np.ndarray,
    m_a: np.ndarray,
    G: np.ndarray,
    rate_now: np.ndarray,
    rate_last: np.ndarray,
    dk: np.ndarray,
    R_rate: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """An aid's increment ``inc + m_a`` (B, m) less the trapezoid ``Δk G (now + last)/2``
    of the rows that measure its rate, and that trapezoid's covariance
    ``Δk² G (R/2) Gᵀ`` (:meth:`Guard._own`, :meth:`Guard._inner`)."""
    e = inc + m_a - dk[:, None] * kf.mv(G, 0.5 * (rate_now + rate_last))
    add = (dk**2)[:, None, None] * (G @ (0.5 * R_rate) @ kf.mT(G))
    return e, add


def _carries(H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(B, m, n) whether state j carries row i of ``H``: its part of the row's predicted
    variance, ``H_ij² P_jj``, is at least :data:`CARRIER_SHARE` of the row's largest."""
    part = H**2 * np.diagonal(P, axis1=-2, axis2=-1)[:, None, :]
    out: np.ndarray = (part >= CARRIER_SHARE * part.max(-1, keepdims=True)) & (part > 0)
    return out


def _carrier(H: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(B, n, m) the map of a jump of the measured quantity onto the states that carry it.

    Each row's carriers are the states whose part of the row's predicted variance,
    ``H_ij² P_jj``, is at least :data:`CARRIER_SHARE` of its largest: the measured
    quantity itself (a position, a GNSS error state of the same size), not a state that
    moves the measurement only through a small coupling (an attitude through a lever
    arm).  The move is the smallest in the carriers' own σ, ``DHᵀ(HDHᵀ)⁻¹`` with D the
    carriers' variances.  The plain pseudo-inverse ``Hᵀ(HHᵀ)⁻¹`` mixes units: with the
    drive's 5 cm lever arm it put half of a 10 m height jump into a 28° roll (a 150 km
    lock-out); weighting every state by its σ still put 85° into the heading for the
    jump back of a 1 km step.  A jump is a linear move of what is measured, and a
    coupling state is linear only for small angles.
    """
    D = np.diagonal(P, axis1=-2, axis2=-1)[:, None, :]  # (B, 1, n)
    HD = np.where(_carries(H, P), H * D, 0.0)
    M: np.ndarray = np.linalg.solve(HD @ kf.mT(H), HD)
    return kf.mT(M)


def inflation(nu: np.ndarray, A: np.ndarray, R: np.ndarray) -> np.ndarray:
    """γ ≥ 0 (B,) with ``νᵀ ((1 + γ) A + R)⁻¹ ν = m`` (0 where the χ² is already ≤ m).

    The χ² decreases in γ; bracketed by doubling, then bisected to 1e-12 relative.
    """
    m = nu.shape[-1]

    def q(g: np.ndarray) -> np.ndarray:
        return _chi2(nu, (1.0 + g)[:, None, None] * A + R)

    lo = np.zeros(nu.shape[0])
    hi = np.ones(nu.shape[0])
    need = q(lo) > m
    for _ in range(200):
        grow = need & (q(hi) > m)
        if not grow.any():
            break
        hi = np.where(grow, hi * 4.0, hi)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        above = q(mid) > m
        lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
    return np.where(need, hi, 0.0)


class Guard:
    """The guard of one method (module docstring).

    Parameters
    ----------
    config : the method's guard settings.
    groups : the aids of each tracked estimate, e.g. ``[(0, 1, 2)]`` (fused) or
        ``[(0,), (1,), (2,)]`` (each local filter).
    sizes : each group's state dimension.
    dims : each aid's measurement dimension.
    dt : the filter period (s), to turn the windows into epochs.
    detector : the ``separation`` detector's settings, or None (no separation alarms).
    rollback : track the pulls and roll back (False: an architecture whose local filters
        each hold only their own aid, tested against the method's reference: the guard
        then keeps the holds, the coasting allowance and the override, module docstring
        2-3).
    devices : the device each aid comes from (:func:`devices_of`), or None.
    common : independent locals (each group one aid, each tested against the method's
        reference in its first ``common`` states): the other groups' aids then witness a
        held aid through those states in the backing of two held aids (module docstring,
        6).
    """

    def __init__(
        self,
        config: GuardSettings,
        groups: Sequence[Sequence[int]],
        sizes: Sequence[int],
        dims: Sequence[int],
        dt: float = 1.0,
        detector: Separation | None = None,
        rollback: bool = True,
        devices: Sequence[str] | None = None,
        common: int | None = None,
        pseudo: Sequence[bool] | None = None,
    ):
        self.config = config
        #: per aid, whether it is a gated pseudo-measurement (a vehicle constraint): it
        #: witnesses only the directions it reads (:meth:`_blind`)
        self.pseudo = np.zeros(len(dims), bool) if pseudo is None else np.array(pseudo, bool)
        #: independent locals (one aid per group): the first ``common`` states are every
        #: group's, and the other groups' aids witness a held aid through them
        self.common = None if common is None else int(common)
        #: the device each aid comes from (:func:`devices_of`): two halves of one
        #: receiver do not back each other
        self.devices = tuple(str(d) for d in devices) if devices is not None else None
        self.n_off = 5 if config.n_off is None else int(config.n_off)
        self.groups = [tuple(int(a) for a in g) for g in groups]
        self.sizes = [int(n) for n in sizes]
        self.dims = [int(m) for m in dims]
        self.N = len(self.dims)
        #: per aid, the other aids of its own device (the other half of its receiver)
        self.mates = tuple(
            tuple(j for j in range(self.N) if j != a and not self._apart(a, j))
            for a in range(self.N)
        )
        #: (N, N) ``mate[a, j]``: j is of aid a's device (not a itself); ``apart[a, j]``:
        #: j is an aid of another device
        self.mate = np.zeros((self.N, self.N), bool)
        for a, js in enumerate(self.mates):
            self.mate[a, list(js)] = True
        self.apart = ~self.mate & ~np.eye(self.N, dtype=bool)
        self.group_of = np.empty(self.N, dtype=int)
        self.slot = np.empty(self.N, dtype=int)
        for gi, g in enumerate(self.groups):
            for s, a in enumerate(g):
                self.group_of[a], self.slot[a] = gi, s
        self.nb, self.L, self.nc, self.J = pull_blocks(config, dt)
        span = self.L * self.nb  # epochs of a coarse block: the fine blocks' span
        self.patience = max(1, int(math.ceil(config.patience_s / dt)))
        self.lasting = max(1, int(math.ceil(config.lasting_s / dt)))
        self.pfa = float(config.false_alarm_probability)
        self.T1 = np.array([_threshold(self.pfa, m) for m in self.dims])
        self.gain = _threshold(self.pfa, 1)
        # a sole source's rollback: its move across the jump (dimension m − 1)
        self.T_across = np.array([_threshold(self.pfa, max(m - 1, 1)) for m in self.dims])
        self.detector = detector
        self.rollback = bool(rollback)
        if detector is not None and not self.rollback:
            raise ValueError("detector: the separation test needs the guard's pulls")
        self.Jd = 0  # windows the separation detector reads (shortest first)
        # the longest span (epochs) of each window, newest first: fine, then coarse
        fine_w = self.L * np.arange(1, self.nb + 2)
        coarse_w = fine_w[-1] + span * np.arange(1, self.nc + 2) if self.nc else []
        self.spans = np.concatenate([fine_w, coarse_w]).astype(int)
        if detector is not None:
            d_epochs = max(1, int(round(detector.window_s / dt)))
            self.Jd = max(1, int((self.spans <= d_epochs).sum()))
            self.pfa_d = float(detector.false_alarm_probability) / self.Jd

    @classmethod
    def fused(
        cls,
        config: GuardSettings,
        sensors: Sequence[Sensor],
        n_states: int,
        dt: float = 1.0,
        detector: Separation | None = None,
    ) -> Guard:
        """The guard of one estimate that every aid informs (centralized, the
        distributed centre, fusion-reset and zero-reset federated): one group of every
        aid, ``n_states`` tracked states, each aid's device from its sensor
        (:func:`devices_of`)."""
        dims = [s.dim for s in sensors]
        group = [tuple(range(len(dims)))]
        return cls(
            config,
            group,
            [n_states],
            dims,
            dt,
            detector,
            devices=devices_of(sensors),
            pseudo=[s.gate is not None for s in sensors],
        )

    def init(self, batch: int) -> GuardState:
        B, N = batch, self.N
        pairs = list(zip(self.groups, self.sizes, strict=True))
        nb = self.nb if self.rollback else -1  # no blocks at all without the pulls
        nc = self.nc if self.rollback else 0
        pulls = tuple(sep.init_pulls(B, len(g), nb, n, nc) for g, n in pairs)
        alt = tuple(sep.init_pulls(B, len(g), 0 if self.rollback else -1, n) for g, n in pairs)
        anchor = tuple(np.zeros((B, self.sizes[g], self.sizes[g])) for g in self.group_of)
        zb, zi = np.zeros((B, N), bool), np.zeros((B, N), int)
        return GuardState(
            pulls,
            alt,
            anchor,
            zb,
            zb.copy(),
            zi,
            zi.copy(),
            zb.copy(),
            0,
            zb.copy(),
            zi.copy(),
            zi.copy() - 1,
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.zeros((B, m, m)) for m in self.dims),
            zi.copy(),
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.full((B, NOISE_WINDOW, m), np.nan) for m in self.dims),
            zi.copy(),
            np.zeros((B, N)),
            zi.copy(),
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.zeros((B, m, m)) for m in self.dims),
            zi.copy() - 1,
            zb.copy(),
            zi.copy(),
            tuple(np.zeros((B, self.sizes[g])) for g in self.group_of),
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.zeros((B, m, m)) for m in self.dims),
            zi.copy(),
            zi.copy(),
            tuple(np.zeros((B, m)) for m in self.dims),
            tuple(np.zeros((B, m, m)) for m in self.dims),
            zb.copy(),
            zb.copy(),
            zi.copy() - 1,
            zb.copy(),
        )

    @staticmethod
    def _matrices(H: np.ndarray, R: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        return (
            np.broadcast_to(H, (B,) + H.shape[-2:]),
            np.broadcast_to(R, (B,) + R.shape[-2:]),
        )

    def _stacked(
        self,
        aids: Sequence[int],
        H: Sequence[np.ndarray],
        R: Sequence[np.ndarray],
        usable: np.ndarray,
        B: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """``H`` and block-diagonal ``R`` of ``aids`` stacked, a row of an aid not
        measuring (``usable``) left out (zero in ``H``, :data:`LEFT_OUT` in ``R``)."""
        Hs, Rs = [], []
        for a in aids:
            Ha, Ra = self._matrices(H[a], R[a], B)
            Hs.append(np.where(usable[:, a, None, None], Ha, 0.0))
            Rs.append(np.where(usable[:, a, None, None], Ra, LEFT_OUT * np.eye(Ra.shape[-1])))
        m = sum(r.shape[-1] for r in Rs)
        R_all = np.zeros((B, m, m))
        i = 0
        for r in Rs:
            j = i + r.shape[-1]
            R_all[:, i:j, i:j] = r
            i = j
        return np.concatenate(Hs, -2), R_all

    # ---------------------------------------------------------------------------- test
    def test(
        self,
        state: GuardState,
        priors: Sequence[Gaussian],
        F: Sequence[np.ndarray],
        z: Sequence[np.ndarray],
        H: Sequence[np.ndarray],
        R: Sequence[np.ndarray],
        usable: np.ndarray,
    ) -> GuardTest:
        """Propagate the pulls (``F`` per group) and test every aid on its group's prior.

        ``priors`` per group; ``z``, ``H`` (on the group's state), ``R`` per aid.
        """
        pulls, alt = state.pulls, state.alternative
        if self.rollback:
            # the state's pulls are this epoch's to take (the state is not read again for
            # them): the lazy form's time update in place, no copy of the closed blocks
            pulls = tuple(sep.propagate(p, f, copy=False) for p, f in zip(pulls, F, strict=True))
            alt = tuple(sep.propagate(p, f) for p, f in zip(alt, F, strict=True))
        out, Hs = [], []
        for a in range(self.N):
            g, s = self.group_of[a], self.slot[a]
            x, P = priors[g]
            B, m = x.shape[0], self.dims[a]
            Ha, Ra = self._matrices(H[a], R[a], B)
            Hs.append(Ha)
            use = usable[:, a]
            if not use.any():  # nothing to test: the aid has no measurement this epoch
                eye = np.broadcast_to(np.eye(m), (B, m, m))
                zero = np.zeros(B)
                out.append(_AidTest(np.zeros((B, m)), eye, eye, zero, zero, zero.astype(int)))
                continue
            nu = np.where(use[:, None], np.nan_to_num(z[a]) - kf.mv(Ha, x), 0.0)
            K, A = _gain(P, Ha, Ra)
            nis = np.where(use, _chi2(nu, A + Ra), 0.0)
            ratio = np.zeros(B)
            if not self.rollback:
                out.append(_AidTest(nu, A, Ra, nis, ratio, ratio.astype(int)))
                continue
            window = np.zeros(B, int)
            if self.Jd:  # the separation detector: the pulls with this epoch's update
                cw, Gw = sep.windows(pulls[g], s, self.Jd)
                d = kf.mv(K, nu)
                D = reduction(K, A, Ra)
                e_d, T_d = sep.measured(cw + d[:, None], Gw + D[:, None], Ha)
                lam, dof = sep.separation_of(e_d, T_d)
                r = np.where(use[:, None], lam / _thresholds(self.pfa_d, dof), 0.0)
                ratio, window = r.max(1), r.argmax(1)
            out.append(_AidTest(nu, A, Ra, nis, ratio, window))
        return GuardTest(pulls, alt, tuple(out), tuple(p.P for p in priors), tuple(Hs), tuple(F))

    def _measured(self, test: GuardTest, a: int) -> tuple[np.ndarray, np.ndarray]:
        """Aid ``a``'s applied pulls of every window as it measures them: ``H c``
        (B, J, m) and their covariance ``H Γ Hᵀ`` (B, J, m, m).  Only an onset reads
        them, so they are formed there, not every epoch."""
        cw, Gw = sep.windows(test.pulls[self.group_of[a]], self.slot[a])
        return sep.measured(cw, Gw, test.H[a])

    # -------------------------------------------------------------------------- decide
    def decide(
        self,
        state: GuardState,
        test: GuardTest,
        detection: DetectorOutput | None,
        usable: np.ndarray,
        keep: Callable[[np.ndarray], np.ndarray] | None = None,
        repeated: np.ndarray | None = None,
    ) -> tuple[
        GuardState,
        GuardOutput,
        np.ndarray,
        np.ndarray,
        np.ndarray,
        tuple[np.ndarray, ...],
        np.ndarray,
        tuple[tuple[np.ndarray, np.ndarray], ...],
        tuple[np.ndarray, ...],
    ]:
        """The epoch's flags (B, N): the aids the method isolates this epoch.

        Rising edges (a separation alarm, or the detector's flag; ``keep`` is the
        method's common-mode rule on them) start a hold, with the rollback window chosen
        (module docstring, 1); held aids are re-admitted after their passes, from the
        next epoch on.  Returns the new state, the output, the flags, the windows, the
        held sole sources whose consistent increment informs the estimate's rate, and
        the noise each aid is used with where it is held but used for its noise
        (``output.noisy``), and the aids back home with the epoch's increments
        (:attr:`Guarded.home`).
        """
        c = self.config
        B, N = usable.shape
        idx = np.arange(B)
        det_flag = np.zeros((B, N), bool) if detection is None else detection.flag
        det_raw = np.zeros((B, N), bool) if detection is None else detection.raw
        overruled = state.overruled & det_flag  # cleared once the detector's flag clears
        ratio = np.zeros((B, N))
        unobs, ok, ok_alt, strict = (np.zeros((B, N), bool) for _ in range(4))
        k2 = c.kappa**2
        for a, t in enumerate(test.aids):
            ratio[:, a] = t.ratio
            look = (state.hold[:, a] | det_flag[:, a]) & usable[:, a]
            if not look.any():
                continue
            g, Ha = self.group_of[a], test.H[a]
            # the coasting growth since the aid last informed the estimate, allowed kappa
            # times its σ
            A_hold = kf.symmetrize(Ha @ state.anchor[a] @ kf.mT(Ha))
            v, v0 = np.trace(t.A, axis1=-2, axis2=-1), np.trace(A_hold, axis1=-2, axis2=-1)
            unobs[:, a] = look & (v >= c.growth * v0)
            A_grow = _psd(kf.symmetrize(Ha @ (test.P[g] - state.anchor[a]) @ kf.mT(Ha)))
            S = A_hold + k2 * A_grow + t.R
            strict[:, a] = look & (t.nis <= self.T1[a])
            ok[:, a] = look & (_chi2(t.nu, S) <= self.T1[a])
            pend = look & state.hold[:, a] & state.pending[:, a]
            if pend.any():  # the other hypothesis: the rollback undone
                ok_alt[:, a] = pend & self._alternative(a, t, S, test, state, usable)
        # the detector tests against the coasting covariance; where the aid's quantity is
        # unheld (the guard allows for that covariance's optimism) it need not be quiet.
        # Without a rollback (independent locals) a fault the allowance let back in
        # could never be taken out again: the detector's word is then kept
        loose = unobs if self.rollback else np.zeros_like(unobs)
        quiet = ~det_raw | overruled | loose
        # a repeated output passes no re-admission test: a frozen receiver's last value
        # passes as the coasting allowance grows past the distance driven since, and
        # taking it back drags the estimate to where the vehicle was (the drive's GNSS
        # alone frozen for 120 s: re-admitted at 38 s, a 135 km lock-out)
        fresh = np.ones((B, N), bool) if repeated is None else ~repeated
        ok &= fresh
        ok_alt &= fresh
        tested = state.hold & usable
        passes = np.where(tested, np.where(ok & quiet, state.passes + 1, 0), state.passes)
        # the detector tests against the rolled-back estimate: the alternative is judged
        # on its own test
        passes_alt = np.where(tested, np.where(ok_alt, state.passes_alt + 1, 0), state.passes_alt)
        # the guard's own consistency for long enough overrules a detector still alarming
        override = tested & ok & ~quiet & (state.passes + 1 >= c.override)
        passes = np.where(override, self.n_off, passes)
        overruled = overruled | override
        # a deferred rollback is applied once the aid disagrees with the estimate as it
        # is and agrees with the rolled-back one (a drag over: its fix jumped back), and
        # is then an ordinary doubtful one, undone on the aid's agreement without it
        applied = tested & state.pending & state.deferred & ~ok & ok_alt
        passes_alt = np.where(applied, 0, passes_alt)
        undone = state.hold & (passes_alt >= c.confirm) & (passes < self.n_off) & ~applied
        # each aid's innovation beyond the guard's own χ² now
        far = np.stack([t.nis > self.T1[a] for a, t in enumerate(test.aids)], 1)
        # where an aid's kind (a sole source or not) matters: held, or may be isolated
        # now; only beside the vehicle constraints (:meth:`_blind`), else nowhere
        care = np.zeros((B, N), bool)
        if self.pseudo.any():
            care = state.hold | det_flag | det_raw | (ratio > 1.0) | far
        # no other aid of the estimate measures now (a sole source in the strict sense),
        # or those that do leave a direction of its quantity unseen (:meth:`_blind`)
        alone = np.stack(
            [
                ~self._witness_present(a, usable, state, test=test, care=care[:, a])
                for a in range(N)
            ],
            1,
        )
        # no other aid of the estimate measures at all, held or not (the only aid now): a
        # held healthy aid must not leave a faulty one the field.  Between the fixes no
        # aid measures, so every held aid is "only" there: its patience may end its hold
        # at such an epoch (relaxed, the detector overruled until its flag clears), beside
        # aids that measure other quantities at the fixes (docs/integrity.md §5: this
        # re-admits the drive's GLR after a noise minute in 1.4 s rather than 14 s, and
        # takes a lasting 5 m east step after 10 s; requiring the aid to measure traded
        # the first for the second, and was not kept)
        only = np.stack(
            [~self._witness_present(a, usable, test=test, care=care[:, a]) for a in range(N)], 1
        )
        # no aid of the method other than ``a`` measures (independent locals: the other
        # locals' aids too; else ``only``)
        only_m = (
            only
            if self.common is None
            else np.stack([~self._witness_present(a, usable, method=True) for a in range(N)], 1)
        )
        # the increments matter where an aid is held or may be isolated now
        # (independent locals: where held or flagged, for the noise rule below)
        need = (
            (state.hold | det_flag | (ratio > 1.0))
            if self.rollback
            else ((state.hold | det_flag) if self.common is not None else None)
        )
        # a repeated output is no measurement for the increments: it is neither tested
        # nor their reference, so a freeze is an outage to them, and the first fresh
        # output is tested against the last one before it (the walk's 15 s freeze of its
        # only aid was held as a jump for the patience after it: 2.0 m against ckf's 1.1)
        good, inc, since, last = self._increments(state, test, usable & fresh, need)
        judged = tested & fresh  # the held aids whose output is a measurement now
        # the noise each aid shows: its last increments (a repeated output's is none)
        pushed = usable & (state.since >= 0) & fresh
        spread = tuple(
            np.where(
                pushed[:, a, None, None],
                np.concatenate([state.spread[a][:, 1:], inc[a][0][:, None]], 1),
                state.spread[a],
            )
            for a in range(N)
        )
        shows, shown_R, very = self._loud(state.hold & usable & fresh, spread, test)
        # (an independent local is not used with its noise: its estimate is the fused one)
        loud = shows & only & self.rollback
        # a held aid beside others whose increments show a noise far above its R passes
        # only the strict test with a consistent increment: a noisy fix that passes the
        # coasting allowance by chance is taken whole, relaxed, and the estimate left that
        # far off (slowramp's fix at 10 times its noise: 8 m off for 100 s after it).  And
        # none while they show a noise past NOISE_RATIO² times R (its σ four times the
        # declared): there the coast has grown so that n_off strict passes in a row come
        # by chance, and a sequential detector, quiet after its alarm, lets them count
        # (slowramp's fix at 10 times its σ: CUSUM and GLR 1.17 and 1.01 m after it,
        # ckf 0.30 m).  A milder show may be the estimate's own moves after a relaxed
        # re-admission, which a healthy aid's consistent increments end
        passes = np.where(tested & shows & ~only_m & (very | ~(strict & good)), 0, passes)
        steady, steps = state.steady, state.steps
        calm = np.where(state.hold, np.where(judged & ~good, 0, state.calm + 1), state.calm)
        # consistent increments in a row of every hold (a steady one's: its steps)
        steps = np.where(judged, np.where(good, steps + 1, 0), steps)
        steady = steady & ~(judged & ~good)
        jump, jump_cov = self._jumps(state, inc, judged & ~good)
        returned = np.zeros((B, N), bool)
        for a in range(N):  # the jumps cancel: the aid is back where it was
            fail = judged[:, a] & ~good[:, a]
            if not fail.any():
                continue
            back = self._cancelled(a, jump[a], jump_cov[a], fail)
            steady[:, a] |= back & self.rollback & alone[:, a]
            steps[:, a] = np.where(back, 0, steps[:, a])
            calm[:, a] = np.where(back, self.patience, calm[:, a])
            # the only aid measuring, back at the level it had before its one jump (the
            # sum held that jump alone, not zero): it is taken at once (an intermittent
            # fault leaves it healthy between its bursts); never a repeated output, nor
            # an aid whose increments show a noise increase (its sums cancel by chance)
            one_out = (state.jumps[:, a] == 1) & ~self._cancelled(
                a, state.jump[a], state.jump_cov[a], back
            )
            returned[:, a] = back & one_out & only[:, a] & state.hold[:, a] & self.rollback
            returned[:, a] &= fresh[:, a] & ~loud[:, a]
        # a sole source isolated on an alarm nothing explained (no rollback), whose own
        # increments have stayed consistent since, no other aid measuring: the model,
        # not the aid, drifted
        settled = state.hold & steady & unobs & alone & (steps >= self.n_off) & ~undone
        # a sole source consistent again for the patience since its last jump: the jump
        # is its new value (the plain filter's choice; a coast does not outlast it)
        # (or no other aid measuring can judge its jump: an altimeter or a star tracker
        # beside a GNSS that stepped north cannot say which is right, and the coast
        # drifts; seed002: held 115 s, re-admitted on the allowance with the step, its
        # end held 110 s more)
        ripe = state.hold & (steps >= self.n_off) & (calm >= self.patience)
        unwitnessed = np.stack(
            [self._unwitnessed(a, usable, test, state, only[:, a], ripe[:, a]) for a in range(N)],
            1,
        )
        # (between the fixes no aid measures, so every held aid is "only" there; but a
        # jump an aid that measured since the held aid's last fix sees as an offset is
        # not the held aid's new value: a velocity step beside the positions, which
        # integrate it.  The drive's GNSS velocities biased 0.5 m/s east for 60 s were
        # taken so 10 s in, the detector overruled; the healthy positions were then
        # held: 35 m after the fault against ckf's 0.06 m)
        for b in np.flatnonzero((ripe & unwitnessed & only).any(0)).tolist():
            unwitnessed[:, b] &= ~self._offset_seen(b, usable, test, state)
        # rows the other aids measuring see through their rates only (a star tracker's
        # attitude beside GNSS, whose velocities a tilt moves only through their rate,
        # where an accelerometer bias can take the tilt's part), gone unheld (``unobs``:
        # their variance grew ``growth`` times since the aid last informed them): the
        # others cannot judge the jump either, and the coast does not hold what the aid
        # measures.  Taken after the patience as beside aids that cannot see it, the
        # whole covariance faded to cover the aid (:meth:`record`): the states through
        # which the others see the rows (the biases) were learned from the old level.
        # Sensors only witness here: a vehicle constraint reads a velocity with the
        # attitude, and a whole receiver held beside it is the device rule's (below)
        faded = ripe & unobs & ~unwitnessed & usable & self.rollback
        for a in np.flatnonzero(faded.any(0)).tolist():
            faded[:, a] &= self._confounded(a, usable & ~self.pseudo, test)
        expired = ripe & (unwitnessed | faded)
        # an expiry between the aid's measurements would release it with nothing to
        # take (its jump is taken where it measures), and its next measurement, still
        # off, started a new hold whose patience ended between them again: the drive's
        # fixes after a 0.01 m/s ramp of 300 s held to the end of the run.  The jump is
        # due at the aid's next measurement instead, while no new jump comes
        between = expired & ~usable & self.rollback & (state.level_age >= 0)
        # (never while the other half of its device is held: the device is still failing,
        # and its new level is no healthy value.  The drive's fixes stepped 5 m beside
        # their velocities turned noisy: the step taken, the GLR held the fixes again,
        # and the coast beside the noisy velocities reached 115 m)
        for b in np.flatnonzero(between.any(0)).tolist():
            for j in self.mates[b]:
                between[:, b] &= ~state.hold[:, j]
        owed = (state.due | between) & ripe & state.hold
        # (taken where the aid's offset has kept one level for the patience: a ramp
        # still running moves it, and taking it then holds its end the patience more)
        kept_level = state.level_age >= self.patience
        expired = (expired & ~between) | (owed & usable & fresh & kept_level)
        settled |= expired & ~undone & self.rollback
        # a hold the other aids back: the aid was right, the estimate (the INS) wrong (a
        # gyro bias step: the star tracker flagged, the GNSS velocities confirming it)
        support, backed = self._support(state, test, usable & fresh)
        # never an aid whose own device's other half, unheld, sees its offset at its own
        # rate and agrees with the estimate: the device disagrees with itself and the INS
        # sides with that half (the drive's GNSS velocities biased 0.5 m/s: their
        # positions' per-epoch evidence drifted to a backing 14 s in, the bias was taken,
        # and the healthy positions were then held: 21 m after the fault)
        for b in np.flatnonzero(backed.any(0)).tolist():
            backed[:, b] &= ~self._offset_seen(b, usable, test, state, device=True)
        settled |= backed & ~undone
        # a whole device held, no other sensor measuring unheld, and the device consistent
        # with itself for ``n_off`` of its own increments since the patience: the
        # estimate drifted, not the device (a SINS gyro step: the receiver's positions
        # and velocities both held, the vehicle constraints gated by the same error, and
        # nothing measured again: 164 km against ckf's 0.03 m).  Back, relaxed, with no
        # jump taken: the whole innovation is the estimate's error
        # (the other aids' corrections since each aid's last measurement, carried on:
        # its test against its device mate's rate, and against its own, :meth:`_inner`)
        moved = tuple(
            kf.mv(test.F[self.group_of[a]], state.moved[a]) if self.rollback else state.moved[a]
            for a in range(N)
        )
        # (tested from the onset's flag: a step of one half is a jump against itself)
        watched = (state.hold | det_flag) & usable & fresh
        own_tested, own_good, own_e, own_S = self._own(state, test, inc, watched, moved)
        agree = np.where(own_tested & state.hold, np.where(own_good, state.own + 1, 0), state.own)
        own_fail = own_tested & ~own_good
        own_jump = tuple(
            np.where(own_fail[:, a, None], state.own_jump[a] + own_e[a], state.own_jump[a])
            for a in range(N)
        )
        own_cov = tuple(
            np.where(own_fail[:, a, None, None], state.own_cov[a] + own_S[a], state.own_cov[a])
            for a in range(N)
        )
        sensor = usable & ~state.hold & ~self.pseudo
        device = np.zeros((B, N), bool)
        for a in np.flatnonzero((agree >= self.n_off).any(0)).tolist():
            mates = list(self.mates[a])
            whole = state.hold[:, a] & state.hold[:, mates].all(-1)
            alone_d = ~(sensor & self.apart[a]).any(-1)
            ready = (agree[:, a] >= self.n_off) & (state.length[:, a] >= self.patience)
            on = whole & alone_d & ready & usable[:, a] & fresh[:, a] & ~undone[:, a]
            device[:, a] |= on
            device[:, mates] |= on[:, None] & state.hold[:, mates]
        # the only aid measuring at all, held past the longest coast (COAST_PATIENCES
        # patiences) with a fresh output it is not used for its noise: nothing is left to
        # judge it but the estimate's drift, and the plain filter would have used it all
        # along (the drive's GNSS positions alone under a 1 °/s pitch-gyro step: every
        # increment a jump against the drifting INS, the patience never came, 126 km).
        # Back as a device consistent with itself is, the covariance scaled to cover it
        coasted = (
            state.hold
            & (state.coast >= COAST_PATIENCES * self.patience)
            & usable
            & fresh
            & ~undone
            & self.rollback
        )
        # (and an aid beside others that cannot judge it: its rows they see agree with the
        # estimate, and it departs in rows none of them sees (:meth:`_unjudged`; not where
        # they see it only as a state it does not read, :meth:`_confounded`: a GNSS height
        # step beside an altimeter with a bias state was taken 30 s in, and the CUSUM
        # method's error after it went 0.53 -> 1.67 m).  seed002's GNSS beside its star
        # tracker and altimeter, held on a CUSUM alarm while the estimate re-learned the
        # accelerometer biases a biased star tracker had taught it: height and
        # velocities in agreement, the horizontal coast 15 m off after 30 s and 74 m at
        # the run's end.  Sensors judge here, at least one measuring: beside the vehicle
        # constraints alone a whole receiver is the device rule's, above.  An aid with
        # no rows measuring its other rows' rate (a star tracker, positions alone) is
        # never taken by it: nothing tells its ramp from the estimate's drift)
        inner, inner_sum, inner_cov, inner_good = self._inner(state, test, inc, judged, moved)
        judges = usable & ~state.hold & ~self.pseudo
        for a in np.flatnonzero((coasted & ~only).any(0)).tolist():
            blind = self._unjudged(a, judges, test) & judges[:, self._peers(a)].any(-1)
            # (its own rate rows agreeing with its other rows for n_off increments: a
            # drift of the estimate, not a ramp of the aid, whose positions leave its
            # own velocities behind: seed002's GNSS ramping 1 m/s east was taken 30 s in
            # without this, 26 m after it for the CUSUM method against 0.49 m)
            coasted[:, a] &= only[:, a] | (blind & inner_good[:, a])
        device |= coasted
        settled |= device
        # a held aid beside aids of its rate only, at one constant offset from the
        # estimate for ``lasting_s``: that offset is taken (a rollback the rate aids could
        # not judge, or a lasting step: the plain filter's choice)
        level, level_A, level_age, offset = self._lasting(
            state, test, judged & ~only & ~shows & ~settled & ~undone, usable
        )
        lasting = np.stack([o.any(-1) for o in offset], 1)
        settled |= lasting
        # a jump's hold: the jump is taken, not a drift (a hold whose sum holds no jump, a
        # freeze's, ends relaxed with nothing to take); a lasting offset is taken too,
        # its jump sum kept for the jump back at the fault's end
        # (independent locals keep no pulls: a hold of theirs takes no jump)
        taken = (settled & ~steady & (state.jumps > 0) & self.rollback & ~device) | lasting
        faded &= settled & ~device & ~undone
        # a backed aid: the estimate drifted, so the whole covariance is faded to cover
        # the aid's innovation (:meth:`record`), as a device back whole's.  The fused
        # estimate only (a no-reset local faded so lost its weight in the fusion:
        # seed001's no-reset federated methods moved both ways, 18.8 -> 21.0 m and
        # 17.7 -> 15.0 m), and only an aid backed by aids not held: where two held aids
        # back each other, the other may be the faulty one, and the faded estimate then
        # followed it when it was let back (slowramp's odometer 1 m/s off for 400 s: the
        # CUSUM method held its healthy fix to the end, 77.8 m against 0.30)
        # (another aid held: also the single-fault rule of the alarms, below)
        others_held = (state.hold.sum(1, keepdims=True) - state.hold) > 0
        faded |= backed & ~others_held & ~undone & ~device & self.rollback
        returned &= ~undone & ~settled
        release = state.hold & ((passes >= self.n_off) | undone | settled | returned)
        relaxed = (release & ~undone & ~strict) | settled | returned
        # a re-admission the detector does not agree with yet overrules it until it clears
        overruled = overruled | (release & det_flag)
        # single fault at a time (module docstring, 1 and 4)
        alarm = np.zeros((B, N), bool)
        if self.detector is not None:
            over = (ratio > 1.0) & ~state.hold & ~others_held
            top = np.argmax(np.where(over, ratio, 0.0), 1)
            alarm[idx, top] = over[idx, top]
        # an aid returning to an unheld quantity (after an outage of the only position
        # aid) within the allowance is taken at once, the covariance inflated to cover it
        # (in :meth:`record`): the detector tested it against the coasting covariance the
        # allowance is for
        welcome = ~state.hold & det_flag & ~overruled & loose & ok
        # an aid whose new jump undoes the jump sum it was re-admitted with (the
        # allowance took it back with its step, and the estimate followed), in rows no
        # other aid measuring reads: it is back at the level the estimate had before it
        # followed, and is taken at once, relaxed (the drive's 2 m GNSS step for 60 s:
        # re-admitted with the step after 23 s, its end was held 40 s, 2 m off, where
        # ckf was back at 0.06 m)
        # (flagged, and inconsistent now: the epoch after a re-admission's update is no
        # jump back; never an aid whose increments show a noise increase: its jumps
        # cancel by chance)
        # (or not flagged at all, where the estimate took the jump the sum keeps: a
        # separation test does not flag the jump back, it alarms on its pull after)
        kept = np.stack([(state.taken[a] != 0).any(-1) for a in range(N)], 1)
        due = (det_flag | kept) & far & ~state.hold & fresh
        due &= ~self._loud(due & usable, spread, test)[0]
        home = self._home(state, inc, good, due, usable, test)
        # (home in rows the others see only as a state the aid does not read: that state
        # was learned from the level the estimate followed, and is faded as at the take)
        for a in np.flatnonzero((home & ~self.pseudo).any(0)).tolist():
            faded[:, a] |= home[:, a] & self._confounded(a, usable & ~self.pseudo, test)
        welcome = welcome | home
        overruled = overruled | welcome
        # an overruled detector's aid is watched by the guard's own χ² instead
        own = overruled & usable & far & ~home
        # a detector's flag of an aid whose device mate is held, while the aid's own
        # increment is consistent and an aid of another device measures, is the coast's
        # drift, not the device's: the mate's hold left the estimate to the INS, whose
        # drift in a turn shifts this aid's innovations too (the drive's GLR held the GNSS
        # velocities at 429 s and flagged the positions 0.25 s later, both halves held for
        # a relaxed re-admission).  Where the device is all that measures, the flag may
        # be the only sign of its fault (the GLR blames the velocities for a position
        # ramp): held as before (the receiver alone, a ramp from 250 s: 0.76 -> 1.58 m)
        coast = det_flag & good
        if coast.any():
            coast &= (state.hold[:, None, :] & self.mate).any(-1)
            coast &= (usable[:, None, :] & self.apart).any(-1)
        triggered = alarm | (det_flag & ~overruled & ~coast) | own
        # an aid's first measurement is the estimate's first word from it: nothing it
        # could have jumped from (no increment, no anchor), and the estimate's own
        # start (its alignment) may be what is off.  Holding it coasted an INS that no
        # aid had informed (module docstring, 8; the fused estimate only)
        if self.rollback:
            triggered &= ~(usable & (state.since < 0))
        hold_before = state.hold
        if keep is not None:
            # the common-mode rule sees every aid isolated or flagged now: when a quorum
            # of them disagree the shared reference failed, and none is isolated (the
            # holds are released with the rest)
            both = state.hold | triggered
            kept = keep(both)
            common = both & ~kept
            triggered = triggered & kept
            hold_before = state.hold & kept
            release = release | (state.hold & common)
        rising = ~hold_before & triggered
        flags = hold_before | rising | welcome  # re-admitted aids: used from the next epoch
        choose = np.zeros((B, N), bool)
        doubt = np.zeros((B, N), bool)  # a rollback on the separation alone: undoable
        defer = np.zeros((B, N), bool)  # a doubtful rollback kept as the alternative
        ended = np.zeros((B, N), bool)  # a rollback that explains a jump: the fault ended
        windows = np.zeros((B, N), int)
        for a, t in enumerate(test.aids):
            # (an output repeated bit for bit is the aid's own fault, a freeze: nothing
            # to roll back; seed002's receiver frozen at 299 s, one run of four: a
            # window's removal "explained" the stale fix and moved the estimate 78 m)
            new = rising[:, a] & ~others_held[:, a] & usable[:, a] & fresh[:, a]
            if not new.any() or not self.rollback:
                continue
            # the window of the aid's applied pull that explains the flag: the one whose
            # removal makes the flagged measurement the most consistent, while it was not,
            # by more than chance against the same widened covariance (the pull points
            # at the jump: a drag now over, the measurement jumped back), else the most
            # significant pull too large for its covariance (a drag still on); none:
            # nothing to roll back.  A window whose covariance merely swallows the jump
            # (a filter that converged from its start) explains nothing.  "More than
            # chance": the gain ``before − after = −2 νᵀS⁻¹e − eᵀS⁻¹e`` of a pull e that
            # has nothing to do with ν is at most z² (z ~ N(0, 1), the maximum of
            # 2|z|√q − q over q), a χ²₁ variate whatever the aid's dimension: the gain
            # must pass χ²₁'s quantile (χ²_m's, 21.1 for a 3-D fix, missed the drive's
            # 0.05 m/s ramps ending at 150-244 s: their gain 16.5-17.4, and 3 m held for
            # the patience: 1.65-1.85 m after them against ckf's 0.11)
            e, T = self._measured(test, a)
            lam, dof = sep.separation_of(e, T)
            r = lam / _thresholds(self.pfa / self.J, dof)
            sig = r > 1.0
            S_w = (t.A + t.R)[:, None] + T
            after_ = _chi2(t.nu[:, None] + e, S_w)
            before_ = _chi2(np.broadcast_to(t.nu[:, None], e.shape), S_w)
            fits = (after_ <= self.T1[a]) & (before_ - after_ > self.gain)
            # a sole source's window holds its corrections of the INS's drift as well: its
            # removal may move the measured quantity along the jump only, across it (where
            # the measurement agrees with the estimate) by no more than chance against the
            # aid's own covariance (the drive's GNSS alone, a 6 m height ramp ending: the
            # removal explained the jump and moved the horizontal 5.8 m, 0.47 m after the
            # ramp against ckf's 0.067)
            if alone[:, a].any():
                S0 = t.A + t.R
                Si_nu = np.linalg.solve(S0, t.nu[..., None])[..., 0]
                q_nu = np.maximum(np.einsum("bm,bm->b", t.nu, Si_nu), 1e-300)
                along = np.einsum("bjm,bm->bj", e, Si_nu) / q_nu[:, None]
                e_x = e - along[..., None] * t.nu[:, None, :]
                q_x = _chi2(e_x, np.broadcast_to(S0[:, None], T.shape))
                across = q_x <= self.T_across[a]
                fits &= across | ~alone[:, a, None]
            fits &= (t.nis > self.T1[a])[:, None]
            # a pull merely too large for its covariance is no evidence where no other aid
            # sees the estimate: a sole source's pulls are as large as the model's
            # optimism makes them (real noise), and removing them is an outage
            sig &= ~alone[:, a, None]
            # the other aids witness: a rollback they disagree with is no rollback.  Of
            # the windows that explain the jump, the best one every witness accepts (the
            # longest such pull also holds corrections of the INS a witness disputes:
            # the drive's fixes with its velocities alone, a 0.05 m/s ramp ending at
            # 480 s, whose best window moved the velocity 0.24 m/s against them)
            fitted = new & fits.any(1)
            explain = new & (fitted | sig.any(1))
            if explain.any():  # (B, J): the windows whose removal every witness accepts
                accepted = self._witnessed(a, test, state, usable)
                fits &= ~fitted[:, None] | accepted
                explain = new & (fits.any(1) | (sig.any(1) & ~fitted))
            best = np.argmin(np.where(fits, after_, np.inf), 1)
            w = np.where(fits.any(1), best, np.argmax(r, 1))
            pulled = explain & ~fits.any(1)  # a drag still on: its window witnessed too
            if pulled.any():
                explain &= ~pulled | accepted[np.arange(B), w]
            # a separation alarm removes the window that raised it
            fired = new & alarm[:, a]
            choose[:, a] = explain | fired
            # a drag's rollback in rows no other aid responds to (seed002's horizontal
            # GNSS positions beside its star tracker and altimeter) rests on the aid's own
            # pull: a false alarm after the SINS's fault found its large correcting pulls
            # "too large" and rolled 576 m back.  Kept as a hypothesis, as a separation
            # alarm's: undone when the aid keeps agreeing with the estimate without it
            drag = explain & ~fits.any(1)
            # so is any rollback of a pull too large (or a separation alarm's) in the
            # aid's first fine window after its relaxed re-admission: its pulls then are
            # the re-convergence of a model the re-admission found wrong (its covariance
            # was inflated along the aid's rows only), not a drag (slowramp's odometer
            # ramp: the fix taken back 96 m off, a CUSUM alarm 45 s later rolled 3.5 m of
            # its re-convergence back and the fix was held 100 s)
            agrees = t.nis <= self.T1[a]
            recent = (state.settling[:, a] >= 0) & (state.settling[:, a] < self.nb * self.L)
            quiet = (drag | fired) & recent & agrees
            if drag.any():
                drag &= self._unseen(a, usable & ~state.hold, test).any(-1)
            doubt[:, a] = fired | drag | quiet
            # and while the flagged measurement agrees with the estimate as it is, that
            # doubtful rollback is not applied but kept as the alternative: the estimate
            # stays, and the aid's agreement with the rolled-back one applies it (the
            # seed002 receiver after a 1 deg/h gyro step: a CUSUM false alarm at a fix
            # that agreed rolled the estimate 332 m back for the 20 s until it was undone)
            defer[:, a] = (drag & agrees) | quiet
            ended[:, a] = explain & fits.any(1)
            windows[:, a] = np.where(fired, t.window, w)
        hold = (hold_before & ~release) | rising
        # a rollback that explains a jump (the measurement consistent again with the
        # rolled-back estimate: the fault ended) leaves an offset its covariance covers;
        # a sequential detector sees that lasting offset as the mean shift it tests for
        # and holds the aid for the patience (the drive's GLR after a 0.2 m/s ramp,
        # 3.9 m left by the rollback at NIS 5-9 of 21: back in 10.4 s).  The guard's own
        # χ² judges the aid instead until the detector's flag clears
        overruled = overruled | (ended & det_flag)
        reset = rising | release
        passes = np.where(reset, 0, passes)
        passes_alt = np.where(reset, 0, passes_alt)
        # the onset's own increment: a jump (a step, a frozen output) is a fault of the aid
        steady = np.where(reset, rising & ~choose & good & alone & self.rollback, steady)
        steps = np.where(reset, 0, steps)
        # the onset's jump joins the hold's sum; the sum outlives a re-admission that
        # took the aid with its jump (the allowance: the estimate followed the step), so
        # the jump back cancels it, and is cleared when the jumps cancelled
        onset = rising & ~good & (since == 0)
        calm = np.where(rising, 0, calm)
        for a in range(N):  # an onset jump that cancels the sum: the aid is back
            if not onset[:, a].any():
                continue
            carried = onset[:, a] & (jump[a] != 0).any(-1)
            back = self._cancelled(a, jump[a] + inc[a][0], jump_cov[a] + inc[a][1], carried)
            calm[:, a] = np.where(back & only[:, a], self.patience, calm[:, a])
        # a jump taken stays in the sum; a sum that cancelled is gone
        clear = (release & ((settled & ~taken) | returned)) | home
        # but a steady hold (a false alarm: no jump of its own) that ends settled leaves
        # the sum it found: a step the estimate followed or took before it still has its
        # jump back to come (the drive's GNSS alone, a 5 m step from 100 to 480 s: a GLR
        # false alarm in a turn cleared the sum, and the step's end was held for the
        # patience, 10.1 s, where it now comes back at once)
        carry = clear & release & settled & state.steady & ~returned & ~home
        jump = tuple(
            np.where(
                carry[:, a, None],
                state.jump[a],
                np.where(
                    clear[:, a, None], 0.0, jump[a] + np.where(onset[:, a, None], inc[a][0], 0.0)
                ),
            )
            for a in range(N)
        )
        jump_cov = tuple(
            np.where(
                carry[:, a, None, None],
                state.jump_cov[a],
                np.where(
                    clear[:, a, None, None],
                    0.0,
                    jump_cov[a] + np.where(onset[:, a, None, None], inc[a][1], 0.0),
                ),
            )
            for a in range(N)
        )
        jumps = np.where(
            carry, state.jumps, np.where(clear, 0, state.jumps + (judged & ~good) + onset)
        )
        # a held only aid whose increments show much more noise than its R (a noise
        # increase: no jump, no drift) is used with that noise; coasting without it
        # would trade the aid's noise for the INS's drift.  Its jump sum stays: a jump
        # held before (a followed ramp's end) is still to be taken
        rate = state.hold & hold & usable & only & good & fresh & (steps >= self.n_off)
        rate &= (state.since >= 0) & self.rollback & ~loud  # a loud aid's rate: its noise
        noisy = loud & state.hold & hold & usable & only & fresh
        # beside other aids, in the rows none of them responds to (seed002's horizontal
        # GNSS positions beside its star tracker and altimeter): used with its noise
        # there, the other rows left out (an infinite noise); coasting those rows had
        # cost the wait for the noise window to clear after the noise (GNSS noise ×20:
        # 1.08 m after it against ckf's 0.91)
        apart = shows & ~only & state.hold & hold & usable & fresh & self.rollback
        free_rows = [np.zeros((B, m), bool) for m in self.dims]
        for a in range(N):
            if apart[:, a].any():
                free_rows[a] = apart[:, a, None] & self._unseen(a, usable & ~state.hold, test)
        beside = np.stack([f.any(-1) for f in free_rows], 1)
        noise = tuple(
            np.where(
                noisy[:, a, None, None],
                shown_R[a],
                np.where(
                    beside[:, a, None, None],
                    _rows_only(shown_R[a], free_rows[a]),
                    t.R,
                ),
            )
            for a, t in enumerate(test.aids)
        )
        noisy = noisy | beside
        taken_sum = tuple(
            np.where(
                clear[:, a, None] & ~carry[:, a, None],
                0.0,
                np.where(taken[:, a, None], jump[a], state.taken[a]),
            )
            for a in range(N)
        )
        # a device back whole keeps its jumps against itself as its sum, taken (the
        # estimate followed them with the device), so the jump back at a step's end is
        # home at once; the estimate's drift it held is gone (the drive's fixes stepped
        # 5 m beside noisy velocities: taken with the device, its end then held for the
        # patience, 0.94 m after it against ckf's 0.17)
        if device.any():
            kept_own = np.stack([(own_jump[a] != 0).any(-1) for a in range(N)], 1)
            jump, jump_cov, jumps, taken_sum = _kept_as_taken(
                device, own_jump, own_cov, kept_own.astype(jumps.dtype), jump, jump_cov, jumps,
                taken_sum,
            )  # fmt: skip
        # a hold begun at an aid's first measurement after an outage has no jump (the
        # coast's drift allowance covers the increment over the gap), whatever offset it
        # came back with.  Ended relaxed, its innovation beyond chance, the relaxed update
        # takes that offset as the aid's level: it is kept as the sum, taken, as a jump's
        # hold keeps its jump, and the jump back at the fault's end comes home at once
        # (the drive's fixes back 5 m off after a 60 s outage were taken after the
        # patience, and the step's end was then held for the patience again: 0.20 m
        # after it against ckf's 0.03).  Only there: after any hold without a jump, the
        # slowramp odometer's step held the separation method's fixes to the end
        offset_taken = relaxed & release & state.gap & (state.jumps == 0) & (jumps == 0)
        offset_taken &= usable & fresh & ~device & ~undone & self.rollback
        if offset_taken.any():
            offset_taken &= np.stack([t.nis for t in test.aids], 1) > self.T1
            nu = [t.nu for t in test.aids]
            S = [kf.symmetrize(t.A + t.R) for t in test.aids]
            jump, jump_cov, jumps, taken_sum = _kept_as_taken(
                offset_taken, nu, S, 1, jump, jump_cov, jumps, taken_sum
            )
        # (kept from the flag's onset, which may come before the hold's, through a
        # release and a new hold, until the aid is used again unflagged or back whole)
        on = ~(usable & ~hold & ~det_flag) & ~device
        own_jump = tuple(np.where(on[:, a, None], own_jump[a], 0.0) for a in range(N))
        own_cov = tuple(np.where(on[:, a, None, None], own_cov[a], 0.0) for a in range(N))
        pending = np.where(reset, doubt, state.pending)
        deferred = np.where(reset, defer, state.deferred & ~applied)
        support = np.where(reset, 0.0, support)
        length = np.where(hold & ~rising, state.length + 1, 0)
        agree = np.where(hold & ~rising, agree, 0)
        level_age = np.where(hold & ~rising, level_age, -1)  # a new or ended hold: none
        owed = owed & hold & ~rising
        new_state = state._replace(
            level=level,
            level_A=level_A,
            level_age=level_age,
            due=owed,
            support=support,
            length=length,
            own=agree,
            inner=inner,
            inner_sum=inner_sum,
            inner_cov=inner_cov,
            deferred=deferred,
            applied=applied,
            moved=moved,
            own_jump=own_jump,
            own_cov=own_cov,
            pulls=test.pulls,
            alternative=test.alternative,
            hold=hold,
            pending=pending,
            passes=passes,
            passes_alt=passes_alt,
            overruled=overruled,
            steady=steady,
            steps=steps,
            since=since,
            last=last,
            jump=jump,
            jump_cov=jump_cov,
            jumps=jumps,
            calm=calm,
            taken=taken_sum,
            spread=spread,
            settling=np.where(
                relaxed | welcome, 0, np.where(state.settling >= 0, state.settling + 1, -1)
            ),
            gap=np.where(rising, state.since >= self.patience, state.gap) & hold,
        )
        out = GuardOutput(
            ratio,
            flags,
            alarm,
            (choose & ~defer) | applied,
            undone,
            unobs,
            relaxed | welcome,
            taken,
            noisy,
            device,
            faded,
        )
        # ``rate`` (above): a held only aid's consistent increment (after a step the aid
        # moves as the vehicle does, offset) still tells the estimate's rate, once
        # ``n_off`` in a row were consistent; never a repeated output's (a frozen receiver
        # looks like a stop at a crawl, and would hold the estimate still)
        return new_state, out, flags, windows, rate, noise, home, inc, offset

    def _lasting(
        self,
        state: GuardState,
        test: GuardTest,
        judged: np.ndarray,
        usable: np.ndarray,
    ) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...], np.ndarray, tuple[np.ndarray, ...]]:
        """A held aid's lasting offset (module docstring, 3): the new ``level``,
        ``level_A``, ``level_age`` and, per aid, the rows (B, m) of an offset to take now.

        Where a held aid measures (``judged``: held, fresh, beside other aids, no noise
        shown), its innovation is compared with its level, the innovation when its
        present run began: ``ν − ν₀`` against ``2R + κ² H(P − P₀)Hᵀ`` (its two noises
        and the coast's growth since).  A departure (a jump, a ramp, a drift the coast did
        not foresee) starts a new run at the present innovation.  A run that has kept its
        level for ``lasting_s`` is a constant offset between the aid and the estimate:
        neither the aid's ramp nor the estimate's drift.  Its rows that moved beyond
        chance are taken when no other aid measuring responds to an offset of them
        (:meth:`_unseen` with ``offset``: a position beside velocities, an odometer or the
        vehicle constraints, which cannot tell one constant position offset from another;
        not a star tracker's tilt beside GNSS velocities, whose rate the tilt moves) and
        the rows they respond to did not move."""
        B, N = judged.shape
        k2 = self.config.kappa**2
        t1 = _threshold(self.pfa, 1)
        level, level_A = list(state.level), list(state.level_A)
        age = state.level_age.copy()
        offset = []
        for a, t in enumerate(test.aids):
            j = judged[:, a] & self.rollback
            rows = np.zeros((B, self.dims[a]), bool)
            # (in epochs: ``lasting_s`` is a time, whatever the aid's rate)
            age[:, a] += ~usable[:, a] & state.hold[:, a] & (age[:, a] >= 0)
            if not j.any():
                offset.append(rows)
                continue
            restart = j & (age[:, a] < 0)  # no level yet (a departure fails ``keeps``)
            S = 2.0 * t.R + k2 * _psd(kf.symmetrize(t.A - level_A[a]))
            keeps = j & ~restart & (_chi2(t.nu - level[a], S) <= self.T1[a])
            new = j & ~keeps
            level[a] = np.where(new[:, None], t.nu, level[a])
            level_A[a] = np.where(new[:, None, None], t.A, level_A[a])
            age[:, a] = np.where(j, np.where(keeps, age[:, a] + 1, 0), age[:, a])
            ripe = keeps & (age[:, a] >= self.lasting)
            if ripe.any():
                var = np.diagonal(t.A + t.R, axis1=-2, axis2=-1)
                moved = t.nu**2 / np.where(var > 0, var, np.inf) > t1
                read = ~self._unseen(a, usable & ~state.hold, test, offset=True)
                ok = ripe & moved.any(-1) & ~(moved & read).any(-1)
                rows = ok[:, None] & moved
            offset.append(rows)
        return tuple(level), tuple(level_A), age, tuple(offset)

    def _loud(
        self, candidate: np.ndarray, spread: Sequence[np.ndarray], test: GuardTest
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...], np.ndarray]:
        """(B, N) the candidates whose increments show a noise variance above
        :data:`NOISE_RATIO` times their R in some component, and per aid the noise to
        use them with (B, m, m): the larger of R and the shown noise per component.  The
        shown noise is robust to a jump and to the estimate's drift: from the median
        absolute deviation of the last increments about their median,
        ``R̂ = (MAD_SIGMA · MAD)² / 2`` (an increment of white noise has variance 2R),
        given at least half the window; and (B, N) the loud ones whose shown noise passes
        ``NOISE_RATIO²`` times it."""
        loud = np.zeros(candidate.shape, bool)
        very = np.zeros(candidate.shape, bool)
        noise = [t.R for t in test.aids]
        if (not self.rollback and self.common is None) or not candidate.any():
            return loud, tuple(noise), very
        for a in range(len(test.aids)):
            if not candidate[:, a].any():
                continue
            shown, enough = _shown_noise(spread[a])
            r = self._floor(a, test)
            loud[:, a] = candidate[:, a] & enough & (shown > NOISE_RATIO * r).any(-1)
            very[:, a] = loud[:, a] & (shown > NOISE_RATIO**2 * r).any(-1)
            noise[a] = np.maximum(shown, r)[..., None] * np.eye(self.dims[a])
        return loud, tuple(noise), very

    def _floor(self, a: int, test: GuardTest) -> np.ndarray:
        """(B, m) the noise variance aid ``a``'s increments are judged against: its R,
        and for an independent local its private states' part, ``H_p P_p H_pᵀ`` (a GNSS
        position's augmented Markov error moves its innovation as its noise does; the
        fused guard folds it into R the same way)."""
        t = test.aids[a]
        r = np.diagonal(t.R, axis1=-2, axis2=-1)
        c = self.common
        g = self.group_of[a]
        if c is None or self.sizes[g] <= c:
            return np.asarray(r)
        Hp, Pp = test.H[a][..., c:], test.P[g][:, c:, c:]
        return np.asarray(r + np.diagonal(Hp @ Pp @ kf.mT(Hp), axis1=-2, axis2=-1))

    def _support(
        self, state: GuardState, test: GuardTest, usable: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(B, N) the other aids' evidence for each held aid, and where it backs the aid
        (module docstring, 6).

        Each witness ``j`` (measuring, not held, responding to the held aid's rows:
        :meth:`_unseen`) gives twice its log-likelihood ratio of "the held aid is right"
        (its innovation against the estimate updated by the held aid's measurement,
        ``ν_j − H_j K_a ν_a`` with ``S_j⁺ = H_j (I − K_a H_a) P H_jᵀ + R_j``) against "the
        estimate is right" (``ν_j``, ``S_j``):
        ``χ²(ν_j, S_j) + ln|S_j| − χ²(ν_j − H_j K_a ν_a, S_j⁺) − ln|S_j⁺|``.  Where the
        held aid is right its update moves the estimate towards what the witness
        measures; where it is faulty, away.  The witnesses' sum is accumulated over the
        hold as Page's CUSUM (floored at zero): above ``2 ln(1/pfa)`` (a mean run
        between false backings of at least ``1/pfa`` epochs, for true likelihood ratios)
        the aid is backed, once held for the patience (the other rules had their chance:
        on the drive the GLR's false alarms in turns last a few seconds, and ending them
        early only moved the next one).  Only a hold with no jump (its onset's or since):
        a jump is the signature of the aid's own fault — unless another aid, of another
        device (:func:`devices_of`), is held beside it.  Under a single fault two
        devices do not fail at once, so the estimate did, and its drift makes a jump of
        every increment: the two held aids witness each other (with the unheld ones), and
        the patience counts from the hold's onset (``length``).  A backed hold with jumps
        takes its jump sum (:meth:`decide`).  Two aids of one device (a receiver's
        positions and velocities) may fail together (both noisy) and never back each
        other."""
        B, N = usable.shape
        support = state.support.copy()  # zero where not held: reset at every hold's ends
        backed = np.zeros((B, N), bool)
        held = state.hold & usable
        if (not self.rollback and self.common is None) or not held.any():
            return support, backed
        # another held aid of the group, of another device, measuring now: under a
        # single fault, two devices' aids held at once are not both faulty, so a jump of
        # each is no longer the aid's own.  Never two aids of one device (a receiver's
        # positions and velocities fail together: a noise increase of both shares the
        # coast's drift, and they would back each other on it)
        co = np.zeros((B, N), bool)
        for a in range(N):
            for j in self._peers(a):
                if self._apart(a, j):
                    co[:, a] |= held[:, j]
        co &= held
        # (independent locals: only two held aids back each other, no steady hold)
        cand = held & (((state.jumps == 0) & self.rollback) | co)
        if not cand.any():
            return support, backed
        for a in range(N):
            ca = cand[:, a]
            if not ca.any():
                continue
            g, ta = self.group_of[a], test.aids[a]
            P, Ha = test.P[g], test.H[a]
            K, A = _gain(P, Ha, ta.R)
            dx = kf.mv(K, ta.nu)
            P_a = P - reduction(K, A, ta.R)  # the estimate updated by the held aid
            gain, seen_any = np.zeros(B), np.zeros(B, bool)
            for j in self._peers(a):
                # a held witness only for an aid held beside it (the two back each other)
                w = ca & usable[:, j]
                w &= ~state.hold[:, j] | (co[:, a] & self._apart(a, j))
                if not w.any():
                    continue
                only_j = np.zeros((B, N), bool)
                only_j[:, j] = w
                w &= ~self._unseen(a, only_j, test).all(-1)
                if not w.any():
                    continue
                tj, Hj = test.aids[j], self._on(j, g, test.H[j])
                S0 = tj.A + tj.R
                R_j = tj.R
                if self.group_of[j] != g:  # another local's: its private part of S0 stays
                    R_j = kf.symmetrize(S0 - Hj @ P @ kf.mT(Hj))
                    R_j = np.where(_pd_rows(R_j)[:, None, None], R_j, tj.R)
                S1 = kf.symmetrize(Hj @ P_a @ kf.mT(Hj)) + R_j
                # no evidence from a covariance gone singular (a diverged run)
                fine = _pd_rows(S0) & _pd_rows(S1)
                w &= fine
                if not w.any():
                    continue
                eye = np.eye(S0.shape[-1])
                S0 = np.where(fine[:, None, None], S0, eye)
                S1 = np.where(fine[:, None, None], S1, eye)
                q0 = _chi2(tj.nu, S0) + np.linalg.slogdet(S0)[1]
                q1 = _chi2(tj.nu - kf.mv(Hj, dx), S1) + np.linalg.slogdet(S1)[1]
                gain += np.where(w, q0 - q1, 0.0)
                seen_any |= w
            support[:, a] = np.where(seen_any, np.maximum(0.0, support[:, a] + gain), support[:, a])
            # the other rules had their chance: the patience since the last jump, or,
            # backed by another held aid, since the hold began (the estimate's drift
            # makes a jump of every increment)
            ripe = (state.calm[:, a] >= self.patience) | (
                co[:, a] & (state.length[:, a] >= self.patience)
            )
            backed[:, a] = ca & seen_any & ripe & (support[:, a] > -2.0 * math.log(self.pfa))
        return support, backed

    def _apart(self, a: int, j: int) -> bool:
        """Whether aids ``a`` and ``j`` are two (not one aid) of different devices."""
        if a == j:
            return False
        return self.devices is None or self.devices[a] != self.devices[j]

    def _cancelled(self, a: int, J: np.ndarray, C: np.ndarray, where: np.ndarray) -> np.ndarray:
        """(B,) where ``where``: whether aid ``a``'s jump sum ``J`` is zero within its
        covariance ``C`` (the jumps cancel: the aid is back where it was)."""
        valid = where & _pd_rows(np.where(where[:, None, None], C, np.eye(self.dims[a])))
        C = np.where(valid[:, None, None], C, np.eye(self.dims[a]))
        return np.asarray(valid & (_chi2(J, C) <= self.T1[a]))

    def _home(
        self,
        state: GuardState,
        inc: Sequence[tuple[np.ndarray, np.ndarray]],
        good: np.ndarray,
        candidate: np.ndarray,
        usable: np.ndarray,
        test: GuardTest,
    ) -> np.ndarray:
        """(B, N) the aids (not held, flagged, ``candidate``) whose increment now is a
        jump that undoes the jump sum kept from a hold they were re-admitted with: in
        every row the jump moves (beyond chance), the sum is a jump (beyond chance in
        its own covariance) and the sum plus the jump is zero within their covariance,
        and no other aid measuring now reads those rows
        (:meth:`_unseen` without rates: a position beside velocities and constraints).
        The aid is back where it was before its fault (module docstring, 3).  Only the
        moved rows are compared: the sum's other rows may hold what the estimate's own
        moves (a rollback, a jump taken) left in the held aid's increments."""
        B, N = usable.shape
        out = np.zeros((B, N), bool)
        if not self.rollback and self.common is None:  # the neuron centre: no sums
            return out
        for a in range(N):
            cand = candidate[:, a] & usable[:, a] & (state.since[:, a] >= 0) & ~good[:, a]
            cand &= (state.jumps[:, a] > 0) & (state.jump[a] != 0).any(-1)
            if not cand.any():
                continue
            # the rows the jump now moves must cancel the kept sum there (the sum's
            # other rows may hold what the estimate's own moves left in it)
            d, Cd = inc[a]
            J, C = state.jump[a], state.jump_cov[a]
            t1 = _threshold(self.pfa, 1)
            var_d = np.diagonal(Cd, axis1=-2, axis2=-1)
            var_j = np.diagonal(C, axis1=-2, axis2=-1)
            var_s = var_j + var_d
            moved = d**2 / np.where(var_d > 0, var_d, np.inf) > t1
            undone = (J + d) ** 2 / np.where(var_s > 0, var_s, np.inf) <= t1
            # and the sum there must be a jump itself, beyond chance: a sum within its
            # own covariance is a pile of noisy increments that any jump "undoes"
            # (seed002's noise ramp under VB, whose R̂ hid the noise from the noise
            # rules: home on such a sum moved the velocity 4.3 m/s)
            undone &= J**2 / np.where(var_j > 0, var_j, np.inf) > t1
            back = cand & moved.any(-1) & (undone | ~moved).all(-1)
            read = ~self._unseen(a, usable & ~state.hold, test, rates=False)
            out[:, a] = back & ~(moved & read).any(-1)
        return out

    def _own(
        self,
        state: GuardState,
        test: GuardTest,
        inc: Sequence[tuple[np.ndarray, np.ndarray]],
        judged: np.ndarray,
        moved: Sequence[np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray, list[np.ndarray], list[np.ndarray]]:
        """Each held aid's test against its own device (module docstring, 7).

        Where a mate ``b`` of aid ``a``'s device measures its rate (``H_b`` fits the
        rate rows ``H_a(Φ − I) ≈ G H_b`` but for :data:`RATE_FIT` of their weight, each
        state in its own σ: a receiver's velocities beside its positions) and both
        measured now and at the same epoch before, ``Δk`` epochs back, the aid's
        increment less the trapezoid of the mate's,
        ``e = (ν_a + H_a m_a − r_a) − Δk G (ν_b + H_b m_b + r_b)/2``, holds the device's
        disagreement with itself only: the estimate's drift enters both alike and
        cancels to first order, whatever it is (a SINS fault's), and the other aids'
        updates since (``moved``, ``m``: the vehicle constraints between the fixes) are
        taken out of both.  Its covariance ``2R_a + Δk² G (R_b/2) Gᵀ``.
        Returns ``tested`` and ``consistent`` (B, N), each where some mate tested it,
        and per aid ``e`` (B, m) and its covariance (zero where untested).
        """
        B, N = judged.shape
        tested, bad = np.zeros((B, N), bool), np.zeros((B, N), bool)
        es = [np.zeros((B, m)) for m in self.dims]
        Ss = [np.zeros((B, m, m)) for m in self.dims]
        for a in range(N):
            for b in self.mates[a]:
                g = self.group_of[a]
                both = judged[:, a] & judged[:, b] & (state.since[:, a] >= 0)
                both &= state.since[:, a] == state.since[:, b]
                if g != self.group_of[b] or not both.any():
                    continue
                Ha, Hb = test.H[a], test.H[b]
                G, miss, whole, fine = _rate_map(Ha, Hb, test.P[g], test.F[g], both)
                if not fine.any():
                    continue
                fine &= miss.sum(-1) <= RATE_FIT * whole.sum(-1)
                ta, tb = test.aids[a], test.aids[b]
                dk = (state.since[:, a] + 1).astype(float)
                nu_b = tb.nu + kf.mv(Hb, moved[b])
                e, add = _less_trapezoid(
                    inc[a][0], kf.mv(Ha, moved[a]), G, nu_b, state.last[b], dk, tb.R
                )
                S = kf.symmetrize(2.0 * ta.R + add)
                tested[:, a] |= fine
                bad[:, a] |= fine & (_chi2(e, S) > self.T1[a])
                es[a] = np.where(fine[:, None], e, es[a])
                Ss[a] = np.where(fine[:, None, None], S, Ss[a])
        return tested, tested & ~bad, es, Ss

    def _inner(
        self,
        state: GuardState,
        test: GuardTest,
        inc: Sequence[tuple[np.ndarray, np.ndarray]],
        judged: np.ndarray,
        moved: Sequence[np.ndarray],
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...], tuple[np.ndarray, ...], np.ndarray]:
        """Each held aid's rows that measure the rate of its other rows, against them
        over the hold (:meth:`_own` within one aid: a receiver's positions beside its
        own velocities).

        Rows ``r`` of ``H_a`` whose rate ``H_r(Φ − I)`` the aid's other rows fit,
        ``≈ G_r H_a`` but for :data:`RATE_FIT` of their weight (each state in its own
        σ), measured now and ``Δk`` epochs before: their increment less the trapezoid of
        the aid's own, ``e = (Δν + H_a m)_r − Δk G_r (ν + H_a m + r)/2``, summed over the
        hold, with covariance ``2R_r + Σ Δk² G (R/2) Gᵀ`` (the increments telescope: the
        rows' own noise enters once).  The estimate's drift enters both alike; a ramp
        of the rows that their rate rows do not share adds up (seed002's GNSS positions
        ramping 1 m/s east beside its healthy velocities: 30 m in 30 s against a σ of
        1.4 m, where each increment's 1 m is inside its own 1.4 m).  Returns the count
        of increments summed, the sums, their covariances, and ``consistent`` (B, N):
        at least ``n_off`` increments, the sum's χ² within the guard's false-alarm
        probability.
        """
        B, N = judged.shape
        count = np.where(state.hold, state.inner, 0)
        sums, covs = list(state.inner_sum), list(state.inner_cov)
        good = np.zeros((B, N), bool)
        for a in range(N):
            held = state.hold[:, a]
            sums[a] = np.where(held[:, None], sums[a], 0.0)
            covs[a] = np.where(held[:, None, None], covs[a], 0.0)
            now = judged[:, a] & (state.since[:, a] >= 0)
            if not now.any():
                continue
            g = self.group_of[a]
            Ha, t = test.H[a], test.aids[a]
            # (a rate by the other rows, not a row's own level)
            G, miss, whole, fine = _rate_map(Ha, Ha, test.P[g], test.F[g], now, own=False)
            rows = (miss <= RATE_FIT * whole) & (whole > 0) & fine[:, None]
            on = rows.any(-1)
            if not on.any():
                continue
            dk = (state.since[:, a] + 1).astype(float)
            m_a = kf.mv(Ha, moved[a])
            e, add = _less_trapezoid(inc[a][0], m_a, G, t.nu + m_a, state.last[a], dk, t.R)
            sums[a] = np.where(on[:, None], sums[a] + np.where(rows, e, 0.0), sums[a])
            covs[a] = np.where(on[:, None, None], covs[a] + add, covs[a])
            count[:, a] = np.where(on, count[:, a] + 1, count[:, a])
            q = _chi2_rows(sums[a], kf.symmetrize(2.0 * t.R + covs[a]), rows)
            k = rows.sum(-1)
            good[:, a] = on & (count[:, a] >= self.n_off) & (q <= _thresholds(self.pfa, k))
        return count, tuple(sums), tuple(covs), good

    def _jumps(
        self, state: GuardState, inc: Sequence[tuple[np.ndarray, np.ndarray]], fail: np.ndarray
    ) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
        """The hold's jump sums with this epoch's inconsistent increments added."""
        N = fail.shape[1]
        j0, c0 = state.jump, state.jump_cov
        jump = tuple(np.where(fail[:, a, None], j0[a] + inc[a][0], j0[a]) for a in range(N))
        cov = tuple(np.where(fail[:, a, None, None], c0[a] + inc[a][1], c0[a]) for a in range(N))
        return jump, cov

    def _increments(
        self, state: GuardState, test: GuardTest, usable: np.ndarray, need: np.ndarray | None
    ) -> tuple[
        np.ndarray,
        tuple[tuple[np.ndarray, np.ndarray], ...],
        np.ndarray,
        tuple[np.ndarray, ...],
    ]:
        """Each aid's increment test (module docstring, 3): whether its measurement moved
        since its last one as the estimate did.

        ``Δk`` epochs after its last measurement, the innovation of a healthy aid differs
        from its residual then (against the posterior the estimate went on from, or its
        innovation while held) by its two noises and the estimate's drift over those
        epochs: ``ν_k − r_prev`` with covariance ``2R + κ² Δk² H(Φ − I)P(Φ − I)ᵀHᵀ``
        (one epoch's drift of the measured quantity, linear over a few epochs).  A jump,
        the frozen output of a moving vehicle or a noise increase fails it; a drift of
        the estimate that the covariance did not foresee does not.  Returns ``good``
        (B, N; False where untested), each aid's increment and its covariance, the new
        ``since`` and ``last`` (the held aids' innovations; :meth:`record` sets the used
        aids' residuals).  The test itself is made only where ``need`` (B, N) holds
        (none: nowhere); ``good`` is False elsewhere.
        """
        B, N = usable.shape
        good = np.zeros((B, N), bool)
        inc = []
        since = state.since.copy()
        last = list(state.last)
        k2 = self.config.kappa**2
        for a, t in enumerate(test.aids):
            check = usable[:, a] & (since[:, a] >= 0)
            d = np.where(check[:, None], t.nu - last[a], 0.0)
            S = 2.0 * t.R
            if need is not None and (check & need[:, a]).any():
                g = self.group_of[a]
                P = test.P[g]
                HF = test.H[a] @ (np.broadcast_to(test.F[g], P.shape) - np.eye(P.shape[-1]))
                drift = kf.symmetrize(HF @ P @ kf.mT(HF))  # one epoch's drift of it
                dk = (since[:, a] + 1).astype(float)
                S = S + k2 * (dk**2)[:, None, None] * drift
                good[:, a] = check & need[:, a] & (_chi2(d, S) <= self.T1[a])
            inc.append((d, np.where(check[:, None, None], S, 0.0)))
            now = usable[:, a]
            last[a] = np.where(now[:, None], t.nu, last[a])
            since[:, a] = np.where(now, 0, np.where(since[:, a] >= 0, since[:, a] + 1, -1))
        return good, tuple(inc), since, tuple(last)

    def _alternative(
        self,
        a: int,
        t: _AidTest,
        S: np.ndarray,
        test: GuardTest,
        state: GuardState,
        usable: np.ndarray,
    ) -> np.ndarray:
        """(B,) whether the estimate with aid ``a``'s rollback undone passes: the aid's
        own χ² (``S`` its allowed covariance) and no other aid of its group that holds
        what the rollback moved disagreeing with it more than with the estimate as it is
        (a redundant aid confirms the rollback; a sole-source aid has no such witness)."""
        g = self.group_of[a]
        alt = test.alternative[g]
        c_alt, G_alt = alt.c[:, self.slot[a], 0], alt.G[:, self.slot[a], 0]
        Ha = test.H[a]
        HGH = kf.symmetrize(Ha @ G_alt @ kf.mT(Ha))
        # a deferred rollback's alternative adds its covariance (its G is negated)
        later = state.deferred[:, a, None, None]
        S_b = np.where(later, S + _psd(-HGH), S - _psd(HGH))
        S_b = np.where(_pd_rows(S_b)[:, None, None], S_b, S)
        ok = np.asarray(_chi2(t.nu - kf.mv(Ha, c_alt), S_b) <= self.T1[a])
        for j in self.groups[g]:
            if j == a:
                continue
            tj = test.aids[j]
            w = usable[:, j] & ~state.hold[:, j]
            if not w.any():
                continue
            S_j = tj.A + tj.R
            q_a = _chi2(tj.nu, S_j)
            q_b = _chi2(tj.nu - kf.mv(test.H[j], c_alt), S_j)
            ok &= ~w | (q_b <= np.maximum(self.T1[j], q_a))
        return np.asarray(ok, bool)

    def _peers(self, a: int) -> list[int]:
        """The aids that may witness aid ``a``: the others of its group, or, for
        independent locals (``common``), every other aid."""
        if self.common is None:
            return [j for j in self.groups[self.group_of[a]] if j != a]
        return [j for j in range(self.N) if j != a]

    def _on(self, j: int, g: int, Hj: np.ndarray) -> np.ndarray:
        """Aid ``j``'s ``H`` on group ``g``'s states: itself in its own group, else its
        columns of the shared states (the first ``common``), zero on the rest."""
        if self.group_of[j] == g or self.common is None:
            return Hj
        c = self.common
        out = np.zeros(Hj.shape[:-1] + (self.sizes[g],))
        out[..., :c] = Hj[..., :c]
        return out

    def _witness_present(
        self,
        a: int,
        usable: np.ndarray,
        state: GuardState | None = None,
        method: bool = False,
        test: GuardTest | None = None,
        care: np.ndarray | None = None,
    ) -> np.ndarray:
        """(B,) whether another aid of ``a``'s group has a measurement and is not isolated
        (with ``state``; without: whether another aid has a measurement); with ``method``
        another aid of the method (:meth:`_peers`).  With ``test``, where ``care`` (B,),
        those aids must together see every direction of ``a``'s quantity
        (:meth:`_blind`)."""
        out = np.zeros(usable.shape[0], bool)
        present = np.zeros(usable.shape, bool)
        for j in self._peers(a) if method else self.groups[self.group_of[a]]:
            if j != a:
                present[:, j] = usable[:, j] & (True if state is None else ~state.hold[:, j])
                out |= present[:, j]
        if test is not None and care is not None and (out & care).any():
            out &= ~self._blind(a, present, test, out & care & self._constrained(a, usable))
        return out

    def _constrained(self, a: int, usable: np.ndarray) -> np.ndarray:
        """(B,) whether every other aid that measures now, held or not, is a gated
        pseudo-measurement (a vehicle constraint): no sensor beside aid ``a``."""
        peers = self._peers(a)
        return np.asarray(~(usable[:, peers] & ~self.pseudo[peers]).any(-1))

    def _blind(
        self, a: int, witnesses: np.ndarray, test: GuardTest, where: np.ndarray
    ) -> np.ndarray:
        """(B,) whether the aids in ``witnesses`` (B, N) leave a direction of aid ``a``'s
        measured quantity unseen: a direction ``u`` of ``a``'s measurement space whose
        quantity ``uᵀH_a x`` and rate ``uᵀH_a D x`` (``D = Φ − I``) both lie mostly
        outside the span of what the witnesses respond to (``H_j``, ``H_j D``,
        ``H_j D²``, each state in its own σ: ``Σ = diag(P)^{1/2}``).  The share of a
        direction a witness sees is ``uᵀ A^{-1/2} H Σ Π Σ Hᵀ A^{-1/2} u`` with ``Π`` the
        projector on the witnesses' rows and ``A = H Σ² Hᵀ``, for ``H`` the quantity and
        for its rate; a direction is unseen where the two shares add to less than
        :data:`BLIND_SHARE`.
        The vehicle constraints see a position's rate across the track and up, not along
        it: beside them alone the drive's fixes are the only source of the along-track
        motion (docs/integrity.md §1.6).  Decided only where no sensor measures beside the
        aid (:meth:`_constrained`); computed where ``where`` (B,), False elsewhere."""
        out = np.zeros(where.shape[0], bool)
        rows = np.flatnonzero(where & witnesses[:, self._peers(a)].any(-1))
        if rows.size == 0:
            return out
        g = self.group_of[a]
        P = test.P[g][rows]
        n = P.shape[-1]
        # each state in its own σ, its correlations left out (as :func:`_carries`): what
        # a witness reads, not what the prior happens to correlate with it (with P's
        # square root the shares of the drive's along-track direction crossed 0.5 and
        # back as the correlations moved, and the fixes alternated between the two rules:
        # the GLR 0.138 m fault-free against 0.063 m so)
        sd = np.sqrt(np.maximum(np.diagonal(P, axis1=-2, axis2=-1), 0.0))[:, None, :]
        D = np.broadcast_to(test.F[g], test.P[g].shape)[rows] - np.eye(n)
        blocks = []
        for j in self._peers(a):
            Hj = self._on(j, g, test.H[j])[rows]
            HjD = Hj @ D
            for M in (Hj, HjD, HjD @ D):
                W = M * sd
                norm = np.linalg.norm(W, axis=-1, keepdims=True)
                W = np.where(norm > 0, W / np.where(norm > 0, norm, 1.0), 0.0)
                blocks.append(W * witnesses[rows, j, None, None])
        _, sv, Vt = np.linalg.svd(np.concatenate(blocks, 1), full_matrices=False)
        keep = sv > BLIND_RANK * sv[:, :1]
        V = kf.mT(Vt) * keep[:, None, :]
        Ha = test.H[a][rows]
        share = np.zeros(Ha.shape[:-2] + (Ha.shape[-2],) * 2)
        for Q in (Ha * sd, (Ha @ D) * sd):
            A = Q @ kf.mT(Q)
            w, U = np.linalg.eigh(A)
            inv = np.where(w > 1e-12 * w[:, -1:], 1.0 / np.sqrt(np.maximum(w, 1e-300)), 0.0)
            Ai = (U * inv[:, None, :]) @ kf.mT(U)
            QV = Ai @ Q @ V
            share += QV @ kf.mT(QV)
        out[rows] = np.linalg.eigvalsh(kf.symmetrize(share))[:, 0] < BLIND_SHARE
        return out

    def _unseen(
        self,
        a: int,
        witnesses: np.ndarray,
        test: GuardTest,
        rates: bool = True,
        offset: bool = False,
    ) -> np.ndarray:
        """(B, m) the rows of aid ``a`` that no other aid of its group in ``witnesses``
        (B, N) responds to.  A row's quantity is carried by the states of ``H_a`` and of
        its rate ``H_a D`` (``D = Φ − I``); a witness responds to the states of its rows,
        their rates and the rates' rates (``H_j``, ``H_j D``, ``H_j D²``), each state by
        the 1 % rule of :func:`_carries`.  A star tracker or an altimeter responds to no
        horizontal GNSS row; GNSS velocities, an odometer or the vehicle constraints to
        the position's rate; GNSS positions or velocities to an attitude (a tilt moves
        the velocity's rate).  Every row where no witness measures.  Without ``rates``
        the rows no witness *reads*: the quantity is carried by ``H_a``'s states and a
        witness reads those of ``H_j`` only (a rate or a constraint reads none of a
        position's: it cannot tell one constant offset from another).  With ``offset`` the
        rows where a constant offset of the quantity itself (``H_a``'s states, not their
        rate) moves nothing a witness responds to, rates included: a position beside a
        velocity aid (a constant position offset has no rate), not a star tracker's tilt
        beside GNSS velocities (a tilt moves their rate)."""
        g = self.group_of[a]
        others = self._peers(a)
        present = np.zeros(witnesses.shape[0], bool)
        for j in others:
            present |= witnesses[:, j]
        out = np.ones((witnesses.shape[0], self.dims[a]), bool)
        if not present.any():
            return out
        P, Ha = test.P[g], test.H[a]
        D = np.broadcast_to(test.F[g], P.shape) - np.eye(P.shape[-1])
        quantity = _carries(Ha, P)  # (B, m, n)
        if rates and not offset:
            quantity = quantity | _carries(Ha @ D, P)
        seen = np.zeros(P.shape[:2], bool)
        for j in others:
            Hj = self._on(j, g, test.H[j])
            moves = _carries(Hj, P)
            if rates or offset:
                HjD = Hj @ D
                moves = moves | _carries(HjD, P) | _carries(HjD @ D, P)
            seen |= witnesses[:, j, None] & moves.any(1)
        return np.asarray(~(quantity & seen[:, None, :]).any(-1))

    def _unwitnessed(
        self,
        a: int,
        usable: np.ndarray,
        test: GuardTest,
        state: GuardState,
        only: np.ndarray,
        care: np.ndarray,
    ) -> np.ndarray:
        """(B,) whether no other aid of ``a``'s group that measures now can judge ``a``'s
        hold: its jump (the hold's sum, or the jump taken whose end cancels it) lies in
        rows none of them sees (:meth:`_unseen`), and the rows they see moved by no
        more than chance (the sum's χ² there against its covariance, at the guard's
        false-alarm probability).  True where no other aid measures (``only``, (B,)).
        A noise increase moves every row, so it does not pass.  Computed where ``care``
        (B,); elsewhere ``only``."""
        if not (~only & care).any():
            return only
        unseen = self._unseen(a, usable, test)
        J, C = state.jump[a], state.jump_cov[a]
        var = np.diagonal(C, axis1=-2, axis2=-1)
        z2 = np.maximum(J**2, state.taken[a] ** 2) / np.where(var > 0, var, np.inf)
        moved = (z2 > _threshold(self.pfa, 1)) & unseen
        seen = ~unseen
        still = _chi2_rows(J, C, seen) <= _thresholds(self.pfa, seen.sum(-1))
        return np.asarray(only | (moved.any(-1) & still))

    def _unjudged(self, a: int, witnesses: np.ndarray, test: GuardTest) -> np.ndarray:
        """(B,) whether aid ``a``'s innovation departs from the estimate only in rows no
        other aid of its group in ``witnesses`` (B, N) responds to (:meth:`_unseen`): its
        χ² over the unseen rows beyond, and over the seen rows within, the guard's
        false-alarm probability (each against its part of ``S = A + R``).  What the
        others can judge of the aid, they find right; what it disagrees in, they cannot
        see (seed002's GNSS: its height and velocities beside the altimeter and the star
        tracker, its horizontal position beside nothing)."""
        t = test.aids[a]
        unseen = self._unseen(a, witnesses, test)
        q = [
            _chi2_rows(t.nu, t.A + t.R, rows) - _thresholds(self.pfa, rows.sum(-1))
            for rows in (unseen, ~unseen)
        ]
        return np.asarray((q[0] > 0) & (q[1] <= 0))

    def _confounded(self, a: int, witnesses: np.ndarray, test: GuardTest) -> np.ndarray:
        """(B,) whether the other aids of ``a``'s group in ``witnesses`` (B, N) that
        respond to ``a``'s quantity (:meth:`_unseen`'s 1 % rule on ``H_j``, ``H_j D``,
        ``H_j D²``) respond to the move ``a``'s innovation asks (on its carriers,
        :func:`_carrier`) only as states ``a`` does not measure could make them: within
        :data:`CONFOUNDED` of its size in the span of those states' columns, each in its
        σ.  A star tracker's tilt beside GNSS velocities, whose rate a tilt moves as an
        accelerometer bias does: at no epoch can they say which of the two moved.  False
        where no witness responds (:meth:`_unwitnessed` is for that); a position beside
        its velocities (they read its rate) or velocities beside positions (a velocity
        offset is all their rate holds) are judged."""
        g = self.group_of[a]
        P, Ha, t = test.P[g], test.H[a], test.aids[a]
        D = np.broadcast_to(test.F[g], P.shape) - np.eye(P.shape[-1])
        sigma = np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
        quantity = _carries(Ha, P).any(1)  # (B, n) the states a reads
        move = kf.mv(_carrier(Ha, P), t.nu)
        seen = np.zeros(P.shape[0], bool)
        judged = np.zeros(P.shape[0], bool)
        for j in self._peers(a):
            w = witnesses[:, j]
            if not w.any():
                continue
            Hk = self._on(j, g, test.H[j])
            for _ in range(3):  # the witness's quantity, its rate, its rate's rate
                cols = _carries(Hk, P).any(1)
                sees = w & (cols & quantity).any(-1)
                other = Hk * np.where(cols & ~quantity, sigma, 0.0)[:, None, :]
                y = kf.mv(Hk, move)
                fit = kf.mv(other @ np.linalg.pinv(other), y)
                left = np.linalg.norm(y - fit, axis=-1) > CONFOUNDED * np.linalg.norm(y, axis=-1)
                seen |= sees
                judged |= sees & left
                Hk = Hk @ D
        return np.asarray(seen & ~judged)

    def _offset_seen(
        self,
        a: int,
        usable: np.ndarray,
        test: GuardTest,
        state: GuardState,
        device: bool = False,
    ) -> np.ndarray:
        """(B,) whether an unheld aid of held aid ``a``'s group that measured since
        ``a``'s last measurement (now, or at the same fix) responds to a constant offset
        of one of ``a``'s rows (:meth:`_unseen` with ``offset``): a witness of whatever
        offset ``a`` holds, at its own rate, though none measures now (GNSS positions of
        their velocities; not GNSS velocities, an odometer or the constraints of a
        position).  With ``device`` only the aids of ``a``'s own device witness
        (:func:`devices_of`)."""
        since = state.since
        recent = (usable | ((since >= 0) & (since <= since[:, a, None]))) & ~state.hold
        recent[:, a] = False
        if device:
            recent &= np.isin(np.arange(self.N), self.mates[a])
        if not recent.any():
            return np.zeros(usable.shape[0], bool)
        # (a batch row without such an aid has every row unseen)
        return np.asarray(~self._unseen(a, recent, test, offset=True).all(-1))

    def _witnessed(
        self, a: int, test: GuardTest, state: GuardState, usable: np.ndarray
    ) -> np.ndarray:
        """(B, J) whether no other aid of ``a``'s group that has a measurement (and is not
        isolated) speaks against removing ``a``'s pull over each window.

        Each witness ``j`` weighs the two hypotheses by their likelihoods: its innovation
        ``ν_j`` against ``S_j`` as the estimate is, and ``ν_j + H_j c`` against
        ``S_j + H_j G H_jᵀ`` with the pull removed.  It disagrees when the first is
        favoured by more than 100 to 1 (twice the log-likelihood ratio above its
        χ²₁ quantile): a witness that does not see the moved states has a ratio near 1,
        one that sees a real drag favours the removal, and one that sees a removal of
        noise (a pull merely large for its covariance, e.g. under a noise increase) is
        moved away from its measurement and refuses it.  A sole source has no witness:
        its rollback rests on its own pull (a turn the INS errs in can look like a drag
        there: docs/integrity.md)."""
        g = self.group_of[a]
        cw, Gw = sep.windows(test.pulls[g], self.slot[a])
        ok = np.ones(cw.shape[:2], bool)
        for j in self.groups[g]:
            if j == a:
                continue
            tj = test.aids[j]
            seen = usable[:, j] & ~state.hold[:, j]
            if not seen.any():
                continue
            e, T = sep.measured(cw, Gw, test.H[j])  # H_j c, H_j G H_jᵀ of every window
            S_j = tj.A + tj.R
            q_before = _chi2(tj.nu, S_j)[:, None]
            S_a = S_j[:, None] + T
            q_after = _chi2(tj.nu[:, None] + e, S_a)
            grow = np.linalg.slogdet(S_a)[1] - np.linalg.slogdet(S_j)[1][:, None]
            ok &= ~seen[:, None] | (q_after - q_before + grow <= WITNESS_LLR)
        return ok

    # ----------------------------------------------------------------------- one epoch
    def begin(
        self,
        state: GuardState,
        priors: Sequence[Gaussian],
        F: Sequence[np.ndarray],
        z: Sequence[np.ndarray],
        H: Sequence[np.ndarray],
        R: Sequence[np.ndarray],
        usable: np.ndarray,
        detection: DetectorOutput | None,
        keep: Callable[[np.ndarray], np.ndarray] | None = None,
        repeated: np.ndarray | None = None,
    ) -> Guarded:
        """:meth:`test` and :meth:`decide` in one: the epoch's flags before the update.

        ``repeated`` (B, N): the aids whose output repeats its previous one bit for bit
        (the epoch's :attr:`~ftnav.model.system.Epoch.repeated`), or None.
        """
        test = self.test(state, priors, F, z, H, R, usable)
        after, out, flags, windows, rate, noise, home, inc, lasting = self.decide(
            state, test, detection, usable, keep, repeated
        )
        B, N = usable.shape
        if detection is None:
            detection = DetectorOutput(out.statistic, np.ones((B, N)), out.alarm, flags)
        else:
            detection = detection._replace(raw=detection.raw | out.alarm, flag=flags)
        return Guarded(
            state, after, test, out, flags, detection, windows, rate, noise, home, inc, lasting
        )

    def finish(
        self,
        g: Guarded,
        priors: Sequence[Gaussian],
        z: Sequence[np.ndarray],
        H: Sequence[np.ndarray],
        R: Sequence[np.ndarray],
        usable: np.ndarray,
    ) -> tuple[GuardState, tuple[Amend, ...]]:
        """:meth:`record` of a :meth:`begin`: the new state and each group's amend."""
        return self.record(g, priors, z, H, R, usable)

    # -------------------------------------------------------------------------- record
    def record(
        self,
        g: Guarded,
        priors: Sequence[Gaussian],
        z: Sequence[np.ndarray],
        H: Sequence[np.ndarray],
        R: Sequence[np.ndarray],
        usable: np.ndarray,
    ) -> tuple[GuardState, tuple[Amend, ...]]:
        """Accumulate the epoch's pulls and say what each group's estimate takes.

        A sequential pass over the aids the group used, on its prior, adds each aid's
        pull and maps the others' (and the alternatives); the chosen windows of the newly
        isolated aids are removed (the rollback, kept as their alternative); an aid
        re-admitted on its alternative gets its rollback back (its covariance part where
        that leaves P positive definite: the bookkeeping is first order); a relaxed
        re-admission gets the covariance that covers its innovation and its update at
        this epoch; every aid the estimate used (or rolled back) records the covariance
        the estimate coasts from.
        """
        before, after, out = g.before, g.after, g.output
        pulls, alts = list(after.pulls), list(after.alternative)
        anchor = list(after.anchor)
        last = list(after.last)
        moved = list(after.moved)
        amends = []
        rising = out.hold & ~before.hold
        released = before.hold & ~after.hold
        jumped_now = rising & (after.jumps > before.jumps)  # a hold begun at a jump
        informed = np.zeros(usable.shape, bool)  # held aids used for their noise
        for gi, grp in enumerate(self.groups):
            x, P = priors[gi]
            B, n = x.shape
            idx = np.arange(B)
            # updated in place below: with the rollback the test's pulls are this epoch's
            # own (the state's, taken over by :meth:`test`'s time update; nothing reads
            # them after the record); without it they are only read
            p, alt = pulls[gi], alts[gi]
            for s, a in enumerate(grp):  # the aids the group used, in order
                use = usable[:, a] & ~out.hold[:, a]
                if not use.any() or not self.rollback:
                    continue
                Ha, Ra = self._matrices(H[a], R[a], B)
                K, A = _gain(P, Ha, Ra)
                nu = np.where(use[:, None], np.nan_to_num(z[a]) - kf.mv(Ha, x), 0.0)
                d = np.where(use[:, None], kf.mv(K, nu), 0.0)
                D = np.where(use[:, None, None], reduction(K, A, Ra), 0.0)
                p = sep.with_own(sep.map_others(p, s, K, Ha, use, copy=False), s, d, D, copy=False)
                alt = sep.map_others(alt, s, K, Ha, use, copy=False)
                x, P = x + d, kf.symmetrize(P - D)
            dx, dP, dP_undo = np.zeros((B, n)), np.zeros((B, n, n)), np.zeros((B, n, n))
            rolled = np.zeros((B, n))  # the estimate's move by this epoch's rollbacks
            where = np.zeros(B, bool)
            c_alt, G_alt = alt.c, alt.G
            for s, a in enumerate(grp):
                applied = after.applied[:, a]
                if applied.any():  # a deferred rollback applied: an ordinary one from now
                    dx -= np.where(applied[:, None], c_alt[:, s, 0], 0.0)
                    dP -= np.where(applied[:, None, None], G_alt[:, s, 0], 0.0)
                    c_alt[:, s, 0] = np.where(applied[:, None], -c_alt[:, s, 0], c_alt[:, s, 0])
                    G_alt[:, s, 0] = np.where(
                        applied[:, None, None], -G_alt[:, s, 0], G_alt[:, s, 0]
                    )
                    where |= applied
                back = out.rollback[:, a] & ~applied
                # a deferred rollback: not applied, its negative the alternative (so
                # that undoing it applies it, with its covariance)
                later = rising[:, a] & after.deferred[:, a]
                if back.any() or later.any():  # the rollback of a newly isolated aid
                    cw, Gw = sep.windows(p, s)
                    w = g.windows[:, a]
                    cw, Gw = cw[idx, w], Gw[idx, w]
                    dx += np.where(back[:, None], cw, 0.0)
                    rolled += np.where(back[:, None], cw, 0.0)
                    dP += np.where(back[:, None, None], Gw, 0.0)
                    cw = np.where(later[:, None], -cw, cw)
                    Gw = np.where(later[:, None, None], -Gw, Gw)
                    kept = (back | later)[:, None]
                    c_alt[:, s, 0] = np.where(kept, cw, c_alt[:, s, 0])
                    G_alt[:, s, 0] = np.where(kept[..., None], Gw, G_alt[:, s, 0])
                    where |= back
                undo = out.undone[:, a]
                if undo.any():  # the aid was right: its rollback comes back
                    dx -= np.where(undo[:, None], c_alt[:, s, 0], 0.0)
                    dP_undo += np.where(undo[:, None, None], G_alt[:, s, 0], 0.0)
                    where |= undo
                if self.rollback:  # a rollback's pulls are gone (the older ones stay)
                    p = sep.clear(p, s, back | later, g.windows[:, a])
                    gone = released[:, a] | (rising[:, a] & ~back & ~later)
                    c_alt[gone, s, 0] = 0.0
                    G_alt[gone, s, 0] = 0.0
            alt = sep.Pulls(c_alt, G_alt)
            dP_back = dP.copy()
            if out.undone.any():
                fits = _pd_rows(P + dP - dP_undo)
                dP = dP - np.where(fits[:, None, None], dP_undo, 0.0)
            x, P = x - dx, P + dP
            # a device back whole (the estimate drifted): every variance was optimistic,
            # the attitude's and the biases' that drove the drift with the rest, so the
            # whole covariance is scaled to cover the device's innovation (a fading
            # factor, as a strong tracking filter's) before its relaxed update
            # (an aid taken where the others see its rows through their rates only:
            # the biases that carried the old level, likewise)
            fade = out.device | out.faded
            whole = [a for a in grp if (fade[:, a] & usable[:, a]).any()]
            if whole:
                on = np.zeros(B, bool)
                for a in whole:
                    on |= fade[:, a] & usable[:, a]
                Hs, Rs = self._stacked(whole, H, R, usable, B)
                nu = np.where(
                    on[:, None],
                    np.nan_to_num(np.concatenate([z[a] for a in whole], -1)) - kf.mv(Hs, x),
                    0.0,
                )
                A = kf.symmetrize(Hs @ P @ kf.mT(Hs))
                gam = np.where(on, inflation(nu, A, Rs), 0.0)
                grow = gam[:, None, None] * P
                P = kf.symmetrize(P + grow)
                dP += grow
                where |= on
            for s, a in enumerate(grp):
                # the relaxed re-admissions: the covariance inflated along the aid's
                # measurement to cover its innovation, and the aid taken at this epoch
                rel = out.relaxed[:, a] & usable[:, a]
                if rel.any():
                    Ha, Ra = self._matrices(H[a], R[a], B)
                    lasted = rel[:, None] & g.lasting[a]
                    jumped = out.taken[:, a] & ~lasted.any(-1)
                    homed = rel & g.home[:, a]
                    if jumped.any() or homed.any() or lasted.any():
                        # a sole source's jump taken, or an aid's jump back home: the
                        # estimate moves by it in the measured quantity only, with its
                        # covariance; the rest of the innovation is the coast's drift
                        # (below).  A jump taken moves the rows no other aid measuring
                        # sees (the others hold theirs); a home aid's rows none reads
                        M = _carrier(Ha, P)
                        J, C = np.zeros((B, self.dims[a])), np.zeros((B,) + (self.dims[a],) * 2)
                        if jumped.any():
                            seen_by = usable & ~out.hold
                            free = jumped[:, None] & self._unseen(a, seen_by, g.test)
                            # (every row where the others leave a direction unseen: the
                            # aid is a sole source there, and its jump a sole source's)
                            alone_by = jumped & self._constrained(a, usable)
                            free |= self._blind(a, seen_by, g.test, alone_by)[:, None]
                            # a jump due since the patience ended between the fixes: in
                            # every row (the others judged the level it kept meanwhile)
                            free |= (jumped & before.due[:, a])[:, None]
                            J = np.where(free, after.jump[a] - before.taken[a], 0.0)
                            C = np.where(
                                free[:, :, None] & free[:, None, :], after.jump_cov[a], 0.0
                            )
                        d, Cd = g.increments[a]
                        J = np.where(homed[:, None], d, J)
                        C = np.where(homed[:, None, None], Cd, C)
                        # a lasting offset: the innovation in its rows, with the aid's R
                        nu_l = np.nan_to_num(z[a]) - kf.mv(Ha, x)
                        J = np.where(lasted, nu_l, J)
                        C = np.where(lasted[:, :, None] & lasted[:, None, :], Ra, C)
                        shift = kf.mv(M, J)
                        spread = kf.symmetrize(M @ C @ kf.mT(M))
                        x, P = x + shift, kf.symmetrize(P + spread)
                        dx -= shift
                        dP += spread
                        where |= jumped | homed | lasted.any(-1)
                    A = kf.symmetrize(Ha @ P @ kf.mT(Ha))
                    nu = np.where(rel[:, None], np.nan_to_num(z[a]) - kf.mv(Ha, x), 0.0)
                    gam = np.where(rel, inflation(nu, A, Ra), 0.0)
                    PHt = P @ kf.mT(Ha)
                    grow = gam[:, None, None] * (PHt @ np.linalg.solve(A, kf.mT(PHt)))
                    P_in = kf.symmetrize(P + grow)
                    K, A_in = _gain(P_in, Ha, Ra)
                    d = np.where(rel[:, None], kf.mv(K, nu), 0.0)
                    D = np.where(rel[:, None, None], reduction(K, A_in, Ra), 0.0)
                    dx -= d
                    dP += np.where(rel[:, None, None], grow, 0.0) - D
                    if self.rollback:
                        p = sep.with_own(p, s, d, D, copy=False)
                    x, P = x + d, kf.symmetrize(P_in - D)
                    where |= rel
            for s, a in enumerate(grp):
                # a held sole source's consistent increment: ``ν − r_prev`` measures the
                # estimate's drift since the aid's last measurement, ``Δk H(Φ − I)`` of
                # the present error to first order, with noise 2R
                on = g.rate[:, a]
                if on.any():
                    Ha, Ra = self._matrices(H[a], R[a], B)
                    dk = (before.since[:, a] + 1).astype(float)
                    Fi = np.broadcast_to(g.test.F[gi], P.shape) - np.eye(n)
                    Hd = dk[:, None, None] * (Ha @ Fi)
                    nu = np.nan_to_num(z[a]) - kf.mv(Ha, x) - before.last[a]
                    nu = np.where(on[:, None], nu, 0.0)
                    K, A_d = _gain(P, Hd, 2.0 * Ra)
                    d = np.where(on[:, None], kf.mv(K, nu), 0.0)
                    D = np.where(on[:, None, None], reduction(K, A_d, 2.0 * Ra), 0.0)
                    dx -= d
                    dP -= D
                    p = sep.with_own(p, s, d, D, copy=False)
                    x, P = x + d, kf.symmetrize(P - D)
                    where |= on
            for s, a in enumerate(grp):
                # a held only aid that shows a noise increase: used with that noise where
                # its innovation is consistent with it
                on = out.noisy[:, a]
                if on.any():
                    Ha, Rn = self._matrices(H[a], g.noise[a], B)
                    K, A_n = _gain(P, Ha, Rn)
                    nu = np.where(on[:, None], np.nan_to_num(z[a]) - kf.mv(Ha, x), 0.0)
                    on = on & (_chi2(nu, A_n + Rn) <= self.T1[a])
                    d = np.where(on[:, None], kf.mv(K, nu), 0.0)
                    D = np.where(on[:, None, None], reduction(K, A_n, Rn), 0.0)
                    dx -= d
                    dP -= D
                    p = sep.with_own(p, s, d, D, copy=not self.rollback)
                    x, P = x + d, kf.symmetrize(P - D)
                    where |= on
                    informed[:, a] = on
            if self.rollback:  # the used aids' residuals against the posterior
                for a in grp:
                    used = (usable[:, a] & ~out.hold[:, a]) | g.rate[:, a] | informed[:, a]
                    if used.any():
                        Ha = self._matrices(H[a], R[a], B)[0]
                        r = np.nan_to_num(z[a]) - kf.mv(Ha, x)
                        last[a] = np.where(used[:, None], r, last[a])
                    # a hold begun at a jump of the aid: its innovation against the
                    # estimate as the rollback left it, the rollback's move being the
                    # estimate's, not a second jump of the aid's (the drive's fixes 3 m
                    # east: a healthy window's 1.9 m pull, removed at the onset, entered
                    # the step's sum as a jump back; the sum no longer undid the step,
                    # whose end was held for the patience).  An alarm without a jump
                    # keeps it in the sum: the jump taken after the patience then undoes
                    # a rollback the aid never agreed with (the drive's GLR in a turn,
                    # a false alarm that rolled 1.7 m back: 11 s held, not 17)
                    held = usable[:, a] & ~used & jumped_now[:, a]  # (no rollback: + 0)
                    if held.any():
                        Ha = self._matrices(H[a], R[a], B)[0]
                        last[a] = np.where(held[:, None], last[a] + kf.mv(Ha, rolled), last[a])
                # the epoch's corrections of the estimate, for each aid's ``moved``: none
                # after a used aid's residual, all of them after a held aid's innovation
                d_all = x - priors[gi][0]
                for a in grp:
                    used = (usable[:, a] & ~out.hold[:, a]) | g.rate[:, a] | informed[:, a]
                    held = usable[:, a] & ~used
                    m_a = np.where(held[:, None], d_all, moved[a] + d_all)
                    moved[a] = np.where(used[:, None], 0.0, m_a)
            # the aids that informed the estimate now: its coasting without them is
            # measured from this epoch's prior (with a rollback's covariance)
            P_from = priors[gi][1] + dP_back
            for a in grp:
                now = (usable[:, a] & ~out.hold[:, a]) | out.rollback[:, a] | informed[:, a]
                if now.any():
                    anchor[a] = np.where(now[:, None, None], P_from, anchor[a])
            pulls[gi], alts[gi] = p, alt
            amends.append(Amend(dx, kf.symmetrize(dP), where))
        age = after.age + 1
        if age >= self.L * self.nb:  # a coarse block's span: the fine blocks'
            age = 0
        if age % self.L == 0 and self.rollback:
            close = age == 0 and self.nc > 0  # a coarse block's span is over
            pulls = [sep.rotate(p, self.nc, close) for p in pulls]
        # a held aid's coast: epochs it was not used for its noise (its increments
        # informing the rate do not end a coast: the estimate's level still drifts)
        coast = np.where(after.hold & ~informed, before.coast + 1, 0)
        new = after._replace(
            coast=coast,
            moved=tuple(moved),
            pulls=tuple(pulls),
            alternative=tuple(alts),
            anchor=tuple(anchor),
            age=age,
            last=tuple(last),
        )
        return new, tuple(amends)
