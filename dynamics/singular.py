"""Singular and folded configurations (physics.md section 9)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dynamics.model import FloatArray


def _angles(alpha: ArrayLike) -> FloatArray:
    array = np.asarray(alpha, dtype=np.float64)
    if array.ndim == 0:
        raise ValueError("alpha must have a last axis (the n hitch angles)")
    if not np.all(np.isfinite(array)):
        raise ValueError("alpha contains non-finite values (NaN or inf)")
    return array


def singular_margin(alpha: ArrayLike) -> FloatArray:
    """Distance to the singular set: min over k <= n-1 of |cos(alpha_k)|.

    Configurations with cos(alpha_k) = 0 for some k < n (two consecutive bodies
    perpendicular) are where the degree of nonholonomy jumps; the last
    trailer's angle never matters, so the margin is 1 when n <= 1.

    Args:
        alpha: Hitch angles ``(..., n)``.

    Returns:
        The margin in [0, 1], shape ``alpha.shape[:-1]``.

    Example:
        >>> float(singular_margin([0.0, 3.0]))
        1.0
    """
    array = _angles(alpha)
    if array.shape[-1] <= 1:
        return np.ones(array.shape[:-1])
    return np.min(np.abs(np.cos(array[..., :-1])), axis=-1)


def is_jackknifed(alpha: ArrayLike, fold_angle: float = np.pi / 2) -> np.ndarray:
    """Whether any hitch angle, the last included, has |alpha_k| >= ``fold_angle``.

    Angles are wrapped to (-pi, pi] first. Returns a boolean array ``alpha.shape[:-1]``.
    """
    array = _angles(alpha)
    wrapped = np.abs(np.angle(np.exp(1j * array)))
    if array.shape[-1] == 0:
        return np.zeros(array.shape[:-1], dtype=bool)
    return np.any(wrapped >= fold_angle, axis=-1)
