"""The shaped reward of :class:`trailer_env.core.ShapedCore`, written once for every path.

:func:`shaped_reward` is the formula for one row; scenes whose reward is computed inside
their compiled step (Coast) call it there, and :meth:`ShapedCore._reward` calls it through
:func:`shaped_rewards` for the whole batch, so the fused and unfused steps share it.
"""

from __future__ import annotations

import numpy as np

from dynamics.jit import cached_njit


@cached_njit(nogil=True)
def shaped_reward(
    potential: float,
    previous: float,
    cost: float,
    success: bool,
    jackknifed: bool,
    failed: bool,
    penalties: np.ndarray,
) -> float:
    """``potential - previous - time_penalty - band_penalty * cost + success_bonus * success
    - fold_penalty * jackknifed - failure_penalty * failed``.

    ``penalties`` is :attr:`trailer_env.core.ShapedCore.shaping_penalties`: (time_penalty,
    band_penalty, success_bonus, fold_penalty, failure_penalty).
    """
    return (
        potential
        - previous
        - penalties[0]
        - penalties[1] * cost
        + penalties[2] * success
        - penalties[3] * jackknifed
        - penalties[4] * failed
    )


@cached_njit()
def shaped_rewards(
    potential: np.ndarray,
    previous: np.ndarray,
    cost: np.ndarray,
    success: np.ndarray,
    jackknifed: np.ndarray,
    failed: np.ndarray,
    penalties: np.ndarray,
    out: np.ndarray,
) -> None:
    """:func:`shaped_reward` of every row into ``out``."""
    for i in range(out.shape[0]):
        out[i] = shaped_reward(potential[i], previous[i], cost[i], success[i], jackknifed[i],
                               failed[i], penalties)  # fmt: skip
