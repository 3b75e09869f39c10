"""The twin's physics: the actuator, the auto substep rule, RK4 on the field, the rail clamp.

Each function restates, operation for operation where it matters, its compiled original:
:func:`field` is :func:`dynamics._kernel.field_row` (the O(n) hitch recurrences of
``_hitch_step``, ``_hitch_totals`` and ``_accelerations``), :func:`substep_counts` calls
:func:`trailer_env.substeps.auto_substeps` itself, :func:`guarded_accel` is
:func:`trailer_env.actuator.guard_accel` and :func:`physics_step` is the pipeline of
:func:`trailer_env.kernels.step_serial`. The package docstring says what the gradient
does at their branches.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch
from torch import Tensor

from dynamics.columns import ETA, ETA_DOT, OMEGA, XI, XI_DDOT, XI_DOT, U
from trailer_env.substeps import auto_substeps
from trailer_env.twin.params import TwinParams

#: The kernel's margin of the fold test (``dynamics._kernel._FOLD_MARGIN``).
FOLD_MARGIN = 1e-12


def _min(a: Tensor, b: Tensor) -> Tensor:
    """Python's ``min(a, b)``: ``b`` where ``b < a``; the gradient goes to the one taken."""
    return torch.where(b < a, b, a)


def _max(a: Tensor, b: Tensor) -> Tensor:
    """Python's ``max(a, b)``: ``b`` where ``b > a``; the gradient goes to the one taken."""
    return torch.where(b > a, b, a)


def field(
    z: Tensor, mass: tuple[Tensor, ...], params: TwinParams, with_pose: bool | None = None
) -> Tensor:
    """d z / dt (B, width) for the mass ``(xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)``."""
    p = params
    n = p.n
    pose = p.with_pose if with_pose is None else with_pose
    xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot = mass
    u = z[:, U]
    w = z[:, OMEGA]
    l = p.l
    ones = torch.ones_like(u)
    zeros = torch.zeros_like(u)
    prefix_c2, prefix_c, sum_prefix_c2 = ones, ones, zeros
    g_weighted_s, sum_g_s, g_weighted_t = zeros, zeros, zeros
    tail_c2, sum_tail_c2, c1s1 = ones, zeros, zeros
    s_prev, c_prev = zeros, ones
    rates = []
    alpha = z[:, 2 : 2 + n]
    sines, cosines = torch.sin(alpha), torch.cos(alpha)
    for k in range(n):
        s, c = sines[:, k], cosines[:, k]
        c2 = c * c
        if k == 0:
            a_k = -s / l
            c1s1 = c * s
        else:
            a_k = prefix_c * (s_prev - c_prev * s) / l
            prefix_c = prefix_c * c_prev
            tail_c2 = tail_c2 * c2
        sum_tail_c2 = sum_tail_c2 + tail_c2
        g = a_k * (-2.0 * s * c * prefix_c2)
        g_weighted_s = c2 * g_weighted_s + g
        sum_g_s = sum_g_s + g_weighted_s
        g_weighted_t = c2 * g_weighted_t + g
        prefix_c2 = prefix_c2 * c2
        sum_prefix_c2 = sum_prefix_c2 + prefix_c2
        s_prev, c_prev = s, c
        rates.append(a_k * u + w if k == 0 else a_k * u)
    J_l2 = p.J / (l * l)
    r_trailers = p.m * sum_prefix_c2 + J_l2 * (1.0 - prefix_c2)
    dr_dalpha1 = -2.0 * c1s1 * (p.m * sum_tail_c2 - J_l2 * tail_c2)
    sum_a_dr = p.m * sum_g_s - J_l2 * g_weighted_t
    M, a, mu = p.M, p.a, p.mu
    I0 = p.J0 + M * a * a
    R = M + r_trailers
    phi_u = -0.5 * sum_a_dr * u * u - 0.5 * dr_dalpha1 * u * w + M * a * w * w
    phi_w = -M * a * u * w
    ax_rest = -2.0 * w * eta_dot + xi_ddot - w * w * xi
    ay_rest = eta_ddot + 2.0 * w * xi_dot + w * u - w * w * eta
    b0 = phi_u - mu * ax_rest
    b1 = phi_w - mu * (xi * ay_rest - eta * ax_rest)
    m00 = R + mu
    m01 = -mu * eta
    m11 = I0 + mu * (xi * xi + eta * eta)
    det = m00 * m11 - m01 * m01
    columns = [(m11 * b0 - m01 * b1) / det, (m00 * b1 - m01 * b0) / det, *rates]
    if pose:
        theta = z[:, n + 4]
        columns += [u * torch.cos(theta), u * torch.sin(theta), w]
    return torch.stack(columns, dim=1)


def rail_accel_upper(s: Tensor, v: Tensor, p: TwinParams) -> Tensor:
    """:func:`trailer_env.actuator.rail_accel_upper`: the largest acceleration in [-A, A]
    that keeps the mass able to stop before +s_max (branches as the original's)."""
    A, dt, s_max = p.accel_max, p.dt, p.s_max
    room = s_max - s
    qa = dt * dt / (2.0 * A)
    qb = 0.5 * dt * dt + v * dt / A
    qc = v * dt + v * v / (2.0 * A) - room
    disc = qb * qb - 4.0 * qa * qc
    real = disc >= 0.0
    root = torch.sqrt(torch.where(real, disc, torch.ones_like(disc)))
    positive = qb > 0.0
    denominator = torch.where(positive, qb + root, torch.ones_like(qb))
    upper = torch.where(positive, -2.0 * qc / denominator, (-qb + root) / (2.0 * qa))
    first = real & (upper >= -v / dt)
    clipped = torch.clamp(upper, -A, A)
    has_room = room > 0.0
    safe_room = torch.where(has_room, room, torch.ones_like(room))
    turning = torch.where(
        has_room, torch.clamp(-v * v / (2.0 * safe_room), min=-A), torch.full_like(v, -A)
    )
    stopping = torch.clamp(-v / dt, max=A)
    return torch.where(first, clipped, torch.where(v > 0.0, turning, stopping))


def guarded_accel(accel: Tensor, s: Tensor, v: Tensor, p: TwinParams) -> Tensor:
    """:func:`trailer_env.actuator.guard_accel`: clipped to [-A, A] and to the rail guard."""
    upper = rail_accel_upper(s, v, p)
    lower = -rail_accel_upper(-s, -v, p)
    A = p.accel_max
    bounded = _min(_max(accel, torch.full_like(accel, -A)), torch.full_like(accel, A))
    if p.straight_through:  # the value clipped, the gradient as if it were not
        bounded = accel + (bounded - accel).detach()
    return _max(_min(bounded, upper), lower)


def servo_accel(target: Tensor, s: Tensor, v: Tensor, p: TwinParams) -> Tensor:
    """:func:`trailer_env.actuator.servo_accel`. The linear part is written ``w e`` (equal
    to the original's ``copysign(w |e|, e)``), so its gradient holds at ``e = 0``."""
    error = target - s
    w = p.frequency
    size = error.abs()
    linear = w * size <= torch.sqrt(p.accel_max * size)
    braking = torch.sqrt(p.accel_max * torch.where(linear, torch.ones_like(size), size))
    desired = torch.where(linear, w * error, torch.copysign(braking, error))
    return guarded_accel(4.0 * w * (desired - v), s, v, p)


def mass_accelerations(action: Tensor, act: Tensor, p: TwinParams) -> tuple[Tensor, Tensor]:
    """(xi_ddot, eta_ddot) the actuator commands for ``action`` (B, action_dim)."""
    command = torch.clamp(action[:, 0], -1.0, 1.0)
    if p.straight_through:
        command = action[:, 0] + (command - action[:, 0]).detach()
    if p.mode == "servo":
        return act[:, XI_DDOT], servo_accel(command * p.s_max, act[:, ETA], act[:, ETA_DOT], p)
    if p.mode == "accel":
        accel = command * p.accel_max
        return act[:, XI_DDOT], guarded_accel(accel, act[:, ETA], act[:, ETA_DOT], p)
    if p.mode == "planar":
        forward = servo_accel(command * p.s_max, act[:, XI] - p.b, act[:, XI_DOT], p)
        lateral = torch.clamp(action[:, 1], -1.0, 1.0)
        return forward, servo_accel(lateral * p.s_max, act[:, ETA], act[:, ETA_DOT], p)
    raise ValueError(f"unknown action mode {p.mode!r}")


@torch.no_grad()
def substep_counts(z: Tensor, act: Tensor, p: TwinParams) -> Tensor:
    """Substeps of every row (int64, (B,)): fixed, or the kernel's own auto rule
    (:func:`trailer_env.substeps.auto_substeps`, run on a host copy: the count is
    piecewise constant, so it carries no gradient, and the same compiled rule keeps the
    twin's counts the kernel's; per-row parameters get per-row settings, as the kernel's
    draws give them)."""
    if p.substeps is not None:
        return torch.full((z.shape[0],), p.substeps, dtype=torch.int64, device=z.device)
    counts = np.empty(z.shape[0], dtype=np.int64)
    by_row = p.auto_by_row(z.shape[0])
    auto_substeps(
        z.detach().cpu().numpy(),
        act.detach().cpu().numpy(),
        np.asarray(p.auto, dtype=np.float64) if by_row is None else by_row,
        counts,
    )
    return torch.from_numpy(counts).to(z.device)


def _folded(z: Tensor, n: int, fold_angle: float) -> Tensor:
    """The kernel's fold test after a substep: any wrapped |alpha_k| >= fold_angle."""
    if n == 0 or not fold_angle < math.inf:
        return torch.zeros(z.shape[0], dtype=torch.bool, device=z.device)
    alpha = z[:, 2 : 2 + n].detach()
    near = alpha.abs().amax(dim=1) >= fold_angle - FOLD_MARGIN
    wrapped = torch.atan2(torch.sin(alpha), torch.cos(alpha)).abs() >= fold_angle
    return near & wrapped.any(dim=1)


def rk4(
    z: Tensor, act: Tensor, accelerations: tuple[Tensor, Tensor], substeps: int, p: TwinParams
) -> tuple[Tensor, Tensor]:
    """RK4 over ``dt`` in ``substeps`` equal substeps (:func:`dynamics._kernel.advance_row`):
    (new z, folded at the end of some substep)."""
    xi0, eta0, xi_dot0, eta_dot0 = act[:, XI], act[:, ETA], act[:, XI_DOT], act[:, ETA_DOT]
    xi_ddot, eta_ddot = accelerations

    def at(tau: float) -> tuple[Tensor, ...]:
        return (
            xi0 + xi_dot0 * tau + 0.5 * xi_ddot * tau * tau,
            eta0 + eta_dot0 * tau + 0.5 * eta_ddot * tau * tau,
            xi_dot0 + xi_ddot * tau,
            eta_dot0 + eta_ddot * tau,
            xi_ddot,
            eta_ddot,
        )

    h = p.dt / substeps
    half_h, sixth_h = 0.5 * h, h / 6.0
    folded = torch.zeros(z.shape[0], dtype=torch.bool, device=z.device)
    for step in range(substeps):
        t0 = step * h
        t_mid, t1 = t0 + 0.5 * h, t0 + h
        deriv = field(z, at(t0), p)
        total = deriv
        deriv = field(z + half_h * deriv, at(t_mid), p)
        total = total + 2.0 * deriv
        deriv = field(z + half_h * deriv, at(t_mid), p)
        total = total + 2.0 * deriv
        deriv = field(z + h * deriv, at(t1), p)
        z = z + sixth_h * (total + deriv)
        folded = folded | _folded(z, p.n, p.fold_angle)
    return z, folded


class PhysicsResult(NamedTuple):
    """One control step's physics (leading axis B)."""

    z: Tensor
    act: Tensor
    #: A wrapped hitch angle reached the fold angle at the end of some substep.
    jackknifed: Tensor
    #: 1.0 inside the singular band (``min_(k<n-1) |cos alpha_k| < singular_band``), else 0.
    cost: Tensor
    substeps: Tensor


def physics_step(z: Tensor, act: Tensor, action: Tensor, p: TwinParams) -> PhysicsResult:
    """The kernel's control step of ``z`` (B, width) and ``act`` (B, 6) under ``action``
    (B, action_dim): actuator, substeps, RK4 with the fold test, the mass, the rail clamp."""
    xi_ddot, eta_ddot = mass_accelerations(action, act, p)
    held = torch.stack(
        [act[:, XI], act[:, ETA], act[:, XI_DOT], act[:, ETA_DOT], xi_ddot, eta_ddot], dim=1
    )
    counts = substep_counts(z, held, p)
    values = counts.unique()
    if values.numel() == 1:
        z_new, folded = rk4(z, held, (xi_ddot, eta_ddot), int(values.item()), p)
    else:  # rows grouped by their count, as the kernel's blocks
        z_new = torch.empty_like(z)
        folded = torch.zeros(z.shape[0], dtype=torch.bool, device=z.device)
        for value in values.tolist():
            rows = torch.nonzero(counts == value).squeeze(1)
            part, part_folded = rk4(
                z[rows], held[rows], (xi_ddot[rows], eta_ddot[rows]), int(value), p.rows(rows)
            )
            z_new = z_new.index_copy(0, rows, part)
            folded[rows] = part_folded
    dt = p.dt
    xi = act[:, XI] + act[:, XI_DOT] * dt + 0.5 * xi_ddot * dt * dt
    eta = act[:, ETA] + act[:, ETA_DOT] * dt + 0.5 * eta_ddot * dt * dt
    act_new = torch.stack(
        [
            torch.clamp(xi, p.b - p.s_max, p.b + p.s_max),
            torch.clamp(eta, -p.s_max, p.s_max),
            act[:, XI_DOT] + xi_ddot * dt,
            act[:, ETA_DOT] + eta_ddot * dt,
            xi_ddot,
            eta_ddot,
        ],
        dim=1,
    )
    return PhysicsResult(z_new, act_new, folded, band_cost(z_new, p), counts)


def band_cost(z: Tensor, p: TwinParams) -> Tensor:
    """1.0 where ``min_(k<n-1) |cos alpha_k| < singular_band`` (the kernel's cost), else 0."""
    n = p.n
    if n <= 1:
        return torch.zeros(z.shape[0], dtype=z.dtype, device=z.device)
    margin = torch.cos(z[:, 2 : 1 + n].detach()).abs().amin(dim=1).clamp(max=1.0)
    return (margin < p.singular_band).to(z.dtype)
