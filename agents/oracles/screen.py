"""Feasibility screen: the smallest rail stroke that recovers a start, by a linear programme.

Around a straight convoy at speed ``u`` the state ``x = (omega, alpha_1..alpha_n, s,
s_dot)`` obeys ``x_dot = A x + B s_ddot`` to first order
(:func:`trailer_env.controllers.linearise`, central differences of ``dynamics.rhs``).
Held over each control period ``dt`` (zero-order hold, as the env holds it), the
acceleration gives the exact discrete system ``x_{k+1} = Ad x_k + Bd a_k``
(:func:`discretise`).

A start is *recovered* within ``N`` steps when, at step ``N``, every unstable mode of
``Ad`` (``|lambda| > 1``) is zero and the mass is back at the centre of its rail and at
rest: from there, with the mass left alone, the linearised convoy decays to straight
along its stable modes and stays. :func:`minimal_stroke` finds the smallest stroke
``S`` for which some acceleration sequence with ``|a_k| <= accel_max``, ``|s_dot_k| <=
speed_max`` and ``|s_k| <= S`` at every step recovers the start: a linear programme in
``(a_0..a_{N-1}, S)`` solved by HiGHS (:func:`scipy.optimize.linprog`). The unstable
modes' conditions are written as ``w^T x_0 + sum_k lambda^-(k+1) w^T Bd a_k = 0`` (``w`` a
left eigenvector), which stays well conditioned however large ``lambda^N`` is.

The answer is a statement about the linearisation: a start whose minimal stroke exceeds
the rail's ``s_max`` (or that no stroke recovers within the horizon) is *not recoverable
under the linearisation*. The nonlinear convoy's growth is close to linear while the
angles stay small, so this flags the starts no controller is expected to save; it proves
nothing about the nonlinear model (the planner, :mod:`agents.oracles.planner`, does the converse:
a replayed safe episode is a proof of feasibility). The servo and the end-of-rail guard
are not modelled: the LP may use any acceleration within the bound, so it is optimistic
about servo mode.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from agents.oracles.rail import require_rail
from trailer_env.controllers import linearise
from trailer_env.settings import EnvSettings

#: Eigenvalues of Ad with modulus above 1 + this are unstable (the mass's double integrator
#: is a Jordan block at 1, which rounding splits by about sqrt(machine epsilon)).
UNSTABLE_TOLERANCE = 1e-6
#: Default horizon of the convoy screen, seconds.
DEFAULT_HORIZON = 10.0


@dataclass(frozen=True)
class ScreenResult:
    """The screen's answer for one start.

    Attributes:
        stroke: Smallest stroke S (m) that recovers the start within the horizon;
            ``inf`` when no stroke does (the speed and acceleration bounds forbid it).
        s_max: The rail's half-length the stroke is compared with.
        accelerations: The LP's acceleration sequence (N,) (empty when infeasible).
        unstable_eigenvalues: The unstable eigenvalues of Ad (complex).
    """

    stroke: float
    s_max: float
    accelerations: np.ndarray
    unstable_eigenvalues: np.ndarray

    @property
    def recoverable(self) -> bool:
        """Whether a finite stroke recovers the start and fits the rail (``stroke <= s_max``)."""
        return bool(np.isfinite(self.stroke) and self.stroke <= self.s_max)

    @property
    def stroke_fraction(self) -> float:
        """``stroke / s_max`` (``inf`` when not recoverable at any stroke)."""
        return self.stroke / self.s_max


def discretise(
    a_matrix: np.ndarray, b_matrix: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation ``(Ad, Bd)`` of ``x_dot = A x + B a``, period ``dt``."""
    if not (np.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be finite and > 0, got {dt!r}")
    a_matrix = np.asarray(a_matrix, dtype=np.float64)
    b_matrix = np.asarray(b_matrix, dtype=np.float64).reshape(a_matrix.shape[0], -1)
    size, inputs = b_matrix.shape
    augmented = np.zeros((size + inputs, size + inputs))
    augmented[:size, :size] = a_matrix
    augmented[:size, size:] = b_matrix
    exponential = scipy.linalg.expm(augmented * dt)
    return exponential[:size, :size], exponential[:size, size:]


def minimal_stroke(
    a_d: np.ndarray,
    b_d: np.ndarray,
    x0: np.ndarray,
    *,
    position: int,
    speed: int,
    speed_max: float,
    accel_max: float,
    steps: int,
    s_max: float = np.inf,
) -> ScreenResult:
    """Smallest stroke that brings the unstable modes of a discrete system to zero in ``steps``.

    Args:
        a_d, b_d: The discrete system ``x_{k+1} = a_d x_k + b_d a_k`` (``b_d`` one column,
            the mass's acceleration).
        x0: The start (length of ``a_d``).
        position, speed: Indices of the mass's position s and velocity s_dot in the state.
        speed_max, accel_max: Bounds on ``|s_dot_k|`` and ``|a_k|`` (> 0).
        steps: The horizon N >= 1 (steps of the system).
        s_max: The rail's half-length, only reported in the result (``recoverable``).

    Returns:
        The minimal stroke S over sequences with ``|a_k| <= accel_max``,
        ``|s_dot_k| <= speed_max`` and ``|s_k| <= S`` for k = 0..N, such that every
        unstable mode is zero at step N and ``s_N = s_dot_N = 0``; ``inf`` if none exists.

    Raises:
        ValueError: On mismatched shapes, a non-finite start or non-positive bounds.
    """
    a_d = np.asarray(a_d, dtype=np.float64)
    b_d = np.asarray(b_d, dtype=np.float64).reshape(-1)
    x0 = np.asarray(x0, dtype=np.float64).reshape(-1)
    _check_system(a_d, b_d, x0, position, speed, speed_max, accel_max, steps)
    eigenvalues = scipy.linalg.eigvals(a_d)
    unstable = np.abs(eigenvalues) > 1.0 + UNSTABLE_TOLERANCE
    rows, free = _mass_course(a_d, b_d, x0, (position, speed), steps)
    # Unknowns: a_0..a_{N-1}, S. Minimise S.
    cost = np.zeros(steps + 1)
    cost[-1] = 1.0
    upper_rows, upper_bounds = _stroke_and_speed_rows(rows, free, speed_max)
    equal_rows = [np.concatenate([rows[0, steps], [0.0]]), np.concatenate([rows[1, steps], [0.0]])]
    equal_bounds = [-free[0, steps], -free[1, steps]]
    if unstable.any():
        mode_rows, mode_bounds = _unstable_mode_rows(a_d, b_d, x0, steps)
        equal_rows += mode_rows
        equal_bounds += mode_bounds
    bounds = [(-accel_max, accel_max)] * steps + [(0.0, None)]
    solution = scipy.optimize.linprog(
        cost,
        A_ub=np.array(upper_rows),
        b_ub=np.array(upper_bounds),
        A_eq=np.array(equal_rows),
        b_eq=np.array(equal_bounds),
        bounds=bounds,
        method="highs",
    )
    if solution.status == 2:  # infeasible
        return ScreenResult(np.inf, float(s_max), np.zeros(0), eigenvalues[unstable])
    if solution.status != 0:
        raise RuntimeError(f"the screen's linear programme failed: {solution.message}")
    return ScreenResult(
        float(solution.x[-1]), float(s_max), solution.x[:-1].copy(), eigenvalues[unstable]
    )


def _check_system(
    a_d: np.ndarray,
    b_d: np.ndarray,
    x0: np.ndarray,
    position: int,
    speed: int,
    speed_max: float,
    accel_max: float,
    steps: int,
) -> None:
    """The checks of :func:`minimal_stroke`'s arguments (ValueError naming the bad one)."""
    size = a_d.shape[0]
    if a_d.shape != (size, size) or b_d.shape != (size,) or x0.shape != (size,):
        raise ValueError(f"shapes do not match: a_d {a_d.shape}, b_d {b_d.shape}, x0 {x0.shape}")
    if not np.all(np.isfinite(x0)):
        raise ValueError("x0 must be finite")
    if not (0 <= position < size and 0 <= speed < size):
        raise ValueError(f"position and speed must index the state (size {size})")
    if not (speed_max > 0.0 and accel_max > 0.0):
        raise ValueError("speed_max and accel_max must be > 0")
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"steps must be an integer >= 1, got {steps!r}")


def _mass_course(
    a_d: np.ndarray, b_d: np.ndarray, x0: np.ndarray, indices: tuple[int, int], steps: int
) -> tuple[np.ndarray, np.ndarray]:
    """The mass's position and speed at steps 0..N as affine functions of the inputs:
    ``(rows, free)``, (2, N + 1, N) and (2, N + 1), the value at step k being
    ``rows[:, k] @ a + free[:, k]``.

    x_k = a_d^k x0 + input_map_k a with input_map_k = a_d input_map_(k-1) + b_d e_(k-1)^T.
    """
    size = a_d.shape[0]
    selector = np.zeros((2, size))
    selector[0, indices[0]] = 1.0
    selector[1, indices[1]] = 1.0
    rows = np.zeros((2, steps + 1, steps))
    free = np.zeros((2, steps + 1))
    state = x0.copy()
    input_map = np.zeros((size, steps))
    free[:, 0] = selector @ state
    for k in range(1, steps + 1):
        input_map = a_d @ input_map
        input_map[:, k - 1] += b_d
        state = a_d @ state
        rows[:, k] = selector @ input_map
        free[:, k] = selector @ state
    return rows, free


def _stroke_and_speed_rows(
    rows: np.ndarray, free: np.ndarray, speed_max: float
) -> tuple[list[np.ndarray], list[float]]:
    """The inequality rows over (a_0..a_{N-1}, S): ``|s_k| <= S`` and
    ``|s_dot_k| <= speed_max`` for k = 0..N."""
    upper_rows = []
    upper_bounds = []
    for k in range(rows.shape[1]):
        # |s_k| <= S  ->  +-(rows a + free) - S <= 0
        for sign in (1.0, -1.0):
            upper_rows.append(np.concatenate([sign * rows[0, k], [-1.0]]))
            upper_bounds.append(-sign * free[0, k])
            upper_rows.append(np.concatenate([sign * rows[1, k], [0.0]]))
            upper_bounds.append(speed_max - sign * free[1, k])
    return upper_rows, upper_bounds


def _unstable_mode_rows(
    a_d: np.ndarray, b_d: np.ndarray, x0: np.ndarray, steps: int
) -> tuple[list[np.ndarray], list[float]]:
    """The equality rows over (a_0..a_{N-1}, S) that put every unstable mode at zero at
    step N, each row scaled to a largest coefficient of 1.

    The unstable left invariant subspace (repeated eigenvalues: identical trailers give
    Jordan blocks, where eigenvectors would miss directions): an ordered real Schur form
    of a_d^T, a_d^T U = U T11, unstable block first; U^T x_(k+1) = T11^T U^T x_k + U^T
    b_d a_k. The condition U^T x_N = 0, multiplied by T11^-N (transposed), reads
    U^T x0 + sum_k T11^-T(k+1) U^T b_d a_k = 0.
    """
    schur_form, basis, sorted_count = scipy.linalg.schur(
        a_d.T, output="real", sort=lambda re, im: np.hypot(re, im) > 1.0 + UNSTABLE_TOLERANCE
    )
    count = int(sorted_count)
    basis = basis[:, :count]
    inverse = np.linalg.inv(schur_form[:count, :count].T)
    coefficients = np.empty((count, steps))
    column = basis.T @ b_d
    for k in range(steps):
        column = inverse @ column
        coefficients[:, k] = column
    constant = basis.T @ x0
    equal_rows = []
    equal_bounds = []
    for row, value in zip(coefficients, constant, strict=True):
        scale = max(float(np.max(np.abs(row))), 1e-300)
        equal_rows.append(np.concatenate([row / scale, [0.0]]))
        equal_bounds.append(-float(value) / scale)
    return equal_rows, equal_bounds


def screen_start(
    settings: EnvSettings,
    z0: np.ndarray,
    *,
    s: float = 0.0,
    s_dot: float = 0.0,
    horizon: float = DEFAULT_HORIZON,
) -> ScreenResult:
    """The screen for a convoy start ``z0 = (u, omega, alpha_1..alpha_n)`` with the mass at ``s``.

    Linearised at the start's speed ``u`` (:func:`trailer_env.controllers.linearise`),
    discretised at ``settings.dt``, with the rail's speed bound ``settings.rail_speed_max``
    and acceleration bound ``settings.rail_accel_max``, over ``horizon`` seconds.

    Raises:
        ValueError: If the settings use the planar actuator, or on a bad start or horizon.
    """
    require_rail(settings, "the screen models")
    n = settings.n_trailers
    z0 = np.asarray(z0, dtype=np.float64).reshape(-1)
    if z0.shape[0] < n + 2:
        raise ValueError(f"z0 must hold (u, omega, alpha_1..alpha_{n}), got length {z0.shape[0]}")
    if not (np.isfinite(horizon) and horizon > 0.0):
        raise ValueError(f"horizon must be finite and > 0, got {horizon!r}")
    a_matrix, b_matrix = linearise(settings, float(z0[0]))
    a_d, b_d = discretise(a_matrix, b_matrix, settings.dt)
    x0 = np.concatenate([z0[1 : n + 2], [s, s_dot]])
    return minimal_stroke(
        a_d,
        b_d,
        x0,
        position=n + 1,
        speed=n + 2,
        speed_max=settings.rail_speed_max,
        accel_max=settings.rail_accel_max,
        steps=max(1, round(horizon / settings.dt)),
        s_max=settings.params.s_max,
    )


__all__ = ["DEFAULT_HORIZON", "ScreenResult", "discretise", "minimal_stroke", "screen_start"]
