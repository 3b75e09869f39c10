"""The iLQR planner behind the batched policy interface: observations -> actions.

An observation holds the state in float32 (about 1e-7 relative) and, for Dock-v0, the
last axle's pose in the dock's frame rather than the plane poses: the dynamics do not
depend on where the convoy is, so :func:`dock_state_from_observation` puts the dock at
the origin (heading 0) and the cart where that pose says, and the planner plans for that
copy of the task.
"""

from __future__ import annotations

import numpy as np

from agents.oracles.ilqr import ILQRConfig, ILQRPlanner
from agents.oracles.planner import state_from_observation
from dynamics import body_poses
from trailer_env.core import ConvoyCore
from trailer_env.scenes.dock import DISTANCE_SCALE, DockCore
from trailer_env.settings import EnvSettings


def dock_state_from_observation(
    obs: np.ndarray, settings: EnvSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(z, act, target)`` of Dock-v0 observations (B, 2n+8): z (B, n+5) with the cart's
    pose, the dock at the origin ``target = (0, 0, 0)``.

    Raises:
        ValueError: In planar mode, or for observations of another length.
    """
    n = settings.n_trailers
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    if batch.shape[1] != 2 * n + 8:
        raise ValueError(f"Dock-v0 observations with n = {n} have {2 * n + 8} entries, "
                         f"got {batch.shape[1]}")  # fmt: skip
    z_core, act = state_from_observation(batch, settings)
    base = 2 * n + 4
    last_x = batch[:, base] * DISTANCE_SCALE
    last_y = batch[:, base + 1] * DISTANCE_SCALE
    error = np.arctan2(batch[:, base + 2], batch[:, base + 3])
    alpha = z_core[:, 2 : 2 + n]
    # theta_last = theta_cart - sum(alpha) (dynamics.body_poses): turn, then translate.
    theta = error + np.sum(alpha, axis=1)
    xs, ys, _ = body_poses(settings.params.l, np.zeros_like(theta), np.zeros_like(theta),
                           theta, alpha)  # fmt: skip
    z = np.column_stack([z_core, last_x - xs[:, -1], last_y - ys[:, -1], theta])
    return z, act, np.zeros((batch.shape[0], 3))


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
        if settings.action_mode == "planar":
            raise ValueError("the planner drives the rail actuator, not action_mode='planar'")
        self.core_class = core_class
        self.settings = settings
        self.config = config
        self.planner: ILQRPlanner | None = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.atleast_2d(np.asarray(obs))
        task: dict[str, np.ndarray] = {}
        if issubclass(self.core_class, DockCore):
            z, act, task["target"] = dock_state_from_observation(batch, self.settings)
        else:
            z, act = state_from_observation(batch, self.settings)
        if self.planner is None or self.planner.batch_size != z.shape[0]:
            self.planner = ILQRPlanner(self.core_class, self.settings, z.shape[0], self.config)
        return self.planner.plan(z, act, task).astype(np.float32)


__all__ = ["ILQRPolicy", "dock_state_from_observation"]
