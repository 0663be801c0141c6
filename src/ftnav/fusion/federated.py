"""Carlson federated Kalman filter with adaptive information sharing (spec §1-§2).

Modes (spec §1.5):

* ``fusion-reset`` (FR): fuse every epoch; every ``reset_interval`` epochs reset
  each healthy local filter to ``x̂_g``, ``P_g/β_i`` and the master to
  ``P_g/β_m``; local filters propagate with ``Q/β_i``.  Equals the centralized
  filter when the reset interval is 1 (spec §1.6).
* ``no-reset`` (NR): the initial sharing only; locals stay independent.
* ``zero-reset`` (ZR): the master holds all information; locals are information
  filters over the common state that are zeroed after each reset (fusion).

Fault factors ``r_i`` (spec §1.8): a filter flagged at epoch k is fused with its
prior (time update only) at k, gets ``β_i = 0`` from the sharing at the end of
k and runs standalone (``Q_i = Q``) on its own measurements; a recovery flagged
at epoch k re-admits it at the next sharing, so it is fused again from k+1
(with reset interval 1).  ``no-reset`` re-admits a recovered filter at once.

``no-reset`` with ``isolation = "time-update"``: a flagged local filter discards its
measurements, so its estimate is its last healthy one propagated (spec §6.3); nothing
of the fault enters it and, the locals staying independent, it stays in the fusion with
its share (``Q/β_i``) instead of being dropped.  The fused solution keeps the
information it had before the fault (e.g. the TAN height while TAN is isolated) rather
than falling back on the remaining aids alone.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.core.sharing import information_content, sharing_coefficients
from ftnav.fdi.chi2 import DetectorState
from ftnav.fdi.features import detector_features, whitened_innovation
from ftnav.fusion.local import (
    NoiseState,
    StateTest,
    StepOutput,
    check_prior,
    detect,
    detector_feature_kinds,
    initial_noise,
    local_update,
    make_detector,
    predicted_noise,
    residual_statistic,
    select,
    valid_measurement,
    vb_enabled,
    vb_variant,
    with_common,
)
from ftnav.model.scenario import Method
from ftnav.model.system import LinearSystem

__all__ = ["FederatedFilter", "FederatedState", "MIN_SHARE"]

#: Smallest positive sharing coefficient: a local reset with P_g/β for β below it
#: loses accuracy roughly as (machine epsilon)/β.
MIN_SHARE = 1e-6


class FederatedState(NamedTuple):
    """Full state of the federated filter (nothing hidden in the object).

    ``x``/``P`` hold each local filter's posterior after the sharing (in ZR the
    information vector and matrix).  ``share`` is the β each local was last
    reset with (its Q scaling), ``active`` whether it is fused next epoch.
    """

    x: tuple[np.ndarray, ...]
    P: tuple[np.ndarray, ...]
    master: kf.Gaussian | None
    xg: np.ndarray
    Pg: np.ndarray
    share: np.ndarray
    active: np.ndarray
    noise: tuple[NoiseState | None, ...]
    detector: DetectorState | None
    propagator: tuple[kf.Gaussian, ...] | None


class FederatedFilter:
    """Federated filter with the spec §2 sharing rules and fault factors.

    Parameters
    ----------
    system : linear system (local filters carry ``[x_c; x_si]``).
    method : settings: ``mode``, ``reset_interval``, ``sharing``, ``betas``,
        ``master_share``, ``trace_mode``, ``detector`` and its settings,
        ``prior``, ``adaptive_noise``.
    features : feature kinds (spec §4.1) to compute every epoch even without an
        RBF detector (training data collection); reported in ``StepOutput.features``.
    """

    def __init__(
        self, system: LinearSystem, method: Method, features: tuple[str, ...] | None = None
    ):
        name = f"methods[{method.name}]"
        if method.mode == "rescale":
            raise ValueError(f"{name}.mode: 'rescale' is provided by the distributed architecture")
        if method.mode == "zero-reset":
            if system.has_private:
                raise ValueError(
                    f"{name}.mode: zero-reset needs full-state local filters "
                    "(a sensor has private states)"
                )
            if method.adaptive_noise != "none":
                raise ValueError(
                    f"{name}.adaptive_noise: not available with zero-reset "
                    "(local filters have no prior)"
                )
            if method.detector in ("state-chi2", "rbf") or features:
                raise ValueError(
                    f"{name}.detector: {method.detector!r} needs local priors; "
                    "zero-reset locals have none"
                )
        check_prior(method)
        N = system.n_sensors
        q = method.common_mode_quorum
        if q is not None and not (method.common_mode == "keep" and 2 <= q <= N):
            raise ValueError(
                f"{name}.common_mode_quorum: needs common_mode 'keep' and "
                f"2 <= quorum <= {N}, got {q} with {method.common_mode!r}"
            )
        if method.sharing == "fixed" and len(method.betas) != N:
            raise ValueError(f"{name}.betas: expected {N} values, got {len(method.betas)}")
        self.system = system
        self.method = method
        self.N = N
        self.nc = system.n_common
        self.locals = [system.local(i) for i in range(N)]
        self.detector = make_detector(method, system)
        self.features, self.feature_prior = detector_feature_kinds(self.detector, method, features)
        self.state_test = (
            StateTest(method.state_test_reset) if method.detector == "state-chi2" else None
        )
        self.variant = vb_variant(method)
        self.vb_on = vb_enabled(method, system.sensors)
        self.scale = None if method.trace_mode == "raw" else 1.0 / np.sqrt(np.diag(system.model.P0))
        self.info = information_content(
            [s.H for s in system.sensors], [s.R for s in system.sensors], self.scale
        )
        self.zr = method.mode == "zero-reset"
        self.beta_m = 0.0 if self.zr else float(method.master_share)
        self.global_prior = method.prior == "global" or self.zr

    @property
    def n_filters(self) -> int:
        return self.N

    def _sharing(self, P_common: np.ndarray, r: np.ndarray) -> np.ndarray:
        """β of the rule, a positive share raised to at least :data:`MIN_SHARE`.

        The adaptive rules can drive a healthy filter's β geometrically to 0 (e.g.
        inverse-trace when sensors observe different subspaces); ``P_g/β`` then
        overflows.  Raising it to the floor (the others renormalized, Σβ + β_m = 1)
        keeps its measurements in the fusion; a zero β (fault, fixed 0) stays 0.
        """
        m = self.method
        beta = sharing_coefficients(
            m.sharing,
            P_common,
            r,
            master_share=self.beta_m,
            betas=np.asarray(m.betas),
            info=self.info,
            scale=self.scale,
        )
        tiny = (beta > 0) & (beta < MIN_SHARE)
        if not tiny.any():
            return beta
        rest = np.where(tiny, 0.0, beta)
        budget = 1.0 - self.beta_m - MIN_SHARE * tiny.sum(-1, keepdims=True)
        # a run whose shares are all zero (every filter faulty) keeps them at zero; without
        # the guard its 0/0 gave NaN shares (read as zero) and a divide-by-zero warning
        total = rest.sum(-1, keepdims=True)
        return np.where(tiny, MIN_SHARE, rest * (budget / np.where(total > 0, total, 1.0)))

    def init(self, batch: int) -> FederatedState:
        B, nc = batch, self.nc
        x0c, P0c = self.system.model.x0, self.system.model.P0
        r = np.ones((B, self.N))
        share = self._sharing(np.broadcast_to(P0c, (B, self.N, nc, nc)), r)
        xs, Ps = [], []
        for i, lm in enumerate(self.locals):
            if self.zr:
                xs.append(np.zeros((B, nc)))
                Ps.append(np.zeros((B, nc, nc)))
                continue
            P = np.broadcast_to(lm.P0, (B,) + lm.P0.shape).copy()
            P[:, :nc, :nc] = P0c / np.where(share[:, i] > 0, share[:, i], 1.0)[:, None, None]
            xs.append(np.broadcast_to(lm.x0, (B, lm.n)).copy())
            Ps.append(P)
        master = None
        if self.zr or self.beta_m > 0:
            bm = 1.0 if self.zr else self.beta_m
            master = kf.Gaussian(
                np.broadcast_to(x0c, (B, nc)).copy(), np.broadcast_to(P0c / bm, (B, nc, nc)).copy()
            )
        noise = tuple(
            initial_noise(s.R, B) if on else None
            for s, on in zip(self.system.sensors, self.vb_on, strict=True)
        )
        det = self.detector.init(B, self.N) if self.detector else None
        prop = (
            tuple(kf.Gaussian(x, P) for x, P in zip(xs, Ps, strict=True))
            if self.state_test
            else None
        )
        return FederatedState(
            tuple(xs),
            tuple(Ps),
            master,
            np.broadcast_to(x0c, (B, nc)).copy(),
            np.broadcast_to(P0c, (B, nc, nc)).copy(),
            share,
            np.ones((B, self.N), dtype=bool) if self.zr else share > 0,
            noise,
            det,
            prop,
        )

    # ------------------------------------------------------------------------------
    def step(self, state: FederatedState, k: int, z, available, oracle, lin=None):
        """Advance one epoch (spec §1.3): predict, update, test, fuse, share.

        ``lin`` (:class:`~ftnav.model.system.Linearization`) supplies the epoch's
        per-run matrices of an error-state model linearized at the INS solution.
        """
        m, nc, N = self.method, self.nc, self.N
        F, Q = self.system.transition(k, lin)
        Hs = [lm.H for lm in self.locals] if lin is None else list(lin.H)
        B = state.xg.shape[0]
        # the fused prior: needed by global-prior tests and when every local is isolated
        need_prior = (
            self.global_prior
            or self.features is not None
            or not state.active.any(1).all()
            and state.master is None
        )
        xg_pr, Pg_pr = kf.predict(state.xg, state.Pg, F, Q) if need_prior else (None, None)
        usable, nan = zip(
            *(valid_measurement(z[i], available[:, i]) for i in range(N)), strict=True
        )
        usable, nan = np.stack(usable, 1), np.stack(nan, 1)

        priors, posts, noise, R_hat, stat, props = [], [], [], [], [], []
        for i, s in enumerate(self.system.sensors):
            use = usable[:, i]
            if self.zr:
                y, Y = kf.information_predict(state.x[i], state.P[i], F, Q)
                HtRinv = kf.mT(np.linalg.solve(s.R, Hs[i]))
                Y_post = np.where(use[:, None, None], Y + HtRinv @ Hs[i], Y)
                y_post = np.where(
                    use[:, None], y + kf.mv(HtRinv, np.where(use[:, None], z[i], 0.0)), y
                )
                priors.append((y, Y))
                posts.append((y_post, Y_post))
                noise.append(None)
                R_hat.append(np.broadcast_to(np.diag(s.R), (B, s.dim)))
            else:
                sharing_local = state.active[:, i] & (state.share[:, i] > 0)
                scale = np.where(
                    sharing_local, 1.0 / np.where(sharing_local, state.share[:, i], 1.0), 1.0
                )
                Fi, Qi = self.system.local_transition(i, k, scale, lin)
                x_pr, P_pr = kf.predict(state.x[i], state.P[i], Fi, Qi)
                up = local_update(
                    x_pr,
                    P_pr,
                    z[i],
                    use,
                    Hs[i],
                    s.R,
                    state.noise[i],
                    variant=self.variant if self.vb_on[i] else None,
                    rho=m.vb_rho,
                    iterations=m.vb_iterations,
                )
                priors.append((x_pr, P_pr))
                posts.append((up.x, up.P))
                noise.append(up.noise)
                R_hat.append(np.diagonal(up.R, axis1=-2, axis2=-1))
                if self.state_test is not None:
                    props.append(kf.predict(*state.propagator[i], Fi, Qi))
            if m.detector != "residual-chi2":  # no other detector reads the statistic
                stat.append(np.zeros(B))
            elif self.global_prior:  # covers zero-reset
                stat.append(
                    self._residual(
                        i, *with_common(priors[i], xg_pr, Pg_pr), z[i], use, state.noise[i], Hs[i]
                    )
                )
            else:
                stat.append(up.nis)
        stat = np.stack(stat, 1)
        dof = np.array([s.dim for s in self.system.sensors])[None, :] * usable
        tested = usable
        if self.state_test is not None:
            res = [self.state_test.statistic(k, *posts[i], *props[i]) for i in range(N)]
            stat = np.stack([r[0] for r in res], 1)
            dof = np.stack([r[1] for r in res], 1)
            tested = np.stack([r[2] for r in res], 1)
        feats = None
        if self.features is not None:
            feats = self._features(priors, posts, xg_pr, Pg_pr, z, usable, state.noise, Hs)
        det_state, det_out = detect(
            m, self.detector, state.detector, stat, dof, tested, oracle, feats
        )
        flag = np.zeros((B, N), dtype=bool) if det_out is None else det_out.flag
        if m.common_mode == "keep" and N > 1:
            # at least a quorum of the aids (by default every one) flagged at once: the
            # shared reference (the SINS) failed, not the aids, so none is isolated
            quorum = N if m.common_mode_quorum is None else m.common_mode_quorum
            flag = flag & ~(flag.sum(1, keepdims=True) >= quorum)

        # ---- fusion over the active set (spec §1.3 step 3) --------------------------
        newly = state.active & flag
        if self.zr:
            Pm_pr = kf.predict(state.master.x, state.master.P, F, Q)
            ym, Ym = kf.to_information(*Pm_pr)
            Yg, yg = Ym.copy(), ym.copy()
            for i in range(N):
                y_i = select(newly[:, i], priors[i][0], posts[i][0])
                Y_i = select(newly[:, i], priors[i][1], posts[i][1])
                Yg += np.where(state.active[:, i, None, None], Y_i, 0.0)
                yg += np.where(state.active[:, i, None], y_i, 0.0)
            xg, Pg = kf.from_information(yg, Yg)
            any_source = np.ones(B, dtype=bool)
        else:
            xc = np.stack(
                [select(newly[:, i], priors[i][0], posts[i][0])[:, :nc] for i in range(N)], 1
            )
            Pc = np.stack(
                [select(newly[:, i], priors[i][1], posts[i][1])[:, :nc, :nc] for i in range(N)], 1
            )
            P_common = [posts[i][1][:, :nc, :nc] for i in range(N)]
            master = y0 = Y0 = None
            if state.master is not None:
                master = kf.predict(state.master.x, state.master.P, F, Q / self.beta_m)
                y0, Y0 = kf.to_information(*master)
            any_source = state.active.any(1) | (state.master is not None)
            if not any_source.all():  # every local isolated: output the global prior
                Y0 = np.where(any_source[:, None, None], 0.0 if Y0 is None else Y0, np.eye(nc))
            xf, Pf = kf.fuse(xc, Pc, state.active.astype(float), y0, Y0)
            xg, Pg = select(any_source, xf, xg_pr), select(any_source, Pf, Pg_pr)

        # ---- sharing / reset (spec §1.2, §1.5, §1.8) ---------------------------------
        r = ~flag
        reset_epoch = m.mode != "no-reset" and k % m.reset_interval == 0
        active_next = r.copy() if (reset_epoch or m.mode == "no-reset") else state.active & r
        if m.mode == "no-reset":
            # time-update isolation leaves a flagged local uncontaminated: keep fusing it
            active_next = (
                (state.share > 0)
                if m.isolation == "time-update" and not self.zr
                else active_next & (state.share > 0)
            )
        xs = [p[0] for p in posts]
        Ps = [p[1] for p in posts]
        if m.isolation == "time-update" and not self.zr:
            # a flagged local filter discards this epoch's measurement (spec §6.3)
            xs = [select(flag[:, i], priors[i][0], xs[i]) for i in range(N)]
            Ps = [select(flag[:, i], priors[i][1], Ps[i]) for i in range(N)]
        share = state.share
        new_master = None
        if self.zr:
            if reset_epoch:
                xs = [np.zeros_like(x) for x in xs]
                Ps = [np.zeros_like(P) for P in Ps]
                new_master = kf.Gaussian(xg, Pg)
            else:
                new_master = Pm_pr
            beta_report = np.zeros((B, N))
        elif reset_epoch:
            share = self._sharing(np.stack(P_common, 1), r.astype(float))
            active_next &= share > 0  # a zero share is not reset (P_g/0) nor fused
            for i in range(N):
                xs[i], Ps[i] = self._reset(xs[i], Ps[i], xg, Pg, share[:, i], active_next[:, i])
            if state.master is not None:
                new_master = kf.Gaussian(xg.copy(), Pg / self.beta_m)
            beta_report = np.where(active_next, share, 0.0)
        else:
            new_master = master
            beta_report = np.where(active_next, share, 0.0)

        prop = None
        if self.state_test is not None:
            prop = tuple(
                kf.Gaussian(*self.state_test.restart(k, xs[i], Ps[i], *props[i])) for i in range(N)
            )
        out = StepOutput(xg, Pg, beta_report, det_out, tuple(R_hat), nan, feats)
        return FederatedState(
            tuple(xs),
            tuple(Ps),
            new_master,
            xg,
            Pg,
            share,
            active_next,
            tuple(noise),
            det_state,
            prop,
        ), out

    # ------------------------------------------------------------------------------
    def _residual(self, i, x, P, z, use, noise, H):
        """NIS of sensor i against the prior (x, P) (spec §3.1)."""
        R = predicted_noise(noise, self.system.sensors[i].R, self.method.vb_rho)
        return residual_statistic(x, P, z, use, H, R)

    def _features(self, priors, posts, xg_pr, Pg_pr, z, usable, noise, Hs):
        """Spec §4.1 features: posterior − fused prior, whitened innovations."""
        nc = self.nc
        innov = []
        for i, s in enumerate(self.system.sensors):
            base = (
                with_common(priors[i], xg_pr, Pg_pr)
                if self.feature_prior == "global"
                else priors[i]
            )
            R = predicted_noise(noise[i], s.R, self.method.vb_rho)
            innov.append(whitened_innovation(*base, z[i], usable[:, i], Hs[i], R))
        xl = np.stack([p[0][:, :nc] for p in posts], 1)
        vl = np.stack([np.diagonal(p[1], axis1=-2, axis2=-1)[:, :nc] for p in posts], 1)
        return detector_features(self.features, xl, vl, xg_pr, innov)

    def _reset(self, x, P, xg, Pg, beta, where):
        """Reset common block to ``x̂_g``, ``P_g/β`` (spec §1.2); cross block per §1.7."""
        nc = self.nc
        b = np.where(where, beta, 1.0)[:, None, None]
        P_new_cc = Pg / b
        x_new = x.copy()
        x_new[:, :nc] = xg
        P_new = P.copy()
        if P.shape[-1] > nc:
            L_old = np.linalg.cholesky(P[:, :nc, :nc])
            L_new = np.linalg.cholesky(P_new_cc)
            P_cs = L_new @ np.linalg.solve(L_old, P[:, :nc, nc:])
            P_new[:, :nc, nc:] = P_cs
            P_new[:, nc:, :nc] = kf.mT(P_cs)
        P_new[:, :nc, :nc] = P_new_cc
        return select(where, x_new, x), select(where, P_new, P)
