"""stable-baselines3 model zips, loaded without unpickling anything unless trusted."""

from __future__ import annotations

import json
import math
import re
import zipfile
from pathlib import Path
from typing import Any

#: Entries of an SB3 ``data`` that hold runtime state, rebuilt by SB3 when they are None.
_RUNTIME_STATE = (
    "_last_obs",
    "_last_episode_starts",
    "_last_original_obs",
    "ep_info_buffer",
    "ep_success_buffer",
    "rollout_buffer_class",
    "replay_buffer_class",
)


#: Module of each algorithm's MlpPolicy, as SB3 records it in ``policy_class``.
_POLICY_MODULES = {
    "ppo": "stable_baselines3.common.policies",
    "sac": "stable_baselines3.sac.policies",
    "td3": "stable_baselines3.td3.policies",
}


class UnsafeFileError(ValueError):
    """A file (or part of one) could only be read by unpickling it, which was not allowed."""


#: Algorithm name (as on the command line) -> stable-baselines3 class name.
ALGOS: dict[str, str] = {"ppo": "PPO", "sac": "SAC", "td3": "TD3"}


def algo_class(algo: str) -> Any:
    """The stable-baselines3 class of ``algo`` ("ppo", "sac" or "td3").

    Raises:
        ValueError: On an unknown algorithm.
    """
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; choose from {sorted(ALGOS)}")
    import stable_baselines3

    return getattr(stable_baselines3, ALGOS[algo])


def read_sb3_data(path: Path) -> dict[str, Any]:
    """The JSON ``data`` entry of an SB3 zip, as text values (nothing unpickled).

    Raises:
        ValueError: If the file is not a zip with a JSON ``data`` entry.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not a stable-baselines3 model: {error}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} is not a stable-baselines3 model: data is not a JSON object")
    return data


def _is_serialized(value: Any) -> bool:
    return isinstance(value, dict) and ":serialized:" in value


def saved_shape(data: dict[str, Any], key: str) -> tuple[int, ...] | None:
    """The shape of a saved space, from the JSON ``_shape`` SB3 writes beside the pickle
    (a list of ints, or its text), or None when it is not there."""
    entry = data.get(key)
    shape = entry.get("_shape") if isinstance(entry, dict) else None
    if isinstance(shape, list) and all(isinstance(size, int) for size in shape):
        return tuple(shape)
    if isinstance(shape, str) and re.fullmatch(r"[\[(][\d, ]*[\])]", shape):
        return tuple(int(part) for part in re.findall(r"\d+", shape))
    return None


def _constant(value: Any, fallback: float) -> float:
    """A schedule's constant from its text ``ConstantSchedule(val=x)``, else ``fallback``."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, dict):
        match = re.fullmatch(
            r"ConstantSchedule\(val=([-+0-9.eE]+)\)", str(value.get("value_schedule"))
        )
        if match and math.isfinite(float(match.group(1))):
            return float(match.group(1))
    return fallback


def safe_custom_objects(
    path: Path,
    algo: str,
    observation_space: Any,
    action_space: Any,
    algo_kwargs: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Replacements for every ``:serialized:`` entry of an SB3 zip (SB3's ``custom_objects``).

    Args:
        path: The model zip.
        algo: "ppo", "sac" or "td3".
        observation_space, action_space: The spaces of the environment the model will
            act in (checked against the saved shapes).
        algo_kwargs: The hyperparameter file's algorithm arguments: schedules, train
            frequency and action noise for a resumed training (None: evaluation only,
            constants read from the file's text, no noise).

    Raises:
        ValueError: On a shape mismatch, a policy class of another algorithm, or a
            serialized entry that has no safe replacement.
    """
    from agents.artifacts.sb3_zip import algo_class

    data = read_sb3_data(path)
    kwargs = algo_kwargs or {}
    for key, space in (("observation_space", observation_space), ("action_space", action_space)):
        shape = saved_shape(data, key)
        if shape is not None and shape != tuple(space.shape):
            noun = "observations" if key == "observation_space" else "actions"
            raise ValueError(
                f"model {path} expects {noun} of shape {shape}, "
                f"but the environment has {tuple(space.shape)}"
            )
    entry = data.get("policy_class", {})
    if not isinstance(entry, dict):
        raise ValueError(f"{path}: its policy_class entry is not an SB3 class record")
    module = str(entry.get("__module__", ""))
    if module and module != _POLICY_MODULES[algo]:
        raise ValueError(
            f"{path}: policy class from {module!r}, not {algo}'s MlpPolicy; "
            "custom policies load only with --trust-pickle"
        )
    learning_rate = kwargs.get("learning_rate", _constant(data.get("learning_rate"), 3e-4))
    replacements: dict[str, Any] = {
        "policy_class": algo_class(algo).policy_aliases["MlpPolicy"],
        "observation_space": observation_space,
        "action_space": action_space,
        "learning_rate": learning_rate,
        "lr_schedule": (lambda _: 0.0) if callable(learning_rate) else learning_rate,
        "clip_range": kwargs.get("clip_range", _constant(data.get("clip_range"), 0.2)),
        "train_freq": kwargs.get("train_freq", 1),
        "action_noise": kwargs.get("action_noise"),
        **dict.fromkeys(_RUNTIME_STATE),
    }
    if "clip_range_vf" in data:
        replacements["clip_range_vf"] = kwargs.get("clip_range_vf")
    custom = {}
    for key, value in data.items():
        if not _is_serialized(value):
            continue
        if key not in replacements:
            raise UnsafeFileError(
                f"{path}: entry {key!r} is a pickle with no safe replacement; "
                "load it with --trust-pickle only if you trust the file"
            )
        custom[key] = replacements[key]
    return custom


def load_sb3(
    path: Path,
    algo: str,
    observation_space: Any,
    action_space: Any,
    *,
    env: Any = None,
    algo_kwargs: dict[str, Any] | None = None,
    trust_pickle: bool = False,
) -> Any:
    """Load an SB3 model on the CPU, unpickling nothing unless ``trust_pickle``.

    Raises:
        ValueError: If the file is not a loadable model of ``algo`` for these spaces
            (damaged or missing weights included), or needs unpickling and
            ``trust_pickle`` is false (:class:`UnsafeFileError`).
    """
    from agents.artifacts.sb3_zip import algo_class

    custom = (
        None
        if trust_pickle
        else safe_custom_objects(path, algo, observation_space, action_space, algo_kwargs)
    )
    with zipfile.ZipFile(path) as archive:
        if "policy.pth" not in archive.namelist():
            raise ValueError(f"{path} holds no policy weights (policy.pth)")
    try:
        return algo_class(algo).load(path, env=env, device="cpu", custom_objects=custom)
    except Exception as error:  # torch/SB3 raise many types for a damaged file
        raise ValueError(f"cannot load model {path}: {type(error).__name__}: {error}") from None
