"""Qualitative analysis of the free convoy (physics.md sections 6-8).

Everything here is about the convoy moving by inertia: the moving mass is
switched off (``mu`` is ignored, i.e. treated as 0: every function calls the
package's ``rhs``/``energy`` with ``params.replace(mu=0.0)``), so the energy

    E = (R(alpha) u^2 + I0 omega^2) / 2

is conserved. The module offers

* the energy-torus coordinates (section 6): :func:`to_torus`, :func:`from_torus`,
  :func:`torus_field`;
* the 2^(n+1) equilibria on an energy level and their eigenvalues (section 7):
  :func:`equilibria`, with :func:`jacobian` (central differences of ``rhs``) to check them;
* the relative equilibria (circles) of the case a = 0 (section 8):
  :func:`relative_equilibria`;
* the one-trailer case with a = 0 (section 8): :func:`critical_energy`,
  :func:`period`, :func:`one_trailer_equilibria`, :func:`limiting_radius`,
  :func:`one_trailer_hitch_rate`.

Only the equations already implemented in :mod:`dynamics.model` are used:
the torus field's alpha part is ``rhs`` evaluated at :func:`from_torus`, and R
comes from :func:`dynamics.inertia_R`.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq

from dynamics.columns import ALPHA, OMEGA, U
from dynamics.model import FloatArray, energy, inertia_R, rhs
from dynamics.params import ConvoyParams

__all__ = [
    "Equilibrium",
    "RelativeEquilibrium",
    "critical_energy",
    "equilibria",
    "equilibrium_eigenvalues",
    "free_params",
    "from_torus",
    "jacobian",
    "limiting_radius",
    "one_trailer_equilibria",
    "one_trailer_hitch_rate",
    "period",
    "relative_equilibria",
    "to_torus",
    "torus_field",
]

KINDS = ("stable node", "unstable node", "saddle")  # the values of Equilibrium.kind


# ----------------------------------------------------------------------------
# Common checks
# ----------------------------------------------------------------------------


def free_params(params: ConvoyParams) -> ConvoyParams:
    """The same convoy with the moving mass removed (mu = 0).

    Raises:
        TypeError: If ``params`` is not a ConvoyParams.
    """
    if not isinstance(params, ConvoyParams):
        raise TypeError(f"params must be a ConvoyParams, got {type(params).__name__}")
    if params.mu == 0.0:
        return params
    with warnings.catch_warnings():
        # The J >= m l^2 warning was already given when params was built.
        warnings.simplefilter("ignore", UserWarning)
        return params.replace(mu=0.0)


def _finite_scalar(value: float, name: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return number


def _positive_energy(E: float) -> float:
    energy_level = _finite_scalar(E, "E")
    if energy_level <= 0.0:
        raise ValueError(f"E must be > 0 (the energy level of a moving convoy), got {E!r}")
    return energy_level


def _reduced_state(params: ConvoyParams, z: ArrayLike) -> FloatArray:
    array = np.asarray(z, dtype=np.float64)
    n = params.n_trailers
    if array.ndim == 0 or array.shape[-1] != n + 2:
        raise ValueError(
            f"z must have last axis of length n+2 = {n + 2} (u, omega, alpha_1..alpha_{n}); "
            f"got shape {array.shape}"
        )
    if not np.all(np.isfinite(array)):
        raise ValueError("z contains non-finite values (NaN or inf)")
    return array


# ----------------------------------------------------------------------------
# Section 6: the energy tori
# ----------------------------------------------------------------------------


def to_torus(params: ConvoyParams, z: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Energy-torus coordinates (E, beta, alpha) of reduced states (physics.md section 6).

    Inverts ``u = sqrt(2E/R(alpha)) cos(beta)``, ``omega = sqrt(2E/I0) sin(beta)``:

        E = (R u^2 + I0 omega^2) / 2,   beta = atan2(sqrt(I0) omega, sqrt(R) u),

    so beta lies in (-pi, pi] (beta = 0 at rest). ``mu`` is ignored.

    Args:
        params: Convoy parameters.
        z: Reduced states ``(..., n+2)``.

    Returns:
        ``E`` and ``beta`` of shape ``z.shape[:-1]``, and ``alpha`` (a copy of ``z[..., 2:]``).
    """
    free = free_params(params)
    states = _reduced_state(free, z)
    alpha = states[..., ALPHA:].copy()
    R = inertia_R(free, alpha)
    E = energy(free, states)
    beta = np.arctan2(math.sqrt(free.I0) * states[..., OMEGA], np.sqrt(R) * states[..., U])
    return np.asarray(E, dtype=np.float64), beta, alpha


def _torus_arrays(
    params: ConvoyParams, E: ArrayLike, beta: ArrayLike, alpha: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Validate and broadcast torus coordinates to a common batch shape."""
    n = params.n_trailers
    E_array = np.asarray(E, dtype=np.float64)
    beta_array = np.asarray(beta, dtype=np.float64)
    alpha_array = np.asarray(alpha, dtype=np.float64)
    if alpha_array.ndim == 0 or alpha_array.shape[-1] != n:
        raise ValueError(
            f"alpha must have last axis of length n = {n}; got shape {alpha_array.shape}"
        )
    for name, value in (("E", E_array), ("beta", beta_array), ("alpha", alpha_array)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    if np.any(E_array < 0.0):
        raise ValueError(f"E must be >= 0 (a kinetic energy), got min {E_array.min()!r}")
    try:
        batch = np.broadcast_shapes(E_array.shape, beta_array.shape, alpha_array.shape[:-1])
    except ValueError:
        raise ValueError(
            f"E {E_array.shape}, beta {beta_array.shape} and alpha's batch "
            f"{alpha_array.shape[:-1]} do not broadcast together"
        ) from None
    return (
        np.broadcast_to(E_array, batch),
        np.broadcast_to(beta_array, batch),
        np.broadcast_to(alpha_array, (*batch, n)),
    )


def from_torus(params: ConvoyParams, E: ArrayLike, beta: ArrayLike, alpha: ArrayLike) -> FloatArray:
    """Reduced state z from energy-torus coordinates (physics.md section 6, thesis 3.25).

        u = sqrt(2E / R(alpha)) cos(beta),   omega = sqrt(2E / I0) sin(beta)

    Args:
        params: Convoy parameters (``mu`` ignored).
        E: Energy level(s), >= 0.
        beta: Torus angle(s).
        alpha: Hitch angles ``(..., n)``; E, beta and alpha's batch axes broadcast.

    Returns:
        z of shape ``(*batch, n+2)``.
    """
    free = free_params(params)
    E_b, beta_b, alpha_b = _torus_arrays(free, E, beta, alpha)
    R = inertia_R(free, alpha_b)
    z = np.empty((*beta_b.shape, free.n_trailers + 2))
    z[..., U] = np.sqrt(2.0 * E_b / R) * np.cos(beta_b)
    z[..., OMEGA] = np.sqrt(2.0 * E_b / free.I0) * np.sin(beta_b)
    z[..., ALPHA:] = alpha_b
    return z


def torus_field(
    params: ConvoyParams, E: ArrayLike, beta: ArrayLike, alpha: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """The vector field on the energy torus (physics.md section 6, thesis 3.26-3.27).

        beta_dot    = -(M a / I0) sqrt(2E / R(alpha)) sin(beta)
        alpha_1_dot = sqrt(2E/I0) sin(beta) - sqrt(2E/R) sin(alpha_1) cos(beta) / l
        alpha_k_dot = sqrt(2E/R) cos(beta) A_k                        (k = 2..n)

    The alpha part is the package's ``rhs`` at :func:`from_torus` (the
    kinematics are not re-implemented); beta_dot is the closed form, which
    follows from omega_dot = -(M a / I0) u omega and the conservation of E.

    Args:
        params: Convoy parameters (``mu`` ignored).
        E, beta, alpha: Torus coordinates, as in :func:`from_torus`.

    Returns:
        ``(beta_dot, alpha_dot)`` of shapes ``batch`` and ``(*batch, n)``.
    """
    free = free_params(params)
    E_b, beta_b, alpha_b = _torus_arrays(free, E, beta, alpha)
    R = inertia_R(free, alpha_b)
    beta_dot = -(free.M * free.a / free.I0) * np.sqrt(2.0 * E_b / R) * np.sin(beta_b)
    alpha_dot = rhs(free, from_torus(free, E_b, beta_b, alpha_b))[..., ALPHA:]
    return beta_dot, alpha_dot


# ----------------------------------------------------------------------------
# Section 7: equilibria and their linearisation
# ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """An equilibrium of the free convoy on an energy level (physics.md section 7).

    Attributes:
        z: The state ``(u, 0, alpha_1..alpha_n)`` with ``alpha_k`` in {0, pi}.
        sigma: ``(sigma_0, sigma_1..sigma_n)``: sigma_0 = sign(u) (+1 forward),
            sigma_k = cos(alpha_k) (-1: trailer k folded onto its predecessor).
        eigenvalues: ``(lambda_0, lambda_1..lambda_n)`` of the linearisation on the
            torus, by the closed form of section 7 (read-only array).
        kind: "stable node" (all eigenvalues < 0), "unstable node" (all > 0) or "saddle".
        stable: Whether the equilibrium is asymptotically stable on its energy level.
    """

    z: FloatArray
    sigma: tuple[int, ...]
    eigenvalues: FloatArray
    kind: str
    stable: bool


def equilibrium_eigenvalues(params: ConvoyParams, E: float, sigma: tuple[int, ...]) -> FloatArray:
    """Eigenvalues of the torus linearisation at an equilibrium (Prop. 3.2.1, section 3.2.2).

        lambda_0 = -(M a / I0) sqrt(2E/(M + n m)) sigma_0
        lambda_k = -(1/l) sqrt(2E/(M + n m)) prod_{j=0}^k sigma_j        (k = 1..n)

    M + n m is R at a straight or folded configuration, taken from ``inertia_R``.

    Raises:
        ValueError: If E <= 0 or sigma is not n+1 signs +-1.
    """
    free = free_params(params)
    n = free.n_trailers
    E = _positive_energy(E)
    signs = np.asarray(sigma, dtype=np.float64)
    if signs.shape != (n + 1,) or not np.all(np.abs(signs) == 1.0):
        raise ValueError(f"sigma must be n+1 = {n + 1} signs (+1 or -1), got {sigma!r}")
    alpha = np.where(signs[1:] > 0, 0.0, np.pi)
    speed = math.sqrt(2.0 * E / float(inertia_R(free, alpha)))
    lam = np.empty(n + 1)
    lam[0] = -(free.M * free.a / free.I0) * speed * signs[0]
    lam[1:] = -(speed / free.l) * np.cumprod(signs)[1:]
    return lam


def _classify(eigenvalues: FloatArray) -> str:
    stable_node, unstable_node, saddle = KINDS
    if np.all(eigenvalues < 0.0):
        return stable_node
    if np.all(eigenvalues > 0.0):
        return unstable_node
    return saddle


def equilibria(params: ConvoyParams, E: float) -> list[Equilibrium]:
    """All 2^(n+1) equilibria on the energy level E (physics.md section 7, Prop. 3.2.1).

    omega = 0, sin(alpha_k) = 0 and u = sigma_0 sqrt(2E / (M + n m)). The kind
    follows from the signs of the eigenvalues, so it is right for any a != 0:
    with a > 0 the straight convoy going forward is the stable node, reversing
    the unstable node, any folded one a saddle (physics.md's statement). With
    a < 0 lambda_0 changes sign; turning the cart round maps (a, u, alpha_1) to
    (-a, -u, alpha_1 + pi), so the same rules hold with sigma_0 and sigma_1
    flipped (the stable node is then u < 0 with alpha_1 = pi: the cart backs
    away from trailer 1, pulling the straight train).

    The list starts with sigma = (+1, ..., +1) and follows ``itertools.product``
    order over (+1, -1).

    Args:
        params: Convoy parameters (``mu`` ignored); ``a`` must be non-zero.
        E: Energy level, > 0.

    Returns:
        The equilibria.

    Raises:
        ValueError: If E <= 0, or a = 0 (omega is then conserved and the
            equilibria are not isolated on the energy level: relative equilibria
            with omega != 0 fill continua; see :func:`relative_equilibria`).
    """
    free = free_params(params)
    energy_level = _positive_energy(E)
    if free.a == 0.0:
        raise ValueError(
            "equilibria() needs a != 0: with a = 0 omega is conserved, lambda_0 = 0 and the "
            "equilibria on an energy level are not isolated (use relative_equilibria)"
        )
    found = []
    for sigma in itertools.product((1, -1), repeat=free.n_trailers + 1):
        z = np.zeros(free.n_trailers + 2)
        z[ALPHA:] = np.where(np.asarray(sigma[1:]) > 0, 0.0, np.pi)
        z[U] = sigma[0] * math.sqrt(2.0 * energy_level / float(inertia_R(free, z[ALPHA:])))
        lam = equilibrium_eigenvalues(free, energy_level, sigma)
        kind = _classify(lam)
        z.setflags(write=False)
        lam.setflags(write=False)
        found.append(Equilibrium(z, tuple(sigma), lam, kind, kind == "stable node"))
    return found


def jacobian(params: ConvoyParams, z: ArrayLike, eps: float = 1e-6) -> FloatArray:
    """Numerical Jacobian d rhs / d z by central differences (``mu`` ignored).

    Column j is (rhs(z + h_j e_j) - rhs(z - h_j e_j)) / (2 h_j) with
    h_j = eps * max(1, |z_j|); the error is O(h^2) + O(machine eps / h), about
    1e-10 relative for the default eps.

    Args:
        params: Convoy parameters.
        z: One state, ``(n+2,)`` or extended ``(n+5,)``.
        eps: Relative step, > 0.

    Returns:
        The ``(w, w)`` matrix, w = len(z).
    """
    free = free_params(params)
    state = np.asarray(z, dtype=np.float64)
    if state.ndim != 1:
        raise ValueError(f"jacobian takes one state (a 1-D array), got shape {state.shape}")
    step_rel = _finite_scalar(eps, "eps")
    if step_rel <= 0.0:
        raise ValueError(f"eps must be > 0, got {eps!r}")
    width = state.shape[0]
    steps = step_rel * np.maximum(1.0, np.abs(state))
    shifts = np.diag(steps)
    rows = np.concatenate([state + shifts, state - shifts])
    values = rhs(free, rows)
    return ((values[:width] - values[width:]) / (2.0 * steps[:, None])).T


# ----------------------------------------------------------------------------
# Section 8: a = 0, relative equilibria
# ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RelativeEquilibrium:
    """A relative equilibrium of the a = 0 convoy: the cart runs on a circle (section 8).

    Attributes:
        z: ``(u0, omega0, alpha_1..alpha_n)``, a fixed point of the reduced equations.
        sigma: ``(sign cos(alpha_1), ..., sign cos(alpha_n))``; all +1 is the principal
            (unfolded) one. A hitch at exactly pi/2 counts as +1.
        radius: Radius of the cart's circle, |u0 / omega0| (inf when omega0 = 0).
    """

    z: FloatArray
    sigma: tuple[int, ...]
    radius: float


def _hitch_angles_on_circle(n: int, ratio: float, sigma: tuple[int, ...]) -> FloatArray:
    """Hitch angles with prod_{j<k} cos(alpha_j) sin(alpha_k) = ratio = l omega0 / u0 (3.32).

    sin(alpha_k) = ratio / prod_{j<k} cos(alpha_j) and cos(alpha_k) = sigma_k sqrt(1 - sin^2);
    then sin^2(alpha_k) = l^2 omega0^2 / (u0^2 - (k-1) l^2 omega0^2) (physics.md section 8).
    """
    alpha = np.empty(n)
    prefix_cos = 1.0
    for k in range(n):
        sine = ratio / prefix_cos
        # Rounding can push |sine| a hair over 1 at the border case u0^2 = n l^2 omega0^2.
        sine = min(1.0, max(-1.0, sine))
        cosine = sigma[k] * math.sqrt(max(0.0, 1.0 - sine * sine))
        alpha[k] = math.atan2(sine, cosine)
        prefix_cos *= cosine
    return alpha


def relative_equilibria(
    params: ConvoyParams, u0: float, omega0: float
) -> list[RelativeEquilibrium]:
    """Relative equilibria with u = u0, omega = omega0 when a = 0 (physics.md section 8).

    They exist iff n l^2 omega0^2 <= u0^2 (thesis 3.31), with

        sin^2(alpha_k) = l^2 omega0^2 / (u0^2 - (k-1) l^2 omega0^2),
        cos^2(alpha_k) = (u0^2 - k l^2 omega0^2) / (u0^2 - (k-1) l^2 omega0^2);

    the signs follow from sin(alpha_1) = l omega0 / u0 and A_k = 0. Every sign
    choice of cos(alpha_k) is returned (2^n points; fewer on the border
    u0^2 = n l^2 omega0^2, where cos(alpha_n) = 0), the principal one
    (all |alpha_k| < pi/2) first. ``mu`` is ignored. For omega0 = 0 these are
    the 2^n straight or folded configurations (radius inf).

    Args:
        params: Convoy parameters with a = 0.
        u0: Forward speed of the cart.
        omega0: Its (conserved) angular velocity.

    Returns:
        The relative equilibria; empty when n l^2 omega0^2 > u0^2.

    Raises:
        ValueError: If a != 0 (omega is then not conserved), or u0 = omega0 = 0.
    """
    free = free_params(params)
    if free.a != 0.0:
        raise ValueError(
            f"relative_equilibria needs a = 0 (physics.md section 8), got a = {free.a}"
        )
    speed = _finite_scalar(u0, "u0")
    turn = _finite_scalar(omega0, "omega0")
    if speed == 0.0 and turn == 0.0:
        raise ValueError("u0 = omega0 = 0: every configuration is at rest, none is singled out")
    n = free.n_trailers
    if n * (free.l * turn) ** 2 > speed**2:
        return []
    ratio = free.l * turn / speed if speed != 0.0 else 0.0  # speed = 0 only reaches here if n = 0
    radius = abs(speed / turn) if turn != 0.0 else math.inf
    found = []
    seen: set[tuple[float, ...]] = set()
    for sigma in itertools.product((1, -1), repeat=n):
        alpha = _hitch_angles_on_circle(n, ratio, sigma)
        key = tuple(alpha.tolist())
        if key in seen:  # the border case: cos(alpha_n) = 0 for both signs
            continue
        seen.add(key)
        z = np.concatenate([[speed, turn], alpha])
        z.setflags(write=False)
        signs = tuple(1 if math.cos(angle) >= -1e-15 else -1 for angle in alpha)
        found.append(RelativeEquilibrium(z, signs, radius))
    return found


# ----------------------------------------------------------------------------
# Section 8: one trailer, a = 0
# ----------------------------------------------------------------------------


def _check_one_trailer(params: ConvoyParams, omega0: float) -> tuple[ConvoyParams, float]:
    free = free_params(params)
    if free.n_trailers != 1:
        raise ValueError(
            f"this is the one-trailer analysis (physics.md section 8): needs n_trailers = 1, "
            f"got {free.n_trailers}"
        )
    if free.a != 0.0:
        raise ValueError(
            f"the one-trailer analysis needs a = 0 (omega conserved), got a = {free.a}"
        )
    turn = _finite_scalar(omega0, "omega0")
    if turn <= 0.0:
        raise ValueError(f"omega0 must be > 0 (omega0 < 0 is the mirror image), got {omega0!r}")
    return free, turn


def _translational_budget(free: ConvoyParams, E: float, omega0: float) -> float:
    """K = 2E - J0 omega0^2 = R(alpha) u^2, the part of 2E not spent on turning the cart.

    Raises:
        ValueError: If E < J0 omega0^2 / 2.
    """
    energy_level = _finite_scalar(E, "E")
    budget = 2.0 * energy_level - free.J0 * omega0**2
    if budget < 0.0:
        raise ValueError(
            f"E = {energy_level!r} is below the rotational energy J0 omega0^2 / 2 = "
            f"{0.5 * free.J0 * omega0**2!r}: no motion has this energy and omega0"
        )
    return budget


def critical_energy(params: ConvoyParams, omega0: float) -> float:
    """E_c = (J0 + J + M l^2) omega0^2 / 2 (physics.md section 8).

    Below E_c the hitch angle turns round periodically; above it there are two
    relative equilibria. It is the energy of the state u = l omega0, alpha = pi/2.

    Raises:
        ValueError: Unless n = 1, a = 0 and omega0 > 0.
    """
    free, turn = _check_one_trailer(params, omega0)
    return 0.5 * (free.J0 + free.J + free.M * free.l**2) * turn**2


def one_trailer_hitch_rate(
    params: ConvoyParams, E: float, omega0: float, alpha: ArrayLike
) -> FloatArray:
    """alpha_dot along the invariant circle of energy E (thesis 3.37-3.38).

        u = sqrt((2E - J0 omega0^2) / R(alpha)) (> 0),   alpha_dot = omega0 - u sin(alpha) / l,

    evaluated through the package's ``rhs`` at z = (u, omega0, alpha).

    Args:
        params: Convoy parameters with n = 1, a = 0.
        E: Energy, >= J0 omega0^2 / 2.
        omega0: Angular velocity of the cart, > 0.
        alpha: Hitch angle(s), any shape.

    Returns:
        alpha_dot, shape of ``alpha``.
    """
    free, turn = _check_one_trailer(params, omega0)
    budget = _translational_budget(free, E, turn)
    angles = np.asarray(alpha, dtype=np.float64)
    if not np.all(np.isfinite(angles)):
        raise ValueError("alpha contains non-finite values (NaN or inf)")
    R = inertia_R(free, angles[..., None])
    z = np.stack([np.sqrt(budget / R), np.full(angles.shape, turn), angles], axis=-1)
    return rhs(free, z)[..., ALPHA]


def _periodic_midpoint(
    integrand_of: Callable[[FloatArray], FloatArray], tol: float, max_nodes: int
) -> float:
    """Integral over one period [-pi, pi) by the midpoint rule, doubling the nodes.

    For an analytic periodic integrand the error falls geometrically with the
    number of nodes, so once two successive differences are below ``tol``
    (relative) the last value is far more accurate than that.

    Raises:
        RuntimeError: If ``max_nodes`` is reached first.
    """

    def rule(nodes: int) -> float:
        grid = -math.pi + (np.arange(nodes, dtype=np.float64) + 0.5) * (2.0 * math.pi / nodes)
        return 2.0 * math.pi * float(np.mean(integrand_of(grid)))

    nodes = 64
    previous = rule(nodes)
    agreements = 0
    while nodes < max_nodes:
        nodes *= 2
        current = rule(nodes)
        agreements = agreements + 1 if abs(current - previous) <= tol * abs(current) else 0
        if agreements == 2:  # twice, so that an unresolved peak cannot fake convergence
            return current
        previous = current
    raise RuntimeError(f"periodic quadrature did not reach rtol {tol:.1e} with {max_nodes} nodes")


def _peak_clustering(rate_of: Callable[[FloatArray], FloatArray], peak: float) -> float:
    """Stretch w for :func:`period`'s change of variables, from the slowest point's shape.

    Near ``peak`` the rate is about g0 + g2 x^2 / 2, so 1 / rate has a peak of
    half-width eps = sqrt(2 g0 / g2). The map with w = sqrt(eps) balances the
    resolution of that peak against the compression of the rest of the circle.
    """
    h = 1e-3
    g0, g_left, g_right = (float(v) for v in rate_of(np.array([peak, peak - h, peak + h])))
    curvature = (g_left + g_right - 2.0 * g0) / h**2
    if curvature <= 0.0:
        return 1.0
    return min(1.0, (2.0 * g0 / curvature) ** 0.25)


def period(params: ConvoyParams, E: float, omega0: float) -> float:
    """Period of the hitch angle's turn for J0 omega0^2 / 2 <= E < E_c (thesis 3.40).

        T(E) = integral_0^{2 pi} l sqrt(R) d alpha
                                 / (l omega0 sqrt(R) - sqrt(2E - J0 omega0^2) sin(alpha)),

    i.e. the integral of 1 / alpha_dot over one turn, with alpha_dot from
    :func:`one_trailer_hitch_rate`. The integrand is analytic and 2 pi-periodic,
    so the periodic midpoint rule converges geometrically. Near E_c alpha_dot
    almost vanishes at alpha = pi/2 (T grows like (E_c - E)^(-1/2)); the nodes are
    then clustered there by the circle map alpha = pi/2 + 2 atan(w tan(phi/2)),
    which keeps the integrand periodic and analytic in phi. Rounding in
    alpha_dot limits the relative accuracy to about 1e-16 omega0 / min(alpha_dot),
    i.e. roughly 1e-16 / (1 - E/E_c).

    Args:
        params: Convoy parameters with n = 1, a = 0.
        E: Energy in [J0 omega0^2 / 2, E_c).
        omega0: Angular velocity of the cart, > 0.

    Returns:
        T(E), the time alpha takes to gain 2 pi.

    Raises:
        ValueError: Outside the regime (n != 1, a != 0, omega0 <= 0, E < J0 omega0^2 / 2,
            or E >= E_c, where alpha stops at an equilibrium and T is infinite), or E so
            close to E_c that alpha_dot at pi/2 is lost to rounding.
    """
    free, turn = _check_one_trailer(params, omega0)
    _translational_budget(free, E, turn)
    E_c = critical_energy(free, turn)
    if float(E) >= E_c:
        raise ValueError(
            f"E = {E!r} >= E_c = {E_c!r}: alpha runs into an equilibrium, the period is "
            "infinite (see one_trailer_equilibria)"
        )

    def rate(alpha: FloatArray) -> FloatArray:
        return one_trailer_hitch_rate(free, E, turn, alpha)

    slowest = float(rate(np.array(math.pi / 2)))
    if slowest <= 1e-13 * turn:
        raise ValueError(
            f"E = {E!r} is within rounding of E_c = {E_c!r}: alpha_dot(pi/2) = {slowest:.3e}, "
            "the period cannot be computed reliably"
        )
    stretch = _peak_clustering(rate, math.pi / 2)

    def integrand(phi: FloatArray) -> FloatArray:
        half = 0.5 * phi
        alpha = math.pi / 2 + 2.0 * np.arctan(stretch * np.tan(half))
        d_alpha = stretch / (np.cos(half) ** 2 + stretch**2 * np.sin(half) ** 2)
        return d_alpha / rate(alpha)

    tol = max(1e-13, 1e-14 * turn / slowest)
    return _periodic_midpoint(integrand, tol=tol, max_nodes=2**22)


def one_trailer_equilibria(params: ConvoyParams, E: float, omega0: float) -> tuple[float, float]:
    """The two relative equilibria alpha(1) < pi/2 < alpha(2) for E > E_c (thesis 3.41).

    They solve sin^2(alpha) / R(alpha) = l^2 omega0^2 / (2E - J0 omega0^2) on (0, pi)
    (the thesis's (3.41) drops the square on omega0); the left side rises
    from 0 to 1/(M + J/l^2) on (0, pi/2] and is symmetric about pi/2, so each
    half holds one root, found by Brent's method. alpha(1) is stable and
    alpha(2) unstable; the cart's speed there is u = l omega0 / sin(alpha).
    Here E is the whole energy at fixed omega0 (I0 = J0 because a = 0).

    Args:
        params: Convoy parameters with n = 1, a = 0.
        E: Energy, > E_c.
        omega0: Angular velocity of the cart, > 0.

    Returns:
        ``(alpha_1, alpha_2)`` with alpha_2 = pi - alpha_1 up to rounding.

    Raises:
        ValueError: Outside the regime (n != 1, a != 0, omega0 <= 0, E <= E_c).
    """
    free, turn = _check_one_trailer(params, omega0)
    E_c = critical_energy(free, turn)
    budget = _translational_budget(free, E, turn)
    if float(E) <= E_c:
        raise ValueError(
            f"E = {E!r} <= E_c = {E_c!r}: there are two relative equilibria only above the "
            "critical energy (below it alpha turns periodically, see period)"
        )
    level = (free.l * turn) ** 2 / budget

    def excess(alpha: float) -> float:
        return math.sin(alpha) ** 2 / float(inertia_R(free, [alpha])) - level

    alpha_1 = brentq(excess, 0.0, math.pi / 2, xtol=1e-15, rtol=1e-15, maxiter=200)
    alpha_2 = brentq(excess, math.pi / 2, math.pi, xtol=1e-15, rtol=1e-15, maxiter=200)
    return float(alpha_1), float(alpha_2)


def limiting_radius(params: ConvoyParams, E: float, omega0: float) -> float:
    """Radius l / sin(alpha(1)) of the circle the cart tends to for E > E_c (section 8).

    At the stable relative equilibrium u = l omega0 / sin(alpha(1)), so the
    cart's circle has radius u / omega0 = l / sin(alpha(1)).

    Raises:
        ValueError: As :func:`one_trailer_equilibria`.
    """
    free, turn = _check_one_trailer(params, omega0)
    alpha_1, _ = one_trailer_equilibria(free, E, turn)
    return free.l / math.sin(alpha_1)
