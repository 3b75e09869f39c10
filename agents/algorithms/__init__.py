"""The algorithms ``agents.train`` trains and ``agents.evaluate`` loads: one record each.

:data:`ALGOS` is the one table of them. A record names the class (stable-baselines3's,
or this package's :class:`~agents.algorithms.ppo_lagrangian.PPOLagrangian`), the module
its saved ``MlpPolicy`` comes from (what the safe loader of :mod:`agents.artifacts.sb3_zip`
accepts in a zip); whether it keeps a replay buffer follows from its class (SB3's
``OffPolicyAlgorithm``). Adding an algorithm is one record here plus its hyperparameter
file ``agents/hyperparams/<name>.yml`` (or none: the files' ``default:`` entries).

The training options (``--start-replay``, ``--init-from`` ...) are records too
(:mod:`agents.algorithms.options`), and a run's recipe is named from its record
(:mod:`agents.algorithms.recipes`).

This package sits in the agents' bottom layer (beside ``seeds``, ``envs``, ``progress``)
so that the artifacts layer can load every algorithm's files.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

__all__ = ["ALGOS", "DEFAULT_NET_ARCH", "Algorithm", "algo_class", "algorithm"]

#: The hidden layers of every hyperparameter file's policies unless a recipe says
#: otherwise (small nets keep a saved model under 300 kB); a recipe with others is
#: labelled with its width (:func:`agents.algorithms.recipes.recipe_name`).
DEFAULT_NET_ARCH = (64, 64)


@dataclass(frozen=True)
class Algorithm:
    """One trainable algorithm.

    Attributes:
        name: As on the command line (``--algo``) and in model cards.
        module, class_name: Where its class lives (imported when first needed).
        policy_module: Module of the ``MlpPolicy`` class its saved zips record.
        label: A short description for help texts and docs.
        marker: An entry of the zip's ``data`` only this algorithm saves (it tells a
            checkpoint without a card from another algorithm's with the same policy), or
            None.
    """

    name: str
    module: str
    class_name: str
    policy_module: str
    label: str
    marker: str | None = None

    def load_class(self) -> Any:
        """The algorithm's class (imports its module)."""
        return getattr(importlib.import_module(self.module), self.class_name)

    @property
    def off_policy(self) -> bool:
        """Whether it keeps a replay buffer (checkpointed beside the model): its class is
        a stable-baselines3 ``OffPolicyAlgorithm`` (imports it)."""
        from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

        return issubclass(self.load_class(), OffPolicyAlgorithm)


#: Every algorithm, by name. A zip without a card is told by its policy's module and
#: the records' markers (:func:`agents.policies.sb3.detect_algo`).
ALGOS: dict[str, Algorithm] = {
    record.name: record
    for record in (
        Algorithm(
            "ppo", "stable_baselines3", "PPO", "stable_baselines3.common.policies", label="PPO"
        ),
        Algorithm(
            "ppo_lag",
            "agents.algorithms.ppo_lagrangian",
            "PPOLagrangian",
            "stable_baselines3.common.policies",
            label="PPO-Lagrangian (episode cost limit on info['cost'])",
            marker="lagrange_multiplier",
        ),
        Algorithm("sac", "stable_baselines3", "SAC", "stable_baselines3.sac.policies", label="SAC"),
        Algorithm("td3", "stable_baselines3", "TD3", "stable_baselines3.td3.policies", label="TD3"),
    )
}


def algorithm(name: str) -> Algorithm:
    """The record of ``name``.

    Raises:
        ValueError: On an unknown algorithm, naming the known ones.
    """
    if name not in ALGOS:
        raise ValueError(f"unknown algorithm {name!r}; choose from {sorted(ALGOS)}")
    return ALGOS[name]


def algo_class(name: str) -> Any:
    """The class of the algorithm ``name``.

    Raises:
        ValueError: On an unknown algorithm.
    """
    return algorithm(name).load_class()
