"""Safe file handling shared by every reader and writer of the agents' files.

* Writes are atomic and confined: :func:`atomic_write_bytes` / :func:`atomic_write_text`
  write a temporary file in the target's folder, ``fsync`` it and ``os.replace`` it
  over the target, so a reader sees the old file or the new one, never half of one.
  Files get the mode ``open()`` would give them (0o666 less the umask).
  A target that is a symbolic link (dangling or not) is refused: nothing a command
  writes follows a link out of the folder it was given.
* Reads are bounded: :func:`read_json` refuses a file over :data:`MAX_JSON_BYTES`
  and a document nested deeper than :data:`MAX_JSON_DEPTH` *before* parsing it (a
  200,000-deep list would otherwise end in a ``RecursionError``), and (by default)
  the non-standard constants ``NaN`` / ``Infinity``.
* :func:`writable_problem` tells before any work whether a file could be written
  where a command was asked to write it (the first existing ancestor must be a
  writable folder; no file on the way; no link as the target).
* :class:`RunLock` holds ``<folder>/.lock`` while a run writes the folder: a second
  writer is refused naming the folder; a lock left by a dead process is reclaimed.

Limits (checked before any work is done):

============================  ===============  ==========================================
what                          limit            where
============================  ===============  ==========================================
JSON file (card, statistics,  16 MiB           :data:`MAX_JSON_BYTES`
certificate, policy card)
JSON nesting                  64 levels        :data:`MAX_JSON_DEPTH`
============================  ===============  ==========================================

Errors are :class:`UnsafeFileError` (a :class:`ValueError`) or :class:`ValueError`.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np

#: The largest JSON file read (cards, statistics, certificates are a few kB to a few MB).
MAX_JSON_BYTES = 16 * 2**20
#: The deepest nesting of lists and objects a JSON file may have.
MAX_JSON_DEPTH = 64
#: The lock file a run holds in its folder.
LOCK_FILE = ".lock"


class UnsafeFileError(ValueError):
    """A file could not be read or written safely (a pickle without trust, a link, a bomb)."""


class FolderLockedError(ValueError):
    """Another live process holds the folder's lock."""


def is_integer(value: object, minimum: int | None = None) -> bool:
    """Whether a JSON value is an integer (not a boolean), >= ``minimum`` when given."""
    return (
        isinstance(value, int)
        and not isinstance(value, bool)
        and (minimum is None or value >= minimum)
    )


def is_number(value: object) -> bool:
    """Whether a JSON value is a finite number (not a boolean)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def refuse_symlink(path: Path) -> None:
    """Raise :class:`UnsafeFileError` when ``path`` is a symbolic link (even a dangling one)."""
    if path.is_symlink():
        raise UnsafeFileError(
            f"{path} is a symbolic link (to {os.readlink(path)}); refusing to write through it"
        )


def file_mode() -> int:
    """The mode ``open()`` gives a new file: 0o666 less the process's umask.

    The umask can only be read by setting it; the mask set for that instant is the
    strictest (0o077), so a file another thread creates meanwhile is never looser.
    """
    mask = os.umask(0o077)
    os.umask(mask)
    return 0o666 & ~mask


def atomic_write_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically: temporary file beside it, fsync, os.replace.
    The file gets the mode the umask gives (:func:`file_mode`), not mkstemp's 0600.

    Raises:
        UnsafeFileError: If ``path`` is a symbolic link.
        OSError: If the folder cannot be written.
    """
    path = Path(path)
    refuse_symlink(path)
    descriptor, temporary = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.name}.", suffix=".tmp"
    )
    try:
        with os.fdopen(descriptor, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fchmod(handle.fileno(), file_mode())
            os.fsync(handle.fileno())
        refuse_symlink(path)  # made a link while we wrote: still not followed (replace swaps it)
        os.replace(temporary, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temporary)
        raise
    with contextlib.suppress(OSError):  # the folder's entry (not every system allows it)
        folder = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(folder)
        finally:
            os.close(folder)
    return path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) for a writer that takes a file name
    (matplotlib, imageio); it replaces ``path`` when the block ends without an error,
    with the mode the umask gives (:func:`file_mode`).

    Raises:
        UnsafeFileError: If ``path`` is a symbolic link.
    """
    path = Path(path)
    refuse_symlink(path)
    descriptor, name = tempfile.mkstemp(
        dir=path.parent, prefix=f".{path.stem}.", suffix=path.suffix
    )
    os.close(descriptor)
    temporary = Path(name)
    try:
        yield temporary
        refuse_symlink(path)
        os.chmod(temporary, file_mode())  # the writer reopened mkstemp's 0600 file
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def atomic_write_text(path: Path, text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def write_json(path: Path, document: object, *, indent: int = 2, sort_keys: bool = True) -> Path:
    """Write a JSON document atomically (sorted keys by default, so that files diff cleanly)."""
    return atomic_write_text(path, json.dumps(document, indent=indent, sort_keys=sort_keys) + "\n")


_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(raw: bytes) -> int:
    """The deepest nesting of ``[`` / ``{`` in a JSON text (strings skipped), without parsing."""
    skeleton = np.frombuffer(_STRING.sub(b'""', raw), dtype=np.uint8)
    steps = (np.isin(skeleton, (ord("["), ord("{"))).astype(np.int64)) - np.isin(
        skeleton, (ord("]"), ord("}"))
    ).astype(np.int64)
    return int(np.cumsum(steps).max(initial=0))


def _no_constant(name: str) -> Any:
    raise ValueError(f"non-finite number {name}")


def parse_json(
    raw: bytes, what: str, *, max_bytes: int = MAX_JSON_BYTES, allow_nan: bool = False
) -> Any:
    """Parse a bounded JSON text; ``what`` names it in errors.

    Raises:
        ValueError: If it is too large, too deep, not UTF-8 JSON, or (unless
            ``allow_nan``) holds NaN or Infinity.
    """
    if len(raw) > max_bytes:
        raise ValueError(f"{what} is {len(raw)} bytes, over the limit of {max_bytes}")
    depth = json_depth(raw)
    if depth > MAX_JSON_DEPTH:
        raise ValueError(f"{what} is nested {depth} deep, over the limit of {MAX_JSON_DEPTH}")
    try:
        text = raw.decode("utf-8")
        if allow_nan:
            return json.loads(text)
        return json.loads(text, parse_constant=_no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as error:
        raise ValueError(f"{what} is not JSON: {error}") from None


def read_json(
    path: Path, what: str = "", *, max_bytes: int = MAX_JSON_BYTES, allow_nan: bool = False
) -> Any:
    """Read a JSON file, refusing one over ``max_bytes`` (checked before reading) or too deep.

    Raises:
        ValueError: As :func:`parse_json`, or if ``path`` is not a readable file.
    """
    label = f"{what} {path}".strip()
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise ValueError(f"{label} is {size} bytes, over the limit of {max_bytes}")
        raw = path.read_bytes()
    except OSError as error:
        raise ValueError(f"cannot read {label}: {error.strerror or error}") from None
    return parse_json(raw, label, max_bytes=max_bytes, allow_nan=allow_nan)


def outputs_problem(out: Path, names: Sequence[str], overwrite: bool) -> str | None:
    """Why the files ``names`` could not be written into the folder ``out`` (None when
    they could), found without writing: the folder must be writable, each file writable,
    and an existing one is replaced only with ``overwrite``."""
    problem = writable_problem(out, folder=True)
    for name in names if problem is None else ():
        path = out / name
        if path.exists() or path.is_symlink():
            problem = problem or writable_problem(path)
            if problem is None and not overwrite:
                problem = f"{path} exists; pass --overwrite to replace it"
    return problem


def writable_problem(path: Path, *, folder: bool = False) -> str | None:
    """Why ``path`` could not be written (None when it could), found without writing.

    ``folder``: ``path`` is a folder to create or write into (else a file). Checks that
    the target is no symbolic link, is not a folder where a file is wanted (or the
    reverse), and that its first existing ancestor is a writable folder.
    """
    path = Path(path)
    if "\x00" in str(path):
        return f"{str(path)!r} holds a NUL character"
    if path.is_symlink():
        return f"{path} is a symbolic link; refusing to write through it"
    if path.exists():
        if folder and not path.is_dir():
            return f"{path} exists and is not a folder"
        if not folder and path.is_dir():
            return f"{path} is a folder, not a file"
        target = path if folder else path.parent
        if not os.access(target, os.W_OK | os.X_OK):
            return f"{target} is not writable"
        return None
    ancestor = path.parent
    while not ancestor.exists() and not ancestor.is_symlink() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        return f"cannot create {path}: {ancestor} is not a folder"
    if not os.access(ancestor, os.W_OK | os.X_OK):
        return f"cannot create {path}: {ancestor} is not writable"
    return None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class RunLock:
    """``<folder>/.lock`` (``O_CREAT | O_EXCL``, holding the pid) for as long as a run writes.

    Use as a context manager; the folder is created. A lock whose pid is not alive (a
    crashed run) is reclaimed.

    Raises:
        FolderLockedError: If a live process (another than this one) holds it.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_FILE
        self.held = False

    def acquire(self) -> RunLock:
        self.folder.mkdir(parents=True, exist_ok=True)
        refuse_symlink(self.path)
        for _ in range(3):
            try:
                descriptor = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                try:
                    pid = int(self.path.read_text().strip() or "0")
                except (OSError, ValueError):
                    pid = 0
                if pid and _pid_alive(pid):
                    raise FolderLockedError(
                        f"{self.folder} is in use by process {pid} (lock {self.path}); "
                        "wait for that run to end"
                    ) from None
                with contextlib.suppress(FileNotFoundError):
                    self.path.unlink()  # stale: its process is gone
                continue
            with os.fdopen(descriptor, "w") as handle:
                handle.write(f"{os.getpid()}\n")
            self.held = True
            return self
        raise FolderLockedError(f"{self.folder}: cannot take the lock {self.path}")

    def release(self) -> None:
        if self.held:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()
            self.held = False

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.release()
