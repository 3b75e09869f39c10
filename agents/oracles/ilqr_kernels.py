"""The compiled arithmetic of the iLQR planner: its backward pass and its feedback law.

Both loop over rows with scalar arithmetic in a fixed order, so a row's result depends on
that row's numbers only, never on the batch it sits in or on a BLAS library's blocking:
the same state gives the same bits wherever it is planned.
"""

from __future__ import annotations

import numpy as np

from dynamics.jit import cached_njit


@cached_njit()
def backward_pass(
    a_matrix: np.ndarray,
    b_vector: np.ndarray,
    jacobian: np.ndarray,
    residual: np.ndarray,
    terminal_jacobian: np.ndarray,
    terminal_residual: np.ndarray,
    alive: np.ndarray,
    control: np.ndarray,
    control_weight: float,
    regularization: np.ndarray,
    k_out: np.ndarray,
    gain_out: np.ndarray,
    decrease_out: np.ndarray,
) -> None:
    """Box-constrained DDP backward pass (Gauss-Newton) for a scalar control in [-1, 1].

    Shapes: ``a_matrix`` (E, H, d, d) and ``b_vector`` (E, H, d), the step's Jacobians
    ``x_{t+1} = A x_t + B v_t``; ``jacobian`` (E, H+1, m, d) and ``residual`` (E, H+1, m)
    of the stage residuals at ``x_t`` (cost ``sum r^2``, counted for t >= 1);
    ``terminal_*`` (E, mT, d) and (E, mT) at ``x_H``; ``alive`` (E, H+1): the episode still
    runs at ``x_t``; ``control`` (E, H) the nominal controls; ``regularization`` (E,) added
    to ``Q_vv``. Writes the feedforward steps ``k_out`` (E, H), clipped so that
    ``control + k`` stays in [-1, 1], the gains ``gain_out`` (E, H, d) (zero where the
    step is clipped: the box's active set) and the model's predicted decrease
    ``decrease_out`` (E,) for a full step. A row whose ``Q_vv`` or ``Q_v`` is not finite
    and positive (a derivative blew up) gets no step at all (zeros).
    """
    count, horizon, d = b_vector.shape
    m = residual.shape[2]
    mt = terminal_residual.shape[1]
    vx = np.zeros(d)
    vxx = np.zeros((d, d))
    qx = np.zeros(d)
    qxx = np.zeros((d, d))
    qvx = np.zeros(d)
    vb = np.zeros(d)
    av = np.zeros((d, d))
    for e in range(count):
        vx[:] = 0.0
        vxx[:] = 0.0
        if alive[e, horizon]:
            for i in range(d):
                total = 0.0
                for j in range(m):
                    total += jacobian[e, horizon, j, i] * residual[e, horizon, j]
                for j in range(mt):
                    total += terminal_jacobian[e, j, i] * terminal_residual[e, j]
                vx[i] = 2.0 * total
                for k in range(d):
                    total = 0.0
                    for j in range(m):
                        total += jacobian[e, horizon, j, i] * jacobian[e, horizon, j, k]
                    for j in range(mt):
                        total += terminal_jacobian[e, j, i] * terminal_jacobian[e, j, k]
                    vxx[i, k] = 2.0 * total
        decrease = 0.0
        for t in range(horizon - 1, -1, -1):
            if not alive[e, t]:
                vx[:] = 0.0
                vxx[:] = 0.0
                k_out[e, t] = 0.0
                gain_out[e, t, :] = 0.0
                continue
            # vb = V_xx B, av = V_xx A.
            for i in range(d):
                total = 0.0
                for j in range(d):
                    total += vxx[i, j] * b_vector[e, t, j]
                vb[i] = total
                for k in range(d):
                    total = 0.0
                    for j in range(d):
                        total += vxx[i, j] * a_matrix[e, t, j, k]
                    av[i, k] = total
            qv = 2.0 * control_weight * control[e, t]
            qvv = 2.0 * control_weight + regularization[e]
            for i in range(d):
                qv += b_vector[e, t, i] * vx[i]
                qvv += b_vector[e, t, i] * vb[i]
            for i in range(d):
                total = 0.0
                value = 0.0
                for j in range(d):
                    total += a_matrix[e, t, j, i] * vx[j]
                    value += b_vector[e, t, j] * av[j, i]
                qvx[i] = value
                state_term = 0.0
                if t > 0:  # the cost of x_0 is fixed: nothing to optimise
                    for j in range(m):
                        state_term += jacobian[e, t, j, i] * residual[e, t, j]
                qx[i] = total + 2.0 * state_term
                for k in range(d):
                    total = 0.0
                    for j in range(d):
                        total += a_matrix[e, t, j, i] * av[j, k]
                    if t > 0:
                        state_term = 0.0
                        for j in range(m):
                            state_term += jacobian[e, t, j, i] * jacobian[e, t, j, k]
                        total += 2.0 * state_term
                    qxx[i, k] = total
            if not (np.isfinite(qv) and np.isfinite(qvv) and qvv > 0.0):
                # A derivative blew up (a kink of the guard, say): no step for this row.
                k_out[e, :] = 0.0
                gain_out[e, :, :] = 0.0
                decrease = 0.0
                break
            step = -qv / qvv
            low = -1.0 - control[e, t]
            high = 1.0 - control[e, t]
            clipped = False
            if step < low:
                step = low
                clipped = True
            elif step > high:
                step = high
                clipped = True
            k_out[e, t] = step
            for i in range(d):
                gain_out[e, t, i] = 0.0 if clipped else -qvx[i] / qvv
            decrease -= step * qv + 0.5 * step * step * qvv
            for i in range(d):
                gain = gain_out[e, t, i]
                vx[i] = qx[i] + gain * qvv * step + gain * qv + qvx[i] * step
            for i in range(d):
                for k in range(i, d):
                    gi = gain_out[e, t, i]
                    gk = gain_out[e, t, k]
                    value = qxx[i, k] + qvv * gi * gk + gi * qvx[k] + qvx[i] * gk
                    other = qxx[k, i] + qvv * gk * gi + gk * qvx[i] + qvx[k] * gi
                    vxx[i, k] = 0.5 * (value + other)
                    vxx[k, i] = vxx[i, k]
        decrease_out[e] = decrease


@cached_njit()
def feedback(
    feedforward: np.ndarray,
    gain: np.ndarray,
    state: np.ndarray,
    reference: np.ndarray,
    out: np.ndarray,
) -> None:
    """``out = clip(feedforward + gain . (state - reference), -1, 1)`` row by row
    (feedforward (R,), gain, state, reference (R, d))."""
    rows, d = state.shape
    for r in range(rows):
        total = feedforward[r]
        for j in range(d):
            total += gain[r, j] * (state[r, j] - reference[r, j])
        out[r] = min(max(total, -1.0), 1.0)


__all__ = ["backward_pass", "feedback"]
