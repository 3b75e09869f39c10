"""The core's ``info`` dicts: per environment, per batch and per row for SB3.

:class:`InfoMixin` is part of :class:`trailer_env.core.ConvoyCore`; :data:`INFO_FIELDS`
is the one table of the keys.
"""

from __future__ import annotations

import numpy as np

from trailer_env.core_base import CoreBase
from trailer_env.randomize import PARAMETERS, SPEED

#: An ``info`` dict of the environments: the keys of :data:`INFO_FIELDS` (Python scalars
#: or arrays), and ``params`` (a dict of them) with randomised physics.
Info = dict[str, object]

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


class InfoMixin(CoreBase):
    """The ``info`` of :class:`trailer_env.core.ConvoyCore`'s environments."""

    def _info_sources(self) -> list[tuple[str, np.ndarray | None]]:
        # The arrays are updated in place for the core's life, so they are looked up once.
        if self._info_arrays is None:
            self._info_arrays = [
                (key, None if name is None else getattr(self, name)) for key, name in INFO_FIELDS
            ]
        return self._info_arrays

    def info_row(self, i: int) -> Info:
        """The ``info`` dict of environment ``i`` (Python scalars), keys :data:`INFO_FIELDS`,
        and ``params`` (:meth:`params_info`, a dict) when the physics are randomised."""
        info: Info = {
            key: self.energy.item(i) - self.energy0.item(i) if array is None else array.item(i)
            for key, array in self._info_sources()
        }
        if self.randomization is not None:
            info["params"] = self.params_info(i)
        return info

    def info_batch(self) -> Info:
        """The same quantities as arrays (B,) (copies); ``params`` is a dict of arrays
        (:meth:`params_batch`)."""
        infos: Info = {}
        for key, array in self._info_sources():
            infos[key] = np.subtract(self.energy, self.energy0) if array is None else array.copy()
        if self.randomization is not None:
            infos["params"] = self.params_batch()
        return infos

    def info_rows(self) -> list[Info]:
        """One ``info`` dict per environment (Python scalars), as SB3's ``VecEnv`` wants."""
        sources = self._info_sources()
        keys = [key for key, _ in sources]
        columns = [
            np.subtract(self.energy, self.energy0).tolist() if array is None else array.tolist()
            for _, array in sources
        ]
        rows: list[Info] = [
            dict(zip(keys, values, strict=True)) for values in zip(*columns, strict=True)
        ]
        if self.randomization is not None:
            for i, row in enumerate(rows):
                row["params"] = self.params_info(i)
        return rows

    def params_info(self, i: int) -> dict[str, float]:
        """Row ``i``'s episode parameters (``info["params"]``): the seven randomisable
        :class:`dynamics.ConvoyParams` fields' values and ``speed_factor``, the factor on
        the start's speed (1 where not randomised)."""
        values = self.param_values[i].tolist()
        return {
            **dict(zip(PARAMETERS, values, strict=True)),
            "speed_factor": float(self.factors[i, SPEED]),
        }

    def params_batch(self) -> dict[str, np.ndarray]:
        """:meth:`params_info` of every row as arrays (B,) (copies)."""
        infos = {name: self.param_values[:, k].copy() for k, name in enumerate(PARAMETERS)}
        infos["speed_factor"] = self.factors[:, SPEED].copy()
        return infos
