"""Built-in scenarios shipped with ftnav (TOML files in this folder)."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["builtin_names", "builtin_path", "builtin_profile_names", "builtin_profile_path"]


def builtin_names() -> list[str]:
    """Names of the built-in scenarios."""
    return sorted(
        p.name[:-5] for p in resources.files(__package__).iterdir() if p.name.endswith(".toml")
    )


def builtin_path(name: str) -> Path:
    """Path of a built-in scenario file."""
    return Path(str(resources.files(__package__) / f"{name}.toml"))


def builtin_profile_names() -> list[str]:
    """Names of the built-in flight profiles (``profiles/*.toml``)."""
    return sorted(
        p.name[:-5]
        for p in (resources.files(__package__) / "profiles").iterdir()
        if p.name.endswith(".toml")
    )


def builtin_profile_path(name: str) -> Path:
    """Path of a built-in flight profile."""
    return Path(str(resources.files(__package__) / "profiles" / f"{name}.toml"))
