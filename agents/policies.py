"""The policy registry: a baseline by name or a saved stable-baselines3 model by path.

``load_policy("lqr", ...)`` and ``load_policy("agents/models/sac_reverse_n2.zip", ...)``
both return a batched :data:`agents.baselines.Policy`. A saved model may carry a
*model card*, a JSON file beside it (same stem) written by :mod:`agents.train`, that
records the algorithm, environment, seed, budget and wall time of its training.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from agents.baselines import BASELINES, Policy, make_baseline
from agents.envs import check_env_id, env_settings, make_vector_env

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


def limit_torch_threads(threads: int = 1) -> None:
    """Use ``threads`` torch threads: small policies on a shared 2-core machine run 10-30x
    faster on one thread than on several competing with the simulation and other jobs."""
    import torch

    torch.set_num_threads(threads)


def card_path(model_path: Path) -> Path:
    """Where the model card of ``model_path`` lives (``x.zip`` -> ``x.json``)."""
    return model_path.with_suffix(".json")


def stats_path(model_path: Path) -> Path:
    """Where the observation-normalisation statistics of ``model_path`` live, if it has any.

    ``x.zip`` -> ``x_vecnormalize.pkl``; SB3 checkpoints ``<algo>_<k>_steps.zip`` ->
    ``<algo>_vecnormalize_<k>_steps.pkl`` (the names ``CheckpointCallback`` writes);
    rl-zoo3's ``<env>.zip`` -> ``<env>/vecnormalize.pkl``.
    """
    stem = model_path.stem
    zoo_stats = model_path.with_suffix("") / "vecnormalize.pkl"
    if zoo_stats.is_file():
        return zoo_stats
    prefix, _, steps = stem.rpartition("_")
    if steps == "steps":
        algo, _, count = prefix.rpartition("_")
        checkpoint_stats = model_path.with_name(f"{algo}_vecnormalize_{count}_steps.pkl")
        if checkpoint_stats.is_file():
            return checkpoint_stats
    return model_path.with_name(f"{stem}_vecnormalize.pkl")


def load_stats(model_path: Path) -> Any:
    """The ``VecNormalize`` saved with ``model_path`` (without its env), or None."""
    path = stats_path(model_path)
    if not path.is_file():
        return None
    import pickle

    with path.open("rb") as handle:
        stats = pickle.load(handle)
    stats.training = False
    return stats


def read_card(model_path: Path) -> dict[str, Any]:
    """The model card of ``model_path``, or an empty dict when there is none."""
    path = card_path(model_path)
    return json.loads(path.read_text()) if path.is_file() else {}


def detect_algo(model_path: Path) -> str:
    """The algorithm that saved ``model_path``: from its card, else from the policy class.

    Raises:
        ValueError: If the file is not a stable-baselines3 zip of PPO, SAC or TD3.
    """
    algo = read_card(model_path).get("algo")
    if algo in ALGOS:
        return str(algo)
    try:
        with zipfile.ZipFile(model_path) as archive:
            data = json.loads(archive.read("data"))
    except (zipfile.BadZipFile, KeyError, json.JSONDecodeError) as error:
        raise ValueError(f"{model_path} is not a stable-baselines3 model: {error}") from None
    module = str(data.get("policy_class", {}).get("__module__", ""))
    for name in ("sac", "td3"):
        if f".{name}." in module:
            return name
    if module.endswith("common.policies"):
        return "ppo"  # actor-critic policies (PPO, A2C) predict the same way
    raise ValueError(f"{model_path}: cannot tell the algorithm from policy module {module!r}")


class ModelPolicy:
    """A model's deterministic action, batched.

    Args:
        model: A stable-baselines3 algorithm.
        stats: The ``VecNormalize`` whose observation statistics the model was trained
            with (None: raw observations). Used read-only.
    """

    def __init__(self, model: Any, stats: Any = None) -> None:
        self.model = model
        self.stats = stats

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.atleast_2d(obs)
        if self.stats is not None:
            batch = self.stats.normalize_obs(batch)
        actions, _ = self.model.predict(batch, deterministic=True)
        return np.asarray(actions, dtype=np.float32)


def load_model(model_path: Path | str, algo: str | None = None) -> Any:
    """Load a saved model on the CPU (the algorithm detected unless given).

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If it is not a model of a known algorithm.
    """
    path = Path(model_path)
    if not path.is_file():
        raise FileNotFoundError(f"no model file {path}")
    return algo_class(algo or detect_algo(path)).load(path, device="cpu")


def is_model_spec(spec: str) -> bool:
    """Whether ``spec`` names a model file rather than a baseline."""
    return spec.endswith(".zip") or "/" in spec or Path(spec).suffix != ""


def policy_label(spec: str) -> str:
    """Short name of a policy spec for tables: the baseline name or the model's file stem."""
    return Path(spec).stem if is_model_spec(spec) else spec


def load_policy(
    spec: str, env_id: str, env_kwargs: dict[str, Any] | None = None, seed: int | None = 0
) -> Policy:
    """A batched policy from a baseline name or a model path.

    Args:
        spec: A baseline name (:data:`agents.baselines.BASELINES`) or a ``.zip`` model path.
        env_id: The environment it will act in.
        env_kwargs: The environment's keyword arguments (``n_trailers`` ...).
        seed: Seed of the random baseline.

    Raises:
        ValueError: Unknown name, unknown environment, or a model whose observation
            space does not fit the environment (e.g. trained for another n).
        FileNotFoundError: A model path that does not exist.
    """
    check_env_id(env_id)
    if not is_model_spec(spec):
        if spec not in BASELINES:
            raise ValueError(
                f"unknown policy {spec!r}: give a baseline ({', '.join(BASELINES)}) "
                "or the path of a saved model (.zip)"
            )
        return make_baseline(spec, env_settings(env_kwargs), env_id, seed)
    model = load_model(spec)
    probe = make_vector_env(env_id, 1, env_kwargs)
    expected = probe.single_observation_space.shape
    if model.observation_space.shape != expected:
        card = read_card(Path(spec))
        trained = (
            f" (trained on {card.get('env_id')} with {card.get('env_kwargs')})" if card else ""
        )
        raise ValueError(
            f"model {spec} expects observations of shape {model.observation_space.shape}, "
            f"but {env_id} with {env_kwargs or {}} gives {expected}{trained}"
        )
    return ModelPolicy(model, load_stats(Path(spec)))
