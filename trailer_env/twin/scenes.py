"""The twin's state and the scenes' outcomes: reward, cost, success and termination.

Each scene's formulas restate its core's (:mod:`trailer_env.scenes`): Reverse's
``reverse_rows``, Coast's ``coast_outcome``, and the hooks of Heading and Dock after a
step (``_update_task``, ``_advance``, ``_is_success``, ``_is_failed``, the default
``_is_terminated``, :class:`~trailer_env.core.ShapedCore`'s reward). A shaped scene's
previous potential is the potential of the state the step starts from (the core keeps it
so between steps), so the state needs no copy of it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from dynamics.columns import ALPHA, ETA, ETA_DOT, OMEGA, XI, XI_DOT, U
from trailer_env.core import ConvoyCore
from trailer_env.scenes import coast, dock, heading, reverse
from trailer_env.twin.params import TwinParams
from trailer_env.twin.physics import physics_step


class TwinState(NamedTuple):
    """What the kernel's step reads, as float64 tensors with leading axis B.

    Attributes:
        z: The convoy state (u, omega, alpha_1..alpha_n[, x, y, theta]).
        act: The mass state (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot).
        task: The scene's task values: Heading's target heading (B, 1), Dock's target
            (x, y, heading) (B, 3); (B, 0) for Reverse and Coast.
        hold: Heading's count of consecutive steps within the tolerance (B,); 0 elsewhere.
    """

    z: Tensor
    act: Tensor
    task: Tensor
    hold: Tensor

    @classmethod
    def from_core(
        cls,
        core: ConvoyCore,
        rows: np.ndarray | None = None,
        device: torch.device | str | None = None,
    ) -> TwinState:
        """The state of ``rows`` (default all) of a batch core, copied."""
        index = slice(None) if rows is None else np.asarray(rows, dtype=np.int64)
        z = core.z[index]
        task = np.zeros((z.shape[0], 0))
        hold = np.zeros(z.shape[0])
        if core.scene == "Heading":
            task = core.target_heading[index][:, None]  # type: ignore[attr-defined]
            hold = core.hold_count[index].astype(np.float64)  # type: ignore[attr-defined]
        elif core.scene == "Dock":
            task = core.target[index]  # type: ignore[attr-defined]

        def tensor(array: np.ndarray) -> Tensor:
            return torch.tensor(np.array(array, dtype=np.float64), device=device)

        return cls(tensor(z), tensor(core.act[index]), tensor(task), tensor(hold))


class TwinOutcome(NamedTuple):
    """Everything one step gives (:func:`step_outcome`), leading axis B."""

    state: TwinState
    reward: Tensor
    cost: Tensor
    terminated: Tensor
    success: Tensor
    failed: Tensor
    jackknifed: Tensor
    substeps: Tensor


def wrap_angle(angle: Tensor) -> Tensor:
    """:func:`trailer_env.scenes.heading.wrap_angle`: angles wrapped to [-pi, pi)."""
    return torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi


def _mean_cos(z: Tensor, n: int) -> Tensor:
    return torch.cos(z[:, ALPHA : ALPHA + n]).sum(dim=1) / n


def _dock_frame(state: TwinState, p: TwinParams) -> tuple[Tensor, Tensor, Tensor]:
    """The last axle in the dock's frame (x, y) and its heading error (DockCore._update_task)."""
    z, n, target = state.z, p.n, state.task
    theta = z[:, n + 4]
    headings = theta[:, None] - torch.cumsum(z[:, ALPHA : ALPHA + n], dim=1)
    x = z[:, n + 2] - p.l * torch.cos(headings).sum(dim=1)
    y = z[:, n + 3] - p.l * torch.sin(headings).sum(dim=1)
    last = headings[:, -1] if n > 0 else theta
    dx, dy = x - target[:, 0], y - target[:, 1]
    cos_dock, sin_dock = torch.cos(target[:, 2]), torch.sin(target[:, 2])
    along = cos_dock * dx + sin_dock * dy
    across = -sin_dock * dx + cos_dock * dy
    return along, across, wrap_angle(last - target[:, 2])


def potential(state: TwinState, p: TwinParams) -> Tensor:
    """The shaped scenes' potential of every row (ShapedCore._potential); 0 for Reverse."""
    z, n = state.z, p.n
    if p.scene == "Coast":
        omega_term = coast.OMEGA_WEIGHT * torch.clamp(z[:, OMEGA].abs(), max=1.0)
        if n == 0:
            return -omega_term
        return -coast.ANGLE_WEIGHT * (1.0 - _mean_cos(z, n)) - omega_term
    if p.scene == "Heading":
        error = wrap_angle(state.task[:, 0] - z[:, n + 4])
        return -heading.HEADING_WEIGHT * error.abs()
    if p.scene == "Dock":
        along, across, error = _dock_frame(state, p)
        return -torch.hypot(along, across) - dock.HEADING_WEIGHT * error.abs()
    return torch.zeros_like(z[:, U])


def _shaped(
    p: TwinParams,
    now: Tensor,
    before: Tensor,
    cost: Tensor,
    success: Tensor,
    jackknifed: Tensor,
    failed: Tensor,
) -> Tensor:
    """:func:`trailer_env.shaping.shaped_reward` with the scene's constants."""
    return (
        now
        - before
        - p.time_penalty
        - p.band_penalty * cost
        + p.success_bonus * success.to(now.dtype)
        - p.fold_penalty * jackknifed.to(now.dtype)
        - p.failure_penalty * failed.to(now.dtype)
    )


def step_outcome(state: TwinState, action: Tensor, params: TwinParams) -> TwinOutcome:
    """One control step of ``state`` under ``action`` (B, action_dim): :func:`step` with the
    success, failure and jackknife flags and the substeps taken."""
    p = params
    physics = physics_step(state.z, state.act, action, p)
    z, jackknifed, cost = physics.z, physics.jackknifed, physics.cost
    n = p.n
    hold = state.hold
    after = TwinState(z, physics.act, state.task, hold)
    no = torch.zeros_like(jackknifed)
    if p.scene == "Reverse":
        failed = jackknifed | (z[:, U].detach() >= -p.min_reverse_speed)
        straightness = _mean_cos(z, n) if n > 0 else torch.ones_like(z[:, U])
        omega = z[:, OMEGA]
        reward = (
            straightness
            - reverse.TURN_WEIGHT * torch.clamp(omega * omega, max=1.0)
            - p.band_penalty * cost
        ) - p.fold_penalty * failed.to(z.dtype)
        return TwinOutcome(
            after, reward, cost, failed, ~failed, failed, jackknifed, physics.substeps
        )
    before = potential(state, p)
    failed = no
    if p.scene == "Coast":
        success = z[:, OMEGA].detach().abs() < coast.SUCCESS_OMEGA
        if n > 0:
            angles = z[:, ALPHA : ALPHA + n].detach().abs() < coast.SUCCESS_ANGLE
            success = success & angles.all(dim=1)
    elif p.scene == "Heading":
        error = wrap_angle(state.task[:, 0] - z[:, n + 4]).detach()
        holding = (error.abs() < heading.HEADING_TOLERANCE) & ~jackknifed
        hold = torch.where(holding, hold + 1.0, torch.zeros_like(hold))
        after = after._replace(hold=hold)
        success = hold >= heading.HOLD_STEPS
    else:  # Dock
        along, across, error = _dock_frame(after, p)
        distance = torch.hypot(along, across).detach()
        success = (distance < dock.SUCCESS_RADIUS) & (error.detach().abs() < dock.SUCCESS_HEADING)
        failed = (along.detach() < -dock.MISS_DEPTH) & ~success
    terminated = jackknifed | success | failed
    reward = _shaped(p, potential(after, p), before, cost, success, jackknifed, failed)
    return TwinOutcome(
        after, reward, cost, terminated, success, failed, jackknifed, physics.substeps
    )


def step(
    state: TwinState, action: Tensor, params: TwinParams
) -> tuple[TwinState, Tensor, Tensor, Tensor]:
    """``(next_state, reward, cost, terminated)`` of the scene's control step (gymnax style).

    ``action`` is (B, action_dim) float64 on the state's device. Nothing is checked: a
    non-finite action gives non-finite results (the kernel refuses it). The package
    docstring says what the gradient does where the kernel branches.
    """
    outcome = step_outcome(state, action, params)
    return outcome.state, outcome.reward, outcome.cost, outcome.terminated


class TwinStep:
    """:func:`step` bound to its parameters: ``TwinStep(params)(state, action)``."""

    def __init__(self, params: TwinParams) -> None:
        if not isinstance(params, TwinParams):
            raise TypeError(f"params must be a TwinParams, got {type(params).__name__}")
        self.params = params

    def __call__(
        self, state: TwinState, action: Tensor
    ) -> tuple[TwinState, Tensor, Tensor, Tensor]:
        return step(state, action, self.params)

    def outcome(self, state: TwinState, action: Tensor) -> TwinOutcome:
        """:func:`step_outcome` with these parameters."""
        return step_outcome(state, action, self.params)


def observe(state: TwinState, params: TwinParams) -> Tensor:
    """The flat observation of every row in float64 (the env's is its float32 rounding),
    without the parameter features of ``observe_params``."""
    p = params
    z, act, n = state.z, state.act, p.n
    alpha = z[:, ALPHA : ALPHA + n]
    speed = p.rail_speed_max
    if p.mode == "planar":
        mass = [
            (act[:, XI] - p.b) / p.s_max,
            act[:, ETA] / p.s_max,
            torch.clamp(act[:, XI_DOT] / speed, -1.0, 1.0),
            torch.clamp(act[:, ETA_DOT] / speed, -1.0, 1.0),
        ]
    else:
        mass = [act[:, ETA] / p.s_max, torch.clamp(act[:, ETA_DOT] / speed, -1.0, 1.0)]
    parts = [z[:, :2], torch.sin(alpha), torch.cos(alpha), torch.stack(mass, dim=1)]
    if p.scene == "Heading":
        error = wrap_angle(state.task[:, 0] - z[:, n + 4])
        fraction = torch.clamp(state.hold, max=heading.HOLD_STEPS) / heading.HOLD_STEPS
        parts.append(torch.stack([torch.sin(error), torch.cos(error), fraction], dim=1))
    elif p.scene == "Dock":
        along, across, error = _dock_frame(state, p)
        scale = dock.DISTANCE_SCALE
        parts.append(
            torch.stack([along / scale, across / scale, torch.sin(error), torch.cos(error)], 1)
        )
    return torch.cat(parts, dim=1)
