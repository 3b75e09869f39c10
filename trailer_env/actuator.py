"""The moving-mass actuator: action modes, the position servo and the end-of-rail guard.

The mass moves on a rail of half-length ``s_max`` (physics.md section 9). Its
acceleration is what enters the dynamics; it is held constant over each control
period ``dt`` (zero-order hold), so within a period the mass's position is an
exact quadratic in time, which :class:`dynamics.Stepper` integrates exactly.

Action modes (``EnvSettings.action_mode``, one entry each in :data:`ACTUATORS`); actions
outside [-1, 1] are clipped:

* ``"servo"`` (default): the action ``a`` is a target position ``s* = a s_max``.
  A servo with natural frequency ``w = min(servo_bandwidth, 0.25 / dt)`` tracks
  it: desired velocity ``v* = sign(e) min(w |e|, sqrt(A |e|))`` for the error
  ``e = s* - s`` (linear near the target, a braking curve at half the bound far
  from it), acceleration ``4 w (v* - s_dot)`` (critically damped when linear),
  clipped to ``[-A, A]`` with ``A = rail_accel_max``, then passed through the guard.
* ``"accel"``: the action is the acceleration, ``a A``, through the same guard.
  The rail's ends act as hard stops enforced by the guard: the mass is braked
  early enough never to reach beyond them.
* ``"planar"``: a 2-D action, target ``(xi*, eta*) = (b + a_0 s_max, a_1 s_max)``
  in the square of half-width ``s_max`` around ``(b, 0)``; one servo and one guard per axis.

The guard. Let ``g(t) = s(t) + max(s_dot(t), 0)^2 / (2 A)``, the farthest point the
mass would reach braking at full rate. If ``g(0) <= s_max`` and the acceleration
``a`` in ``[-A, A]`` is held over ``[0, dt]``, then ``g`` is non-decreasing while
``s_dot > 0`` and equal to ``s`` (decreasing) while ``s_dot < 0``; so ``max g`` over
the period is ``g(dt)`` or the turning point ``s + s_dot^2 / (2|a|)``, both explicit
in ``a`` and both increasing in ``a``. The guard takes the largest admissible ``a``
(closed form, :func:`rail_accel_upper`) and the mirror image for the other end, so
``|s| <= s_max`` holds at every instant and the invariant carries over to the next
period. Both bounds are compatible whenever ``A dt^2 <= 2 s_max``; the settings
demand ``A dt^2 <= s_max``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from dynamics.columns import ETA, ETA_DDOT, ETA_DOT, XI, XI_DDOT, XI_DOT
from dynamics.jit import cached_njit

#: The action modes, the keys of :data:`ACTUATORS` in its order.
ActionMode = Literal["servo", "accel", "planar"]


@cached_njit()
def rail_accel_upper(s: float, v: float, s_max: float, accel_max: float, dt: float) -> float:
    """Largest acceleration in [-A, A] that keeps the mass able to stop before +s_max.

    Assumes the invariant ``s + max(v, 0)^2 / (2 A) <= s_max`` at the start.
    """
    room = s_max - s
    # Case "v(dt) >= 0": s(dt) + v(dt)^2 / (2A) <= s_max, a quadratic in a.
    qa = dt * dt / (2.0 * accel_max)
    qb = 0.5 * dt * dt + v * dt / accel_max
    qc = v * dt + v * v / (2.0 * accel_max) - room
    disc = qb * qb - 4.0 * qa * qc
    if disc >= 0.0:
        root = math.sqrt(disc)
        # The larger root, in the form that avoids cancellation.
        upper = -2.0 * qc / (qb + root) if qb > 0.0 else (-qb + root) / (2.0 * qa)
        if upper >= -v / dt:
            return max(min(upper, accel_max), -accel_max)
    if v > 0.0:
        # The mass turns within the period: its turning point s + v^2 / (2|a|) <= s_max.
        if room <= 0.0:
            return -accel_max
        return max(-v * v / (2.0 * room), -accel_max)
    # Unreachable in exact arithmetic (v <= 0 admits a = -v / dt); stopping is always safe.
    return min(-v / dt, accel_max)


@cached_njit()
def guard_accel(
    accel: float, s: float, v: float, s_max: float, accel_max: float, dt: float
) -> float:
    """Clip a desired acceleration to [-A, A] and to what keeps the mass on the rail."""
    upper = rail_accel_upper(s, v, s_max, accel_max, dt)
    lower = -rail_accel_upper(-s, -v, s_max, accel_max, dt)
    accel = min(max(accel, -accel_max), accel_max)
    return max(min(accel, upper), lower)


@cached_njit()
def servo_accel(
    target: float, s: float, v: float, s_max: float, accel_max: float, dt: float, frequency: float
) -> float:
    """The servo's guarded acceleration towards ``target`` (see the module docstring)."""
    error = target - s
    speed = min(frequency * abs(error), math.sqrt(accel_max * abs(error)))
    desired = math.copysign(speed, error)
    return guard_accel(4.0 * frequency * (desired - v), s, v, s_max, accel_max, dt)


def servo_target_for_accel(
    accel: np.ndarray, s: np.ndarray, v: np.ndarray, frequency: float
) -> np.ndarray:
    """The servo target whose linear law, ``4 w (w (target - s) - v)``, asks for ``accel``.

    The inverse of :func:`servo_accel` where it is linear (small errors, no clipping): what
    a controller that designs an acceleration commands in servo mode.
    """
    return s + (accel + 4.0 * frequency * v) / (4.0 * frequency**2)


# ----------------------------------------------------------------- the modes
# Each mode: a jitted row function writing act[i, XI_DDOT] and act[i, ETA_DDOT] from the
# finite action[i] (same arguments for every mode), the inverse a controller needs (an
# acceleration -> the action on the lateral axis), and an entry in ACTUATORS.


@cached_njit(nogil=True, inline="always")
def servo_row(
    action: np.ndarray,
    i: int,
    act: np.ndarray,
    b: float,
    s_max: float,
    accel_max: float,
    dt: float,
    frequency: float,
) -> None:
    """ "servo": the action is the target position ``a s_max`` on the rail."""
    command = min(max(action[i, 0], -1.0), 1.0)
    act[i, ETA_DDOT] = servo_accel(
        command * s_max, act[i, ETA], act[i, ETA_DOT], s_max, accel_max, dt, frequency
    )


@cached_njit(nogil=True, inline="always")
def accel_row(
    action: np.ndarray,
    i: int,
    act: np.ndarray,
    b: float,
    s_max: float,
    accel_max: float,
    dt: float,
    frequency: float,
) -> None:
    """ "accel": the action is the rail acceleration ``a A``, through the guard."""
    command = min(max(action[i, 0], -1.0), 1.0)
    act[i, ETA_DDOT] = guard_accel(
        command * accel_max, act[i, ETA], act[i, ETA_DOT], s_max, accel_max, dt
    )


@cached_njit(nogil=True, inline="always")
def planar_row(
    action: np.ndarray,
    i: int,
    act: np.ndarray,
    b: float,
    s_max: float,
    accel_max: float,
    dt: float,
    frequency: float,
) -> None:
    """ "planar": axis 0 is a target ``xi - b = a_0 s_max``, axis 1 ``eta = a_1 s_max``."""
    command = min(max(action[i, 0], -1.0), 1.0)
    act[i, XI_DDOT] = servo_accel(
        command * s_max, act[i, XI] - b, act[i, XI_DOT], s_max, accel_max, dt, frequency
    )
    lateral = min(max(action[i, 1], -1.0), 1.0)
    act[i, ETA_DDOT] = servo_accel(
        lateral * s_max, act[i, ETA], act[i, ETA_DOT], s_max, accel_max, dt, frequency
    )


def _servo_command(
    accel: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    s_max: float,
    accel_max: float,
    frequency: float,
) -> np.ndarray:
    return servo_target_for_accel(accel, s, v, frequency) / s_max


def _accel_command(
    accel: np.ndarray,
    s: np.ndarray,
    v: np.ndarray,
    s_max: float,
    accel_max: float,
    frequency: float,
) -> np.ndarray:
    return accel / accel_max


@dataclass(frozen=True)
class Actuator:
    """One action mode.

    Attributes:
        row: The jitted ``row(action, i, act, b, s_max, accel_max, dt, frequency)`` that
            writes the guarded accelerations of the finite ``action[i]`` into
            ``act[i, XI_DDOT]`` and ``act[i, ETA_DDOT]`` (:mod:`dynamics.columns`).
        command_for_accel: ``(accel, s, s_dot, s_max, accel_max, frequency) -> action``
            on the lateral axis for a wanted lateral acceleration (controllers).
        action_dim: The action's length.
        planar: Whether the mass moves in the cart's plane (both axes) rather than on the rail.
        mass_features: Observation entries that describe the mass (2 on the rail, 4 planar).
    """

    row: Callable[..., object]
    command_for_accel: Callable[..., np.ndarray]
    action_dim: int = 1
    planar: bool = False

    @property
    def mass_features(self) -> int:
        """Observation entries of the mass: (s, s_dot), or (xi, eta, xi_dot, eta_dot) planar."""
        return 4 if self.planar else 2

    @property
    def code(self) -> int:
        """Its integer in the compiled step: its position in :data:`ACTUATORS`."""
        return list(ACTUATORS.values()).index(self)


#: The one table of action modes (:data:`ActionMode`): name -> actuator. A new mode is a
#: row function (and its ``command_for_accel``), an entry here, and its line in
#: :func:`apply_action_row` (compiled code cannot look functions up in a dict).
ACTUATORS: dict[str, Actuator] = {
    "servo": Actuator(servo_row, _servo_command),
    "accel": Actuator(accel_row, _accel_command),
    "planar": Actuator(planar_row, _servo_command, action_dim=2, planar=True),
}

_SERVO = ACTUATORS["servo"].code
_ACCEL = ACTUATORS["accel"].code
_PLANAR = ACTUATORS["planar"].code


@cached_njit(nogil=True, inline="always")
def apply_action_row(
    action: np.ndarray,
    i: int,
    act: np.ndarray,
    mode: int,
    b: float,
    s_max: float,
    accel_max: float,
    dt: float,
    frequency: float,
) -> None:
    """The row function of the actuator whose code is ``mode`` (:data:`ACTUATORS`)."""
    if mode == _SERVO:
        servo_row(action, i, act, b, s_max, accel_max, dt, frequency)
    elif mode == _ACCEL:
        accel_row(action, i, act, b, s_max, accel_max, dt, frequency)
    elif mode == _PLANAR:
        planar_row(action, i, act, b, s_max, accel_max, dt, frequency)


@cached_njit(nogil=True)
def first_non_finite_row(action: np.ndarray, rows: np.ndarray) -> int:
    """The first of ``rows`` whose action holds NaN or inf, or -1."""
    for i in rows:
        for j in range(action.shape[1]):
            if not math.isfinite(action[i, j]):
                return i
    return -1


@cached_njit(nogil=True)
def clamp_row_to_rail(act: np.ndarray, i: int, b: float, s_max: float) -> None:
    """Remove rounding-level excursions past the rail's ends (the guard keeps them below 1e-15)."""
    act[i, ETA] = min(max(act[i, ETA], -s_max), s_max)
    act[i, XI] = min(max(act[i, XI], b - s_max), b + s_max)
