"""The bounds every command checks before it does any work (one place, one table).

A value past a bound is refused with exit status 2 and a message naming the argument
or file and the bound, before anything is computed, allocated or written.

Limits:

=============================  ===========================  ===============================
what                           bound                        checked by
=============================  ===========================  ===============================
seeds (``--seed``, a start)    0 .. 2**32 - 1, also the     every command (numpy's
                               last episode's seed + K - 1  ``SeedSequence`` range)
``--episodes`` (evaluate,      1 .. 100,000                 :data:`MAX_EPISODES`
main, report), ``--eval-
episodes`` (train)
``--episodes`` (imitate)       1 .. 4,096 (one batch)       :data:`MAX_IMITATION_EPISODES`
certify ``--seeds``            10,000 seeds at most         :data:`MAX_CERTIFY_SEEDS`
``--n-envs``, ``n_envs``       1 .. 65,536                  :data:`MAX_N_ENVS`
``--timesteps``,               1 .. 2**31, and seed +       :data:`MAX_TIMESTEPS`
``n_timesteps``                steps <= 2**32 - 1
``--torch-threads``            1 .. 4 x os.cpu_count()      :func:`max_torch_threads`
network (``net_arch``,         10,000,000 parameters,       :data:`MAX_NETWORK_PARAMETERS`
``fcnet_hiddens``, a model's   64 layers                    (before building it)
``policy_kwargs``)
``--num-env-runners`` (rllib)  the cluster's CPUs           :mod:`agents.training.rllib`
                               (local: os.cpu_count())
JSON file                      16 MiB, 64 levels deep       :mod:`agents.artifacts.files`
SB3 zip member                 256 MiB inflated, 1 GiB in   :data:`MAX_ZIP_MEMBER_BYTES`,
                               all, ratio <= 200            :data:`MAX_ZIP_RATIO`
=============================  ===========================  ===============================
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterable

#: The largest seed: numpy's legacy seeding and many tools take 32-bit seeds.
MAX_SEED = 2**32 - 1
#: Episodes of one evaluation (one native batch per policy).
MAX_EPISODES = 100_000
#: Convoys per DAgger iteration (one batch, each labelled by the planner).
MAX_IMITATION_EPISODES = 4_096
#: Seeds one certification covers.
MAX_CERTIFY_SEEDS = 10_000
#: Environments of a training batch.
MAX_N_ENVS = 65_536
#: A training budget.
MAX_TIMESTEPS = 2**31
#: Parameters of a policy network (weights and biases of the hidden and output layers).
MAX_NETWORK_PARAMETERS = 10_000_000
#: Hidden layers of a policy network.
MAX_NETWORK_LAYERS = 64
#: Members of an SB3 zip, and what each (and all) may inflate to.
MAX_ZIP_MEMBERS = 64
MAX_ZIP_MEMBER_BYTES = 256 * 2**20
MAX_ZIP_TOTAL_BYTES = 2**30
#: The largest inflated/compressed size ratio of a member over 1 MiB (weights: about 1.1).
MAX_ZIP_RATIO = 200


def max_torch_threads() -> int:
    """Four torch threads per CPU at most."""
    return 4 * (os.cpu_count() or 1)


def seed_problem(seed: int, count: int = 1, what: str = "seed") -> str | None:
    """Why seeds ``seed .. seed + count - 1`` are out of range (None when they are not)."""
    if seed < 0 or seed + max(count, 1) - 1 > MAX_SEED:
        return (
            f"{what} {seed} would need seeds up to {seed + max(count, 1) - 1}; "
            f"seeds must lie in 0..{MAX_SEED} (2**32 - 1)"
        )
    return None


def _widths(net_arch: object) -> Iterable[list[int]]:
    """The hidden-layer lists of an SB3 ``net_arch`` (a list, or a dict of lists)."""
    if isinstance(net_arch, dict):
        for value in net_arch.values():
            yield from _widths(value)
    elif isinstance(net_arch, (list, tuple)):
        if all(isinstance(width, int) and not isinstance(width, bool) for width in net_arch):
            yield list(net_arch)
        else:
            for value in net_arch:
                yield from _widths(value)
    else:
        raise ValueError(f"net_arch must be a list of layer sizes, got {net_arch!r:.60}")


def network_problem(net_arch: object, inputs: int = 64, outputs: int = 64) -> str | None:
    """Why a ``net_arch`` is refused (None when it is not): layer sizes >= 1, at most
    :data:`MAX_NETWORK_LAYERS` layers and :data:`MAX_NETWORK_PARAMETERS` parameters
    over all its stacks (each from ``inputs`` to ``outputs`` units)."""
    try:
        stacks = list(_widths(net_arch))
    except ValueError as error:
        return str(error)
    total = 0
    for widths in stacks:
        if len(widths) > MAX_NETWORK_LAYERS:
            return f"net_arch has {len(widths)} layers, over the limit of {MAX_NETWORK_LAYERS}"
        if any(width < 1 for width in widths):
            return f"net_arch layer sizes must be >= 1, got {widths}"
        sizes = [inputs, *widths, outputs]
        total += sum((a + 1) * b for a, b in itertools.pairwise(sizes))
    if total > MAX_NETWORK_PARAMETERS:
        return (
            f"net_arch {net_arch!r:.80} has about {total:,} parameters, over the limit of "
            f"{MAX_NETWORK_PARAMETERS:,}"
        )
    return None
