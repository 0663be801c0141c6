"""The registry of fusion architectures: one line each.

An entry names the architecture's configuration model (its settings, validated at the
boundary), how to build its filter from a system, the configuration and the trained
models, and the boundary checks that need the system.  The scenario-file format is
the discriminated union of the configuration models (:data:`MethodConfig`), so a new
architecture is one new module (configuration, filter, ``check``) plus one line here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Annotated, Any, NamedTuple, TypeAlias, Union

from pydantic import Discriminator, Tag, ValidationError

from ftnav.fusion import centralized, distributed, federated, neural
from ftnav.fusion.config import CONFIG_ERROR, NOTHING_LEARNED, Learned, MethodBase, config_error
from ftnav.fusion.protocol import Architecture
from ftnav.fusion.zero_reset import ZeroResetFilter
from ftnav.model.system import LinearSystem

__all__ = [
    "ARCHITECTURES",
    "DEFAULT_ARCHITECTURE",
    "MethodConfig",
    "build",
    "check",
    "method_config",
]


class Entry(NamedTuple):
    """One architecture: its configuration model, its filter, its boundary checks."""

    config: type[MethodBase]
    build: Callable[..., Architecture[Any]]
    check: Callable[[Any, LinearSystem, Learned], None]


def _federated(
    system: LinearSystem, config: federated.FederatedConfig, learned: Learned, **kw: Any
) -> Architecture[Any]:
    if config.mode == "zero-reset":
        return ZeroResetFilter(system, config, learned)
    return federated.FederatedFilter(system, config, learned, **kw)


ARCHITECTURES: dict[str, Entry] = {
    "centralized": Entry(
        centralized.CentralizedConfig, centralized.CentralizedFilter, centralized.check
    ),
    "federated": Entry(federated.FederatedConfig, _federated, federated.check),
    "distributed": Entry(
        distributed.DistributedConfig, distributed.DistributedFilter, distributed.check
    ),
    "neural": Entry(neural.NeuralConfig, neural.NeuralFusion, neural.check),
}

#: the architecture of a method that names none
DEFAULT_ARCHITECTURE = "federated"


def _architecture(value: Any) -> str:
    if isinstance(value, dict):
        return str(value.get("architecture", DEFAULT_ARCHITECTURE))
    return str(getattr(value, "architecture", DEFAULT_ARCHITECTURE))


#: a method's configuration: the discriminated union of every architecture's model (built
#: from the registry, so a type checker sees the common base)
if TYPE_CHECKING:
    MethodConfig: TypeAlias = MethodBase
else:
    MethodConfig = Annotated[
        Union[tuple(Annotated[e.config, Tag(name)] for name, e in ARCHITECTURES.items())],  # noqa: UP007
        Discriminator(_architecture),
    ]


def method_config(architecture: str = DEFAULT_ARCHITECTURE, **settings: Any) -> MethodBase:
    """A validated configuration from keyword settings (the Python route to a method).

    ``method_config("federated", name="fkf", sharing="trace")`` is the method a file's
    ``[[methods]]`` table with those keys gives.

    Raises
    ------
    ValueError : an unknown architecture, or the first invalid setting as one line
        ``methods[<name>].<setting>: <reason>``.
    """
    if architecture not in ARCHITECTURES:
        raise ValueError(
            f"methods[{settings.get('name', '?')}].architecture: unknown value "
            f"{architecture!r} (expected one of {sorted(ARCHITECTURES)})"
        )
    try:
        return ARCHITECTURES[architecture].config.model_validate(
            {**settings, "architecture": architecture}
        )
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        loc = tuple(err.get("loc", ()))
        if err["type"] == CONFIG_ERROR:
            loc += tuple(err["ctx"]["path"])
        field = ".".join(str(p) for p in loc if not isinstance(p, int))
        where = f"methods[{settings.get('name', '?')}]" + (f".{field}" if field else "")
        raise ValueError(f"{where}: {err['msg']}") from None


def build(
    system: LinearSystem, config: MethodBase, learned: Learned = NOTHING_LEARNED, **kw: Any
) -> Architecture[Any]:
    """The filter of a method: its architecture's filter on ``system``."""
    return ARCHITECTURES[config.architecture].build(system, config, learned, **kw)  # type: ignore[attr-defined]


def check(system: LinearSystem, config: MethodBase, learned: Learned = NOTHING_LEARNED) -> None:
    """The boundary checks of a method that need the system or its trained models."""
    if config.correction is not None and not system.linearized:
        raise config_error(
            "only read by integrated scenarios and recordings (the SINS correction)",
            "correction",
        )
    ARCHITECTURES[config.architecture].check(config, system, learned)  # type: ignore[attr-defined]
