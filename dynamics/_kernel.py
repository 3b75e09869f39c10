"""The one implementation of the equations: numba-jitted, row by row, O(n) per row.

Every public function of :mod:`dynamics` funnels into these kernels, whether it
serves one state or a batch of thousands.

Conventions (private to the package):

* ``pv``: float64 array ``[M, J0, a, m, J, l, mu]`` (see :func:`pack_params`).
* A row is ``(u, omega, alpha_1..alpha_n)``, optionally followed by the pose
  ``(x, y, theta)`` of the cart's axle midpoint; ``with_pose`` says which. Its columns
  are named in :mod:`dynamics.columns` (``U``, ``OMEGA``, ``ALPHA + k``, ``theta_column(n)``).
* ``act``: float64 array of shape ``(B, ACT_WIDTH)`` holding the moving mass's body-frame
  position, velocity and acceleration ``(xi, eta, xi_dot, eta_dot, xi_ddot,
  eta_ddot)`` (columns ``XI`` .. ``ETA_DDOT`` of :mod:`dynamics.columns`). Over one
  integration call the acceleration is held constant (a zero-order hold), so position
  and velocity are exact quadratics in time.
* Blocks hold the same columns as their first index: ``y[OMEGA, lane]``, ``mass0[XI, lane]``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange, types
from numba.extending import overload

from dynamics._cache import cached_njit
from dynamics.columns import (
    ACT_WIDTH,
    ALPHA,
    ETA,
    ETA_DDOT,
    ETA_DOT,
    OMEGA,
    XI,
    XI_DDOT,
    XI_DOT,
    U,
    theta_column,
    x_column,
    y_column,
)
from dynamics.params import ConvoyParams

P_M, P_J0, P_A, P_SMALL_M, P_J, P_L, P_MU = range(7)


def pack_params(params: ConvoyParams) -> np.ndarray:
    """Pack the parameters the kernels need into a float64 vector."""
    return np.array(
        [params.M, params.J0, params.a, params.m, params.J, params.l, params.mu],
        dtype=np.float64,
    )


# ---------------------------------------------------------------------------
# Shared or per-row parameters. ``pv`` is either ONE packed vector (P,) for every row,
# or per-row vectors: (B, P) for a batch, gathered per block into (P, LANES). The
# helpers below are resolved when numba compiles (on the array's ndim), so the shared
# case compiles to exactly the code it had before per-row parameters existed (the
# same loads, the same operations, bit for bit and at the same speed), and the per-row
# case runs the same arithmetic on each lane's own values.


def lane_value(pv: np.ndarray, index: int, lane: int) -> float:
    """Parameter ``index`` of lane ``lane``: ``pv[index]`` (shared) or ``pv[index, lane]``."""
    return float(pv[index] if pv.ndim == 1 else pv[index, lane])


@overload(lane_value, jit_options={"nogil": True})
def _lane_value(pv, index, lane):  # type: ignore[no-untyped-def]
    if pv.ndim == 1:
        return lambda pv, index, lane: pv[index]
    return lambda pv, index, lane: pv[index, lane]


def lane_at(value: float | np.ndarray, lane: int) -> float:
    """A hoisted parameter of lane ``lane``: ``value`` (a shared scalar) or ``value[lane]``."""
    return float(value[lane] if isinstance(value, np.ndarray) else value)


@overload(lane_at, jit_options={"nogil": True})
def _lane_at(value, lane):  # type: ignore[no-untyped-def]
    if isinstance(value, types.Array):
        return lambda value, lane: value[lane]
    return lambda value, lane: value


def row_params(pv: np.ndarray, i: int) -> np.ndarray:
    """The packed vector of row ``i``: ``pv`` itself (shared, (P,)) or ``pv[i]`` ((B, P))."""
    return pv if pv.ndim == 1 else pv[i]


@overload(row_params, jit_options={"nogil": True})
def _row_params(pv, i):  # type: ignore[no-untyped-def]
    if pv.ndim == 1:
        return lambda pv, i: pv
    return lambda pv, i: pv[i]


def params_scratch(pv: np.ndarray) -> np.ndarray:
    """Room for one block's per-lane parameters (P, LANES); shared ``pv`` needs none (itself)."""
    return pv if pv.ndim == 1 else np.empty((pv.shape[1], LANES))


@overload(params_scratch, jit_options={"nogil": True})
def _params_scratch(pv):  # type: ignore[no-untyped-def]
    if pv.ndim == 1:
        return lambda pv: pv
    return lambda pv: np.empty((pv.shape[1], LANES))


def gather_params(pv: np.ndarray, rows: np.ndarray, nb: int, scratch: np.ndarray) -> np.ndarray:
    """The block kernels' ``pv`` for the block ``rows[:nb]``: ``pv`` itself when shared,
    else the rows' vectors gathered into ``scratch`` (P, LANES) (:func:`params_scratch`)."""
    if pv.ndim == 1:
        return pv
    for j in range(pv.shape[1]):
        for lane in range(nb):
            scratch[j, lane] = pv[rows[lane], j]
    return scratch


@overload(gather_params, jit_options={"nogil": True})
def _gather_params(pv, rows, nb, scratch):  # type: ignore[no-untyped-def]
    if pv.ndim == 1:
        return lambda pv, rows, nb, scratch: pv

    def gather(pv, rows, nb, scratch):  # type: ignore[no-untyped-def]
        for j in range(pv.shape[1]):
            for lane in range(nb):
                scratch[j, lane] = pv[rows[lane], j]
        return scratch

    return gather


# ---------------------------------------------------------------------------
# sin and cos without branches, so that loops over a block of rows vectorise.
#
# numba's math.sin is a call into libm (no SVML here), which stops LLVM from
# vectorising a loop. Cody-Waite reduction by pi/2 in three parts (fdlibm's
# 33-bit splits: k * PIO2_1 and k * PIO2_2 are exact for |k| < 2^20) and fdlibm's
# minimax kernels on [-pi/4, pi/4] give results within about 1 ulp of libm's.
# Beyond SINCOS_MAX_ARG the reduction loses its exactness and callers fall back
# to math.sin / math.cos (never seen at physical states).

SINCOS_MAX_ARG = 1e5
_TWO_OVER_PI = 6.36619772367581382433e-01
_ROUND_MAGIC = 6755399441055744.0  # 1.5 * 2^52: (x + M) - M rounds x to an integer
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@cached_njit(nogil=True)
def sincos_reduced(x: float) -> tuple:
    """(sin x, cos x) without branches, accurate for |x| <= SINCOS_MAX_ARG."""
    k = (x * _TWO_OVER_PI + _ROUND_MAGIC) - _ROUND_MAGIC
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    sin_r = r + z * r * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    half_z = 0.5 * z
    w = 1.0 - half_z
    tail = z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6)))))
    cos_r = w + (((1.0 - w) - half_z) + tail)
    quadrant = np.int64(k)
    odd = (quadrant & 1) == 1
    sin_sign = 1.0 - float(quadrant & 2)
    cos_sign = 1.0 - float((quadrant + 1) & 2)
    sin_x = sin_sign * (cos_r if odd else sin_r)
    cos_x = cos_sign * (sin_r if odd else cos_r)
    return sin_x, cos_x


@cached_njit(nogil=True)
def sincos(x: float) -> tuple:
    """(sin x, cos x): :func:`sincos_reduced`, or libm beyond its range (same values as blocks)."""
    if abs(x) > SINCOS_MAX_ARG:
        return math.sin(x), math.cos(x)
    return sincos_reduced(x)


# ---------------------------------------------------------------------------
# The equations, lane by lane. Each helper is the arithmetic of ONE row; the row
# kernels call them on scalars, the block kernels on every lane of a block held as
# structure of arrays. Same helpers, same operations: a row's result does not depend
# on which path, block or lane it went through.

#: Hitch accumulators of one row (see :func:`_hitch_step`).
(
    H_PREFIX_C2,
    H_PREFIX_C,
    H_SUM_PREFIX_C2,
    H_G_S,
    H_SUM_G_S,
    H_G_T,
    H_TAIL_C2,
    H_SUM_TAIL_C2,
    H_C_PREV,
    H_S_PREV,
    H_C1S1,
) = range(11)
N_HITCH = 11


@cached_njit(nogil=True)
def _hitch_step(k: int, s: float, c: float, l: float, acc: tuple) -> tuple:
    """One step of the forward pass over the hitches: (A_k, new accumulators).

    R(alpha) - M, dR/dalpha_1 and sum_k A_k dR/dalpha_k in one O(n) pass, with
    dR/dalpha_k = -2 s_k c_k P_(k-1) (m S_k - (J/l^2) T_k), the suffix sums
    S_k = sum_(j>=k) prod_(i=k+1..j) c_i^2 and suffix products T_k = prod_(i>k) c_i^2.
    Suffix quantities would need a backward pass; instead the weighted sums
    sum_k g_k S_k and sum_k g_k T_k are accumulated forwards by Horner-like
    recurrences (G_j = c_j^2 G_(j-1) + g_j). Accumulators: P_(k-1) = prod_(j<k) c_j^2,
    prod_(j<=k-2) c_j, sum_(j<=k) P_j, G_j, sum_j G_j, H_j, prod_(i=2..j) c_i^2
    (for S_1 and T_1), its running sum, c_(k-1), s_(k-1) and c_1 s_1.
    """
    (
        prefix_c2,
        prefix_c,
        sum_prefix_c2,
        g_weighted_s,
        sum_g_s,
        g_weighted_t,
        tail_c2,
        sum_tail_c2,
        c_prev,
        s_prev,
        c1s1,
    ) = acc
    c2 = c * c
    if k == 0:
        a_k = -s / l
        c1s1 = c * s
    else:
        a_k = prefix_c * (s_prev - c_prev * s) / l
        prefix_c *= c_prev
        tail_c2 *= c2
    sum_tail_c2 += tail_c2
    g = a_k * (-2.0 * s * c * prefix_c2)
    g_weighted_s = c2 * g_weighted_s + g
    sum_g_s += g_weighted_s
    g_weighted_t = c2 * g_weighted_t + g
    prefix_c2 *= c2
    sum_prefix_c2 += prefix_c2
    return a_k, (
        prefix_c2,
        prefix_c,
        sum_prefix_c2,
        g_weighted_s,
        sum_g_s,
        g_weighted_t,
        tail_c2,
        sum_tail_c2,
        c,
        s,
        c1s1,
    )


@cached_njit(nogil=True)
def _hitch_start() -> tuple:
    return (1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0)


@cached_njit(nogil=True)
def _hitch_totals(pv: np.ndarray, lane: int, acc: tuple) -> tuple:
    """(R(alpha) - M, dR/dalpha_1, sum_k A_k dR/dalpha_k) from the final accumulators
    (the parameters of ``lane``: :func:`lane_value`)."""
    m = lane_value(pv, P_SMALL_M, lane)
    l = lane_value(pv, P_L, lane)
    J_l2 = lane_value(pv, P_J, lane) / (l * l)
    r_trailers = m * acc[H_SUM_PREFIX_C2] + J_l2 * (1.0 - acc[H_PREFIX_C2])
    dr_dalpha1 = -2.0 * acc[H_C1S1] * (m * acc[H_SUM_TAIL_C2] - J_l2 * acc[H_TAIL_C2])
    sum_a_dr = m * acc[H_SUM_G_S] - J_l2 * acc[H_G_T]
    return r_trailers, dr_dalpha1, sum_a_dr


@cached_njit(nogil=True)
def _accelerations(
    pv: np.ndarray,
    lane: int,
    r_trailers: float,
    dr_dalpha1: float,
    sum_a_dr: float,
    u: float,
    w: float,
    xi: float,
    eta: float,
    xi_dot: float,
    eta_dot: float,
    xi_ddot: float,
    eta_ddot: float,
) -> tuple:
    """(u_dot, omega_dot) for the planar moving mass (physics.md sections 3, 5 and 9)."""
    M = lane_value(pv, P_M, lane)
    a = lane_value(pv, P_A, lane)
    mu = lane_value(pv, P_MU, lane)
    I0 = lane_value(pv, P_J0, lane) + M * a * a
    R = M + r_trailers
    # Phi_u with Q / l^2 = -dR/dalpha_1 / 2.
    phi_u = -0.5 * sum_a_dr * u * u - 0.5 * dr_dalpha1 * u * w + M * a * w * w
    phi_w = -M * a * u * w
    # Body-frame acceleration of the mass without the u_dot, omega_dot parts.
    ax_rest = -2.0 * w * eta_dot + xi_ddot - w * w * xi
    ay_rest = eta_ddot + 2.0 * w * xi_dot + w * u - w * w * eta
    # 2x2 system: [[R + mu, -mu eta], [-mu eta, I0 + mu (xi^2 + eta^2)]] (u_dot, w_dot) = rhs.
    b0 = phi_u - mu * ax_rest
    b1 = phi_w - mu * (xi * ay_rest - eta * ax_rest)
    m00 = R + mu
    m01 = -mu * eta
    m11 = I0 + mu * (xi * xi + eta * eta)
    det = m00 * m11 - m01 * m01
    return (m11 * b0 - m01 * b1) / det, (m00 * b1 - m01 * b0) / det


@cached_njit(nogil=True)
def _energy(
    pv: np.ndarray,
    lane: int,
    r_trailers: float,
    u: float,
    w: float,
    eta: float,
    xi_dot: float,
    eta_dot: float,
    xi: float,
) -> float:
    """Kinetic energy, the mass included (physics.md section 9)."""
    M = lane_value(pv, P_M, lane)
    a = lane_value(pv, P_A, lane)
    mu = lane_value(pv, P_MU, lane)
    I0 = lane_value(pv, P_J0, lane) + M * a * a
    vx = u - w * eta + xi_dot
    vy = w * xi + eta_dot
    return 0.5 * ((M + r_trailers) * u * u + I0 * w * w + mu * (vx * vx + vy * vy))


# ---------------------------------------------------------------------------
# Row kernels (single states, DOPRI5, rhs and energy of arbitrary rows).


@cached_njit(nogil=True)
def _hitch_terms(pv: np.ndarray, row: np.ndarray, n: int, A: np.ndarray) -> tuple:
    """R(alpha) - M, dR/dalpha_1 and sum_k A_k dR/dalpha_k of one row in one O(n) pass.

    Writes A_k into ``A[k - 1]``. The recurrences are :func:`_hitch_step`'s.
    """
    acc = _hitch_start()
    for k in range(n):
        s, c = sincos(row[ALPHA + k])
        a_k, acc = _hitch_step(k, s, c, pv[P_L], acc)
        A[k] = a_k
    return _hitch_totals(pv, 0, acc)


@cached_njit(nogil=True)
def field_row(
    pv: np.ndarray,
    row: np.ndarray,
    n: int,
    with_pose: bool,
    xi: float,
    eta: float,
    xi_dot: float,
    eta_dot: float,
    xi_ddot: float,
    eta_ddot: float,
    out: np.ndarray,
) -> None:
    """d(row)/dt for the planar moving mass (physics.md sections 3, 5 and 9)."""
    u = row[U]
    w = row[OMEGA]
    r_trailers, dr_dalpha1, sum_a_dr = _hitch_terms(pv, row, n, out[ALPHA:])
    for k in range(n):
        out[ALPHA + k] *= u
    if n > 0:
        out[ALPHA] += w
    out[U], out[OMEGA] = _accelerations(
        pv, 0, r_trailers, dr_dalpha1, sum_a_dr, u, w, xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot
    )
    if with_pose:
        s_theta, c_theta = sincos(row[theta_column(n)])
        out[x_column(n)] = u * c_theta
        out[y_column(n)] = u * s_theta
        out[theta_column(n)] = w


@cached_njit(nogil=True)
def energy_row(
    pv: np.ndarray, row: np.ndarray, n: int, act: np.ndarray, scratch: np.ndarray
) -> float:
    """Energy of one row with the mass state ``act``; ``scratch`` (>= n) receives the A_k."""
    r_trailers, _, _ = _hitch_terms(pv, row, n, scratch)
    return _energy(
        pv, 0, r_trailers, row[U], row[OMEGA], act[ETA], act[XI_DOT], act[ETA_DOT], act[XI]
    )


@cached_njit()
def rhs_batch(
    pv: np.ndarray, z: np.ndarray, act: np.ndarray, n: int, with_pose: bool
) -> np.ndarray:
    """Time derivative of every row of ``z`` (shape (B, width))."""
    out = np.empty_like(z)
    for i in range(z.shape[0]):
        field_row(
            pv,
            z[i],
            n,
            with_pose,
            act[i, XI],
            act[i, ETA],
            act[i, XI_DOT],
            act[i, ETA_DOT],
            act[i, XI_DDOT],
            act[i, ETA_DDOT],
            out[i],
        )
    return out


@cached_njit()
def energy_batch(pv: np.ndarray, z: np.ndarray, act: np.ndarray, n: int) -> np.ndarray:
    """Energy of every row (physics.md section 9)."""
    out = np.empty(z.shape[0])
    scratch = np.empty(max(n, 1))
    for i in range(z.shape[0]):
        out[i] = energy_row(pv, z[i], n, act[i], scratch)
    return out


# ---------------------------------------------------------------------------
# Block kernels: LANES rows at a time, structure of arrays (quantity, lane), so that
# every loop over lanes is branch-free and LLVM vectorises it (AVX-512: 8 lanes).

#: Rows per block.
LANES = 64
# Rows of the block workspace beyond the state's: hitch accumulators, sin, cos.
_W_SIN = N_HITCH
_W_COS = N_HITCH + 1
_W_ROWS = N_HITCH + 2


@cached_njit(nogil=True)
def sincos_block(x: np.ndarray, sin_out: np.ndarray, cos_out: np.ndarray, nb: int) -> None:
    """sin and cos of ``x[:nb]``: the branch-free loop, then libm for any huge argument."""
    huge = False
    for lane in range(nb):
        s, c = sincos_reduced(x[lane])
        sin_out[lane] = s
        cos_out[lane] = c
        huge |= abs(x[lane]) > SINCOS_MAX_ARG
    if huge:
        for lane in range(nb):
            if abs(x[lane]) > SINCOS_MAX_ARG:
                sin_out[lane] = math.sin(x[lane])
                cos_out[lane] = math.cos(x[lane])


@cached_njit(nogil=True)
def _accumulators(work: np.ndarray, lane: int) -> tuple:
    return (
        work[0, lane],
        work[1, lane],
        work[2, lane],
        work[3, lane],
        work[4, lane],
        work[5, lane],
        work[6, lane],
        work[7, lane],
        work[8, lane],
        work[9, lane],
        work[10, lane],
    )


@cached_njit(nogil=True)
def _hitch_start_block(work: np.ndarray, nb: int) -> None:
    start = _hitch_start()
    for j in range(N_HITCH):
        for lane in range(nb):
            work[j, lane] = start[j]


@cached_njit(nogil=True)
def _hitch_accumulate(
    pv: np.ndarray,
    k: int,
    sin_k: np.ndarray,
    cos_k: np.ndarray,
    deriv: np.ndarray,
    work: np.ndarray,
    nb: int,
) -> None:
    """Hitch k of every lane (:func:`_hitch_step` on ``work``); A_k into ``deriv[ALPHA + k]``."""
    l = pv[P_L]  # a shared scalar, or the lanes' lengths (:func:`lane_at`)
    for lane in range(nb):
        a_k, acc = _hitch_step(
            k, sin_k[lane], cos_k[lane], lane_at(l, lane), _accumulators(work, lane)
        )
        deriv[ALPHA + k, lane] = a_k
        for j in range(N_HITCH):
            work[j, lane] = acc[j]


@cached_njit(nogil=True)
def _hitch_block(
    pv: np.ndarray, y: np.ndarray, n: int, deriv: np.ndarray, work: np.ndarray, nb: int
) -> None:
    """Hitch accumulators of every lane into ``work[:N_HITCH]``; A_k into ``deriv[ALPHA + k]``."""
    _hitch_start_block(work, nb)
    sin_k = work[_W_SIN]
    cos_k = work[_W_COS]
    for k in range(n):
        sincos_block(y[ALPHA + k], sin_k, cos_k, nb)
        _hitch_accumulate(pv, k, sin_k, cos_k, deriv, work, nb)


@cached_njit(nogil=True)
def field_block(
    pv: np.ndarray,
    y: np.ndarray,
    n: int,
    with_pose: bool,
    mass0: np.ndarray,
    tau: float,
    deriv: np.ndarray,
    work: np.ndarray,
    nb: int,
) -> None:
    """d(y)/dt of the first ``nb`` lanes of the block ``y`` (width, LANES) into ``deriv``.

    ``mass0`` (ACT_WIDTH, LANES) holds each lane's mass state at the start of the call; the
    field is taken at time ``tau`` into it (the mass's motion is an exact quadratic).
    ``work`` is scratch of shape (_W_ROWS, LANES). Per lane, the arithmetic is
    :func:`field_row`'s.
    """
    _hitch_block(pv, y, n, deriv, work, nb)
    for lane in range(nb):
        u = y[U, lane]
        w = y[OMEGA, lane]
        xi_ddot = mass0[XI_DDOT, lane]
        eta_ddot = mass0[ETA_DDOT, lane]
        r_trailers, dr_dalpha1, sum_a_dr = _hitch_totals(pv, lane, _accumulators(work, lane))
        deriv[U, lane], deriv[OMEGA, lane] = _accelerations(
            pv,
            lane,
            r_trailers,
            dr_dalpha1,
            sum_a_dr,
            u,
            w,
            mass0[XI, lane] + mass0[XI_DOT, lane] * tau + 0.5 * xi_ddot * tau * tau,
            mass0[ETA, lane] + mass0[ETA_DOT, lane] * tau + 0.5 * eta_ddot * tau * tau,
            mass0[XI_DOT, lane] + xi_ddot * tau,
            mass0[ETA_DOT, lane] + eta_ddot * tau,
            xi_ddot,
            eta_ddot,
        )
    for k in range(n):
        for lane in range(nb):
            deriv[ALPHA + k, lane] *= y[U, lane]
    if n > 0:
        for lane in range(nb):
            deriv[ALPHA, lane] += y[OMEGA, lane]
    if with_pose:
        sin_t = work[_W_SIN]
        cos_t = work[_W_COS]
        sincos_block(y[theta_column(n)], sin_t, cos_t, nb)
        for lane in range(nb):
            deriv[x_column(n), lane] = y[U, lane] * cos_t[lane]
            deriv[y_column(n), lane] = y[U, lane] * sin_t[lane]
            deriv[theta_column(n), lane] = y[OMEGA, lane]


@cached_njit(nogil=True)
def energy_block(
    pv: np.ndarray,
    y: np.ndarray,
    n: int,
    mass0: np.ndarray,
    deriv: np.ndarray,
    work: np.ndarray,
    out: np.ndarray,
    nb: int,
) -> None:
    """Energy of the first ``nb`` lanes, the mass as in ``mass0`` (``deriv`` is overwritten)."""
    _hitch_block(pv, y, n, deriv, work, nb)
    for lane in range(nb):
        r_trailers, _, _ = _hitch_totals(pv, lane, _accumulators(work, lane))
        out[lane] = _energy(
            pv,
            lane,
            r_trailers,
            y[U, lane],
            y[OMEGA, lane],
            mass0[ETA, lane],
            mass0[XI_DOT, lane],
            mass0[ETA_DOT, lane],
            mass0[XI, lane],
        )


@cached_njit(nogil=True)
def energy_block_from_trig(
    pv: np.ndarray,
    y: np.ndarray,
    n: int,
    mass0: np.ndarray,
    trig: np.ndarray,
    deriv: np.ndarray,
    work: np.ndarray,
    out: np.ndarray,
    nb: int,
) -> None:
    """:func:`energy_block` given sin(alpha_k) in ``trig[k]``, cos(alpha_k) in ``trig[n + k]``."""
    _hitch_start_block(work, nb)
    for k in range(n):
        _hitch_accumulate(pv, k, trig[k], trig[n + k], deriv, work, nb)
    for lane in range(nb):
        r_trailers, _, _ = _hitch_totals(pv, lane, _accumulators(work, lane))
        out[lane] = _energy(
            pv,
            lane,
            r_trailers,
            y[U, lane],
            y[OMEGA, lane],
            mass0[ETA, lane],
            mass0[XI_DOT, lane],
            mass0[ETA_DOT, lane],
            mass0[XI, lane],
        )


#: Bytes the workspace's arrays are aligned to: a cache line, and an AVX-512 vector.
_ALIGN = 64


@cached_njit(nogil=True)
def _carve(buffer: np.ndarray, start: int, rows: int, cols: int) -> np.ndarray:
    return buffer[start : start + rows * cols].reshape((rows, cols))


@cached_njit(nogil=True)
def new_workspace(width: int) -> tuple:
    """Scratch of one thread for the block kernels: state, stage, two derivative buffers,
    mass state, hitch workspace, per-lane scalars (energy targets, energies, flags) and
    room for the sines and cosines of the row's angles (observations), and the row
    path's buffers (:func:`advance_row`).

    One allocation, carved into arrays that each start on a 64-byte boundary: the
    lanes' loads are whole cache lines and AVX-512 vectors whatever address the
    allocator returns (with separate allocations the alignment, and a vector step's
    speed, changed from one process to the next by up to a third).
    """
    block = width * LANES  # a multiple of 8 doubles: every carved array stays aligned
    sizes = (
        block,
        block,
        block,
        block,
        ACT_WIDTH * LANES,
        _W_ROWS * LANES,
        3 * LANES,
        2 * block,
        3 * width,
    )
    total = 0
    for size in sizes:
        total += size
    buffer = np.empty(total + _ALIGN // 8)
    start = ((-buffer.ctypes.data) % _ALIGN) // 8
    y = _carve(buffer, start, width, LANES)
    stage = _carve(buffer, start + block, width, LANES)
    deriv = _carve(buffer, start + 2 * block, width, LANES)
    total_deriv = _carve(buffer, start + 3 * block, width, LANES)
    offset = start + 4 * block
    mass = _carve(buffer, offset, ACT_WIDTH, LANES)
    offset += ACT_WIDTH * LANES
    work = _carve(buffer, offset, _W_ROWS, LANES)
    offset += _W_ROWS * LANES
    lane_scalars = _carve(buffer, offset, 3, LANES)
    offset += 3 * LANES
    trig = _carve(buffer, offset, 2 * width, LANES)
    offset += 2 * block
    row_buffers = _carve(buffer, offset, 3, width)
    return (y, stage, deriv, total_deriv, mass, work, lane_scalars, trig, row_buffers)


#: Raw angles this far inside the fold angle cannot wrap onto it (rounding moves ~1e-15).
_FOLD_MARGIN = 1e-12


@cached_njit(nogil=True)
def _wrapped_folded(alpha: float, fold_angle: float) -> bool:
    return abs(math.atan2(math.sin(alpha), math.cos(alpha))) >= fold_angle


@cached_njit(nogil=True)
def gather_block(
    z: np.ndarray, act: np.ndarray, rows: np.ndarray, nb: int, workspace: tuple
) -> None:
    """Copy rows ``rows[:nb]`` of ``z`` and ``act`` into the workspace (structure of arrays)."""
    y = workspace[0]
    mass0 = workspace[4]
    for j in range(z.shape[1]):
        for lane in range(nb):
            y[j, lane] = z[rows[lane], j]
    for j in range(ACT_WIDTH):
        for lane in range(nb):
            mass0[j, lane] = act[rows[lane], j]


@cached_njit(nogil=True)
def scatter_block(
    z: np.ndarray, act: np.ndarray, rows: np.ndarray, nb: int, dt: float, workspace: tuple
) -> None:
    """Write the block back into ``z``; advance the mass state in ``act`` by ``dt`` exactly."""
    y = workspace[0]
    for j in range(z.shape[1]):
        for lane in range(nb):
            z[rows[lane], j] = y[j, lane]
    for lane in range(nb):
        advance_mass_row(act, rows[lane], dt)


@cached_njit(nogil=True)
def advance_mass_row(act: np.ndarray, i: int, dt: float) -> None:
    """The mass state of row ``i`` after ``dt`` under its held acceleration (exact)."""
    xi_ddot = act[i, XI_DDOT]
    eta_ddot = act[i, ETA_DDOT]
    xi_dot0 = act[i, XI_DOT]
    eta_dot0 = act[i, ETA_DOT]
    act[i, XI] = act[i, XI] + xi_dot0 * dt + 0.5 * xi_ddot * dt * dt
    act[i, ETA] = act[i, ETA] + eta_dot0 * dt + 0.5 * eta_ddot * dt * dt
    act[i, XI_DOT] = xi_dot0 + xi_ddot * dt
    act[i, ETA_DOT] = eta_dot0 + eta_ddot * dt


#: Blocks of at most this many rows take the row path (:func:`advance_row`): the block
#: loops' fixed cost outweighs their vectorisation there. Same helpers, same order of
#: operations, same results to the bit (tests/dynamics/test_block_kernel.py).
ROW_PATH_MAX_ROWS = 4


@cached_njit(nogil=True)
def _field_at(
    pv: np.ndarray,
    row: np.ndarray,
    n: int,
    with_pose: bool,
    act: np.ndarray,
    i: int,
    tau: float,
    out: np.ndarray,
) -> None:
    """:func:`field_row` at time ``tau`` into the call (the mass's exact quadratic motion)."""
    xi_ddot = act[i, XI_DDOT]
    eta_ddot = act[i, ETA_DDOT]
    field_row(
        pv,
        row,
        n,
        with_pose,
        act[i, XI] + act[i, XI_DOT] * tau + 0.5 * xi_ddot * tau * tau,
        act[i, ETA] + act[i, ETA_DOT] * tau + 0.5 * eta_ddot * tau * tau,
        act[i, XI_DOT] + xi_ddot * tau,
        act[i, ETA_DOT] + eta_ddot * tau,
        xi_ddot,
        eta_ddot,
        out,
    )


@cached_njit(nogil=True)
def advance_row(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    i: int,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: int,
    preserve_energy: bool,
    target_energy: np.ndarray,
    fold_angle: float,
    folded: np.ndarray,
    buffers: np.ndarray,
) -> None:
    """:func:`advance_block` for the one row ``z[i]`` (``act[i]`` is left unchanged).

    ``buffers`` is scratch of shape (3, width).
    """
    row = z[i]
    width = row.shape[0]
    total = buffers[0]
    stage = buffers[1]
    deriv = buffers[2]
    target = 0.0
    if preserve_energy:
        current = energy_row(pv, row, n, act[i], deriv)
        wanted = target_energy[i]
        target = wanted if wanted > 0.0 else current
    check_fold = fold_angle < math.inf
    near_fold = fold_angle - _FOLD_MARGIN
    h = dt / substeps
    half_h = 0.5 * h
    sixth_h = h / 6.0
    for step in range(substeps):
        t0 = step * h
        t_mid = t0 + 0.5 * h
        t1 = t0 + h
        _field_at(pv, row, n, with_pose, act, i, t0, deriv)
        for j in range(width):
            total[j] = deriv[j]
            stage[j] = row[j] + half_h * deriv[j]
        _field_at(pv, stage, n, with_pose, act, i, t_mid, deriv)
        for j in range(width):
            total[j] = total[j] + 2.0 * deriv[j]
            stage[j] = row[j] + half_h * deriv[j]
        _field_at(pv, stage, n, with_pose, act, i, t_mid, deriv)
        for j in range(width):
            total[j] = total[j] + 2.0 * deriv[j]
            stage[j] = row[j] + h * deriv[j]
        _field_at(pv, stage, n, with_pose, act, i, t1, deriv)
        for j in range(width):
            row[j] += sixth_h * (total[j] + deriv[j])
        if preserve_energy:
            current = energy_row(pv, row, n, act[i], deriv)
            if current > 0.0:
                scale = math.sqrt(target / current)
                row[U] *= scale
                row[OMEGA] *= scale
        if check_fold:
            near = 0.0
            for k in range(n):
                near = max(near, abs(row[ALPHA + k]))
            if near >= near_fold:
                for k in range(n):
                    if _wrapped_folded(row[ALPHA + k], fold_angle):
                        folded[i] = True


@cached_njit(nogil=True)
def advance_block(
    pv: np.ndarray,
    rows: np.ndarray,
    nb: int,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: int,
    preserve_energy: bool,
    target_energy: np.ndarray,
    fold_angle: float,
    folded: np.ndarray,
    workspace: tuple,
) -> None:
    """Classical RK4 on the gathered block (see :func:`gather_block`), ``substeps`` equal substeps.

    Per row the arithmetic is that of RK4 on :func:`field_row` (the same helpers, the
    same order of operations); the rows of a block share only the loops. With a
    finite ``fold_angle``, ``folded[rows[lane]]`` is set True if any wrapped |alpha_k|
    reaches it at the end of any substep (a fold between control instants); other
    entries are left as they are. ``target_energy`` is indexed by row, like ``folded``.
    """
    y, stage, deriv, total, mass0, work, lane_scalars, _, _ = workspace
    width = y.shape[0]
    target = lane_scalars[0]
    current = lane_scalars[1]
    if preserve_energy:
        energy_block(pv, y, n, mass0, deriv, work, current, nb)
        for lane in range(nb):
            wanted = target_energy[rows[lane]]
            target[lane] = wanted if wanted > 0.0 else current[lane]
    check_fold = fold_angle < math.inf
    near_fold = fold_angle - _FOLD_MARGIN
    h = dt / substeps
    half_h = 0.5 * h
    sixth_h = h / 6.0
    for step in range(substeps):
        t0 = step * h
        t_mid = t0 + 0.5 * h
        t1 = t0 + h
        field_block(pv, y, n, with_pose, mass0, t0, deriv, work, nb)
        for j in range(width):
            for lane in range(nb):
                total[j, lane] = deriv[j, lane]
                stage[j, lane] = y[j, lane] + half_h * deriv[j, lane]
        field_block(pv, stage, n, with_pose, mass0, t_mid, deriv, work, nb)
        for j in range(width):
            for lane in range(nb):
                total[j, lane] = total[j, lane] + 2.0 * deriv[j, lane]
                stage[j, lane] = y[j, lane] + half_h * deriv[j, lane]
        field_block(pv, stage, n, with_pose, mass0, t_mid, deriv, work, nb)
        for j in range(width):
            for lane in range(nb):
                total[j, lane] = total[j, lane] + 2.0 * deriv[j, lane]
                stage[j, lane] = y[j, lane] + h * deriv[j, lane]
        field_block(pv, stage, n, with_pose, mass0, t1, deriv, work, nb)
        for j in range(width):
            for lane in range(nb):
                y[j, lane] += sixth_h * (total[j, lane] + deriv[j, lane])
        if preserve_energy:
            # At fixed alpha and a mass at rest on the cart, E is a quadratic form in
            # (u, omega): one scale factor restores it exactly.
            energy_block(pv, y, n, mass0, deriv, work, current, nb)
            for lane in range(nb):
                if current[lane] > 0.0:
                    scale = math.sqrt(target[lane] / current[lane])
                    y[U, lane] *= scale
                    y[OMEGA, lane] *= scale
        if check_fold:
            near = work[_W_SIN]
            for lane in range(nb):
                near[lane] = 0.0
            for k in range(n):
                for lane in range(nb):
                    near[lane] = max(near[lane], abs(y[ALPHA + k, lane]))
            for lane in range(nb):
                if near[lane] >= near_fold:  # rare: the exact wrapped test
                    for k in range(n):
                        if _wrapped_folded(y[ALPHA + k, lane], fold_angle):
                            folded[rows[lane]] = True


@cached_njit(nogil=True)
def block_order(substeps: np.ndarray) -> np.ndarray:
    """Row order in which runs of equal substep counts are contiguous (identity if all equal)."""
    count = substeps.shape[0]
    uniform = True
    for i in range(1, count):
        if substeps[i] != substeps[0]:
            uniform = False
            break
    if uniform:
        return np.arange(count)
    return np.argsort(substeps, kind="mergesort")


@cached_njit(nogil=True)
def block_end(order: np.ndarray, first: int, stop: int, substeps: np.ndarray) -> int:
    """End of the block that starts at ``order[first]``: the rows ``order[first:end]``
    (``end <= stop``) share its substep count, at most :data:`LANES` of them.

    The one grouping rule of every batched RK4 driver (:func:`rk4_ordered_rows`,
    ``trailer_env.kernels``): blocks of at most :data:`ROW_PATH_MAX_ROWS` rows take the
    row path, larger ones the block path.
    """
    count = substeps[order[first]]
    end = first + 1
    while end < stop and end - first < LANES and substeps[order[end]] == count:
        end += 1
    return end


@cached_njit(nogil=True)
def advance_rows(
    pv: np.ndarray,
    scratch: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    rows: np.ndarray,
    nb: int,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: int,
    preserve_energy: bool,
    target_energy: np.ndarray,
    fold_angle: float,
    folded: np.ndarray,
    workspace: tuple,
) -> np.ndarray:
    """RK4 on the ``nb`` rows ``rows[:nb]`` (one block of :func:`block_end`), in place.

    The one step of every batched RK4 driver: blocks of at most
    :data:`ROW_PATH_MAX_ROWS` rows take the row path (:func:`advance_row`), larger
    ones the block path (:func:`gather_block`, :func:`advance_block`,
    :func:`scatter_block`); both leave the block's new state in ``workspace[0]``, so a
    caller can read it as structure of arrays. The mass state in ``act`` advances by
    ``dt`` exactly; ``workspace[4]`` still holds its value at the start of the call.
    Returns the block's parameters (:func:`gather_params` into ``scratch``).
    """
    lane_pv = gather_params(pv, rows, nb, scratch)
    if nb <= ROW_PATH_MAX_ROWS:
        for i in rows[:nb]:
            advance_row(
                row_params(pv, i),
                z,
                act,
                i,
                n,
                with_pose,
                dt,
                substeps,
                preserve_energy,
                target_energy,
                fold_angle,
                folded,
                workspace[8],
            )
        gather_block(z, act, rows, nb, workspace)
        for i in rows[:nb]:
            advance_mass_row(act, i, dt)
    else:
        gather_block(z, act, rows, nb, workspace)
        advance_block(
            lane_pv,
            rows,
            nb,
            n,
            with_pose,
            dt,
            substeps,
            preserve_energy,
            target_energy,
            fold_angle,
            folded,
            workspace,
        )
        scatter_block(z, act, rows, nb, dt, workspace)
    return lane_pv


@cached_njit(nogil=True)
def rk4_ordered_rows(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    order: np.ndarray,
    start: int,
    stop: int,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: np.ndarray,
    preserve_energy: bool,
    target_energy: np.ndarray,
    fold_angle: float,
    folded: np.ndarray,
    workspace: tuple,
) -> None:
    """RK4 on rows ``order[start:stop]``, in blocks of up to LANES rows of equal substeps."""
    scratch = params_scratch(pv)
    i = start
    while i < stop:
        j = block_end(order, i, stop, substeps)
        advance_rows(
            pv,
            scratch,
            z,
            act,
            order[i:j],
            j - i,
            n,
            with_pose,
            dt,
            substeps[order[i]],
            preserve_energy,
            target_energy,
            fold_angle,
            folded,
            workspace,
        )
        i = j


#: Below this many rows the serial loop wins: waking worker threads costs more
#: than a small batch's arithmetic (see benchmarks/README.md, "Threads"). The one
#: threshold of every batched driver (``dynamics.Stepper``, ``trailer_env.kernels``).
PARALLEL_MIN_ROWS = 1024
#: Rows per parallel chunk (a multiple of LANES), for every batched driver.
ROWS_PER_CHUNK = 4 * LANES


@cached_njit()
def rk4_batch_serial(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: np.ndarray,
    preserve_energy: bool,
    target_energy: np.ndarray,
) -> None:
    """Same as :func:`rk4_batch` on the calling thread (single envs, small batches)."""
    order = block_order(substeps)
    folded = np.zeros(0, dtype=np.bool_)
    rk4_ordered_rows(
        pv,
        z,
        act,
        order,
        0,
        z.shape[0],
        n,
        with_pose,
        dt,
        substeps,
        preserve_energy,
        target_energy,
        math.inf,
        folded,
        new_workspace(z.shape[1]),
    )


@cached_njit(parallel=True)
def rk4_batch(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: np.ndarray,
    preserve_energy: bool,
    target_energy: np.ndarray,
) -> None:
    """Advance every row of ``z`` and ``act`` in place by ``dt`` with classical RK4.

    Row i takes ``substeps[i]`` equal substeps, so a batch can mix fidelities.
    With ``preserve_energy``, row i is rescaled to ``target_energy[i]`` (or, where
    that is NaN or <= 0, to its energy at the start of the call): a target held
    across calls keeps rounding errors from accumulating over long runs.
    Rows are independent, so chunks of rows run on all cores; each row's
    arithmetic is the same whatever the chunking or the block it shares, so
    results do not depend on the number of threads.
    """
    order = block_order(substeps)
    folded = np.zeros(0, dtype=np.bool_)
    n_rows = z.shape[0]
    for chunk in prange((n_rows + ROWS_PER_CHUNK - 1) // ROWS_PER_CHUNK):
        stop = min(n_rows, (chunk + 1) * ROWS_PER_CHUNK)
        rk4_ordered_rows(
            pv,
            z,
            act,
            order,
            chunk * ROWS_PER_CHUNK,
            stop,
            n,
            with_pose,
            dt,
            substeps,
            preserve_energy,
            target_energy,
            math.inf,
            folded,
            new_workspace(z.shape[1]),
        )


@cached_njit(nogil=True)
def singular_margin_row(row: np.ndarray, offset: int, n: int) -> float:
    """min over k < n of |cos(alpha_k)| for the angles ``row[offset:offset + n]`` (1 if n <= 1)."""
    margin = 1.0
    for k in range(n - 1):
        margin = min(margin, abs(math.cos(row[offset + k])))
    return margin


@cached_njit(nogil=True)
def is_folded_row(row: np.ndarray, offset: int, n: int, fold_angle: float) -> bool:
    """Whether any wrapped |alpha_k|, the last included, reaches ``fold_angle``."""
    # Fast path: when every raw |alpha_k| is inside the fold angle, so is every wrapped one,
    # and the three trig calls per angle of the wrap are not needed (hot in the envs).
    for k in range(n):
        if not abs(row[offset + k]) < fold_angle - _FOLD_MARGIN:
            break
    else:
        return False
    for k in range(n):
        alpha = row[offset + k]
        if abs(math.atan2(math.sin(alpha), math.cos(alpha))) >= fold_angle:
            return True
    return False


@cached_njit()
def singular_batch(
    alpha: np.ndarray, fold_angle: float, margin: np.ndarray, folded: np.ndarray
) -> None:
    """Singular margin and fold flag of every row of ``alpha`` (B, n)."""
    n = alpha.shape[1]
    for i in range(alpha.shape[0]):
        margin[i] = singular_margin_row(alpha[i], 0, n)
        folded[i] = is_folded_row(alpha[i], 0, n, fold_angle)
