"""The iLQR planner behind the batched policy interface: observations -> actions.

An observation holds the state in float32 (about 1e-7 relative) and the scene's task as
its record decodes it (:attr:`agents.oracles.scenes.SceneOracle.observation_state`; for
Dock-v0 the last axle's pose in the dock's frame, planned as a copy of the task with the
dock at the origin).
"""

from __future__ import annotations

import numpy as np

from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.rail import require_rail
from agents.oracles.scenes import scene_oracle
from trailer_env.core import ConvoyCore
from trailer_env.settings import EnvSettings


class ILQRPolicy:
    """:class:`~agents.oracles.ilqr.ILQRPlanner` as a batched policy (the ``ilqr`` baseline).

    The batch size is fixed by the first call (a new size builds a new planner). With the
    config's ``reuse`` the planner warm-starts each row from its previous plan; a row whose
    episode restarted is not detected, which costs little: the LQR's rollout is a
    candidate at every step.
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        config: ILQRConfig | None = None,
    ) -> None:
        require_rail(settings)
        self.core_class = core_class
        self.observation_state = scene_oracle(core_class).observation_state
        self.settings = settings
        self.config = config
        self.planner: ILQRPlanner | None = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.atleast_2d(np.asarray(obs))
        z, act, task = self.observation_state(batch, self.settings)
        if self.planner is None or self.planner.batch_size != z.shape[0]:
            self.planner = ILQRPlanner(self.core_class, self.settings, z.shape[0], self.config)
        return self.planner.plan(z, act, task).astype(np.float32)


__all__ = ["ILQRPolicy"]
