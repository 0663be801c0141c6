"""Built-in recordings shipped with ftnav (recording files in this folder, their data in
``data/`` with the upstream licence); ``ftnav process <name>``."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["recording_names", "recording_path"]


def recording_names() -> list[str]:
    """Names of the built-in recordings."""
    return sorted(
        p.name[:-5] for p in resources.files(__package__).iterdir() if p.name.endswith(".toml")
    )


def recording_path(name: str) -> Path:
    """Path of a built-in recording file."""
    return Path(str(resources.files(__package__) / f"{name}.toml"))
