"""Model files: their names, their cards, their export, and loading them without code execution.

Names: a model ``x.zip`` has its card ``x.json`` (:func:`card_path`), its observation
statistics ``x_vecnormalize.json`` (:func:`stats_path`) and, once exported, its learning
curve ``x.csv`` (:func:`curve_path`); a shipped model is named ``<algo>_<scene>_n<n>``
(:func:`model_stem`).

What is safe to load, and what is not:

* ``<model>_vecnormalize.json`` (observation-normalisation statistics): plain JSON
  numbers, always safe. The former ``<model>_vecnormalize.pkl`` was a pickle.
* An SB3 model zip: its weights (``*.pth``) are read by ``torch.load(weights_only=True)``,
  which refuses anything but tensors and plain containers. Its ``data`` entry is
  JSON, but SB3 stores some values in it as base64 *cloudpickle* (entries holding a
  ``:serialized:`` key: the spaces, the policy class, schedules, buffers' classes);
  SB3 would unpickle them. :func:`safe_custom_objects` replaces every such entry
  (SB3's ``custom_objects``) with a value built here: the spaces of the environment
  the model will act in (after checking the saved shapes, read from the entry's
  plain-text description), the algorithm's ``MlpPolicy``, and the hyperparameter
  file's schedules, so nothing of the file is unpickled. An entry it does not know is
  refused. Only ``trust_pickle=True`` (``--trust-pickle``) lets SB3 unpickle.
* SAC/TD3 replay buffers (``*_replay_buffer_*.pkl``) and legacy ``*_vecnormalize.pkl``
  files are pickles: loaded only with ``trust_pickle=True``.
* RLlib checkpoints: see :mod:`agents.rllib_backend` (a pickle-free export beside
  RLlib's own pickled files).
"""

from __future__ import annotations

import json
import math
import re
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

#: Format tag of the statistics files.
STATS_FORMAT = "trailer_env-vecnormalize/1"

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


def model_stem(algo: str, env_id: str, n_trailers: int) -> str:
    """The name of a shipped model: ``ppo_reverse_n2`` for PPO on Reverse-v0 with two trailers."""
    from agents.envs import scene_of

    return f"{algo}_{scene_of(env_id)}_n{n_trailers}"


def card_path(model_path: Path) -> Path:
    """Where the model card of ``model_path`` lives (``x.zip`` -> ``x.json``)."""
    return model_path.with_suffix(".json")


def stats_path(model_path: Path) -> Path:
    """Where the observation-normalisation statistics (JSON) of ``model_path`` live.

    ``x.zip`` -> ``x_vecnormalize.json``; checkpoints ``<algo>_<k>_steps.zip`` ->
    ``<algo>_vecnormalize_<k>_steps.json`` (beside them, as SB3's CheckpointCallback
    names its statistics).
    """
    stem = model_path.stem
    prefix, _, steps = stem.rpartition("_")
    if steps == "steps":
        algo, _, count = prefix.rpartition("_")
        if algo and count.isdigit():
            return model_path.with_name(f"{algo}_vecnormalize_{count}_steps.json")
    return model_path.with_name(f"{stem}_vecnormalize.json")


def pickled_stats_path(model_path: Path) -> Path | None:
    """A legacy pickled ``VecNormalize`` beside ``model_path`` (``.pkl``; rl-zoo3's
    ``<env>/vecnormalize.pkl``), or None."""
    for candidate in (
        stats_path(model_path).with_suffix(".pkl"),
        model_path.with_suffix("") / "vecnormalize.pkl",
    ):
        if candidate.is_file():
            return candidate
    return None


def replay_buffer_path(checkpoint: Path) -> Path | None:
    """The replay buffer CheckpointCallback saved with ``<algo>_<steps>_steps.zip``, if any."""
    stem = checkpoint.stem
    if not stem.endswith("_steps"):
        return None
    prefix = stem.removesuffix("_steps")
    algo, _, steps = prefix.rpartition("_")
    candidate = checkpoint.with_name(f"{algo}_replay_buffer_{steps}_steps.pkl")
    return candidate if candidate.is_file() else None


def read_card(model_path: Path) -> dict[str, Any]:
    """The model card of ``model_path``, or an empty dict when there is none.

    Raises:
        ValueError: If the card is not a JSON object.
    """
    path = card_path(model_path)
    if not path.is_file():
        return {}
    try:
        card = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"model card {path} is not JSON: {error}") from None
    if not isinstance(card, dict):
        raise ValueError(f"model card {path} is not a JSON object")
    return card


def write_json(path: Path, document: dict[str, Any]) -> Path:
    """Write a card or a run's ``config.json`` (sorted keys, so that files diff cleanly)."""
    path.write_text(json.dumps(document, indent=2, sort_keys=True) + "\n")
    return path


def write_card(model_path: Path, card: dict[str, Any]) -> Path:
    """Write the model card (JSON beside the model) that :func:`read_card` reads."""
    return write_json(card_path(model_path), card)


def curve_path(model_path: Path) -> Path:
    """Where an exported model's learning curve lives (``x.zip`` -> ``x.csv``)."""
    return model_path.with_suffix(".csv")


def export_files(destination: Path) -> list[Path]:
    """The files of a model exported to ``destination``: model, card, statistics, curve
    (:func:`agents.run_folder.export_model`)."""
    model = destination.with_suffix(".zip")
    return [model, card_path(model), stats_path(model), curve_path(model)]


def stats_document(vecnormalize: Any) -> dict[str, Any]:
    """A ``VecNormalize``'s statistics and settings as JSON-ready data (float64, exact)."""

    def running(rms: Any) -> dict[str, Any]:
        return {
            "mean": np.asarray(rms.mean, dtype=np.float64).tolist(),
            "var": np.asarray(rms.var, dtype=np.float64).tolist(),
            "count": float(rms.count),
        }

    return {
        "format": STATS_FORMAT,
        "norm_obs": bool(vecnormalize.norm_obs),
        "norm_reward": bool(vecnormalize.norm_reward),
        "clip_obs": float(vecnormalize.clip_obs),
        "clip_reward": float(vecnormalize.clip_reward),
        "gamma": float(vecnormalize.gamma),
        "epsilon": float(vecnormalize.epsilon),
        "obs_rms": running(vecnormalize.obs_rms),
        "ret_rms": running(vecnormalize.ret_rms),
    }


def save_stats(vecnormalize: Any, path: Path) -> Path:
    """Write a ``VecNormalize``'s statistics as JSON (Python's float repr round-trips exactly)."""
    path.write_text(json.dumps(stats_document(vecnormalize), indent=1) + "\n")
    return path


def read_stats(path: Path) -> dict[str, Any]:
    """Read and check a statistics file written by :func:`save_stats`.

    Raises:
        ValueError: If it is not such a file (format, keys, finite numbers).
    """
    try:
        document = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ValueError(f"{path} is not a statistics JSON file: {error}") from None
    if not isinstance(document, dict) or document.get("format") != STATS_FORMAT:
        raise ValueError(f"{path} is not a {STATS_FORMAT} statistics file")
    for key in ("obs_rms", "ret_rms"):
        rms = document.get(key)
        if not isinstance(rms, dict) or not {"mean", "var", "count"} <= set(rms):
            raise ValueError(f"{path}: {key} needs mean, var and count")
        values = np.asarray([*np.ravel(rms["mean"]), *np.ravel(rms["var"]), rms["count"]], float)
        if not np.all(np.isfinite(values)) or np.any(np.asarray(rms["var"]) < 0):
            raise ValueError(f"{path}: {key} holds non-finite or negative-variance values")
    return document


def _running_mean_std(data: dict[str, Any]) -> Any:
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    rms = RunningMeanStd(shape=np.shape(data["mean"]))
    rms.mean = np.asarray(data["mean"], dtype=np.float64)
    rms.var = np.asarray(data["var"], dtype=np.float64)
    rms.count = float(data["count"])
    return rms


def restore_stats(vecnormalize: Any, document: dict[str, Any]) -> Any:
    """Put saved statistics and settings into a ``VecNormalize`` (returns it).

    Raises:
        ValueError: If the saved observation statistics do not fit its observations.
    """
    obs_rms = _running_mean_std(document["obs_rms"])
    expected = tuple(vecnormalize.observation_space.shape)
    if obs_rms.mean.shape != expected:
        raise ValueError(
            f"statistics for observations of shape {obs_rms.mean.shape}, "
            f"but the environment gives {expected}"
        )
    vecnormalize.obs_rms = obs_rms
    vecnormalize.ret_rms = _running_mean_std(document["ret_rms"])
    for key in ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon"):
        setattr(vecnormalize, key, document[key])
    return vecnormalize


def frozen_normalizer(document: dict[str, Any], observation_space: Any) -> Any:
    """A read-only ``VecNormalize`` without an env, for ``normalize_obs`` at evaluation.

    It is built the way SB3's own unpickling builds one (``__setstate__``, no venv), so
    the normalisation is SB3's code, not a copy of its formula.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    normalizer = VecNormalize.__new__(VecNormalize)
    normalizer.__setstate__(
        {
            "observation_space": observation_space,
            "norm_obs_keys": None,
            "training": False,
            "returns": np.zeros(1),
        }
    )
    restore_stats(normalizer, document)
    return normalizer


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
    from agents.policies import algo_class

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
    from agents.policies import algo_class

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


def convert_pickled_stats(pickled: Path, destination: Path, overwrite: bool = False) -> Path:
    """Convert a legacy pickled ``VecNormalize`` (``*_vecnormalize.pkl``) to the JSON format.

    This unpickles ``pickled``: run it only on files you trust (your own runs).
    Command line: ``python -m agents.model_files --trust-pickle OLD.pkl NEW.json``.

    Raises:
        FileExistsError: If ``destination`` exists and ``overwrite`` is false.
    """
    if destination.exists() and not overwrite:
        raise FileExistsError(f"{destination} exists; pass --overwrite to replace it")
    return save_stats(load_pickled_stats(pickled), destination)


def load_pickled_stats(pickled: Path) -> Any:
    """Unpickle a legacy ``VecNormalize`` (read-only, no env). Only for trusted files."""
    import pickle

    with pickled.open("rb") as handle:
        vecnormalize = pickle.load(handle)  # the caller vouches for the file
    vecnormalize.training = False
    return vecnormalize


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.model_files --trust-pickle OLD.pkl NEW.json``: convert statistics."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="python -m agents.model_files",
        description="Convert pickled VecNormalize statistics (your own files) to JSON.",
    )
    parser.add_argument("pickled", type=Path, help="the *_vecnormalize.pkl to convert")
    parser.add_argument("destination", type=Path, help="the .json to write")
    parser.add_argument(
        "--trust-pickle", action="store_true", help="required: the conversion unpickles the file"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace the destination")
    args = parser.parse_args(argv)
    if not args.trust_pickle:
        parser.error("argument --trust-pickle: required, the conversion unpickles the file")
    if not args.pickled.is_file():
        parser.error(f"argument pickled: no file {args.pickled}")
    try:
        print(f"wrote {convert_pickled_stats(args.pickled, args.destination, args.overwrite)}")
    except FileExistsError as error:
        parser.error(f"argument destination: {error}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
