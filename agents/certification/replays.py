"""Replaying a certificate's action records: the test every record passes.

A start is feasible when its record, replayed open-loop in a fresh env
(``gym.make(env_id, **env_kwargs)``, ``reset(seed=seed)``), reaches the scene's success:
a goal scene's goal at the record's last step, a survival scene's full episode kept
safe. The scene says which (``core_class_of(env_id).objective``).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from agents.artifacts.certificates import Certificate, Certified
from agents.certification.certify import replay
from agents.envs import MakeKwargs, check_env_id
from trailer_env.objective import Objective
from trailer_env.registry import core_class_of


def is_goal(env_id: str) -> bool:
    """Whether ``env_id``'s scene is certified by reaching its goal (not by surviving)."""
    return core_class_of(env_id).objective is Objective.GOAL


def replays_to_success(env_id: str, env_kwargs: MakeKwargs, seed: int, record: np.ndarray) -> bool:
    """Whether ``record`` replayed open-loop in a fresh env from ``reset(seed=seed)``
    reaches the scene's success exactly at its last step (goal scenes) or keeps the start
    safe for the full episode (Reverse): the test the planners' records pass."""
    return replay(env_id, env_kwargs, seed, record).feasible


def check_records(certified: Certified, where: str) -> None:
    """Replay a certificate's own action records on its own scene, n and physics (its
    ``env_id`` and ``env_kwargs``) before they are passed on.

    Every feasible start must have a record that replays to success
    (:func:`replays_to_success`); no start that is not feasible may have one; a start
    that states its drawn parameters (``params``, randomised physics) must draw exactly
    those again at ``reset(seed=seed)``. A record swapped for another, or a certificate
    relabelled with another scene, n or physics, fails here.

    Raises:
        ValueError: Naming ``where`` and the first start whose record or parameters do
            not match what the certificate states.
    """
    certificate, actions = certified.certificate, certified.actions
    env_id = check_env_id(certificate.env_id)
    env_kwargs = certificate.env_kwargs.kwargs()
    feasible = [start.seed for start in certificate.starts if start.feasible]
    missing = [seed for seed in feasible if seed not in actions]
    if missing:
        raise ValueError(f"{where}: no action record of the feasible starts {missing[:8]}")
    extra = sorted(set(actions) - set(feasible))
    if extra:
        raise ValueError(f"{where}: action records of starts that are not feasible {extra[:8]}")
    _check_params(certificate, where)
    outcome = "the goal" if is_goal(env_id) else "a safe episode of the full length"
    for seed in feasible:
        if not replays_to_success(env_id, env_kwargs, seed, np.asarray(actions[seed])):
            raise ValueError(
                f"{where}: the record of start {seed} does not replay to its stated outcome "
                f"(feasible: {outcome} on {env_id} with {_kwargs_text(env_kwargs)})"
            )


def _check_params(certificate: Certificate, where: str) -> None:
    """Every start that states its drawn parameters draws exactly those again."""
    stated = [start for start in certificate.starts if start.params is not None]
    if not stated:
        return
    env_kwargs = certificate.env_kwargs.kwargs()
    env = gym.make(certificate.env_id, **env_kwargs)
    try:
        for start in stated:
            _, info = env.reset(seed=start.seed)
            if start.params != info.get("params"):
                raise ValueError(
                    f"{where}: start {start.seed} states parameters that "
                    f"{certificate.env_id} with {_kwargs_text(env_kwargs)} does not draw"
                )
    finally:
        env.close()


def _kwargs_text(env_kwargs: MakeKwargs) -> str:
    return ", ".join(f"{key}={value!r}" for key, value in env_kwargs.items())


__all__ = ["check_records", "is_goal", "replays_to_success"]
