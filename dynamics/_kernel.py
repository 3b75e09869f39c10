"""The one implementation of the equations: numba-jitted, row by row, O(n) per row.

Every public function of :mod:`dynamics` funnels into these kernels, whether it
serves one state or a batch of thousands.

Conventions (private to the package):

* ``pv``: float64 array ``[M, J0, a, m, J, l, mu]`` (see :func:`pack_params`).
* A row is ``(u, omega, alpha_1..alpha_n)``, optionally followed by the pose
  ``(x, y, theta)`` of the cart's axle midpoint; ``with_pose`` says which.
* ``act``: float64 array of shape ``(B, 6)`` holding the moving mass's body-frame
  position, velocity and acceleration ``(xi, eta, xi_dot, eta_dot, xi_ddot,
  eta_ddot)``. Over one integration call the acceleration is held constant (a
  zero-order hold), so position and velocity are exact quadratics in time.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from dynamics.params import ConvoyParams

P_M, P_J0, P_A, P_SMALL_M, P_J, P_L, P_MU = range(7)


def pack_params(params: ConvoyParams) -> np.ndarray:
    """Pack the parameters the kernels need into a float64 vector."""
    return np.array(
        [params.M, params.J0, params.a, params.m, params.J, params.l, params.mu],
        dtype=np.float64,
    )


@njit(cache=True, nogil=True)
def _hitch_terms(row: np.ndarray, n: int, m: float, J: float, l: float, A: np.ndarray) -> tuple:
    """R(alpha) - M, dR/dalpha_1 and sum_k A_k dR/dalpha_k in one O(n) forward pass.

    Writes A_k into ``A[k-1]``.

    dR/dalpha_k = -2 s_k c_k P_(k-1) (m S_k - (J/l^2) T_k) with the suffix sums
    S_k = sum_(j>=k) prod_(i=k+1..j) c_i^2 and suffix products T_k = prod_(i>k) c_i^2.
    Suffix quantities would need a backward pass; instead the weighted sums
    sum_k g_k S_k and sum_k g_k T_k are accumulated forwards by Horner-like
    recurrences (G_j = c_j^2 G_(j-1) + g_j), so no scratch arrays are needed.
    """
    J_l2 = J / (l * l)
    prefix_c2 = 1.0  # P_(k-1) = prod_(j<k) c_j^2
    prefix_c = 1.0  # prod_(j<=k-2) c_j
    sum_prefix_c2 = 0.0  # sum_(j<=k) P_j
    g_weighted_S = 0.0  # running G_j
    sum_g_S = 0.0  # sum_j G_j = sum_k g_k S_k
    g_weighted_T = 0.0  # H_j; H_n = sum_k g_k T_k
    tail_c2 = 1.0  # prod_(i=2..j) c_i^2, for S_1 and T_1
    sum_tail_c2 = 0.0
    c_prev = 1.0
    s_prev = 0.0
    c1s1 = 0.0
    for k in range(n):
        alpha = row[2 + k]
        c = math.cos(alpha)
        s = math.sin(alpha)
        c2 = c * c
        if k == 0:
            A_k = -s / l
            c1s1 = c * s
        else:
            A_k = prefix_c * (s_prev - c_prev * s) / l
            prefix_c *= c_prev
            tail_c2 *= c2
        A[k] = A_k
        sum_tail_c2 += tail_c2
        g = A_k * (-2.0 * s * c * prefix_c2)
        g_weighted_S = c2 * g_weighted_S + g
        sum_g_S += g_weighted_S
        g_weighted_T = c2 * g_weighted_T + g
        prefix_c2 *= c2
        sum_prefix_c2 += prefix_c2
        c_prev = c
        s_prev = s
    R_trailers = m * sum_prefix_c2 + J_l2 * (1.0 - prefix_c2)
    dR_dalpha1 = -2.0 * c1s1 * (m * sum_tail_c2 - J_l2 * tail_c2)
    sum_A_dR = m * sum_g_S - J_l2 * g_weighted_T
    return R_trailers, dR_dalpha1, sum_A_dR


@njit(cache=True, nogil=True)
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
    """d(row)/dt for the planar moving mass (physics.md sections 3, 4 and 10)."""
    M = pv[P_M]
    a = pv[P_A]
    mu = pv[P_MU]
    I0 = pv[P_J0] + M * a * a
    u = row[0]
    w = row[1]
    R_trailers, dR_dalpha1, sum_A_dR = _hitch_terms(
        row, n, pv[P_SMALL_M], pv[P_J], pv[P_L], out[2:]
    )
    R = M + R_trailers
    for k in range(n):
        out[2 + k] *= u
    if n > 0:
        out[2] += w
    # Phi_u with Q / l^2 = -dR/dalpha_1 / 2.
    phi_u = -0.5 * sum_A_dR * u * u - 0.5 * dR_dalpha1 * u * w + M * a * w * w
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
    out[0] = (m11 * b0 - m01 * b1) / det
    out[1] = (m00 * b1 - m01 * b0) / det
    if with_pose:
        theta = row[n + 4]
        out[n + 2] = u * math.cos(theta)
        out[n + 3] = u * math.sin(theta)
        out[n + 4] = w


@njit(cache=True, nogil=True)
def energy_row(
    pv: np.ndarray, row: np.ndarray, n: int, act: np.ndarray, scratch: np.ndarray
) -> float:
    M = pv[P_M]
    a = pv[P_A]
    mu = pv[P_MU]
    I0 = pv[P_J0] + M * a * a
    R_trailers, _, _ = _hitch_terms(row, n, pv[P_SMALL_M], pv[P_J], pv[P_L], scratch)
    u = row[0]
    w = row[1]
    xi, eta, xi_dot, eta_dot = act[0], act[1], act[2], act[3]
    vx = u - w * eta + xi_dot
    vy = w * xi + eta_dot
    return 0.5 * ((M + R_trailers) * u * u + I0 * w * w + mu * (vx * vx + vy * vy))


@njit(cache=True)
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
            act[i, 0],
            act[i, 1],
            act[i, 2],
            act[i, 3],
            act[i, 4],
            act[i, 5],
            out[i],
        )
    return out


@njit(cache=True)
def energy_batch(pv: np.ndarray, z: np.ndarray, act: np.ndarray, n: int) -> np.ndarray:
    """Energy of every row (physics.md section 10)."""
    out = np.empty(z.shape[0])
    scratch = np.empty(max(n, 1))
    for i in range(z.shape[0]):
        out[i] = energy_row(pv, z[i], n, act[i], scratch)
    return out


@njit(cache=True, nogil=True)
def _rk4_row(
    pv: np.ndarray,
    row: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: int,
    preserve_energy: bool,
    target_energy: float,
    k1: np.ndarray,
    k2: np.ndarray,
    k3: np.ndarray,
    k4: np.ndarray,
    stage: np.ndarray,
    scratch: np.ndarray,
) -> None:
    width = row.shape[0]
    h = dt / substeps
    xi0, eta0, xi_dot0, eta_dot0, xi_ddot, eta_ddot = act[0], act[1], act[2], act[3], act[4], act[5]
    if preserve_energy and not target_energy > 0.0:
        target_energy = energy_row(pv, row, n, act, scratch)
    for step in range(substeps):
        t0 = step * h
        t_mid = t0 + 0.5 * h
        t1 = t0 + h
        # The mass's motion is a known quadratic in time: evaluate it exactly at each stage.
        field_row(
            pv,
            row,
            n,
            with_pose,
            xi0 + xi_dot0 * t0 + 0.5 * xi_ddot * t0 * t0,
            eta0 + eta_dot0 * t0 + 0.5 * eta_ddot * t0 * t0,
            xi_dot0 + xi_ddot * t0,
            eta_dot0 + eta_ddot * t0,
            xi_ddot,
            eta_ddot,
            k1,
        )
        xi_mid = xi0 + xi_dot0 * t_mid + 0.5 * xi_ddot * t_mid * t_mid
        eta_mid = eta0 + eta_dot0 * t_mid + 0.5 * eta_ddot * t_mid * t_mid
        xi_dot_mid = xi_dot0 + xi_ddot * t_mid
        eta_dot_mid = eta_dot0 + eta_ddot * t_mid
        for j in range(width):
            stage[j] = row[j] + 0.5 * h * k1[j]
        field_row(
            pv, stage, n, with_pose, xi_mid, eta_mid, xi_dot_mid, eta_dot_mid, xi_ddot, eta_ddot, k2
        )
        for j in range(width):
            stage[j] = row[j] + 0.5 * h * k2[j]
        field_row(
            pv, stage, n, with_pose, xi_mid, eta_mid, xi_dot_mid, eta_dot_mid, xi_ddot, eta_ddot, k3
        )
        for j in range(width):
            stage[j] = row[j] + h * k3[j]
        field_row(
            pv,
            stage,
            n,
            with_pose,
            xi0 + xi_dot0 * t1 + 0.5 * xi_ddot * t1 * t1,
            eta0 + eta_dot0 * t1 + 0.5 * eta_ddot * t1 * t1,
            xi_dot0 + xi_ddot * t1,
            eta_dot0 + eta_ddot * t1,
            xi_ddot,
            eta_ddot,
            k4,
        )
        for j in range(width):
            row[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
        if preserve_energy:
            # At fixed alpha and a mass at rest on the cart, E is a quadratic form in
            # (u, omega): one scale factor restores it exactly.
            current = energy_row(pv, row, n, act, scratch)
            if current > 0.0:
                scale = math.sqrt(target_energy / current)
                row[0] *= scale
                row[1] *= scale
    act[0] = xi0 + xi_dot0 * dt + 0.5 * xi_ddot * dt * dt
    act[1] = eta0 + eta_dot0 * dt + 0.5 * eta_ddot * dt * dt
    act[2] = xi_dot0 + xi_ddot * dt
    act[3] = eta_dot0 + eta_ddot * dt


#: Below this many rows the serial loop wins: waking worker threads costs more
#: than a small batch's arithmetic (milliseconds on a loaded machine).
PARALLEL_MIN_ROWS = 256
_ROWS_PER_CHUNK = 64


@njit(cache=True, nogil=True)
def _rk4_rows(
    pv: np.ndarray,
    z: np.ndarray,
    act: np.ndarray,
    n: int,
    with_pose: bool,
    dt: float,
    substeps: np.ndarray,
    preserve_energy: bool,
    target_energy: np.ndarray,
    start: int,
    stop: int,
) -> None:
    """RK4 on rows ``start:stop`` with one set of scratch buffers."""
    buffers = np.empty((5, z.shape[1]))
    scratch = np.empty(max(n, 1))
    for i in range(start, stop):
        _rk4_row(pv, z[i], act[i], n, with_pose, dt, substeps[i], preserve_energy,
                 target_energy[i], buffers[0], buffers[1], buffers[2], buffers[3], buffers[4],
                 scratch)  # fmt: skip


@njit(cache=True)
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
    _rk4_rows(pv, z, act, n, with_pose, dt, substeps, preserve_energy, target_energy, 0, z.shape[0])


@njit(cache=True, parallel=True)
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
    arithmetic is the same whatever the chunking, so results do not depend on
    the number of threads.
    """
    n_rows = z.shape[0]
    for chunk in prange((n_rows + _ROWS_PER_CHUNK - 1) // _ROWS_PER_CHUNK):
        stop = min(n_rows, (chunk + 1) * _ROWS_PER_CHUNK)
        _rk4_rows(pv, z, act, n, with_pose, dt, substeps, preserve_energy, target_energy,
                  chunk * _ROWS_PER_CHUNK, stop)  # fmt: skip


@njit(cache=True, nogil=True)
def singular_margin_row(row: np.ndarray, offset: int, n: int) -> float:
    """min over k < n of |cos(alpha_k)| for the angles ``row[offset:offset + n]`` (1 if n <= 1)."""
    margin = 1.0
    for k in range(n - 1):
        margin = min(margin, abs(math.cos(row[offset + k])))
    return margin


#: Raw angles this far inside the fold angle cannot wrap onto it (rounding moves ~1e-15).
_FOLD_MARGIN = 1e-12


@njit(cache=True, nogil=True)
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


@njit(cache=True)
def singular_batch(
    alpha: np.ndarray, fold_angle: float, margin: np.ndarray, folded: np.ndarray
) -> None:
    """Singular margin and fold flag of every row of ``alpha`` (B, n)."""
    n = alpha.shape[1]
    for i in range(alpha.shape[0]):
        margin[i] = singular_margin_row(alpha[i], 0, n)
        folded[i] = is_folded_row(alpha[i], 0, n, fold_angle)
