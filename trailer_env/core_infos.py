"""The core's ``info`` dicts: per environment, per batch and per row for SB3.

:class:`InfoMixin` is part of :class:`trailer_env.core.ConvoyCore`; :data:`INFO_FIELDS`
is the one table of the keys.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from trailer_env.json_types import JSONObject
from trailer_env.randomize import Randomization

#: The ``info`` keys of every environment and the core arrays behind them (None:
#: ``actuator_work``, derived as ``energy - energy0``); the single env, the vector env
#: and the SB3 adapter all build their infos from this table.
INFO_FIELDS: tuple[tuple[str, str | None], ...] = (
    ("cost", "cost"),
    ("singular_margin", "singular_margin"),
    ("energy", "energy"),
    ("actuator_work", None),
    ("is_success", "success"),
    ("jackknifed", "jackknifed"),
)


class InfoMixin:
    """The ``info`` of :class:`trailer_env.core.ConvoyCore`'s environments."""

    if TYPE_CHECKING:  # what the methods read of the core (set by ConvoyCore.__init__)
        energy: np.ndarray
        energy0: np.ndarray
        randomization: Randomization | None
        _info_arrays: list[tuple[str, np.ndarray | None]] | None

        def params_info(self, i: int) -> dict[str, float]: ...

        def params_batch(self) -> dict[str, np.ndarray]: ...

    def _info_sources(self) -> list[tuple[str, np.ndarray | None]]:
        # The arrays are updated in place for the core's life, so they are looked up once.
        if self._info_arrays is None:
            self._info_arrays = [
                (key, None if name is None else getattr(self, name)) for key, name in INFO_FIELDS
            ]
        return self._info_arrays

    def info_row(self, i: int) -> JSONObject:
        """The ``info`` dict of environment ``i`` (Python scalars), keys :data:`INFO_FIELDS`,
        and ``params`` (:meth:`params_info`, a dict) when the physics are randomised."""
        info: JSONObject = {
            key: self.energy.item(i) - self.energy0.item(i) if array is None else array.item(i)
            for key, array in self._info_sources()
        }
        if self.randomization is not None:
            info["params"] = self.params_info(i)
        return info

    def info_batch(self) -> JSONObject:
        """The same quantities as arrays (B,) (copies); ``params`` is a dict of arrays
        (:meth:`params_batch`)."""
        infos: JSONObject = {}
        for key, array in self._info_sources():
            infos[key] = np.subtract(self.energy, self.energy0) if array is None else array.copy()
        if self.randomization is not None:
            infos["params"] = self.params_batch()
        return infos

    def info_rows(self) -> list[JSONObject]:
        """One ``info`` dict per environment (Python scalars), as SB3's ``VecEnv`` wants."""
        batch = self.info_batch()
        batch.pop("params", None)
        columns = [values.tolist() for values in batch.values()]
        rows = [dict(zip(batch, values, strict=True)) for values in zip(*columns, strict=True)]
        if self.randomization is not None:
            for i, row in enumerate(rows):
                row["params"] = self.params_info(i)
        return rows
