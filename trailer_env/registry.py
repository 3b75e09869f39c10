"""Registration of the scenes with Gymnasium, and the look-ups from an id back to a scene.

Every id is ``trailer_env/{scene}-v{version}`` as the scene's core declares it
(:data:`trailer_env.scenes.SCENE_ENVS`). Each has an ``entry_point`` (the single env) and a
``vector_entry_point`` (:class:`trailer_env.vector.ConvoyVectorEnv` bound to the scene's
core), and ``max_episode_steps`` from the core.
"""

from __future__ import annotations

import functools

import gymnasium as gym

from trailer_env.core import ConvoyCore
from trailer_env.env import ConvoyEnv
from trailer_env.scenes import SCENE_ENVS
from trailer_env.vector import ConvoyVectorEnv

NAMESPACE = "trailer_env"


def env_id_of(env_class: type[ConvoyEnv]) -> str:
    """The id a scene's env class is registered under, e.g. "trailer_env/Reverse-v0"."""
    core = env_class.core_class
    return f"{NAMESPACE}/{core.scene}-v{core.version}"


#: Registered id -> the scene's single-env class, in registration order.
ENVIRONMENTS: dict[str, type[ConvoyEnv]] = {env_id_of(env): env for env in SCENE_ENVS}


def register_scenes() -> None:
    """Register every scene of :data:`ENVIRONMENTS` (ids already registered are kept)."""
    for env_id, env_class in ENVIRONMENTS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=f"{env_class.__module__}:{env_class.__name__}",
            vector_entry_point=functools.partial(ConvoyVectorEnv, env_class.core_class),
            max_episode_steps=env_class.core_class.max_episode_steps,
        )


def env_class_of(env_id: str) -> type[ConvoyEnv]:
    """The single-env class registered as ``env_id``.

    Raises:
        ValueError: Naming the registered ids, if ``env_id`` is not one of them.
    """
    if env_id not in ENVIRONMENTS:
        raise ValueError(f"unknown environment {env_id!r}; choose from {list(ENVIRONMENTS)}")
    return ENVIRONMENTS[env_id]


def core_class_of(env_id: str) -> type[ConvoyCore]:
    """The batch core of the scene registered as ``env_id`` (ValueError if unknown)."""
    return env_class_of(env_id).core_class
