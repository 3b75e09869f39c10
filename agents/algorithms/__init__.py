"""The algorithms ``agents.train`` trains and ``agents.evaluate`` loads: one record each.

:data:`ALGOS` is the one table of them. A record names the class (stable-baselines3's,
or this package's :class:`~agents.algorithms.ppo_lagrangian.PPOLagrangian`), the module
its saved ``MlpPolicy`` comes from (what the safe loader of :mod:`agents.artifacts.sb3_zip`
accepts in a zip); whether it keeps a replay buffer follows from its class (SB3's
``OffPolicyAlgorithm``). Adding an algorithm is one record here plus its hyperparameter
file ``agents/hyperparams/<name>.yml`` (or none: the files' ``default:`` entries).

This package sits in the agents' bottom layer (beside ``seeds``, ``envs``, ``progress``)
so that the artifacts layer can load every algorithm's files.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any

__all__ = ["ALGOS", "DEFAULT_NET_ARCH", "Algorithm", "algo_class", "algorithm", "recipe_name"]

#: The hidden layers of every hyperparameter file's policies unless a recipe says
#: otherwise (small nets keep a saved model under 300 kB); a recipe with others is
#: labelled with its width (:func:`recipe_name`).
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


def _uses_sde(hyperparams: object) -> bool:
    """Whether recorded hyperparameters turn on gSDE (PPO's argument, or SAC's and TD3's
    ``policy_kwargs`` entry)."""
    if not isinstance(hyperparams, Mapping):
        return False
    kwargs = hyperparams.get("policy_kwargs")
    in_policy = isinstance(kwargs, Mapping) and kwargs.get("use_sde") is True
    return hyperparams.get("use_sde") is True or in_policy


def _net_width(hyperparams: object) -> str | None:
    """The hidden layers as "256x256" when recorded and not :data:`DEFAULT_NET_ARCH`."""
    if not isinstance(hyperparams, Mapping):
        return None
    kwargs = hyperparams.get("policy_kwargs")
    arch = kwargs.get("net_arch") if isinstance(kwargs, Mapping) else None
    if not isinstance(arch, list) or arch == list(DEFAULT_NET_ARCH):
        return None
    return "x".join(str(width) for width in arch)


def recipe_name(record: Mapping[str, object], upper: bool = False) -> str:
    """A run's recipe from its configuration or model card: "ppo", "ppo (gSDE)",
    "ppo (gSDE, 256x256)", "ppo (gSDE) + lqr shaping", "ppo (gSDE) + start curriculum",
    "ppo (gSDE, 256x256) + start replay 0.25",
    "ppo from dagger_reverse_v1_n4" (the algorithm's name upper-cased when ``upper``).

    State-dependent exploration, a network other than :data:`DEFAULT_NET_ARCH`, reward
    shaping, a start curriculum (``start_curriculum``), a start replay (``start_replay``,
    by its share), a fine-tuning run's starting
    model (``init_from``, by its stem), randomised physics
    (``env_kwargs["randomize"]``: "ppo (mismatch20)") and counts fixed by the batch row
    (``trailer_draw="row"``: "n by row") are recipes of their own: runs are grouped,
    tabled and labelled by this name, so that they are never averaged with the plain
    algorithm's.
    """
    name = str(record.get("algo", "?"))
    if upper:
        name = name.upper()
    hyperparams = record.get("hyperparams")
    tags = ["gSDE"] if _uses_sde(hyperparams) else []
    width = _net_width(hyperparams)
    if width is not None:
        tags.append(width)
    env_kwargs = record.get("env_kwargs")
    if isinstance(env_kwargs, Mapping):
        randomize = env_kwargs.get("randomize")
        if randomize is not None:
            tags.append(randomize if isinstance(randomize, str) else "randomised")
        if env_kwargs.get("trailer_draw") == "row":
            tags.append("n by row")
    if tags:
        name += f" ({', '.join(tags)})"
    shaping = record.get("shaping")
    if isinstance(shaping, Mapping):
        name += f" + {shaping.get('potential')} shaping"
    if isinstance(record.get("start_curriculum"), Mapping):
        name += " + start curriculum"
    replay = record.get("start_replay")
    if isinstance(replay, Mapping):
        name += f" + start replay {replay.get('fraction')}"
        if "max_replays" in replay:
            name += f" (max {replay['max_replays']})"
    init_from = record.get("init_from")
    if isinstance(init_from, str):
        name += f" from {PurePath(init_from).stem}"
    return name
