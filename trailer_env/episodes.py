"""Compiled episode bookkeeping of the batched environments, one call per step.

After the physics step, the vector env and the SB3 adapter count the step, apply the
time limit and mark the environments to reset; in NumPy that is five to eight small
array operations per step, which at a few environments cost as much as the physics.
"""

from __future__ import annotations

import numpy as np

from dynamics.jit import cached_njit


@cached_njit()
def count_step(
    elapsed: np.ndarray,
    max_steps: int,
    terminated: np.ndarray,
    truncated: np.ndarray,
    needs_reset: np.ndarray,
) -> int:
    """After a step: count it in ``elapsed``, write ``truncated`` (the time limit reached)
    and ``needs_reset`` (terminated or truncated); returns how many need a reset."""
    count = 0
    for i in range(elapsed.shape[0]):
        elapsed[i] += 1
        truncated[i] = elapsed[i] >= max_steps
        needs_reset[i] = terminated[i] or truncated[i]
        count += needs_reset[i]
    return count


@cached_njit()
def count_episodes(
    elapsed: np.ndarray,
    max_steps: int,
    terminated: np.ndarray,
    rewards: np.ndarray,
    returns: np.ndarray,
    lengths: np.ndarray,
    dones: np.ndarray,
    truncated: np.ndarray,
) -> int:
    """After a step: count it, add ``rewards`` (float32, as SB3's ``Monitor`` sums them) to
    the episodes' returns, write ``truncated`` (time limit, not terminated) and ``dones``;
    returns how many episodes ended."""
    ended = 0
    for i in range(elapsed.shape[0]):
        elapsed[i] += 1
        returns[i] += rewards[i]
        lengths[i] += 1
        truncated[i] = elapsed[i] >= max_steps and not terminated[i]
        dones[i] = terminated[i] or truncated[i]
        ended += dones[i]
    return ended
