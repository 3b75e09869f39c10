"""A certificate's action records replayed: the planner's certified row without planning.

Each episode seeded ``s`` plays the committed record of start ``s``
(:func:`agents.artifacts.certificates.committed_actions`), step by step, open-loop. A
start without a record (the planner found no safe sequence: "open" or "not
recoverable") plays the zero action, so its episode counts as the planner failing.
Exact only on the environment the records were made in (the default settings of the
scene and n): the records are a trace, not a controller.
"""

from __future__ import annotations

import numpy as np


class RecordedPolicy:
    """Replays ``records[seed]`` in the episodes seeded ``first_seed``, ``first_seed + 1``, ...

    Args:
        records: Start seed -> (T, action_dim) float64 actions.
        first_seed: The seed of the batch's first episode (episode ``i`` is ``first_seed + i``).
        action_dim: The environment's action dimension.
    """

    def __init__(self, records: dict[int, np.ndarray], first_seed: int, action_dim: int) -> None:
        self.records = records
        self.first_seed = first_seed
        self.action_dim = action_dim
        self.step = 0
        self._table: np.ndarray | None = None

    def _episode_table(self, count: int) -> np.ndarray:
        """(count, longest record, action_dim): each episode's record, zeros after its end."""
        length = max((len(record) for record in self.records.values()), default=0)
        table = np.zeros((count, length, self.action_dim))
        for row in range(count):  # once per batch: records are per start
            record = self.records.get(self.first_seed + row)
            if record is not None:
                table[row, : len(record)] = record
        return table

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        count = np.atleast_2d(obs).shape[0]
        if self._table is None or self._table.shape[0] != count:
            self._table = self._episode_table(count)
        step = self.step
        self.step += 1
        if step >= self._table.shape[1]:
            return np.zeros((count, self.action_dim))
        return self._table[:, step].copy()
