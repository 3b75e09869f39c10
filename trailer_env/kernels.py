"""Numba kernels of the batch core: one call per control step for the whole batch.

Scalar settings are packed into float64 vectors once (see :class:`trailer_env.core.ConvoyCore`)
so that a call for one environment costs well under a microsecond. Large batches
(:data:`PARALLEL_MIN_ROWS` rows or more) use the parallel variants, which split the rows
into chunks; every row's arithmetic is the same either way, so results do not depend on
the batch size or the number of threads.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from dynamics.jit import cached_njit, energy_row, is_folded_row, singular_margin_row
from trailer_env import actuator, fidelity
from trailer_env.actuator import apply_actions
from trailer_env.fidelity import auto_substeps

#: Batches at least this large use the parallel kernels.
PARALLEL_MIN_ROWS = 256
_CHUNK = 64

# Indices into the packed observation settings.
OBS_B, OBS_S_MAX, OBS_SPEED_MAX, OBS_BAND, OBS_FOLD = range(5)


@cached_njit(depends_on=(actuator, fidelity))
def prepare_step(
    action: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    mode: int,
    b: float,
    s_max: float,
    accel_max: float,
    dt: float,
    frequency: float,
    auto: bool,
    auto_settings: np.ndarray,
    substeps: np.ndarray,
    z_backup: np.ndarray,
    act_backup: np.ndarray,
) -> int:
    """Actions -> guarded accelerations, substep counts, and a backup of the state.

    With ``auto``, the substeps of every row follow the fidelity's auto rule
    (:func:`trailer_env.fidelity.auto_substeps`, settings from
    :meth:`~trailer_env.fidelity.Fidelity.auto_settings`) given the new accelerations.
    Returns -1, or the first row with a non-finite action (then nothing is changed
    beyond the accelerations of the rows before it).
    """
    bad = apply_actions(action, act, mode, b, s_max, accel_max, dt, frequency)
    if bad >= 0:
        return bad
    if auto:
        auto_substeps(z, act, auto_settings, substeps)
    z_backup[:, :] = z
    act_backup[:, :] = act
    return -1


@cached_njit(depends_on=(actuator, fidelity))
def _observe_row(
    i: int,
    z: np.ndarray,
    act: np.ndarray,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    obs: np.ndarray,
    margin: np.ndarray,
    cost: np.ndarray,
    jackknifed: np.ndarray,
    energy: np.ndarray,
    scratch: np.ndarray,
) -> bool:
    for j in range(z.shape[1]):
        if not math.isfinite(z[i, j]):
            return False
    b = settings[OBS_B]
    s_max = settings[OBS_S_MAX]
    speed_max = settings[OBS_SPEED_MAX]
    obs[i, 0] = z[i, 0]
    obs[i, 1] = z[i, 1]
    for k in range(n):
        obs[i, 2 + k] = math.sin(z[i, 2 + k])
        obs[i, 2 + n + k] = math.cos(z[i, 2 + k])
    row_margin = singular_margin_row(z[i], 2, n)
    folded = is_folded_row(z[i], 2, n, settings[OBS_FOLD])
    base = 2 + 2 * n
    if planar:
        obs[i, base] = (act[i, 0] - b) / s_max
        obs[i, base + 1] = act[i, 1] / s_max
        obs[i, base + 2] = min(max(act[i, 2] / speed_max, -1.0), 1.0)
        obs[i, base + 3] = min(max(act[i, 3] / speed_max, -1.0), 1.0)
    else:
        obs[i, base] = act[i, 1] / s_max
        obs[i, base + 1] = min(max(act[i, 3] / speed_max, -1.0), 1.0)
    margin[i] = row_margin
    cost[i] = 1.0 if row_margin < settings[OBS_BAND] else 0.0
    jackknifed[i] = folded
    energy[i] = energy_row(pv, z[i], n, act[i], scratch)
    return True


@cached_njit(depends_on=(actuator, fidelity))
def _observe_rows(
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    outputs: tuple,
    start: int,
    stop: int,
) -> int:
    """:func:`_observe_row` on ``rows[start:stop]``; returns how many were not finite."""
    obs, margin, cost, jackknifed, energy = outputs
    scratch = np.empty(max(n, 1))
    bad = 0
    for j in range(start, stop):
        if not _observe_row(
            rows[j], z, act, n, planar, settings, pv, obs, margin, cost, jackknifed, energy, scratch
        ):
            bad += 1
    return bad


@cached_njit(depends_on=(actuator, fidelity))
def observe(
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    obs: np.ndarray,
    margin: np.ndarray,
    cost: np.ndarray,
    jackknifed: np.ndarray,
    energy: np.ndarray,
) -> int:
    """Common observation, singular margin, cost, jackknife flag and energy of ``rows``.

    The margin and the jackknife test are :mod:`dynamics.jit`'s (as
    :func:`dynamics.singular_margin` and :func:`dynamics.is_jackknifed` define them);
    so is the energy. Returns the number of rows holding a non-finite value (they are
    left untouched).
    """
    outputs = (obs, margin, cost, jackknifed, energy)
    return _observe_rows(z, act, rows, n, planar, settings, pv, outputs, 0, rows.shape[0])


@cached_njit(depends_on=(actuator, fidelity), parallel=True)
def observe_parallel(
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    obs: np.ndarray,
    margin: np.ndarray,
    cost: np.ndarray,
    jackknifed: np.ndarray,
    energy: np.ndarray,
) -> int:
    """:func:`observe` over chunks of rows on all cores."""
    count = rows.shape[0]
    outputs = (obs, margin, cost, jackknifed, energy)
    bad = 0
    for chunk in prange((count + _CHUNK - 1) // _CHUNK):
        stop = min(count, (chunk + 1) * _CHUNK)
        bad += _observe_rows(z, act, rows, n, planar, settings, pv, outputs, chunk * _CHUNK, stop)
    return bad
