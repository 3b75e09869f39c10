"""A stable-baselines3 ``VecEnv`` over the native batch core (imports stable_baselines3).

stable-baselines3 does not accept Gymnasium's ``VectorEnv``. :class:`ConvoySB3VecEnv`
implements SB3's own interface directly on a scene's :class:`~trailer_env.core.ConvoyCore`
with B = num_envs, so training steps every environment with one kernel call::

    from stable_baselines3 import PPO
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv("trailer_env/Reverse-v0", num_envs=64, n_trailers=2)
    PPO("MlpPolicy", venv).learn(100_000)

SB3 semantics: an environment that ends is reset within the same step; its
last observation is in ``infos[i]["terminal_observation"]`` and
``infos[i]["TimeLimit.truncated"]`` says whether it was cut by the time limit.
Seeding follows SB3 (``venv.seed(s)`` seeds environment i with ``s + i`` at the next
``reset()``), which matches the native vector env and ``gym.make`` + ``reset(seed=s + i)``.

Episode statistics are recorded as SB3's ``Monitor``/``VecMonitor`` record them: the
info of the step that ends an episode holds ``info["episode"] = {"r": return, "l":
length, "t": seconds since the adapter was built}``, so SB3's logger shows
``rollout/ep_rew_mean`` without a wrapper, and ``env_is_wrapped(Monitor)`` answers True.
Wrapping in ``VecMonitor`` as well is harmless (it writes the same values).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvStepReturn,
    VecEnvWrapper,
)

from dynamics.params import bounded_integer
from trailer_env.batch_infos import BatchInfos
from trailer_env.episodes import count_episodes
from trailer_env.generators import GeneratorBank
from trailer_env.mixed import build_core, observation_view
from trailer_env.registry import core_class_of
from trailer_env.shaping import check_gamma, make_potential, shaped_return_step
from trailer_env.start_replay import StartReplay
from trailer_env.vector import MAX_NUM_ENVS, as_action_batch, as_bank, seed_generators


class ConvoySB3VecEnv(VecEnv):
    """SB3 vectorised environment of one scene, stepped as one batch.

    Args:
        env_id: A registered id, e.g. "trailer_env/Reverse-v0".
        num_envs: Number of environments, an integer in [1, 2**24]
            (:data:`trailer_env.vector.MAX_NUM_ENVS`).
        max_episode_steps: Truncation length; default the id's registered value.
        **kwargs: Settings as for ``gym.make`` (``n_trailers``, ``mu``, ``dt`` ...).

    Raises:
        TypeError, ValueError: On a bad argument (``num_envs`` out of range included),
            naming it, before any memory is allocated.
    """

    def __init__(
        self, env_id: str, num_envs: int = 1, max_episode_steps: int | None = None, **kwargs: object
    ):
        num_envs = bounded_integer("num_envs", num_envs, 1, MAX_NUM_ENVS)
        core_class = core_class_of(env_id)
        self.env_id = env_id
        self.settings, self.core = build_core(core_class, kwargs, num_envs, False)
        registered = gym.spec(env_id).max_episode_steps
        steps = (
            max_episode_steps
            if max_episode_steps is not None
            else registered or core_class.max_episode_steps
        )
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise ValueError(f"max_episode_steps must be an integer >= 1, got {steps!r}")
        self.max_episode_steps = int(steps)
        self._view = observation_view(self.core)
        observation_space = self._view.space
        action_space = spaces.Box(-1.0, 1.0, (self.settings.action_dim,), dtype=np.float32)
        self.render_mode = None
        super().__init__(self.core.batch_size, observation_space, action_space)
        self.elapsed_steps = np.zeros(self.num_envs, dtype=np.int64)
        self._generators: GeneratorBank | None = None
        self._all_rows = np.arange(self.num_envs)
        self._action_buffer = np.zeros((self.num_envs, self.settings.action_dim))
        self._actions = self._action_buffer
        self._episode_returns = np.zeros(self.num_envs)
        self._episode_lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._start_time = time.time()
        #: The start replay (:meth:`set_start_replay`), None: the scene's starts only.
        self.start_replay: StartReplay | None = None

    def reset(self) -> np.ndarray:
        """Reset every environment (with the seeds set by :meth:`seed`, if any)."""
        seeds = self._seeds if any(seed is not None for seed in self._seeds) else None
        self._generators = as_bank(seed_generators(seeds, self.num_envs, self._generators))
        self.core.reset_rows_from(self._all_rows, self._generators)
        if self.start_replay is not None:
            self.start_replay.starts_drawn(self.core, self._all_rows)
        self.elapsed_steps[:] = 0
        self._episode_returns[:] = 0.0
        self._episode_lengths[:] = 0
        self.reset_infos = self.core.info_rows()
        self._reset_seeds()
        self._reset_options()
        return self._view.batch(self.core.obs)  # type: ignore[return-value]

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = as_action_batch(
            actions, self.num_envs, self.settings.action_dim, self._action_buffer
        )

    def step_wait(self) -> VecEnvStepReturn:
        if self._generators is None:
            raise RuntimeError("call reset() before step()")
        core = self.core
        core.step(self._actions)
        rewards = core.reward.astype(np.float32)
        dones = np.empty(self.num_envs, dtype=bool)
        truncated = np.empty(self.num_envs, dtype=bool)
        ended = count_episodes(
            self.elapsed_steps,
            self.max_episode_steps,
            core.terminated,
            rewards,
            self._episode_returns,
            self._episode_lengths,
            dones,
            truncated,
        )
        extras: dict[int, dict[str, object]] = {}
        if ended:
            rows = np.flatnonzero(dones)
            elapsed = round(time.time() - self._start_time, 6)
            returns = self._episode_returns[rows].tolist()
            lengths = self._episode_lengths[rows].tolist()
            cut = truncated[rows].tolist()
            for j, i in enumerate(rows.tolist()):
                extras[i] = {
                    "terminal_observation": self._view.row(core.obs, i),
                    "TimeLimit.truncated": cut[j],
                    "episode": {"r": returns[j], "l": lengths[j], "t": elapsed},
                }
            infos = BatchInfos(core.info_batch(), extras, self.num_envs)
            replay = self.start_replay
            if replay is not None:
                replay.episodes_ended(rows, core.success[rows])
            core.reset_rows_from(rows, self._generators)
            if replay is not None:
                replay.starts_drawn(core, rows)
            self.elapsed_steps[rows] = 0
            self._episode_returns[rows] = 0.0
            self._episode_lengths[rows] = 0
        else:
            infos = BatchInfos(core.info_batch(), extras, self.num_envs)
        return self._view.batch(core.obs), rewards, dones, infos  # type: ignore[return-value]

    def set_start_scale(self, scale: float) -> None:
        """Draw the episodes that start from now on with the starting perturbation's
        size times ``scale`` (:meth:`trailer_env.core.ConvoyCore.set_start_scale`; raises
        as it does)."""
        self.core.set_start_scale(scale)

    def set_start_replay(self, replay: StartReplay | None) -> None:
        """Begin a share of the episodes that start from now on from starts that failed
        (:class:`trailer_env.start_replay.StartReplay`); None: the scene's starts only.

        Raises:
            TypeError: If ``replay`` is neither a StartReplay nor None.
            ValueError: If the batch mixes counts of trailers, or the replay serves
                another batch (one that still lives, or of another scene, size, state or
                physics draw); nothing changes.
        """
        if replay is not None:
            if not isinstance(replay, StartReplay):
                shown = type(replay).__name__
                raise TypeError(f"replay must be a StartReplay or None, got {shown}")
            replay.attach(self.core)
        previous = self.start_replay
        if previous is not None and previous is not replay:
            previous.detach()  # free for another batch
        self.start_replay = replay

    def close(self) -> None:
        """Nothing to release."""

    def _indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, int):
            return [indices]
        return indices

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attributes are shared by the batch: the same value for every index."""
        value = getattr(self, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: object, indices: VecEnvIndices = None) -> None:
        raise AttributeError(
            "the batch's settings are fixed at construction; build a new ConvoySB3VecEnv"
        )

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        method = getattr(self, method_name)
        return [method(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        # The adapter records episodes exactly as Monitor does (see the module docstring).
        recorded = isinstance(wrapper_class, type) and issubclass(Monitor, wrapper_class)
        return [recorded for _ in self._indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]


class PotentialShapingVecEnv(VecEnvWrapper):
    """A :class:`ConvoySB3VecEnv` whose rewards carry potential-based shaping,
    ``gamma Phi(s') - Phi(s)`` (:class:`trailer_env.wrappers.PotentialShaping` for a batch).

    An ending step uses the terminal observation SB3 puts in ``infos[i]``: ``Phi = 0`` when
    the episode terminated, ``Phi(terminal_observation)`` when the time limit cut it; the
    next step starts from the new episode's potential. Observations, dones, infos and the
    episode statistics (``info["episode"]``, recorded by the adapter beneath) are the
    scene's own; :attr:`unshaped_rewards` holds the last step's unshaped rewards.

    Args:
        venv: A :class:`ConvoySB3VecEnv` of one count of trailers.
        potential, gamma, **potential_kwargs: As :class:`trailer_env.wrappers.PotentialShaping`.

    Raises:
        TypeError, ValueError: Another VecEnv, a mixed count of trailers, an unknown
            potential or keyword, or a bad value.
    """

    def __init__(
        self,
        venv: ConvoySB3VecEnv,
        potential: str = "lqr",
        gamma: float = 0.99,
        **potential_kwargs: float,
    ) -> None:
        if not isinstance(venv, ConvoySB3VecEnv):
            raise TypeError(
                f"PotentialShapingVecEnv wraps a ConvoySB3VecEnv, got {type(venv).__name__}"
            )
        if len(venv.core.counts) > 1:
            raise ValueError("PotentialShapingVecEnv needs one count of trailers, not a mix")
        if venv.settings.observation != "flat":
            raise ValueError(
                "PotentialShapingVecEnv reads the flat observation; got "
                f"observation={venv.settings.observation!r}"
            )
        self.gamma = check_gamma(gamma)
        self.potential = make_potential(potential, venv.settings, **potential_kwargs)
        super().__init__(venv)
        self._previous = np.zeros(self.num_envs)
        self.unshaped_rewards = np.zeros(self.num_envs, dtype=np.float32)

    def reset(self) -> np.ndarray:
        obs = np.asarray(self.venv.reset())
        self._previous = self.potential(obs)
        return obs

    def step_wait(self) -> VecEnvStepReturn:
        batch, rewards, dones, infos = self.venv.step_wait()
        obs = np.asarray(batch)
        after = self.potential(obs)
        terminated = dones.copy()
        reached = after.copy()
        ended = np.flatnonzero(dones)
        if ended.size:
            terminated[ended] = [not infos[i]["TimeLimit.truncated"] for i in ended.tolist()]
            reached[ended] = self.potential(
                np.stack([infos[i]["terminal_observation"] for i in ended.tolist()])
            )
        shaped = shaped_return_step(rewards, self._previous, reached, terminated, self.gamma)
        self.unshaped_rewards = rewards
        self._previous = after
        return obs, shaped.astype(np.float32), dones, infos
