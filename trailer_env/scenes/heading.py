"""Heading-v0: turn the coasting convoy to a target heading and hold it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dynamics.columns import ALPHA, OMEGA, U, x_column, y_column
from dynamics.jit import cached_njit
from dynamics.params import bounded_real
from trailer_env.core import MAX_TASK_MAGNITUDE, ShapedCore
from trailer_env.env import ConvoyEnv
from trailer_env.rendering import Marker
from trailer_env.settings import EnvSettings

SPEED_RANGE = (0.8, 1.2)
ANGLE_NOISE = 0.05
OMEGA_NOISE = 0.02
#: Range of |target heading| (rad); the sign is random. Small on purpose, see HeadingEnv.
TARGET_RANGE = (0.05, 0.15)
#: Success: |heading error| below this for HOLD_STEPS consecutive steps.
HEADING_TOLERANCE = 0.03
HOLD_STEPS = 20
HEADING_WEIGHT = 20.0


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


@cached_njit()
def heading_starts(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    rows: np.ndarray,
    z: np.ndarray,
    start: tuple,
) -> None:
    """Row ``rows[j]``'s start from ``generators[picks[j]]`` (``start`` = ``(n,
    target_heading)``): speed, omega and hitch angles uniform in their ranges, then the
    target heading's sign (1/2 each) and size."""
    n, target_heading = start
    for j in range(rows.size):
        rng = generators[picks[j]]
        i = rows[j]
        z[i, U] = rng.uniform(SPEED_RANGE[0], SPEED_RANGE[1])
        z[i, OMEGA] = rng.uniform(-OMEGA_NOISE, OMEGA_NOISE)
        for k in range(n):
            z[i, ALPHA + k] = rng.uniform(-ANGLE_NOISE, ANGLE_NOISE)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        target_heading[i] = sign * rng.uniform(TARGET_RANGE[0], TARGET_RANGE[1])


class HeadingCore(ShapedCore):
    """Batched task logic of Heading-v0.

    The cart's heading theta is integrated with the state (the Stepper's pose
    extension; x and y come along but are not used), the target heading is held
    per environment.
    """

    scene = "Heading"
    max_episode_steps = 300
    baselines = ("zero", "random", "lqr", "heading-p")
    task_keys = ("target_heading",)
    start_kernel = staticmethod(heading_starts)
    uses_pose = True
    n_task_features = 3
    #: sin and cos of the heading error, the hold fraction.
    mirror_task_signs = (-1.0, 1.0, 1.0)

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        super().__init__(settings, batch_size, track_pose=track_pose)
        self.target_heading = np.zeros(self.batch_size)
        self.hold_count = np.zeros(self.batch_size, dtype=np.int64)
        self.heading_error = np.zeros(self.batch_size)

    def _start_arguments(self) -> tuple[int, np.ndarray]:
        return (self.n, self.target_heading)

    def check_task_value(self, key: str, value: object) -> float:
        """``target_heading`` (rad), a real number (not a bool or a string) in [-1e6, 1e6]
        (:data:`~trailer_env.core.MAX_TASK_MAGNITUDE`)."""
        if isinstance(value, np.ndarray) and value.shape == ():
            value = value[()]
        bound = MAX_TASK_MAGNITUDE
        return bounded_real("target_heading", value, -bound, bound)

    def render_markers(self, i: int) -> tuple[Marker, ...]:
        n = self.n  # the arrow starts at the cart's axle midpoint
        x, y, heading = (
            float(self.z[i, x_column(n)]),
            float(self.z[i, y_column(n)]),
            self.target_heading[i],
        )
        return (Marker("arrow", x, y, float(heading)),)

    def _task_feature_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 1.0])

    def _update_task(self, rows: slice | np.ndarray) -> None:
        error = wrap_angle(self.target_heading[rows] - self.z[rows, self.n + 4])
        self.heading_error[rows] = error
        start = self.n_common
        self.obs[rows, start] = np.sin(error)
        self.obs[rows, start + 1] = np.cos(error)
        self.obs[rows, start + 2] = np.minimum(self.hold_count[rows], HOLD_STEPS) / HOLD_STEPS

    def _advance(self) -> None:
        holding = (np.abs(self.heading_error) < HEADING_TOLERANCE) & ~self.jackknifed
        self.hold_count[:] = np.where(holding, self.hold_count + 1, 0)
        self.obs[:, self.n_common + 2] = np.minimum(self.hold_count, HOLD_STEPS) / HOLD_STEPS

    def _after_reset(self, rows: np.ndarray) -> None:
        super()._after_reset(rows)
        self.hold_count[rows] = 0
        self.obs[rows, self.n_common + 2] = 0.0

    def _step_records(self) -> tuple[np.ndarray, ...]:
        return (*super()._step_records(), self.hold_count)

    def _potential(self) -> np.ndarray:
        return -HEADING_WEIGHT * np.abs(self.heading_error)

    def _is_success(self) -> np.ndarray:
        return self.hold_count >= HOLD_STEPS


class HeadingEnv(ConvoyEnv):
    """Turn a coasting convoy to a target heading and hold it, staying out of the singular band.

    ## Description

    The convoy of Reverse-v0 (a cart, ``n_trailers`` trailers, no motor, one moving
    mass on a lateral rail of the cart; physics.md sections 1-10) coasts forwards,
    nearly straight, the cart heading along x. The agent must turn the cart to a target
    heading and hold it there for 1 s, without passing near a singular configuration
    (two consecutive bodies nearly perpendicular, physics.md section 10) or folding.

    Why the targets are small (0.05-0.15 rad). The rail equations of physics.md
    section 9 give exactly

        d/dt [ (I0 + mu (b^2 + s^2)) omega + mu b s_dot ] = -(M a + mu b) u omega + mu s u_dot,

    so, while the speed u changes little, `I_eff omega + mu b s_dot + (M a + mu b) u theta`
    is conserved: whenever the cart stops turning and the mass stops moving, the heading
    returns to where it started. A heading offset lasts only while the mass keeps moving
    along its rail (an offset e needs `s_dot ~ (M a + mu b) u e / (mu b)`, about 0.2 m/s
    for e = 0.1 rad with the defaults); the speed-dependent term `mu s u_dot` moves the
    steady heading by only about `mu s_max / (M a + mu b)`, 0.25 rad, per e-fold of
    speed. Large turns are therefore out of reach of the moving mass, and holding a
    small one is a timing task: the proportional baseline
    `trailer_env.controllers.heading_policy` succeeds in most episodes (docs/results.md),
    the zero action never.

    The cart's heading is integrated with the state (the pose extension of
    `dynamics.Stepper`); the planar position is not used by this task.

    ## Action Space

    `Box(-1, 1, (1,), float32)` by default: the target position `s* = action * s_max` of
    the mass on its rail (servo with acceleration bound `rail_accel_max`, guarded so
    that `|s| <= s_max` at every instant). Other modes: `action_mode="accel"`,
    `"planar"`. Out-of-range actions are clipped; NaN or infinite ones raise ValueError.

    ## Observation Space

    `Box` of float32, length `2n + 7` (`2n + 9` in planar mode):

    | Index        | Observation                                      | Min  | Max |
    |--------------|--------------------------------------------------|------|-----|
    | 0            | u, forward speed of the cart's axle (m/s)        | -Inf | Inf |
    | 1            | omega, the cart's turning rate (rad/s)           | -Inf | Inf |
    | 2 .. n+1     | sin(alpha_k), hitch angle k = 1..n               | -1   | 1   |
    | n+2 .. 2n+1  | cos(alpha_k)                                     | -1   | 1   |
    | 2n+2         | s / s_max, the mass on its rail                  | -1   | 1   |
    | 2n+3         | s_dot / v_max, v_max = 2 sqrt(rail_accel_max s_max) | -1 | 1   |
    | 2n+4         | sin(e), e = target heading - cart heading, wrapped | -1 | 1   |
    | 2n+5         | cos(e)                                           | -1   | 1   |
    | 2n+6         | hold progress: steps held within tolerance / 20  | 0    | 1   |

    In planar mode the actuator takes indices 2n+2 .. 2n+5 ((xi - b) / s_max,
    eta / s_max, xi_dot / v_max, eta_dot / v_max) and the task features follow.
    With `observation="trailers"` the same numbers come as a `Dict` of `body` (u, omega,
    then every entry from index 2n+2 on, in order), `trailers` (max_trailers, 2) and
    `mask`: the layout of Reverse-v0's docstring (`trailer_env.observation`).

    ## Rewards

    Potential-based: with `Phi = -20 |e|`, each step earns
    `Phi(after) - Phi(before) - 0.01 - 0.05 cost`, plus `+10` on success and `-20`
    when the convoy jackknifes. The per-step penalties over a full episode (at most 18)
    stay below the fold penalty, so folding on purpose never pays.

    ## Starting State

    `u ~ U(0.8, 1.2)` m/s forwards, `omega ~ U(-0.02, 0.02)` rad/s, each
    `alpha_k ~ U(-0.05, 0.05)` rad, the cart at the origin heading along x, the mass at
    rest at the centre of its rail; target heading `±U(0.05, 0.15)` rad.

    ## Episode End

    Terminated on success, `|e| < 0.03` rad for 20 consecutive steps (1 s at
    `dt = 0.05`), or on a jackknife (any `|alpha_k| >= fold_angle`, default pi/2).
    Truncated after 300 steps (15 s).

    ## Information

    `cost`, `singular_margin`, `energy`, `actuator_work`, `jackknifed`, `is_success`.

    `singular_margin` is `min_(k<n) |cos alpha_k|`: the hitches between consecutive
    bodies k <= n - 1, where the convoy's degree of nonholonomy drops. The last hitch
    `alpha_n` is not in it (a last trailer at a right angle counts only once it folds, at
    `fold_angle`), so with one trailer the margin is 1 and "safe" (never in the band,
    no failure) means "not folded and not stopped".

    ## Arguments

    As Reverse-v0: the keywords of every scene (`trailer_env.settings.MAKE_KEYWORDS`,
    docs/generated/keywords.md) and `render_mode`. `set_state(z, target_heading=...)`
    builds a state by hand.

    ## References

    * `docs/physics.md` of this project.
    * A. Bravo-Doddoli and L. C. García-Naranjo, "The dynamics of an articulated
      n-trailer vehicle", Regular and Chaotic Dynamics 20 (2015); A. Bravo-Doddoli's thesis.
    * J. M. Osborne and D. V. Zenkov, "Steering the Chaplygin sleigh by a moving mass",
      Proc. 44th IEEE CDC (2005).
    """

    core_class = HeadingCore
