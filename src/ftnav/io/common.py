"""The validation kit of every ftnav file: one-line errors, pydantic field types, TOML.

Every problem of a scenario, profile or recording file is a :class:`ScenarioError`
whose message is a single line ``<field path>: <reason>``, e.g.
``sensors[1].R: not positive definite``.  The pydantic models of the file formats use
the field types and the strict configuration here; :func:`to_scenario_error` turns a
pydantic ``ValidationError`` into that one line.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import stat
import tomllib
import types
import unicodedata
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, TypedDict, Union, Unpack, get_args, get_origin

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Tag, ValidationError
from pydantic.types import AllowInfNan
from pydantic_core import PydanticCustomError

__all__ = [
    "ScenarioError",
    "STRICT",
    "FileName",
    "Matrix",
    "covariance_problem",
    "file_name_problem",
    "Name",
    "Vector",
    "fail",
    "format_loc",
    "number",
    "one_line",
    "read_input",
    "read_text",
    "read_toml",
    "to_scenario_error",
    "unique",
]

#: Relative tolerance of the symmetry test: max|A - Aᵀ| <= SYM_RTOL · max|A|.
SYM_RTOL = 1e-9
#: Tolerance of ``sum(betas) + master_share == 1``.
SHARE_TOL = 1e-9
#: Relative tolerance of the positive-semi-definite test on the smallest eigenvalue.
PSD_RTOL = 1e-10

_CHECK = "ftnav_check"  # pydantic error type of the checks below


# --------------------------------------------------------------------------- errors


class ScenarioError(ValueError):
    """An invalid scenario: the message is one line ``<field path>: <reason>``.

    Attributes
    ----------
    path : dotted field path (``methods[2].sharing``), or the file name for
        problems reading the file.
    reason : what is wrong, one line.
    origin : where the data came from (file name or ``"<scenario>"``).
    line : the 1-based line of the file that sets the field (:func:`field_line`), or
        None.
    """

    def __init__(
        self, path: str, reason: str, origin: str = "<scenario>", line: int | None = None
    ) -> None:
        self.path = one_line(path)
        self.reason = one_line(reason)
        self.origin = origin
        self.line = line
        super().__init__(f"{self.path}: {self.reason}")

    @property
    def where(self) -> str | None:
        """``file:line`` the field is set in; None where the line is not known (the
        message names the field alone, or the file where the file is the problem)."""
        if self.origin == "<scenario>" or self.line is None:
            return None
        return f"{self.origin}:{self.line}"

    def __reduce__(self) -> tuple[type[ScenarioError], tuple[str, str, str, int | None]]:
        # keep picklable despite the custom signature
        return (type(self), (self.path, self.reason, self.origin, self.line))


_SEGMENT = re.compile(r"([^.\[\]]+)(?:\[([^\]]+)\])?")
#: a table header: a key (not a number: an inner line of a written matrix, ``[1.0, 0.0]``)
_HEADER = re.compile(r"\s*\[\[?\s*([A-Za-z_\"'][\w.\-\"' ]*?)\s*\]\]?\s*(#.*)?$")


def field_line(text: str, field: str) -> int | None:
    """The 1-based line of a TOML document ``text`` that sets ``field`` (a path of
    :class:`ScenarioError`: ``faults[0].end``, ``methods[ckf].sharing`` — an index or a
    ``name`` —, ``filter.dt``, ``name``), or None where it cannot be told (a default
    not written, an inline table's inner key is given its table's line)."""
    segments = _SEGMENT.findall(field)
    if not segments:
        return None
    lines = text.splitlines()
    headers = [(i, m[1]) for i, m in ((i, _HEADER.match(ln)) for i, ln in enumerate(lines)) if m]
    table, index = segments[0]
    starts = [i for i, h in headers if h == table]
    rest = segments[1:]
    if not starts:  # a top-level key, before the first table
        first = headers[0][0] if headers else len(lines)
        at = _key_line(lines, 0, first, table)
        if at is None or not index:
            return at
        # an array of inline tables, one a line: the one at the index, or of that name
        items = [i for i in range(at - 1, first) if lines[i].lstrip().lstrip("[").startswith("{")]
        if index.isdigit():
            return items[int(index)] + 1 if int(index) < len(items) else at
        named = re.compile(rf"[{{,]\s*name\s*=\s*[\"']{re.escape(index)}[\"']")
        return next((i + 1 for i in items if named.search(lines[i])), at)
    block = None
    for k, start in enumerate(starts):
        end = next((i for i, _ in headers if i > start), len(lines))
        if not index or (index.isdigit() and k == int(index)):
            block = (start, end)
        elif not index.isdigit() and _key_value(lines, start + 1, end, "name") == index:
            block = (start, end)
        if block is not None:
            break
    if block is None:
        return None
    if not rest:
        return block[0] + 1
    return _key_line(lines, block[0] + 1, block[1], rest[0][0])


def with_line(e: ScenarioError, source: str | Path) -> ScenarioError:
    """``e`` with the line of the file ``source`` that sets its field
    (:func:`field_line`), where ``e`` names that file and has no line yet."""
    if e.origin == str(source) and e.line is None:
        try:
            e.line = field_line(Path(source).read_text("utf-8-sig"), e.path)
        except (OSError, UnicodeDecodeError):
            pass
    return e


def _key_line(lines: list[str], start: int, end: int, key: str) -> int | None:
    pattern = re.compile(rf"\s*[\"']?{re.escape(key)}[\"']?\s*=")
    return next((i + 1 for i in range(start, end) if pattern.match(lines[i])), None)


def _key_value(lines: list[str], start: int, end: int, key: str) -> str | None:
    line = _key_line(lines, start, end, key)
    if line is None:
        return None
    m = re.match(r"[^=]*=\s*[\"']([^\"']*)[\"']", lines[line - 1])
    return m[1] if m else None


def one_line(text: str) -> str:
    """Collapse every line break (``\\n``, ``\\r``, U+2028, ...) to one space."""
    return " ".join(str(text).splitlines()).strip() if text else str(text)


def fail(reason: str, *path: str | int) -> PydanticCustomError:
    """A validation error at ``path`` (relative to the validator's own location)."""
    return PydanticCustomError(_CHECK, "{reason}", {"reason": reason, "path": tuple(path)})


def format_loc(loc: Sequence[str | int]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += f".{part}" if out else str(part)
    return out


_TOML_TYPES = {
    bool: "boolean",
    int: "integer",
    float: "float",
    str: "string",
    list: "array",
    tuple: "array",
    dict: "table",
}


def _show(value: Any) -> str:
    """Short one-line description of an offending input: ``string 'abc'``."""
    kind = _TOML_TYPES.get(type(value), type(value).__name__)
    if isinstance(value, list | tuple | dict):
        return kind
    text = repr(value)
    if len(text) > 40:
        text = text[:37] + "..."
    return f"{kind} {text}"


def _reason(err: Mapping[str, Any]) -> str:
    """One-line reason for one pydantic error."""
    kind = err["type"]
    ctx = err.get("ctx") or {}
    value = err.get("input")
    if kind == _CHECK:
        return str(ctx["reason"])
    if kind == "extra_forbidden":
        return "unknown key"
    if kind == "union_tag_invalid":
        tag = str(ctx.get("tag"))
        choices = re.findall(r"'((?:[^'\\]|\\.)*)'", str(ctx.get("expected_tags", "")))
        close = difflib.get_close_matches(tag, choices, n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}? " if close else ""
        return f"unknown value {tag!r} ({hint}expected one of: {', '.join(choices)})"
    if kind == "missing":
        return "missing required key"
    if kind == "literal_error":
        expected = str(ctx.get("expected", ""))
        # strings are quoted ('a' or 'b'); numbers are not (18 or 15)
        choices = re.findall(r"'((?:[^'\\]|\\.)*)'", expected) or re.findall(
            r"-?\d+(?:\.\d+)?", expected
        )
        shown = repr(value) if isinstance(value, str) else _show(value)
        return f"unknown value {shown} (expected one of: {', '.join(choices)})"
    if kind in ("float_type", "float_parsing"):
        return f"expected a number, got {_show(value)}"
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return f"expected an integer, got {_show(value)}"
    if kind in ("bool_type", "bool_parsing"):
        return f"expected true or false, got {_show(value)}"
    if kind == "string_type":
        return f"expected a string, got {_show(value)}"
    if kind in ("list_type", "tuple_type"):
        return f"expected an array, got {_show(value)}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return f"expected a table, got {_show(value)}"
    if kind == "finite_number":
        return f"is NaN or inf ({value!r})"
    bounds = {
        "greater_than": ("gt", ">"),
        "greater_than_equal": ("ge", ">="),
        "less_than": ("lt", "<"),
        "less_than_equal": ("le", "<="),
    }
    if kind in bounds:
        key, op = bounds[kind]
        return f"must be {op} {ctx.get(key)}, got {value!r}"
    if kind == "too_short":
        need = ctx.get("min_length", 1)
        return f"must have at least {need} {'entry' if need == 1 else 'entries'}"
    if kind == "string_too_short":
        return "must not be empty"
    return str(err.get("msg", kind))


#: why a key is refused in a table of a model: ``explain(key, model) -> reason | None``
Explainer = Callable[[str, type[BaseModel]], str | None]


def to_scenario_error(
    exc: ValidationError,
    origin: str,
    root: type[BaseModel] | None = None,
    explain: Explainer | None = None,
) -> ScenarioError:
    """The one line of the first problem (an unknown key before the rest: it usually
    explains a missing one).  With ``root`` (the model that was validated) an unknown
    key gets the closest valid key of its table, or the reason ``explain`` gives (e.g.
    a method's setting that another architecture reads)."""
    errors = exc.errors(include_url=False)
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    raw = tuple(err.get("loc", ()))
    if err["type"] == _CHECK:
        raw = raw + tuple(err["ctx"]["path"])
    if err["type"] == "union_tag_invalid":  # the tag key itself is the field at fault
        raw = raw + (str(err["ctx"]["discriminator"]).strip("'()_"),)
    loc, models = _walk(root, raw) if root is not None else (raw, [])
    path = format_loc(loc) or origin
    reason = _reason(err)
    if err["type"] == "extra_forbidden" and models:
        key = str(loc[-1])
        reason = (explain and explain(key, models[-1])) or _unknown_key(key, models[-1])
    return ScenarioError(path, reason, origin)


def _walk(root: type[BaseModel], loc: tuple[Any, ...]) -> tuple[tuple[Any, ...], list[Any]]:
    """``loc`` without the tags of tagged unions, and the model class at each table."""
    out: list[Any] = []
    models: list[Any] = [root]
    current: Any = root
    for part in loc:
        current = _unwrap(current)
        if isinstance(current, type) and issubclass(current, BaseModel):
            field = current.model_fields.get(part) if isinstance(part, str) else None
            if field is None:
                out.append(part)
                current = None
                continue
            out.append(part)
            current = field.annotation
            continue
        origin_ = get_origin(current)
        if origin_ in (list, tuple) and isinstance(part, int):
            out.append(part)
            current = get_args(current)[0]
            continue
        members = _union_members(current)
        if members and isinstance(part, str) and part in members:
            current = members[part]  # a tag: not part of the user's path
            models.append(_unwrap(current))
            continue
        out.append(part)
        current = None
    if isinstance(_unwrap(current), type) and issubclass(_unwrap(current), BaseModel):
        models.append(_unwrap(current))
    return tuple(out), [m for m in models if isinstance(m, type) and issubclass(m, BaseModel)]


def _unwrap(tp: Any) -> Any:
    while get_origin(tp) is Annotated:
        tp = get_args(tp)[0]
    args = [a for a in get_args(tp) if a is not type(None)] if _is_union(tp) else []
    if len(args) == 1:
        return _unwrap(args[0])
    return tp


def _is_union(tp: Any) -> bool:
    return get_origin(tp) in (Union, types.UnionType)


def _union_members(tp: Any) -> dict[str, Any]:
    """Tag → member of a tagged union (pydantic ``Tag``, or a ``kind``/``architecture``
    literal), empty for anything else."""
    tp0 = tp
    while get_origin(tp0) is Annotated:
        tp0 = get_args(tp0)[0]
    if not _is_union(tp0):
        return {}
    members = {}
    for member in get_args(tp0):
        tag = None
        inner = member
        if get_origin(member) is Annotated:
            inner = get_args(member)[0]
            tag = next((m.tag for m in get_args(member)[1:] if isinstance(m, Tag)), None)
        if isinstance(inner, type) and issubclass(inner, BaseModel) and tag is None:
            for key in ("kind", "architecture"):
                f = inner.model_fields.get(key)
                if f is not None and get_origin(f.annotation) is Literal:
                    tags = get_args(f.annotation)
                    for t in tags:
                        members[str(t)] = inner
                    break
            continue
        if tag is not None:
            members[tag] = inner
    return members


def _fields(model: type[BaseModel]) -> list[str]:
    return list(model.model_fields)


def _unknown_key(key: str, model: type[BaseModel]) -> str:
    """``unknown key``, with the closest valid key of ``model``'s table when there is one."""
    close = difflib.get_close_matches(key, _fields(model), n=1, cutoff=0.6)
    return f"unknown key (did you mean {close[0]!r}?)" if close else "unknown key"


# ------------------------------------------------------------- field-level types


def _finite_vector(values: list[float]) -> list[float]:
    if not all(math.isfinite(v) for v in values):
        raise fail("contains NaN or inf")
    return values


def _finite_matrix(rows: list[list[float]]) -> list[list[float]]:
    if rows and any(len(r) != len(rows[0]) for r in rows):
        lengths = ", ".join(str(len(r)) for r in rows)
        raise fail(f"rows have different lengths ({lengths})")
    if not all(math.isfinite(v) for r in rows for v in r):
        raise fail("contains NaN or inf")
    return rows


def _name(text: str) -> str:
    if not text.strip():
        raise fail("must be a non-empty name")
    return text


#: Longest name that becomes part of a file name (UTF-8 bytes): a method's and an aid's
#: names together make ``vb_noise_<method>_<aid>.png``, within the 255 bytes of a name.
MAX_FILE_NAME_BYTES = 100


def file_name_problem(text: str) -> str | None:
    """Why ``text`` cannot be (part of) a file name on every system, or None.

    Refused: an empty or blank name, ``/`` and ``\\`` (folder separators), NUL and other
    control characters, a leading ``.`` (hidden, or ``.``/``..``: a name of only dots),
    leading or trailing spaces, more than :data:`MAX_FILE_NAME_BYTES` bytes.
    """
    if not text.strip():
        return "must be a non-empty name"
    bad = sorted(
        {c for c in text if c in "/\\" or unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp")}
    )
    if bad:
        shown = ", ".join(repr(c) for c in bad)
        return f"must be usable as a file name (it contains {shown})"
    if text.startswith("."):
        return "must be usable as a file name (it starts with '.')"
    if text != text.strip():
        return "must be usable as a file name (leading or trailing spaces)"
    if len(text.encode("utf-8")) > MAX_FILE_NAME_BYTES:
        return f"must be usable as a file name (at most {MAX_FILE_NAME_BYTES} bytes)"
    return None


def _file_name(text: str) -> str:
    problem = file_name_problem(text)
    if problem is not None:
        raise fail(problem)
    return text


_Float = Annotated[float, AllowInfNan(True)]  # NaN/inf refused for the whole field, below
Vector = Annotated[list[_Float], AfterValidator(_finite_vector)]
Matrix = Annotated[list[list[_Float]], AfterValidator(_finite_matrix)]
Name = Annotated[str, AfterValidator(_name)]
#: a name that becomes part of a file name: scenarios, methods, aids (:func:`file_name_problem`)
FileName = Annotated[str, AfterValidator(_file_name)]


# ---------------------------------------------------------------- plausibility bounds

#: Largest variance of a covariance matrix of a linear scenario (state units²): σ up to
#: 1e10 state units.  Squares of it, and of the states it drives, stay far from overflow.
MAX_VARIANCE = 1e20
#: Smallest nonzero variance (state units²), σ down to 1e-10 state units: below it the
#: Kalman update loses the covariance to rounding (``P − K H P`` cancels).
MIN_VARIANCE = 1e-20
#: Largest condition number (largest / smallest eigenvalue) of a positive definite
#: covariance: its Cholesky factor keeps 4 significant digits in float64.
MAX_CONDITION = 1e12
#: Largest size of a fault offset of a linear scenario (state units), as for σ.
MAX_OFFSET = 1e10
#: Largest noise-scale factor of a fault: the variance grows by its square (1e12).
MAX_NOISE_FACTOR = 1e6


def covariance_problem(a: np.ndarray, definite: bool) -> str | None:
    """Why the symmetric matrix ``a`` is not a plausible covariance, or None.

    Every diagonal entry (variance) is at most :data:`MAX_VARIANCE`, and a nonzero one at
    least :data:`MIN_VARIANCE`; a positive definite one (``definite``) has a condition
    number of at most :data:`MAX_CONDITION`.
    """
    d = np.diagonal(a)
    if d.size and float(d.max()) > MAX_VARIANCE:
        i = int(np.argmax(d))
        return (
            f"variance [{i}][{i}] = {d[i]:.3g} is implausibly large "
            f"(at most {MAX_VARIANCE:g}: σ up to {MAX_VARIANCE**0.5:g} state units)"
        )
    small = (d > 0) & (d < MIN_VARIANCE)
    if small.any():
        i = int(np.argmax(small))
        return (
            f"variance [{i}][{i}] = {d[i]:.3g} is implausibly small "
            f"(at least {MIN_VARIANCE:g}, or 0 where allowed: the filters lose it to rounding)"
        )
    if definite and a.size:
        eig = np.linalg.eigvalsh(a)
        if eig[0] * MAX_CONDITION < eig[-1]:
            return (
                f"ill-conditioned (eigenvalues {eig[0]:.3g} to {eig[-1]:.3g}, condition "
                f"number above {MAX_CONDITION:g}: the filters lose it to rounding)"
            )
    return None


class _Bounds(TypedDict, total=False):
    """What :func:`number` passes on to ``pydantic.Field``: a default and bounds."""

    default: float
    gt: float
    ge: float
    lt: float
    le: float


def number(description: str, **bounds: Unpack[_Bounds]) -> Any:
    """A finite float field with optional bounds (pydantic's field marker: ``Any``)."""
    return Field(description=description, allow_inf_nan=False, **bounds)


#: strict types, no unknown key, no NaN or inf in any float field
STRICT = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


#: Largest input file ftnav reads (bytes): a TOML file, a model file, a log.  A
#: bigger one is refused before it is read (``/dev/zero`` or a mistyped path to a
#: disk image must not fill the memory).  Logs of a day at 1 kHz stay below it.
MAX_INPUT_BYTES = 4 * 1024**3
#: Largest TOML file (scenario, profile, recording): they are hand-written text.
MAX_TOML_BYTES = 16 * 1024**2


def read_input(path: Path, what: str, limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, or a one-line refusal.

    A FIFO, a device, a socket or a folder is refused before it is opened (reading
    one blocks forever or never ends), and so is a file larger than ``limit``; the
    read itself is bounded too (a file that grows while it is read).  The error is a
    :class:`ScenarioError` whose path is the file and whose reason starts with
    ``what`` (e.g. ``"imu"``).
    """
    name = str(path)
    w = f"{what}: " if what else ""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ScenarioError(name, f"{w}file not found", name) from None
    except OSError as exc:
        raise ScenarioError(name, f"{w}cannot read ({exc.strerror or exc})", name) from None
    if stat.S_ISDIR(st.st_mode):
        raise ScenarioError(name, f"{w}is a folder, not a file", name)
    if not stat.S_ISREG(st.st_mode):
        kind = (
            "a FIFO (named pipe)"
            if stat.S_ISFIFO(st.st_mode)
            else "a device"
            if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
            else "a socket"
            if stat.S_ISSOCK(st.st_mode)
            else "not a regular file"
        )
        raise ScenarioError(name, f"{w}is {kind}, not a regular file", name)
    if st.st_size > limit:
        raise ScenarioError(name, f"{w}{st.st_size} bytes, more than the {limit} ftnav reads", name)
    try:
        with open(path, "rb") as fh:
            raw = fh.read(limit + 1)
    except OSError as exc:
        raise ScenarioError(name, f"{w}cannot read ({exc.strerror or exc})", name) from None
    if len(raw) > limit:
        raise ScenarioError(name, f"{w}more than the {limit} bytes ftnav reads", name)
    return raw


def read_text(path: Path, what: str, limit: int = MAX_INPUT_BYTES) -> str:
    """:func:`read_input` decoded as UTF-8; a byte-order mark (Excel's "CSV UTF-8")
    is dropped; a file that is not UTF-8 is refused with the offending line."""
    raw = read_input(path, what, limit)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ScenarioError(
            f"{path}:{line}", f"{what}: not UTF-8 text (byte {exc.start})", str(path)
        ) from None


def read_toml(source: str | Path) -> dict[str, Any]:
    """Read a TOML file; every problem is a one-line :class:`ScenarioError` naming the file."""
    path = Path(source)
    name = str(source)
    raw = read_input(path, "", MAX_TOML_BYTES)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ScenarioError(name, f"not valid UTF-8 text (byte {exc.start})", name) from None
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise ScenarioError(name, _TOO_DEEP, name) from None
    except tomllib.TOMLDecodeError as exc:
        msg = one_line(str(exc))
        where = re.fullmatch(r"(.*?)\s*\(at line (\d+), column (\d+)\)", msg)
        if where:
            reason = f"TOML syntax error at line {where[2]}, column {where[3]}: {where[1]}"
        else:
            reason = f"TOML syntax error: {msg}"
        raise ScenarioError(name, reason, name) from None
    if _depth(data) > MAX_TOML_DEPTH:
        raise ScenarioError(name, _TOO_DEEP, name)
    return data


#: Deepest nesting of arrays and tables in a TOML file ftnav reads: its formats need 5
#: (``methods[i].detector`` of a table, a matrix in a table of an array).
MAX_TOML_DEPTH = 32
_TOO_DEEP = f"nested more than {MAX_TOML_DEPTH} levels (arrays and tables): not an ftnav file"


def _depth(value: Any) -> int:
    """Nesting depth of arrays and tables, without recursion."""
    deepest, stack = 0, [(value, 0)]
    while stack:
        item, level = stack.pop()
        if isinstance(item, dict):
            item = list(item.values())
        elif not isinstance(item, list):
            continue
        deepest = max(deepest, level + 1)
        if deepest > MAX_TOML_DEPTH:
            return deepest
        stack.extend((v, level + 1) for v in item)
    return deepest


def unique(names: Sequence[str], what: str, *path: str | int) -> None:
    seen: set[str] = set()
    for i, name in enumerate(names):
        if name in seen:
            raise fail(f"duplicate {what} {name!r}", *path, i)
        seen.add(name)
