"""The disk-cache key of every compiled kernel: one hash of all the kernel sources.

numba keys a function's disk cache on its own source file's (mtime, size) only, so a
kernel that inlines or calls a jitted function of another file would keep running its
stale compiled copy after that file changed. :func:`cached_njit` keys every cache on
:data:`SOURCE_HASH` instead: a SHA-256 of every ``.py`` file of :data:`KERNEL_TREES`
(their paths and contents), taken once when this module is first imported. An edit to
any of those files recompiles every kernel once (more compiling after an edit, never
stale code), and :func:`cached_njit` refuses a function defined outside them, so no
dependency can be left out of the key. Plain ``njit(cache=True)`` is not used in those
trees (``tests/dynamics/test_cache_key.py`` checks it).

The hash is of the files as they were when this module was imported, before the
packages' other modules: a file edited while a process is importing them keys that
process's caches on the text before the edit, which a later process only matches if
the file is put back to that text.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from numba import njit
from numba.core.caching import NullCache

#: The folder holding the ``dynamics``, ``trailer_env`` and ``agents`` packages.
ROOT = Path(__file__).resolve().parent.parent
#: The source trees (relative to :data:`ROOT`) that hold every cached kernel and
#: everything a kernel may call or inline.
KERNEL_TREES = ("dynamics", "trailer_env", "agents/oracles")


def source_hash(root: Path, trees: Sequence[str]) -> str:
    """SHA-256 (hex) of the relative path and the bytes of every ``.py`` file of ``trees``.

    A tree that does not exist under ``root`` adds nothing.
    """
    digest = hashlib.sha256()
    for tree in trees:
        for path in sorted((root / tree).rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(b"\0")
            digest.update(path.read_bytes())
            digest.update(b"\0")
    return digest.hexdigest()


#: The key of every kernel's disk cache (see the module docstring).
SOURCE_HASH = source_hash(ROOT, KERNEL_TREES)


def _in_kernel_trees(filename: str) -> bool:
    path = Path(filename).resolve()
    return any(path.is_relative_to(ROOT / tree) for tree in KERNEL_TREES)


def _key_cache(dispatcher: Any) -> None:
    """Replace the cache's source stamp by :data:`SOURCE_HASH` (a numba private detail).

    If numba's internals move, fall back to no disk cache (compile once per process)
    rather than risk running stale code.
    """
    try:
        dispatcher.enable_caching()
        dispatcher._cache._cache_file._source_stamp = SOURCE_HASH
    except Exception:  # pragma: no cover - depends on numba internals
        dispatcher._cache = NullCache()


def cached_njit(**options: Any) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit`` with a disk cache keyed on :data:`SOURCE_HASH`.

    Args:
        **options: Passed to ``numba.njit`` (e.g. ``parallel=True``,
            ``inline="always"``); not ``cache``, which this decorator owns.

    Raises:
        TypeError: ``cache`` among the options.
        ValueError: (when decorating) the function is defined outside
            :data:`KERNEL_TREES`, whose hash would not cover its source.
    """
    if "cache" in options:
        raise TypeError("cached_njit() sets the cache itself; do not pass cache=")

    def decorate(function: Callable[..., Any]) -> Any:
        filename = function.__code__.co_filename
        if not _in_kernel_trees(filename):
            raise ValueError(
                f"cached_njit: {function.__qualname__} is defined in {filename}, outside "
                f"the kernel trees {KERNEL_TREES} under {ROOT} whose hash keys the cache"
            )
        dispatcher = njit(**options)(function)
        _key_cache(dispatcher)
        return dispatcher

    return decorate
