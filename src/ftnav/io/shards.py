"""Shards of a campaign: ``ftnav run --runs A:B`` writes ``shard.npz``, ``ftnav merge``
joins shards into the campaign of all their runs.

A shard holds what evaluation needs of its runs: every method's per-run, per-epoch
:class:`~ftnav.eval.montecarlo.MethodResult` arrays (with and without the faults, and
on the second trajectory where the scenario has one), and a header naming the
scenario file (its path and SHA-256), the root seed, the first run and the number of
runs and the ftnav version.  Run ``i`` of a campaign depends on the root seed and
``i`` only (:func:`~ftnav.eval.montecarlo.run_scenario`), so the shards ``0:40``,
``40:100`` merged equal ``--runs 100`` bit for bit (``tests/cli/test_shards.py``).

The file is a NumPy ``.npz`` read with ``allow_pickle=False``: nothing in it is
unpickled, and the header is JSON.  Merging refuses (one line, naming the shard)
shards of another scenario file or seed or ftnav version, and run ranges that
overlap or leave a gap.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ftnav.engine.driver import GuardTrace
from ftnav.eval.montecarlo import RESULT_FIELDS, MethodResult, ScenarioResult
from ftnav.version import __version__

__all__ = ["SHARD", "ShardHeader", "scenario_digest", "write_shard", "read_shard", "check_shards"]

#: file name of a shard in a run's output folder
SHARD = "shard.npz"
_HEADER = "header.json"
#: the parts of a shard: the faulty runs, their fault-free twins, the second trajectory's
_PARTS = ("results", "fault_free", "second.results", "second.fault_free")


def scenario_digest(path: Path) -> str:
    """SHA-256 of a scenario file's bytes (a shard names the file it was run from)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@dataclass(frozen=True, slots=True)
class ShardHeader:
    """What a shard was run from: the scenario file, seed, runs and ftnav version."""

    scenario: str
    scenario_path: str
    scenario_sha256: str
    seed: int
    first_run: int
    runs: int
    methods: tuple[str, ...]
    version: str = __version__

    @property
    def end(self) -> int:
        """One past the last run."""
        return self.first_run + self.runs


def _flatten(prefix: str, value: Any, out: dict[str, np.ndarray]) -> None:
    if value is None:
        return
    if hasattr(value, "_fields"):  # a GuardTrace (NamedTuple of arrays)
        for f in value._fields:
            _flatten(f"{prefix}/{f}", getattr(value, f), out)
    elif isinstance(value, tuple):
        for i, v in enumerate(value):
            _flatten(f"{prefix}/{i}", v, out)
    else:
        out[prefix] = np.asarray(value)


def write_shard(
    path: Path,
    header: ShardHeader,
    result: ScenarioResult,
    second: ScenarioResult | None = None,
) -> Path:
    """Write ``result`` (and the second trajectory's) as the shard ``path``."""
    arrays: dict[str, np.ndarray] = {}
    doc = {k: getattr(header, k) for k in ShardHeader.__dataclass_fields__}
    doc["methods"] = list(header.methods)
    arrays[_HEADER] = np.frombuffer(json.dumps(doc).encode(), dtype=np.uint8)
    parts = [result.results, result.fault_free]
    if second is not None:
        parts += [second.results, second.fault_free]
    for part, methods in zip(_PARTS, parts, strict=False):
        for name, res in methods.items():
            for field in RESULT_FIELDS:
                _flatten(f"{part}/{name}/{field}", getattr(res, field), arrays)
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]
    return Path(path)


def _method(arrays: dict[str, np.ndarray], prefix: str) -> MethodResult:
    values: dict[str, Any] = {}
    for field in RESULT_FIELDS:
        key = f"{prefix}/{field}"
        if key in arrays:
            values[field] = arrays[key]
        elif field == "R_hat":
            i, items = 0, []
            while f"{key}/{i}" in arrays:
                items.append(arrays[f"{key}/{i}"])
                i += 1
            values[field] = tuple(items)
        elif field == "guard" and f"{key}/{GuardTrace._fields[0]}" in arrays:
            values[field] = GuardTrace(*(arrays[f"{key}/{f}"] for f in GuardTrace._fields))
        else:
            values[field] = None
    return MethodResult(**values)


def read_shard(
    path: Path,
) -> tuple[ShardHeader, list[dict[str, MethodResult]]]:
    """The header and the parts (:data:`_PARTS` present) of the shard ``path``.

    ValueError naming the file when it is not a shard ftnav wrote.
    """
    where = str(path)
    not_shard = f"{where}: not a shard written by 'ftnav run --runs A:B'"
    # an .npz is a zip archive: anything else (an .npy, text, a pickle) is refused before
    # NumPy, whose message for it suggests unpickling
    if not zipfile.is_zipfile(path):
        raise ValueError(f"{not_shard} (not an .npz archive)")
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except OSError as e:
        raise ValueError(f"{where}: not readable ({e.strerror or e})") from None
    except (ValueError, EOFError, zipfile.BadZipFile):
        raise ValueError(f"{not_shard} (a damaged or foreign archive)") from None
    if _HEADER not in arrays:
        raise ValueError(f"{where}: not a shard written by 'ftnav run --runs A:B'")
    try:
        doc = json.loads(arrays.pop(_HEADER).tobytes().decode())
        if not isinstance(doc, dict) or not isinstance(doc.get("methods"), list):
            raise TypeError("not the fields of a shard (methods a list of names, ...)")
        doc["methods"] = tuple(doc["methods"])
        header = ShardHeader(**doc)
        _check_header(header)
    except (ValueError, TypeError, KeyError) as e:
        raise ValueError(f"{where}: damaged shard header ({e})") from None
    parts = []
    for part in _PARTS:
        names = [n for n in header.methods if any(k.startswith(f"{part}/{n}/") for k in arrays)]
        if not names:
            break
        parts.append({n: _method(arrays, f"{part}/{n}") for n in names})
    if not parts:
        raise ValueError(f"{where}: the shard holds no results")
    for key, a in arrays.items():  # every result has the runs first: the merge joins on it
        if a.ndim == 0 or a.shape[0] != header.runs:
            raise ValueError(
                f"{where}: damaged shard: {key} holds {a.shape[0] if a.ndim else 0} runs, "
                f"its header {header.runs}"
            )
    return header, parts


def _check_header(h: ShardHeader) -> None:
    """TypeError or ValueError for a header field of the wrong type or out of range."""
    for name in ("scenario", "scenario_path", "scenario_sha256", "version"):
        if not isinstance(getattr(h, name), str):
            raise TypeError(f"{name}: not a string")
    for name, low in (("seed", 0), ("first_run", 0), ("runs", 1)):
        value = getattr(h, name)
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"{name}: {value!r} is not a whole number")
        if value < low:
            raise ValueError(f"{name}: {value} is below {low}")
    if not h.methods or not all(isinstance(m, str) for m in h.methods):
        raise TypeError("methods: not a list of names")


def check_shards(headers: list[tuple[str, ShardHeader]]) -> list[int]:
    """The order (by first run) in which the shards ``(where, header)`` join; ValueError,
    naming the shard, for shards that do not make one campaign: another scenario file,
    seed, methods or ftnav version, overlapping runs or a gap."""
    order = sorted(range(len(headers)), key=lambda i: headers[i][1].first_run)
    where0, h0 = headers[order[0]]
    for i in order[1:]:
        where, h = headers[i]
        for field in ("scenario_sha256", "seed", "methods", "version"):
            if getattr(h, field) != getattr(h0, field):
                what = {"scenario_sha256": "scenario file"}.get(field, field)
                raise ValueError(
                    f"{where}: another {what} than {where0} "
                    f"({getattr(h, field)!r} against {getattr(h0, field)!r})"
                )
    for a, b in zip(order, order[1:], strict=False):
        (wa, ha), (wb, hb) = headers[a], headers[b]
        if hb.first_run < ha.end:
            raise ValueError(
                f"{wb}: runs {hb.first_run}:{hb.end} overlap {wa}'s {ha.first_run}:{ha.end}"
            )
        if hb.first_run > ha.end:
            raise ValueError(
                f"{wb}: runs {ha.end}:{hb.first_run} are in no shard "
                f"(between {wa}'s {ha.first_run}:{ha.end} and this one's)"
            )
    return order
