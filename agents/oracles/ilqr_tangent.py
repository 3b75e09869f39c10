"""Exact Jacobians of the iLQR planner's step: forward-mode autograd through the twin.

The planner's step maps its state ``x = (z, s, s_dot)`` (the core's row plus the mass's
rail position and velocity) and its control ``v`` (the rail acceleration as a fraction of
its bound) to the next state: the actuator's inverse (the action the planner sends,
``settings.actuator.command_for_accel``, the same function the planner calls, here on
tensors), the actuator, RK4 with each row's substep count, and the mass's exact advance
with the rail clamp. :class:`StepTangent` runs that pipeline on the differentiable twin
(:mod:`trailer_env.twin`, held to the compiled kernel by tests/trailer_env/test_twin.py)
and differentiates it by reverse-mode autograd, one backward pass over ``d`` copies of
every row (copy i seeded with the unit cotangent e_i, so its gradient is row i of the
Jacobian): every derivative exact to rounding, where finite differences of the kernel
carry an error of the order of their step (forward) or its square (central) and, across
a kink (the rail guard switching on between the nominal and a copy 1e-5 away), a slope
of the jump's size over the step. (Forward mode, ``torch.func.jvp`` under ``vmap`` over
the ``d + 1`` tangents, gave the same numbers 1.3-2.3 times slower on the CPU: its cost
per operation is the transforms', not the arithmetic's.)

Cost. The twin is torch on small arrays, so its time goes to dispatching operations,
not to arithmetic: on the CPU these Jacobians take several times the wall time of the
finite differences' one compiled step of ``d + 2`` copies
(``python -m benchmarks.ilqr_jacobians`` measures the certify search both ways). What
they buy is exactness where the planner's cost turns: the guard's and the servo's kinks.

At a kink the derivative is that of the branch the nominal takes (the twin's rule). One
exception, on purpose: a control on the box's bound (``|v| = 1``) is differentiated a
hair inside it (``|v| = 1 - 1e-9``): on the bound the actuator's own clip to
``[-A, A]`` may cut the commanded acceleration by a rounding error, which would give a
zero derivative (no control authority), while the only directions the box allows lead
inside, where the derivative is what the finite differences' one-sided copies measured.

torch is the ``agents`` extra's.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from dynamics.columns import ETA, ETA_DDOT, ETA_DOT, XI, XI_DDOT, XI_DOT
from trailer_env.core import ConvoyCore
from trailer_env.settings import EnvSettings

if TYPE_CHECKING:
    from torch import Tensor

#: How far inside the box a control on its bound is differentiated (see the module).
BOUND_INSET = 1e-9


class StepTangent:
    """Exact Jacobians ``A = d x' / d x`` and ``B = d x' / d v`` of the planner's step.

    Args:
        core_class: The scene's batch core.
        settings: The planner's derivative settings (the "rk4" integrator; the substep
            count of each row is given to :meth:`jacobians`).
        with_pose: Whether the core's rows carry the pose (x, y, theta).

    Raises:
        ImportError: Without torch (the ``agents`` extra).
        ValueError: For a scene the twin does not restate, or randomised physics.
    """

    def __init__(
        self, core_class: type[ConvoyCore], settings: EnvSettings, with_pose: bool
    ) -> None:
        try:
            import torch
        except ImportError as error:  # pragma: no cover - the extra is installed in the tests
            raise ImportError(
                "exact iLQR Jacobians need torch: pip install 'trailer-env[agents]'"
            ) from error
        from trailer_env.twin import TwinParams

        self._torch = torch
        self.settings = settings
        # The fold test is a flag (no derivative): the Jacobians skip it.
        self.params = dataclasses.replace(
            TwinParams.from_settings(settings, core_class, track_pose=with_pose),
            substeps=None,
            fold_angle=math.inf,
        )
        self.width = self.params.width
        self.d = self.width + 2

    def _next_state(self, x: Tensor, act: Tensor, groups: list[tuple[int, Tensor]]) -> Tensor:
        """The step of the rows ``x`` (R, d + 1: state then control), their mass states
        ``act`` (R, 6) for the coordinates ``x`` does not carry, the rows grouped by count."""
        from trailer_env.twin.physics import mass_accelerations, rk4

        torch = self._torch
        p = self.params
        width = self.width
        z, s, s_dot, v = x[:, :width], x[:, width], x[:, width + 1], x[:, width + 2]
        command = self.settings.actuator.command_for_accel(
            v * p.accel_max, s, s_dot, p.s_max, p.accel_max, p.frequency
        )
        mass = torch.stack(
            [act[:, XI], s, act[:, XI_DOT], s_dot, act[:, XI_DDOT], act[:, ETA_DDOT]], dim=1
        )
        xi_ddot, eta_ddot = mass_accelerations(torch.clamp(command, -1.0, 1.0)[:, None], mass, p)
        held = torch.stack([mass[:, 0], s, mass[:, 2], s_dot, xi_ddot, eta_ddot], dim=1)
        if len(groups) == 1:
            z_next, _ = rk4(z, held, (xi_ddot, eta_ddot), groups[0][0], p)
        else:  # rows grouped by their count, put back in order
            parts, rows = [], []
            for count, index in groups:
                part, _ = rk4(z[index], held[index], (xi_ddot[index], eta_ddot[index]), count, p)
                parts.append(part)
                rows.append(index)
            z_next = torch.cat(parts)[torch.argsort(torch.cat(rows))]
        dt = p.dt
        s_next = torch.clamp(s + s_dot * dt + 0.5 * eta_ddot * dt * dt, -p.s_max, p.s_max)
        return torch.cat([z_next, s_next[:, None], (s_dot + eta_ddot * dt)[:, None]], dim=1)

    def jacobians(
        self, z: np.ndarray, act: np.ndarray, control: np.ndarray, substeps: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The step's Jacobians at R rows: core rows ``z`` (R, width), mass states ``act``
        (R, 6), controls (R,) in [-1, 1], RK4 substeps (R,).

        Returns:
            ``(next_state (R, d), A (R, d, d), B (R, d))`` with ``A[r, i, j] = d x'_i /
            d x_j`` and ``B[r, i] = d x'_i / d v``, float64 numpy arrays.
        """
        torch = self._torch
        d = self.d
        rows = z.shape[0]
        inside = np.clip(control, -1.0 + BOUND_INSET, 1.0 - BOUND_INSET)
        x = np.column_stack([z, act[:, ETA], act[:, ETA_DOT], inside]).astype(np.float64)
        # Row r's copy i carries the cotangent e_i: one backward pass gives every row of
        # every Jacobian (rows are independent, so no copy's gradient mixes with another).
        copies = torch.from_numpy(np.repeat(x, d, axis=0)).requires_grad_(True)
        mass = torch.from_numpy(np.repeat(np.asarray(act, dtype=np.float64), d, axis=0))
        counts = np.repeat(np.asarray(substeps, dtype=np.int64), d)
        groups = [
            (int(count), torch.from_numpy(np.flatnonzero(counts == count)))
            for count in np.unique(counts)
        ]
        after = self._next_state(copies, mass, groups)
        cotangent = torch.eye(d, dtype=torch.float64).repeat(rows, 1)
        (gradient,) = torch.autograd.grad(after, copies, grad_outputs=cotangent)
        full = gradient.numpy().reshape(rows, d, d + 1)
        primal = after.detach().numpy()[::d]
        return primal.copy(), np.ascontiguousarray(full[:, :, :d]), full[:, :, d].copy()


__all__ = ["BOUND_INSET", "StepTangent"]
