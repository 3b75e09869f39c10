"""The sampling planner behind the batched policy interface: the ``mpc`` baseline.

:class:`MPCPolicy` reads the state an observation holds (:func:`state_from_observation`)
and plans every row with :class:`agents.oracles.planner.SamplingPlanner`
(``agents.evaluate --policy mpc``); the iLQR planner's counterpart is
:mod:`agents.oracles.ilqr_policy`.
"""

from __future__ import annotations

import numpy as np

from agents.oracles.planner import PlannerConfig, SamplingPlanner
from agents.oracles.rail import require_rail
from dynamics.columns import ETA, ETA_DOT, XI
from trailer_env.core import ConvoyCore
from trailer_env.settings import EnvSettings


def state_from_observation(obs: np.ndarray, settings: EnvSettings) -> tuple[np.ndarray, np.ndarray]:
    """The state (z, act) an observation of a rail-mode scene holds (float32 rounding).

    Raises:
        ValueError: In planar mode (the observation's layout differs).
    """
    require_rail(settings)
    n = settings.n_trailers
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    z = np.column_stack(
        [batch[:, :2], np.arctan2(batch[:, 2 : 2 + n], batch[:, 2 + n : 2 + 2 * n])]
    )
    act = np.zeros((batch.shape[0], 6))
    act[:, XI] = settings.params.b
    act[:, ETA] = batch[:, 2 + 2 * n] * settings.params.s_max
    act[:, ETA_DOT] = batch[:, 3 + 2 * n] * settings.rail_speed_max
    return z, act


class MPCPolicy:
    """The planner behind the batched policy interface (observations -> actions).

    The batch size is fixed by the first call. Between calls the planner keeps each
    row's warm start; rows whose observation says a new episode began are not detected
    (the LQR's sequence is a candidate at every step, so a stale warm start costs
    little). It reads the state from the observation (float32: about 1e-7 relative).
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        config: PlannerConfig | None = None,
    ) -> None:
        self.core_class = core_class
        self.settings = settings
        self.config = config
        self.planner: SamplingPlanner | None = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z, act = state_from_observation(obs, self.settings)
        if self.planner is None or self.planner.batch_size != z.shape[0]:
            self.planner = SamplingPlanner(self.core_class, self.settings, z.shape[0], self.config)
        return self.planner.plan(z, act).astype(np.float32)


__all__ = ["MPCPolicy", "state_from_observation"]
