"""Views of a trailer_env env in other libraries' conventions.

* :class:`SafetyStep`: safety-gymnasium's step, ``(obs, reward, cost, terminated,
  truncated, info)``, with the cost that ``info["cost"]`` carries (1 inside the
  singular band, else 0);
* :class:`PotentialShaping`: the scene's reward plus potential-based shaping
  (:mod:`trailer_env.shaping`), which keeps the task's optimal policies;
* :class:`GoalConditioned`: Gymnasium-Robotics' goal-conditioned form for the goal
  scenes (Dock-v0, Heading-v0): ``Dict`` observations with ``observation``,
  ``achieved_goal`` and ``desired_goal``, and a vectorised ``compute_reward`` that
  hindsight relabelling (SB3's ``HerReplayBuffer``) calls on any goal.

Each wraps one environment made from a trailer_env id (``gym.make``; a vector env, another
library's env or anything else is refused with TypeError or ValueError) and are
:class:`gymnasium.utils.RecordConstructorArgs`, as Gymnasium's own wrappers: the wrapped
env's ``spec`` names them, so ``env.spec.make()`` rebuilds the wrapped env and
Gymnasium's ``check_env`` accepts :class:`GoalConditioned`.
"""

from __future__ import annotations

from typing import SupportsFloat

import gymnasium as gym
import numpy as np

from dynamics.columns import theta_column
from trailer_env.env import ConvoyEnv
from trailer_env.scenes.dock import SUCCESS_HEADING, SUCCESS_RADIUS, DockCore
from trailer_env.scenes.heading import HEADING_TOLERANCE, HeadingCore
from trailer_env.shaping import check_gamma, make_potential, shaped_return_step


def _convoy_env(wrapper: str, env: object) -> ConvoyEnv:
    """The trailer_env environment under ``env`` (what ``wrapper`` may wrap).

    Raises:
        TypeError: If ``env`` is a vector env or not a :class:`gymnasium.Env`.
        ValueError: If it is another library's environment.
    """
    if isinstance(env, gym.vector.VectorEnv):
        raise TypeError(
            f"{wrapper} wraps one environment, got the vector env {type(env).__name__}; "
            f"wrap each of them (gym.make_vec(..., vectorization_mode='sync', "
            f"wrappers=[{wrapper}]))"
        )
    if not isinstance(env, gym.Env):
        raise TypeError(
            f"{wrapper} needs an environment made with gym.make('trailer_env/...'), got "
            f"{type(env).__name__} {env!r}"
        )
    base = env.unwrapped
    if not isinstance(base, ConvoyEnv):
        name = base.spec.id if base.spec is not None else type(base).__name__
        raise ValueError(f"{wrapper} needs a trailer_env environment, got {name}")
    return base


class SafetyStep(gym.Wrapper[object, object, object, object], gym.utils.RecordConstructorArgs):
    """safety-gymnasium's step signature: ``step`` returns the cost as its third value.

    ``reset`` is unchanged. The cost is ``info["cost"]`` (also left in ``info``).

    Raises:
        TypeError, ValueError: For anything but one trailer_env environment (see the
            module docstring).
    """

    def __init__(self, env: gym.Env[object, object]) -> None:
        _convoy_env("SafetyStep", env)
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def step(  # type: ignore[override]
        self, action: object
    ) -> tuple[object, SupportsFloat, float, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, float(info["cost"]), terminated, truncated, info


class PotentialShaping(
    gym.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray], gym.utils.RecordConstructorArgs
):
    """The scene's reward plus potential-based shaping, ``gamma Phi(s') - Phi(s)``
    (:func:`trailer_env.shaping.shaped_return_step`; ``Phi = 0`` on a terminal state).

    Over an episode the added terms sum to ``-Phi(s_0)`` (``gamma = 1``) whatever the
    policy does, so the task's optimal policies are unchanged (Ng, Harada and Russell
    1999) while the reward tells at once whether a step brought the convoy nearer to or
    farther from where the potential is high. The observation, termination and success
    are the scene's; ``info["unshaped_reward"]`` is the scene's own reward.

    Args:
        env: One environment made with ``gym.make("trailer_env/...")``.
        potential: A name of :data:`trailer_env.shaping.POTENTIALS` ("lqr").
        gamma: The learner's discount factor, in (0, 1].
        **potential_kwargs: The potential's own settings (``scale``, ``reference``).

    Raises:
        TypeError, ValueError: For anything but one trailer_env environment, an unknown
            potential or keyword, or a bad value, before anything is built.
    """

    def __init__(
        self,
        env: gym.Env[np.ndarray, np.ndarray],
        potential: str = "lqr",
        gamma: float = 0.99,
        **potential_kwargs: float,
    ) -> None:
        base = _convoy_env("PotentialShaping", env)
        if base.settings.observation != "flat":
            raise ValueError(
                "PotentialShaping reads the flat observation (observation='flat'), got "
                f"observation={base.settings.observation!r}"
            )
        gamma = check_gamma(gamma)
        self.potential = make_potential(potential, base.settings, **potential_kwargs)
        # RecordConstructorArgs's keyword-only flag (a bool) makes mypy check every **
        # value against it; these are the constructor's own arguments.
        gym.utils.RecordConstructorArgs.__init__(
            self,
            potential=potential,
            gamma=gamma,
            **potential_kwargs,  # type: ignore[arg-type]
        )
        gym.Wrapper.__init__(self, env)
        self.gamma = gamma
        self._previous = 0.0

    def reset(
        self, *, seed: int | None = None, options: dict[str, object] | None = None
    ) -> tuple[np.ndarray, dict[str, object]]:
        obs, info = self.env.reset(seed=seed, options=options)
        self._previous = float(self.potential(obs)[0])
        return obs, info

    def step(
        self, action: np.ndarray
    ) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        after = self.potential(obs)
        shaped = shaped_return_step(
            np.array([float(reward)]),
            np.array([self._previous]),
            after,
            np.array([terminated]),
            self.gamma,
        )
        self._previous = float(after[0])
        return obs, float(shaped[0]), terminated, truncated, {**info, "unshaped_reward": reward}


def _angle_features(angle: np.ndarray) -> np.ndarray:
    return np.stack([np.sin(angle), np.cos(angle)], axis=-1)


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle between two (sin, cos) features, in [0, pi]."""
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    dot = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]
    return np.abs(np.arctan2(cross, dot))


def goal_observation(core: DockCore | HeadingCore, obs: np.ndarray) -> dict[str, np.ndarray]:
    """The goal-conditioned observations of a whole batch (``core`` of a single env or
    of the native vector env; ``obs`` its (B, obs_dim) observations), as
    :class:`GoalConditioned` defines them (float32, a leading batch axis)."""
    if isinstance(core, DockCore):
        x, y, heading = core.last_body_pose()
        achieved = np.column_stack([x, y, _angle_features(heading)])
        desired = np.column_stack([core.target[:, :2], _angle_features(core.target[:, 2])])
    else:
        achieved = _angle_features(core.z[:, theta_column(core.n)])
        desired = _angle_features(core.target_heading)
    return {
        "observation": np.asarray(obs[:, : core.n_common], dtype=np.float32),
        "achieved_goal": achieved.astype(np.float32),
        "desired_goal": desired.astype(np.float32),
    }


class GoalConditioned(
    gym.Wrapper[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray],
    gym.utils.RecordConstructorArgs,
):
    """Dock-v0 or Heading-v0 as a goal-conditioned env with a sparse reward.

    Observation (``Dict``, float32):

    * ``observation``: the scene's observation without its goal-relative task features
      (u, omega, the hitches' sin and cos, the mass; indices 0 .. 2n + 3);
    * ``achieved_goal``: Dock: the last axle's (x, y, sin h, cos h) in the plane;
      Heading: the cart's (sin theta, cos theta);
    * ``desired_goal``: the same quantities of the dock pose or the target heading.

    Reward: :meth:`compute_reward`, 0 where the achieved goal is within the scene's
    success tolerance of the desired one (Dock: 0.3 m and 0.15 rad; Heading: 0.03 rad,
    without the scene's 1 s hold), else -1. It replaces the scene's shaped reward;
    termination, truncation and ``info`` are the scene's (``info["scene_reward"]`` keeps
    its reward).

    Raises:
        TypeError: For a vector env or anything that is not a :class:`gymnasium.Env`.
        ValueError: For another library's env, or an env of another scene (or of a range
            of trailer counts), or with observation="trailers".
    """

    def __init__(self, env: gym.Env[np.ndarray, np.ndarray]) -> None:
        core = _convoy_env("GoalConditioned", env).core
        if not isinstance(core, (DockCore, HeadingCore)):
            raise ValueError(
                "GoalConditioned needs trailer_env/Dock-v0 or trailer_env/Heading-v0 with one "
                f"number of trailers, got a {type(core).__name__}"
            )
        if core.settings.observation != "flat":
            raise ValueError(
                "GoalConditioned needs the flat observation (observation='flat'), got "
                f"observation={core.settings.observation!r}"
            )
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        self._core = core
        self._dock = isinstance(core, DockCore)
        #: Entries of a goal: Dock (x, y, sin h, cos h), Heading (sin theta, cos theta).
        self.goal_size = 4 if self._dock else 2
        goal = gym.spaces.Box(-np.inf, np.inf, (self.goal_size,), np.float32)
        base = env.observation_space
        if not isinstance(base, gym.spaces.Box):  # pragma: no cover - every scene's is a Box
            raise TypeError(f"GoalConditioned needs a Box observation space, got {base}")
        self.observation_space = gym.spaces.Dict(
            {
                "observation": gym.spaces.Box(
                    base.low[: core.n_common], base.high[: core.n_common], dtype=np.float32
                ),
                "achieved_goal": goal,
                "desired_goal": goal,
            }
        )

    def _observation(self, obs: np.ndarray) -> dict[str, np.ndarray]:
        batch = goal_observation(self._core, obs[np.newaxis])
        return {key: value[0] for key, value in batch.items()}

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: object
    ) -> np.ndarray:
        """0 where the goals agree within the scene's tolerance, else -1 (float32).

        Args:
            achieved_goal, desired_goal: Goals, shape ``(..., goal_size)`` (4 on Dock, 2
                on Heading), real numbers; leading (batch) axes broadcast together, as
                hindsight relabelling passes them.
            info: Unused.

        Raises:
            TypeError: If a goal is None, a string or not real numbers.
            ValueError: If a goal's last axis is not ``goal_size`` long (a scalar
                included), or the leading axes do not broadcast.
        """
        achieved = self._goals("achieved_goal", achieved_goal)
        desired = self._goals("desired_goal", desired_goal)
        try:
            np.broadcast_shapes(achieved.shape, desired.shape)
        except ValueError:
            raise ValueError(
                f"achieved_goal {achieved.shape} and desired_goal {desired.shape}: the leading "
                "(batch) axes do not broadcast"
            ) from None
        if self._dock:
            close = np.linalg.norm(achieved[..., :2] - desired[..., :2], axis=-1) < SUCCESS_RADIUS
            close &= _angle_between(achieved[..., 2:], desired[..., 2:]) < SUCCESS_HEADING
        else:
            close = _angle_between(achieved, desired) < HEADING_TOLERANCE
        return np.where(close, 0.0, -1.0).astype(np.float32)

    def _goals(self, name: str, value: object) -> np.ndarray:
        """``value`` as float64 goals of shape (..., goal_size), or a clear error."""
        width = self.goal_size
        expected = f"goals of shape (..., {width})"
        if value is None or isinstance(value, (str, bytes)):
            raise TypeError(f"{name} must be {expected}, got {type(value).__name__} {value!r}")
        try:
            array = np.asarray(value)
        except ValueError:  # a ragged sequence
            raise ValueError(f"{name} must be {expected}, got a ragged {value!r}") from None
        if array.dtype.kind not in "iuf":
            raise TypeError(f"{name} must be {expected} of real numbers, got dtype {array.dtype}")
        if array.ndim == 0 or array.shape[-1] != width:
            raise ValueError(f"{name} must be {expected}, got shape {array.shape}")
        return array.astype(np.float64, copy=False)

    def reset(
        self, *, seed: int | None = None, options: dict[str, object] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, object]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return self._observation(obs), info

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, object]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        goal_obs = self._observation(obs)
        info = {**info, "scene_reward": float(reward)}
        achieved, desired = goal_obs["achieved_goal"], goal_obs["desired_goal"]
        sparse = float(self.compute_reward(achieved, desired, info))
        return goal_obs, sparse, terminated, truncated, info
