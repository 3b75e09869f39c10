"""Hand-designed baselines: an LQR from hitch angles, turning rate and mass to the servo.

:class:`LQRController` keeps the convoy straight (the Reverse-v0 and
Coast-v0 tasks; in Heading-v0 and Dock-v0 it only stabilises, ignoring the
task features). It reads the common part of any scene's observation and
returns an action for the settings' action mode. :func:`heading_policy` is a
proportional baseline for Heading-v0.

Design. Around a straight convoy moving at speed ``u`` the state
``x = (omega, alpha_1..alpha_n, s, s_dot)`` obeys ``x_dot = A(u) x + B(u) s_ddot``
to first order (``u`` itself changes only at second order). ``A`` and ``B``
are taken by central differences of :func:`dynamics.rhs`, the one
implementation of the equations; a linear-quadratic regulator (weights
``Q = diag(1, 10 I_n, 1, 0.1)``, ``R = 0.01``) gives ``s_ddot = -K(u) x``, with
``K`` computed on a grid of speeds for each direction and interpolated in
``|u|``. In servo mode the wanted acceleration is turned into the target
position that the servo's linear law maps back to it,
``s* = s + (s_ddot + 4 w s_dot) / (4 w^2)`` (:mod:`trailer_env.actuator`).
Saturation (the rail, the acceleration bound) is ignored by the design, so
large perturbations are lost; on Reverse-v0 with n = 2 it still keeps most
episodes from folding where the zero action folds them all.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg

from dynamics import rhs
from trailer_env.settings import EnvSettings

#: Speeds (m/s) at which the regulator is designed; gains are interpolated in between.
DESIGN_SPEEDS = np.array([0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0])
ANGLE_WEIGHT = 10.0
OMEGA_WEIGHT = 1.0
RAIL_WEIGHT = 1.0
RAIL_SPEED_WEIGHT = 0.1
ACCEL_WEIGHT = 0.01


def linearise(settings: EnvSettings, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """A, B of the straight convoy at forward speed ``speed`` (negative: reversing).

    The state is (omega, alpha_1..alpha_n, s, s_dot) and the input s_ddot.
    """
    params = settings.params
    n = params.n_trailers

    def field(x: np.ndarray, accel: float) -> np.ndarray:
        z = np.concatenate([[speed, x[0]], x[1 : 1 + n]])
        z_dot = rhs(params, z, x[1 + n], x[2 + n], accel)
        return np.concatenate([[z_dot[1]], z_dot[2:], [x[2 + n], accel]])

    size = n + 3
    step = 1e-6
    zero = np.zeros(size)
    columns = [
        (field(zero + step * e, 0.0) - field(zero - step * e, 0.0)) / (2 * step)
        for e in np.eye(size)
    ]
    a_matrix = np.column_stack(columns)
    b_matrix = ((field(zero, step) - field(zero, -step)) / (2 * step))[:, None]
    return a_matrix, b_matrix


def regulator(settings: EnvSettings, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """LQR gain K (n+3,) for ``s_ddot = -K x`` and the Riccati solution P (n+3, n+3) at
    ``speed``, so that ``x^T P x`` is the regulator's cost-to-go from ``x``; zeros if the
    design fails (mu = 0: the actuator has no authority)."""
    n = settings.n_trailers
    a_matrix, b_matrix = linearise(settings, speed)
    q = np.diag([OMEGA_WEIGHT] + [ANGLE_WEIGHT] * n + [RAIL_WEIGHT, RAIL_SPEED_WEIGHT])
    r = np.array([[ACCEL_WEIGHT]])
    try:
        p = scipy.linalg.solve_continuous_are(a_matrix, b_matrix, q, r)
    except (np.linalg.LinAlgError, ValueError):
        warnings.warn(f"no regulator at speed {speed}: the actuator has no authority", stacklevel=2)
        return np.zeros(n + 3), np.zeros((n + 3, n + 3))
    return np.linalg.solve(r, b_matrix.T @ p)[0], p


def regulator_gain(settings: EnvSettings, speed: float) -> np.ndarray:
    """LQR gain K (n+3,) for ``s_ddot = -K x`` at ``speed`` (:func:`regulator`)."""
    return regulator(settings, speed)[0]


class LQRController:
    """Linear state feedback (LQR on the linearised convoy) from observations to actions.

    Args:
        settings: The environment's settings (``env.unwrapped.settings``).

    Call it with one observation ``(obs_dim,)`` or a batch ``(B, obs_dim)``; it returns
    float32 actions ``(action_dim,)`` or ``(B, action_dim)`` in [-1, 1].
    """

    def __init__(self, settings: EnvSettings) -> None:
        self.settings = settings
        self.n = settings.n_trailers
        forward = [regulator(settings, speed) for speed in DESIGN_SPEEDS]
        reverse = [regulator(settings, -speed) for speed in DESIGN_SPEEDS]
        self.forward_gains = np.stack([gain for gain, _ in forward])
        self.reverse_gains = np.stack([gain for gain, _ in reverse])
        #: Riccati solutions per direction (reversing, forward) and design speed
        #: (2, S, n+3, n+3), for :meth:`cost_to_go`.
        self.cost_tables = np.stack(
            [np.stack([cost for _, cost in reverse]), np.stack([cost for _, cost in forward])]
        )

    @classmethod
    def from_env(cls, env: object) -> LQRController:
        """Build for a (possibly wrapped) single or vector environment of this package."""
        settings = getattr(getattr(env, "unwrapped", None), "settings", None)
        if not isinstance(settings, EnvSettings):
            raise TypeError(f"{type(env).__name__} is not an environment of trailer_env")
        return cls(settings)

    def gains(self, speed: np.ndarray) -> np.ndarray:
        """Interpolated gains (B, n+3) for forward speeds ``speed`` (B,)."""
        magnitude = np.clip(np.abs(speed), DESIGN_SPEEDS[0], DESIGN_SPEEDS[-1])
        out = np.empty((speed.shape[0], self.n + 3))
        for column in range(self.n + 3):
            forward = np.interp(magnitude, DESIGN_SPEEDS, self.forward_gains[:, column])
            reverse = np.interp(magnitude, DESIGN_SPEEDS, self.reverse_gains[:, column])
            out[:, column] = np.where(speed >= 0.0, forward, reverse)
        return out

    def regulator_state(self, obs: np.ndarray) -> np.ndarray:
        """The design's state ``x = (omega, alpha_1..alpha_n, s, s_dot)`` (B, n+3) of a batch
        of observations (B, obs_dim): the common part every scene's observation starts with."""
        settings = self.settings
        n = self.n
        batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        alpha = np.arctan2(batch[:, 2 : 2 + n], batch[:, 2 + n : 2 + 2 * n])
        planar = settings.actuator.planar
        lateral = 2 + 2 * n + (1 if planar else 0)
        lateral_speed = lateral + (2 if planar else 1)
        s = batch[:, lateral] * settings.params.s_max
        s_dot = batch[:, lateral_speed] * settings.rail_speed_max
        return np.column_stack([batch[:, 1], alpha, s, s_dot])

    def cost_to_go(self, obs: np.ndarray) -> np.ndarray:
        """``x^T P(u) x`` (B,) of a batch of observations: the regulator's quadratic cost-to-go
        from each state (the Riccati solution interpolated in ``|u|`` like the gains), large
        where the unstable modes are far from the straight convoy."""
        batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        state = self.regulator_state(batch)
        speed = batch[:, 0]
        # Whole matrices interpolated linearly, two gathers per batch: the gains' entry-by-entry
        # np.interp loop cost 13 steps of 64 convoys per call, a shaping wrapper's every step.
        magnitude = np.clip(np.abs(speed), DESIGN_SPEEDS[0], DESIGN_SPEEDS[-1])
        last = DESIGN_SPEEDS.size - 2
        left = np.minimum(np.searchsorted(DESIGN_SPEEDS, magnitude, side="right") - 1, last)
        weight = (magnitude - DESIGN_SPEEDS[left]) / (DESIGN_SPEEDS[left + 1] - DESIGN_SPEEDS[left])
        side = (speed >= 0.0).astype(np.intp)
        tables = self.cost_tables
        costs = (1.0 - weight)[:, None, None] * tables[side, left]
        costs += weight[:, None, None] * tables[side, left + 1]
        return np.einsum("bi,bij,bj->b", state, costs, state)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        settings = self.settings
        params = settings.params
        batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        state = self.regulator_state(batch)
        s, s_dot = state[:, -2], state[:, -1]
        accel = -np.sum(self.gains(batch[:, 0]) * state, axis=1)
        actuator = settings.actuator
        command = actuator.command_for_accel(
            accel, s, s_dot, params.s_max, settings.rail_accel_max, settings.servo_frequency
        )
        command = np.clip(command, -1.0, 1.0)
        planar = actuator.planar
        actions = np.column_stack([np.zeros_like(command), command]) if planar else command[:, None]
        actions = actions.astype(np.float32)
        return actions[0] if np.ndim(obs) == 1 else actions


def heading_policy(obs: np.ndarray, n_trailers: int = 2, gain: float = 8.0) -> np.ndarray:
    """A proportional baseline for Heading-v0 (servo mode): move the mass against the heading error.

    The servo target is ``s / s_max - gain * e`` for the heading error ``e`` (target minus
    heading, from the task features), so the mass keeps moving while an error remains:
    the only way to hold a heading offset (see HeadingEnv).
    """
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    base = 2 + 2 * n_trailers
    error = np.arctan2(batch[:, base + 2], batch[:, base + 3])
    actions = np.clip(batch[:, base] - gain * error, -1.0, 1.0)[:, None].astype(np.float32)
    return actions[0] if np.ndim(obs) == 1 else actions


__all__ = [
    "LQRController",
    "heading_policy",
    "linearise",
    "regulator",
    "regulator_gain",
]
