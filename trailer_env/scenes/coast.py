"""Coast-v0: from a random coasting state, straighten the convoy without nearing a singularity."""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from dynamics.columns import ALPHA, OMEGA, U
from dynamics.jit import cached_njit
from trailer_env.core import ShapedCore
from trailer_env.env import ConvoyEnv
from trailer_env.kernels import StepOutputs, outcome_due, step_serial
from trailer_env.shaping import shaped_reward

SPEED_RANGE = (0.5, 1.5)
#: Half-widths of the starting hitch angles and turning rate, forwards and backwards.
#: Backwards the straight convoy is unstable and the moving mass recovers only small
#: deviations (see Reverse-v0), so the backward range is smaller.
FORWARD_ANGLE_RANGE = 0.5
FORWARD_OMEGA_RANGE = 0.2
REVERSE_ANGLE_RANGE = 0.1
REVERSE_OMEGA_RANGE = 0.05
#: Straight: every |alpha_k| and |omega| below these.
SUCCESS_ANGLE = 0.05
SUCCESS_OMEGA = 0.05
ANGLE_WEIGHT = 10.0
OMEGA_WEIGHT = 1.0


@cached_njit()
def coast_potential(z: np.ndarray, hitch_trig: np.ndarray, i: int, n: int) -> float:
    """Potential of row ``i``: -10 mean_k (1 - cos alpha_k) - min(|omega|, 1).

    ``hitch_trig`` holds cos(alpha_k) in columns n .. 2n-1
    (:attr:`trailer_env.core.ConvoyCore.hitch_trig`).
    """
    omega_term = OMEGA_WEIGHT * min(abs(z[i, OMEGA]), 1.0)
    if n == 0:
        return -omega_term
    total = 0.0
    for k in range(n):
        total += 1.0 - hitch_trig[i, n + k]
    return -ANGLE_WEIGHT * (total / n) - omega_term


@cached_njit()
def coast_potentials(z: np.ndarray, hitch_trig: np.ndarray, n: int, out: np.ndarray) -> None:
    """:func:`coast_potential` of every row into ``out``."""
    for i in range(z.shape[0]):
        out[i] = coast_potential(z, hitch_trig, i, n)


@cached_njit()
def coast_is_straight(z: np.ndarray, i: int, n: int) -> bool:
    """Every |alpha_k| below SUCCESS_ANGLE and |omega| below SUCCESS_OMEGA."""
    if not abs(z[i, OMEGA]) < SUCCESS_OMEGA:
        return False
    for k in range(n):  # noqa: SIM110 - a loop numba compiles, not a generator
        if not abs(z[i, ALPHA + k]) < SUCCESS_ANGLE:
            return False
    return True


@cached_njit()
def coast_straight_rows(z: np.ndarray, n: int, out: np.ndarray) -> None:
    """:func:`coast_is_straight` of every row into ``out``."""
    for i in range(z.shape[0]):
        out[i] = coast_is_straight(z, i, n)


class CoastScene(NamedTuple):
    """What Coast's formulas read and write besides the step's outputs."""

    z: np.ndarray
    n: int
    previous: np.ndarray
    failed: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    success: np.ndarray
    #: :attr:`trailer_env.core.ShapedCore.shaping_penalties`.
    penalties: np.ndarray


@cached_njit()
def coast_outcome(rows: np.ndarray, outputs: tuple, scene: tuple) -> None:
    """ShapedCore's reward (:func:`trailer_env.shaping.shaped_reward`), termination and
    success of ``rows`` after a step.

    ``outputs`` and ``scene``: :class:`~trailer_env.kernels.StepOutputs` and
    :class:`CoastScene`, or plain tuples of their fields. Both the fused step
    (:func:`coast_step`) and the unfused one (``fidelity="dopri5"``) call it.
    """
    step = StepOutputs(*outputs)
    task = CoastScene(*scene)
    z = task.z
    n = task.n
    jackknifed = step.jackknifed
    for i in rows:
        if step.nonfinite[i]:
            continue  # the step is redone (core._retry_finer): keep the potential it started from
        straight = coast_is_straight(z, i, n)
        potential = coast_potential(z, step.hitch_trig, i, n)
        task.success[i] = straight
        task.failed[i] = False
        task.terminated[i] = jackknifed[i] or straight
        task.reward[i] = shaped_reward(
            potential,
            task.previous[i],
            step.cost[i],
            straight,
            jackknifed[i],
            False,
            task.penalties,
        )
        task.previous[i] = potential


@cached_njit()
def coast_step(
    action: np.ndarray,
    rows: np.ndarray,
    prepare: bool,
    config: tuple,
    state: tuple,
    outputs: tuple,
    scene: tuple,
) -> tuple:
    """The control step of Coast-v0 in one call: physics, then :func:`coast_outcome`."""
    # One per scene: see trailer_env.kernels.outcome_due.
    result = step_serial(action, rows, prepare, config, state, outputs)
    if outcome_due(result):
        coast_outcome(rows, outputs, scene)
    return result


@cached_njit()
def coast_starts(
    generators: Sequence[np.random.Generator],
    picks: np.ndarray,
    rows: np.ndarray,
    z: np.ndarray,
    start: tuple,
) -> None:
    """Row ``rows[j]``'s start from ``generators[picks[j]]`` (``start`` = ``(n,)``): a
    direction (forwards with probability 1/2), a speed in SPEED_RANGE, then omega and the
    hitch angles uniform within that direction's ranges, drawn again while the convoy
    is already straight (a start must leave something to do)."""
    (n,) = start
    for j in range(rows.size):
        rng = generators[picks[j]]
        i = rows[j]
        while True:
            forward = rng.random() < 0.5
            angle_range = FORWARD_ANGLE_RANGE if forward else REVERSE_ANGLE_RANGE
            omega_range = FORWARD_OMEGA_RANGE if forward else REVERSE_OMEGA_RANGE
            z[i, U] = (1.0 if forward else -1.0) * rng.uniform(SPEED_RANGE[0], SPEED_RANGE[1])
            z[i, OMEGA] = rng.uniform(-omega_range, omega_range)
            for k in range(n):
                z[i, ALPHA + k] = rng.uniform(-angle_range, angle_range)
            if not coast_is_straight(z, i, n):
                break


class CoastCore(ShapedCore):
    """Batched task logic of Coast-v0 (no task features, no pose).

    The step's reward and termination run inside the step kernel (:func:`coast_step`),
    with the formulas of :class:`~trailer_env.core.ShapedCore` and the hooks below.
    """

    scene = "Coast"
    max_episode_steps = 300
    scene_kernel = staticmethod(coast_step)
    scene_outcome = staticmethod(coast_outcome)
    start_kernel = staticmethod(coast_starts)

    def _scene_arguments(self) -> CoastScene:
        return CoastScene(
            z=self.z,
            n=self.n,
            previous=self.previous_potential,
            failed=self.failed,
            reward=self.reward,
            terminated=self.terminated,
            success=self.success,
            penalties=self.shaping_penalties,
        )

    def _start_arguments(self) -> tuple[int]:
        return (self.n,)

    def _potential(self) -> np.ndarray:
        out = np.empty(self.batch_size)
        coast_potentials(self.z, self.hitch_trig, self.n, out)
        return out

    def _is_success(self) -> np.ndarray:
        return _is_straight(self.z, self.n)


def _is_straight(z: np.ndarray, n: int) -> np.ndarray:
    straight = np.empty(z.shape[0], dtype=bool)
    coast_straight_rows(z, n, straight)
    return straight


class CoastEnv(ConvoyEnv):
    """Straighten a coasting convoy, forwards or backwards, without nearing a singularity.

    ## Description

    The convoy of Reverse-v0 (a cart, ``n_trailers`` trailers, no motor, one moving
    mass on a lateral rail of the cart; physics.md sections 1-10) starts from a random
    coasting state: moving forwards or backwards at a random speed, turning, its hitch
    angles up to 0.5 rad forwards, 0.1 rad backwards. Forwards, a straight convoy is a
    stable node (physics.md section 7) and the convoy straightens by itself; backwards
    it is an unstable node, and the hitch angles grow unless the mass steers the cart.
    The agent must bring
    the convoy to a straight configuration, every hitch angle and the turning rate
    small, without passing near a singular configuration (two consecutive bodies
    nearly perpendicular, physics.md section 10) and without folding.

    ## Action Space

    `Box(-1, 1, (1,), float32)` by default: the target position `s* = action * s_max` of
    the mass on its rail, tracked by a servo with acceleration bounded by
    `rail_accel_max` and guarded so that `|s| <= s_max` at every instant. Other modes:
    `action_mode="accel"` (rail acceleration), `"planar"` (2-D target around `(b, 0)`).
    Out-of-range actions are clipped; NaN or infinite ones raise ValueError
    (`trailer_env.actuator`).

    ## Observation Space

    `Box` of float32, length `2n + 4` (`2n + 6` in planar mode); no task features:

    | Index        | Observation                                      | Min  | Max |
    |--------------|--------------------------------------------------|------|-----|
    | 0            | u, forward speed of the cart's axle (m/s)        | -Inf | Inf |
    | 1            | omega, the cart's turning rate (rad/s)           | -Inf | Inf |
    | 2 .. n+1     | sin(alpha_k), hitch angle k = 1..n               | -1   | 1   |
    | n+2 .. 2n+1  | cos(alpha_k)                                     | -1   | 1   |
    | 2n+2         | s / s_max, the mass on its rail                  | -1   | 1   |
    | 2n+3         | s_dot / v_max, v_max = 2 sqrt(rail_accel_max s_max) | -1 | 1   |

    In planar mode indices 2n+2 .. 2n+5 are (xi - b) / s_max, eta / s_max,
    xi_dot / v_max, eta_dot / v_max.
    With `observation="trailers"` the same numbers come as a `Dict` of `body` (u, omega,
    then every entry from index 2n+2 on, in order), `trailers` (max_trailers, 2) and
    `mask`: the layout of Reverse-v0's docstring (`trailer_env.observation`).

    ## Rewards

    Potential-based: with `Phi = -10 mean_k (1 - cos alpha_k) - min(|omega|, 1)`, each
    step earns `Phi(after) - Phi(before) - 0.01 - 0.05 cost`, plus `+10` when the convoy
    is straight and `-20` when it jackknifes. The per-step penalties over a full episode
    (at most 18) stay below the fold penalty, so folding on purpose never pays.

    ## Starting State

    `|u| ~ U(0.5, 1.5)` m/s, forwards or backwards with probability 1/2 each. Forwards
    `omega ~ U(-0.2, 0.2)` rad/s and each `alpha_k ~ U(-0.5, 0.5)` rad; backwards, where
    the straight convoy is unstable and the mass recovers only small deviations,
    `omega ~ U(-0.05, 0.05)` and `alpha_k ~ U(-0.1, 0.1)`. Redrawn if already straight.
    The mass starts at rest at the centre of its rail.

    ## Episode End

    Terminated on success, the convoy straight (every `|alpha_k| < 0.05` rad and
    `|omega| < 0.05` rad/s), or on a jackknife (any `|alpha_k| >= fold_angle`, default
    pi/2). Truncated after 300 steps (15 s at `dt = 0.05`).

    ## Information

    `cost` (1.0 inside the singular band `singular_margin < singular_band`, else 0.0),
    `singular_margin`, `energy`, `actuator_work`, `jackknifed`, `is_success` (straight).

    `singular_margin` is `min_(k<n) |cos alpha_k|`: the hitches between consecutive
    bodies k <= n - 1, where the convoy's degree of nonholonomy drops. The last hitch
    `alpha_n` is not in it (a last trailer at a right angle counts only once it folds, at
    `fold_angle`), so with one trailer the margin is 1 and "safe" (never in the band,
    no failure) means "not folded and not stopped".

    ## Arguments

    As Reverse-v0: the keywords of every scene (`trailer_env.settings.MAKE_KEYWORDS`,
    docs/generated/keywords.md) and `render_mode`.

    ## References

    * `docs/physics.md` of this project.
    * A. Bravo-Doddoli and L. C. García-Naranjo, "The dynamics of an articulated
      n-trailer vehicle", Regular and Chaotic Dynamics 20 (2015); A. Bravo-Doddoli's thesis.
    * J. M. Osborne and D. V. Zenkov, "Steering the Chaplygin sleigh by a moving mass",
      Proc. 44th IEEE CDC (2005).
    """

    core_class = CoastCore
