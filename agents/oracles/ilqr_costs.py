"""The costs the iLQR planner (:mod:`agents.oracles.ilqr`) minimises, one per scene.

Every cost is a sum of squared residuals read from a batched core
(:class:`trailer_env.core.ConvoyCore`) after ``refresh()`` or ``step()``, so that the
scene's own task arrays (Dock's ``dock_xy`` and ``dock_heading_error``, the singular
margin, ...) define it and a copy of the core evaluates it on any state: the stage cost
of a state is ``sum(stage_residuals(core) ** 2)``, the terminal cost adds
``sum(terminal_residuals(z, act, index) ** 2)``. Squared residuals give the planner a
Gauss-Newton Hessian (``2 J^T J``, never indefinite) from first derivatives alone.

Residuals (``sqrt(weight) * feature``):

* every scene: the hitch angles, the turning rate, the mass's position ``s / s_max``;
  hinges ``max(0, |alpha_k| - barrier_angle)`` (the fold at ``fold_angle``),
  ``max(0, |s| / s_max - stroke_fraction)`` (the rail's ends),
  ``max(0, band + band_pad - margin)`` (the singular band) and, for scenes that fail
  when the convoy stops reversing (Reverse-v1), ``max(0, u + min_speed + speed_pad)``;
* a scene's record (:data:`agents.oracles.scenes.SCENE_ORACLES`) adds its task
  residuals: Dock-v0 the last axle's lateral offset from the dock line and its heading
  error (both in the dock's frame), so the convoy tracks the line that ends on the dock;
* the terminal residuals are ``L^T x`` with ``P = L L^T`` the LQR's Riccati matrix
  (:func:`agents.oracles.planner.riccati_matrices`) at the design speed nearest the
  plan's final speed, on ``x = (omega, alpha, s, s_dot)``: the regulator's cost-to-go,
  so that a plan ends where the convoy can still be held.

A rollout also pays what squared residuals cannot say: ``failure + failure_per_step *
(steps left)`` when the episode ends without success (a fold, a missed dock, a stop),
and nothing after it ends in success (the episode is over).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from agents.oracles.planner import riccati_matrices
from agents.oracles.scenes import scene_oracle
from dynamics.columns import ALPHA, ETA, ETA_DOT, OMEGA, U
from trailer_env.controllers import DESIGN_SPEEDS
from trailer_env.core import ConvoyCore
from trailer_env.settings import EnvSettings


@dataclass(frozen=True)
class CostWeights:
    """Weights of the planner's cost (per control step; all >= 0, finite).

    Attributes:
        angle, omega, rail: Of alpha_k^2, omega^2 and (s / s_max)^2.
        control: Of the planned acceleration fraction squared (keeps the problem strictly
            convex in the control).
        barrier, barrier_angle: Of the hinge on |alpha_k| beyond ``barrier_angle`` (rad).
        stroke, stroke_fraction: Of the hinge on |s| / s_max beyond ``stroke_fraction``:
            a mass parked near the rail's end has no stroke left to steer with.
        band, band_pad: Of the hinge on the singular margin below ``band + band_pad``.
        speed, speed_pad: Of the hinge on the reversing speed within ``speed_pad`` (m/s)
            of the scene's minimum (scenes with one).
        lateral, heading: Of Dock's lateral offset (m) and heading error (rad).
        terminal: Factor on the terminal cost-to-go ``x^T P x``.
        failure, failure_per_step: A rollout that ends without success pays
            ``failure + failure_per_step * (steps left in the horizon)``.
    """

    angle: float = 1.0
    omega: float = 0.1
    rail: float = 0.05
    control: float = 1e-3
    barrier: float = 1000.0
    barrier_angle: float = 0.9
    stroke: float = 0.0
    stroke_fraction: float = 0.7
    band: float = 200.0
    band_pad: float = 0.1
    speed: float = 1000.0
    speed_pad: float = 0.15
    lateral: float = 0.0
    heading: float = 0.0
    terminal: float = 10.0
    failure: float = 1000.0
    failure_per_step: float = 100.0

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)):
                raise TypeError(f"{field.name} must be a real number, got {value!r}")
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{field.name} must be finite and >= 0, got {value!r}")


def scene_horizon(core_class: type[ConvoyCore]) -> int:
    """The default horizon (steps) for a scene, its record's
    (:data:`agents.oracles.scenes.SCENE_ORACLES`): 100 (5 s) for Dock, 60 (3 s) otherwise.

    Dock's approach lasts 4-6 s; planned over 3 s, a hard start (validation seed 50000,
    0.58 m off the line) drove the mass to the rail's end and folded, over 5 s it docked.
    """
    return scene_oracle(core_class).horizon


def scene_weights(core_class: type[ConvoyCore]) -> CostWeights:
    """The default weights for a scene, :class:`CostWeights` with its record's changes
    (:data:`agents.oracles.scenes.SCENE_ORACLES`): survival for Reverse, goal-reaching
    for the others.

    Coast weighs the turning rate like the angles (its success needs both small);
    Dock adds the dock line and keeps the convoy's own shape weights small, so that
    steering onto the line may bend it, and weighs the mass's position ten times more
    (with 0.05 the mass drifted to a rail end on the way and the convoy folded). Both
    keep the terminal factor at 1: Reverse's 10 (the regulator's cost-to-go outweighing
    a 3 s horizon) lost Dock and Coast starts on validation seeds 50000-50019 (19 -> 18
    docked, 20 -> 18 straightened), while with 1 Reverse-v1 (n = 2) lost 2 of 20 that
    10 keeps safe.
    """
    return replace(CostWeights(), **scene_oracle(core_class).weights)


#: The weights that scale residuals (their square roots).
_ROOTED = ("angle", "omega", "rail", "barrier", "stroke", "band", "speed", "lateral", "heading")


class SceneCost:
    """The residuals of one scene's cost (see the module), evaluated on a core's rows.

    Args:
        core_class: The scene's core class (its record chooses the task terms).
        settings: The environment's settings (the Riccati matrices, the thresholds).
        weights: The weights; default :func:`scene_weights`.
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        weights: CostWeights | None = None,
    ) -> None:
        if weights is not None and not isinstance(weights, CostWeights):
            raise TypeError(f"weights must be CostWeights, got {type(weights).__name__}")
        self.weights = weights or scene_weights(core_class)
        self.settings = settings
        self.n = settings.n_trailers
        self.task_residuals = scene_oracle(core_class).task_residuals
        self.min_speed = float(getattr(core_class, "min_reverse_speed", 0.0))
        # Both directions: Coast's convoys may move forwards.
        self.speeds = np.concatenate([-DESIGN_SPEEDS, DESIGN_SPEEDS])
        riccati = riccati_matrices(settings, self.speeds) * self.weights.terminal
        # P = L L^T; tiny jitter keeps the factorisation defined if a design degenerated.
        jitter = 1e-12 * np.eye(riccati.shape[1])
        self.factors = np.linalg.cholesky(riccati + jitter)
        w = self.weights
        self.size = (
            2 * self.n + 3 + (self.n > 1) + (self.min_speed > 0.0) + len(self.task_residuals)
        )
        self.terminal_size = self.n + 3
        self._root = {name: float(np.sqrt(getattr(w, name))) for name in _ROOTED}

    def speed_index(self, speed: np.ndarray) -> np.ndarray:
        """Index (B,) of the design speed nearest each of ``speed`` (B,): the terminal
        matrix a plan ending at that speed uses."""
        return np.abs(np.asarray(speed)[:, None] - self.speeds[None, :]).argmin(axis=1)

    def stage_residuals(self, core: ConvoyCore) -> np.ndarray:
        """Residuals (B, size) of every row of ``core``'s current state."""
        n = self.n
        root = self._root
        w = self.weights
        z = core.z
        alpha = z[:, ALPHA : ALPHA + n]
        stroke = core.act[:, ETA : ETA + 1] / core.params.s_max
        columns = [
            root["angle"] * alpha,
            root["omega"] * z[:, OMEGA : OMEGA + 1],
            root["rail"] * stroke,
            root["barrier"] * np.maximum(np.abs(alpha) - w.barrier_angle, 0.0),
            root["stroke"] * np.maximum(np.abs(stroke) - w.stroke_fraction, 0.0),
        ]
        if n > 1:  # the margin looks at the hitches k < n only (trailer_env.kernels.observe)
            gap = self.settings.singular_band + w.band_pad - core.singular_margin
            columns.append(root["band"] * np.maximum(gap, 0.0)[:, None])
        if self.min_speed > 0.0:
            excess = z[:, U] + self.min_speed + w.speed_pad
            columns.append(root["speed"] * np.maximum(excess, 0.0)[:, None])
        for name, feature in self.task_residuals:  # task arrays are current after refresh/step
            columns.append(root[name] * feature(core)[:, None])
        return np.concatenate(columns, axis=1)

    def terminal_residuals(self, z: np.ndarray, act: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Residuals (B, n+3) ``L^T x`` of the terminal cost of core rows ``z``, ``act``
        (as :attr:`ConvoyCore.z`, :attr:`ConvoyCore.act`), with the matrices ``index``."""
        n = self.n
        state = np.column_stack(
            [z[:, OMEGA], z[:, ALPHA : ALPHA + n], act[:, ETA], act[:, ETA_DOT]]
        )
        return np.einsum("bji,bj->bi", self.factors[index], state)


__all__ = ["CostWeights", "SceneCost", "scene_horizon", "scene_weights"]
