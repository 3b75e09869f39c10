"""The block-vectorised kernels: sincos accuracy, and rows independent of their block."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from dynamics import ConvoyParams, Stepper, _kernel
from dynamics.jit import LANES, block_end, field_block, new_workspace


@njit  # not cached: a disk cache keyed on this file would miss edits to _kernel
def _sincos_all(x: np.ndarray) -> tuple:
    sin = np.empty_like(x)
    cos = np.empty_like(x)
    for i in range(x.shape[0]):
        sin[i], cos[i] = _kernel.sincos(x[i])
    return sin, cos


@njit  # not cached: a disk cache keyed on this file would miss edits to _kernel
def _sincos_all_block(x: np.ndarray) -> tuple:
    sin = np.empty_like(x)
    cos = np.empty_like(x)
    for start in range(0, x.shape[0], LANES):
        stop = min(x.shape[0], start + LANES)
        _kernel.sincos_block(x[start:stop], sin[start:stop], cos[start:stop], stop - start)
    return sin, cos


def test_sincos_matches_libm_to_one_ulp(rng: np.random.Generator) -> None:
    x = np.concatenate(
        [
            rng.uniform(-4.0, 4.0, 200_000),
            rng.uniform(-1e5, 1e5, 200_000),
            rng.uniform(-1e9, 1e9, 1000),  # beyond the reduction's range: libm
            np.pi / 4 * np.arange(-40, 41),
            [0.0, -0.0, 1e-300, -1e-300, 5e-324],
        ]
    )
    sin, cos = _sincos_all(x)
    assert np.max(np.abs(sin - np.sin(x))) <= 2.3e-16
    assert np.max(np.abs(cos - np.cos(x))) <= 2.3e-16
    block_sin, block_cos = _sincos_all_block(x)
    np.testing.assert_array_equal(block_sin, sin)
    np.testing.assert_array_equal(block_cos, cos)
    sin_nan, cos_nan = _sincos_all(np.array([np.nan, np.inf, -np.inf]))
    assert np.all(np.isnan(sin_nan)) and np.all(np.isnan(cos_nan))


@pytest.mark.parametrize(("n", "with_pose"), [(0, False), (1, True), (3, False), (9, True)])
def test_field_block_equals_field_row_bit_for_bit(
    rng: np.random.Generator, n: int, with_pose: bool
) -> None:
    params = ConvoyParams(n_trailers=n)
    width = n + (5 if with_pose else 2)
    count = 37  # a partial block: vector body and scalar remainder both used
    z = rng.normal(size=(count, width)) * 2.0
    act = rng.normal(size=(count, 6)) * 0.3
    rows = _kernel.rhs_batch(_kernel.pack_params(params), z, act, n, with_pose)  # field_row
    workspace = new_workspace(width)
    y, deriv, mass0 = workspace[0], workspace[2], workspace[4]
    y[:, :count] = z.T
    mass0[:, :count] = act.T
    field_block(
        _kernel.pack_params(params), y, n, with_pose, mass0, 0.0, deriv, workspace[5], count
    )
    np.testing.assert_array_equal(deriv[:, :count].T, rows)


@pytest.mark.parametrize("n", [0, 2, 5])
def test_a_row_steps_the_same_alone_in_any_batch_and_on_any_thread_count(
    rng: np.random.Generator, n: int
) -> None:
    params = ConvoyParams(n_trailers=n)
    count = 3 * LANES + 5
    z = np.zeros((count, n + 5))
    z[:, 0] = rng.uniform(-2.0, 2.0, count)
    z[:, 1] = rng.uniform(-0.5, 0.5, count)
    z[:, 2 : 2 + n] = rng.uniform(-1.0, 1.0, (count, n))
    act = np.zeros((count, 6))
    act[:, 0] = params.b
    act[:, 1:] = rng.uniform(-0.3, 0.3, (count, 5))
    substeps = rng.integers(1, 4, count)  # mixed counts: blocks are formed by count
    stepper = Stepper(params, with_pose=True)
    batch_z, batch_act = z.copy(), act.copy()
    stepper.step(batch_z, batch_act, 0.05, substeps)
    for i in (0, 1, LANES, count - 1):
        alone_z, alone_act = z[i : i + 1].copy(), act[i : i + 1].copy()
        stepper.step(alone_z, alone_act, 0.05, substeps[i : i + 1])
        np.testing.assert_array_equal(alone_z[0], batch_z[i])
        np.testing.assert_array_equal(alone_act[0], batch_act[i])
    serial_z, serial_act = z.copy(), act.copy()
    _kernel.rk4_batch_serial(
        _kernel.pack_params(params),
        serial_z,
        serial_act,
        n,
        True,
        0.05,
        substeps,
        False,
        np.full(count, np.nan),
    )
    np.testing.assert_array_equal(serial_z, batch_z)
    import numba

    before = numba.get_num_threads()
    try:
        results = []
        for threads in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
            numba.set_num_threads(threads)
            threaded_z, threaded_act = z.copy(), act.copy()
            _kernel.rk4_batch(
                _kernel.pack_params(params),
                threaded_z,
                threaded_act,
                n,
                True,
                0.05,
                substeps,
                False,
                np.full(count, np.nan),
            )
            results.append(threaded_z)
    finally:
        numba.set_num_threads(before)
    for threaded_z in results:
        np.testing.assert_array_equal(threaded_z, batch_z)


def test_energy_preserving_rows_step_the_same_alone_and_in_a_block(
    rng: np.random.Generator,
) -> None:
    params = ConvoyParams(n_trailers=3, mu=0.0)
    count = LANES + 3
    z = np.zeros((count, 5))
    z[:, 0] = rng.uniform(-2.0, 2.0, count)
    z[:, 1] = rng.uniform(-0.5, 0.5, count)
    z[:, 2:] = rng.uniform(-1.0, 1.0, (count, 3))
    act = np.zeros((count, 6))
    act[:, 0] = params.b
    stepper = Stepper(params, preserve_energy=True)
    batch_z, batch_act = z.copy(), act.copy()
    stepper.step(batch_z, batch_act, 0.05, np.full(count, 3))
    for i in (0, count - 1):
        alone_z, alone_act = z[i : i + 1].copy(), act[i : i + 1].copy()
        stepper.step(alone_z, alone_act, 0.05, np.full(1, 3))  # the row path
        np.testing.assert_array_equal(alone_z[0], batch_z[i])


def test_blocks_are_runs_of_equal_substeps_of_at_most_lanes_rows() -> None:
    """The grouping every batched RK4 driver shares (dynamics and trailer_env.kernels)."""
    substeps = np.array([1] * (LANES + 3) + [2, 2, 5], dtype=np.int64)
    order = np.arange(substeps.size)
    ends, first = [], 0
    while first < substeps.size:
        first = block_end(order, first, substeps.size, substeps)
        ends.append(first)
    assert ends == [LANES, LANES + 3, LANES + 5, LANES + 6]
    assert block_end(order, 0, 2, substeps) == 2  # never past ``stop``
