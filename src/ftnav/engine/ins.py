"""The closed-loop SINS of the engine: mechanization, linearization, aids, feedback.

Every method owns a SINS mechanization per run; the SINS of all methods are
integrated, linearized and measured as one batch of ``methods × runs`` (lock-step).
Per filter epoch k (spec §6.2, §8.4-§8.5):

1. the error model is linearized at each run's INS solution at the start of the epoch
   (specific force averaged over the epoch's increments) and discretized (spec §8.4);
2. the SINS integrates the epoch's IMU increments (:mod:`ftnav.nav.mechanization`);
3. each aid's nonlinear measurement ``z = INS − aid`` and its ``H`` are formed at the INS
   solution (:mod:`ftnav.sensors`); gated epochs count as missing; an aid with a
   differenced Markov error (GNSS ``markov = "difference"``) is differenced with its
   previous epoch and the correction fed back since (Bryson-Henrikson);
4. the filters step on these per-run matrices (every local filter and the centre use
   the same ones, spec §6.2);
5. with ``correction = "feedback"`` the fused navigation errors are fed back to the
   SINS and every filter's estimates are shifted by the same correction (with
   ``bias_compensation`` the estimated IMU biases too: accumulated, and subtracted from
   every IMU increment before the mechanization and the linearization of the next
   epochs, as KF-GINS and pyins do — spec §8.5); with
   ``"output"`` the SINS runs free and its output is corrected.  A method may set its
   own ``correction`` (its SINS rows are fed back or not).  With output correction and
   an architecture whose local filters each keep their own copy of the SINS output
   (paper 001 §3: ``local_copies``), aid i is measured at its local's copy: the free
   SINS corrected by that local's predicted estimate ``x̂_i⁻ = Φ x̂_i``, and
   ``z_i = h(copy_i) − aid + H_i[:, :9] x̂_i⁻[:9]`` so that the local's innovation
   ``z_i − H_i x̂_i⁻`` is the aid's residual at its copy (the error-state EKF
   relinearized at each local's own solution; the terrain slopes are read there).

Aids are applied at the filter epochs ``t_k = k·dt``: every aid's time stamps must be
epoch times (:meth:`InsModel.check`).  Nothing here reads a truth.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal, NamedTuple

import numpy as np

from ftnav.core import kalman as kf
from ftnav.engine.driver import N_NAV, LocalCopies
from ftnav.model.streams import InsStream, repeated
from ftnav.model.system import Epoch, Linearization, LinearSystem
from ftnav.nav import attitude
from ftnav.nav.error_model import ErrorModelParams, discrete_model
from ftnav.nav.mechanization import InsState, apply_correction, feedback, integrate
from ftnav.sensors.base import AidingSensor

__all__ = ["InsModel", "InsModelState", "N_NAV"]


Previous = tuple[tuple[np.ndarray, np.ndarray, np.ndarray] | None, ...]


class InsModelState(NamedTuple):
    """The SINS of every method and run, and the differencing memory of each aid.

    Attributes
    ----------
    ins : the mechanization state of ``methods × runs`` rows, method-major.
    previous : per aid, the last raw ``(z, H, usable)`` of a differenced aid, else None.
    shift : (rows, n) the correction fed back after the last epoch (differencing needs it).
    """

    ins: InsState
    previous: Previous
    shift: np.ndarray | None
    repeated: tuple[np.ndarray, ...] = ()
    """per aid, (B, K) its output repeats its previous one bit for bit (a frozen aid)."""
    bias: np.ndarray | None = None
    """(rows, 6) the IMU biases fed back so far, gyro ε̂ (rad/s) then accelerometer ∇̂
    (m/s²), body frame, subtracted from the increments (``bias_compensation``); (rows,
    12) with the 21-state model: then the gyro and accelerometer scale factors ŝ_g, ŝ_a
    (the increments are divided by ``1 + ŝ``); or None."""


def _rows(rows: np.ndarray, a: np.ndarray) -> np.ndarray:
    """The (rows,) mask shaped to broadcast over ``a``'s trailing axes."""
    return rows.reshape(rows.shape + (1,) * (a.ndim - 1))


def _pick(rows: np.ndarray, a: InsState, b: InsState) -> InsState:
    """``a``'s rows where ``rows`` is True, ``b``'s elsewhere."""
    return InsState(*(np.where(_rows(rows, x), x, y) for x, y in zip(a, b, strict=True)))


def _tile(a: np.ndarray, M: int) -> np.ndarray:
    return a if M == 1 else np.concatenate([a] * M, 0)


def _common(H: np.ndarray, n: int) -> np.ndarray:
    """An aid's ``H`` on the common states of the sensor contract (18 columns, spec §8.3
    order; aids act on the 9 navigation states) as the model's first ``n`` columns:
    the 15-state model keeps 15, the 21-state model's scale-factor columns are zero."""
    if n <= H.shape[-1]:
        return H[..., :n]
    out = np.zeros(H.shape[:-1] + (n,))
    out[..., : H.shape[-1]] = H
    return out


class InsModel:
    """Integrated navigation as the engine runs it (module docstring).

    Parameters
    ----------
    system : the filters' system (linearized: Φ, Q and H come with every epoch).
    error_model : the SINS error model the filters assume.
    aids : the aid sensor models (:mod:`ftnav.sensors`), in stream order.
    dt : filter period (s); ``samples_per_epoch`` IMU increments make one epoch.
    correction : ``"feedback"`` or ``"output"``.
    discretization : ``"series"`` or ``"van-loan"``; ``algorithm`` the strapdown algorithm.
    bias_compensation : feed the estimated IMU bias states back too and subtract the
        accumulated biases from the increments (module step 5): the filters' bias states
        then hold what is left of the biases, ``n_fed`` is the error model's n.  With a
        Markov bias model (18 states, or 15 with a random walk) the fed-back part is
        held constant while the model lets the residual decay (the usual closed-loop
        approximation, KF-GINS); needs ``bias_frame = "body"``.
    """

    per_method_rows: bool = True
    n_fed: int = N_NAV
    n_local: int | None = N_NAV

    def __init__(
        self,
        system: LinearSystem,
        error_model: ErrorModelParams,
        aids: Sequence[AidingSensor],
        dt: float,
        samples_per_epoch: int,
        correction: Literal["feedback", "output"] = "feedback",
        discretization: Literal["van-loan", "series"] = "series",
        algorithm: Literal["two-sample", "single-sample"] = "two-sample",
        bias_compensation: bool = False,
    ):
        if bias_compensation and error_model.bias_frame != "body":
            raise ValueError(
                "bias_compensation: the bias states must be in the body frame "
                f"(bias_frame 'body', got {error_model.bias_frame!r})"
            )
        self.compensate = bool(bias_compensation)
        if self.compensate:
            self.n_fed = error_model.n
        self.system = system
        self.error_model = error_model
        self.aids = tuple(aids)
        self.dt = float(dt)
        self.spe = int(samples_per_epoch)
        self.feedback = correction == "feedback"
        self.discretization = discretization
        self.algorithm = algorithm
        self.every = self.spe // (2 if algorithm == "two-sample" else 1)
        self.psi: list[np.ndarray | None] = [
            getattr(a, "difference_factor", None) for a in self.aids
        ]

    def check(self, stream: InsStream, steps: int) -> None:
        """Refuse a stream the model cannot run: too short, aids off the epoch times."""
        n_imu = stream.imu.dtheta.shape[1]
        if n_imu < steps * self.spe:
            raise ValueError(f"imu: {n_imu} increments, {steps} epochs need {steps * self.spe}")
        t = stream.imu.t0 + self.dt * np.arange(1, steps + 1)
        for i, aid in enumerate(stream.aids):
            if aid.t.shape[0] < steps or not np.allclose(aid.t[:steps], t, atol=1e-9):
                raise ValueError(f"aids[{i}].t: the aid must be sampled at the filter epochs")

    def start(self, stream: InsStream, copies: int) -> InsModelState:
        """Every method's SINS starts at the stream's initial solution."""
        ins = InsState(*(_tile(a, copies) for a in stream.start))
        width = 12 if self.error_model.n == 21 else 6
        bias = np.zeros((ins.q.shape[0], width)) if self.compensate else None
        # a pseudo-measurement's output (a vehicle constraint's 0) repeats by design
        rep = tuple(
            np.zeros(aid.available.shape, bool)
            if getattr(sensor, "pseudo", False)
            else repeated(aid.raw, aid.available)
            for sensor, aid in zip(self.aids, stream.aids, strict=True)
        )
        return InsModelState(ins, (None,) * len(self.aids), None, rep, bias)

    def epoch(
        self,
        state: InsModelState,
        stream: InsStream,
        k: int,
        copies: int,
        local_copies: LocalCopies | None = None,
    ) -> tuple[InsModelState, Epoch]:
        """Propagate every SINS over epoch k, linearize, form the aids' measurements
        (at each local's copy for the rows of ``local_copies``: module step 5)."""
        ins = state.ins
        sl = slice((k - 1) * self.spe, k * self.spe)
        dth = _tile(stream.imu.dtheta[:, sl], copies)
        dvel = _tile(stream.imu.dv[:, sl], copies)
        b = state.bias
        if b is not None:  # the biases (and scale factors) fed back so far (module step 5)
            dth = dth - b[:, None, 0:3] * stream.imu.dt
            dvel = dvel - b[:, None, 3:6] * stream.imu.dt
            if b.shape[1] == 12:
                dth = dth / (1.0 + b[:, None, 6:9])
                dvel = dvel / (1.0 + b[:, None, 9:12])
        f_b = dvel.sum(1) / self.dt
        # the gyro's mean rate over the epoch: the scale factors' columns, and a lever
        # arm's rotation (the receiver's velocity is an average too, and the IMU's
        # vibration averages out)
        w_ib = dth.sum(1) / self.dt
        w_b = w_ib if self.error_model.n == 21 else None
        C_bn = attitude.quat_to_dcm(ins.q)
        Phi, Q = discrete_model(
            ins.p[:, 0],
            ins.p[:, 1],
            ins.p[:, 2],
            ins.v,
            f_b,
            C_bn,
            self.error_model,
            self.dt,
            self.discretization,
            5,
            w_b=w_b,
        )
        ins, _ = integrate(
            ins, dth, dvel, stream.imu.dt, algorithm=self.algorithm, output_every=self.every
        )
        z, H, avail, previous = self._measure(state, stream, k, copies, ins, Phi, w_ib)
        if local_copies is not None and local_copies.rows.any():
            self._at_local_copies(stream, k, copies, ins, Phi, local_copies, z, H, avail, w_ib)
        rep = np.stack([_tile(r[:, k - 1], copies) for r in state.repeated], 1) & avail
        lin = Linearization(Phi, Q, tuple(H))
        epoch = Epoch(k, tuple(z), avail, stream.labels[k - 1], lin, rep)
        return state._replace(ins=ins, previous=previous), epoch

    def _measure(
        self,
        state: InsModelState,
        stream: InsStream,
        k: int,
        copies: int,
        ins: InsState,
        Phi: np.ndarray,
        w_ib: np.ndarray,
    ) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray, Previous]:
        """Each aid's ``z``, ``H`` and availability at the INS solution (module step 3);
        ``w_ib`` (rows, 3) the gyro's rate at the epoch."""
        n = self.system.n_common
        rows = ins.q.shape[0]
        z, H, avail = [], [], np.zeros((rows, len(self.aids)), bool)
        previous = list(state.previous)
        for i, (sensor, aid) in enumerate(zip(self.aids, stream.aids, strict=True)):
            raw = _tile(aid.raw[:, k - 1], copies)
            lin = sensor.measure(ins.q, ins.v, ins.p, np.nan_to_num(raw, nan=1.0), w_ib)
            ok = _tile(aid.available[:, k - 1], copies) & lin.valid & np.isfinite(lin.z).all(-1)
            zi = lin.z
            Hi = np.nan_to_num(np.concatenate([_common(lin.H, n), lin.H_private], -1))
            psi, last = self.psi[i], previous[i]
            if psi is not None:  # measurement differencing of a Markov error (GNSS)
                this = (zi, Hi, ok)
                if last is None:
                    ok = np.zeros_like(ok)  # nothing to difference with yet
                else:
                    z_prev, H_prev, ok_prev = last
                    zi, Hi = kf.differenced_measurement(
                        zi, Hi, z_prev, H_prev, Phi, psi, state.shift
                    )
                    ok = ok & ok_prev
                previous[i] = this
            z.append(np.where(ok[:, None], zi, np.nan))
            H.append(Hi)
            avail[:, i] = ok
        return z, H, avail, tuple(previous)

    def _at_local_copies(
        self,
        stream: InsStream,
        k: int,
        copies: int,
        ins: InsState,
        Phi: np.ndarray,
        local: LocalCopies,
        z: list[np.ndarray],
        H: list[np.ndarray],
        avail: np.ndarray,
        w_ib: np.ndarray,
    ) -> None:
        """Re-measure every aid of the rows ``local.rows`` at its local's own copy of the
        SINS output (module step 5), in place of ``z``, ``H`` and ``avail``."""
        n = self.system.n_common
        r = local.rows
        q, v, p = ins.q[r], ins.v[r], ins.p[r]
        Phi_nav = Phi[r][:, :N_NAV, :n]  # the locals' estimates predicted to this epoch
        for i, (sensor, aid) in enumerate(zip(self.aids, stream.aids, strict=True)):
            if self.psi[i] is not None:
                raise ValueError(f"aids[{i}]: a differenced aid cannot be measured at local copies")
            d = np.einsum("bij,bj->bi", Phi_nav, local.estimate[r, i])
            qc, vc, pc = apply_correction(q, v, p, d[:, 0:3], d[:, 3:6], d[:, 6:9])
            raw = _tile(aid.raw[:, k - 1], copies)[r]
            lin = sensor.measure(qc, vc, pc, np.nan_to_num(raw, nan=1.0), w_ib[r])
            ok = _tile(aid.available[:, k - 1], copies)[r] & lin.valid
            zi = lin.z + np.einsum("bij,bj->bi", lin.H[..., :N_NAV], d)
            ok &= np.isfinite(zi).all(-1)
            z[i][r] = np.where(ok[:, None], zi, np.nan)
            H[i][r] = np.nan_to_num(np.concatenate([_common(lin.H, n), lin.H_private], -1))
            avail[r, i] = ok

    def navigation(self, state: InsModelState) -> InsState:
        """Every method's SINS solution before this epoch's correction."""
        return state.ins

    def compensated_bias(self, state: InsModelState) -> np.ndarray | None:
        """The IMU biases fed back so far (:attr:`InsModelState.bias`), or None."""
        return state.bias

    def correct(
        self, state: InsModelState, fused: np.ndarray, rows: np.ndarray | None = None
    ) -> InsModelState:
        """Feed the fused navigation errors (rows, ≥ 9) back to every SINS (spec §8.5),
        or only to the ``rows`` that are True (methods with their own ``correction``)."""
        if rows is None and not self.feedback:
            return state
        d = fused[:, : self.n_fed]
        ins = feedback(state.ins, d[:, 0:3], d[:, 3:6], d[:, 6:9])
        if rows is not None:  # the other rows' SINS run free
            ins = _pick(rows, ins, state.ins)
            d = np.where(rows[:, None], d, 0.0)
        bias = state.bias
        if bias is not None:
            bias = bias + self._bias_states(d)
        shift = None
        if any(p is not None for p in self.psi):
            n = self.system.n_common
            shift = np.concatenate([d, np.zeros((d.shape[0], n - d.shape[1]))], 1)
        return state._replace(ins=ins, shift=shift, bias=bias)

    def _bias_states(self, d: np.ndarray) -> np.ndarray:
        """(rows, 6) gyro and accelerometer biases of the fed-back states ``d``: 15
        states ``[ε, ∇]``; 18 states ``ε_b + ε_r`` and ``∇``; 21 states (rows, 12) ``[ε, ∇,
        s_g, s_a]`` (:mod:`ftnav.nav.error_model`)."""
        if d.shape[1] in (15, 21):
            return d[:, 9:]
        return np.concatenate([d[:, 9:12] + d[:, 12:15], d[:, 15:18]], 1)

    def output(
        self, state: InsModelState, fused: np.ndarray, rows: np.ndarray | None = None
    ) -> InsState:
        """The corrected navigation solution: the SINS after feedback, or its output
        corrected by the fused errors (output correction); ``rows`` as for
        :meth:`correct`."""
        if rows is None and self.feedback:
            return state.ins
        d = fused[:, :N_NAV]
        q, v, p = apply_correction(
            state.ins.q, state.ins.v, state.ins.p, d[:, 0:3], d[:, 3:6], d[:, 6:9]
        )
        out = state.ins._replace(q=q, v=v, p=p)
        if rows is None:
            return out
        return _pick(rows, state.ins, out)
