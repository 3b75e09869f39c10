"""The policy registry: a baseline by name, a saved model by path or shipped stem.

``load_policy("lqr", ...)`` and ``load_policy("agents/models/sac_reverse_n2.zip", ...)``
both return a batched :data:`agents.baselines.Policy`. A saved model may carry a
*model card*, a JSON file beside it (same stem; names in :mod:`agents.model_files`), that
records the algorithm, environment, seed, budget and wall time of its training.
Models load without unpickling anything unless the caller trusts the file
(:mod:`agents.model_files`); RLlib checkpoints come from :mod:`agents.rllib_backend`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from agents.baselines import BASELINES, Policy, make_baseline
from agents.envs import check_env_id, env_settings, make_vector_env
from agents.model_files import (
    UnsafeFileError,
    frozen_normalizer,
    load_pickled_stats,
    pickled_stats_path,
    read_card,
    read_sb3_data,
    read_stats,
    stats_path,
)
from agents.run_folder import RLLIB_CHECKPOINT

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


def load_stats(model_path: Path, observation_space: Any = None, trust_pickle: bool = False) -> Any:
    """The read-only ``VecNormalize`` saved with ``model_path`` (no env), or None.

    Reads ``stats_path(model_path)`` (JSON). A legacy pickled file is unpickled only
    with ``trust_pickle``.

    Raises:
        ValueError: On a damaged statistics file, statistics that do not fit
            ``observation_space``, or a pickled one without ``trust_pickle``.
    """
    path = stats_path(model_path)
    if path.is_file():
        if observation_space is None:
            import gymnasium as gym

            mean = read_stats(path)["obs_rms"]["mean"]
            observation_space = gym.spaces.Box(-np.inf, np.inf, np.shape(mean), np.float32)
        return frozen_normalizer(read_stats(path), observation_space)
    pickled = pickled_stats_path(model_path)
    if pickled is None:
        return None
    if not trust_pickle:
        raise UnsafeFileError(
            f"the observation statistics of {model_path} are a pickle ({pickled}); "
            "pass --trust-pickle to load them only if you trust the file"
        )
    return load_pickled_stats(pickled)


def detect_algo(model_path: Path) -> str:
    """The algorithm that saved ``model_path``: from its card, else from the policy class.

    Raises:
        ValueError: If the file is not a stable-baselines3 zip of PPO, SAC or TD3.
    """
    algo = read_card(model_path).get("algo")
    if algo in ALGOS:
        return str(algo)
    data = read_sb3_data(model_path)
    if not isinstance(data.get("policy_class", {}), dict):
        raise ValueError(f"{model_path} is not a stable-baselines3 model: unexpected data")
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


def load_model(
    model_path: Path | str,
    algo: str | None = None,
    *,
    env_id: str | None = None,
    env_kwargs: dict[str, Any] | None = None,
    trust_pickle: bool = False,
) -> Any:
    """Load a saved model on the CPU (the algorithm detected unless given) without pickles.

    The spaces that replace the file's pickled ones are those of ``env_id`` with
    ``env_kwargs``; by default the model card's environment (see
    :mod:`agents.model_files` for what is and is not unpickled).

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If it is not a loadable model of a known algorithm, or it needs
            unpickling and ``trust_pickle`` is false.
    """
    from agents.model_files import load_sb3

    path = Path(model_path)
    if not path.is_file():
        raise FileNotFoundError(f"no model file {path}")
    algo = algo or detect_algo(path)
    card = read_card(path)
    env_id = env_id or card.get("env_id")
    if env_id is None and not trust_pickle:
        raise ValueError(
            f"{path} has no model card naming its environment: give the environment, "
            "or pass --trust-pickle to read the spaces from the file's pickles"
        )
    if env_id is None:
        return load_sb3(path, algo, None, None, trust_pickle=True)
    kwargs = env_kwargs if env_kwargs is not None else card.get("env_kwargs", {})
    probe = make_vector_env(env_id, 1, kwargs)
    return load_sb3(
        path,
        algo,
        probe.single_observation_space,
        probe.single_action_space,
        trust_pickle=trust_pickle,
    )


#: Where shipped models live (inside the installed package, not the working directory).
MODELS_DIR = Path(__file__).resolve().parent / "models"


def resolve_model(spec: str) -> str:
    """A shipped model's path from its stem (``ppo_reverse_n2`` ->
    ``<package>/models/ppo_reverse_n2.zip``); other specs are returned unchanged."""
    if spec in BASELINES or "/" in spec or Path(spec).suffix:
        return spec
    shipped = MODELS_DIR / f"{spec}.zip"
    return str(shipped) if shipped.is_file() else spec


def shipped_models() -> list[str]:
    """Stems of the models shipped in :data:`MODELS_DIR`."""
    return sorted(path.stem for path in MODELS_DIR.glob("*.zip"))


def is_model_spec(spec: str) -> bool:
    """Whether ``spec`` names a model (file, shipped stem or RLlib folder), not a baseline."""
    if spec in BASELINES:
        return False
    return (
        spec.endswith(".zip")
        or "/" in spec
        or Path(spec).suffix != ""
        or (resolve_model(spec) != spec or Path(spec).is_dir())
    )


def policy_label(spec: str) -> str:
    """Short name of a policy spec for tables: the baseline name or the model's file stem."""
    if not is_model_spec(spec):
        return spec
    path = Path(resolve_model(spec))
    if path.is_dir() and path.name == RLLIB_CHECKPOINT:
        return path.resolve().parent.name  # an RLlib run's checkpoint: the run's name
    return path.stem


def check_card(card: dict[str, Any], spec: str, env_id: str, env_kwargs: dict[str, Any]) -> None:
    """Refuse a model whose card names another environment id or number of trailers.

    Raises:
        ValueError: On a mismatch (observations of equal length do not make two scenes
            alike: a Reverse-v0 model and Dock-v0 both see 8 numbers with n = 2).
    """
    if not card:
        return
    trained_id = card.get("env_id")
    trained_n = card.get("env_kwargs", {}).get("n_trailers")
    wanted_n = env_settings(env_kwargs).n_trailers
    if (trained_id is not None and trained_id != env_id) or (
        trained_n is not None and trained_n != wanted_n
    ):
        raise ValueError(
            f"model {spec} was trained on {trained_id} with n_trailers = {trained_n}, not "
            f"{env_id} with n_trailers = {wanted_n}; pass --force to evaluate it anyway"
        )


def load_policy(
    spec: str,
    env_id: str,
    env_kwargs: dict[str, Any] | None = None,
    seed: int | None = 0,
    *,
    trust_pickle: bool = False,
    force: bool = False,
) -> Policy:
    """A batched policy from a baseline name, a model path, a shipped model's stem or an
    RLlib checkpoint folder.

    Args:
        spec: A baseline name (:data:`agents.baselines.BASELINES`), a ``.zip`` model
            path, the stem of a shipped model (:func:`resolve_model`), or an RLlib
            checkpoint folder (:mod:`agents.rllib_backend`).
        env_id: The environment it will act in.
        env_kwargs: The environment's keyword arguments (``n_trailers`` ...).
        seed: Seed of the random baseline.
        trust_pickle: Allow unpickling the file's pickled parts (see :mod:`agents.model_files`).
        force: Evaluate a model whose card names another env id or n.

    Raises:
        ValueError: Unknown name, unknown environment, a model whose card or
            observation space does not fit the environment, a damaged file, or one
            that needs unpickling without ``trust_pickle``.
        FileNotFoundError: A model path that does not exist.
    """
    check_env_id(env_id)
    kwargs = env_kwargs or {}
    spec = resolve_model(spec)
    if not is_model_spec(spec):
        if spec not in BASELINES:
            raise ValueError(
                f"unknown policy {spec!r}: give a baseline ({', '.join(BASELINES)}), "
                f"a shipped model ({', '.join(shipped_models())}) "
                "or the path of a saved model (.zip) or RLlib checkpoint"
            )
        return make_baseline(spec, env_settings(kwargs), env_id, seed)
    path = Path(spec)
    probe = make_vector_env(env_id, 1, kwargs)
    if path.is_dir():
        from agents.rllib_backend import is_rllib_checkpoint, load_rllib_policy, read_rllib_card

        if not is_rllib_checkpoint(path):
            raise ValueError(f"{path} is a folder but not an RLlib checkpoint")
        if not force:
            check_card(read_rllib_card(path), spec, env_id, kwargs)
        return load_rllib_policy(
            path, probe.single_observation_space, probe.single_action_space, trust_pickle
        )
    if not force:
        check_card(read_card(path), spec, env_id, kwargs)
    model = load_model(path, env_id=env_id, env_kwargs=kwargs, trust_pickle=trust_pickle)
    return ModelPolicy(model, load_stats(path, model.observation_space, trust_pickle))
