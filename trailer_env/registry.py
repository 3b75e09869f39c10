"""Registration of the scenes with Gymnasium, and the look-ups from an id back to a scene.

Every id is ``trailer_env/{scene}-v{version}`` as the scene's core declares it
(:data:`trailer_env.scenes.SCENE_ENVS`). Each has an ``entry_point`` (the single env), a
``vector_entry_point`` (:class:`trailer_env.vector.ConvoyVectorEnv` bound to the scene's
core, a class of this module such as ``ReverseVectorEnv``) and ``max_episode_steps`` from
the core. Both entry points are ``"module:attr"`` strings, as Gymnasium's own ids have,
so ``gym.make(id).spec.to_json()`` works and ``gym.make(EnvSpec.from_json(...))`` makes
the environment again.
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.vector import AutoresetMode

from trailer_env.core import ConvoyCore
from trailer_env.env import ConvoyEnv
from trailer_env.scenes import SCENE_ENVS
from trailer_env.vector import ConvoyVectorEnv

NAMESPACE = "trailer_env"


def env_id_of(env_class: type[ConvoyEnv]) -> str:
    """The id a scene's env class is registered under, e.g. "trailer_env/Reverse-v0"."""
    core = env_class.core_class
    return f"{NAMESPACE}/{core.scene}-v{core.version}"


def _bound_vector_env(env_class: type[ConvoyEnv]) -> type[ConvoyVectorEnv]:
    """``ConvoyVectorEnv`` bound to the scene's core, named after the env class
    (``ReverseEnv`` -> ``ReverseVectorEnv``) and importable from this module."""
    core_class = env_class.core_class
    name = env_class.__name__.removesuffix("Env") + "VectorEnv"

    class Bound(ConvoyVectorEnv):
        def __init__(
            self,
            num_envs: int = 1,
            max_episode_steps: int | None = None,
            render_mode: str | None = None,
            autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
            **kwargs: object,
        ) -> None:
            super().__init__(
                core_class, num_envs, max_episode_steps, render_mode, autoreset_mode, **kwargs
            )

    Bound.__name__ = Bound.__qualname__ = name
    Bound.__doc__ = f"The vector env of {env_id_of(env_class)} (``{core_class.__name__}``)."
    return Bound


#: Registered id -> the scene's single-env class, in registration order.
ENVIRONMENTS: dict[str, type[ConvoyEnv]] = {env_id_of(env): env for env in SCENE_ENVS}
#: Registered id -> its vector env class (the ``vector_entry_point``).
VECTOR_ENVIRONMENTS: dict[str, type[ConvoyVectorEnv]] = {
    env_id: _bound_vector_env(env) for env_id, env in ENVIRONMENTS.items()
}
globals().update({cls.__name__: cls for cls in VECTOR_ENVIRONMENTS.values()})


def register_scenes() -> None:
    """Register every scene of :data:`ENVIRONMENTS` (ids already registered are kept)."""
    for env_id, env_class in ENVIRONMENTS.items():
        if env_id in gym.registry:
            continue
        vector_class = VECTOR_ENVIRONMENTS[env_id]
        gym.register(
            id=env_id,
            entry_point=f"{env_class.__module__}:{env_class.__name__}",
            vector_entry_point=f"{vector_class.__module__}:{vector_class.__name__}",
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
