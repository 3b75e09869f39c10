"""Environment construction for training and evaluation: id checks, native batches, SB3 adapter."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import gymnasium as gym

from trailer_env.mixed import is_trailer_range, mixed_settings
from trailer_env.registry import ENVIRONMENTS, core_class_of, env_class_of
from trailer_env.settings import EnvSettings, settings_from_kwargs
from trailer_env.vector import ConvoyVectorEnv

if TYPE_CHECKING:
    from trailer_env.sb3 import ConvoySB3VecEnv

#: The headline scene: the commands' default environment.
HEADLINE_ENV_ID = "trailer_env/Reverse-v1"
#: The headline scenario's number of trailers (the main job's, the report's first table's).
HEADLINE_N_TRAILERS = 2

#: The registered ids, e.g. "trailer_env/Reverse-v0" (the scene table's order).
ENV_IDS: tuple[str, ...] = tuple(ENVIRONMENTS)


def check_env_id(env_id: str) -> str:
    """Return ``env_id`` if it names a trailer_env scene.

    Raises:
        ValueError: Naming the valid ids otherwise.
    """
    env_class_of(env_id)
    return env_id


def scene_of(env_id: str) -> str:
    """The scene's short name as its core declares it, lower case, with its version past 0:
    "reverse" for "trailer_env/Reverse-v0", "reverse_v1" for "trailer_env/Reverse-v1" (run
    folders and model files are named with it)."""
    core = core_class_of(env_id)
    return core.scene.lower() + (f"_v{core.version}" if core.version else "")


def scene_title(env_id: str) -> str:
    """The id without its namespace, for titles: "Reverse-v0"."""
    core = core_class_of(env_id)
    return f"{core.scene}-v{core.version}"


def headline_metric(env_id: str) -> str:
    """The rate reported first for the scene (a key of
    :func:`agents.evaluation.metrics.summarize`)."""
    return core_class_of(env_id).headline_metric


def scene_baselines(env_id: str) -> tuple[str, ...]:
    """The baselines the scene evaluates by default (:data:`agents.policies.baselines.BASELINES`),
    as its core declares them. The planners that apply too, run only when named, are the
    scene's record's (:func:`agents.policies.baselines.applicable_baselines`)."""
    return core_class_of(env_id).baselines


#: ``gym.make`` keywords as a caller gives them: checked by the environment itself.
MakeKwargs = Mapping[str, object]


def make_keywords(env_kwargs: MakeKwargs | None) -> dict[str, Any]:
    """``env_kwargs`` to pass on as ``gym.make(id, **keywords)`` (their types are the
    settings' to check)."""
    return dict(env_kwargs or {})


def env_settings(env_kwargs: MakeKwargs | None = None) -> EnvSettings:
    """The settings that ``gym.make(id, **env_kwargs)`` would build (validated)."""
    return settings_from_kwargs(**make_keywords(env_kwargs))


def settings_by_count(env_kwargs: MakeKwargs) -> dict[int, EnvSettings]:
    """The validated settings of each n that ``env_kwargs`` asks for: one entry for one
    count, one per count of a range ``n_trailers=(low, high)`` (:mod:`trailer_env.mixed`)."""
    keywords = make_keywords(env_kwargs)
    if is_trailer_range(keywords.get("n_trailers")):
        return mixed_settings(keywords)
    settings = env_settings(keywords)
    return {settings.n_trailers: settings}


def make_vector_env(
    env_id: str, num_envs: int, env_kwargs: MakeKwargs | None = None
) -> ConvoyVectorEnv:
    """The native batched env (one kernel call per step for all ``num_envs``)."""
    envs = gym.make_vec(
        check_env_id(env_id),
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        **make_keywords(env_kwargs),
    )
    native = envs.unwrapped
    if not isinstance(native, ConvoyVectorEnv):  # pragma: no cover - registration guarantees it
        raise TypeError(f"{env_id} did not build a ConvoyVectorEnv")
    return native


def make_sb3_env(
    env_id: str, num_envs: int, env_kwargs: MakeKwargs | None = None, seed: int | None = None
) -> ConvoySB3VecEnv:
    """The SB3 ``VecEnv`` over the native batch (it records episode statistics itself).

    Environment ``i`` is seeded with ``seed + i`` at the first reset.
    """
    from trailer_env.sb3 import ConvoySB3VecEnv

    venv = ConvoySB3VecEnv(check_env_id(env_id), num_envs=num_envs, **make_keywords(env_kwargs))
    if seed is not None:
        venv.seed(seed)
    return venv
