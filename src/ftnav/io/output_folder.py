"""Where a command's files go: never a user's file replaced, a result replaced as a whole.

An ``--out`` target is claimed before anything is computed (:meth:`Output.claim`)
and written after the computation has succeeded (:meth:`Output.staged`):

* **Ownership.**  Every folder ftnav writes into holds :data:`MANIFEST`, the list of
  the files it wrote there: ``files`` for an output folder (``ftnav run``,
  ``process``, ``trajectory``: the last run's files, replaced by the next run) and
  ``kept`` for single files (a model file of ``train-*``, a schema, and their
  figures: never deleted by a folder run).  A file that no manifest lists (nor, for
  a model file, an ftnav model file's own header) is the user's: a command that
  would write a file of that name refuses, naming it, and writes nothing.  The check
  is made at the claim for the names known in advance and again, for every name,
  just before the files are moved in.
* **A lock.**  The claim takes an exclusive ``flock`` on a lock file named after the
  target's real path (in ``$TMPDIR/ftnav-locks-<uid>``; held until the command ends,
  released by the kernel when the process dies): a second command on the same
  target refuses at once, naming the process that holds it.
* **All or nothing.**  Files are written into a hidden staging folder next to the
  target (``.<name>.ftnav-partial-<token>``).  A new target is the staging folder
  renamed (one atomic rename).  An existing one is replaced with a journal: the
  earlier result's files are moved into ``<stage>/.previous``, then the new files
  are moved in and the new manifest last; while this runs, SIGINT and SIGTERM are
  held back.  If the process dies inside (SIGKILL, power), the staging folder is the
  journal: the next claim of the same target finds it (its owner's lock is gone),
  moves the earlier files back and deletes the new ones if the new manifest had not
  been moved in yet, and removes the staging folder either way.  So a target holds
  one run's complete result, the earlier or the new, and no stray folder survives
  the next command.

Limits: locking needs ``fcntl`` (POSIX; elsewhere there is no lock), and it is per
user and per machine (a shared network folder written from two machines is not
protected).
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import secrets
import shutil
import tempfile
import zipfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ftnav.io.model_file import FORMAT, METADATA_MEMBER
from ftnav.parallel import signals_held
from ftnav.version import __version__

try:  # POSIX
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]

__all__ = ["MANIFEST", "Output", "OutputRefused"]

#: File in a folder that lists the files ftnav wrote there (JSON).
MANIFEST = ".ftnav-outputs.json"
#: Infix of a staging folder's name: ``.<target name>.ftnav-partial-<token>``.
PARTIAL = ".ftnav-partial-"
_PREVIOUS = ".previous"
#: errors of the file system that stop a write (full, read-only, denied, too big, I/O)
_FULL_OR_DENIED = {
    errno.ENOSPC,
    errno.EDQUOT,
    errno.EROFS,
    errno.EACCES,
    errno.EPERM,
    errno.EFBIG,
    errno.EIO,
}


class OutputRefused(ValueError):
    """An ``--out`` that cannot be written without harm: one line, exit status 2."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"--out: {' '.join(reason.split())}")


# ------------------------------------------------------------------------- manifest


def _read_manifest(folder: Path) -> dict[str, Any]:
    """The manifest's ``files`` and ``kept`` lists (names of plain files in ``folder``)
    and ``stamps`` (name -> [size, mtime_ns] of the file as ftnav wrote it)."""
    try:
        doc = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"files": [], "kept": [], "stamps": {}}
    out: dict[str, Any] = {}
    for key in ("files", "kept"):
        names = doc.get(key, []) if isinstance(doc, dict) else []
        out[key] = [n for n in names if _plain_name(n)] if isinstance(names, list) else []
    stamps = doc.get("stamps", {}) if isinstance(doc, dict) else {}
    out["stamps"] = {
        n: v
        for n, v in (stamps.items() if isinstance(stamps, dict) else ())
        if _plain_name(n) and isinstance(v, list) and len(v) == 2
    }
    return out


def _stamp(p: Path) -> list[int]:
    """A file's size and modification time (ns): what ftnav wrote, or a file replaced."""
    st = p.stat()
    return [int(st.st_size), int(st.st_mtime_ns)]


def _plain_name(n: object) -> bool:
    return (
        isinstance(n, str)
        and n not in ("", ".", "..", MANIFEST)
        and "/" not in n
        and "\\" not in n
        and "\0" not in n
    )


def _is_plain_file(p: Path) -> bool:
    return p.is_file() and not p.is_symlink()


def _is_model_file(p: Path) -> bool:
    """An ftnav model file, recognised by its own header (older files had no manifest)."""
    if p.suffix != ".npz" or not _is_plain_file(p):
        return False
    try:
        with zipfile.ZipFile(p) as zf:
            info = zf.getinfo(METADATA_MEMBER)
            if info.file_size > 1 << 20:
                return False
            meta: object = json.loads(zf.read(info))
            return isinstance(meta, dict) and meta.get("format") == FORMAT
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return False


def _manifest_text(
    files: list[str], kept: list[str], last: list[str], stamps: dict[str, list[int]]
) -> str:
    doc = {
        "written_by": f"ftnav {__version__}",
        "files": files,
        "kept": kept,
        "last": last,
        "stamps": stamps,
    }
    return json.dumps(doc, indent=1) + "\n"


# --------------------------------------------------------------------------- locking


def _lock_path(target: Path, what: str = "") -> Path:
    key = hashlib.sha256(os.fsencode(os.path.realpath(target)) + what.encode()).hexdigest()[:32]
    uid = os.getuid() if hasattr(os, "getuid") else 0
    folder = Path(tempfile.gettempdir()) / f"ftnav-locks-{uid}"
    folder.mkdir(mode=0o700, exist_ok=True)
    return folder / f"{key}.lock"


@contextmanager
def _manifest_lock(home: Path) -> Iterator[None]:
    """Hold ``home``'s manifest for one commit (waiting for another command's commit):
    two commands writing different targets into one folder update one manifest."""
    fd = None
    if fcntl is not None and home.is_dir():
        try:
            fd = os.open(_lock_path(home, "#manifest"), os.O_RDWR | os.O_CREAT, 0o600)
            fcntl.flock(fd, fcntl.LOCK_EX)
        except OSError:  # no lock folder: go on without it
            if fd is not None:
                os.close(fd)
            fd = None
    try:
        yield
    finally:
        if fd is not None:
            os.close(fd)


# ------------------------------------------------------------------------ the target


class Output:
    """An ``--out`` target of one command (module docstring).

    Parameters
    ----------
    out : the path as the user gave it (for messages).
    folder : True for an output folder; False for a file (written with its
        companions, e.g. a figure, in the file's folder).
    """

    def __init__(self, out: Path, *, folder: bool) -> None:
        self.out = out
        self.target = Path(os.path.abspath(out))
        self.folder = folder
        self._lock_fd: int | None = None

    # -- where files land
    @property
    def home(self) -> Path:
        """The folder the files land in."""
        return self.target if self.folder else self.target.parent

    def _stage_parents(self) -> list[Path]:
        """Folders where a staging folder of this target may be."""
        return [self.target, self.target.parent] if self.folder else [self.target.parent]

    # -- claim
    def claim(self, names: Iterable[str] = ()) -> None:
        """Check, lock, recover and check the names known in advance (module docstring).

        Raises
        ------
        OutputRefused
            The target cannot be written, another command holds it, or one of
            ``names`` is a user's file.
        """
        self._check_writable()
        self._lock()
        try:
            self.recover()
            self.check_names(names)
        except BaseException:
            self.release()
            raise

    def _check_writable(self) -> None:
        out, target = self.out, self.target
        if target.is_symlink() and not target.exists():
            raise OutputRefused(f"{str(out)!r} is a broken symbolic link")
        if self.folder and target.exists() and not target.is_dir():
            raise OutputRefused(f"{str(out)!r} is a file, not a folder")
        if not self.folder and target.is_dir():
            raise OutputRefused(f"{str(out)!r} is a folder; give a file name")
        base = self.home
        while not base.exists() and base != base.parent:
            base = base.parent
        if not base.is_dir():
            raise OutputRefused(f"cannot create {str(out)!r}: {str(base)!r} is not a folder")
        if not os.access(base, os.W_OK | os.X_OK):
            raise OutputRefused(f"cannot write to {str(base)!r} (permission denied)")

    def _lock(self) -> None:
        if fcntl is None or self._lock_fd is not None:  # pragma: no cover - not POSIX
            return
        try:
            fd = os.open(_lock_path(self.target), os.O_RDWR | os.O_CREAT, 0o600)
        except OSError:  # no lock folder (read-only /tmp): go on without a lock
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 64).decode(errors="replace").strip()
            os.close(fd)
            who = f" (process {holder})" if holder.isdigit() else ""
            raise OutputRefused(
                f"{str(self.out)!r} is being written by another ftnav command{who}; "
                "wait for it or choose another --out"
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._lock_fd = fd

    def release(self) -> None:
        """Release the lock (the kernel does it too when the process ends)."""
        if self._lock_fd is not None:
            os.close(self._lock_fd)
            self._lock_fd = None

    def __enter__(self) -> Output:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    # -- ownership
    def _owned(self, folder: Path) -> set[str]:
        """The files ftnav wrote here and that are still what it wrote: a name it listed
        whose file a user has since replaced (deleted and written again) is the user's
        (``ftnav schema --out s.json`` replaced a user's new ``s.json`` before)."""
        m = _read_manifest(folder)
        stamps = m["stamps"]
        owned = set()
        for n in m["files"] + m["kept"]:
            p = folder / n
            if _is_plain_file(p) and (n not in stamps or stamps[n] == _stamp(p)):
                owned.add(n)
        return owned

    def check_names(self, names: Iterable[str]) -> None:
        """Refuse if a file this command would write is a user's (module docstring)."""
        home = self.home
        if not home.is_dir():
            return
        owned = self._owned(home)
        for name in names:
            p = home / name
            if (p.exists() or p.is_symlink()) and name not in owned and not _is_model_file(p):
                raise OutputRefused(
                    f"{str(p)!r} exists and no ftnav manifest lists it (or it changed since "
                    "ftnav wrote it): it is not replaced; "
                    "move it or choose another --out"
                )

    # -- recovery
    def recover(self) -> None:
        """Finish what a killed command left: restore or drop its staging folders."""
        for parent in self._stage_parents():
            if not parent.is_dir():
                continue
            for stage in parent.glob(f".{glob_escape(self.target.name)}{PARTIAL}*"):
                if stage.is_dir() and not stage.is_symlink():
                    _roll_back(stage, self.home)

    # -- writing
    @contextmanager
    def staged(self) -> Iterator[Path]:
        """A staging folder whose files replace the target when the block succeeds.

        On any exception the staging folder, and every folder created for it, is
        removed and the target is left as it was.
        """
        home = self.home
        target = self.target
        created: list[Path] = []
        parent = target if self.folder and target.is_dir() else target.parent
        try:
            created = _make_folders(parent)
            # mkdir, not mkdtemp: the folder gets the umask's mode, as it will be the output
            stage = parent / f".{target.name}{PARTIAL}{secrets.token_hex(6)}"
            stage.mkdir()
        except OSError as e:
            _remove_folders(created)
            raise OutputRefused(f"cannot create {str(self.out)!r}: {e.strerror or e}") from None
        try:
            yield stage
            names = sorted(p.name for p in stage.iterdir())
            self.check_names(names)
            with signals_held(), _manifest_lock(home):
                self._commit(stage, names, home)
        except OSError as e:
            shutil.rmtree(stage, ignore_errors=True)
            _remove_folders(created)
            if e.errno in _FULL_OR_DENIED:  # the disk's, not ftnav's, problem: exit 2
                raise OutputRefused(f"cannot write {str(self.out)!r}: {e.strerror}") from e
            raise
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            _remove_folders(created)
            raise

    def _commit(self, stage: Path, names: list[str], home: Path) -> None:
        empty: dict[str, Any] = {"files": [], "kept": [], "stamps": {}}
        before = _read_manifest(home) if home.is_dir() else empty
        if self.folder:
            files, kept = names, [n for n in before["kept"] if n not in names]
            gone = before["files"]  # the earlier run's files: deleted
        else:
            files = [n for n in before["files"] if n not in names]
            kept = sorted({*before["kept"], *names})
            gone = []
        # what is written now, as the renames below keep it (size and mtime)
        stamps = {n: v for n, v in before["stamps"].items() if n in {*files, *kept}}
        stamps |= {n: _stamp(stage / n) for n in names}
        text = _manifest_text(files, kept, names, stamps)
        (stage / MANIFEST).write_text(text, encoding="utf-8")
        if self.folder and not self.target.exists():
            os.rename(stage, self.target)  # a new folder: one atomic rename
            return
        # every file deleted or replaced is first moved aside: the journal
        old = [n for n in dict.fromkeys([*gone, *names, MANIFEST]) if _is_plain_file(home / n)]
        previous = stage / _PREVIOUS
        previous.mkdir()
        for n in old:
            os.replace(home / n, previous / n)
        for n in names:
            os.replace(stage / n, home / n)
        os.replace(stage / MANIFEST, home / MANIFEST)  # the commit point
        shutil.rmtree(stage)


def glob_escape(name: str) -> str:
    """``name`` with the glob characters escaped."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


def _roll_back(stage: Path, home: Path) -> None:
    """Undo an interrupted commit (module docstring), then remove ``stage``.

    Before the commit point the new manifest is still in ``stage``: the new files
    already moved in (its ``last`` names no longer in ``stage``) are deleted and the
    earlier files in ``<stage>/.previous`` are moved back.  After it, the commit was
    complete and only ``stage`` is left to remove.
    """
    previous = stage / _PREVIOUS
    new_manifest = stage / MANIFEST
    if previous.is_dir() and new_manifest.is_file():
        try:
            last = json.loads(new_manifest.read_text(encoding="utf-8")).get("last", [])
        except (OSError, ValueError, AttributeError):
            last = []
        for n in last if isinstance(last, list) else []:
            if _plain_name(n) and not (stage / n).exists() and _is_plain_file(home / n):
                (home / n).unlink()
        for p in previous.iterdir():
            os.replace(p, home / p.name)
    shutil.rmtree(stage, ignore_errors=True)


def _make_folders(folder: Path) -> list[Path]:
    """Create ``folder`` and its missing parents; the ones created, deepest first."""
    missing = []
    while not folder.exists():
        missing.append(folder)
        folder = folder.parent
    for f in reversed(missing):
        f.mkdir()
    return missing


def _remove_folders(created: list[Path]) -> None:
    for f in created:  # deepest first; stops at one that is no longer empty
        try:
            f.rmdir()
        except OSError:
            break
