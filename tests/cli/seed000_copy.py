"""seed000 written as a user's file with some of its methods and fewer epochs (helper)."""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from pathlib import Path

import tomli_w

from ftnav.scenarios import builtin_path


def seed000_copy(path: Path, methods: Sequence[str], steps: int = 600) -> Path:
    """seed000's model, sensors and fault with ``methods`` only, ``steps`` epochs and no
    figure specs, written to ``path`` (a user's file: it gets no paper claims)."""
    doc = tomllib.loads(builtin_path("seed000").read_text())
    doc["methods"] = [m for m in doc["methods"] if m["name"] in methods]
    doc["steps"] = steps
    doc.pop("figures", None)
    path.write_text(tomli_w.dumps(doc))
    return path
