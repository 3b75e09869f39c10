"""stable-baselines3 model zips, loaded without unpickling anything unless trusted.

Before anything is inflated, :func:`check_zip` reads the zip's directory and refuses
a zip bomb: more than :data:`~agents.artifacts.limits.MAX_ZIP_MEMBERS` members, a member
inflating past :data:`~agents.artifacts.limits.MAX_ZIP_MEMBER_BYTES` (all together past
:data:`~agents.artifacts.limits.MAX_ZIP_TOTAL_BYTES`), or one over 1 MiB compressed more
than :data:`~agents.artifacts.limits.MAX_ZIP_RATIO` times. The network the ``data``
entry's ``policy_kwargs`` asks for is bounded (:func:`~agents.artifacts.limits.network_problem`)
before SB3 builds it. Models are saved atomically (:func:`save_model`).

A ``policy_kwargs`` that holds a class (a features extractor, an activation) is a pickle
in the zip; it is rebuilt from the entry's JSON text instead, with classes taken only
from the tables the caller passes (``extractors``: the shipped features extractors,
:func:`agents.policies.extractors.feature_extractors`) and torch's activations: a class
named by the text and in no table is refused.
"""

from __future__ import annotations

import io
import math
import re
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from gymnasium.spaces import Dict, flatdim

from agents.algorithms import ALGOS, algo_class, algorithm
from agents.artifacts import files, limits
from agents.artifacts.files import UnsafeFileError

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


__all__ = ["ALGOS", "UnsafeFileError", "algo_class", "check_zip", "load_sb3", "read_sb3_data"]


def check_zip(path: Path) -> None:
    """Refuse a zip whose members would inflate too far (read from its directory only).

    Raises:
        ValueError: If it is not a zip, or is a zip bomb (see the module's docstring).
    """
    try:
        with zipfile.ZipFile(path) as archive:
            members = archive.infolist()
    except (zipfile.BadZipFile, OSError, ValueError) as error:
        raise ValueError(f"{path} is not a stable-baselines3 model: {error}") from None
    if len(members) > limits.MAX_ZIP_MEMBERS:
        raise UnsafeFileError(
            f"{path} has {len(members)} members, over the limit of {limits.MAX_ZIP_MEMBERS}"
        )
    total = 0
    for member in members:
        total += member.file_size
        ratio = member.file_size / max(member.compress_size, 1)
        if member.file_size > limits.MAX_ZIP_MEMBER_BYTES or (
            member.file_size > 2**20 and ratio > limits.MAX_ZIP_RATIO
        ):
            raise UnsafeFileError(
                f"{path}: member {member.filename!r} inflates to {member.file_size} bytes "
                f"({ratio:.0f} times its compressed size); limits: "
                f"{limits.MAX_ZIP_MEMBER_BYTES} bytes, ratio {limits.MAX_ZIP_RATIO}"
            )
    if total > limits.MAX_ZIP_TOTAL_BYTES:
        raise UnsafeFileError(
            f"{path} inflates to {total} bytes, over the limit of {limits.MAX_ZIP_TOTAL_BYTES}"
        )


def read_sb3_data(path: Path) -> dict[str, object]:
    """The JSON ``data`` entry of an SB3 zip, as text values (nothing unpickled).

    Raises:
        ValueError: If the file is not a zip with a JSON ``data`` entry, or is a zip bomb
            (:func:`check_zip`).
    """
    check_zip(path)
    try:
        with zipfile.ZipFile(path) as archive:
            raw = archive.read("data")
    except (zipfile.BadZipFile, KeyError, OSError, ValueError, EOFError) as error:
        raise ValueError(f"{path} is not a stable-baselines3 model: {error}") from None
    try:
        data = files.parse_json(raw, f"the data entry of {path}", allow_nan=True)
    except ValueError as error:
        raise ValueError(f"{path} is not a stable-baselines3 model: {error}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} is not a stable-baselines3 model: data is not a JSON object")
    return data


def check_network(path: Path, data: Mapping[str, object], observation_space: Any = None) -> None:
    """Refuse a model whose ``policy_kwargs.net_arch`` is past the network bound.

    Raises:
        ValueError: Naming the file and the bound.
    """
    kwargs = data.get("policy_kwargs")
    if not isinstance(kwargs, dict) or "net_arch" not in kwargs:
        return
    inputs = int(flatdim(observation_space)) if observation_space is not None else 64
    problem = limits.network_problem(kwargs["net_arch"], inputs=inputs)
    if problem is not None:
        raise ValueError(f"{path}: {problem}")


def save_model(model: Any, path: Path) -> Path:
    """``model.save`` made atomic: the zip is built in memory, then replaces ``path``."""
    buffer = io.BytesIO()
    model.save(buffer)
    return files.atomic_write_bytes(path, buffer.getvalue())


def _is_serialized(value: object) -> bool:
    return isinstance(value, dict) and ":serialized:" in value


def saved_shape(data: Mapping[str, object], key: str) -> tuple[int, ...] | None:
    """The shape of a saved space, from the JSON ``_shape`` SB3 writes beside the pickle
    (a list of ints, or its text), or None when it is not there."""
    entry = data.get(key)
    shape = entry.get("_shape") if isinstance(entry, dict) else None
    if isinstance(shape, list) and all(isinstance(size, int) for size in shape):
        return tuple(shape)
    if isinstance(shape, str) and re.fullmatch(r"[\[(][\d, ]*[\])]", shape):
        return tuple(int(part) for part in re.findall(r"\d+", shape))
    return None


def _constant(value: object, fallback: float) -> float:
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


#: torch activations a saved ``policy_kwargs`` may name (as its text ``<class '...'>``).
_ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "SiLU", "GELU")


def _class_text(cls: type) -> str:
    """How SB3's ``data`` entry writes a class it pickled: ``str(cls)``."""
    return str(cls)


def safe_policy_kwargs(
    path: Path, entry: Mapping[str, object], extractors: Mapping[str, type] | None = None
) -> dict[str, object]:
    """A pickled ``policy_kwargs`` entry rebuilt from its JSON text (nothing unpickled).

    SB3 writes beside the pickle each item as JSON, or as its ``str`` when it is not
    JSON (a class: ``"<class 'module.Name'>"``). JSON items are kept; a class text must
    be one of ``extractors`` (for ``features_extractor_class``) or a torch activation of
    :data:`_ACTIVATIONS` (for ``activation_fn``).

    Raises:
        UnsafeFileError: If the entry is not a dict's record, or an item is a class (or
            any other object) outside those tables.
    """
    if entry.get(":type:") != "<class 'dict'>":
        raise UnsafeFileError(
            f"{path}: its policy_kwargs is a pickled {entry.get(':type:')!r}, not a dict; "
            "load it with --trust-pickle only if you trust the file"
        )
    classes: dict[str, type] = {_class_text(cls): cls for cls in (extractors or {}).values()}
    import torch.nn

    activations = {
        _class_text(getattr(torch.nn, name)): getattr(torch.nn, name) for name in _ACTIVATIONS
    }
    kwargs: dict[str, object] = {}
    for key, value in entry.items():
        if key in (":type:", ":serialized:"):
            continue
        table = {"features_extractor_class": classes, "activation_fn": activations}.get(key)
        if table is not None and isinstance(value, str) and value in table:
            kwargs[key] = table[value]
        elif isinstance(value, str) and value.startswith("<"):
            raise UnsafeFileError(
                f"{path}: policy_kwargs[{key!r}] is {value[:80]!r}, which has no safe "
                "replacement (shipped features extractors and torch activations only); load "
                "it with --trust-pickle only if you trust the file"
            )
        else:
            kwargs[key] = value
    return kwargs


def safe_custom_objects(
    path: Path,
    algo: str,
    observation_space: Any,
    action_space: Any,
    algo_kwargs: Mapping[str, object] | None = None,
    extractors: Mapping[str, type] | None = None,
) -> dict[str, object]:
    """Replacements for every ``:serialized:`` entry of an SB3 zip (SB3's ``custom_objects``).

    Args:
        path: The model zip.
        algo: A name of :data:`agents.algorithms.ALGOS`.
        observation_space, action_space: The spaces of the environment the model will
            act in (checked against the saved shapes).
        algo_kwargs: The hyperparameter file's algorithm arguments: schedules, train
            frequency and action noise for a resumed training (None: evaluation only,
            constants read from the file's text, no noise).
        extractors: The features extractors a pickled ``policy_kwargs`` may name
            (:func:`safe_policy_kwargs`); None: none.

    Raises:
        ValueError: On a shape mismatch, a policy class of another algorithm, or a
            serialized entry that has no safe replacement.
    """
    data = read_sb3_data(path)
    check_network(path, data, observation_space)
    kwargs = algo_kwargs or {}
    for key, space in (("observation_space", observation_space), ("action_space", action_space)):
        shape = saved_shape(data, key)
        if shape is not None and space.shape is not None and shape != tuple(space.shape):
            noun = "observations" if key == "observation_space" else "actions"
            raise ValueError(
                f"model {path} expects {noun} of shape {shape}, "
                f"but the environment has {tuple(space.shape)}"
            )
    entry = data.get("policy_class", {})
    if not isinstance(entry, dict):
        raise ValueError(f"{path}: its policy_class entry is not an SB3 class record")
    module = str(entry.get("__module__", ""))
    if module and module != algorithm(algo).policy_module:
        raise ValueError(
            f"{path}: policy class from {module!r}, not {algo}'s MlpPolicy; "
            "custom policies load only with --trust-pickle"
        )
    learning_rate = kwargs.get("learning_rate", _constant(data.get("learning_rate"), 3e-4))
    # A Dict observation (observation="trailers") needs the algorithm's MultiInputPolicy,
    # recorded under the same module.
    policy = "MultiInputPolicy" if isinstance(observation_space, Dict) else "MlpPolicy"
    replacements: dict[str, object] = {
        "policy_class": algo_class(algo).policy_aliases[policy],
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
    policy_kwargs = data.get("policy_kwargs")
    if isinstance(policy_kwargs, dict) and _is_serialized(policy_kwargs):
        rebuilt = safe_policy_kwargs(path, policy_kwargs, extractors)
        problem = limits.network_problem(rebuilt.get("net_arch", [64, 64]))
        if problem is not None:
            raise ValueError(f"{path}: {problem}")
        replacements["policy_kwargs"] = rebuilt
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
    observation_space: object,
    action_space: object,
    *,
    env: object = None,
    algo_kwargs: Mapping[str, object] | None = None,
    trust_pickle: bool = False,
    extractors: Mapping[str, type] | None = None,
) -> Any:
    """Load an SB3 model on the CPU, unpickling nothing unless ``trust_pickle``
    (``extractors``: see :func:`safe_custom_objects`).

    Raises:
        ValueError: If the file is not a loadable model of ``algo`` for these spaces
            (damaged or missing weights included), or needs unpickling and
            ``trust_pickle`` is false (:class:`UnsafeFileError`).
    """
    if trust_pickle:
        check_network(path, read_sb3_data(path), observation_space)
    custom = (
        None
        if trust_pickle
        else safe_custom_objects(
            path, algo, observation_space, action_space, algo_kwargs, extractors
        )
    )
    with zipfile.ZipFile(path) as archive:
        if "policy.pth" not in archive.namelist():
            raise ValueError(f"{path} holds no policy weights (policy.pth)")
    try:
        return algo_class(algo).load(path, env=env, device="cpu", custom_objects=custom)
    except Exception as error:  # torch/SB3 raise many types for a damaged file
        raise ValueError(f"cannot load model {path}: {type(error).__name__}: {error}") from None
