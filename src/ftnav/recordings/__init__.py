"""Built-in recordings shipped with ftnav (recording files in this folder, their data in
``data/`` with the upstream licence); ``ftnav process <name>``.

The NaveGo built-ins (``navego-adis16405``, ``navego-adis16488``) do not vendor their
data: they read ``$FTNAV_NAVEGO_DIR`` or, unset, ``<repository>/../shared/data/
navego_synthetic/`` (:func:`navego_dir`)."""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

__all__ = ["navego_dir", "recording_names", "recording_path"]


def recording_names() -> list[str]:
    """Names of the built-in recordings."""
    return sorted(
        p.name[:-5] for p in resources.files(__package__).iterdir() if p.name.endswith(".toml")
    )


def recording_path(name: str) -> Path:
    """Path of a built-in recording file."""
    return Path(str(resources.files(__package__) / f"{name}.toml"))


def navego_dir() -> Path:
    """Where the NaveGo built-ins read their ``.mat`` files: ``$FTNAV_NAVEGO_DIR``, else
    ``<repository>/../shared/data/navego_synthetic`` (relative to this package)."""
    env = os.environ.get("FTNAV_NAVEGO_DIR")
    if env:
        return Path(env)
    here = Path(str(resources.files(__package__)))
    return (here / "../../../../shared/data/navego_synthetic").resolve()
