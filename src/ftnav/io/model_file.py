"""Open-format storage of learned models (RBF-network fault detector, neuron fusion centre).

A model file is a ZIP archive (``ZIP_DEFLATED``; suffix ``.npz`` recommended, not
enforced) holding

* ``metadata.json``: a UTF-8 JSON object (strict JSON: no NaN/inf), and
* one ``<name>.npy`` member per array, written by
  :func:`numpy.lib.format.write_array` with ``allow_pickle=False``.

Because the layout is the one of ``numpy.savez_compressed``, ``numpy.load(path,
allow_pickle=False)`` also opens the file (it then lists ``metadata.json`` as a
non-array member and the arrays under their names); no part of the file is ever
pickled, and :func:`load_model` never unpickles or executes anything from it.

The metadata object always holds

``format``          ``"ftnav-model"``
``format_version``  ``1``
``kind``            what the model is, e.g. ``"rbf-detector"``, ``"neuron-fusion"``
``ftnav_version``   :data:`ftnav.__version__` of the writer
``created``         ISO-8601 UTC time stamp of the writing
``compatibility``   JSON object chosen by the caller (states, sensors, system hash ...),
                    compared key by key on loading (see :func:`load_model`)
``settings``        JSON object chosen by the caller (hyper-parameters, feature
                    definition, normalisation ...)
``arrays``          ``{name: {"dtype": str, "shape": [...], "sha256": hex}}``; the hash is
                    of the array's C-contiguous bytes
``checksum``        sha256 hex of the canonical JSON
                    (``json.dumps(sort_keys=True, separators=(",", ":"))``) of the
                    metadata object without the ``checksum`` key.

The checksums detect accidental corruption and naive edits; they are not a signature
(anyone can recompute them).  Every loading failure is a one-line
:class:`ModelFileError` ``model '<path>': <reason>``.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import re
import secrets
import struct
import zipfile
import zlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from types import MappingProxyType
from typing import IO, Any

import numpy as np
from numpy.lib import format as npy_format

from ftnav.io.common import ScenarioError, read_input
from ftnav.version import __version__

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "METADATA_MEMBER",
    "ModelFile",
    "ModelFileError",
    "load_model",
    "save_model",
    "system_hash",
]

FORMAT = "ftnav-model"
"""Value of the ``format`` metadata field."""

FORMAT_VERSION = 1
"""The newest ``format_version`` this ftnav reads and the one it writes."""

_METADATA = "metadata.json"
#: the zip member that holds a model file's metadata (its ``format`` is :data:`FORMAT`)
METADATA_MEMBER = _METADATA
_NPY = ".npy"
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*\Z")
_SHA256 = re.compile(r"[0-9a-f]{64}\Z")
_ALLOWED_KINDS = "biufc"  # bool, signed/unsigned integer, floating, complex
#: Bounds on what a model file may hold, checked before anything is inflated (a small
#: ZIP can declare gigabytes).  ftnav's own files are kilobytes: an RBF detector of
#: 10 000 centres of 800 features, far above the defaults (60 centres), is 64 MB.
_MAX_FILE_BYTES = 128 * 2**20
_MAX_METADATA_BYTES = 16 * 2**20
_MAX_ARRAY_BYTES = 64 * 2**20
_MAX_TOTAL_BYTES = 128 * 2**20
_MAX_NPY_HEADER = 65536
_REQUIRED = {
    "kind": str,
    "ftnav_version": str,
    "created": str,
    "compatibility": dict,
    "settings": dict,
    "arrays": dict,
}
_ZIP_READ_ERRORS: tuple[type[BaseException], ...] = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    NotImplementedError,
    RuntimeError,
    struct.error,
)
try:  # lzma may be missing from a minimal Python build
    import lzma

    _ZIP_READ_ERRORS += (lzma.LZMAError,)
except ImportError:  # pragma: no cover
    pass


class ModelFileError(ValueError):
    """An unreadable, corrupted or unsuitable model file; the message is one line.

    ``str(error)`` is ``"<field>: <reason>"``, where ``field`` defaults to
    ``model '<path>'``.

    Parameters
    ----------
    path : str or os.PathLike
        The model file concerned.
    reason : str
        What is wrong (line breaks are collapsed to spaces).
    field : str, optional
        What the message starts with, instead of ``model '<path>'``.

    Attributes
    ----------
    path, reason, field : as given (``field`` filled in).
    """

    def __init__(self, path: str | os.PathLike[str], reason: str, field: str | None = None) -> None:
        self.path = path
        self.reason = _one_line(reason)
        self.field = _one_line(field) if field is not None else f"model {str(path)!r}"
        super().__init__(f"{self.field}: {self.reason}")

    def __reduce__(
        self,
    ) -> tuple[type[ModelFileError], tuple[str | os.PathLike[str], str, str]]:
        # keep picklable despite the custom signature
        return (type(self), (self.path, self.reason, self.field))


#: the error of the file being read, from its reason (:func:`load_model`'s ``fail``)
_Fail = Callable[[str], ModelFileError]


@dataclass(frozen=True, slots=True)
class ModelFile:
    """A loaded, verified model file.

    Attributes
    ----------
    kind : str
        The model kind (``metadata["kind"]``).
    metadata : dict
        The whole metadata object, ``checksum`` included.
    arrays : Mapping[str, numpy.ndarray]
        Read-only mapping of read-only arrays.
    path : pathlib.Path or None
        Where the model was read from.
    """

    kind: str
    metadata: dict[str, Any] = field(repr=False)
    arrays: Mapping[str, np.ndarray] = field(repr=False)
    path: Path | None = None

    @property
    def settings(self) -> dict[str, Any]:
        """The ``settings`` object stored by the writer."""
        settings: dict[str, Any] = self.metadata["settings"]  # a JSON object (checked on load)
        return settings

    @property
    def compatibility(self) -> dict[str, Any]:
        """The ``compatibility`` object stored by the writer."""
        compatibility: dict[str, Any] = self.metadata["compatibility"]  # checked on load
        return compatibility


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------


def _one_line(text: Any) -> str:
    """Collapse every line break (``\\n``, ``\\r``, U+2028, ...) to one space."""
    return " ".join(str(text).splitlines()).strip()


def _short(value: Any, limit: int = 120) -> str:
    """One-line ``repr`` of ``value``, cut at ``limit`` characters."""
    text = _one_line(repr(value))
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _canonical(obj: Any) -> str:
    """Canonical JSON text: sorted keys, no spaces, strict (no NaN/inf)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), allow_nan=False)


def _sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _array_sha256(array: np.ndarray) -> str:
    """sha256 hex of the array's C-contiguous bytes."""
    return hashlib.sha256(array.tobytes(order="C")).hexdigest()


def _to_plain(value: Any, where: str, *, float_arrays: bool = False) -> Any:
    """Convert ``value`` to plain JSON types, refusing what strict JSON cannot hold.

    numpy integers/floats/bools become Python ones, arrays and tuples become lists.
    With ``float_arrays`` numeric arrays become nested lists of float.

    Raises
    ------
    ValueError : ``<where>: <reason>`` for NaN/inf, non-string keys or a value of a type
        JSON cannot hold.
    """
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, str):
        return str(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        number = float(value)
        if not math.isfinite(number):
            raise ValueError(f"{where}: {number!r} is not allowed (strict JSON, finite numbers)")
        return number
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biuf":
            raise ValueError(
                f"{where}: array of dtype {value.dtype} is not JSON-serialisable "
                "(only bool, integer and float arrays)"
            )
        if float_arrays and value.dtype.kind in "iuf":
            value = value.astype(float)
        return _to_plain(value.tolist(), where)
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise ValueError(f"{where}: key {key!r} is not a string")
            out[key] = _to_plain(
                item, f"{where}.{key}" if where else key, float_arrays=float_arrays
            )
        return out
    if isinstance(value, list | tuple):
        return [
            _to_plain(item, f"{where}[{i}]", float_arrays=float_arrays)
            for i, item in enumerate(value)
        ]
    raise ValueError(f"{where}: value of type {type(value).__name__} is not JSON-serialisable")


def _normalised(value: Any) -> Any:
    """``value`` after a JSON round trip (tuples -> lists, numpy -> Python); as is if
    it cannot be serialised."""
    try:
        return json.loads(_canonical(_to_plain(value, "value")))
    except (TypeError, ValueError):
        return value


def system_hash(parts: Mapping[str, Any]) -> str:
    """Fingerprint of the system a model was trained on.

    Parameters
    ----------
    parts : Mapping[str, Any]
        Plain values (str, int, float, bool, None, lists/tuples, nested mappings with
        string keys) and numpy scalars/arrays.  Numeric arrays are hashed as nested
        lists of float (so an integer and a float array with equal values hash alike).
        Every float is rounded to :data:`HASH_DIGITS` significant digits first: a model
        stays valid across NumPy builds whose ``exp`` or ``sin`` differ in the last bit
        (a 1-ulp change of a derived matrix), while any change of a setting a user can
        write (a σ, a τ, a period) changes the hash.

    Returns
    -------
    str
        sha256 hex of the canonical JSON of ``parts``.

    Raises
    ------
    ValueError : naming the key, for NaN/inf or a value JSON cannot hold.
    """
    if not isinstance(parts, Mapping):
        raise ValueError(f"parts: expected a mapping, got {type(parts).__name__}")
    return _sha256_text(_canonical(_rounded(_to_plain(parts, "", float_arrays=True))))


#: significant digits of every float in :func:`system_hash`
HASH_DIGITS = 12


def _rounded(value: Any) -> Any:
    """Plain JSON value with every float rounded to :data:`HASH_DIGITS` digits."""
    if isinstance(value, float):
        return float(f"{value:.{HASH_DIGITS}g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_rounded(v) for v in value]
    return value


def _check_array_name(name: Any) -> str:
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(
            f"arrays[{name!r}]: array names are letters, digits, '_', '.', '-' "
            "(not starting with '.' or '-')"
        )
    return name


def _prepare_array(name: str, value: Any) -> np.ndarray:
    """The array to store under ``name``, C-contiguous; refuses non-numeric or non-finite."""
    array = np.asarray(value)
    if array.dtype.kind not in _ALLOWED_KINDS or array.dtype.fields is not None:
        raise ValueError(
            f"arrays.{name}: dtype {array.dtype} is not allowed (only numeric and bool arrays)"
        )
    if array.dtype.kind in "fc" and not np.isfinite(array).all():
        raise ValueError(f"arrays.{name}: contains NaN or inf")
    return np.asarray(array, order="C")


# ---------------------------------------------------------------------------------------
# writing
# ---------------------------------------------------------------------------------------


def _zip_info(name: str) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
    info.compress_type = zipfile.ZIP_DEFLATED
    info.external_attr = 0o644 << 16
    return info


def save_model(
    path: str | os.PathLike[str],
    kind: str,
    arrays: Mapping[str, np.ndarray],
    *,
    compatibility: Mapping[str, Any],
    settings: Mapping[str, Any],
) -> Path:
    """Write a model file atomically (temporary file in the same folder, then rename).

    Parameters
    ----------
    path : str or os.PathLike
        Destination (suffix ``.npz`` recommended); its folder must exist.
    kind : str
        Model kind, e.g. ``"rbf-detector"`` or ``"neuron-fusion"``.
    arrays : Mapping[str, numpy.ndarray]
        Numeric or bool arrays, finite; names of letters, digits, ``_ . -``.
    compatibility : Mapping[str, Any]
        What a user of the model must match (keys chosen by the caller); see
        :func:`load_model`.
    settings : Mapping[str, Any]
        Hyper-parameters, feature definition, normalisation ...; numpy scalars and
        arrays and tuples are converted to plain JSON values.

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ValueError : naming the key, for an object/string/structured array, NaN/inf in an
        array or in ``compatibility``/``settings``, or a value JSON cannot hold.
    OSError : the file cannot be written (nothing is left behind).
    """
    path = Path(path)
    if not isinstance(kind, str) or not kind.strip():
        raise ValueError(f"kind: expected a non-empty string, got {kind!r}")
    if not isinstance(arrays, Mapping):
        raise ValueError(f"arrays: expected a mapping, got {type(arrays).__name__}")
    for label, obj in (("compatibility", compatibility), ("settings", settings)):
        if not isinstance(obj, Mapping):
            raise ValueError(f"{label}: expected a mapping, got {type(obj).__name__}")
    prepared = {_check_array_name(n): _prepare_array(n, a) for n, a in arrays.items()}
    metadata: dict[str, Any] = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "kind": kind,
        "ftnav_version": __version__,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "compatibility": _to_plain(compatibility, "compatibility"),
        "settings": _to_plain(settings, "settings"),
        "arrays": {
            name: {"dtype": a.dtype.str, "shape": list(a.shape), "sha256": _array_sha256(a)}
            for name, a in prepared.items()
        },
    }
    metadata["checksum"] = _sha256_text(_canonical(metadata))
    text = json.dumps(metadata, sort_keys=True, indent=1, allow_nan=False, ensure_ascii=False)

    tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}.tmp"
    try:
        with open(tmp, "xb") as fh:
            with zipfile.ZipFile(fh, "w", zipfile.ZIP_DEFLATED) as zf:
                zf.writestr(_zip_info(_METADATA), text.encode("utf-8"))
                for name, array in prepared.items():
                    big = array.nbytes > 2**30
                    with zf.open(_zip_info(name + _NPY), "w", force_zip64=big) as member:
                        npy_format.write_array(member, array, allow_pickle=False)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


# ---------------------------------------------------------------------------------------
# reading
# ---------------------------------------------------------------------------------------


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, fail: _Fail) -> bytes:
    """The decompressed bytes of one member; corruption becomes a :class:`ModelFileError`."""
    try:
        return zf.read(info)
    except zipfile.BadZipFile as exc:
        if "crc" in str(exc).lower():
            raise fail("file is corrupted (CRC mismatch)") from None
        raise fail(f"file is corrupted (member {info.filename!r}: {exc})") from None
    except _ZIP_READ_ERRORS as exc:
        raise fail(
            f"file is corrupted (member {info.filename!r} cannot be read: "
            f"{type(exc).__name__}: {exc})"
        ) from None


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"duplicate key {key!r}")
        out[key] = value
    return out


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"{name} is not valid JSON")


def _finite_float(text: str) -> float:
    number = float(text)
    if not math.isfinite(number):
        raise ValueError(f"number {text[:20]} overflows")
    return number


def _parse_metadata(raw: bytes, fail: _Fail) -> dict[str, Any]:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise fail("metadata.json is not UTF-8 text") from None
    try:
        metadata = json.loads(
            text,
            object_pairs_hook=_no_duplicates,
            parse_constant=_refuse_constant,
            parse_float=_finite_float,
        )
    except (ValueError, RecursionError) as exc:
        raise fail(f"metadata.json is not valid JSON ({exc})") from None
    if not isinstance(metadata, dict):
        raise fail(f"metadata.json is not a JSON object (it is a {type(metadata).__name__})")
    return metadata


def _check_metadata(metadata: dict[str, Any], kind: str | None, fail: _Fail) -> None:
    """Format, version, checksum, required fields, kind: in this order."""
    if metadata.get("format") != FORMAT:
        raise fail(
            f"is not an ftnav model file (format {_short(metadata.get('format'))}, "
            f"expected {FORMAT!r})"
        )
    version = metadata.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or version < 1:
        raise fail(f"invalid format version {_short(version)}")
    if version > FORMAT_VERSION:
        raise fail(f"format version {version} is newer than this ftnav supports ({FORMAT_VERSION})")
    checksum = metadata.get("checksum")
    body = {k: v for k, v in metadata.items() if k != "checksum"}
    try:
        expected = _sha256_text(_canonical(body))
    except ValueError:  # cannot happen for parsed strict JSON; be safe
        expected = None
    if not isinstance(checksum, str) or checksum != expected:
        raise fail("metadata was edited or corrupted (checksum mismatch)")
    for key, typ in _REQUIRED.items():
        if key not in metadata:
            raise fail(f"metadata has no {key!r} field")
        if not isinstance(metadata[key], typ):
            raise fail(
                f"metadata field {key!r} is not a JSON {'object' if typ is dict else 'string'}"
            )
    if kind is not None and metadata["kind"] != kind:
        raise fail(f"is a {metadata['kind']!r} model, expected {kind!r}")
    for name, entry in metadata["arrays"].items():
        if not _NAME.match(name):
            raise fail(f"invalid array name {_short(name)}")
        if not isinstance(entry, dict):
            raise fail(f"metadata arrays.{name} is not a JSON object")
        dtype, shape, sha = entry.get("dtype"), entry.get("shape"), entry.get("sha256")
        if not isinstance(dtype, str):
            raise fail(f"metadata arrays.{name}.dtype is not a string")
        if not (
            isinstance(shape, list)
            and all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape)
        ):
            raise fail(f"metadata arrays.{name}.shape is not a list of non-negative integers")
        if not isinstance(sha, str) or not _SHA256.match(sha):
            raise fail(f"metadata arrays.{name}.sha256 is not a sha256 hex digest")


def _check_header(
    zf: zipfile.ZipFile, info: zipfile.ZipInfo, name: str, entry: dict[str, Any], fail: _Fail
) -> None:
    """Check one ``.npy`` member's header (dtype, shape, size) against its metadata entry
    and the bounds, inflating only the header: a member that would inflate to more than
    :data:`_MAX_ARRAY_BYTES` (or to another size than its header says) is never read."""
    if info.file_size > _MAX_ARRAY_BYTES + _MAX_NPY_HEADER:
        raise fail(
            f"array {name!r} declares {info.file_size} bytes, more than the "
            f"{_MAX_ARRAY_BYTES} a model array may hold"
        )
    try:
        with zf.open(info) as fh:
            shape, dtype, header = _npy_header(name, fh, fail)
    except ModelFileError:
        raise
    except _ZIP_READ_ERRORS as exc:
        raise fail(f"file is corrupted (member {info.filename!r}: {_one_line(exc)})") from None
    _check_npy(name, shape, dtype, entry, fail)
    size = dtype.itemsize * math.prod(shape)
    if size > _MAX_ARRAY_BYTES:
        raise fail(
            f"array {name!r} of shape {list(shape)} holds {size} bytes, more than the "
            f"{_MAX_ARRAY_BYTES} a model array may hold"
        )
    if header + size != info.file_size:
        raise fail(
            f"array {name!r} holds {info.file_size} bytes, {header + size} expected "
            "(truncated or padded)"
        )


def _npy_header(name: str, fp: IO[bytes], fail: _Fail) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape, dtype and header length of the ``.npy`` data read from ``fp``."""
    try:
        version = npy_format.read_magic(fp)
        if version == (1, 0):
            shape, _, dtype = npy_format.read_array_header_1_0(fp, max_header_size=_MAX_NPY_HEADER)
        elif version == (2, 0):
            shape, _, dtype = npy_format.read_array_header_2_0(fp, max_header_size=_MAX_NPY_HEADER)
        else:
            raise fail(f"array {name!r} has an unsupported .npy version {version}")
    except ModelFileError:
        raise
    except (ValueError, TypeError, SyntaxError, EOFError, OverflowError) as exc:
        raise fail(f"array {name!r} is not a valid .npy member ({_one_line(exc)})") from None
    return shape, dtype, fp.tell()


def _check_npy(
    name: str, shape: tuple[int, ...], dtype: np.dtype, entry: dict[str, Any], fail: _Fail
) -> None:
    """A ``.npy`` header's dtype (numeric, never objects) and shape against its entry."""
    if dtype.hasobject or dtype.kind not in _ALLOWED_KINDS or dtype.fields is not None:
        raise fail(
            f"array {name!r} has dtype {_short(str(dtype))}, refused "
            "(only numeric and bool arrays; object arrays would need unpickling)"
        )
    if dtype.str != entry["dtype"]:
        raise fail(f"array {name!r} has dtype {dtype.str!r}, the metadata says {entry['dtype']!r}")
    if list(shape) != entry["shape"]:
        raise fail(f"array {name!r} has shape {list(shape)}, the metadata says {entry['shape']}")


def _read_array(name: str, raw: bytes, entry: dict[str, Any], fail: _Fail) -> np.ndarray:
    """Parse one ``.npy`` member (never unpickling) and check it against its entry."""
    fp = io.BytesIO(raw)
    shape, dtype, header = _npy_header(name, fp, fail)
    _check_npy(name, shape, dtype, entry, fail)
    expected_size = header + dtype.itemsize * math.prod(shape)
    if len(raw) != expected_size:
        raise fail(
            f"array {name!r} holds {len(raw)} bytes, {expected_size} expected (truncated or padded)"
        )
    try:
        array = npy_format.read_array(
            io.BytesIO(raw), allow_pickle=False, max_header_size=_MAX_NPY_HEADER
        )
    except (ValueError, TypeError, EOFError, OSError) as exc:  # pragma: no cover
        raise fail(f"array {name!r} cannot be read ({_one_line(exc)})") from None
    if _array_sha256(array) != entry["sha256"]:
        raise fail(f"array {name!r} was edited or corrupted (sha256 mismatch)")
    if dtype.kind in "fc" and not np.isfinite(array).all():
        raise fail(f"array {name!r} contains NaN or inf")
    array.setflags(write=False)
    return array


def _check_compatibility(stored: dict[str, Any], expected: Mapping[str, Any], fail: _Fail) -> None:
    for key, want in expected.items():
        want_n = _normalised(want)
        if key not in stored:
            raise fail(
                f"was trained without a recorded {key} (missing from its compatibility "
                f"record), this scenario has {_short(want_n)}"
            )
        have_n = _normalised(stored[key])
        if have_n == want_n:
            continue
        if key == "system_hash" and isinstance(have_n, str) and isinstance(want_n, str):
            raise fail(
                f"was trained for another scenario (system hash {have_n[:12]}… "
                f"differs from {want_n[:12]}…)"
            )
        raise fail(f"was trained for {key} = {_short(have_n)}, this scenario has {_short(want_n)}")


def load_model(
    path: str | os.PathLike[str],
    kind: str | None = None,
    *,
    compatibility: Mapping[str, Any] | None = None,
) -> ModelFile:
    """Read and verify a model file written by :func:`save_model`.

    Nothing in the file is executed or unpickled: arrays are read with
    ``allow_pickle=False`` after their ``.npy`` header was checked.

    Checks, in order: the file exists and is readable; it is a ZIP archive;
    ``metadata.json`` exists and is a JSON object; ``format``; ``format_version`` (not
    newer than :data:`FORMAT_VERSION`); ``checksum``; required fields; ``kind`` (when
    given); the ``.npy`` members are exactly the listed arrays; each array's dtype,
    shape and sha256; no NaN/inf in float arrays; then each key of ``compatibility``
    (when given) equals the file's value after JSON normalisation (tuples equal lists;
    extra keys in the file are ignored).

    Parameters
    ----------
    path : str or os.PathLike
        The model file.
    kind : str, optional
        Expected model kind.
    compatibility : Mapping, optional
        What this use of the model requires, e.g. ``{"sensors": [...], "system_hash":
        ...}``.

    Returns
    -------
    ModelFile

    Raises
    ------
    ModelFileError : one line, ``model '<path>': <reason>``, for every failure.
    """
    where = path

    def fail(reason: str) -> ModelFileError:
        return ModelFileError(where, reason)

    path = Path(path)
    try:  # a regular file of bounded size (never a FIFO or a device)
        data = read_input(path, "", _MAX_FILE_BYTES)
    except ScenarioError as exc:
        raise fail(exc.reason) from None

    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except _ZIP_READ_ERRORS:
        raise fail("truncated or not a ZIP archive") from None
    with zf:
        infos = zf.infolist()
        names = [info.filename for info in infos]
        if len(set(names)) != len(names):
            dup = next(n for n in names if names.count(n) > 1)
            raise fail(f"file is corrupted (member {dup!r} appears twice)")
        by_name = dict(zip(names, infos, strict=True))
        total = sum(info.file_size for info in infos)
        if total > _MAX_TOTAL_BYTES:
            raise fail(
                f"declares {total} bytes uncompressed, more than the {_MAX_TOTAL_BYTES} a "
                "model file may hold (refused before inflating it)"
            )
        if _METADATA not in by_name:
            raise fail("has no metadata.json (not an ftnav model file)")
        if by_name[_METADATA].file_size > _MAX_METADATA_BYTES:
            raise fail("metadata.json is implausibly large")
        metadata = _parse_metadata(_read_member(zf, by_name[_METADATA], fail), fail)
        _check_metadata(metadata, kind, fail)

        listed = metadata["arrays"]
        for member in names:
            if member == _METADATA:
                continue
            if not member.endswith(_NPY):
                raise fail(f"unexpected member {member!r} (only metadata.json and .npy)")
            if member[: -len(_NPY)] not in listed:
                raise fail(f"array {member[: -len(_NPY)]!r} is not listed in the metadata")
        for name in listed:
            if name + _NPY not in by_name:
                raise fail(f"array {name!r} is listed in the metadata but missing")

        arrays: dict[str, np.ndarray] = {}
        for name, entry in listed.items():
            info = by_name[name + _NPY]
            try:
                itemsize = np.dtype(entry["dtype"]).itemsize
            except (TypeError, ValueError, SyntaxError):
                raise fail(
                    f"metadata arrays.{name}.dtype {entry['dtype']!r} is not a dtype"
                ) from None
            if info.file_size > itemsize * math.prod(entry["shape"]) + _MAX_NPY_HEADER:
                raise fail(f"array {name!r} is larger than its metadata says")
            _check_header(zf, info, name, entry, fail)
            arrays[name] = _read_array(name, _read_member(zf, info, fail), entry, fail)

    if compatibility is not None:
        _check_compatibility(metadata["compatibility"], compatibility, fail)
    return ModelFile(
        kind=metadata["kind"], metadata=metadata, arrays=MappingProxyType(arrays), path=path
    )
