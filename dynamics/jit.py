"""Numba-level building blocks, for jitted code outside :mod:`dynamics` (environments).

Call these from ``@njit`` functions: they are the package's one implementation of
the field, the energy and the singular tests, row by row (``*_row``) and on blocks of
up to :data:`LANES` rows held as structure of arrays (``*_block``: gather a block with
:func:`gather_block` into a :func:`new_workspace`, advance it with :func:`advance_block`,
read what you need from the block, write it back with :func:`scatter_block`). Row and parameter
conventions are those of :mod:`dynamics._kernel` (``pv`` from :func:`pack_params`, one
vector for every row, or per-row vectors (B, P): take a row's with :func:`row_params`,
a block's (P, LANES) with :func:`gather_params` into :func:`params_scratch`;
a row is ``(u, omega, alpha_1..alpha_n[, x, y, theta])``; ``act`` is the mass's
``(xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)``).

:func:`cached_njit` compiles with numba's disk cache keyed on the source files
the function inlines, not only on its own: numba alone would keep running a
stale copy of, say, the field after ``dynamics/_kernel.py`` changes.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any

from numba import njit
from numba.core.caching import NullCache

from dynamics import _kernel
from dynamics._kernel import (
    LANES,
    ROW_PATH_MAX_ROWS,
    advance_block,
    advance_mass_row,
    advance_row,
    block_order,
    energy_block,
    energy_block_from_trig,
    energy_row,
    field_block,
    field_row,
    gather_block,
    gather_params,
    is_folded_row,
    lane_value,
    new_workspace,
    pack_params,
    params_scratch,
    row_params,
    scatter_block,
    sincos,
    sincos_block,
    singular_margin_row,
)

__all__ = [
    "LANES",
    "ROW_PATH_MAX_ROWS",
    "advance_block",
    "advance_mass_row",
    "advance_row",
    "block_order",
    "cached_njit",
    "energy_block",
    "energy_block_from_trig",
    "energy_row",
    "field_block",
    "field_row",
    "gather_block",
    "gather_params",
    "is_folded_row",
    "lane_value",
    "new_workspace",
    "pack_params",
    "params_scratch",
    "row_params",
    "scatter_block",
    "sincos",
    "sincos_block",
    "singular_margin_row",
]


def source_stamp(path: str) -> tuple[float, int]:
    """(mtime, size) of a source file, as numba stamps its caches."""
    stat = os.stat(path)
    return stat.st_mtime, stat.st_size


def _import_stamp(module: ModuleType) -> tuple[float, int]:
    """The module's stamp when it was imported (``SOURCE_STAMP``), else its stamp now.

    A module edited after it was imported but before a dependent module is decorated
    would otherwise stamp the dependent's cache with the new file while the process
    compiles the old code: a stale cache that later runs accept.
    """
    recorded = getattr(module, "SOURCE_STAMP", None)
    return recorded if recorded is not None else source_stamp(str(module.__file__))


def _key_cache_on(dispatcher: Any, modules: Sequence[ModuleType]) -> None:
    """Extend the cache's source stamp with the modules' stamps (numba private detail).

    If numba's internals move, fall back to no disk cache (compile once per
    process) rather than risk running stale code.
    """
    try:
        dispatcher.enable_caching()
        cache_file = dispatcher._cache._cache_file
        stamps = tuple(_import_stamp(module) for module in modules if module.__file__)
        cache_file._source_stamp = (cache_file._source_stamp, *stamps)
    except Exception:  # pragma: no cover - depends on numba internals
        dispatcher._cache = NullCache()


def cached_njit(
    *, depends_on: Sequence[ModuleType] = (), **options: Any
) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit`` with a disk cache invalidated by this module's kernels and ``depends_on``.

    Args:
        depends_on: Modules whose jitted functions the decorated one calls.
        **options: Passed to ``numba.njit`` (e.g. ``parallel=True``).
    """

    def decorate(function: Callable[..., Any]) -> Any:
        dispatcher = njit(**options)(function)
        _key_cache_on(dispatcher, (_kernel, *depends_on))
        return dispatcher

    return decorate
