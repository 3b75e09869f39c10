"""The core's per-row physics: the episode's drawn factors (``randomize``) and what they set.

:class:`PhysicsMixin` is part of :class:`trailer_env.core.ConvoyCore`; the draws and the
arithmetic are :mod:`trailer_env.randomize`'s compiled functions. What ``info["params"]``
reports of them is :mod:`trailer_env.core_infos`'.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dynamics.params import ConvoyParams
from trailer_env.core_base import CoreBase
from trailer_env.generators import typed_generators
from trailer_env.randomize import PARAMETERS, apply_factors, apply_params, draw_factors


class PhysicsMixin(CoreBase):
    """Each row's physical parameters: drawn, set and reported (for ConvoyCore)."""

    def _draw_physics(
        self, rows: np.ndarray, rngs: Sequence[np.random.Generator], picks: np.ndarray | None
    ) -> None:
        """The episode's factors of ``rows`` from their generators, after the start's draws
        (:mod:`trailer_env.randomize`), and what they set: parameters, auto settings, speed
        and the parameter features."""
        assert self._draws is not None
        if picks is None:  # the Python hook drew from rngs, aligned with rows
            rngs, picks = typed_generators(rngs), np.arange(len(rows), dtype=np.int64)
        indices = np.asarray(rows, dtype=np.int64)
        columns, low, high = self._draws
        draw_factors(rngs, picks, indices, columns, low, high, self.factors)
        if self._unscaled.size:
            self.factors[np.ix_(indices, self._unscaled)] = 1.0
        apply_factors(
            indices,
            self.factors,
            self._packed,
            self.param_values,
            self.kernel_args.nominal_auto,
            self.kernel_args.row_auto,
            float(self.params.b),
            float(self.params.s_max),
            self.planar,
            self.z,
        )
        self._observe_parameters(indices)

    def _restore_physics(self, rows: np.ndarray, factors: np.ndarray) -> None:
        """Give ``rows`` recorded episode ``factors`` (rows of :attr:`factors`) and what they
        set, as :meth:`_draw_physics` did when they were drawn, except the speed: the
        recorded state already holds the scaled one."""
        self.factors[rows] = factors
        self._apply_params(rows, self._packed * factors[:, : len(PARAMETERS)])
        self._observe_parameters(rows)

    def _apply_params(self, rows: np.ndarray, values: np.ndarray) -> None:
        """``param_values`` of ``rows`` and the auto rule's settings they imply."""
        apply_params(
            rows,
            values,
            self.param_values,
            self.kernel_args.nominal_auto,
            self.kernel_args.row_auto,
            float(self.params.b),
            float(self.params.s_max),
            self.planar,
        )

    def _observe_parameters(self, rows: np.ndarray) -> None:
        """Write the parameter features of ``rows`` into the observation, where observed."""
        if self.n_param_features:
            self.obs[rows, self.param_offset :] = self.parameter_features(rows)

    def parameter_features(self, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        """The ``observe_params`` features of ``rows`` (len(rows), 7): ``log(value /
        nominal)`` of each episode's parameters, columns :data:`PARAMETERS`, whether or not
        this core observes them (a privileged policy reads them here)."""
        return np.log(self.factors[rows, : len(PARAMETERS)])

    def set_row_params(self, rows: np.ndarray, values: np.ndarray) -> None:
        """Give ``rows`` (int array) the parameters ``values`` (len(rows), 7), columns
        :data:`trailer_env.randomize.PARAMETERS`, and the auto rule's settings they imply
        (as a reset's draws would); their factors become ``values / nominal`` (1 where the
        nominal value is 0). For a core
        whose settings randomise a physical parameter (the kernels take per-row
        parameters only then); the speed and the state are left as they are.

        Raises:
            ValueError: If the core's parameters are shared, or on bad shapes or values.
        """
        if self.step_config.pv is not self.param_values:
            raise ValueError(
                "set_row_params needs per-row parameters: build the core with settings "
                "that randomise a physical parameter (randomize=...)"
            )
        indices = np.asarray(rows, dtype=np.int64)
        values = np.asarray(values, dtype=np.float64)
        if values.shape != (indices.size, len(PARAMETERS)):
            raise ValueError(
                f"values must be ({indices.size}, {len(PARAMETERS)}), got {values.shape}"
            )
        if not (np.all(np.isfinite(values)) and np.all(values > 0.0)):
            raise ValueError("parameter values must be finite and > 0")
        if indices.size and (indices.min() < 0 or indices.max() >= self.batch_size):
            raise ValueError(f"rows must be in 0..{self.batch_size - 1}")
        self._apply_params(indices, values)
        nominal = np.broadcast_to(self._packed, values.shape)
        self.factors[indices, : len(PARAMETERS)] = np.divide(
            values, nominal, out=np.ones_like(values), where=nominal != 0.0
        )

    def params_of(self, i: int) -> ConvoyParams:
        """Row ``i``'s episode parameters as a :class:`dynamics.ConvoyParams`."""
        values = dict(zip(PARAMETERS, self.param_values[i].tolist(), strict=True))
        return self.params.replace(**values)
