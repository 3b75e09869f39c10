"""Fixed-step integration over batches: classical RK4 and its energy-preserving variant.

The energy-preserving variant applies, after every RK4 substep, the exact
rescaling ``(u, omega) <- c (u, omega)`` that restores the initial energy. It
is exact because, at fixed alpha and with the mass at rest on the cart, E is a
positive-definite quadratic form in (u, omega) (physics.md section 4); so it
is offered only where the energy is conserved: ``mu = 0``, or a mass that does
not move relative to the cart.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dynamics import _kernel
from dynamics.columns import ACT_WIDTH, ETA, ETA_DOT, XI_DOT
from dynamics.jit import cached_njit
from dynamics.model import (
    FloatArray,
    check_state,
    finite_result,
    planar_actuator,
    rail_actuator,
)
from dynamics.params import ConvoyParams, bounded_integer, real_number

#: Largest substep count of one call, per row: 1e8 RK4 substeps of a short convoy take
#: about a minute; anything above is a mistake, not a request.
MAX_SUBSTEPS = 10**8


def _check_substeps(substeps: ArrayLike, batch_size: int) -> np.ndarray:
    if isinstance(substeps, (int, np.integer)) and not isinstance(substeps, (bool, np.bool_)):
        counts = np.full(batch_size, bounded_integer("substeps", substeps, 1, MAX_SUBSTEPS))
        return counts.astype(np.int64)
    if isinstance(substeps, (bool, np.bool_, str, bytes)) or substeps is None:
        raise TypeError(f"substeps must be integers, got {type(substeps).__name__} {substeps!r}")
    array = np.asarray(substeps)
    if array.dtype.kind not in "iuf":
        raise TypeError(f"substeps must be integers, got dtype {array.dtype}")
    if array.dtype.kind == "f" and not np.all(array == np.round(array)):
        raise ValueError(f"substeps must be integers, got {substeps!r}")
    if array.size and (np.any(array < 1) or np.any(array > MAX_SUBSTEPS)):
        raise ValueError(
            f"substeps must be >= 1 and <= {MAX_SUBSTEPS}, got min {array.min()!r}, "
            f"max {array.max()!r}"
        )
    try:
        counts = np.broadcast_to(array.astype(np.int64), (batch_size,)).copy()
    except ValueError:
        raise ValueError(
            f"substeps of shape {array.shape} does not match the batch size {batch_size}"
        ) from None
    return counts


def _check_dt(dt: float) -> float:
    value = real_number("dt", dt)
    if value <= 0.0:
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    return value


@cached_njit()
def _first_bad_count(substeps: np.ndarray, high: int) -> int:
    """Index of the first substep count outside [1, high], or -1."""
    for i in range(substeps.shape[0]):
        if substeps[i] < 1 or substeps[i] > high:
            return i
    return -1


def _counts_in_range(substeps: np.ndarray) -> bool:
    if substeps.shape[0] == 1:
        return bool(1 <= substeps[0] <= MAX_SUBSTEPS)
    return _first_bad_count(substeps, MAX_SUBSTEPS) < 0


_FLOAT64 = np.dtype(np.float64)
_INT64 = np.dtype(np.int64)


def _check_stepper_arguments(
    width: int,
    z: object,
    act: object,
    dt: object,
    substeps: object,
    target_energy: object,
) -> None:
    """Stepper.step's contract, checked in well under a microsecond (it runs in hot loops)."""
    if (
        type(z) is np.ndarray
        and type(act) is np.ndarray
        and type(substeps) is np.ndarray
        and z.dtype is _FLOAT64
        and act.dtype is _FLOAT64
        and substeps.dtype is _INT64
        and z.ndim == 2
        and z.shape[1] == width
        and act.shape == (z.shape[0], ACT_WIDTH)
        and substeps.shape == (z.shape[0],)
        and type(dt) is float
        and 0.0 < dt < math.inf
        and (
            target_energy is None
            or (type(target_energy) is np.ndarray and target_energy.shape == (z.shape[0],))
        )
    ) and _counts_in_range(substeps):
        return
    _explain_bad_stepper_arguments(width, z, act, dt, substeps, target_energy)


def _explain_bad_stepper_arguments(
    width: int,
    z: object,
    act: object,
    dt: object,
    substeps: object,
    target_energy: object,
) -> None:
    """Raise the TypeError or ValueError that says what is wrong with Stepper.step's arguments
    (the slow path: it returns when they are valid after all)."""
    for name, array in (("z", z), ("act", act)):
        if type(array) is not np.ndarray or array.dtype != np.float64:
            raise TypeError(
                f"{name} must be a float64 numpy array (it is updated in place), got "
                f"{getattr(array, 'dtype', type(array).__name__)}"
            )
    assert isinstance(z, np.ndarray) and isinstance(act, np.ndarray)
    rows = z.shape[0] if z.ndim == 2 else -1
    if z.ndim != 2 or z.shape[1] != width or act.shape != (rows, ACT_WIDTH):
        raise ValueError(
            f"expected z of shape (B, {width}) and act of shape (B, 6); "
            f"got {z.shape} and {act.shape}"
        )
    if type(substeps) is not np.ndarray or substeps.dtype != np.int64:
        raise TypeError(
            "substeps must be an int64 numpy array of shape (B,), got "
            f"{getattr(substeps, 'dtype', type(substeps).__name__)}"
        )
    if substeps.shape != (rows,):
        raise ValueError(f"substeps must have shape ({rows},), got {substeps.shape}")
    bad = _first_bad_count(substeps, MAX_SUBSTEPS)
    if bad >= 0:
        raise ValueError(
            f"substeps must be in [1, {MAX_SUBSTEPS}], got {substeps[bad]} at row {bad}"
        )
    _check_dt(dt)  # type: ignore[arg-type]
    if target_energy is not None and (
        type(target_energy) is not np.ndarray or target_energy.shape != (rows,)
    ):
        raise ValueError(
            f"target_energy must be a numpy array of shape ({rows},), got "
            f"{getattr(target_energy, 'shape', type(target_energy).__name__)}"
        )
    # Valid after all (e.g. an equal but distinct dtype object, or an int dt).


class Stepper:
    """In-place batched RK4 stepper for hot loops (environments, benchmarks).

    The parameters are validated and packed once; each :meth:`step` is one call
    into the jitted kernel, whatever the batch size. The kernel advances blocks of
    up to 64 rows of equal substep counts held as structure of arrays, so that the
    field vectorises across rows (``dynamics._kernel``); a row's result does not
    depend on the batch it is in, nor on the number of numba threads (batches of
    ``_kernel.PARALLEL_MIN_ROWS`` rows or more run on all of them).

    Args:
        params: Convoy parameters.
        with_pose: Whether rows carry the cart's pose (x, y, theta) after alpha.
        preserve_energy: Rescale (u, omega) after each substep to the energy at the
            start of the call (valid only while the mass is at rest on the cart).
    """

    #: The arrays of the last call whose types and shapes were checked.
    _checked_arrays: tuple[object, ...] = (None, None, None, None)

    def __init__(
        self, params: ConvoyParams, *, with_pose: bool = False, preserve_energy: bool = False
    ) -> None:
        self.params = params
        self.with_pose = with_pose
        self.preserve_energy = preserve_energy
        self.width = params.n_trailers + (5 if with_pose else 2)
        self._packed = _kernel.pack_params(params)

    def step(
        self,
        z: FloatArray,
        act: FloatArray,
        dt: float,
        substeps: np.ndarray,
        target_energy: FloatArray | None = None,
    ) -> None:
        """Advance ``z`` (B, width) and the mass state ``act`` (B, 6) by ``dt`` in place.

        ``act`` holds (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot); the
        accelerations are held over ``dt`` and the rest is updated exactly.
        ``substeps`` is an int64 array (B,) of counts in [1, 1e8] (:data:`MAX_SUBSTEPS`);
        ``z`` and ``act`` must be float64 arrays (they are updated in place, so nothing
        is converted). Types, shapes, ``dt`` and the counts are checked (TypeError,
        ValueError); values are trusted to be finite, and a non-finite result is left
        for the caller to detect (the environments retry such a step): callers validate
        at their boundary (see :func:`step_rk4`). With
        ``preserve_energy``, ``target_energy`` (B,) is the energy each row is held
        to; by default, its energy at the start of the call. Holding one target
        over a long run keeps rounding errors from accumulating call after call.
        """
        checked = self._checked_arrays
        if not (
            z is checked[0]
            and act is checked[1]
            and substeps is checked[2]
            and target_energy is checked[3]
            and type(dt) is float
            and 0.0 < dt < math.inf
            and _counts_in_range(substeps)
        ):
            _check_stepper_arguments(self.width, z, act, dt, substeps, target_energy)
            self._checked_arrays = (z, act, substeps, target_energy)
        if self.preserve_energy and self.params.mu > 0.0 and np.any(act[:, XI_DOT:] != 0.0):
            raise ValueError(
                "preserve_energy needs a conserved energy: mu = 0 or a mass at rest on the cart "
                "(xi_dot = eta_dot = xi_ddot = eta_ddot = 0)"
            )
        if target_energy is None:
            target_energy = np.full(z.shape[0], np.nan)
        kernel = (
            _kernel.rk4_batch
            if z.shape[0] >= _kernel.PARALLEL_MIN_ROWS
            else _kernel.rk4_batch_serial
        )
        kernel(
            self._packed,
            z,
            act,
            self.params.n_trailers,
            self.with_pose,
            dt,
            substeps,
            self.preserve_energy,
            target_energy,
        )


def _step(
    params: ConvoyParams,
    z: ArrayLike,
    dt: float,
    substeps: ArrayLike,
    act_of_shape: Callable[[tuple[int, ...]], FloatArray],
    preserve_energy: bool,
) -> tuple[FloatArray, FloatArray]:
    array, with_pose = check_state(params, z)
    batch_shape = array.shape[:-1]
    act = act_of_shape(batch_shape)
    rows = array.reshape(-1, array.shape[-1]).copy()
    counts = _check_substeps(substeps, rows.shape[0])
    Stepper(params, with_pose=with_pose, preserve_energy=preserve_energy).step(
        rows, act, _check_dt(dt), counts
    )
    finite_result("the RK4 step", rows, params.n_trailers)
    return rows.reshape(array.shape), act.reshape(*batch_shape, ACT_WIDTH)


def step_rk4(
    params: ConvoyParams,
    z: ArrayLike,
    dt: float,
    *,
    substeps: ArrayLike = 1,
    s: ArrayLike = 0.0,
    s_dot: ArrayLike = 0.0,
    s_ddot: ArrayLike = 0.0,
    preserve_energy: bool = False,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Advance states by ``dt`` with the mass on the rail under constant acceleration ``s_ddot``.

    Args:
        params: Convoy parameters.
        z: State ``(..., n+2)`` or extended state ``(..., n+5)``.
        dt: Time to advance, > 0.
        substeps: Number of equal RK4 substeps, scalar or one per state.
        s, s_dot: Mass position and velocity on the rail at the start.
        s_ddot: Mass acceleration, held constant over ``dt``.
        preserve_energy: Use the energy-preserving variant (mu = 0 or mass at rest).

    Returns:
        The new state, and the mass's position and velocity at the end.

    Raises:
        TypeError: If ``substeps`` or ``dt`` is not a number (bools and strings refused).
        ValueError: If ``dt`` is not finite and > 0, ``substeps`` is outside [1, 1e8] or
            does not fit the batch, or the state is invalid.
        FloatingPointError: If the step overflows from finite input, naming the component.

    Example:
        >>> p = ConvoyParams(n_trailers=2, mu=0.0)
        >>> z1, _, _ = step_rk4(p, [1.0, 0.1, 0.2, -0.1], 0.1, substeps=4)
        >>> z1.shape
        (4,)
    """
    z_new, act = _step(
        params,
        z,
        dt,
        substeps,
        lambda shape: rail_actuator(params, shape, s, s_dot, s_ddot),
        preserve_energy,
    )
    return z_new, act[..., ETA], act[..., ETA_DOT]


def step_rk4_planar(
    params: ConvoyParams,
    z: ArrayLike,
    dt: float,
    *,
    xi: ArrayLike,
    eta: ArrayLike,
    xi_dot: ArrayLike = 0.0,
    eta_dot: ArrayLike = 0.0,
    xi_ddot: ArrayLike = 0.0,
    eta_ddot: ArrayLike = 0.0,
    substeps: ArrayLike = 1,
    preserve_energy: bool = False,
) -> tuple[FloatArray, FloatArray]:
    """Like :func:`step_rk4` with the planar actuator.

    Returns:
        The new state and the mass state (..., 6): (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot).
    """
    return _step(
        params,
        z,
        dt,
        substeps,
        lambda shape: planar_actuator(shape, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot),
        preserve_energy,
    )


@dataclass(frozen=True)
class Trajectory:
    """A sampled solution: ``z[k]`` is the state at ``t[k]`` (leading batch axes follow time)."""

    t: FloatArray
    z: FloatArray
    s: FloatArray
    s_dot: FloatArray


#: Largest trajectory simulate returns, in float64 values (16 GiB).
MAX_TRAJECTORY_VALUES = 2**31


def _check_simulate_arguments(
    params: ConvoyParams, z0: ArrayLike, n_steps: object
) -> tuple[FloatArray, bool]:
    steps = bounded_integer("n_steps", n_steps, 0, MAX_TRAJECTORY_VALUES)
    array, with_pose = check_state(params, z0, "z0")
    if array.size == 0:
        raise ValueError(f"z0 holds no state (batch shape {array.shape[:-1]})")
    if (steps + 1) * array.size > MAX_TRAJECTORY_VALUES:
        raise ValueError(
            f"n_steps = {steps} for {array.size // array.shape[-1]} state(s) would return "
            f"{(steps + 1) * array.size:.3g} values, more than {MAX_TRAJECTORY_VALUES} (16 GiB)"
        )
    return array, with_pose


def simulate(
    params: ConvoyParams,
    z0: ArrayLike,
    dt: float,
    n_steps: int,
    *,
    substeps: int = 1,
    s0: ArrayLike = 0.0,
    s_dot0: ArrayLike = 0.0,
    s_ddot: ArrayLike = 0.0,
    preserve_energy: bool = False,
) -> Trajectory:
    """Integrate ``n_steps`` steps of length ``dt`` with a constant rail acceleration.

    Args:
        params: Convoy parameters.
        z0: Initial state, ``(..., n+2)`` or ``(..., n+5)`` with the pose.
        dt: Sampling interval.
        n_steps: Number of samples after the initial one.
        substeps: RK4 substeps per sample.
        s0, s_dot0, s_ddot: Rail state at t = 0 and its constant acceleration.
        preserve_energy: Use the energy-preserving variant.

    Returns:
        The trajectory sampled at ``t = 0, dt, ..., n_steps * dt``.

    Raises:
        TypeError: If an argument has the wrong type (e.g. ``n_steps`` a str or bool).
        ValueError: If ``n_steps`` is not an integer >= 0 (``inf`` included), ``z0`` is
            empty or invalid, or the trajectory would exceed 2**31 values.
        FloatingPointError: If the trajectory overflows from finite input, naming the
            component.
    """
    array, with_pose = _check_simulate_arguments(params, z0, n_steps)
    batch_shape = array.shape[:-1]
    act = rail_actuator(params, batch_shape, s0, s_dot0, s_ddot)
    rows = array.reshape(-1, array.shape[-1]).copy()
    counts = _check_substeps(substeps, rows.shape[0])
    stepper = Stepper(params, with_pose=with_pose, preserve_energy=preserve_energy)
    step = _check_dt(dt)
    target = (
        _kernel.energy_batch(stepper._packed, rows, act, params.n_trailers)
        if preserve_energy
        else None
    )
    states = np.empty((int(n_steps) + 1, *array.shape))
    rail = np.empty((int(n_steps) + 1, rows.shape[0], 2))
    states[0] = array
    rail[0] = act[:, [ETA, ETA_DOT]]
    for k in range(1, int(n_steps) + 1):
        stepper.step(rows, act, step, counts, target)
        states[k] = rows.reshape(array.shape)
        rail[k] = act[:, [ETA, ETA_DOT]]
    finite_result("simulate", states, params.n_trailers)
    times = step * np.arange(int(n_steps) + 1, dtype=np.float64)
    return Trajectory(
        t=times,
        z=states,
        s=rail[..., 0].reshape(-1, *batch_shape),
        s_dot=rail[..., 1].reshape(-1, *batch_shape),
    )
