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

from ftnav.fdi.features import feature_names
from ftnav.fdi.rbf import MODEL_KIND as RBF_KIND
from ftnav.fdi.rbf import RBFModel, RBFNetwork
from ftnav.fusion.config import NOTHING_LEARNED, Learned, MethodBase, RbfDetector
from ftnav.fusion.neural_model import FREE_INPUT, NeuronModel
from ftnav.fusion.neural_model import MODEL_KIND as NEURON_KIND
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


def _rbf_fits(model: RBFModel, system: LinearSystem) -> str | None:
    """Why an RBF detector cannot serve ``system`` (outputs, features), or None."""
    net = model.network
    N = system.n_sensors
    if net.n_outputs_ != N:
        return f"has {net.n_outputs_} outputs (one per local filter), this scenario has {N} sensors"
    if model.prior not in ("local", "global"):
        return f"has an unknown prior {model.prior!r} (expected 'local' or 'global')"
    try:
        names = feature_names(
            model.features,
            system.model.states,
            [s.name for s in system.sensors],
            [s.dim for s in system.sensors],
        )
    except ValueError as e:
        return f"has unknown features ({e})"
    if net.n_features_in_ != len(names):
        return (
            f"takes {net.n_features_in_} features, its feature kinds "
            f"{list(model.features)} give {len(names)} on this scenario"
        )
    return None


def _neurons_fit(model: NeuronModel, system: LinearSystem) -> str | None:
    """Why a neuron fusion model cannot serve ``system`` (inputs, states), or None."""
    sensors = tuple(s.name for s in system.sensors)
    inputs = tuple(i for i in model.inputs if i != FREE_INPUT)
    if inputs != sensors or model.inputs[: len(sensors)] != sensors:
        return f"has the inputs {list(model.inputs)}, this scenario's sensors are {list(sensors)}"
    if model.patterns.shape[1] != len(sensors):
        return (
            f"has flag patterns of {model.patterns.shape[1]} sensors, this scenario has "
            f"{len(sensors)}"
        )
    if model.states != tuple(system.model.states):
        return f"was trained for states {list(model.states)}"
    if model.rmse.shape != model.weights.shape[:2]:
        return (
            f"has rmse of shape {list(model.rmse.shape)}, {list(model.weights.shape[:2])} expected"
        )
    return None


def learned_for(
    method: MethodBase, index: int, system: LinearSystem, base: Path | None = None
) -> Learned:
    """Load the trained models ``methods[index]`` names, checked against ``system``.

    A relative path is relative to ``base`` (the scenario file's folder).  The model must
    fit the system before anything runs: an RBF detector's outputs (one per sensor) and
    features, a neuron bank's inputs, flag patterns and states.  A bad or foreign file
    raises :class:`~ftnav.io.model_file.ModelFileError` whose field is the
    method's setting, e.g. ``methods[2].detector.model``.
    """

    def path(name: str) -> Path:
        p = Path(name)
        return p if p.is_absolute() or base is None else base / p

    compat = compatibility(system)
    if isinstance(method.detector, RbfDetector):
        field = f"methods[{index}].detector.model"
        file = path(method.detector.model)
        try:
            rbf = load_rbf_model(file, compat)
            problem = _rbf_fits(rbf, system)
            if problem is not None:
                raise ModelFileError(file, problem)
        except ModelFileError as e:
            raise _named(e, field, method.name) from None
        return Learned(detector=rbf)
    if method.architecture == "neural":  # type: ignore[attr-defined]
        field = f"methods[{index}].model"
        if method.model is None:  # type: ignore[attr-defined]
            raise ModelFileError(
                "",
                "architecture 'neural' needs a trained model file (ftnav train-fusion)",
                field=field,
            )
        file = path(method.model)  # type: ignore[attr-defined]
        try:
            neurons = load_neuron_model(file, compat)
            problem = _neurons_fit(neurons, system)
            if problem is not None:
                raise ModelFileError(file, problem)
        except ModelFileError as e:
            raise _named(e, field, method.name) from None
        return Learned(fusion=neurons)
    return NOTHING_LEARNED
