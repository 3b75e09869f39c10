"""Numba kernels of the batch core: ONE compiled call per control step for the whole batch.

:func:`step_serial` and :func:`step_parallel` run the whole physics pipeline of a control
step: the actuator (action -> guarded mass acceleration), the fidelity's auto substep
rule, a backup of the state, RK4 on blocks of rows (:mod:`dynamics.jit`'s block kernels,
the package's one implementation of the equations) with a fold test after every substep,
the rail guard, and the observation, singular margin, cost, jackknife flag and energy of
every row, computed on the block while it is still held as structure of arrays. A scene
whose reward and termination are array formulas adds them in its own small kernel that
calls :func:`step_serial` first (see :mod:`trailer_env.scenes.reverse`), so its whole
step stays one call; batches large enough for :func:`step_parallel` call the scene's
formulas in a second call (numba can crash loading from its disk cache a function that
calls a parallel one).

Scalar settings and arrays are packed once into the named tuples :class:`StepConfig`,
:class:`StepState` and :class:`StepOutputs` (see :class:`trailer_env.core.ConvoyCore`), so
a call crosses into compiled code with three arguments whatever the batch (the cost of
a call: benchmarks/README.md, "Figures quoted from the code"). Compiled code reads
their fields by name. Called from Python, the entry points (:func:`step_serial`,
:func:`step_parallel`, :func:`prepare_step`, :func:`observe` and the scenes' kernels)
take them either as the named tuples or as plain tuples of their fields,
``tuple(config)``, which is what the core passes: numba unboxes a plain tuple faster
than a named one (by how much: the same section of benchmarks/README.md), and
rebuilding the named tuple inside compiled code (``StepConfig(*config)``) costs
nothing. Large batches (``PARALLEL_MIN_ROWS`` rows or more, the threshold of
:mod:`dynamics.jit` that ``dynamics.Stepper`` uses too) use the parallel variant, which
splits the rows into chunks of ``ROWS_PER_CHUNK``. Either way rows are grouped into
blocks by ``dynamics.jit.block_end`` and advanced by ``dynamics.jit.advance_rows``,
the one RK4 driver that ``dynamics.Stepper`` uses too; every row's arithmetic is the
same whatever its block (the blocks share loops, not operations), so results do not
depend on the batch size or the number of threads.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from dynamics.columns import ALPHA, OMEGA, U
from dynamics.jit import (
    LANES,
    ROWS_PER_CHUNK,
    advance_rows,
    block_end,
    block_order,
    cached_njit,
    energy_block_from_trig,
    gather_block,
    gather_params,
    is_folded_row,
    new_workspace,
    params_scratch,
    row_params,
    sincos_block,
)
from dynamics.jit import PARALLEL_MIN_ROWS as PARALLEL_MIN_ROWS  # read here by the core
from trailer_env.actuator import apply_action_row, clamp_row_to_rail, first_non_finite_row
from trailer_env.substeps import AUTO_WORK_SUBSTEPS, auto_substeps_row, grew_absurdly_row

# Indices into the packed observation settings (OBS_BOUND: a row holding a value beyond it
# in magnitude is flagged as non-finite; infinite for resets, DIVERGENCE_BOUND for steps).
OBS_B, OBS_S_MAX, OBS_SPEED_MAX, OBS_BAND, OBS_FOLD, OBS_BOUND = range(6)
#: A step whose result holds a value beyond this in magnitude has diverged (u = 1e12 m/s
#: is far beyond any physical meaning; float32 observations and the energy ~ M u^2 stay
#: finite up to it): it is treated as a non-finite result (retried with more substeps,
#: then FloatingPointError). Hand-built states (resets) are not subject to it.
DIVERGENCE_BOUND = 1e12
#: The step kernels' first result when the auto rule's substeps exceed the work budget
#: (nothing was integrated).
OVER_BUDGET = -2


class StepConfig(NamedTuple):
    """The step kernel's settings, fixed for a core's life."""

    #: The actuator's kernel code (:data:`trailer_env.actuator.ACTUATORS`).
    mode: int
    b: float
    s_max: float
    accel_max: float
    dt: float
    #: The servo's natural frequency (rad/s).
    frequency: float
    #: Whether the auto substep rule runs (:mod:`trailer_env.substeps`).
    auto: bool
    #: The auto rule's packed settings (:func:`trailer_env.substeps.auto_settings`): one
    #: vector for every row, or one per row (B, 12) when the parameters are per row.
    auto_settings: np.ndarray
    #: The packed parameters (:func:`dynamics.jit.pack_params`): one vector (P,) for every
    #: row, or one per row (B, P) (randomised physics, :mod:`trailer_env.randomize`).
    pv: np.ndarray
    n: int
    with_pose: bool
    preserve_energy: bool
    planar: bool
    #: The observation settings (indices ``OBS_*``).
    obs_settings: np.ndarray


class StepState(NamedTuple):
    """The arrays a step advances (leading axis B), and its backup for a retry."""

    z: np.ndarray
    act: np.ndarray
    substeps: np.ndarray
    z_backup: np.ndarray
    act_backup: np.ndarray
    #: Energy targets of the energy-preserving RK4 (NaN: the energy at the call's start).
    target_energy: np.ndarray
    #: Rows whose last step's estimated error exceeded the tolerance.
    exceeded: np.ndarray


class StepOutputs(NamedTuple):
    """What a step or :func:`observe` derives from every row's state (leading axis B)."""

    obs: np.ndarray
    margin: np.ndarray
    cost: np.ndarray
    jackknifed: np.ndarray
    energy: np.ndarray
    #: Rows whose state holds a non-finite value (left untouched).
    nonfinite: np.ndarray
    #: sin(alpha_k) then cos(alpha_k), float64 (B, 2n), for the scenes' formulas.
    hitch_trig: np.ndarray


@cached_njit()
def observe_block(
    z: np.ndarray,
    rows: np.ndarray,
    nb: int,
    n: int,
    planar: bool,
    settings: np.ndarray,
    lane_pv: np.ndarray,
    outputs: StepOutputs,
    workspace: tuple,
    fold_checked: bool,
) -> int:
    """Observation, margin, cost, jackknife flag and energy of the gathered block ``rows[:nb]``.

    ``lane_pv`` is the block's parameters: the shared vector, or the rows' gathered
    (:func:`dynamics.jit.gather_params`).

    The workspace must hold ``z`` and ``act`` of those rows
    (:func:`dynamics.jit.gather_block`). ``jackknifed`` is OR-ed with the fold test at
    the current state (the step kernel clears it and latches folds between control
    instants before). The margin and the fold test are :func:`dynamics.singular_margin`'s
    and :func:`dynamics.is_jackknifed`'s; so is the energy. Rows holding a non-finite
    value are left untouched and flagged in ``nonfinite``; returns their number.
    ``outputs.hitch_trig`` (B, 2n) receives sin(alpha_k) then cos(alpha_k) in float64 (for
    the scenes' formulas). With ``fold_checked`` the current state's fold test is skipped:
    the step kernel's per-substep test has just done it.
    """
    obs = outputs.obs
    margin = outputs.margin
    cost = outputs.cost
    jackknifed = outputs.jackknifed
    energy = outputs.energy
    nonfinite = outputs.nonfinite
    hitch_trig = outputs.hitch_trig
    y, _, deriv, _, mass0, work, lane_scalars, trig, _ = workspace
    width = y.shape[0]
    finite = lane_scalars[2]
    limit = settings[OBS_BOUND]
    for lane in range(nb):
        finite[lane] = 0.0
    for j in range(width):
        for lane in range(nb):
            value = y[j, lane]
            # Stays 0 unless a value is NaN, infinite or beyond the bound.
            finite[lane] += value * 0.0 + (abs(value) > limit)
    for k in range(n):
        sincos_block(y[ALPHA + k], trig[k], trig[n + k], nb)
    energies = lane_scalars[0]
    energy_block_from_trig(lane_pv, y, n, mass0, trig, deriv, work, energies, nb)
    b = settings[OBS_B]
    s_max = settings[OBS_S_MAX]
    speed_max = settings[OBS_SPEED_MAX]
    band = settings[OBS_BAND]
    fold_angle = settings[OBS_FOLD]
    bad = 0
    base = 2 + 2 * n
    for lane in range(nb):
        i = rows[lane]
        if finite[lane] != 0.0:
            nonfinite[i] = True
            bad += 1
            continue
        nonfinite[i] = False
        obs[i, 0] = y[U, lane]
        obs[i, 1] = y[OMEGA, lane]
        row_margin = 1.0
        for k in range(n):
            sin_k = trig[k, lane]
            cos_k = trig[n + k, lane]
            hitch_trig[i, k] = sin_k
            hitch_trig[i, n + k] = cos_k
            obs[i, 2 + k] = sin_k
            obs[i, 2 + n + k] = cos_k
            if k < n - 1:
                row_margin = min(row_margin, abs(cos_k))
        if planar:
            obs[i, base] = (mass0[0, lane] - b) / s_max
            obs[i, base + 1] = mass0[1, lane] / s_max
            obs[i, base + 2] = min(max(mass0[2, lane] / speed_max, -1.0), 1.0)
            obs[i, base + 3] = min(max(mass0[3, lane] / speed_max, -1.0), 1.0)
        else:
            obs[i, base] = mass0[1, lane] / s_max
            obs[i, base + 1] = min(max(mass0[3, lane] / speed_max, -1.0), 1.0)
        margin[i] = row_margin
        cost[i] = 1.0 if row_margin < band else 0.0
        if not fold_checked:
            jackknifed[i] = jackknifed[i] or is_folded_row(z[i], 2, n, fold_angle)
        energy[i] = energies[lane]
    return bad


@cached_njit()
def _observe_rows(
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    start: int,
    stop: int,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    outputs: StepOutputs,
) -> int:
    workspace = new_workspace(z.shape[1])
    scratch = params_scratch(pv)
    jackknifed = outputs.jackknifed
    bad = 0
    for first in range(start, stop, LANES):
        block = rows[first : min(stop, first + LANES)]
        nb = block.shape[0]
        for lane in range(nb):
            jackknifed[block[lane]] = False
        gather_block(z, act, block, nb, workspace)
        lane_pv = gather_params(pv, block, nb, scratch)
        bad += observe_block(z, block, nb, n, planar, settings, lane_pv, outputs, workspace, False)
    return bad


@cached_njit()
def observe(
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    n: int,
    planar: bool,
    settings: np.ndarray,
    pv: np.ndarray,
    outputs: tuple,
) -> int:
    """:func:`observe_block` on ``rows`` (the state as it is: resets, states set by hand).

    ``outputs`` is a :class:`StepOutputs` or the plain tuple of its fields. Returns the
    number of rows holding a non-finite value (they are left untouched).
    """
    named = StepOutputs(*outputs)
    return _observe_rows(z, act, rows, 0, rows.shape[0], n, planar, settings, pv, named)


@cached_njit(nogil=True)
def _prepare_rows(
    action: np.ndarray,
    rows: np.ndarray,
    start: int,
    stop: int,
    config: StepConfig,
    state: StepState,
) -> tuple:
    """Rows ``rows[start:stop]``: guarded accelerations, the auto substep count and a backup
    of the state. Returns (rows over the tolerance: a cap binds, their substeps in all).

    The rows are prepared in this one loop, not by a function called per row: such a
    call copies the structs it is given, which cost a third of a vector step.
    """
    z, act, substeps = state.z, state.act, state.substeps
    exceeded, z_backup, act_backup = state.exceeded, state.z_backup, state.act_backup
    mode, b, s_max, accel_max = config.mode, config.b, config.s_max, config.accel_max
    dt, frequency, auto = config.dt, config.frequency, config.auto
    auto_settings = config.auto_settings
    over = 0
    total = 0
    for j in range(start, stop):
        i = rows[j]
        apply_action_row(action, i, act, mode, b, s_max, accel_max, dt, frequency)
        if auto:
            count, within = auto_substeps_row(z, act, row_params(auto_settings, i), i)
            substeps[i] = count
            exceeded[i] = not within
            over += not within
        for k in range(z.shape[1]):
            z_backup[i, k] = z[i, k]
        for k in range(6):
            act_backup[i, k] = act[i, k]
        total += substeps[i]
    return over, total


@cached_njit()
def _step_chunk(
    action: np.ndarray,
    rows: np.ndarray,
    start: int,
    stop: int,
    prepare: bool,
    config: StepConfig,
    state: StepState,
    outputs: StepOutputs,
) -> tuple:
    """The control step of ``rows[start:stop]``: (non-finite rows, rows over the tolerance)."""
    b = config.b
    s_max = config.s_max
    dt = config.dt
    pv = config.pv
    n = config.n
    with_pose = config.with_pose
    preserve_energy = config.preserve_energy
    z = state.z
    act = state.act
    substeps = state.substeps
    target_energy = state.target_energy
    jackknifed = outputs.jackknifed
    fold_angle = config.obs_settings[OBS_FOLD]
    over_tolerance = 0
    if prepare:
        over_tolerance, _ = _prepare_rows(action, rows, start, stop, config, state)
    for j in range(start, stop):
        jackknifed[rows[j]] = False
    # Blocks of equal substep counts, in a chunk-local order: per-row results do not
    # depend on the chunking.
    local = rows[start:stop]
    counts = np.empty(stop - start, dtype=np.int64)
    for j in range(stop - start):
        counts[j] = substeps[local[j]]
    order = local[block_order(counts)]
    workspace = new_workspace(z.shape[1])
    scratch = params_scratch(pv)
    bad = 0
    first = 0
    while first < order.shape[0]:
        count = substeps[order[first]]
        last = block_end(order, first, order.shape[0], substeps)
        block = order[first:last]
        nb = last - first
        lane_pv = advance_rows(
            pv,
            scratch,
            z,
            act,
            block,
            nb,
            n,
            with_pose,
            dt,
            count,
            preserve_energy,
            target_energy,
            fold_angle,
            jackknifed,
            workspace,
        )
        # The block holds the new state; only the mass's new position and velocity
        # (after the rail guard) are to be read back for the observations.
        mass0 = workspace[4]
        for lane in range(nb):
            i = block[lane]
            clamp_row_to_rail(act, i, b, s_max)
            for j in range(4):
                mass0[j, lane] = act[i, j]
        if config.auto:
            # A step the substep cap left inaccurate whose speed grew absurdly has diverged:
            # poisoned, it is reported as non-finite below (redone or refused by the core).
            y = workspace[0]
            for lane in range(nb):
                i = block[lane]
                settings = row_params(config.auto_settings, i)
                if state.exceeded[i] and grew_absurdly_row(z, state.z_backup, settings, i):
                    z[i, U] = np.nan
                    y[U, lane] = np.nan
        bad += observe_block(
            z,
            block,
            nb,
            n,
            config.planar,
            config.obs_settings,
            lane_pv,
            outputs,
            workspace,
            fold_angle < np.inf,
        )
        first = last
    return bad, over_tolerance


@cached_njit()
def step_serial(
    action: np.ndarray,
    rows: np.ndarray,
    prepare: bool,
    config: tuple,
    state: tuple,
    outputs: tuple,
) -> tuple:
    """One control step of ``rows`` on the calling thread.

    ``config``, ``state`` and ``outputs``: a :class:`StepConfig`, :class:`StepState` and
    :class:`StepOutputs`, or plain tuples of their fields (see the module docstring).
    With ``prepare``: actions -> guarded accelerations (clipped to [-1, 1]), the auto
    substep rule (``exceeded[i]`` set where a cap keeps the estimated error above the
    tolerance), a backup of the state; without (a retry): the accelerations and
    ``substeps`` as they are. Then RK4 with a fold test after every substep, the rail
    guard and the observations. Returns ``(bad action row or -1, non-finite rows, rows
    over the tolerance)``; on a bad action nothing is changed. With the auto rule, when
    the rows' substeps add up to more than its work budget
    (:data:`trailer_env.substeps.MAX_STEP_WORK` body-substeps), nothing is integrated
    and the first value is :data:`OVER_BUDGET` (the state is unchanged; the chosen
    counts are in ``substeps``).
    """
    named_config = StepConfig(*config)
    named_state = StepState(*state)
    over = 0
    if prepare:
        bad_action = first_non_finite_row(action, rows)
        if bad_action >= 0:
            return bad_action, 0, 0
        over, total = _prepare_rows(action, rows, 0, rows.shape[0], named_config, named_state)
        budget = row_params(named_config.auto_settings, 0)[AUTO_WORK_SUBSTEPS]  # same per row
        if named_config.auto and total > budget:
            return OVER_BUDGET, 0, over
    bad, _ = _step_chunk(
        action, rows, 0, rows.shape[0], False, named_config, named_state, StepOutputs(*outputs)
    )
    return -1, bad, over


@cached_njit()
def outcome_due(result: tuple) -> bool:
    """Whether a scene's outcome runs after a fused step that returned ``result``.

    Not when the step was refused (a bad action row, or :data:`OVER_BUDGET`) nor when a
    row diverged: the core redoes those rows, then runs the outcome once
    (:meth:`trailer_env.core.ConvoyCore.step`). A scene's fused step kernel is
    ``result = step_serial(...)``, then its outcome if this holds; it is written per
    scene (``reverse_step``, ``coast_step``) because a factory closing over the outcome,
    or the outcome passed as an argument, is recompiled in every process (numba's disk
    cache misses on both).
    """
    return result[0] == -1 and result[1] == 0


@cached_njit(parallel=True)
def step_parallel(
    action: np.ndarray,
    rows: np.ndarray,
    prepare: bool,
    config: tuple,
    state: tuple,
    outputs: tuple,
) -> tuple:
    """:func:`step_serial` over chunks of rows on numba's threads (the same results)."""
    named_config = StepConfig(*config)
    named_state = StepState(*state)
    named_outputs = StepOutputs(*outputs)
    count = rows.shape[0]
    n_chunks = (count + ROWS_PER_CHUNK - 1) // ROWS_PER_CHUNK
    bad = np.zeros(n_chunks, dtype=np.int64)
    over = np.zeros(n_chunks, dtype=np.int64)
    if prepare:
        bad_action = first_non_finite_row(action, rows)
        if bad_action >= 0:
            return bad_action, 0, 0
        total = np.zeros(n_chunks, dtype=np.int64)
        for chunk in prange(n_chunks):
            stop = min(count, (chunk + 1) * ROWS_PER_CHUNK)
            over[chunk], total[chunk] = _prepare_rows(
                action, rows, chunk * ROWS_PER_CHUNK, stop, named_config, named_state
            )
        budget = row_params(named_config.auto_settings, 0)[AUTO_WORK_SUBSTEPS]  # same per row
        if named_config.auto and total.sum() > budget:
            return OVER_BUDGET, 0, over.sum()
    for chunk in prange(n_chunks):
        stop = min(count, (chunk + 1) * ROWS_PER_CHUNK)
        bad[chunk], _ = _step_chunk(
            action,
            rows,
            chunk * ROWS_PER_CHUNK,
            stop,
            False,
            named_config,
            named_state,
            named_outputs,
        )
    return -1, bad.sum(), over.sum()


@cached_njit()
def prepare_step(action: np.ndarray, rows: np.ndarray, config: tuple, state: tuple) -> tuple:
    """The actuator, the auto rule and the backup alone (integrators outside this module).

    Returns ``(bad action row or -1, rows over the tolerance)``.
    """
    bad_action = first_non_finite_row(action, rows)
    if bad_action >= 0:
        return bad_action, 0
    over, _ = _prepare_rows(action, rows, 0, rows.shape[0], StepConfig(*config), StepState(*state))
    return -1, over


@cached_njit()
def clamp_rows_to_rail(act: np.ndarray, rows: np.ndarray, b: float, s_max: float) -> None:
    """:func:`trailer_env.actuator.clamp_row_to_rail` for ``rows``."""
    for i in rows:
        clamp_row_to_rail(act, i, b, s_max)
