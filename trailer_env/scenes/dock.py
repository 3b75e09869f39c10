"""Dock-v0: reverse until the last trailer's axle reaches a target pose (the truck backer-upper)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dynamics import body_poses
from dynamics.columns import ALPHA, OMEGA, U, theta_column, x_column, y_column
from dynamics.jit import cached_njit
from trailer_env.core import MAX_TASK_MAGNITUDE, ShapedCore
from trailer_env.env import ConvoyEnv, real_array
from trailer_env.rendering import Marker
from trailer_env.scenes.heading import wrap_angle
from trailer_env.settings import EnvSettings

SPEED_RANGE = (0.8, 1.2)
ANGLE_NOISE = 0.05
OMEGA_NOISE = 0.05
#: The dock lies this far (m) behind the last axle's starting position ...
DISTANCE_RANGE = (4.0, 6.0)
#: ... this far to the side (m, either sign) and turned by up to this much (rad).
LATERAL_RANGE = 0.5
HEADING_RANGE = 0.05
#: Success: the last axle within this distance (m) of the dock, its heading within this (rad).
SUCCESS_RADIUS = 0.3
SUCCESS_HEADING = 0.15
#: Missed: the last axle more than this far (m) past the dock line.
MISS_DEPTH = 0.5
HEADING_WEIGHT = 1.0
#: Task features are distances divided by this (m).
DISTANCE_SCALE = 5.0


@cached_njit()
def dock_starts(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    rows: np.ndarray,
    z: np.ndarray,
    start: tuple,
) -> None:
    """Row ``rows[j]``'s start from ``generators[picks[j]]`` (``start`` = ``(n, l,
    target)``): speed, omega and hitch angles uniform in their ranges, then the dock's
    distance behind the last axle (the cart at the origin heading along x), lateral
    offset and heading. The last axle's x is :func:`dynamics.body_poses`' to the bit:
    ``-l sum_k cos(-(alpha_1 + ... + alpha_k))``, summed in the same order."""
    n, l, target = start
    for j in range(rows.size):
        rng = generators[picks[j]]
        i = rows[j]
        z[i, U] = -rng.uniform(SPEED_RANGE[0], SPEED_RANGE[1])
        z[i, OMEGA] = rng.uniform(-OMEGA_NOISE, OMEGA_NOISE)
        for k in range(n):
            z[i, ALPHA + k] = rng.uniform(-ANGLE_NOISE, ANGLE_NOISE)
        total_angle = 0.0
        rods = 0.0
        for k in range(n):
            total_angle += z[i, ALPHA + k]
            rods += np.cos(0.0 - total_angle)
        last_x = 0.0 - l * rods
        target[i, 0] = last_x - rng.uniform(DISTANCE_RANGE[0], DISTANCE_RANGE[1])
        target[i, 1] = rng.uniform(-LATERAL_RANGE, LATERAL_RANGE)
        target[i, 2] = rng.uniform(-HEADING_RANGE, HEADING_RANGE)


class DockCore(ShapedCore):
    """Batched task logic of Dock-v0; the only scene that tracks plane poses.

    Attributes:
        target: (B, 3) dock pose (x, y, heading) for the last trailer's axle midpoint.
        dock_xy: (B, 2) the last axle's position in the dock's frame (x along the
            dock heading, so the convoy arrives from x > 0 while reversing).
        dock_heading_error: (B,) last body's heading minus the dock heading, wrapped.
    """

    scene = "Dock"
    max_episode_steps = 400
    task_keys = ("target",)
    start_kernel = staticmethod(dock_starts)
    #: The hitch positions of the reward and the task features use one rod length.
    fixed_parameters = ("l",)
    failure_words = "a miss (the last axle ran past the dock)"
    uses_pose = True
    n_task_features = 4
    #: (x, y) in the dock's frame, sin and cos of the heading error.
    mirror_task_signs = (1.0, -1.0, -1.0, 1.0)
    # 400 steps * (0.01 + 0.05) = 24 < 30: neither folding nor missing on purpose pays.
    fold_penalty = 30.0
    failure_penalty = 30.0

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        super().__init__(settings, batch_size, track_pose=track_pose)
        self.target = np.zeros((self.batch_size, 3))
        self.dock_xy = np.zeros((self.batch_size, 2))
        self.dock_heading_error = np.zeros(self.batch_size)

    def last_body_pose(
        self, rows: slice | np.ndarray = slice(None)
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading) of the last body's axle midpoint (the cart's when n = 0) for ``rows``."""
        n = self.n
        z = self.z[rows]
        xs, ys, thetas = body_poses(
            self.params.l,
            z[:, x_column(n)],
            z[:, y_column(n)],
            z[:, theta_column(n)],
            z[:, ALPHA : ALPHA + n],
        )
        return xs[:, -1], ys[:, -1], thetas[:, -1]

    def _start_arguments(self) -> tuple[int, float, np.ndarray]:
        return (self.n, float(self.params.l), self.target)

    def check_task_value(self, key: str, value: object) -> np.ndarray:
        """``target`` = (x, y, heading) of the dock: 3 real numbers (not bools or strings),
        each within +-1e6 (m, m, rad; :data:`~trailer_env.core.MAX_TASK_MAGNITUDE`)."""
        target = real_array("target", value, "3 real numbers (x, y, heading)").astype(np.float64)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise ValueError(f"target must be 3 finite numbers (x, y, heading), got {value!r}")
        if np.max(np.abs(target)) > MAX_TASK_MAGNITUDE:
            raise ValueError(
                f"target must be within +-{MAX_TASK_MAGNITUDE:g} (x, y in m, heading in rad), "
                f"got {value!r}"
            )
        return target

    def render_markers(self, i: int) -> tuple[Marker, ...]:
        x, y, heading = (float(value) for value in self.target[i])
        return (Marker("pose", x, y, heading),)

    def render_view_size(self) -> float:
        # The picture is centred on the convoy: leave room for the farthest dock on either side.
        l = self.params.l
        return self.n * l + 2.0 * (DISTANCE_RANGE[1] + LATERAL_RANGE) + 2.0 * l

    def _task_feature_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([-np.inf, -np.inf, -1.0, -1.0]), np.array([np.inf, np.inf, 1.0, 1.0])

    def _update_task(self, rows: slice | np.ndarray) -> None:
        x, y, heading = self.last_body_pose(rows)
        target = self.target[rows]
        dx = x - target[:, 0]
        dy = y - target[:, 1]
        cos_dock = np.cos(target[:, 2])
        sin_dock = np.sin(target[:, 2])
        dock_xy = np.stack([cos_dock * dx + sin_dock * dy, -sin_dock * dx + cos_dock * dy], axis=1)
        error = wrap_angle(heading - target[:, 2])
        self.dock_xy[rows] = dock_xy
        self.dock_heading_error[rows] = error
        start = self.n_common
        self.obs[rows, start : start + 2] = dock_xy / DISTANCE_SCALE
        self.obs[rows, start + 2] = np.sin(error)
        self.obs[rows, start + 3] = np.cos(error)

    def dock_distance(self) -> np.ndarray:
        """Distance (m) from the last axle to the dock, (B,)."""
        return np.hypot(self.dock_xy[:, 0], self.dock_xy[:, 1])

    def _potential(self) -> np.ndarray:
        return -self.dock_distance() - HEADING_WEIGHT * np.abs(self.dock_heading_error)

    def _is_success(self) -> np.ndarray:
        return (self.dock_distance() < SUCCESS_RADIUS) & (
            np.abs(self.dock_heading_error) < SUCCESS_HEADING
        )

    def _is_failed(self) -> np.ndarray:
        return (self.dock_xy[:, 0] < -MISS_DEPTH) & ~self.success


class DockEnv(ConvoyEnv):
    """Reverse until the last trailer's axle reaches a dock: the n-trailer truck backer-upper.

    ## Description

    The convoy of Reverse-v0 (a cart, ``n_trailers`` trailers, no motor, one moving
    mass on a lateral rail of the cart; physics.md sections 1-10) starts nearly
    straight, reversing, the cart at the origin heading along x. A dock, a target pose
    (x, y, heading) for the axle midpoint of the last trailer (of the cart when n = 0),
    lies 4-6 m behind, up to 0.5 m to the side. The agent must keep the reversing
    convoy from folding (an unstable node, physics.md section 7) and steer it onto the
    dock, using only the moving mass: the n-trailer form of the truck backer-upper.

    This is the only scene that tracks plane poses: the cart's pose is integrated with
    the state and the trailers' poses follow from `dynamics.body_poses`.

    ## Action Space

    `Box(-1, 1, (1,), float32)` by default: the target position `s* = action * s_max` of
    the mass on its rail (servo with acceleration bound `rail_accel_max`, guarded so
    that `|s| <= s_max` at every instant). Other modes: `action_mode="accel"`,
    `"planar"`. Out-of-range actions are clipped; NaN or infinite ones raise ValueError.

    ## Observation Space

    `Box` of float32, length `2n + 8` (`2n + 10` in planar mode):

    | Index        | Observation                                      | Min  | Max |
    |--------------|--------------------------------------------------|------|-----|
    | 0            | u, forward speed of the cart's axle (m/s)        | -Inf | Inf |
    | 1            | omega, the cart's turning rate (rad/s)           | -Inf | Inf |
    | 2 .. n+1     | sin(alpha_k), hitch angle k = 1..n               | -1   | 1   |
    | n+2 .. 2n+1  | cos(alpha_k)                                     | -1   | 1   |
    | 2n+2         | s / s_max, the mass on its rail                  | -1   | 1   |
    | 2n+3         | s_dot / v_max, v_max = 2 sqrt(rail_accel_max s_max) | -1 | 1   |
    | 2n+4         | last axle's x in the dock frame / 5 m (along the dock heading) | -Inf | Inf |
    | 2n+5         | last axle's y in the dock frame / 5 m            | -Inf | Inf |
    | 2n+6         | sin(e), e = last body's heading - dock heading   | -1   | 1   |
    | 2n+7         | cos(e)                                           | -1   | 1   |

    In planar mode the actuator takes indices 2n+2 .. 2n+5 ((xi - b) / s_max,
    eta / s_max, xi_dot / v_max, eta_dot / v_max) and the task features follow.
    With `observation="trailers"` the same numbers come as a `Dict` of `body` (u, omega,
    then every entry from index 2n+2 on, in order), `trailers` (max_trailers, 2) and
    `mask`: the layout of Reverse-v0's docstring (`trailer_env.observation`).

    ## Rewards

    Potential-based: with `Phi = -d - |e|` (d the distance from the last axle to the
    dock, in m), each step earns `Phi(after) - Phi(before) - 0.01 - 0.05 cost`, plus
    `+10` on docking and `-30` on a jackknife or a missed dock. The per-step penalties
    over a full episode (at most 24) stay below either, so neither folding nor missing
    on purpose pays.

    ## Starting State

    `u ~ -U(0.8, 1.2)` m/s, `omega ~ U(-0.05, 0.05)` rad/s, each `alpha_k ~ U(-0.05, 0.05)`
    rad, the cart at the origin heading along x, the mass at rest at the centre of its
    rail. Dock: `U(4, 6)` m behind the last axle, `y ~ U(-0.5, 0.5)` m, heading
    `~ U(-0.05, 0.05)` rad.

    ## Episode End

    Terminated on docking (distance < 0.3 m and `|e| < 0.15` rad), on missing the dock
    (the last axle more than 0.5 m past the dock line), or on a jackknife (any
    `|alpha_k| >= fold_angle`, default pi/2). Truncated after 400 steps (20 s).

    ## Information

    `cost`, `singular_margin`, `energy`, `actuator_work`, `jackknifed`, `is_success` (docked).

    `singular_margin` is `min_(k<n) |cos alpha_k|`: the hitches between consecutive
    bodies k <= n - 1, where the convoy's degree of nonholonomy drops. The last hitch
    `alpha_n` is not in it (a last trailer at a right angle counts only once it folds, at
    `fold_angle`), so with one trailer the margin is 1 and "safe" (never in the band,
    no failure) means "not folded and not stopped".

    ## Arguments

    As Reverse-v0: the keywords of every scene (`trailer_env.settings.MAKE_KEYWORDS`,
    docs/generated/keywords.md) and `render_mode`. `set_state(z, target=(x, y, heading))`
    builds a state by hand (`z` may include the cart's pose). `randomize`,
    `observe_params` as Reverse-v0, but for `l`, which the hitch positions of the reward
    and the task features use as one value: the presets (`"mismatch10"`,
    `"mismatch20"`) keep it nominal and vary M, J0, a and mu; a dict of ranges that
    names `l` is refused.

    ## References

    * `docs/physics.md` of this project (section 2 for the poses).
    * D. Nguyen and B. Widrow, "The truck backer-upper: an example of self-learning in
      neural networks", IEEE Control Systems Magazine 10 (1990).
    * A. Bravo-Doddoli and L. C. García-Naranjo, "The dynamics of an articulated
      n-trailer vehicle", Regular and Chaotic Dynamics 20 (2015); A. Bravo-Doddoli's thesis.
    * J. M. Osborne and D. V. Zenkov, "Steering the Chaplygin sleigh by a moving mass",
      Proc. 44th IEEE CDC (2005).
    """

    core_class = DockCore
