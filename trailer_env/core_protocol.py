"""The batch core's interface: what the environments ask of B environments of one scene.

:class:`BatchCore` is satisfied by a scene's own core (:class:`trailer_env.core.ConvoyCore`,
one number of trailers) and by :class:`trailer_env.mixed.MixedCore` (a range of them,
one scene core per count); :func:`trailer_env.mixed.build_core` returns one or the other
as the keywords ask. The single env, the vector env and the SB3 adapter use only this
interface; ``counts`` says how many trailer counts the batch holds, so no caller tests
the core's class.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from trailer_env.core import ConvoyCore
from trailer_env.core_infos import Info
from trailer_env.generators import GeneratorBank
from trailer_env.randomize import Randomization
from trailer_env.settings import EnvSettings


@runtime_checkable
class BatchCore(Protocol):
    """B environments of one scene, stepped and reset together (see :mod:`trailer_env.core`)."""

    @property
    def settings(self) -> EnvSettings:
        """The settings (of the largest count for a range of counts)."""

    @property
    def n(self) -> int:
        """The number of trailers (the largest of a range)."""

    @property
    def counts(self) -> tuple[int, ...]:
        """The trailer counts the batch's episodes run, increasing (one for a scene core)."""

    @property
    def trailers(self) -> NDArray[np.int64]:
        """Each row's number of trailers in its running episode (B,)."""

    @property
    def batch_size(self) -> int:
        """B."""

    @property
    def obs_dim(self) -> int:
        """The width of one observation."""

    @property
    def n_common(self) -> int:
        """Observation entries before the task features (the convoy's and the mass's)."""

    @property
    def n_task_features(self) -> int:
        """The scene's task features in the observation."""

    @property
    def with_pose(self) -> bool:
        """Whether the state carries the cart's pose (x, y, theta)."""

    @property
    def task_keys(self) -> tuple[str, ...]:
        """Task values ``reset(options=...)`` accepts beyond the state."""

    @property
    def randomization(self) -> Randomization | None:
        """The physics each episode draws (None: nominal)."""

    @property
    def start_scale(self) -> float:
        """The factor on the starting perturbation's size."""

    @property
    def obs(self) -> NDArray[np.float32]:
        """Observations (B, obs_dim), updated in place."""

    @property
    def reward(self) -> NDArray[np.float64]:
        """The last step's rewards (B,)."""

    @property
    def terminated(self) -> NDArray[np.bool_]:
        """Whether each row's episode ended at the last step (B,)."""

    @property
    def success(self) -> NDArray[np.bool_]:
        """Each row's success flag (B,)."""

    def count_cores(self) -> Mapping[int, ConvoyCore]:
        """The scene core of each count in :attr:`counts`."""

    def row_core(self, i: int) -> ConvoyCore:
        """The scene core holding row ``i``'s running episode."""

    def observation_bounds(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Lower and upper bounds of one observation."""

    def mirror_signs(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The mirror image's observation and action signs (None: no mirror symmetry)."""

    def set_start_scale(self, scale: float) -> None:
        """Draw the next starts with the perturbation's size times ``scale``."""

    def reset_rows(self, rows: NDArray[np.int64], rngs: Sequence[np.random.Generator]) -> None:
        """Start new episodes in ``rows``, row ``rows[j]`` drawing from ``rngs[j]``."""

    def reset_rows_from(self, rows: NDArray[np.int64], bank: GeneratorBank) -> None:
        """Start new episodes in ``rows``, row ``i`` drawing from ``bank[i]``."""

    def step(self, action: NDArray[np.float64], rows: NDArray[np.int64] | None = None) -> None:
        """Advance ``rows`` (default all) by one control step under ``action``."""

    def info_batch(self) -> Info:
        """The infos of every row as arrays (B,)."""

    def info_row(self, i: int) -> Info:
        """Row ``i``'s info (Python scalars)."""

    def info_rows(self) -> list[Info]:
        """One info per row (Python scalars)."""

    def params_batch(self) -> dict[str, NDArray[np.float64]]:
        """Each row's episode parameters as arrays (B,)."""

    def check_row_state(self, z: object, s: float = 0.0, s_dot: float = 0.0) -> NDArray[np.float64]:
        """The hand-built state :meth:`set_row_state` would set, checked; changes nothing."""

    def check_task(self, task: Mapping[str, object]) -> dict[str, object]:
        """The task values :meth:`set_row_state` would set, checked; changes nothing."""

    def set_row_state(
        self, i: int, z: object, *, s: float = 0.0, s_dot: float = 0.0, **task: object
    ) -> None:
        """Start a new episode of row ``i`` in a hand-built state."""


__all__ = ["BatchCore", "Info"]
