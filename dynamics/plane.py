"""Poses of every body in the plane (physics.md section 2, eq. 2.4).

Only scenes that need positions (docking, rendering) call this: the reduced
dynamics never do, because (x, y, theta) do not enter them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dynamics.model import FloatArray, real_array
from dynamics.params import real_number


def body_poses(
    l: float, x: ArrayLike, y: ArrayLike, theta: ArrayLike, alpha: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Axle-midpoint positions and headings of the cart and all trailers.

    Args:
        l: Hitch rod length, > 0.
        x, y, theta: Pose of the cart's axle midpoint, shape ``batch``.
        alpha: Hitch angles ``(*batch, n)``.

    Returns:
        ``(x_i, y_i, theta_i)``, each ``(*batch, n+1)``; index 0 is the cart.
        theta_i = theta - (alpha_1 + ... + alpha_i) and
        (x_i, y_i) = (x, y) - l * sum_(j<=i) (cos theta_j, sin theta_j), an O(n) cumulative sum.

    Example:
        >>> xs, ys, ths = body_poses(1.0, 0.0, 0.0, 0.0, [0.0, 0.0])
        >>> xs.tolist()
        [0.0, -1.0, -2.0]

    Raises:
        TypeError: If an argument is not made of real numbers (bools, strings, complex).
        ValueError: If ``l <= 0``, a value is not finite, or the shapes do not broadcast.
    """
    if real_number("l", l) <= 0.0:
        raise ValueError(f"l must be finite and > 0, got {l!r}")
    alpha_array = real_array("alpha", alpha)
    if alpha_array.ndim == 0:
        raise ValueError("alpha must have a last axis (the n hitch angles)")
    batch = alpha_array.shape[:-1]
    try:
        x0, y0, th0 = (
            np.broadcast_to(real_array(name, v), batch)
            for name, v in (("x", x), ("y", y), ("theta", theta))
        )
    except ValueError:
        raise ValueError(f"x, y, theta must broadcast to alpha's batch shape {batch}") from None
    for name, value in (("x", x0), ("y", y0), ("theta", th0), ("alpha", alpha_array)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    headings = th0[..., None] - np.concatenate(
        [np.zeros((*batch, 1)), np.cumsum(alpha_array, axis=-1)], axis=-1
    )
    rod_x = np.cumsum(np.cos(headings[..., 1:]), axis=-1)
    rod_y = np.cumsum(np.sin(headings[..., 1:]), axis=-1)
    xs = x0[..., None] - l * np.concatenate([np.zeros((*batch, 1)), rod_x], axis=-1)
    ys = y0[..., None] - l * np.concatenate([np.zeros((*batch, 1)), rod_y], axis=-1)
    return xs, ys, headings
