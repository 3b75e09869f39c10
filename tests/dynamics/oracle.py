"""Independent full-coordinate oracle for the n-trailer convoy with a moving mass.

This module re-derives the equations of motion from scratch, without importing
``dynamics`` and without using any formula of physics.md sections 3-5 or 9
other than the geometry of the bodies:

* Full coordinates ``q = (x, y, theta_0, theta_1, ..., theta_n)``: cart axle
  midpoint ``(x, y)``, cart heading ``theta_0`` and the trailers' headings.
* Trailer ``i``'s axle midpoint is
  ``(x - l sum_{j<=i} cos(theta_j), y - l sum_{j<=i} sin(theta_j))``.
* Bodies: the cart (mass ``M`` at distance ``a`` ahead of its axle midpoint,
  inertia ``J0`` about its centre of mass), each trailer (mass ``m`` at its axle
  midpoint, inertia ``J`` about it) and a point mass ``mu`` at body-frame
  position ``(xi, eta)`` from the cart's axle midpoint, whose motion relative
  to the cart is prescribed (a rheonomic constraint: the actuator's force does
  no virtual work).

The kinetic energy ``T(q, q_dot, xi, eta, xi_dot, eta_dot)`` is written with
sympy from each body's own position; Lagrange's equations with multipliers for
the ``n + 1`` no-slip constraints ``x_i_dot sin(theta_i) - y_i_dot cos(theta_i) = 0``
(body 0 is the cart at ``(x, y)``) give the saddle-point system

    [[Mass, -B^T], [B, 0]] [q_ddot; lambda] = [-h; -B_dot q_dot],

where ``Mass = d^2T/dq_dot^2`` and ``h = (d/dt dT/dq_dot)|_{q_ddot=0} - dT/dq``
(the total time derivative includes the prescribed ``xi, eta`` and their
derivatives). The symbolic derivation is cached per ``n``.

The reduced state ``z = (u, omega, alpha_1..alpha_n)`` is mapped to a full
state by ``theta_k = theta - (alpha_1 + ... + alpha_k)``,
``x_dot = u cos(theta)``, ``y_dot = u sin(theta)``, ``theta_dot = omega`` and
trailer angular velocities obtained by solving the constraints numerically;
the full accelerations are mapped back by ``u_dot = x_ddot cos(theta) +
y_ddot sin(theta)``, ``omega_dot = theta_ddot``,
``alpha_1_dot = theta_0_dot - theta_1_dot`` and
``alpha_k_dot = theta_(k-1)_dot - theta_k_dot``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

__all__ = [
    "FullModel",
    "OracleParams",
    "actuator_power_planar",
    "energy_planar",
    "energy_rail",
    "energy_rate_planar",
    "full_model",
    "full_state",
    "reduced_rhs_planar",
    "reduced_rhs_rail",
    "solve_full",
]

_PARAM_NAMES = ("M", "J0", "a", "m", "J", "l", "mu")


@dataclass(frozen=True)
class OracleParams:
    """Physical parameters used by the oracle (no validation, no warnings).

    Attributes:
        n_trailers: Number of trailers n >= 0.
        M: Cart mass.
        J0: Cart moment of inertia about its centre of mass.
        a: Signed distance from the cart's axle midpoint to its centre of mass.
        m: Mass of each trailer (at its axle midpoint).
        J: Moment of inertia of each trailer about its axle midpoint.
        l: Hitch rod length.
        mu: Moving point mass (0 = none).
    """

    n_trailers: int
    M: float
    J0: float
    a: float
    m: float
    J: float
    l: float
    mu: float

    @classmethod
    def from_any(cls, params: Any) -> OracleParams:
        """Copy the fields of any object exposing them as attributes (duck typing).

        Args:
            params: An object with attributes ``n_trailers, M, J0, a, m, J, l, mu``
                (for example ``dynamics.ConvoyParams``, which is not imported here).

        Returns:
            The corresponding OracleParams.
        """
        if isinstance(params, OracleParams):
            return params
        return cls(
            n_trailers=int(params.n_trailers),
            **{name: float(getattr(params, name)) for name in _PARAM_NAMES},
        )

    def values(self) -> tuple[float, ...]:
        """Parameter values in the order the lambdified functions expect."""
        return tuple(float(getattr(self, name)) for name in _PARAM_NAMES)


@dataclass(frozen=True)
class FullModel:
    """Lambdified full-coordinate model for one number of trailers.

    Every function takes ``(q, qd, ext, par)`` as flat float arguments spliced in
    this order: ``q`` (n+3), ``qd`` (n+3), then the function-specific extras,
    then the 7 parameters ``(M, J0, a, m, J, l, mu)``.

    Attributes:
        n: Number of trailers.
        mass: ``(q, xi, eta, par) -> (n+3, n+3)`` mass matrix d^2T/dq_dot^2.
        h: ``(q, qd, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot, par) -> (n+3,)``
            velocity-dependent and prescribed-motion terms of Lagrange's equations.
        B: ``(q) -> (n+1, n+3)`` constraint matrix (constraints are ``B qd = 0``).
        Bdot_qd: ``(q, qd) -> (n+1,)`` the term ``(dB/dt) qd``.
        T: ``(q, qd, xi, eta, xi_dot, eta_dot, par) -> float`` kinetic energy.
        T_rate: ``(q, qd, qdd, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot, par)``
            exact total time derivative of T.
        acc_mu: ``(q, qd, qdd, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot) -> (2,)``
            world-frame acceleration of the moving mass.
    """

    n: int
    mass: Callable[..., Any]
    h: Callable[..., Any]
    B: Callable[..., Any]
    Bdot_qd: Callable[..., Any]
    T: Callable[..., Any]
    T_rate: Callable[..., Any]
    acc_mu: Callable[..., Any]


@functools.cache
def full_model(n: int) -> FullModel:
    """Derive (with sympy) and lambdify the full-coordinate model for n trailers.

    Args:
        n: Number of trailers, n >= 0.

    Returns:
        The lambdified model (cached per n).
    """
    if n < 0:
        raise ValueError(f"n must be >= 0, got {n}")
    dim = n + 3
    q = sp.symbols(f"q0:{dim}", real=True)
    qd = sp.symbols(f"qd0:{dim}", real=True)
    qdd = sp.symbols(f"qdd0:{dim}", real=True)
    xi, eta, xid, etad, xidd, etadd = sp.symbols("xi eta xid etad xidd etadd", real=True)
    M, J0, a, m, J, rod, mu = sp.symbols("M J0 a m J l mu", real=True)
    par = (M, J0, a, m, J, rod, mu)

    def ddt(expr: sp.Expr, with_qdd: bool = True) -> sp.Expr:
        """Total time derivative along (q, qd, qdd) and the prescribed (xi, eta)."""
        out = sp.Integer(0)
        for k in range(dim):
            out += sp.diff(expr, q[k]) * qd[k]
            if with_qdd:
                out += sp.diff(expr, qd[k]) * qdd[k]
        out += sp.diff(expr, xi) * xid + sp.diff(expr, xid) * xidd
        out += sp.diff(expr, eta) * etad + sp.diff(expr, etad) * etadd
        return out

    x, y, th = q[0], q[1], q[2:]
    th_dot = qd[2:]

    # Positions of the bodies' reference points (geometry only).
    cart_axle = sp.Matrix([x, y])
    cart_cm = cart_axle + a * sp.Matrix([sp.cos(th[0]), sp.sin(th[0])])
    trailer_pos = []
    for i in range(1, n + 1):
        trailer_pos.append(
            sp.Matrix(
                [
                    x - rod * sum(sp.cos(th[j]) for j in range(1, i + 1)),
                    y - rod * sum(sp.sin(th[j]) for j in range(1, i + 1)),
                ]
            )
        )
    mass_pos = cart_axle + sp.Matrix(
        [
            xi * sp.cos(th[0]) - eta * sp.sin(th[0]),
            xi * sp.sin(th[0]) + eta * sp.cos(th[0]),
        ]
    )

    def vel(p: sp.Matrix) -> sp.Matrix:
        return p.applyfunc(lambda e: ddt(e, with_qdd=False))

    def sq(v: sp.Matrix) -> sp.Expr:
        return v[0] ** 2 + v[1] ** 2

    # Kinetic energy, each body from its own position.
    T = sp.Rational(1, 2) * (M * sq(vel(cart_cm)) + J0 * th_dot[0] ** 2)
    for i in range(1, n + 1):
        T += sp.Rational(1, 2) * (m * sq(vel(trailer_pos[i - 1])) + J * th_dot[i] ** 2)
    v_mass = vel(mass_pos)
    T += sp.Rational(1, 2) * mu * sq(v_mass)

    # Lagrange's equations: Mass qdd + h = B^T lambda.
    p_mom = [sp.diff(T, qd[k]) for k in range(dim)]
    mass = sp.Matrix(dim, dim, lambda r, c: sp.diff(p_mom[r], qd[c]))
    h = sp.Matrix([ddt(p_mom[k], with_qdd=False) - sp.diff(T, q[k]) for k in range(dim)])

    # No-slip constraints, body 0 = cart at (x, y), body i = trailer i.
    body_pos = [cart_axle, *trailer_pos]
    cons = []
    for i, pos in enumerate(body_pos):
        v = vel(pos)
        cons.append(v[0] * sp.sin(th[i]) - v[1] * sp.cos(th[i]))
    cons_v = sp.Matrix(cons)
    B = cons_v.jacobian(sp.Matrix(qd))
    Bdot_qd = cons_v.jacobian(sp.Matrix(q)) * sp.Matrix(qd)

    T_rate = ddt(T, with_qdd=True)
    acc_mu = v_mass.applyfunc(lambda e: ddt(e, with_qdd=True))

    def lam(args: tuple[Any, ...], expr: Any) -> Callable[..., Any]:
        return sp.lambdify(args, expr, modules="numpy", cse=True)

    return FullModel(
        n=n,
        mass=lam((*q, xi, eta, *par), mass),
        h=lam((*q, *qd, xi, eta, xid, etad, xidd, etadd, *par), h),
        B=lam((*q, rod), B),
        Bdot_qd=lam((*q, *qd, rod), Bdot_qd),
        T=lam((*q, *qd, xi, eta, xid, etad, *par), T),
        T_rate=lam((*q, *qd, *qdd, xi, eta, xid, etad, xidd, etadd, *par), T_rate),
        acc_mu=lam((*q, *qd, *qdd, xi, eta, xid, etad, xidd, etadd), acc_mu),
    )


def _as_matrix(value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Broadcast a lambdified result (which may contain python scalars) to floats."""
    out = np.empty(shape)
    arr = np.asarray(value, dtype=object)
    for idx in np.ndindex(*shape):
        out[idx] = float(arr[idx])
    return out


def full_state(
    params: Any,
    z: np.ndarray,
    x: float = 0.0,
    y: float = 0.0,
    theta: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Map a reduced state to a full state satisfying every no-slip constraint.

    Args:
        params: Parameters (any object with the OracleParams fields).
        z: Reduced state ``(u, omega, alpha_1..alpha_n)``, shape (n+2,).
        x: Cart axle midpoint abscissa (arbitrary: the dynamics is SE(2)-invariant).
        y: Cart axle midpoint ordinate.
        theta: Cart heading.

    Returns:
        ``(q, qd)``, each of shape (n+3,). The trailers' angular velocities are the
        unique solution of the trailers' constraints (solved numerically).
    """
    p = OracleParams.from_any(params)
    n = p.n_trailers
    z = np.asarray(z, dtype=float)
    if z.shape != (n + 2,):
        raise ValueError(f"z must have shape ({n + 2},), got {z.shape}")
    u, omega, alpha = z[0], z[1], z[2:]
    q = np.empty(n + 3)
    q[0], q[1], q[2] = x, y, theta
    q[3:] = theta - np.cumsum(alpha)
    qd = np.zeros(n + 3)
    qd[0], qd[1], qd[2] = u * np.cos(theta), u * np.sin(theta), omega
    if n > 0:
        B = _as_matrix(full_model(n).B(*q, p.l), (n + 1, n + 3))
        rhs = -B[1:, :3] @ qd[:3]
        qd[3:] = np.linalg.solve(B[1:, 3:], rhs)
    return q, qd


def solve_full(
    params: Any,
    q: np.ndarray,
    qd: np.ndarray,
    xi: float,
    eta: float,
    xi_dot: float = 0.0,
    eta_dot: float = 0.0,
    xi_ddot: float = 0.0,
    eta_ddot: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Solve the saddle-point system for the full accelerations and multipliers.

    Args:
        params: Parameters (any object with the OracleParams fields).
        q: Full configuration, shape (n+3,).
        qd: Full velocity (should satisfy the constraints), shape (n+3,).
        xi: Longitudinal body-frame position of the moving mass.
        eta: Lateral body-frame position of the moving mass.
        xi_dot: Its rate.
        eta_dot: Its rate.
        xi_ddot: Its second derivative.
        eta_ddot: Its second derivative.

    Returns:
        ``(qdd, lam)`` of shapes (n+3,) and (n+1,).
    """
    p = OracleParams.from_any(params)
    n = p.n_trailers
    fm = full_model(n)
    dim = n + 3
    par = p.values()
    mass = _as_matrix(fm.mass(*q, xi, eta, *par), (dim, dim))
    h = _as_matrix(fm.h(*q, *qd, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot, *par), (dim, 1))
    B = _as_matrix(fm.B(*q, p.l), (n + 1, dim))
    bq = _as_matrix(fm.Bdot_qd(*q, *qd, p.l), (n + 1, 1))
    kkt = np.zeros((dim + n + 1, dim + n + 1))
    kkt[:dim, :dim] = mass
    kkt[:dim, dim:] = -B.T
    kkt[dim:, :dim] = B
    rhs = np.concatenate([-h[:, 0], -bq[:, 0]])
    sol = np.linalg.solve(kkt, rhs)
    return sol[:dim], sol[dim:]


def _full_motion(
    params: Any,
    z: np.ndarray,
    act: tuple[float, float, float, float, float, float],
    pose: tuple[float, float, float],
) -> tuple[OracleParams, np.ndarray, np.ndarray, np.ndarray]:
    """Embed z at ``pose`` and solve for the full accelerations.

    Args:
        params: Parameters (any object with the OracleParams fields).
        z: Reduced state, shape (n+2,).
        act: ``(xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)`` of the moving mass.
        pose: ``(x, y, theta)`` used to embed z.

    Returns:
        ``(p, q, qd, qdd)``: the parameters and the full state and accelerations.
    """
    p = OracleParams.from_any(params)
    q, qd = full_state(p, z, *pose)
    qdd, _ = solve_full(p, q, qd, *act)
    return p, q, qd, qdd


def _reduce(qdd: np.ndarray, qd: np.ndarray, theta: float) -> np.ndarray:
    """Map full accelerations (and velocities) to the reduced state's derivative."""
    n = qd.size - 3
    out = np.empty(n + 2)
    out[0] = qdd[0] * np.cos(theta) + qdd[1] * np.sin(theta)
    out[1] = qdd[2]
    th_dot = qd[2:]
    out[2:] = th_dot[:-1] - th_dot[1:]
    return out


def reduced_rhs_planar(
    params: Any,
    z: np.ndarray,
    xi: float,
    eta: float,
    xi_dot: float = 0.0,
    eta_dot: float = 0.0,
    xi_ddot: float = 0.0,
    eta_ddot: float = 0.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Reduced vector field dz/dt from the full model, planar actuator.

    Args:
        params: Parameters (any object with the OracleParams fields).
        z: Reduced state ``(u, omega, alpha_1..alpha_n)``, shape (n+2,).
        xi: Body-frame longitudinal position of the moving mass.
        eta: Body-frame lateral position of the moving mass.
        xi_dot: Its rate.
        eta_dot: Its rate.
        xi_ddot: Its second derivative.
        eta_ddot: Its second derivative.
        pose: ``(x, y, theta)`` of the cart used to embed z (result must not depend
            on it).

    Returns:
        dz/dt, shape (n+2,).
    """
    act = (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)
    _, _, qd, qdd = _full_motion(params, z, act, pose)
    return _reduce(qdd, qd, pose[2])


def reduced_rhs_rail(
    params: Any,
    z: np.ndarray,
    b: float,
    s: float = 0.0,
    s_dot: float = 0.0,
    s_ddot: float = 0.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> np.ndarray:
    """Reduced vector field for the lateral rail: ``xi = b`` fixed, ``eta = s``.

    Args:
        params: Parameters (any object with the OracleParams fields).
        z: Reduced state, shape (n+2,).
        b: Longitudinal position of the rail.
        s: Lateral position of the mass.
        s_dot: Its rate.
        s_ddot: Its second derivative.
        pose: ``(x, y, theta)`` used to embed z.

    Returns:
        dz/dt, shape (n+2,).
    """
    return reduced_rhs_planar(params, z, b, s, 0.0, s_dot, 0.0, s_ddot, pose=pose)


def energy_planar(
    params: Any,
    z: np.ndarray,
    xi: float,
    eta: float,
    xi_dot: float = 0.0,
    eta_dot: float = 0.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> float:
    """Total kinetic energy (all bodies and the moving mass) of a reduced state.

    The arguments are those of :func:`reduced_rhs_planar` (the accelerations do not enter).

    Returns:
        The kinetic energy.
    """
    p = OracleParams.from_any(params)
    q, qd = full_state(p, z, *pose)
    return float(full_model(p.n_trailers).T(*q, *qd, xi, eta, xi_dot, eta_dot, *p.values()))


def energy_rail(params: Any, z: np.ndarray, b: float, s: float = 0.0, s_dot: float = 0.0) -> float:
    """Total kinetic energy for the lateral rail (``xi = b``, ``eta = s``).

    Args:
        params: Parameters (any object with the OracleParams fields).
        z: Reduced state, shape (n+2,).
        b: Longitudinal position of the rail.
        s: Lateral position of the mass.
        s_dot: Its rate.

    Returns:
        The kinetic energy.
    """
    return energy_planar(params, z, b, s, 0.0, s_dot)


def energy_rate_planar(
    params: Any,
    z: np.ndarray,
    xi: float,
    eta: float,
    xi_dot: float = 0.0,
    eta_dot: float = 0.0,
    xi_ddot: float = 0.0,
    eta_ddot: float = 0.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> float:
    """Exact dT/dt along the oracle's own motion (symbolic chain rule).

    The arguments are those of :func:`reduced_rhs_planar`.

    Returns:
        The rate of change of the total kinetic energy.
    """
    act = (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)
    p, q, qd, qdd = _full_motion(params, z, act, pose)
    return float(full_model(p.n_trailers).T_rate(*q, *qd, *qdd, *act, *p.values()))


def actuator_power_planar(
    params: Any,
    z: np.ndarray,
    xi: float,
    eta: float,
    xi_dot: float = 0.0,
    eta_dot: float = 0.0,
    xi_ddot: float = 0.0,
    eta_ddot: float = 0.0,
    pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> float:
    """Power of the actuator, from the oracle's own motion of the moving mass.

    The only horizontal force on the mass is the actuator's, ``F = mu a`` with
    ``a`` the mass's world acceleration; its reaction acts on the cart. The pair
    does work at rate ``F . v_rel``, where ``v_rel`` is the mass's velocity
    relative to the cart's material point it occupies, i.e. ``(xi_dot, eta_dot)``
    rotated to the world frame. The arguments are those of :func:`reduced_rhs_planar`.

    Returns:
        The actuator's power.
    """
    act = (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)
    p, q, qd, qdd = _full_motion(params, z, act, pose)
    acc = _as_matrix(full_model(p.n_trailers).acc_mu(*q, *qd, *qdd, *act), (2, 1))[:, 0]
    th0 = q[2]
    v_rel = np.array(
        [
            xi_dot * np.cos(th0) - eta_dot * np.sin(th0),
            xi_dot * np.sin(th0) + eta_dot * np.cos(th0),
        ]
    )
    return float(p.mu * acc @ v_rel)
