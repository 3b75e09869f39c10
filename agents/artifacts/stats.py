"""Observation-normalisation statistics as JSON; the legacy pickled format (trusted files only)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from agents.artifacts import files
from trailer_env.json_types import JSONObject

#: Format tag of the statistics files.
STATS_FORMAT = "trailer_env-vecnormalize/1"


def stats_document(vecnormalize: Any) -> JSONObject:
    """A ``VecNormalize``'s statistics and settings as JSON-ready data (float64, exact)."""

    def running(rms: Any) -> JSONObject:
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


def save_stats(vecnormalize: object, path: Path) -> Path:
    """Write a ``VecNormalize``'s statistics as JSON (Python's float repr round-trips exactly)."""
    return files.atomic_write_text(path, json.dumps(stats_document(vecnormalize), indent=1) + "\n")


#: The settings a statistics file holds beside its running statistics, and their types.
_SETTINGS = {
    "norm_obs": bool,
    "norm_reward": bool,
    "clip_obs": float,
    "clip_reward": float,
    "gamma": float,
    "epsilon": float,
}
#: The longest observation a statistics file may describe.
MAX_STATS_SIZE = 100_000


def _vector(value: object, where: str) -> np.ndarray:
    """A non-empty flat list of finite numbers as float64 (booleans refused)."""
    if (
        not isinstance(value, list)
        or not 0 < len(value) <= MAX_STATS_SIZE
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value)
    ):
        raise ValueError(f"{where} must be a non-empty list of at most {MAX_STATS_SIZE} numbers")
    vector = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(vector)):
        raise ValueError(f"{where} holds non-finite values")
    return vector


def check_stats(document: object, where: str) -> JSONObject:
    """``document`` if it is a statistics document of :func:`stats_document`'s form.

    Raises:
        ValueError: Naming ``where`` and what is missing or wrong.
    """
    if not isinstance(document, dict) or document.get("format") != STATS_FORMAT:
        raise ValueError(f"{where} is not a {STATS_FORMAT} statistics file")
    for key, kind in _SETTINGS.items():
        value = document.get(key)
        valid = isinstance(value, bool) if kind is bool else files.is_number(value)
        if not valid:
            raise ValueError(f"{where}: {key} must be a {'boolean' if kind is bool else 'number'}")
    for key in ("obs_rms", "ret_rms"):
        rms = document.get(key)
        if not isinstance(rms, dict) or not {"mean", "var", "count"} <= set(rms):
            raise ValueError(f"{where}: {key} needs mean, var and count")
        mean, var = rms["mean"], rms["var"]
        if key == "ret_rms" and not isinstance(mean, list):  # a scalar running statistic
            mean, var = [mean], [var]
        mean_vector = _vector(mean, f"{where}: {key}.mean")
        var_vector = _vector(var, f"{where}: {key}.var")
        count = rms["count"]
        if not files.is_number(count) or count < 0:
            raise ValueError(f"{where}: {key}.count must be a finite number >= 0")
        if mean_vector.shape != var_vector.shape:
            raise ValueError(f"{where}: {key} needs mean and var of one length")
        if np.any(var_vector < 0):
            raise ValueError(f"{where}: {key} holds negative-variance values")
    return document


def read_stats(path: Path) -> JSONObject:
    """Read and check a statistics file written by :func:`save_stats`.

    Raises:
        ValueError: If it is not such a file (size, format, keys, types, finite numbers).
    """
    try:
        document = files.read_json(path, "the file")
    except ValueError as error:
        raise ValueError(f"{path} is not a statistics JSON file: {error}") from None
    return check_stats(document, str(path))


def _running_mean_std(data: JSONObject) -> Any:
    from stable_baselines3.common.running_mean_std import RunningMeanStd

    rms = RunningMeanStd(shape=np.shape(data["mean"]))
    rms.mean = np.asarray(data["mean"], dtype=np.float64)
    rms.var = np.asarray(data["var"], dtype=np.float64)
    rms.count = float(data["count"])
    return rms


def restore_stats(vecnormalize: Any, document: JSONObject) -> Any:
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


def frozen_normalizer(document: JSONObject, observation_space: object) -> Any:
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
