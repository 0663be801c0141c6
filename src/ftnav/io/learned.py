"""Trained models on disk: the RBF detector and the neuron fusion centre (open formats).

Both are model files of :mod:`ftnav.io.model_file` (npz arrays + JSON metadata, never
pickle) that record the *compatibility* of the system they were trained on
(:func:`compatibility`: state and sensor names, measurement sizes, a hash of the
filters' model) and are refused by a scenario whose system differs.  A method's
trained models are loaded once, at the boundary (:func:`learned_for`), and handed to
its filter as objects (:class:`~ftnav.fusion.config.Learned`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ftnav.fdi.rbf import MODEL_KIND as RBF_KIND
from ftnav.fdi.rbf import RBFModel, RBFNetwork
from ftnav.fusion.config import NOTHING_LEARNED, Learned, MethodBase, RbfDetector
from ftnav.fusion.neural_model import MODEL_KIND as NEURON_KIND
from ftnav.fusion.neural_model import NeuronModel
from ftnav.io.model_file import ModelFileError, load_model, save_model, system_hash
from ftnav.model.system import LinearSystem

__all__ = [
    "compatibility",
    "learned_for",
    "load_neuron_model",
    "load_rbf_model",
    "save_neuron_model",
    "save_rbf_model",
]


def compatibility(system: LinearSystem) -> dict[str, Any]:
    """What a learned model trained on ``system`` records and later checks.

    State and sensor names, measurement sizes and ``system_hash``, a SHA-256
    fingerprint of the filters' model (F, Q, x0, P0, every H, R and private block; a
    linearized system's F, Q and H change every epoch and are left out, so a model
    trained along one flight serves another flight of the same sensors and filters).
    Faults, methods and the simulator's true noise are left out, so a model trained
    on one scenario serves any scenario of the same system.
    """
    m = system.model
    if system.linearized:
        parts: dict[str, Any] = {"states": list(m.states), "P0": m.P0}
    else:
        parts = {"states": list(m.states), "F": m.F, "Q": m.Q, "x0": m.x0, "P0": m.P0}
    for s in system.sensors:
        private = (
            None
            if s.private is None
            else {
                "names": list(s.private.names),
                "F": s.private.F,
                "Q": s.private.Q,
                **({} if system.linearized else {"x0": s.private.x0}),
                "P0": s.private.P0,
                **({} if system.linearized else {"H": s.private.H}),
            }
        )
        entry: dict[str, Any] = {"R": s.R, "every": s.every, "offset": s.offset, "private": private}
        if not system.linearized:
            entry = {"H": s.H, **entry}
        parts[f"sensor:{s.name}"] = entry
    return {
        "states": list(m.states),
        "sensors": [s.name for s in system.sensors],
        "measurement_dims": [s.dim for s in system.sensors],
        "system_hash": system_hash(parts),
    }


# ------------------------------------------------------------------------ RBF detector
def save_rbf_model(model: RBFModel, path: str | Path) -> Path:
    """Write an RBF detector model file (npz arrays + JSON metadata, no pickle)."""
    settings = {
        "network": model.network.get_params(),
        "features": list(model.features),
        "prior": model.prior,
        "threshold": [float(v) for v in model.threshold],
        "n_on": int(model.n_on),
        "n_off": int(model.n_off),
        "training": model.training,
    }
    return save_model(
        path,
        RBF_KIND,
        model.network.to_arrays(),
        compatibility=model.compatibility,
        settings=settings,
    )


def load_rbf_model(path: str | Path, compat: Mapping[str, Any] | None = None) -> RBFModel:
    """Read and check an RBF detector file; a bad or foreign file raises ``ModelFileError``."""
    mf = load_model(path, RBF_KIND, compatibility=compat)
    s = mf.settings
    try:
        net = RBFNetwork.from_arrays(mf.arrays, s["network"])
        tau = np.asarray(s["threshold"], dtype=float)
        if tau.shape != (net.n_outputs_,) or not (np.isfinite(tau).all()):
            raise ValueError("threshold: expected one finite value per output")
        return RBFModel(
            net,
            tuple(s["features"]),
            str(s["prior"]),
            tau,
            int(s["n_on"]),
            int(s["n_off"]),
            dict(mf.compatibility),
            dict(s.get("training", {})),
        )
    except (KeyError, TypeError, ValueError) as e:
        raise ModelFileError(path, f"inconsistent RBF detector settings ({e})") from None


# ------------------------------------------------------------------ neuron fusion centre
def save_neuron_model(model: NeuronModel, path: str | Path) -> Path:
    """Write a neuron fusion model file (npz arrays + JSON metadata, no pickle)."""
    settings = {
        "configurations": list(model.configurations),
        "inputs": list(model.inputs),
        "states": list(model.states),
        "training": model.training,
    }
    arrays = {"patterns": model.patterns, "weights": model.weights, "rmse": model.rmse}
    return save_model(
        path, NEURON_KIND, arrays, compatibility=model.compatibility, settings=settings
    )


def load_neuron_model(path: str | Path, compat: Mapping[str, Any] | None = None) -> NeuronModel:
    """Read and check a neuron fusion file; a bad or foreign file raises ``ModelFileError``."""
    mf = load_model(path, NEURON_KIND, compatibility=compat)
    s = mf.settings
    try:
        return NeuronModel(
            tuple(s["configurations"]),
            np.array(mf.arrays["patterns"], dtype=bool),
            tuple(s["inputs"]),
            tuple(s["states"]),
            np.array(mf.arrays["weights"]),
            np.array(mf.arrays["rmse"]),
            dict(mf.compatibility),
            dict(s.get("training", {})),
        )
    except (KeyError, TypeError, ValueError) as e:
        raise ModelFileError(path, f"inconsistent neuron fusion settings ({e})") from None


# --------------------------------------------------------------------------- a method
def _named(e: ModelFileError, field: str, method: str) -> ModelFileError:
    """The error of a model file named by the scenario field that names it, the method
    (its name: a recording run with ``--methods`` numbers the chosen methods only) and
    the file's path."""
    return ModelFileError(
        e.path, f"{e.reason} (method {method!r}, file {str(e.path)!r})", field=field
    )


def learned_for(
    method: MethodBase, index: int, system: LinearSystem, base: Path | None = None
) -> Learned:
    """Load the trained models ``methods[index]`` names, checked against ``system``.

    A relative path is relative to ``base`` (the scenario file's folder).  A bad or
    foreign file raises :class:`~ftnav.io.model_file.ModelFileError` whose field is the
    method's setting, e.g. ``methods[2].detector.model``.
    """

    def path(name: str) -> Path:
        p = Path(name)
        return p if p.is_absolute() or base is None else base / p

    compat = compatibility(system)
    if isinstance(method.detector, RbfDetector):
        field = f"methods[{index}].detector.model"
        try:
            return Learned(detector=load_rbf_model(path(method.detector.model), compat))
        except ModelFileError as e:
            raise _named(e, field, method.name) from None
    if method.architecture == "neural":  # type: ignore[attr-defined]
        field = f"methods[{index}].model"
        if method.model is None:  # type: ignore[attr-defined]
            raise ModelFileError(
                "",
                "architecture 'neural' needs a trained model file (ftnav train-fusion)",
                field=field,
            )
        try:
            return Learned(fusion=load_neuron_model(path(method.model), compat))  # type: ignore[attr-defined]
        except ModelFileError as e:
            raise _named(e, field, method.name) from None
    return NOTHING_LEARNED
