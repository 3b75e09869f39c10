"""Adaptive Dormand-Prince 5(4) over batches, with per-state error control.

Every row of a batch takes its own steps: a row near a singular configuration
shrinks its step without slowing the others down. The field is
:func:`dynamics._kernel.field_row`, the one implementation of the equations; this
module only adds the embedded Runge-Kutta pair (Dormand and Prince 1980, the
method behind MATLAB's ode45 and scipy's RK45) and its step-size controller
(Hairer, Norsett and Wanner, Solving ODEs I, section II.4).

Conventions are those of :mod:`dynamics.integrate`: a row is
``(u, omega, alpha_1..alpha_n)``, optionally followed by the pose ``(x, y,
theta)``; the moving mass's acceleration is held constant over one call, so
its position and velocity are exact quadratics in time and each stage sees
them exactly.

Two entry points:

* :func:`integrate_adaptive`: validated, shaped like :func:`dynamics.step_rk4`
  (the mass on its rail), optionally sampled at ``t_eval``.
* :class:`AdaptiveStepper`: in place over ``(B, width)`` rows and a ``(B, 6)``
  planar actuator, one jitted call per :meth:`AdaptiveStepper.step`, the step
  size of every row carried from one call to the next (hot loops).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from dynamics import _kernel
from dynamics.columns import ACT_WIDTH, ETA, ETA_DDOT, ETA_DOT, XI, XI_DDOT, XI_DOT
from dynamics.jit import cached_njit
from dynamics.model import FloatArray, check_state, rail_actuator
from dynamics.params import ConvoyParams

IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

STATUS_OK = 0
"""The row reached the end of the interval."""
STATUS_MAX_STEPS = 1
"""The row ran out of steps (``max_steps`` accepted plus rejected) first."""
STATUS_STEP_UNDERFLOW = 2
"""The step size fell below ``1e-12`` times the interval: the solution left the
region where the field is finite, or the tolerance is below what float64 can
deliver."""

# Butcher tableau of DOPRI5 (Dormand and Prince 1980). Stage 7 is evaluated at
# the new point with the 5th-order weights, so it is the next step's first stage
# (FSAL): six field evaluations per accepted step.
DP_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
DP_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1 / 5, 0.0, 0.0, 0.0, 0.0, 0.0],
        [3 / 40, 9 / 40, 0.0, 0.0, 0.0, 0.0],
        [44 / 45, -56 / 15, 32 / 9, 0.0, 0.0, 0.0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0.0, 0.0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0.0],
        [35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    ]
)
DP_B = np.array([35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0])
"""5th-order weights (the solution that is propagated: local extrapolation)."""
DP_B_HAT = np.array(
    [5179 / 57600, 0.0, 7571 / 16695, 393 / 640, -92097 / 339200, 187 / 2100, 1 / 40]
)
"""Embedded 4th-order weights; ``DP_B - DP_B_HAT`` estimates the local error."""
DP_E = DP_B - DP_B_HAT

_SAFETY = 0.9
_FAC_MIN = 0.2
_FAC_MAX = 10.0
_ERROR_EXPONENT = 0.2  # 1 / (q + 1) with q = 4, the order of the error estimate
_UNDERFLOW = 1e-12


@njit(nogil=True)
def _eval(
    pv: np.ndarray,
    y: np.ndarray,
    n: int,
    with_pose: bool,
    act: np.ndarray,
    tau: float,
    out: np.ndarray,
) -> None:
    """The field at time ``tau`` into the call: the mass's quadratic motion is evaluated exactly."""
    xi = act[XI] + act[XI_DOT] * tau + 0.5 * act[XI_DDOT] * tau * tau
    eta = act[ETA] + act[ETA_DOT] * tau + 0.5 * act[ETA_DDOT] * tau * tau
    _kernel.field_row(
        pv,
        y,
        n,
        with_pose,
        xi,
        eta,
        act[XI_DOT] + act[XI_DDOT] * tau,
        act[ETA_DOT] + act[ETA_DDOT] * tau,
        act[XI_DDOT],
        act[ETA_DDOT],
        out,
    )


@njit(nogil=True)
def _scaled_rms(
    delta: np.ndarray, y0: np.ndarray, y1: np.ndarray, rtol: float, atol: float
) -> float:
    """Hairer's norm: RMS of delta_j / (atol + rtol max(|y0_j|, |y1_j|))."""
    total = 0.0
    for j in range(delta.shape[0]):
        scale = atol + rtol * max(abs(y0[j]), abs(y1[j]))
        ratio = delta[j] / scale
        total += ratio * ratio
    return math.sqrt(total / delta.shape[0])


@njit(nogil=True)
def _initial_step(
    pv: np.ndarray,
    row: np.ndarray,
    n: int,
    with_pose: bool,
    act: np.ndarray,
    f0: np.ndarray,
    rtol: float,
    atol: float,
    probe: np.ndarray,
    f1: np.ndarray,
) -> float:
    """Hairer's starting step (Solving ODEs I, II.4): one extra field evaluation."""
    width = row.shape[0]
    d0 = _scaled_rms(row, row, row, rtol, atol)
    d1 = _scaled_rms(f0, row, row, rtol, atol)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    for j in range(width):
        probe[j] = row[j] + h0 * f0[j]
    _eval(pv, probe, n, with_pose, act, h0, f1)
    for j in range(width):
        f1[j] = (f1[j] - f0[j]) / h0
    d2 = _scaled_rms(f1, row, row, rtol, atol)
    largest = max(d1, d2)
    h1 = max(1e-6, 1e-3 * h0) if largest <= 1e-15 else (0.01 / largest) ** _ERROR_EXPONENT
    return min(100.0 * h0, h1)


@njit(nogil=True)
def _dopri_row(
    pv: np.ndarray,
    row: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    duration: float,
    rtol: float,
    atol: float,
    step_size: float,
    max_step: float,
    max_steps: int,
    k: np.ndarray,
    stage: np.ndarray,
    y_new: np.ndarray,
    delta: np.ndarray,
) -> tuple:
    """Advance one row by ``duration``.

    Returns:
        (next step size, accepted steps, rejected steps, field evaluations, status).
    """
    width = row.shape[0]
    _eval(pv, row, n, with_pose, act, 0.0, k[0])
    evaluations = 1
    h = step_size
    if not h > 0.0:
        h = _initial_step(pv, row, n, with_pose, act, k[0], rtol, atol, stage, delta)
        evaluations += 1
        if not h > 0.0 or h == math.inf:  # a non-finite field: let rejections shrink it
            h = duration
    h = min(h, max_step)
    t = 0.0
    accepted = 0
    rejected = 0
    status = 0
    previous_rejected = False
    while t < duration:
        if accepted + rejected >= max_steps:
            status = 1
            break
        proposed = h
        last = t + h >= duration * (1.0 - 1e-14)
        if last:
            h = duration - t
        # Stages 2..7; stage 7 (the new point) is also the next step's stage 1.
        for i in range(1, 7):
            for j in range(width):
                total = 0.0
                for p in range(i):
                    total += DP_A[i, p] * k[p, j]
                stage[j] = row[j] + h * total
            if i == 6:
                for j in range(width):
                    y_new[j] = stage[j]
            _eval(pv, stage, n, with_pose, act, t + DP_C[i] * h, k[i])
        evaluations += 6
        for j in range(width):
            total = 0.0
            for p in range(7):
                total += DP_E[p] * k[p, j]
            delta[j] = h * total
        error = _scaled_rms(delta, row, y_new, rtol, atol)
        if error <= 1.0:
            accepted += 1
            t = duration if last else t + h
            for j in range(width):
                row[j] = y_new[j]
                k[0, j] = k[6, j]
            if error == 0.0:
                factor = _FAC_MAX
            else:
                factor = min(_FAC_MAX, max(_FAC_MIN, _SAFETY * error**-_ERROR_EXPONENT))
            if previous_rejected:
                factor = min(factor, 1.0)
            h = min(h * factor, max_step)
            if last:
                # A step clipped to land on the end says little about the next one.
                h = max(h, min(proposed, max_step))
            previous_rejected = False
        else:
            rejected += 1
            if error == error:  # finite or inf; NaN compares false
                factor = max(_FAC_MIN, _SAFETY * error**-_ERROR_EXPONENT)
            else:
                factor = _FAC_MIN
            h *= factor
            previous_rejected = True
            if not h >= _UNDERFLOW * duration:  # also catches NaN
                status = 2
                break
    # The mass has moved for the time actually covered.
    act[XI] += act[XI_DOT] * t + 0.5 * act[XI_DDOT] * t * t
    act[ETA] += act[ETA_DOT] * t + 0.5 * act[ETA_DDOT] * t * t
    act[XI_DOT] += act[XI_DDOT] * t
    act[ETA_DOT] += act[ETA_DDOT] * t
    return h, accepted, rejected, evaluations, status


@cached_njit()
def dopri_batch(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    duration: float,
    rtol: float,
    atol: float,
    step_size: np.ndarray,
    max_step: float,
    max_steps: int,
    counts: np.ndarray,
    status: np.ndarray,
) -> None:
    """Advance every row of ``z`` and ``act`` in place by ``duration`` with DOPRI5.

    ``step_size`` (B,) holds each row's first trial step (<= 0: choose one) and
    receives the step to try next. ``counts`` (B, 3) receives accepted steps,
    rejected steps and field evaluations; ``status`` (B,) one of the STATUS_* codes.
    """
    width = z.shape[1]
    k = np.empty((7, width))
    buffers = np.empty((3, width))
    for i in range(z.shape[0]):
        h, accepted, rejected, evaluations, code = _dopri_row(
            pv,
            z[i],
            act[i],
            n,
            with_pose,
            duration,
            rtol,
            atol,
            step_size[i],
            max_step,
            max_steps,
            k,
            buffers[0],
            buffers[1],
            buffers[2],
        )
        step_size[i] = h
        counts[i, 0] = accepted
        counts[i, 1] = rejected
        counts[i, 2] = evaluations
        status[i] = code


@dataclass(frozen=True)
class AdaptiveStats:
    """What one :meth:`AdaptiveStepper.step` call did, per row (arrays of shape (B,))."""

    accepted: IntArray
    rejected: IntArray
    evaluations: IntArray
    """Field evaluations: 6 per step tried, 1 to start, 1 more when the first step is chosen."""
    status: IntArray
    """``STATUS_OK``, ``STATUS_MAX_STEPS`` or ``STATUS_STEP_UNDERFLOW``."""


def _check_tolerances(rtol: float, atol: float) -> tuple[float, float]:
    rtol_value, atol_value = float(rtol), float(atol)
    if (
        not (np.isfinite(rtol_value) and np.isfinite(atol_value))
        or rtol_value < 0.0
        or atol_value < 0.0
    ):
        raise ValueError(f"rtol and atol must be finite and >= 0, got rtol={rtol!r}, atol={atol!r}")
    if rtol_value == 0.0 and atol_value == 0.0:
        raise ValueError("rtol and atol cannot both be 0")
    return rtol_value, atol_value


class AdaptiveStepper:
    """In-place batched DOPRI5 for hot loops: the adaptive sibling of :class:`dynamics.Stepper`.

    Args:
        params: Convoy parameters.
        with_pose: Whether rows carry the cart's pose (x, y, theta) after alpha.
        rtol, atol: Per-component tolerances of Hairer's RMS error norm.
        max_step: Upper bound on any step (``inf``: none).
        max_steps: Steps (accepted plus rejected) a row may take per call before it gives up.
    """

    def __init__(
        self,
        params: ConvoyParams,
        *,
        with_pose: bool = False,
        rtol: float = 1e-6,
        atol: float = 1e-9,
        max_step: float = math.inf,
        max_steps: int = 100_000,
    ) -> None:
        self.params = params
        self.with_pose = with_pose
        self.rtol, self.atol = _check_tolerances(rtol, atol)
        if not max_step > 0.0:
            raise ValueError(f"max_step must be > 0, got {max_step!r}")
        if int(max_steps) != max_steps or max_steps < 1:
            raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
        self.max_step = float(max_step)
        self.max_steps = int(max_steps)
        self.width = params.n_trailers + (5 if with_pose else 2)
        self._packed = _kernel.pack_params(params)

    def step(
        self, z: FloatArray, act: FloatArray, dt: float, step_size: FloatArray
    ) -> AdaptiveStats:
        """Advance ``z`` (B, width) and the mass state ``act`` (B, 6) by ``dt`` in place.

        ``act`` holds (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot), accelerations
        held over ``dt``. ``step_size`` (B,) float64 is read as each row's first
        trial step (<= 0 lets the row choose) and overwritten with the step it
        should try next: pass the same array to the next call. A row that fails
        (see :class:`AdaptiveStats`) stops where it failed, its mass advanced to match.
        """
        rows = z.shape[0] if z.ndim == 2 else -1
        if (
            rows < 0
            or z.shape[1] != self.width
            or act.shape != (rows, ACT_WIDTH)
            or step_size.shape != (rows,)
        ):
            raise ValueError(
                f"expected z (B, {self.width}), act (B, 6) and step_size (B,); "
                f"got {z.shape}, {act.shape} and {step_size.shape}"
            )
        counts = np.empty((rows, 3), dtype=np.int64)
        status = np.empty(rows, dtype=np.int64)
        dopri_batch(
            self._packed,
            z,
            act,
            self.params.n_trailers,
            self.with_pose,
            float(dt),
            self.rtol,
            self.atol,
            step_size,
            self.max_step,
            self.max_steps,
            counts,
            status,
        )
        return AdaptiveStats(
            accepted=counts[:, 0], rejected=counts[:, 1], evaluations=counts[:, 2], status=status
        )


@dataclass(frozen=True)
class AdaptiveResult:
    """Outcome of :func:`integrate_adaptive`; per-state arrays have the batch shape of ``z0``.

    Attributes:
        z: State at the end (at the failure point for rows that did not succeed).
        s, s_dot: The mass's rail position and velocity at the end.
        accepted, rejected, evaluations: Steps taken and field evaluations, summed over the run.
        success: True where the row reached the end.
        status: The first failure code of the row (``STATUS_*``), ``STATUS_OK`` if none.
        last_step: The step size each row would try next.
        t: ``t_eval`` when given, else None.
        z_samples: States at ``t_eval``, shape ``(len(t_eval), *z0.shape)``, else None;
            after a row fails its later samples repeat the failure point.
    """

    z: FloatArray
    s: FloatArray
    s_dot: FloatArray
    accepted: IntArray
    rejected: IntArray
    evaluations: IntArray
    success: BoolArray
    status: IntArray
    last_step: FloatArray
    t: FloatArray | None = None
    z_samples: FloatArray | None = None


def _check_t_eval(t_eval: ArrayLike, duration: float) -> FloatArray:
    times = np.asarray(t_eval, dtype=np.float64)
    if times.ndim != 1 or times.size == 0:
        raise ValueError(f"t_eval must be a non-empty 1-D array, got shape {times.shape}")
    if (
        not np.all(np.isfinite(times))
        or times[0] < 0.0
        or times[-1] > duration
        or np.any(np.diff(times) < 0.0)
    ):
        raise ValueError(f"t_eval must be non-decreasing within [0, duration = {duration}]")
    return times


def integrate_adaptive(
    params: ConvoyParams,
    z0: ArrayLike,
    duration: float,
    *,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    s: ArrayLike = 0.0,
    s_dot: ArrayLike = 0.0,
    s_ddot: ArrayLike = 0.0,
    t_eval: ArrayLike | None = None,
    first_step: ArrayLike = 0.0,
    max_step: float = math.inf,
    max_steps: int = 100_000,
) -> AdaptiveResult:
    """Integrate states over ``[0, duration]`` with DOPRI5, each state under its own error control.

    Args:
        params: Convoy parameters.
        z0: State ``(..., n+2)`` or extended state ``(..., n+5)``; leading axes are a batch.
        duration: Time to advance, > 0.
        rtol, atol: Tolerances: each step keeps the RMS over components of
            ``error_j / (atol + rtol |z_j|)`` at most 1.
        s, s_dot: The mass's position and velocity on the rail at the start.
        s_ddot: The mass's acceleration, held constant over ``duration``.
        t_eval: Times at which to record the state (steps are shortened to land on them;
            no interpolation), or None.
        first_step: First trial step, scalar or per state; <= 0 chooses one (Hairer's rule).
        max_step: Upper bound on the step.
        max_steps: Steps (accepted plus rejected) a state may take per interval of ``t_eval``
            (per run without it).

    Returns:
        An :class:`AdaptiveResult`.

    Example:
        >>> p = ConvoyParams(n_trailers=2, mu=0.0)
        >>> result = integrate_adaptive(p, [1.0, 0.1, 0.2, -0.1], 2.0, rtol=1e-8)
        >>> bool(result.success), result.z.shape
        (True, (4,))
    """
    array, with_pose = check_state(params, z0, "z0")
    end = float(duration)
    if not np.isfinite(end) or end <= 0.0:
        raise ValueError(f"duration must be finite and > 0, got {duration!r}")
    stepper = AdaptiveStepper(
        params, with_pose=with_pose, rtol=rtol, atol=atol, max_step=max_step, max_steps=max_steps
    )
    batch_shape = array.shape[:-1]
    act = rail_actuator(params, batch_shape, s, s_dot, s_ddot)
    rows = array.reshape(-1, array.shape[-1]).copy()
    size = rows.shape[0]
    try:
        step_size = (
            np.broadcast_to(np.asarray(first_step, dtype=np.float64), batch_shape)
            .reshape(size)
            .copy()
        )
    except ValueError:
        raise ValueError(
            f"first_step does not broadcast to the batch shape {batch_shape}"
        ) from None
    step_size[~np.isfinite(step_size)] = 0.0

    times = None if t_eval is None else _check_t_eval(t_eval, end)
    boundaries = (
        np.concatenate([[0.0], times, [end]]) if times is not None else np.array([0.0, end])
    )
    totals = np.zeros((3, size), dtype=np.int64)
    status = np.zeros(size, dtype=np.int64)
    samples = None if times is None else np.empty((times.size, size, rows.shape[1]))
    active = np.ones(size, dtype=bool)
    for interval in range(boundaries.size - 1):
        span = boundaries[interval + 1] - boundaries[interval]
        if span > 0.0 and np.any(active):
            index = np.flatnonzero(active)
            if index.size == size:  # the usual case: step in place, no copies
                stats = stepper.step(rows, act, span, step_size)
            else:
                part_rows, part_act, part_h = rows[index], act[index], step_size[index]
                stats = stepper.step(part_rows, part_act, span, part_h)
                rows[index], act[index], step_size[index] = part_rows, part_act, part_h
            totals[0, index] += stats.accepted
            totals[1, index] += stats.rejected
            totals[2, index] += stats.evaluations
            failed = stats.status != STATUS_OK
            status[index[failed]] = stats.status[failed]
            active[index[failed]] = False
        if samples is not None and interval < samples.shape[0]:
            samples[interval] = rows
    return AdaptiveResult(
        z=rows.reshape(array.shape),
        s=act[:, ETA].reshape(batch_shape),
        s_dot=act[:, ETA_DOT].reshape(batch_shape),
        accepted=totals[0].reshape(batch_shape),
        rejected=totals[1].reshape(batch_shape),
        evaluations=totals[2].reshape(batch_shape),
        success=(status == STATUS_OK).reshape(batch_shape),
        status=status.reshape(batch_shape),
        last_step=step_size.reshape(batch_shape),
        t=times,
        z_samples=None if samples is None else samples.reshape(times.size, *array.shape),  # type: ignore[union-attr]
    )
