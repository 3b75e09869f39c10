"""stable-baselines3 models as batched policies: loading (no pickles unless trusted) and acting."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.artifacts.cards import read_model_card
from agents.artifacts.paths import pickled_stats_path, stats_path
from agents.artifacts.sb3_zip import ALGOS, UnsafeFileError, read_sb3_data
from agents.artifacts.stats import frozen_normalizer, load_pickled_stats, read_stats
from agents.envs import make_vector_env
from agents.policies.extractors import feature_extractors
from trailer_env.observation import trailers_observation

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.vec_env import VecNormalize


def limit_torch_threads(threads: int = 1) -> None:
    """Use ``threads`` torch threads: small policies on a shared 2-core machine run 10-30x
    faster on one thread than on several competing with the simulation and other jobs."""
    import torch

    torch.set_num_threads(threads)


def load_stats(
    model_path: Path, observation_space: object = None, trust_pickle: bool = False
) -> VecNormalize | None:
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

            shape = read_stats(path).observation_shape
            observation_space = gym.spaces.Box(-np.inf, np.inf, shape, np.float32)
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
        ValueError: If the file is not a stable-baselines3 zip of an algorithm of
            :data:`agents.algorithms.ALGOS`.
    """
    algo = read_model_card(model_path).algo
    if algo in ALGOS:
        return str(algo)
    data = read_sb3_data(model_path)
    policy_class = data.get("policy_class", {})
    if not isinstance(policy_class, dict):
        raise ValueError(f"{model_path} is not a stable-baselines3 model: unexpected data")
    module = str(policy_class.get("__module__", ""))
    candidates = [record for record in ALGOS.values() if record.policy_module == module]
    for record in candidates:
        if record.marker is not None and record.marker in data:
            return record.name
    for record in candidates:
        if record.marker is None:
            return record.name  # PPO for actor-critic policies (A2C's predict the same way)
    raise ValueError(f"{model_path}: cannot tell the algorithm from policy module {module!r}")


class ModelPolicy:
    """A model's deterministic action, batched.

    Args:
        model: A stable-baselines3 algorithm.
        stats: The ``VecNormalize`` whose observation statistics the model was trained
            with (None: raw observations). Used read-only.
    """

    def __init__(self, model: BaseAlgorithm, stats: VecNormalize | None = None) -> None:
        self.model = model
        self.stats = stats

    def __call__(self, obs: np.ndarray | dict[str, np.ndarray]) -> np.ndarray:
        # A Dict observation (observation="trailers") is a dict of batched arrays.
        batch = obs if isinstance(obs, dict) else np.atleast_2d(obs)
        if self.stats is not None:
            batch = self.stats.normalize_obs(batch)
        actions, _ = self.model.predict(batch, deterministic=True)
        return np.asarray(actions, dtype=np.float32)


class SampledPolicy:
    """A model's action *sampled* from its distribution, batched and reproducible.

    Each call draws ``model.predict(obs, deterministic=False)`` under a private torch
    generator state started from ``seed`` (the global torch generator is left as it was),
    so the same seed on the same batch draws the same actions. A gSDE policy's noise
    matrices are drawn afresh for the whole batch every ``sde_sample_freq`` calls (once,
    at the first call, when it is not positive), as in its training rollouts; other
    policies sample their Gaussian (or squashed Gaussian) every call.

    Args:
        policy: The deterministic :class:`ModelPolicy` whose model is sampled.
        seed: Seed of the draws.
    """

    def __init__(self, policy: ModelPolicy, seed: int) -> None:
        import torch

        self.model = policy.model
        self.stats = policy.stats
        self.calls = 0
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self._rng_state = torch.get_rng_state()

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        import torch

        batch = np.atleast_2d(obs)
        if self.stats is not None:
            batch = np.asarray(self.stats.normalize_obs(batch))
        period = int(getattr(self.model, "sde_sample_freq", -1))
        with torch.random.fork_rng(devices=[]):
            torch.set_rng_state(self._rng_state)
            if getattr(self.model, "use_sde", False) and (
                self.calls == 0 or (period > 0 and self.calls % period == 0)
            ):
                self.model.policy.reset_noise(len(batch))  # type: ignore[operator]
            actions, _ = self.model.predict(batch, deterministic=False)
            self._rng_state = torch.get_rng_state()
        self.calls += 1
        return np.asarray(actions, dtype=np.float32)


class TrailersPolicy:
    """A policy of ``observation="trailers"`` acting on flat observations: each batch is
    rearranged by :func:`trailer_env.observation.trailers_observation` first.

    Args:
        policy: A policy that takes the dict of ``observation="trailers"``.
        n: Trailers of the flat layout (``high`` of a padded one).
        max_trailers: The policy's trailer slots (>= n).
        padded: Whether the flat observations are the padded layout of a range.
    """

    def __init__(
        self,
        policy: Callable[[dict[str, np.ndarray]], np.ndarray],
        n: int,
        max_trailers: int,
        padded: bool,
    ) -> None:
        self.policy = policy
        self.n = n
        self.max_trailers = max_trailers
        self.padded = padded

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = trailers_observation(
            np.atleast_2d(obs), self.n, self.max_trailers, padded=self.padded
        )
        return np.asarray(self.policy(batch), dtype=np.float32)


def load_model(
    model_path: Path | str,
    algo: str | None = None,
    *,
    env_id: str | None = None,
    env_kwargs: dict[str, object] | None = None,
    trust_pickle: bool = False,
) -> Any:
    """Load a saved model on the CPU (the algorithm detected unless given) without pickles.

    The spaces that replace the file's pickled ones are those of ``env_id`` with
    ``env_kwargs``; by default the model card's environment (see
    :mod:`agents.artifacts` for what is and is not unpickled).

    Raises:
        FileNotFoundError: If the file does not exist.
        ValueError: If it is not a loadable model of a known algorithm, or it needs
            unpickling and ``trust_pickle`` is false.
    """
    from agents.artifacts.sb3_zip import load_sb3

    path = Path(model_path)
    if not path.is_file():
        raise FileNotFoundError(f"no model file {path}")
    algo = algo or detect_algo(path)
    card = read_model_card(path)
    env_id = env_id or card.env_id
    if env_id is None and not trust_pickle:
        raise ValueError(
            f"{path} has no model card naming its environment: give the environment, "
            "or pass --trust-pickle to read the spaces from the file's pickles"
        )
    if env_id is None:
        return load_sb3(path, algo, None, None, trust_pickle=True)
    kwargs = env_kwargs if env_kwargs is not None else card.env_kwargs.as_kwargs()
    probe = make_vector_env(env_id, 1, kwargs)
    return load_sb3(
        path,
        algo,
        probe.single_observation_space,
        probe.single_action_space,
        trust_pickle=trust_pickle,
        extractors=feature_extractors(),
    )
