"""Singular and folded configurations (physics.md section 10)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dynamics import _kernel
from dynamics.model import FloatArray, real_array
from dynamics.params import real_number


def _classify(alpha: ArrayLike, fold_angle: float) -> tuple[FloatArray, NDArray[np.bool_]]:
    array = real_array("alpha", alpha)
    if array.ndim == 0:
        raise ValueError("alpha must have a last axis (the n hitch angles)")
    if not np.all(np.isfinite(array)):
        raise ValueError("alpha contains non-finite values (NaN or inf)")
    batch = int(np.prod(array.shape[:-1], dtype=np.int64))
    rows = np.ascontiguousarray(array.reshape(batch, array.shape[-1]))
    margin = np.empty(rows.shape[0])
    folded = np.empty(rows.shape[0], dtype=np.bool_)
    _kernel.singular_batch(rows, real_number("fold_angle", fold_angle), margin, folded)
    return margin.reshape(array.shape[:-1]), folded.reshape(array.shape[:-1])


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
    return _classify(alpha, np.pi)[0]


def is_jackknifed(alpha: ArrayLike, fold_angle: float = np.pi / 2) -> NDArray[np.bool_]:
    """Whether any hitch angle, the last included, has |alpha_k| >= ``fold_angle``.

    Angles are wrapped to (-pi, pi] first. Returns a boolean array ``alpha.shape[:-1]``.

    Raises:
        TypeError: If ``alpha`` or ``fold_angle`` is not made of real numbers.
        ValueError: If ``alpha`` has no last axis or a value is not finite.
    """
    return _classify(alpha, fold_angle)[1]
