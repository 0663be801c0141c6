"""Families of typical faults for training and testing learned components (spec §4.2).

Paper 000 trains its detector on "typical faults in extensive simulations";
spec §4.2 names them: fault-free runs, step biases of ±{3, 5, 10, 20}σ_i on
each sensor, ramps and noise-variance steps.  A :class:`FaultFamily` states
that list; :func:`fault_variants` turns it into one scenario variant per fault
(each with its own window drawn from a seeded generator), and
:func:`simulate_variants` simulates all of them as one batch whose runs carry
their variant index, so a Monte Carlo runner processes the whole family in
lock-step and every epoch is labelled by the true fault windows.

σ_i is the standard deviation the filters assume for sensor i (√diag R_i); a
fault acts on every component of the measurement with the same sign.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ftnav.model.scenario import Fault, Scenario
from ftnav.model.streams import concat_streams
from ftnav.sim.linear import LinearTruth, Simulated, simulate

__all__ = [
    "FaultFamily",
    "FaultVariant",
    "fault_variants",
    "simulate_variants",
    "window_masks",
    "HOLDOUT_OFFSET",
]

#: Held-out runs use run indices from here on, so they never share a random
#: stream with training runs (whole runs are held out, spec §4.2).
HOLDOUT_OFFSET = 1_000_000


@dataclass(frozen=True, slots=True)
class FaultFamily:
    """The typical faults of spec §4.2 (sizes in units of the sensor's σ).

    Attributes
    ----------
    step_sizes : bias steps, |size| in σ.   signs : signs of the steps.
    ramp_sizes : ramps growing from 0 to size·σ over the window.
    noise_scales : noise standard-deviation factors inside the window.
    fault_free : number of fault-free variants.
    duration : (min, max) window length as a fraction of the run.
    start : (min, max) window start as a fraction of the run.
    """

    step_sizes: tuple[float, ...] = (3.0, 5.0, 10.0, 20.0)
    signs: tuple[int, ...] = (1, -1)
    ramp_sizes: tuple[float, ...] = (20.0,)
    noise_scales: tuple[float, ...] = (5.0,)
    fault_free: int = 2
    duration: tuple[float, float] = (0.15, 0.25)
    start: tuple[float, float] = (0.1, 0.6)

    def __post_init__(self):
        for name in ("step_sizes", "ramp_sizes", "noise_scales"):
            if any(not (v > 0 and np.isfinite(v)) for v in getattr(self, name)):
                raise ValueError(f"{name}: every size must be finite and > 0")
        if any(s not in (-1, 1) for s in self.signs):
            raise ValueError(f"signs: expected +1 and/or -1, got {self.signs}")
        if self.fault_free < 0:
            raise ValueError(f"fault_free: must be >= 0, got {self.fault_free}")
        for name in ("duration", "start"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi <= 1:
                raise ValueError(f"{name}: expected 0 <= min <= max <= 1, got {(lo, hi)}")
        if self.start[1] + self.duration[1] > 1:
            raise ValueError("start, duration: a window may run past the end of the run")


@dataclass(frozen=True, slots=True)
class FaultVariant:
    """One member of a family: a label and the faults it injects."""

    label: str
    sensor: str | None
    kind: str | None
    size: float | None
    faults: tuple[Fault, ...]


def fault_variants(
    scenario: Scenario,
    family: FaultFamily,
    rng: np.random.Generator,
    sensors: tuple[str, ...] | None = None,
) -> list[FaultVariant]:
    """One variant per (sensor, fault) of the family, plus the fault-free ones.

    Parameters
    ----------
    scenario : the system (its own faults are ignored).
    family : the typical faults.
    rng : draws each window (start and duration), so the family is reproducible.
    sensors : restrict to these sensors (default all).
    """
    T = scenario.steps * scenario.dt
    out = [
        FaultVariant(f"fault-free {j + 1}", None, None, None, ()) for j in range(family.fault_free)
    ]
    names = scenario.sensor_names if sensors is None else sensors

    def window():
        start = rng.uniform(*family.start) * T
        length = rng.uniform(*family.duration) * T
        # on the epoch grid so every window holds whole epochs
        a = scenario.dt * np.floor(start / scenario.dt)
        return float(a), float(a + max(scenario.dt, scenario.dt * np.round(length / scenario.dt)))

    for s in scenario.sensors:
        if s.name not in names:
            continue
        sigma = np.sqrt(np.diag(s.R))
        for size in family.step_sizes:
            for sign in family.signs:
                a, b = window()
                out.append(
                    FaultVariant(
                        f"{s.name} bias {sign * size:+g}σ",
                        s.name,
                        "bias",
                        float(size),
                        (Fault(s.name, "bias", a, b, sign * size * sigma),),
                    )
                )
        for size in family.ramp_sizes:
            a, b = window()
            out.append(
                FaultVariant(
                    f"{s.name} ramp {size:g}σ",
                    s.name,
                    "ramp",
                    float(size),
                    (Fault(s.name, "ramp", a, b, size * sigma),),
                )
            )
        for scale in family.noise_scales:
            a, b = window()
            out.append(
                FaultVariant(
                    f"{s.name} noise x{scale:g}",
                    s.name,
                    "noise-scale",
                    float(scale),
                    (Fault(s.name, "noise-scale", a, b, np.full(s.dim, float(scale))),),
                )
            )
    return out


def simulate_variants(
    scenario: Scenario, variants: list[FaultVariant], runs: int, seed: int, first_run: int = 0
) -> tuple[Simulated, np.ndarray]:
    """Simulate ``runs`` runs of every variant as one batch.

    Variant ``v`` uses the run indices ``first_run + v·runs + r``, so every run of
    the family has its own random stream.

    Returns
    -------
    simulated : the stream of ``len(variants)·runs`` runs (its ``labels`` per run,
        ``(K, B, N)``: the true fault windows of each run's variant) and their truth.
    variant : (B,) int, the variant of each run.
    """
    if runs < 1:
        raise ValueError(f"runs: must be >= 1, got {runs}")
    sims = [
        simulate(replace(scenario, faults=v.faults), runs, seed, first_run + j * runs)
        for j, v in enumerate(variants)
    ]
    stream = concat_streams(*(t.stream for t in sims))
    truth = LinearTruth(
        np.concatenate([t.truth.states for t in sims]),
        tuple(np.concatenate(p) for p in zip(*(t.truth.noise_free for t in sims), strict=True)),
    )
    return Simulated(stream, truth), np.repeat(np.arange(len(variants)), runs)


def window_masks(
    scenario: Scenario, variants: list[FaultVariant], runs: int, grace: float = 0.0
) -> np.ndarray:
    """(B, K, N) bool: epoch inside ``[start, end + grace)`` of a fault of sensor i.

    Runs are ordered as :func:`simulate_variants` orders them (``runs`` per variant).
    """
    t = scenario.times
    per_variant = np.zeros((len(variants), t.size, len(scenario.sensors)), dtype=bool)
    for j, v in enumerate(variants):
        for f in v.faults:
            i = scenario.sensor_names.index(f.sensor)
            per_variant[j, :, i] |= (t >= f.start) & (t < f.end + grace)
    return np.repeat(per_variant, runs, axis=0)
