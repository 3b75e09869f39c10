"""Native batched vector environments: one scene core with B = num_envs, one kernel call per step.

Registered as each id's ``vector_entry_point``::

    envs = gym.make_vec("trailer_env/Reverse-v0", num_envs=4096,
                        vectorization_mode="vector_entry_point", n_trailers=3)

Autoreset modes (Gymnasium 1.x, ``autoreset_mode=``; the attribute and
``metadata["autoreset_mode"]`` say which):

* ``"next_step"`` (default): the step after an episode ends resets that
  environment, ignores its action and returns its first observation with reward 0,
  terminated and truncated False.
* ``"same_step"``: an environment that ends is reset within the same step; its last
  observation is in ``info["final_obs"]`` (an object array, None for the others) and
  its info in ``info["final_info"]``, masked by ``info["_final_obs"]``.
* ``"disabled"``: nothing resets by itself; ``reset(options={"reset_mask": mask})``
  resets the environments where the boolean ``mask`` is True (TorchRL's convention).
  Stepping an environment that ended and was not reset raises RuntimeError.

Reset options: ``reset_mask`` (above) and ``state``, an ``(N, n + 2)`` array of
starting states (u, omega, alpha_1..alpha_n) for the environments being reset.
Rendering: ``render_mode="rgb_array"`` makes ``render()`` return a tuple of one
frame per environment, as :class:`gymnasium.vector.SyncVectorEnv` does, for the first
:data:`MAX_RENDER_ENVS` (16) environments at most: a frame is ~1 MB (600 x 600 x 3), so
rendering 4096 environments would return 4.4 GB per call. With more environments
``render()`` returns the first 16 frames and warns once. The env pickles and deep-copies
after rendering too (the renderer is left out and recreated by the next ``render()``).

Ended environments under ``"next_step"`` are not integrated on the step that resets
them (their action is ignored, finite or not): only the other environments' physics runs.

Seeding: ``reset(seed=s)`` seeds environment ``i`` with ``s + i`` (a list of N
seeds sets them one by one). Environment ``i`` then draws every starting state,
autoresets included, from its own generator, exactly as a single environment
made with ``gym.make(...)`` and reset with ``seed=s + i``, then reset without a
seed after each episode: the two produce identical trajectories under the same
actions.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from dynamics.columns import theta_column, x_column
from dynamics.params import bounded_integer, one_of
from trailer_env.core import ConvoyCore
from trailer_env.core_infos import Info
from trailer_env.env import (
    PATH_LENGTH,
    as_action_array,
    checked_seed,
    checked_state,
    options_dict,
    real_array,
)
from trailer_env.episodes import count_step
from trailer_env.generators import GeneratorBank
from trailer_env.mixed import build_core, observation_view
from trailer_env.observation import Observation
from trailer_env.rendering import ConvoyRenderer, PathTrace, core_frame, make_renderer

VECTOR_RENDER_MODES = ("rgb_array",)


def seed_generators(
    seed: int | Sequence[int | None] | None,
    count: int,
    current: Sequence[np.random.Generator] | None,
) -> Sequence[np.random.Generator]:
    """Per-environment generators: ``seed + i``, a list of seeds, or (None) keep/draw fresh ones.

    Raises:
        TypeError: If a seed is not an integer (a float such as 1.5 or a bool is refused,
            never truncated) or the seeds are not an int or a sequence.
        ValueError: If a list of seeds does not have ``count`` entries, or a seed is negative.
    """
    seeds = checked_seeds(seed, count)
    if seeds is None:
        return (
            current if current is not None else [seeding.np_random(None)[0] for _ in range(count)]
        )
    if isinstance(seeds, int):
        return [seeding.np_random(seeds + i)[0] for i in range(count)]
    generators = []
    for i, value in enumerate(seeds):
        if value is not None:
            generators.append(seeding.np_random(value)[0])
        elif current is not None:
            generators.append(current[i])
        else:
            generators.append(seeding.np_random(None)[0])
    return generators


def as_bank(generators: Sequence[np.random.Generator]) -> GeneratorBank:
    """``generators`` as a :class:`~trailer_env.generators.GeneratorBank` (itself if it is one)."""
    return generators if isinstance(generators, GeneratorBank) else GeneratorBank(generators)


def checked_seeds(
    seed: int | Sequence[int | None] | None, count: int
) -> int | list[int | None] | None:
    """``seed`` checked (:func:`trailer_env.env.checked_seed`): None, an int, or a list of
    ``count`` ints or Nones; changes nothing.

    Raises:
        TypeError, ValueError: As :func:`seed_generators`.
    """
    if seed is None or isinstance(seed, (int, np.integer, bool, np.bool_)):
        return checked_seed(seed)
    if isinstance(seed, (str, bytes)) or not isinstance(seed, (Sequence, np.ndarray)):
        raise TypeError(
            f"seed must be an int or a list of {count} seeds, got {type(seed).__name__} {seed!r}"
        )
    seeds = list(seed)
    if len(seeds) != count:
        raise ValueError(f"seed must be an int or a list of {count} seeds, got {len(seeds)}")
    return [checked_seed(value) for value in seeds]


def parse_autoreset_mode(mode: object) -> AutoresetMode:
    """An :class:`AutoresetMode` from itself, its value ("NextStep") or name ("next_step").

    Raises:
        ValueError: Naming the valid modes otherwise.
    """
    if isinstance(mode, AutoresetMode):
        return mode
    for member in AutoresetMode:
        if mode in (member.value, member.name.lower()):
            return member
    valid = [member.name.lower() for member in AutoresetMode]
    raise ValueError(f"autoreset_mode must be one of {valid}, got {mode!r}")


def as_action_batch(
    actions: object, count: int, action_dim: int, out: np.ndarray | None = None
) -> np.ndarray:
    """Actions as a float64 (count, action_dim) array; (count,) is accepted when action_dim == 1.

    Float arrays of up to 64 bits (float32 from ``action_space.sample()``, SB3, TorchRL or
    CleanRL, float64, float16) of the right shape take the fast path: copied into ``out``
    (when given, a float64 (count, action_dim) buffer, which is returned), exactly, since
    every such value is a float64 too. Nothing else is broadcast.

    Raises:
        TypeError: For None, bools, strings, complex numbers or other non-numbers.
        ValueError: On a wrong shape (non-finite values are rejected by the core).
    """
    if type(actions) is np.ndarray and actions.dtype.kind == "f" and actions.dtype.itemsize <= 8:
        shape = actions.shape
        if shape == (count, action_dim) or (action_dim == 1 and shape == (count,)):
            if out is None:
                if actions.dtype == np.float64 and actions.ndim == 2:
                    return actions  # the common case, checked at no cost
                out = np.empty((count, action_dim))
            np.copyto(out, actions.reshape(count, action_dim))
            return out
    batch = as_action_array(
        actions, (count, action_dim), "actions", alternative=(count,) if action_dim == 1 else ()
    )
    if out is None:
        return batch.astype(np.float64, copy=False).reshape(count, action_dim)
    np.copyto(out, batch.reshape(count, action_dim), casting="unsafe")
    return out


#: Most environments ``render()`` draws (the first ones): ~1 MB per frame.
MAX_RENDER_ENVS = 16
#: Largest num_envs: 2**24 environments of a 256-trailer convoy would already need
#: ~40 GiB for their states and observations.
MAX_NUM_ENVS = 2**24
#: Largest max_episode_steps (an int64 step counter never comes close).
MAX_EPISODE_STEPS = 2**62


class ConvoyVectorEnv(VectorEnv):
    """N environments of one scene stepped together (see the module docstring).

    Each registered id's ``vector_entry_point`` is this class bound to the scene's core
    (a subclass in :mod:`trailer_env.registry`, e.g. ``ReverseVectorEnv``);
    ``ConvoyVectorEnv(ReverseCore, num_envs=8)`` builds one directly.

    Args:
        core_class: The scene's batch core.
        num_envs: Number of environments N, an integer in [1, 2**24].
        max_episode_steps: Truncation length, an integer >= 1; default the scene's
            registered value.
        render_mode: None or "rgb_array" (one frame per environment).
        autoreset_mode: "next_step" (default), "same_step" or "disabled" (or an
            :class:`gymnasium.vector.AutoresetMode`), see the module docstring.
        **kwargs: The single environments' settings (``n_trailers``, ``dt``, ``mu`` ...).

    Raises:
        TypeError: On an unknown keyword or a value of the wrong type, naming it.
        ValueError: On a value out of range (``num_envs=0`` included), naming it.
    """

    metadata = {  # noqa: RUF012
        "render_modes": list(VECTOR_RENDER_MODES),
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    @property
    def spec(self) -> EnvSpec | None:
        """The spec ``gym.make_vec`` recorded, with this env's own truncation length (a
        ``max_episode_steps`` keyword of ``make_vec`` truncates here, so the spec says so)."""
        return self._spec

    @spec.setter
    def spec(self, value: EnvSpec | None) -> None:
        steps = getattr(self, "max_episode_steps", None)
        if value is not None and steps is not None and value.max_episode_steps != steps:
            value = dataclasses.replace(value, max_episode_steps=steps)
        self._spec = value

    def __init__(
        self,
        core_class: type[ConvoyCore],
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        **kwargs: object,
    ) -> None:
        # "human" is refused: a window per environment is not offered.
        one_of("render_mode", render_mode, VECTOR_RENDER_MODES, none=True)
        num_envs = bounded_integer("num_envs", num_envs, 1, MAX_NUM_ENVS)
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        if not (isinstance(core_class, type) and issubclass(core_class, ConvoyCore)):
            raise TypeError(f"core_class must be a ConvoyCore subclass, got {core_class!r}")
        self.core_class = core_class
        self._spec = None
        if max_episode_steps is None:
            max_episode_steps = core_class.max_episode_steps
        max_episode_steps = bounded_integer(
            "max_episode_steps", max_episode_steps, 1, MAX_EPISODE_STEPS
        )
        self.settings, self.core = build_core(core_class, kwargs, num_envs, render_mode is not None)
        self.num_envs = self.core.batch_size
        self.max_episode_steps = int(max_episode_steps)
        self.render_mode = render_mode
        self.metadata = {
            **self.metadata,
            "autoreset_mode": self.autoreset_mode,
            "render_fps": max(1, round(1.0 / self.settings.dt)),
        }
        self._paths = PathTrace(self.num_envs, PATH_LENGTH) if render_mode else None
        self._renderer: ConvoyRenderer | None = None
        self._warned_render = False
        self._view = observation_view(self.core)
        self.single_observation_space = self._view.space
        self.single_action_space = spaces.Box(
            -1.0, 1.0, (self.settings.action_dim,), dtype=np.float32
        )
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.elapsed_steps = np.zeros(self.num_envs, dtype=np.int64)
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._pending = 0  # np.count_nonzero(self._needs_reset), kept with it
        self._actions = np.zeros((self.num_envs, self.settings.action_dim))
        self._generators: GeneratorBank | None = None
        self._all_rows = np.arange(self.num_envs)
        self._mask = np.ones(self.num_envs, dtype=bool)
        self._mask.flags.writeable = False
        self._info_masks: dict[str, np.ndarray] | None = None

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: Mapping[str, object] | None = None,
    ) -> tuple[Observation, dict[str, object]]:
        """Reset every environment, or those of ``options["reset_mask"]``.

        ``seed`` seeds environment i with ``seed + i`` (see the module docstring); with a
        mask, only the masked environments' generators are reseeded. Options:
        ``reset_mask`` (bool array (N,)) and ``state`` (float array (N, n + 2)).

        Every argument is checked before anything changes: a refused reset leaves the
        states, observations and generators as they were.

        Raises:
            TypeError: If ``options`` is not a dict, a seed is not an integer (1.5, True),
                or ``state`` is not made of real numbers (bool, string, complex arrays).
            ValueError: On an unknown option, a mask or state of the wrong shape, a state
                value that is not finite or too large, or a negative seed.
        """
        checked_seeds(seed, self.num_envs)
        rows, states = self._reset_options(options)
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            super().reset(seed=int(seed))
        generators = seed_generators(seed, self.num_envs, self._generators)
        if self._generators is None or rows.size == self.num_envs:
            self._generators = as_bank(generators)
        else:
            for i in rows.tolist():
                if generators[i] is not self._generators[i]:
                    self._generators[i] = generators[i]
        self._start(rows, states)
        return self._view.batch(self.core.obs), self._infos()

    def _reset_options(self, options: object) -> tuple[np.ndarray, np.ndarray | None]:
        """The rows to reset and their given states (None: draw them) from ``options``."""
        options = options_dict(options, ("reset_mask", "state"))
        rows = self._all_rows
        if "reset_mask" in options:
            mask = np.asarray(options["reset_mask"])
            if mask.dtype != np.bool_ or mask.shape != (self.num_envs,):
                raise ValueError(
                    f"reset_mask must be a bool array of shape ({self.num_envs},), got "
                    f"{mask.dtype} {mask.shape}"
                )
            if self._generators is None and not mask.all():
                raise ValueError("the first reset must reset every environment (reset_mask)")
            rows = np.flatnonzero(mask)
        states = None
        if "state" in options:
            if len(self.core.counts) > 1:
                # One width for every row would name one count (the pose makes widths of
                # two counts meet); the single env's set_state takes a state per episode.
                raise ValueError("the state reset option needs one number of trailers, not a range")
            width = self.core.n + 2
            expected = f"an array of real numbers of shape ({self.num_envs}, {width})"
            states = real_array("state", options["state"], expected).astype(np.float64)
            if states.shape != (self.num_envs, width):
                raise ValueError(
                    f"state must have shape ({self.num_envs}, {width}), got {states.shape}"
                )
            for i in rows.tolist():  # every row checked before any environment changes
                self.core.check_row_state(checked_state(states[i], 0.0, 0.0)[0])
        return rows, states

    def _start(self, rows: np.ndarray, states: np.ndarray | None = None) -> None:
        """New episodes in ``rows``, drawn from their generators or set to ``states[rows]``."""
        assert self._generators is not None
        self.core.reset_rows_from(rows, self._generators)
        if states is not None:
            for i in rows.tolist():
                self.core.set_row_state(i, states[i])
        self.elapsed_steps[rows] = 0
        self._needs_reset[rows] = False
        self._pending = int(np.count_nonzero(self._needs_reset))
        if self._paths is not None:
            self._paths.clear(rows)
            self._record_paths(rows)

    def step(
        self, actions: object
    ) -> tuple[Observation, np.ndarray, np.ndarray, np.ndarray, dict[str, object]]:
        """Step every environment (autoreset as ``autoreset_mode`` says).

        Raises:
            ValueError: On NaN or infinite actions (of the environments stepped), a wrong
                shape, or a masked array with masked entries (nothing is stepped).
            FloatingPointError: If a step diverged or would exceed the work budget
                (:mod:`trailer_env.core`), naming the environments; every environment is
                left at its state before the step.
            RuntimeError: Before the first reset, or (autoreset disabled) when an
                environment that ended was not reset.
        """
        if self._generators is None:
            raise RuntimeError("call reset() before step()")
        mode = self.autoreset_mode
        pending = self._pending  # environments that ended on the previous step
        if pending and mode is AutoresetMode.DISABLED:
            shown = np.flatnonzero(self._needs_reset)[:8].tolist()
            raise RuntimeError(
                f"environments {shown} ended; reset them with "
                "reset(options={'reset_mask': mask}) before stepping (autoreset_mode disabled)"
            )
        core = self.core
        batch = self._actions
        if (
            type(actions) is np.ndarray
            and actions.shape == batch.shape
            and actions.dtype.kind == "f"
            and actions.dtype.itemsize <= 8
        ):
            np.copyto(batch, actions)  # the common case (float32 or float64), exact
        else:
            batch = as_action_batch(actions, self.num_envs, batch.shape[1], batch)
        ended = None
        if pending and mode is AutoresetMode.NEXT_STEP:
            # Ended environments are reset below, not integrated: their actions are ignored.
            ended = np.flatnonzero(self._needs_reset)
            live = np.flatnonzero(~self._needs_reset)
            if live.size:
                core.step(batch, live)
        else:
            core.step(batch)
        reward = core.reward.copy()
        terminated = core.terminated.copy()
        truncated = np.empty(self.num_envs, dtype=bool)
        self._pending = count_step(
            self.elapsed_steps, self.max_episode_steps, terminated, truncated, self._needs_reset
        )
        if self._paths is not None:
            self._record_paths(self._all_rows)
        final: dict[str, object] | None = None
        if ended is not None:
            self._start(ended)
            reward[ended] = 0.0
            terminated[ended] = False
            truncated[ended] = False
        elif mode is AutoresetMode.SAME_STEP and self._pending:
            done = self._needs_reset.copy()
            rows = np.flatnonzero(done)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in rows.tolist():
                final_obs[i] = self._view.row(core.obs, i)
            final = {
                "final_obs": final_obs,
                "_final_obs": done,
                "final_info": self._infos(done),
                "_final_info": done,
            }
            self._start(rows)
        infos = self._infos()
        if final is not None:
            infos.update(final)
        return self._view.batch(core.obs), reward, terminated, truncated, infos

    def _record_paths(self, rows: np.ndarray) -> None:
        assert self._paths is not None
        core = self.core.row_core(0)  # rendering needs one count: its core holds every row
        self._paths.record(core.z[rows, x_column(core.n) : theta_column(core.n)], rows)

    def render(self) -> tuple[np.ndarray, ...] | None:  # type: ignore[override]
        """One ``(height, width, 3)`` uint8 frame per environment ("rgb_array") for the first
        :data:`MAX_RENDER_ENVS` (16) environments at most (a one-time warning says so when
        there are more); None without a render mode."""
        if self.render_mode is None or self._paths is None:
            return None
        if self._generators is None:
            raise RuntimeError("call reset() before render()")
        if self._renderer is None:
            self._renderer = make_renderer(
                self.core.row_core(0), self.render_mode, self.metadata["render_fps"]
            )
        count = min(self.num_envs, MAX_RENDER_ENVS)
        if count < self.num_envs and not self._warned_render:
            self._warned_render = True
            gym.logger.warn(
                f"render() draws the first {MAX_RENDER_ENVS} of {self.num_envs} environments "
                "(trailer_env.vector.MAX_RENDER_ENVS; ~1 MB per frame)"
            )
        frames = []
        for i in range(count):
            frame = self._renderer.draw(core_frame(self.core.row_core(i), i, self._paths.path(i)))
            assert frame is not None  # "rgb_array", the one vector render mode
            frames.append(frame)
        return tuple(frames)

    def __getstate__(self) -> dict[str, object]:
        """Pickle (and deep-copy) everything but the renderer (it holds pygame objects); it
        is recreated by the next :meth:`render`."""
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state

    def close_extras(self, **kwargs: object) -> None:
        """Release the renderer, if any."""
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.close()
            self._renderer = None

    def _infos(self, mask: np.ndarray | None = None) -> Info:
        """The step's infos as arrays (copies), each key ``k`` with its mask ``_k``."""
        infos = self.core.info_batch()
        if mask is None:
            if self._info_masks is None:
                self._info_masks = {f"_{key}": self._mask for key in infos}
            infos.update(self._info_masks)
        else:
            infos.update({f"_{key}": mask for key in list(infos)})
        return infos
