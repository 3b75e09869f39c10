"""Reverse-v0: back the convoy up without folding it, steering only with the moving mass."""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar, NamedTuple

import numpy as np

from dynamics.columns import OMEGA, U
from dynamics.jit import cached_njit
from trailer_env.core import ConvoyCore
from trailer_env.env import ConvoyEnv
from trailer_env.kernels import StepOutputs, outcome_due, step_serial
from trailer_env.objective import Objective
from trailer_env.settings import EnvSettings

#: Starting speed range (reversing), m/s, and the half-widths of the starting perturbations.
SPEED_RANGE = (0.8, 1.2)
ANGLE_NOISE = 0.05
OMEGA_NOISE = 0.05
TURN_WEIGHT = 0.1


@cached_njit()
def reverse_failed(z: np.ndarray, jackknifed: np.ndarray, i: int, min_reverse_speed: float) -> bool:
    """Row ``i`` failed: jackknifed, or stopped reversing (``u >= -min_reverse_speed``)."""
    return jackknifed[i] or z[i, U] >= -min_reverse_speed


@cached_njit()
def reverse_failed_rows(
    z: np.ndarray,
    jackknifed: np.ndarray,
    rows: np.ndarray,
    min_reverse_speed: float,
    out: np.ndarray,
) -> None:
    """:func:`reverse_failed` of ``rows[j]`` into ``out[j]`` (the reset's success flag)."""
    for j in range(rows.shape[0]):
        out[j] = reverse_failed(z, jackknifed, rows[j], min_reverse_speed)


@cached_njit()
def reverse_rows(
    z: np.ndarray,
    hitch_trig: np.ndarray,
    rows: np.ndarray,
    n: int,
    cost: np.ndarray,
    jackknifed: np.ndarray,
    band_penalty: float,
    fold_penalty: float,
    min_reverse_speed: float,
    reward: np.ndarray,
    terminated: np.ndarray,
    success: np.ndarray,
) -> None:
    """Reward, termination and success of ``rows``: Reverse's formulas, row by row.

    ``hitch_trig`` holds the cosines of the hitch angles in columns n .. 2n-1
    (:attr:`trailer_env.core.ConvoyCore.hitch_trig`).
    """
    for i in rows:
        failed = reverse_failed(z, jackknifed, i, min_reverse_speed)
        straightness = 1.0
        if n > 0:
            total = 0.0
            for k in range(n):
                total += hitch_trig[i, n + k]
            straightness = total / n
        omega = z[i, OMEGA]
        value = straightness - TURN_WEIGHT * min(omega * omega, 1.0) - band_penalty * cost[i]
        if failed:
            value -= fold_penalty
        reward[i] = value
        terminated[i] = failed
        success[i] = not failed


class ReverseScene(NamedTuple):
    """What Reverse's formulas read and write besides the step's outputs."""

    z: np.ndarray
    n: int
    band_penalty: float
    fold_penalty: float
    min_reverse_speed: float
    reward: np.ndarray
    terminated: np.ndarray
    success: np.ndarray


@cached_njit()
def reverse_outcome(rows: np.ndarray, outputs: tuple, scene: tuple) -> None:
    """Reward, termination and success of ``rows`` after a step (:func:`reverse_rows`).

    ``outputs`` and ``scene``: :class:`~trailer_env.kernels.StepOutputs` and
    :class:`ReverseScene`, or plain tuples of their fields. Both the fused step
    (:func:`reverse_step`) and the unfused one (``fidelity="dopri5"``) call it.
    """
    step = StepOutputs(*outputs)
    task = ReverseScene(*scene)
    reverse_rows(
        task.z,
        step.hitch_trig,
        rows,
        task.n,
        step.cost,
        step.jackknifed,
        task.band_penalty,
        task.fold_penalty,
        task.min_reverse_speed,
        task.reward,
        task.terminated,
        task.success,
    )


@cached_njit()
def reverse_step(
    action: np.ndarray,
    rows: np.ndarray,
    prepare: bool,
    config: tuple,
    state: tuple,
    outputs: tuple,
    scene: tuple,
) -> tuple:
    """The control step of Reverse-v0 in one call: physics, then :func:`reverse_outcome`."""
    # One per scene: see trailer_env.kernels.outcome_due.
    result = step_serial(action, rows, prepare, config, state, outputs)
    if outcome_due(result):
        reverse_outcome(rows, outputs, scene)
    return result


class ReverseStart(NamedTuple):
    """Reverse-v0's start: (|u|, omega, alpha_1..alpha_n) = low + span * U[0, 1)^(n+2)."""

    low: np.ndarray
    span: np.ndarray


@cached_njit()
def reverse_starts(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    rows: np.ndarray,
    z: np.ndarray,
    start: tuple,
) -> None:
    """Row ``rows[j]``'s start from ``generators[picks[j]]`` (:class:`ReverseStart`): the
    numbers ``Generator.random(n + 2)`` draws, scaled, then the speed negated."""
    low, span = start
    for j in range(rows.size):
        rng = generators[picks[j]]
        i = rows[j]
        for k in range(low.size):
            z[i, k] = rng.random()
        for k in range(low.size):
            z[i, k] = z[i, k] * span[k] + low[k]
        z[i, U] = -z[i, U]  # reversing


class ReverseCore(ConvoyCore):
    """Batched task logic of Reverse-v0 (no task features, no pose)."""

    scene = "Reverse"
    objective = Objective.SURVIVAL
    max_episode_steps = 400
    headline_metric = "safe_rate"
    failure_words = "the convoy stopped reversing"
    #: The episode fails once the reversing speed -u is at most this (m/s).
    min_reverse_speed: ClassVar[float] = 0.0
    scene_kernel = staticmethod(reverse_step)
    scene_outcome = staticmethod(reverse_outcome)
    start_kernel = staticmethod(reverse_starts)

    def _scene_arguments(self) -> ReverseScene:
        return ReverseScene(
            z=self.z,
            n=self.n,
            band_penalty=float(self.band_penalty),
            fold_penalty=float(self.fold_penalty),
            min_reverse_speed=float(self.min_reverse_speed),
            reward=self.reward,
            terminated=self.terminated,
            success=self.success,
        )

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        super().__init__(settings, batch_size, track_pose=track_pose)
        n = self.n
        # The start (|u|, omega, alpha_1..alpha_n) = low + span * U[0, 1)^(n+2): one draw
        # per reset, the same numbers in the same order as uniform(low, high) per part.
        self._start_low = np.array([SPEED_RANGE[0], -OMEGA_NOISE] + [-ANGLE_NOISE] * n)
        self._start_span = np.array(
            [SPEED_RANGE[1] - SPEED_RANGE[0], OMEGA_NOISE - (-OMEGA_NOISE)]
            + [ANGLE_NOISE - (-ANGLE_NOISE)] * n
        )

    def _start_arguments(self) -> tuple:
        return ReverseStart(low=self._start_low, span=self._start_span)

    def _is_success(self) -> np.ndarray:
        # The reset's flag; after a step :func:`reverse_outcome` writes it.
        return self._starting_success(self._all_rows)

    def _starting_success(self, rows: np.ndarray) -> np.ndarray:
        failed = np.empty(rows.shape[0], dtype=bool)
        speed = float(self.min_reverse_speed)
        reverse_failed_rows(
            self.z, self.jackknifed, rows.astype(np.int64, copy=False), speed, failed
        )
        return ~failed


class ReverseEnv(ConvoyEnv):
    """Back a convoy of ``n`` trailers up without folding it, steering only with a moving mass.

    ## Description

    A cart pulls ``n_trailers`` trailers, each hitched to the axle midpoint of the body
    ahead by a rod of length ``l``; every axle's wheels forbid sideways slip. Nothing
    drives the wheels: the convoy coasts, its kinetic energy changed only by the one
    actuator, a point mass ``mu`` that the cart carries on a lateral rail ``b`` ahead of
    its axle (physics.md section 9). Moving the mass perturbs the cart's turning rate
    through the moving-mass term ``-mu b s_ddot``.

    The episode starts with the convoy nearly straight and moving backwards. A straight
    convoy reversing is an unstable node of the dynamics (physics.md section 7): the
    cart's turning rate and every hitch angle grow exponentially, at rates of about
    ``|u| / l``, which is why backing up a trailer is hard. Left alone the convoy folds
    (jackknifes) within about three seconds. The agent must keep every hitch angle
    small and out of the singular band (two consecutive bodies nearly perpendicular,
    physics.md section 10) for the whole episode. The actuator's authority is small: a
    full stroke of the mass turns the cart by about 0.5 rad, and only while the mass
    moves (see Heading-v0), so perturbations must be caught early. The linear
    controller of `trailer_env.controllers` keeps about two thirds of the two-trailer
    episodes from folding.

    ## Action Space

    `Box(-1, 1, (1,), float32)` by default (`action_mode="servo"`): the target position
    `s* = action * s_max` of the mass on its rail, tracked by a servo whose acceleration
    is bounded by `rail_accel_max` and guarded so that `|s| <= s_max` at every instant.
    `action_mode="accel"`: the action is the rail acceleration in units of
    `rail_accel_max` (same guard). `action_mode="planar"`: `Box(-1, 1, (2,))`, a target
    `(xi, eta) = (b + a_0 s_max, a_1 s_max)` for a mass free to move in the cart's plane.
    Out-of-range actions are clipped to [-1, 1]; NaN or infinite actions raise ValueError.
    See `trailer_env.actuator`.

    ## Observation Space

    `Box` of float32, length `2n + 4` (`2n + 6` in planar mode):

    | Index        | Observation                                      | Min  | Max |
    |--------------|--------------------------------------------------|------|-----|
    | 0            | u, forward speed of the cart's axle (m/s)        | -Inf | Inf |
    | 1            | omega, the cart's turning rate (rad/s)           | -Inf | Inf |
    | 2 .. n+1     | sin(alpha_k), hitch angle k = 1..n               | -1   | 1   |
    | n+2 .. 2n+1  | cos(alpha_k)                                     | -1   | 1   |
    | 2n+2         | s / s_max, the mass on its rail                  | -1   | 1   |
    | 2n+3         | s_dot / v_max, v_max = 2 sqrt(rail_accel_max s_max) | -1 | 1   |

    In planar mode indices 2n+2 .. 2n+5 are (xi - b) / s_max, eta / s_max,
    xi_dot / v_max, eta_dot / v_max. Reverse-v0 adds no task features.
    With `observe_params=True` seven more follow (length `2n + 11`): index `2n + 4 + k`
    is `log(value / nominal)` of M, J0, a, m, J, l, mu (k = 0..6; 0 when not
    randomised, and 0 for a parameter whose nominal value is 0, e.g. `mu=0.0`: a factor
    leaves it 0; bounds +-log(1000)). The other scenes append them after their task
    features.

    With `observation="trailers"` the same numbers come as a `Dict` whose shapes do not
    depend on n (`M = max_trailers`, default 8; `trailer_env.observation`), for policies
    with weights shared across trailers (`agents.policies.convoy_encoder`):

    | Key, index        | Observation                                  | Min  | Max |
    |-------------------|----------------------------------------------|------|-----|
    | `body[0]`         | u (flat index 0)                             | -Inf | Inf |
    | `body[1]`         | omega (flat index 1)                         | -Inf | Inf |
    | `body[2]`         | s / s_max (flat index 2n+2)                  | -1   | 1   |
    | `body[3]`         | s_dot / v_max (flat index 2n+3)              | -1   | 1   |
    | `body[4 ..]`      | flat index 2n+4 .. in order: task, parameters | as flat | as flat |
    | `trailers[k-1, 0]`| sin(alpha_k) for k <= n, 0 beyond (k = 1..M) | -1   | 1   |
    | `trailers[k-1, 1]`| cos(alpha_k) for k <= n, 0 beyond            | -1   | 1   |
    | `mask[k-1]`       | 1 for k <= n, 0 beyond                       | 0    | 1   |

    `body` has `2 + m + T + P` entries (m = 2 mass features, 4 in planar mode, where
    `body[2 .. 5]` are the planar mass's four; T task features, P = 7 with
    `observe_params`): `(4,)` here, `(11,)` with `observe_params`. It is the flat
    observation rearranged (no value is computed anew): row k-1 of `trailers` is trailer
    k counted from the cart, and a row of a mixed-n batch (`n_trailers=(low, high)`)
    equals the observation of `n_trailers=n` in the same state. `max_trailers` must be
    at least n (at least `high` with a range).

    ## Rewards

    Each step: `mean_k cos(alpha_k)` (1 when n = 0) `- 0.1 min(omega^2, 1)`
    `- 0.5 cost` (cost = 1 inside the singular band) `- 10` on the step that fails
    (jackknife, or the convoy stops reversing). A straight convoy earns about 1 per
    step, 400 over a full episode.

    ## Starting State

    `u ~ -U(0.8, 1.2)` m/s, `omega ~ U(-0.05, 0.05)` rad/s, each `alpha_k ~ U(-0.05, 0.05)`
    rad, the mass at rest at the centre of its rail.

    ## Episode End

    Terminated, as a failure, when the convoy jackknifes (any `|alpha_k| >= fold_angle`,
    default pi/2, physics.md section 10) or stops reversing (`u >= 0`: the mass can brake
    the convoy and push it forwards, where it is stable, which escapes the task rather
    than solving it). Truncated after 400 steps (20 s at the default `dt = 0.05`),
    by `gym.make`'s TimeLimit or by the vector env.

    ## Information

    `cost` (1.0 inside the singular band `singular_margin < singular_band`, default
    0.3, else 0.0, the safety-gymnasium convention), `singular_margin`
    (`min_(k<n) |cos alpha_k|`), `energy` (J, the mass included), `actuator_work`
    (J since the reset), `jackknifed`, `is_success` (still reversing, not jackknifed).
    With `randomize`, `params`: the episode's M, J0, a, m, J, l, mu (SI) and
    `speed_factor` (a dict; the native vector env gives a dict of (N,) arrays, the SB3
    adapter one dict per environment).

    `singular_margin` is `min_(k<n) |cos alpha_k|`: the hitches between consecutive
    bodies k <= n - 1, where the convoy's degree of nonholonomy drops. The last hitch
    `alpha_n` is not in it (a last trailer at a right angle counts only once it folds, at
    `fold_angle`), so with one trailer the margin is 1 and "safe" (never in the band,
    no failure) means "not folded and not stopped".

    ## Arguments

    ```python
    import gymnasium as gym
    import trailer_env
    env = gym.make("trailer_env/Reverse-v0", n_trailers=3, mu=0.4, dt=0.05,
                   fidelity="rk4", action_mode="servo", render_mode="rgb_array")
    ```

    The keywords of every scene (`trailer_env.settings.MAKE_KEYWORDS`, with their
    meanings in docs/generated/keywords.md) and `render_mode`. `n_trailers` may be a
    range `(low, high)`: every episode draws its n, or with `trailer_draw="row"` row i of
    a batch runs `low + i mod (high - low + 1)` (`trailer_env.mixed`). Every
    `dynamics.ConvoyParams` field is a keyword (its defaults: `mu = 0.5, b = 1.0,
    s_max = 0.5` for the actuator).
    `randomize` (None): per-episode factors of the nominal parameters, a dict such as
    `{"M": (0.8, 1.2), "mu": (0.9, 1.1), "speed": (0.5, 1.0)}` (any of M, J0, a, m, J,
    l, mu; `speed` scales the start's drawn u) or a preset (`"mismatch10"` ..
    `"mismatch40"`: +-10 .. 40 % on M, J0, a, l, mu; a scene that holds `l` fixed,
    Dock-v0, varies the other four), drawn uniformly after the start
    from the env's generator (`trailer_env.randomize`); bad ranges raise ValueError or
    TypeError naming the entry. `observe_params` (False): append the factors'
    logarithms to the observation. `observation` (`"flat"`): `"trailers"` for the Dict
    above; `max_trailers` (8 with `"trailers"`, an integer from n to 256; refused with
    `"flat"`). `history` (0): append the last k observations and applied actions, a
    memory from which a policy can tell the drawn parameters (`trailer_env.history`).

    ## References

    * `docs/physics.md` of this project (the model, sections 3-10).
    * A. Bravo-Doddoli, "Dinámica de un vehículo articulado de n remolques", thesis.
    * A. Bravo-Doddoli and L. C. García-Naranjo, "The dynamics of an articulated
      n-trailer vehicle", Regular and Chaotic Dynamics 20 (2015) 497-517.
    * J. M. Osborne and D. V. Zenkov, "Steering the Chaplygin sleigh by a moving mass",
      Proc. 44th IEEE CDC (2005): steering by a moving mass.
    """

    core_class = ReverseCore
