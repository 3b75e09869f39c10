"""What the planners and certification know of each scene: one record per scene.

The environments say what a scene is (its core: reward, termination, task arrays); this
table says what the agents' oracles do with it, so that no planner branches on a scene's
name. :data:`SCENE_ORACLES` maps a core's ``scene`` (every version of it) to its
:class:`SceneOracle`; a scene without a record has no planner (:data:`NO_ORACLE`), and a
new scene that a planner should drive adds one record here.

* ``Reverse``: the sampling planner (``mpc``), its committed records (``mpc-replay``)
  and iLQR.
* ``Dock``: iLQR over 5 s with the dock line in its cost, its observations decoded with
  the dock at the origin (:func:`dock_state_from_observation`).
* ``Coast``: iLQR weighing the turning rate like the angles.

Whether a scene is survived or reached is the scene's own (its core's ``objective``,
:mod:`trailer_env.objective`); certification (:mod:`agents.certification.certify`) takes
the planner of that objective when the record names it.

Why each scene's iLQR settings are what they are is in :mod:`agents.oracles.ilqr_costs`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from agents.oracles.mpc_policy import state_from_observation
from dynamics import body_poses
from trailer_env.core import ConvoyCore
from trailer_env.registry import core_class_of
from trailer_env.scenes.dock import DISTANCE_SCALE
from trailer_env.settings import EnvSettings

#: ``(obs, settings) -> (z, act, task)``: the core state and task arrays a batch of
#: observations holds.
ObservationState = Callable[
    [np.ndarray, EnvSettings], tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]
]


def rail_state(
    obs: np.ndarray, settings: EnvSettings
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """``(z, act, {})``: :func:`agents.oracles.mpc_policy.state_from_observation` of a scene
    whose observation holds no task the planner reads."""
    z, act = state_from_observation(obs, settings)
    return z, act, {}


def dock_state_from_observation(
    obs: np.ndarray, settings: EnvSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(z, act, target)`` of Dock-v0 observations (B, 2n+8): z (B, n+5) with the cart's
    pose, the dock at the origin ``target = (0, 0, 0)``.

    An observation holds the last axle's pose in the dock's frame rather than the plane
    poses: the dynamics do not depend on where the convoy is, so the dock goes to the
    origin (heading 0) and the cart where that pose says, and the planner plans for that
    copy of the task.

    Raises:
        ValueError: In planar mode, or for observations of another length.
    """
    n = settings.n_trailers
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    if batch.shape[1] != 2 * n + 8:
        raise ValueError(
            f"Dock-v0 observations with n = {n} have {2 * n + 8} entries, got {batch.shape[1]}"
        )
    z_core, act = state_from_observation(batch, settings)
    base = 2 * n + 4
    last_x = batch[:, base] * DISTANCE_SCALE
    last_y = batch[:, base + 1] * DISTANCE_SCALE
    error = np.arctan2(batch[:, base + 2], batch[:, base + 3])
    alpha = z_core[:, 2 : 2 + n]
    # theta_last = theta_cart - sum(alpha) (dynamics.body_poses): turn, then translate.
    theta = error + np.sum(alpha, axis=1)
    xs, ys, _ = body_poses(
        settings.params.l, np.zeros_like(theta), np.zeros_like(theta), theta, alpha
    )
    z = np.column_stack([z_core, last_x - xs[:, -1], last_y - ys[:, -1], theta])
    return z, act, np.zeros((batch.shape[0], 3))


def _dock_state(
    obs: np.ndarray, settings: EnvSettings
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    z, act, target = dock_state_from_observation(obs, settings)
    return z, act, {"target": target}


def _dock_lateral(core: ConvoyCore) -> np.ndarray:
    """The last axle's offset (B,) from the dock line, in the dock's frame (m)."""
    return core.dock_xy[:, 1]  # type: ignore[attr-defined]


def _dock_heading(core: ConvoyCore) -> np.ndarray:
    """The last body's heading error (B,) from the dock's heading (rad)."""
    return core.dock_heading_error  # type: ignore[attr-defined]


@dataclass(frozen=True)
class SceneOracle:
    """What the planners and certification do with one scene.

    Attributes:
        planners: The oracle baselines that have a cost for the scene (``agents.evaluate
            --policy`` names, run only when named), in the order a default is chosen:
            the DAgger experts (:data:`agents.policies.experts.EXPERTS`) among them fit it.
        horizon: iLQR's default horizon (steps).
        weights: iLQR's cost weights that differ from
            :class:`~agents.oracles.ilqr_costs.CostWeights`' defaults (name -> value).
        task_residuals: iLQR's residuals beyond the convoy's own, in order: (the weight's
            name, ``feature(core) -> (B,)`` read after ``refresh()`` or ``step()``).
        observation_state: The state and task arrays a batch of observations holds
            (the ``ilqr`` baseline plans from them).
    """

    planners: tuple[str, ...] = ()
    horizon: int = 60
    weights: Mapping[str, float] = field(default_factory=dict)
    task_residuals: tuple[tuple[str, Callable[[ConvoyCore], np.ndarray]], ...] = ()
    observation_state: ObservationState = rail_state


#: A scene's record when it has none: no planner drives it.
NO_ORACLE = SceneOracle()

#: Scene (a core's ``scene``) -> its record.
SCENE_ORACLES: dict[str, SceneOracle] = {
    "Reverse": SceneOracle(planners=("mpc", "mpc-replay", "ilqr")),
    "Dock": SceneOracle(
        planners=("ilqr",),
        horizon=100,
        weights={
            "angle": 0.1,
            "omega": 0.05,
            "rail": 0.5,
            "lateral": 2.0,
            "heading": 2.0,
            "terminal": 1.0,
        },
        task_residuals=(("lateral", _dock_lateral), ("heading", _dock_heading)),
        observation_state=_dock_state,
    ),
    "Coast": SceneOracle(planners=("ilqr",), weights={"angle": 2.0, "omega": 2.0, "terminal": 1.0}),
}


def scene_oracle(scene: str | type[ConvoyCore]) -> SceneOracle:
    """The record of a scene: by environment id ("trailer_env/Dock-v0") or core class
    (:data:`NO_ORACLE` for a scene without one).

    Raises:
        ValueError: For an id that is not registered.
    """
    core_class = core_class_of(scene) if isinstance(scene, str) else scene
    return SCENE_ORACLES.get(core_class.scene, NO_ORACLE)


__all__ = [
    "NO_ORACLE",
    "SCENE_ORACLES",
    "ObservationState",
    "SceneOracle",
    "dock_state_from_observation",
    "rail_state",
    "scene_oracle",
]
