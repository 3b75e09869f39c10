"""Native batched vector environments: one scene core with B = num_envs, one kernel call per step.

Registered as each id's ``vector_entry_point``::

    envs = gym.make_vec("trailer_env/Reverse-v0", num_envs=4096,
                        vectorization_mode="vector_entry_point", n_trailers=3)

Autoreset mode NEXT_STEP (Gymnasium 1.x): the step after an episode ends
resets that environment, ignores its action and returns its first observation
with reward 0, terminated and truncated False.

Seeding: ``reset(seed=s)`` seeds environment ``i`` with ``s + i`` (a list of N
seeds sets them one by one). Environment ``i`` then draws every starting state,
autoresets included, from its own generator, exactly as a single environment
made with ``gym.make(...)`` and reset with ``seed=s + i``, then reset without a
seed after each episode: the two produce identical trajectories under the same
actions.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dynamics.params import bounded_integer
from trailer_env.core import ConvoyCore
from trailer_env.env import as_action_array
from trailer_env.scenes import CoastCore, DockCore, HeadingCore, ReverseCore
from trailer_env.settings import settings_from_kwargs


def seed_generators(
    seed: int | Sequence[int | None] | None,
    count: int,
    current: list[np.random.Generator] | None,
) -> list[np.random.Generator]:
    """Per-environment generators: ``seed + i``, a list of seeds, or (None) keep/draw fresh ones.

    Raises:
        ValueError: If a list of seeds does not have ``count`` entries.
    """
    if seed is None:
        return (
            current if current is not None else [seeding.np_random(None)[0] for _ in range(count)]
        )
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [seeding.np_random(int(seed) + i)[0] for i in range(count)]
    if isinstance(seed, bool):
        raise ValueError(f"seed must be an int or a list of {count} seeds, got {seed!r}")
    seeds = list(seed)
    if len(seeds) != count:
        raise ValueError(f"seed must be an int or a list of {count} seeds, got {len(seeds)}")
    generators = []
    for i, value in enumerate(seeds):
        if value is not None:
            generators.append(seeding.np_random(int(value))[0])
        elif current is not None:
            generators.append(current[i])
        else:
            generators.append(seeding.np_random(None)[0])
    return generators


def as_action_batch(actions: Any, count: int, action_dim: int) -> np.ndarray:
    """Actions as a float64 (count, action_dim) array; (count,) is accepted when action_dim == 1.

    Nothing else is broadcast.

    Raises:
        TypeError: For None, bools, strings, complex numbers or other non-numbers.
        ValueError: On a wrong shape (non-finite values are rejected by the core).
    """
    if (
        type(actions) is np.ndarray
        and actions.dtype == np.float64
        and actions.shape == (count, action_dim)
    ):
        return actions  # the common case, checked at no cost
    batch = as_action_array(
        actions, (count, action_dim), "actions", alternative=(count,) if action_dim == 1 else ()
    )
    return batch.astype(np.float64, copy=False).reshape(count, action_dim)


#: Largest num_envs: 2**24 environments of a 256-trailer convoy would already need
#: ~40 GiB for their states and observations.
MAX_NUM_ENVS = 2**24
#: Largest max_episode_steps (an int64 step counter never comes close).
MAX_EPISODE_STEPS = 2**62


class ConvoyVectorEnv(VectorEnv):
    """N environments of one scene stepped together (see the module docstring).

    Args:
        num_envs: Number of environments N, an integer in [1, 2**24].
        max_episode_steps: Truncation length, an integer >= 1; default the scene's
            registered value.
        render_mode: Must be None (render single environments instead).
        **kwargs: The single environments' settings (``n_trailers``, ``dt``, ``mu`` ...).

    Raises:
        TypeError: On an unknown keyword or a value of the wrong type, naming it.
        ValueError: On a value out of range (``num_envs=0`` included), naming it.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}  # noqa: RUF012
    core_class: ClassVar[type[ConvoyCore]]

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        **kwargs: Any,
    ) -> None:
        if render_mode is not None:
            raise ValueError(
                "the vector environments do not render; render a single env (gym.make)"
            )
        num_envs = bounded_integer("num_envs", num_envs, 1, MAX_NUM_ENVS)
        if max_episode_steps is None:
            max_episode_steps = self.core_class.max_episode_steps
        max_episode_steps = bounded_integer(
            "max_episode_steps", max_episode_steps, 1, MAX_EPISODE_STEPS
        )
        self.settings = settings_from_kwargs(**kwargs)
        self.core = self.core_class(self.settings, num_envs)
        self.num_envs = self.core.batch_size
        self.max_episode_steps = int(max_episode_steps)
        self.render_mode = None
        low, high = self.core.observation_bounds()
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.Box(
            -1.0, 1.0, (self.settings.action_dim,), dtype=np.float32
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.elapsed_steps = np.zeros(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._generators: list[np.random.Generator] | None = None
        self._all_rows = np.arange(self.num_envs)
        self._mask = np.ones(self.num_envs, dtype=bool)
        self._mask.flags.writeable = False

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every environment; ``seed`` seeds environment i with ``seed + i``."""
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            super().reset(seed=int(seed))
        self._generators = seed_generators(seed, self.num_envs, self._generators)
        self.core.reset_rows(self._all_rows, self._generators)
        self.elapsed_steps[:] = 0
        self._needs_reset[:] = False
        return self.core.obs.copy(), self._infos()

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every environment (NEXT_STEP autoreset).

        Raises:
            ValueError: On NaN or infinite actions or a wrong shape (nothing is stepped).
        """
        if self._generators is None:
            raise RuntimeError("call reset() before step()")
        core = self.core
        core.step(as_action_batch(actions, self.num_envs, self.settings.action_dim))
        self.elapsed_steps += 1
        reward = core.reward.copy()
        terminated = core.terminated.copy()
        truncated = self.elapsed_steps >= self.max_episode_steps
        rows = np.flatnonzero(self._needs_reset)
        if rows.size:
            core.reset_rows(rows, [self._generators[i] for i in rows.tolist()])
            self.elapsed_steps[rows] = 0
            reward[rows] = 0.0
            terminated[rows] = False
            truncated[rows] = False
        self._needs_reset = terminated | truncated
        return core.obs.copy(), reward, terminated, truncated, self._infos()

    def _infos(self) -> dict[str, Any]:
        infos: dict[str, Any] = self.core.info_batch()
        for key in list(infos):
            infos[f"_{key}"] = self._mask
        return infos


class ReverseVectorEnv(ConvoyVectorEnv):
    """Batched Reverse-v0 (see :class:`trailer_env.scenes.ReverseEnv`)."""

    core_class = ReverseCore


class CoastVectorEnv(ConvoyVectorEnv):
    """Batched Coast-v0 (see :class:`trailer_env.scenes.CoastEnv`)."""

    core_class = CoastCore


class HeadingVectorEnv(ConvoyVectorEnv):
    """Batched Heading-v0 (see :class:`trailer_env.scenes.HeadingEnv`)."""

    core_class = HeadingCore


class DockVectorEnv(ConvoyVectorEnv):
    """Batched Dock-v0 (see :class:`trailer_env.scenes.DockEnv`)."""

    core_class = DockCore
