"""A memory in the observation: ``history=k`` appends the last k observations and actions.

Under randomised physics (``randomize=``) the parameters cannot be told from one frame;
they can from the motion's response to the actions. ``history=k`` gives any policy (an
MLP of SB3, a DAgger student) that motion to read, as rapid motor adaptation's history
encoder reads it::

    env = gym.make("trailer_env/Reverse-v1", n_trailers=2, randomize="mismatch20", history=8)
    obs, info = env.reset(seed=0)  # (d + 8 (d + a),): the scene's d, then 8 frames

With ``d`` the scene's observation width (the flat observation, padded with a range of
counts; :mod:`trailer_env.mixed`) and ``a`` the action's (1 on the rail, 2 planar), the
observation at step t is, in float32::

    [ obs_t | obs_{t-1}, act_{t-1} | obs_{t-2}, act_{t-2} | ... | obs_{t-k}, act_{t-k} ]

where ``act_j`` is the action applied at step j clipped to [-1, 1] (what the convoy
got). At a start (a reset, ``set_state``, an autoreset) every past frame is the start's
observation with a zero action: the episode's first frames read as a convoy at rest
before it, and nothing leaks from the episode before. A step whose integration is
refused (FloatingPointError) leaves the memory as it was, like the state.

The window is kept by :class:`HistoryCore` around the scene's batch core, so the single
env, the vector env and the SB3 adapter give it alike and a vector env's row still
replays the single env seeded ``s + i`` bit for bit (tests/trailer_env/test_history.py).
It is a keyword of the scene, recorded in a model card's ``env_kwargs``: ``agents.evaluate``,
``score()`` and the SB3 adapter rebuild the same window for a saved model. Only
``observation="flat"`` takes it (a Dict's keys have no place for past frames).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from trailer_env.core import ConvoyCore
from trailer_env.core_infos import Info
from trailer_env.core_protocol import BatchCore
from trailer_env.generators import GeneratorBank
from trailer_env.randomize import Randomization
from trailer_env.settings import MAX_HISTORY, EnvSettings


class HistoryCore:
    """A :class:`~trailer_env.core_protocol.BatchCore` whose observation carries the last
    ``k`` observations and actions of the core it wraps (see the module docstring).

    Everything but the observation (state, rewards, infos, the row cores the planners
    read) is the wrapped core's.
    """

    def __init__(self, inner: BatchCore, k: int) -> None:
        if not 1 <= k <= MAX_HISTORY:
            raise ValueError(f"history must be in 1 .. {MAX_HISTORY}, got {k}")
        self.inner = inner
        self.k = k
        self.frame_dim = inner.obs_dim + inner.settings.action_dim
        self._obs = np.zeros((inner.batch_size, inner.obs_dim + k * self.frame_dim), np.float32)
        self._all_rows = np.arange(inner.batch_size, dtype=np.int64)

    # --------------------------------------------------------- the window
    @property
    def obs(self) -> NDArray[np.float32]:
        """Observations (B, d + k (d + a)), updated in place."""
        return self._obs

    @property
    def obs_dim(self) -> int:
        return int(self._obs.shape[1])

    def _start(self, rows: NDArray[np.int64]) -> None:
        """Fill ``rows``' windows with their new start: every frame (obs_0, 0)."""
        d = self.inner.obs_dim
        current = self.inner.obs[rows]
        frame = np.zeros((len(rows), self.frame_dim), np.float32)
        frame[:, :d] = current
        self._obs[rows] = np.concatenate([current, np.tile(frame, (1, self.k))], axis=1)

    def _push(self, rows: NDArray[np.int64] | None, action: NDArray[np.float64]) -> None:
        """Shift ``rows``' frames back by one and put (the observation before the step,
        its clipped action) first; then the new observation."""
        d, f = self.inner.obs_dim, self.frame_dim
        window = self._obs if rows is None else self._obs[rows]
        taken = action if rows is None else action[rows]
        # numpy copies overlapping slices before assigning, so the shift is exact.
        window[:, d + f :] = window[:, d : d + (self.k - 1) * f]
        window[:, d + d : d + f] = np.clip(taken, -1.0, 1.0)
        window[:, d : d + d] = window[:, :d]
        window[:, :d] = self.inner.obs if rows is None else self.inner.obs[rows]
        if rows is not None:
            self._obs[rows] = window

    def observation_bounds(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        low, high = self.inner.observation_bounds()
        ones = np.ones(self.inner.settings.action_dim, np.float32)
        frame_low, frame_high = np.concatenate([low, -ones]), np.concatenate([high, ones])
        return (
            np.concatenate([low, np.tile(frame_low, self.k)]).astype(np.float32),
            np.concatenate([high, np.tile(frame_high, self.k)]).astype(np.float32),
        )

    def mirror_signs(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        signs = self.inner.mirror_signs()
        if signs is None:
            return None
        observation, action = signs
        frame = np.concatenate([observation, action])
        return np.concatenate([observation, np.tile(frame, self.k)]), action

    # ------------------------------------------------ what changes the window
    def reset_rows(self, rows: NDArray[np.int64], rngs: Sequence[np.random.Generator]) -> None:
        self.inner.reset_rows(rows, rngs)
        self._start(np.asarray(rows, dtype=np.int64))

    def reset_rows_from(self, rows: NDArray[np.int64], bank: GeneratorBank) -> None:
        self.inner.reset_rows_from(rows, bank)
        self._start(np.asarray(rows, dtype=np.int64))

    def step(self, action: NDArray[np.float64], rows: NDArray[np.int64] | None = None) -> None:
        self.inner.step(action, rows)  # a refused step raises before the window moves
        self._push(rows, action)

    def set_row_state(
        self, i: int, z: object, *, s: float = 0.0, s_dot: float = 0.0, **task: object
    ) -> None:
        self.inner.set_row_state(i, z, s=s, s_dot=s_dot, **task)
        self._start(np.array([i], dtype=np.int64))

    # ------------------------------------------------ the wrapped core's own
    @property
    def settings(self) -> EnvSettings:
        return self.inner.settings

    @property
    def n(self) -> int:
        return self.inner.n

    @property
    def counts(self) -> tuple[int, ...]:
        return self.inner.counts

    @property
    def trailers(self) -> NDArray[np.int64]:
        return self.inner.trailers

    @property
    def batch_size(self) -> int:
        return self.inner.batch_size

    @property
    def n_common(self) -> int:
        return self.inner.n_common

    @property
    def n_task_features(self) -> int:
        return self.inner.n_task_features

    @property
    def with_pose(self) -> bool:
        return self.inner.with_pose

    @property
    def task_keys(self) -> tuple[str, ...]:
        return self.inner.task_keys

    @property
    def randomization(self) -> Randomization | None:
        return self.inner.randomization

    @property
    def start_scale(self) -> float:
        return self.inner.start_scale

    @property
    def reward(self) -> NDArray[np.float64]:
        return self.inner.reward

    @property
    def terminated(self) -> NDArray[np.bool_]:
        return self.inner.terminated

    @property
    def success(self) -> NDArray[np.bool_]:
        return self.inner.success

    def count_cores(self) -> Mapping[int, ConvoyCore]:
        return self.inner.count_cores()

    def row_core(self, i: int) -> ConvoyCore:
        return self.inner.row_core(i)

    def set_start_scale(self, scale: float) -> None:
        self.inner.set_start_scale(scale)

    def info_batch(self) -> Info:
        return self.inner.info_batch()

    def info_row(self, i: int) -> Info:
        return self.inner.info_row(i)

    def info_rows(self) -> list[Info]:
        return self.inner.info_rows()

    def params_batch(self) -> dict[str, NDArray[np.float64]]:
        return self.inner.params_batch()

    def check_row_state(self, z: object, s: float = 0.0, s_dot: float = 0.0) -> NDArray[np.float64]:
        return self.inner.check_row_state(z, s, s_dot)

    def check_task(self, task: Mapping[str, object]) -> dict[str, object]:
        return self.inner.check_task(task)
