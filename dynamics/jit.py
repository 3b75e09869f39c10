"""Numba-level building blocks, for jitted code outside :mod:`dynamics` (environments).

Call these from ``@njit`` functions: they are the package's one implementation of
the field, the energy and the singular tests, row by row (``*_row``) and on blocks of
up to :data:`LANES` rows held as structure of arrays (``*_block``). A batched driver
groups rows with :func:`block_order` and :func:`block_end` and advances each group
with :func:`advance_rows`, which picks the row path or the block path and leaves the
group's new state in its :func:`new_workspace` as structure of arrays (the one RK4
driver of ``dynamics.Stepper`` and ``trailer_env.kernels``). Row and parameter
conventions are those of :mod:`dynamics._kernel` (``pv`` from :func:`pack_params`, one
vector for every row, or per-row vectors (B, P): take a row's with :func:`row_params`,
a block's (P, LANES) with :func:`gather_params` into :func:`params_scratch`;
a row is ``(u, omega, alpha_1..alpha_n[, x, y, theta])``; ``act`` is the mass's
``(xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)``).

:func:`cached_njit` compiles with numba's disk cache keyed on a hash of every kernel
source (:mod:`dynamics._cache`), not on the function's own file only: numba alone
would keep running a stale copy of, say, the field after ``dynamics/_kernel.py``
changes. Every compiled function of ``dynamics``, ``trailer_env`` and
``agents.oracles`` uses it.
"""

from __future__ import annotations

from dynamics._cache import cached_njit
from dynamics._kernel import (
    LANES,
    PARALLEL_MIN_ROWS,
    ROW_PATH_MAX_ROWS,
    ROWS_PER_CHUNK,
    advance_block,
    advance_mass_row,
    advance_row,
    advance_rows,
    block_end,
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
    "PARALLEL_MIN_ROWS",
    "ROWS_PER_CHUNK",
    "ROW_PATH_MAX_ROWS",
    "advance_block",
    "advance_mass_row",
    "advance_row",
    "advance_rows",
    "block_end",
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
