"""Imitate the planner (DAgger) into a stable-baselines3 PPO policy.

Usage::

    python -m agents.imitate --env trailer_env/Reverse-v1 --n-trailers 2 --seed 0 \
        [--expert {mpc,ilqr,specialists}] [--iterations 6] [--episodes 256] [--run-dir DIR] \
        [--export PATH] [--overwrite]

The expert is a record of :data:`agents.policies.teachers.DAGGER_EXPERTS`: ``mpc``, the
sampling planner (the Reverse scenes' default), ``ilqr``, the deterministic iLQR planner
(Reverse, and the default on Dock and Coast; one n, nominal physics), which labels a
state with the same action whatever was labelled before, or ``specialists``, trained
policies, one per n, each labelling the rows of its own count (policy distillation).

A generalist: ``--n-trailers 1-3 --randomize mismatch20`` (the env draws each
episode's n and physics; the expert, :class:`agents.oracles.experts.PrivilegedExpert`,
plans each row with its true parameters; the student sees the padded observation and
the trailer mask, no parameters).

Why: PPO from the scene's reward needs millions of steps before the states that matter
(near the edge of the recoverable set, where the rail saturates) enter its data, and
with three trailers it may never find them (docs, Agents: what limits performance). The ``mpc``
planner (:mod:`agents.oracles.planner`) knows how to steer there but simulates
thousands of steps per decision. DAgger (Ross, Gordon and Bagnell, 2011) trains a cheap
policy on the planner's decisions at the states the *policy itself* visits, so that its own
mistakes are in its training data:

1. iteration 0: the planner drives ``episodes`` convoys for one episode length, and
   labels every step with its action (the expert's own distribution);
2. iteration k >= 1: the current policy drives fresh convoys, the planner labels every
   state they visit (from the exact state: it is an oracle) and the labels join the
   data set;
3. after each iteration the policy's mean action is fitted to all labels so far (mean
   squared error, Adam) and evaluated on the validation seeds
   (:data:`agents.seeds.VALIDATION_SEED`); the best iteration is the best model.

Training episodes are seeded from :data:`TRAINING_SEED` on (disjoint from the test
seeds 1000-1099, the tuning seeds 2000-2199 and the validation seeds). The policy is
SB3's PPO ``MlpPolicy`` with the hyperparameter file's architecture; observations are
normalised with statistics frozen from iteration 0's data (variances floored at
:data:`OBS_VAR_FLOOR`) and saved as JSON, so the
model loads, evaluates and fine-tunes (``agents.train --resume``) like any PPO model.
The run folder gets ``config.json``, ``evaluations.csv`` (one row per iteration;
``timesteps`` counts labelled steps), ``best_model.zip`` and ``final_model.zip`` with
their cards and statistics. After every iteration it also gets a checkpoint
(``checkpoint.json``, the aggregated ``dataset.npz`` and the final model so far):
``--resume`` continues a run cut short, or one asked for more ``--iterations``, with the
same data, weights and random streams, so that it ends as an uninterrupted run would.
A resume first reads back and checks every file it needs (:func:`read_saved_run`): a
damaged one, or a run configured otherwise, is refused (:class:`CheckpointError`, naming
the file or the settings with their old and new values) before anything is written; the
run's record is rewritten with its first new iteration, and the curve's earlier rows stay
as they were written.

With ``observation="trailers"`` (``--observation trailers``) the student is PPO's
``MultiInputPolicy`` with :class:`~agents.policies.convoy_encoder.ConvoyEncoder` (a GRU
along the convoy) reading the Dict of :mod:`trailer_env.observation`, rearranged from the
flat observations the labelling collects (:func:`trailer_env.observation.trailers_observation`):
no statistics (the encoder scales its inputs itself), and its card's ``env_kwargs`` record
the observation, so :func:`agents.policies.registry.load_policy` evaluates it on the flat
envs of any n up to ``max_trailers``.
"""

from __future__ import annotations

import io
import json
import pickle
import sys
import time
import zipfile
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.artifacts import files, limits
from agents.artifacts.cards import read_card, write_card
from agents.artifacts.curves import CURVE_COLUMNS, append_rows, read_curve, write_curve
from agents.artifacts.files import atomic_write_bytes
from agents.artifacts.paths import card_path, stats_path
from agents.artifacts.run_folder import (
    BEST_MODEL,
    CONFIG_FILE,
    CURVE_FILE,
    FINAL_MODEL,
    IMITATION_CHECKPOINT,
    IMITATION_DATASET,
    read_record,
    record_differences,
    write_config,
)
from agents.artifacts.sb3_zip import check_zip, save_model
from agents.artifacts.stats import read_stats, restore_stats, save_stats
from agents.envs import check_env_id, make_sb3_env, settings_by_count
from agents.evaluation.metrics import rollout, summarize
from agents.oracles.experts import ExpertConfig, Labeller, default_expert
from agents.oracles.planner import SamplingPlanner
from agents.policies.convoy_order import CONVOY_DIRECTIONS, check_direction
from agents.policies.extractors import feature_extractor
from agents.policies.mirror import MirroredPolicy
from agents.policies.sb3 import ModelPolicy, TrailersPolicy
from agents.policies.teachers import DAGGER_EXPERTS, TeacherConfig
from agents.progress import Progress
from agents.seeds import TRAINING_SEED, VALIDATION_SEED
from agents.training.callbacks import score
from agents.training.config import load_hyperparams, parse_policy_kwargs
from trailer_env.json_types import JSONObject
from trailer_env.mixed import is_trailer_range, trailer_range
from trailer_env.observation import checked_observation, flat_observation, trailers_observation
from trailer_env.randomize import PRESETS, Randomization
from trailer_env.registry import core_class_of
from trailer_env.vector import ConvoyVectorEnv

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.vec_env import VecNormalize

#: Keys of the run's record that the best model's card takes at the end of the run.
RUN_TOTALS = ("timesteps", "wall_time_s", "simulated_steps")


#: The aggregated data set (observations: normalised, or raw with "trailers"; labels) in the
#: run folder.
DATASET_FILE = IMITATION_DATASET

#: The run's checkpoint, rewritten after every iteration (with the data set and the final
#: model): what ``--resume`` continues from.
CHECKPOINT_FILE = IMITATION_CHECKPOINT

#: Columns of the run's evaluations.csv: one row per iteration.
CURVE_FIELDS = (*CURVE_COLUMNS, "iteration", "loss")

#: Keys of the run's record that may differ when a run is resumed (the rest must match):
#: the command, the budget and the iterations asked for, and the totals of the run so far.
RESUMABLE_KEYS = (
    "command",
    "budget",
    "imitation.iterations",
    "resumed_at",
    *RUN_TOTALS,
)


#: Floor of the observations' variance in the frozen statistics. The cosines of nearly
#: straight hitch angles vary by about 1e-5 over the expert's data: unfloored, the policy
#: would read them amplified 300-fold and see inputs far outside its data as soon as an
#: angle grows (the edge of the basin, where the actions matter most).
OBS_VAR_FLOOR = 1e-3


#: Log standard deviation the saved policy explores with when fine-tuned by PPO
#: (the imitation fits the mean only).
FINE_TUNE_LOG_STD = -2.5


@dataclass(frozen=True)
class ImitationConfig:
    """What :func:`imitate` trains.

    Attributes:
        env_id: The scene (one that an expert of
            :data:`agents.policies.teachers.DAGGER_EXPERTS` fits).
        n_trailers: Trailers: one count, or a range ``(low, high)`` (a generalist: the
            env draws each episode's n, the student sees the padded observation and
            its mask, :mod:`trailer_env.mixed`).
        seed: Seed of the network's initialisation, the training episodes' offset and
            the planner's sampling.
        iterations: DAgger iterations (iteration 0 is the planner driving).
        episodes: Convoys driven per iteration (one batch; each runs one episode length
            and, when it ends early, starts again).
        epochs: Passes over the aggregated data after each iteration.
        batch_size: Minibatch of the regression.
        learning_rate: Adam's step size.
        net_arch: Hidden layers of the policy (None: the hyperparameter file's).
        validation_episodes: Episodes of each validation.
        expert: The expert's name in :data:`agents.policies.teachers.DAGGER_EXPERTS`; None: the
            scene's default (:func:`agents.oracles.experts.default_expert`: ``mpc`` on
            Reverse, ``ilqr`` on Dock and Coast).
        planner: The expert's settings, of its ``config_class`` (``PlannerConfig`` for
            ``mpc``, whose seed is replaced by ``seed``; ``ILQRConfig`` for ``ilqr``;
            :class:`~agents.policies.teachers.TeacherConfig` for ``specialists``);
            None: its default. More samples make ``mpc``'s labels less noisy: two
            default planners label the same states with a mean squared difference of
            about 0.02; ``ilqr``'s default (``reuse=False``) labels a state the same.
        randomize: The env's ``randomize=`` (a preset name of
            :data:`trailer_env.randomize.PRESETS` or a dict of factor ranges; None: the
            nominal physics). The expert (``mpc``; ``ilqr`` refuses randomised
            parameters) plans with each episode's true parameters; the student does not
            observe them.
        observation: What the student reads: "flat" (default, normalised) or "trailers"
            (the Dict, through :class:`~agents.policies.convoy_encoder.ConvoyEncoder`).
        max_trailers: Trailer slots of "trailers" (default 8; at least the largest n).
        mirror: Train with the convoy's mirror image: every labelled state is
            also added mirrored with its mirrored label, and the student drives and is
            validated made odd under it (:class:`agents.policies.mirror.MirroredPolicy`);
            its card says so, and :func:`agents.policies.registry.load_policy` wraps it
            the same way.
        convoy_direction: The order in which the "trailers" student's encoder reads the
            convoy, one of :data:`agents.policies.convoy_order.CONVOY_DIRECTIONS` (default
            ``"cart_first"``; another needs ``observation="trailers"``).
    """

    env_id: str
    n_trailers: int | tuple[int, int]
    seed: int = 0
    iterations: int = 6
    episodes: int = 256
    epochs: int = 10
    batch_size: int = 1024
    learning_rate: float = 1e-3
    net_arch: tuple[int, ...] | None = None
    validation_episodes: int = 100
    planner: ExpertConfig | TeacherConfig | None = None
    randomize: str | JSONObject | None = None
    expert: str | None = None
    observation: str = "flat"
    max_trailers: int | None = None
    mirror: bool = False
    convoy_direction: str = "cart_first"

    def __post_init__(self) -> None:
        check_env_id(self.env_id)
        if is_trailer_range(self.n_trailers):
            object.__setattr__(self, "n_trailers", trailer_range(self.n_trailers))
        if self.randomize is not None:
            if isinstance(self.randomize, str) and self.randomize not in PRESETS:
                raise ValueError(
                    f"randomize: unknown preset {self.randomize!r}; presets: {sorted(PRESETS)}"
                )
            Randomization.coerce(self.randomize)  # TypeError/ValueError naming the problem
        for name in ("iterations", "episodes", "epochs", "batch_size", "validation_episodes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
            if value < 1:
                raise ValueError(f"{name} must be >= 1, got {value}")
        if self.episodes > limits.MAX_IMITATION_EPISODES:
            raise ValueError(
                f"episodes must be <= {limits.MAX_IMITATION_EPISODES} (one batch), "
                f"got {self.episodes}"
            )
        last = TRAINING_SEED + self.seed * 10_000 + self.iterations * self.episodes
        if limits.seed_problem(last) is not None:
            raise ValueError(
                f"seed {self.seed}: its training episodes would need seeds up to {last}, "
                f"past {limits.MAX_SEED} (2**32 - 1)"
            )
        if self.net_arch is not None:
            problem = limits.network_problem(list(self.net_arch))
            if problem is not None:
                raise ValueError(problem)
        if not (np.isfinite(self.learning_rate) and self.learning_rate > 0.0):
            raise ValueError(f"learning_rate must be finite and > 0, got {self.learning_rate}")
        if not isinstance(self.mirror, bool):
            raise TypeError(f"mirror must be a bool, got {type(self.mirror).__name__}")
        check_direction("convoy_direction", self.convoy_direction)
        if self.convoy_direction != CONVOY_DIRECTIONS[0] and self.observation != "trailers":
            raise ValueError(
                f"convoy_direction={self.convoy_direction!r} needs observation='trailers' "
                "(the flat student has no convoy encoder)"
            )
        self.settings_by_count()  # a bad number of trailers fails here, named
        slots = checked_observation(self.observation, self.max_trailers, self.top_trailers)
        object.__setattr__(self, "max_trailers", slots)
        if self.expert is None:
            object.__setattr__(self, "expert", default_expert(self.env_id))
        elif not isinstance(self.expert, str):
            raise TypeError(f"expert must be a str, got {type(self.expert).__name__}")
        elif self.expert not in DAGGER_EXPERTS:
            raise ValueError(f"expert: unknown {self.expert!r}; experts: {sorted(DAGGER_EXPERTS)}")
        expert = DAGGER_EXPERTS[str(self.expert)]
        problem = expert.problem(self.env_id, self.n_trailers, self.randomize)
        if problem is not None:
            raise ValueError(problem)
        if self.planner is None:
            object.__setattr__(self, "planner", expert.default_config())
        elif not isinstance(self.planner, expert.config_class):
            raise TypeError(
                f"planner: the {expert.name} expert takes {expert.config_class.__name__}, "
                f"got {type(self.planner).__name__}"
            )
        if isinstance(self.planner, TeacherConfig):  # the specialists load, before a run
            problem = self.planner.problem(self.env_id, sorted(self.settings_by_count()))
            if problem is not None:
                raise ValueError(problem)

    @property
    def expert_config(self) -> ExpertConfig | TeacherConfig:
        """The expert's settings (resolved: never None after construction)."""
        if self.planner is None:  # pragma: no cover - __post_init__ sets it
            raise RuntimeError("ImitationConfig was not validated")
        return self.planner

    @property
    def env_kwargs(self) -> JSONObject:
        kwargs: JSONObject = {"n_trailers": self.n_trailers}
        if self.randomize is not None:
            kwargs["randomize"] = self.randomize
        return kwargs

    @property
    def top_trailers(self) -> int:
        """The largest n of the episodes (the padded layout's with a range)."""
        return self.n_trailers[1] if isinstance(self.n_trailers, tuple) else self.n_trailers

    @property
    def student_kwargs(self) -> JSONObject:
        """The environment the student's spaces come from (and its card records): the
        labelling env's keywords with the observation."""
        if self.observation == "flat":
            return self.env_kwargs
        return {
            **self.env_kwargs,
            "observation": self.observation,
            "max_trailers": self.max_trailers,
        }

    def student(
        self, model: BaseAlgorithm, stats: VecNormalize | None
    ) -> ModelPolicy | TrailersPolicy:
        """The student as a policy of the (flat) labelling and validation envs."""
        if self.max_trailers is None:
            return ModelPolicy(model, stats)
        padded = isinstance(self.n_trailers, tuple)
        return TrailersPolicy(ModelPolicy(model), self.top_trailers, self.max_trailers, padded)

    def inputs(self, obs: np.ndarray) -> np.ndarray | dict[str, np.ndarray]:
        """What the student's network reads for the flat observations ``obs``."""
        if self.max_trailers is None:
            return obs
        padded = isinstance(self.n_trailers, tuple)
        return trailers_observation(obs, self.top_trailers, self.max_trailers, padded=padded)

    @property
    def run_label(self) -> str:
        """The trailer part of the default run folder's name: ``2`` or ``1-3``."""
        if isinstance(self.n_trailers, tuple):
            return f"{self.n_trailers[0]}-{self.n_trailers[1]}"
        return str(self.n_trailers)

    def settings_by_count(self) -> dict[int, Any]:
        """The env settings of each count (one entry for one n)."""
        return settings_by_count(self.env_kwargs)


def collect(
    envs: ConvoyVectorEnv,
    planner: Labeller | SamplingPlanner,
    policy: Any,
    seed: int,
    progress: Progress | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One iteration's data: observations and the planner's actions at every visited state.

    ``progress`` (counting labelled steps) advances once per step.

    ``policy`` None lets the planner drive. ``envs`` must reset in the same step
    (``autoreset_mode="same_step"``) so that each observation is the core's state.
    """
    reset_obs, _ = envs.reset(seed=seed)
    obs = flat_observation(reset_obs, "DAgger's labelling")
    planner.reset()
    core = envs.core
    steps = envs.max_episode_steps
    observations = np.empty((steps, *obs.shape), dtype=np.float32)
    labels = np.empty((steps, envs.num_envs), dtype=np.float64)
    for t in range(steps):
        label = planner.label(core)
        observations[t] = obs
        labels[t] = label[:, 0]
        action = label if policy is None else policy(obs)
        stepped, _, terminated, truncated, _ = envs.step(np.asarray(action, dtype=np.float32))
        obs = flat_observation(stepped, "DAgger's labelling")
        ended = np.flatnonzero(terminated | truncated)
        if ended.size:
            planner.reset(ended)
        if progress is not None:
            progress.advance(f"labelling step {t + 1}")
    return observations.reshape(-1, obs.shape[1]), labels.reshape(-1, 1)


def fit(
    model: Any,
    obs: np.ndarray | dict[str, np.ndarray],
    labels: np.ndarray,
    config: ImitationConfig,
    rng: Any,
) -> float:
    """Fit the policy's mean action to ``labels`` (``obs``: normalised flat observations,
    or the dict of ``observation="trailers"``); the last epoch's loss."""
    import torch

    policy = model.policy
    policy.set_training_mode(True)
    optimizer = torch.optim.Adam(policy.parameters(), lr=config.learning_rate)
    if isinstance(obs, dict):
        inputs: Any = {
            key: torch.as_tensor(value, dtype=torch.float32) for key, value in obs.items()
        }
    else:
        inputs = torch.as_tensor(obs, dtype=torch.float32)
    targets = torch.as_tensor(labels, dtype=torch.float32)
    loss_sum = 0.0
    for _ in range(config.epochs):
        order = torch.as_tensor(rng.permutation(len(targets)))
        loss_sum, batches = 0.0, 0
        for start in range(0, len(order), config.batch_size):
            rows = order[start : start + config.batch_size]
            batch = (
                {key: value[rows] for key, value in inputs.items()}
                if isinstance(inputs, dict)
                else inputs[rows]
            )
            mean = policy.get_distribution(batch).distribution.mean
            loss = torch.mean((mean - targets[rows]) ** 2)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            loss_sum += loss.item()
            batches += 1
        loss_sum /= max(batches, 1)
    policy.set_training_mode(False)
    return loss_sum


def _build_model(config: ImitationConfig) -> tuple[Any, Any, JSONObject]:
    """The PPO model (untrained), its frozen VecNormalize (None with "trailers") and the
    hyperparameters used."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    hp = load_hyperparams("ppo", config.env_id)
    policy_kwargs = dict(parse_policy_kwargs(hp.algo_kwargs.get("policy_kwargs", {})))
    if config.net_arch is not None:
        policy_kwargs["net_arch"] = list(config.net_arch)
    policy_kwargs["log_std_init"] = FINE_TUNE_LOG_STD
    algo_kwargs = {**hp.algo_kwargs, "policy_kwargs": policy_kwargs}
    if config.observation == "trailers":
        policy_kwargs["features_extractor_class"] = feature_extractor("ConvoyEncoder")
        if config.convoy_direction != CONVOY_DIRECTIONS[0]:  # default runs keep their saved kwargs
            policy_kwargs["features_extractor_kwargs"] = {
                **policy_kwargs.get("features_extractor_kwargs", {}),
                "direction": config.convoy_direction,
            }
        venv = make_sb3_env(config.env_id, hp.n_envs, config.student_kwargs, seed=config.seed)
        model = PPO(
            "MultiInputPolicy", venv, seed=config.seed, device="cpu", verbose=0, **algo_kwargs
        )
        return model, None, {"n_envs": hp.n_envs, **algo_kwargs}
    venv = make_sb3_env(config.env_id, hp.n_envs, config.env_kwargs, seed=config.seed)
    gamma = algo_kwargs.get("gamma", 0.99)
    stats = VecNormalize(venv, norm_obs=True, norm_reward=False, gamma=gamma, training=False)
    model = PPO(hp.policy, stats, seed=config.seed, device="cpu", verbose=0, **algo_kwargs)
    return model, stats, {"n_envs": hp.n_envs, **algo_kwargs}


class CheckpointError(ValueError):
    """A run cannot be resumed: no checkpoint, a damaged one, or another configuration."""


@dataclass
class _RunState:
    """What a DAgger run has done so far (restored from its checkpoint on resume)."""

    iterations: int = 0
    data_obs: list[np.ndarray] | None = None
    data_labels: list[np.ndarray] | None = None
    curve: list[dict[str, float]] | None = None
    best: tuple[float, ...] | None = None
    wall_s: float = 0.0
    simulated_steps: int = 0


@dataclass(frozen=True)
class SavedRun:
    """The files of an imitation run that its resume reads back, read and checked
    (:func:`read_saved_run`)."""

    checkpoint: JSONObject
    record: JSONObject
    observations: np.ndarray
    labels: np.ndarray
    curve: list[dict[str, float]]


def _refused(run_dir: Path, name: str, problem: str) -> CheckpointError:
    return CheckpointError(f"cannot resume {run_dir}: {name}: {problem}")


def _rng_problem(state: object) -> str | None:
    """Why ``state`` is not the state of a generator of the run (None: it is one)."""
    try:
        np.random.default_rng().bit_generator.state = state  # type: ignore[assignment]
    except (TypeError, ValueError, KeyError, OverflowError) as error:
        return f"{type(error).__name__}: {error}"
    return None


def _checkpoint_problem(checkpoint: object) -> str | None:
    """Why ``checkpoint`` (checkpoint.json's document) is not one :func:`_write_checkpoint`
    writes (None: it is)."""
    if not isinstance(checkpoint, dict):
        return "not a JSON object"
    counts = {"iterations": 1, "rows": 1, "simulated_steps": 0}
    for key, least in counts.items():
        if not files.is_integer(checkpoint.get(key), least):
            return f"{key!r} must be an integer >= {least}, got {checkpoint.get(key)!r:.60}"
    best = checkpoint.get("best")
    if not (isinstance(best, list) and len(best) == 3 and all(map(files.is_number, best))):
        return f"'best' must be a list of 3 finite numbers (a score), got {best!r:.60}"
    wall = checkpoint.get("wall_s")
    if not (files.is_number(wall) and isinstance(wall, (int, float)) and wall >= 0):
        return f"'wall_s' must be a finite number >= 0, got {wall!r:.60}"
    problem = _rng_problem(checkpoint.get("fit_rng"))
    if problem is not None:
        return f"'fit_rng' is not a generator's state ({problem:.80})"
    streams = checkpoint.get("expert_rngs")
    if not isinstance(streams, list):
        return f"'expert_rngs' must be a list of generator states, got {streams!r:.60}"
    for index, state in enumerate(streams):
        problem = _rng_problem(state)
        if problem is not None:
            return f"'expert_rngs'[{index}] is not a generator's state ({problem:.80})"
    return None


def _read_dataset(run_dir: Path, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The data set's observations and labels, checked against the checkpoint's ``rows``.

    Raises:
        CheckpointError: Naming the file and what is wrong.
    """
    path = run_dir / DATASET_FILE
    members = {"observations.npy", "labels.npy"}
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
        if {info.filename for info in infos} != members:
            raise ValueError(f"its members are not {sorted(members)}")
        size = sum(info.file_size for info in infos)
        if size > limits.MAX_ZIP_TOTAL_BYTES:
            raise ValueError(f"it inflates to {size} bytes, over {limits.MAX_ZIP_TOTAL_BYTES}")
        with np.load(path, allow_pickle=False) as dataset:
            observations, labels = dataset["observations"], dataset["labels"]
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as error:
        raise _refused(run_dir, path.name, f"unreadable ({error})") from None
    if observations.dtype != np.float32 or observations.ndim != 2:
        shown = f"{observations.dtype} {observations.shape}"
        raise _refused(run_dir, path.name, f"observations are {shown}, not 2-D float32")
    if labels.dtype != np.float64 or labels.shape != (len(labels), 1):
        shown = f"{labels.dtype} {labels.shape}"
        raise _refused(run_dir, path.name, f"labels are {shown}, not float64 (rows, 1)")
    if len(observations) != len(labels) or len(labels) != rows:
        raise _refused(
            run_dir,
            path.name,
            f"holds {len(observations)} observations and {len(labels)} labels, the "
            f"checkpoint {rows}; a run was cut while writing it",
        )
    if not (np.all(np.isfinite(observations)) and np.all(np.isfinite(labels))):
        raise _refused(run_dir, path.name, "holds values that are not finite")
    return observations, labels


def read_saved_run(run_dir: Path) -> SavedRun:
    """Every file a resume of the imitation run in ``run_dir`` reads back, read and
    checked, before anything is written: :data:`CHECKPOINT_FILE` (its counts, best score,
    times and random streams), the record (``config.json``), the data set (its arrays,
    as many rows as the checkpoint says), the learning curve (one row per iteration done,
    under the run's header), the final model (a bounded zip) and its statistics (a
    normalising student), and the best model's card (and that model).

    Raises:
        CheckpointError: Naming the file and what is wrong with it.
    """
    path = run_dir / CHECKPOINT_FILE
    if not path.is_file():
        raise _refused(run_dir, path.name, "missing")
    try:
        checkpoint = files.read_json(path, "checkpoint")
    except ValueError as error:
        raise _refused(run_dir, path.name, str(error)) from None
    problem = _checkpoint_problem(checkpoint)
    if problem is not None:
        raise _refused(run_dir, path.name, problem)
    try:
        record = read_record(run_dir)
    except ValueError as error:
        raise _refused(run_dir, CONFIG_FILE, str(error)) from None
    done = int(checkpoint["iterations"])
    observations, labels = _read_dataset(run_dir, int(checkpoint["rows"]))
    try:
        curve = read_curve(run_dir / CURVE_FILE, CURVE_FIELDS, header=CURVE_FIELDS)
    except ValueError as error:
        raise _refused(run_dir, CURVE_FILE, str(error)) from None
    if [int(row["iteration"]) for row in curve] != list(range(done)):
        raise _refused(
            run_dir,
            CURVE_FILE,
            f"holds {len(curve)} iterations, the checkpoint {done}; a run was cut while writing it",
        )
    for model in (run_dir / FINAL_MODEL, run_dir / BEST_MODEL):
        if not model.is_file():  # the best: the checkpoint has a best score
            raise _refused(run_dir, model.name, "missing")
        try:
            check_zip(model)
        except ValueError as error:
            raise _refused(run_dir, model.name, str(error)) from None
    try:
        read_card(run_dir / BEST_MODEL)  # the card the run's end completes
    except ValueError as error:
        raise _refused(run_dir, card_path(run_dir / BEST_MODEL).name, str(error)) from None
    final_stats = stats_path(run_dir / FINAL_MODEL)
    if record.get("normalize") is not None:
        if not final_stats.is_file():
            raise _refused(run_dir, final_stats.name, "missing")
        try:
            read_stats(final_stats)
        except ValueError as error:
            raise _refused(run_dir, final_stats.name, str(error)) from None
    return SavedRun(checkpoint, record, observations, labels, curve)


def _restore(
    run_dir: Path,
    config: ImitationConfig,
    record: JSONObject,
    model: Any,
    stats: Any,
    planner: Labeller,
    rng: np.random.Generator,
    width: int,
) -> tuple[_RunState, JSONObject]:
    """Load the run's checkpoint into the model, statistics and random streams; returns
    what the run has done and its saved record. ``width``: the numbers of the labelling
    env's observation (what the data set holds). Nothing is written.

    Raises:
        CheckpointError: If a file of the run is missing or damaged
            (:func:`read_saved_run`), the run was configured differently from ``record``
            (other than :data:`RESUMABLE_KEYS`; the message gives each setting's old and
            new value), it has already done ``config.iterations``, or its model,
            statistics or random streams do not fit the run's.
    """
    saved = read_saved_run(run_dir)
    differing = record_differences(saved.record, record, RESUMABLE_KEYS)
    if differing:
        shown = ", ".join(f"{key} = {old!r:.40}, not {new!r:.40}" for key, old, new in differing)
        raise _refused(run_dir, CONFIG_FILE, f"its run was configured differently ({shown})")
    checkpoint = saved.checkpoint
    done = int(checkpoint["iterations"])
    if done >= config.iterations:
        raise CheckpointError(
            f"cannot resume {run_dir}: it has done {done} iterations; ask for more "
            f"(--iterations > {done})"
        )
    if saved.observations.shape[1] != width:
        raise _refused(
            run_dir,
            DATASET_FILE,
            f"observations of {saved.observations.shape[1]} numbers, the run's have {width}",
        )
    final = run_dir / FINAL_MODEL
    try:
        model.set_parameters(str(final), exact_match=True, device="cpu")
        if stats is not None:
            restore_stats(stats, read_stats(stats_path(final)))
    except (
        OSError,
        ValueError,
        KeyError,
        RuntimeError,
        EOFError,
        zipfile.BadZipFile,
        pickle.UnpicklingError,  # torch's weights-only loader refuses the entry
    ) as error:
        first = (str(error).splitlines() or [""])[0]
        problem = f"does not load into the run's student ({first:.200})"
        raise _refused(run_dir, final.name, problem) from None
    rng.bit_generator.state = checkpoint["fit_rng"]
    streams = planner.random_streams()
    if len(streams) != len(checkpoint["expert_rngs"]):
        raise _refused(run_dir, CHECKPOINT_FILE, "the expert's random streams differ")
    for stream, state in zip(streams, checkpoint["expert_rngs"], strict=True):
        stream.bit_generator.state = state
    state = _RunState(
        iterations=done,
        data_obs=[saved.observations],
        data_labels=[saved.labels],
        curve=saved.curve,
        best=tuple(checkpoint["best"]),
        wall_s=float(checkpoint["wall_s"]),
        simulated_steps=int(checkpoint["simulated_steps"]),
    )
    return state, saved.record


def _write_checkpoint(
    run_dir: Path,
    progress: _RunState,
    model: Any,
    stats: Any,
    planner: Labeller,
    rng: np.random.Generator,
) -> None:
    """The data set, the model and statistics as they are, then the checkpoint naming them
    (written last: a run cut while writing leaves a checkpoint that :func:`_restore` refuses)."""
    observations = np.concatenate(progress.data_obs or [])
    labels = np.concatenate(progress.data_labels or [])
    dataset = io.BytesIO()
    np.savez_compressed(dataset, observations=observations, labels=labels)
    atomic_write_bytes(run_dir / DATASET_FILE, dataset.getvalue())
    if stats is not None:
        save_stats(stats, stats_path(run_dir / FINAL_MODEL))
    save_model(model, run_dir / FINAL_MODEL)
    checkpoint = {
        "iterations": progress.iterations,
        "rows": len(labels),
        "best": list(progress.best or ()),
        "wall_s": progress.wall_s,
        "simulated_steps": progress.simulated_steps,
        "fit_rng": rng.bit_generator.state,
        "expert_rngs": [stream.bit_generator.state for stream in planner.random_streams()],
    }
    atomic_write_bytes(run_dir / CHECKPOINT_FILE, json.dumps(checkpoint, indent=1).encode())


def imitate(
    config: ImitationConfig,
    run_dir: Path,
    verbose: int = 1,
    resume: bool = False,
    command: Sequence[str] | None = None,
) -> JSONObject:
    """Run DAgger (see the module); returns the run's record (also its ``config.json``).

    ``command`` is what the record says started the run (default: this process's
    ``python -m agents.imitate`` arguments).

    After every iteration the run folder gets a checkpoint (:data:`CHECKPOINT_FILE`, the
    data set, the final model and its statistics). With ``resume`` the run in ``run_dir``
    goes on from its checkpoint to ``config.iterations``: the same data, weights and
    random streams (the planner's and the fit's), so the result is the one an
    uninterrupted run would give, bit for bit on one machine.

    Raises:
        CheckpointError: With ``resume``, before anything is written, if the run cannot be
            resumed (see :func:`_restore`).
    """
    started = time.perf_counter()
    settings = config.settings_by_count()
    core_class = core_class_of(config.env_id)
    run_dir.mkdir(parents=True, exist_ok=True)
    model, stats, hyperparams = _build_model(config)
    envs = ConvoyVectorEnv(
        core_class, config.episodes, autoreset_mode="same_step", **config.env_kwargs
    )
    signs = envs.core.mirror_signs() if config.mirror else None
    if config.mirror and signs is None:
        raise ValueError(f"mirror: {config.env_id} declares no mirror symmetry")

    def labelled_states(chunks: list[np.ndarray]) -> int:
        """Rows of the data set that the expert labelled (a mirrored copy is not one)."""
        return sum(len(chunk) for chunk in chunks) // (2 if config.mirror else 1)

    def student() -> Any:
        policy = config.student(model, stats)
        return policy if signs is None else MirroredPolicy(policy, *signs)

    expert = DAGGER_EXPERTS[str(config.expert)]
    planner = expert.build(core_class, settings, config.episodes, config.expert_config, config.seed)
    rng = np.random.default_rng(config.seed)
    record: JSONObject = {
        "algo": "ppo",
        "recipe": "dagger",
        "expert": expert.name,
        "command": list(command or ["python", "-m", "agents.imitate", *sys.argv[1:]]),
        "env_id": config.env_id,
        "env_kwargs": config.student_kwargs,
        "seed": config.seed,
        "imitation": {
            key: (list(value) if isinstance(value, tuple) else value)
            for key, value in asdict(config).items()
            if key
            not in (
                "env_id",
                "n_trailers",
                "seed",
                "planner",
                "randomize",
                "expert",
                "observation",
                "max_trailers",
            )
        },
        "planner": asdict(planner.config),
        "hyperparams": {key: value for key, value in hyperparams.items() if key != "policy_kwargs"}
        | {
            "policy_kwargs": {
                key: value
                for key, value in hyperparams["policy_kwargs"].items()
                if isinstance(value, (int, float, str, list, tuple))
            }
        },
        "normalize": None if stats is None else {"norm_obs": True, "norm_reward": False},
        "policy": "MlpPolicy" if stats is not None else "MultiInputPolicy",
        "training_seed": TRAINING_SEED,
        "budget": config.iterations * config.episodes * envs.max_episode_steps,
    }
    done = _RunState(data_obs=[], data_labels=[], curve=[])
    if resume:
        width = int((envs.single_observation_space.shape or (0,))[-1])
        done, saved = _restore(run_dir, config, record, model, stats, planner, rng, width)
        earlier = saved.get("resumed_at")
        record["resumed_at"] = [*(earlier if isinstance(earlier, list) else []), done.iterations]
        started -= done.wall_s
    first_iteration = done.iterations
    data_obs: list[np.ndarray] = done.data_obs or []
    data_labels: list[np.ndarray] = done.data_labels or []
    curve: list[dict[str, float]] = done.curve or []
    best = done.best
    previous_steps = done.simulated_steps
    summary: JSONObject = {}
    for iteration in range(done.iterations, config.iterations):
        seed = TRAINING_SEED + config.seed * 10_000 + iteration * config.episodes
        driver = None if iteration == 0 else student()
        cost = (
            f"{planner.steps_per_label:,} simulated steps each"
            if planner.steps_per_label
            else "a network call each"
        )
        label = (
            f"imitate: iteration {iteration + 1}/{config.iterations}, {config.episodes} convoys, "
            f"{expert.name} labels ({cost})"
        )
        with Progress(envs.max_episode_steps, label, quiet=not verbose) as bar:
            obs, labels = collect(envs, planner, driver, seed, bar)
        if signs is not None:  # each state also mirrored, with its mirrored label
            obs = np.concatenate([obs, obs * signs[0].astype(np.float32)])
            labels = np.concatenate([labels, labels * signs[1]])
        if iteration == 0 and stats is not None:
            stats.obs_rms.mean = obs.mean(axis=0).astype(np.float64)
            stats.obs_rms.var = np.maximum(obs.var(axis=0), OBS_VAR_FLOOR).astype(np.float64)
            stats.obs_rms.count = float(len(obs))
        data_obs.append((obs if stats is None else stats.normalize_obs(obs)).astype(np.float32))
        data_labels.append(labels)
        inputs = config.inputs(np.concatenate(data_obs))
        loss = fit(model, inputs, np.concatenate(data_labels), config, rng)
        results = rollout(
            student(),
            config.env_id,
            config.validation_episodes,
            VALIDATION_SEED,
            config.env_kwargs,
        )
        summary = summarize(results)
        samples = labelled_states(data_obs)
        row = {
            "timesteps": samples,
            "wall_s": round(time.perf_counter() - started, 1),
            "mean_return": summary["mean_return"],
            "jackknife_rate": summary["jackknife_rate"],
            "safe_rate": summary["safe_rate"],
            "band_time_fraction": summary["band_time_fraction"],
            "min_margin_mean": summary["min_margin_mean"],
            "success_rate": summary["success_rate"],
            "iteration": iteration,
            "loss": round(loss, 6),
        }
        curve.append(row)
        if iteration == first_iteration:
            # The record is written with the first new work: a run (or a resume) that
            # fails before leaves the folder as it was.
            write_config(run_dir, record)
        if iteration == 0:
            write_curve(run_dir / CURVE_FILE, [row], CURVE_FIELDS)
        else:  # the earlier rows stay as they were written
            append_rows(run_dir / CURVE_FILE, [row], CURVE_FIELDS)
        if verbose:
            print(
                f"iteration {iteration}: {samples} labels, loss {loss:.4f}, validation safe "
                f"{summary['safe_rate']:.2f}, folds {summary['jackknife_rate']:.2f} "
                f"({row['wall_s']:.0f} s)",
                flush=True,
            )
        card = {
            **record,
            "validation": summary,
            "selected_at_iteration": iteration,
            "selected_at_timesteps": samples,
            "timesteps": samples,
        }
        if best is None or score(summary) > best:
            best = score(summary)
            if stats is not None:
                save_stats(stats, stats_path(run_dir / BEST_MODEL))
            write_card(run_dir / BEST_MODEL, card)
            save_model(model, run_dir / BEST_MODEL)
        done.iterations = iteration + 1
        done.data_obs, done.data_labels, done.best = data_obs, data_labels, best
        done.wall_s = round(time.perf_counter() - started, 1)
        done.simulated_steps = previous_steps + planner.simulated_steps
        _write_checkpoint(run_dir, done, model, stats, planner, rng)
    record.update(
        {
            "timesteps": labelled_states(data_obs),
            "wall_time_s": round(time.perf_counter() - started, 1),
            "simulated_steps": previous_steps + planner.simulated_steps,
        }
    )
    write_card(run_dir / FINAL_MODEL, {**record, "validation": summary})
    # The best model's card keeps when it was selected, and gets the run's totals.
    best_card = read_card(run_dir / BEST_MODEL)
    write_card(run_dir / BEST_MODEL, {**best_card, **{key: record[key] for key in RUN_TOTALS}})
    write_config(run_dir, record)
    envs.close()
    return record
