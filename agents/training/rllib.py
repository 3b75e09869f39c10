"""Distributed training on Ray RLlib (the ``rllib`` extra): ``agents.train --backend rllib``.

The algorithms it trains are the records of :data:`RLLIB_ALGOS` (PPO today): each builds
its RLlib config from the SB3 hyperparameter file's entry, says which of the resolved
settings the run records, and names the RLModule its exported policy is rebuilt with;
another algorithm is one more record.

Usage::

    python -m agents.train --backend rllib --env trailer_env/Reverse-v0 --algo ppo \
        --num-env-runners 2 --timesteps 200000 [--address ray://head:10001 | auto]

Without ``--address`` a local Ray is started (``ray.init`` with ``num_cpus=2``, or one
per runner when there are more, no dashboard, worker output not echoed) and shut down
on exit, even after an error; its session's logs are copied to the run folder's
``ray_logs/`` first (the session itself stays under Ray's /tmp folder: its unix
sockets need a short path). With ``--address`` the driver joins that cluster and only
disconnects at the end (the logs stay on the cluster).

Before Ray starts, ``--address`` must be ``auto``, ``HOST:PORT`` or ``ray://HOST:PORT``
(:func:`address_problem`) and reachable within :data:`CONNECT_TIMEOUT_S` (a TCP
connection is tried first: an unknown or silent host fails in seconds, not after
Ray's minutes of retries). ``--num-env-runners`` may not exceed the CPUs: this
machine's (``os.cpu_count()``) for a local Ray, the cluster's
(``ray.cluster_resources()['CPU']``) with ``--address`` (checked right after
connecting, before anything is built or written). No orphans: the local Ray is
started by the driver, which owns it (Ray kills the processes of a head node it
started when the driver exits, its fate-sharing); ``ray.shutdown()`` runs in a
``finally`` block, and SIGTERM is turned into an exception so that it runs then too.

How the env runners find the environment: :func:`register_trailer_env` registers
the creator :func:`make_rllib_env` under :data:`RLLIB_ENV_NAME` with
``ray.tune.registry.register_env``. Ray stores the creator by reference to this
module, so a worker process that never imported ``trailer_env`` imports
``agents.training.rllib`` (and with it ``trailer_env``) when it builds its env: the
``agents`` package must be importable on every node (``pip install`` the project
there, or pass ``runtime_env={"working_dir": ...}``).

The native batched env serves each runner: RLlib's new API stack builds a
runner's envs with ``gym.make_vec(..., vectorization_mode=config.gym_env_vectorize_mode)``
and, for a registered creator, registers ``vector_entry_point=creator(ctx | {"num_envs": k})``;
with ``gym_env_vectorize_mode="vector_entry_point"`` each runner therefore steps
one :class:`trailer_env.vector.ConvoyVectorEnv` of ``num_envs_per_env_runner``
convoys (one kernel call per step), not k Python envs.

The run folder has the same layout as an SB3 run: ``config.json``, ``progress.csv``
(one row per training iteration), ``checkpoint/`` (RLlib's checkpoint, for
``Algorithm.from_checkpoint``) and, inside it, a pickle-free export of the policy
that :mod:`agents.commands.evaluate` reads: ``policy_weights.pt`` (tensors only, loaded with
``torch.load(weights_only=True)``) and ``policy_card.json`` (the model card: spaces,
network, training record). RLlib's own checkpoint files are pickles; they are only
read with ``--trust-pickle``.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
import re
import shutil
import signal
import socket
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from agents.artifacts.cards import card_of
from agents.artifacts.curves import write_curve
from agents.artifacts.files import atomic_write_bytes, write_json
from agents.artifacts.rllib_files import POLICY_CARD, POLICY_WEIGHTS
from agents.artifacts.run_folder import PROGRESS_FILE, RLLIB_CHECKPOINT, write_config
from agents.training.config import Hyperparams, TrainConfig
from agents.training.host_speed import measure_host_speed

if TYPE_CHECKING:
    from types import FrameType

    import gymnasium as gym
    import torch
    from ray.rllib.algorithms.ppo import PPOConfig

    #: What ``signal.signal`` returns: the handler it replaced.
    SignalHandler = Callable[[int, FrameType | None], object] | int | signal.Handlers | None

#: The name under which :func:`register_trailer_env` registers the env creator.
RLLIB_ENV_NAME = "trailer_env_rllib"


#: Seconds to wait for the cluster at ``--address`` to answer.
CONNECT_TIMEOUT_S = 10.0


_ADDRESS = re.compile(r"(?:ray://)?(\[[0-9a-fA-F:.]+\]|[A-Za-z0-9][A-Za-z0-9.-]{0,252}):(\d{1,5})")


class ClusterTooSmallError(ValueError):
    """More env runners were asked for than the cluster has CPUs."""


def local_cpus() -> int:
    """The CPUs of this machine (the local Ray's bound on runners)."""
    return os.cpu_count() or 1


def address_problem(address: str, timeout: float = CONNECT_TIMEOUT_S) -> str | None:
    """Why ``address`` is no usable Ray address (None when it is), checked without Ray:
    its form, then a TCP connection within ``timeout`` seconds."""
    if address == "auto":
        return None
    match = _ADDRESS.fullmatch(address)
    if match is None or not 1 <= int(match.group(2)) <= 65535:
        return f"{address[:80]!r} is not auto, HOST:PORT or ray://HOST:PORT (port 1..65535)"
    host = match.group(1).strip("[]")
    try:
        with socket.create_connection((host, int(match.group(2))), timeout=timeout):
            return None
    except OSError as error:
        return f"cannot reach {address} within {timeout:.0f} s: {error.strerror or error}"


def _raise_on_sigterm() -> SignalHandler:
    """Make SIGTERM raise SystemExit (so that ``finally`` shuts Ray down); returns the
    handler it replaced (None off the main thread, where it does nothing)."""

    def handler(signum: int, frame: object) -> None:
        raise SystemExit(128 + signum)

    try:
        return signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        return None


def make_rllib_env(
    env_config: Mapping[str, object],
) -> gym.Env[np.ndarray, np.ndarray] | gym.vector.VectorEnv:
    """RLlib's env creator: the native batch when RLlib asks for ``num_envs``, else one env.

    Args:
        env_config: ``{"env_id": ..., **env_kwargs}``, plus ``num_envs`` when RLlib builds
            a runner's vector env (RLlib passes an ``EnvContext``, a dict subclass).
    """
    import gymnasium as gym

    import trailer_env  # noqa: F401  (registers the ids in this worker process)

    kwargs: dict[str, Any] = dict(env_config)  # gym.make checks its keywords
    env_id = str(kwargs.pop("env_id"))
    num_envs = kwargs.pop("num_envs", None)
    if num_envs is None:
        return gym.make(env_id, **kwargs)
    if not isinstance(num_envs, int):
        raise TypeError(f"num_envs must be an int, got {type(num_envs).__name__}")
    return gym.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs
    )


def register_trailer_env() -> str:
    """Register :func:`make_rllib_env` with Ray Tune's registry; returns its name."""
    from ray.tune.registry import register_env

    register_env(RLLIB_ENV_NAME, make_rllib_env)
    return RLLIB_ENV_NAME


def ppo_config(
    env_id: str,
    env_kwargs: Mapping[str, object],
    hp: Hyperparams,
    seed: int,
    num_env_runners: int,
    envs_per_runner: int,
) -> PPOConfig:
    """An RLlib ``PPOConfig`` equivalent to the SB3 hyperparameters ``hp`` (new API stack).

    The SB3 batch (``n_envs`` x ``n_steps`` steps per update) becomes the learner's
    train batch; ``batch_size`` the minibatch; ``n_epochs``, ``gamma``, ``gae_lambda``,
    ``clip_range``, ``ent_coef`` and a constant ``learning_rate`` carry over, and
    ``policy_kwargs``' ``net_arch`` becomes ``fcnet_hiddens``. Observations are not
    normalised (RLlib has no VecNormalize): u and omega enter unscaled, of order 1 m/s
    and 1 rad/s in the scenes' states; the other entries lie in [-1, 1].
    """
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    steps_per_update = hp.n_envs * (hp.n_steps or 2048)
    net_arch = hp.policy_kwargs.get("net_arch", [64, 64])
    if not isinstance(net_arch, list):
        raise ValueError(f"net_arch must be a list of widths, got {net_arch!r:.60}")
    runners = max(num_env_runners, 1)
    fragment = max(math.ceil(steps_per_update / (runners * envs_per_runner)), 1)
    return (
        PPOConfig()
        .environment(env=register_trailer_env(), env_config={"env_id": env_id, **env_kwargs})
        .env_runners(
            num_env_runners=num_env_runners,
            num_envs_per_env_runner=envs_per_runner,
            gym_env_vectorize_mode="vector_entry_point",
            rollout_fragment_length=fragment,
            num_cpus_per_env_runner=1,
        )
        .learners(num_learners=0)
        .training(
            train_batch_size_per_learner=fragment * runners * envs_per_runner,
            minibatch_size=int(hp.number("batch_size", 64)),
            num_epochs=int(hp.number("n_epochs", 10)),
            lr=hp.number("learning_rate", 3e-4),
            gamma=hp.gamma,
            lambda_=hp.number("gae_lambda", 0.95),
            clip_param=hp.number("clip_range", 0.2),
            entropy_coeff=hp.number("ent_coef", 0.0),
        )
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(net_arch)))
        .debugging(seed=seed)
        .reporting(metrics_num_episodes_for_smoothing=20)
    )


def ppo_settings(rllib_config: PPOConfig) -> dict[str, object]:
    """The settings a ``PPOConfig`` resolved, for the run's record (``fcnet_hiddens``
    rebuilds the exported policy's network)."""
    return {
        "train_batch_size": rllib_config.train_batch_size_per_learner,
        "minibatch_size": rllib_config.minibatch_size,
        "num_epochs": rllib_config.num_epochs,
        "lr": rllib_config.lr,
        "gamma": rllib_config.gamma,
        "lambda": rllib_config.lambda_,
        "clip_param": rllib_config.clip_param,
        "entropy_coeff": rllib_config.entropy_coeff,
        "fcnet_hiddens": list(rllib_config.model_config["fcnet_hiddens"]),
    }


@dataclass(frozen=True)
class RLlibAlgorithm:
    """One algorithm the RLlib backend trains (a record of :data:`RLLIB_ALGOS`).

    Attributes:
        build_config: ``(env_id, env_kwargs, hp, seed, num_env_runners, envs_per_runner)``
            -> the RLlib ``AlgorithmConfig`` equivalent to the SB3 entry ``hp``.
        settings: The settings that config resolved, for ``config.json`` and the policy
            card (their ``fcnet_hiddens`` rebuild the exported policy's network).
        module: ``"module:Class"`` of the RLModule the exported policy is rebuilt with
            (a class under ``ray.rllib``, :func:`agents.policies.rllib.load_rllib_policy`).
    """

    build_config: Callable[[str, Mapping[str, object], Hyperparams, int, int, int], PPOConfig]
    settings: Callable[[PPOConfig], dict[str, object]]
    module: str


#: The RLModule RLlib's PPO trains (its exported policy is rebuilt with it).
PPO_MODULE = "ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module:DefaultPPOTorchRLModule"

#: Algorithms the RLlib backend trains, by ``--algo`` name (a name of
#: :data:`agents.algorithms.ALGOS`).
RLLIB_ALGOS: dict[str, RLlibAlgorithm] = {
    "ppo": RLlibAlgorithm(
        build_config=ppo_config,
        settings=ppo_settings,
        module=PPO_MODULE,
    ),
}


def _runner_env(runner: Any) -> tuple[str, bool, str]:
    """An env runner's env class, whether it is the native batch, and the Ray node it runs
    on (runs on the runner)."""
    import ray

    from trailer_env.vector import ConvoyVectorEnv

    env = runner.env.unwrapped
    node = ray.get_runtime_context().get_node_id()
    return type(env).__name__, isinstance(env, ConvoyVectorEnv), node


def _ray_init(address: str | None, num_env_runners: int) -> tuple[bool, Path | None]:
    """Start a local Ray (or join ``address``).

    Returns whether this call connected (and so must shut down) and, for a local Ray
    it started, the session's log folder.
    """
    import ray

    if ray.is_initialized():
        return False, None
    if address is not None:
        try:
            ray.init(address=address, include_dashboard=False, log_to_driver=False)
        except (ConnectionError, RuntimeError) as error:
            raise ConnectionError(
                f"cannot connect to the Ray cluster at {address}: {str(error).splitlines()[0]} "
                "(a cluster with token authentication, Ray's default, also needs "
                "RAY_AUTH_MODE=token and its token in ~/.ray/auth_token or RAY_AUTH_TOKEN)"
            ) from None
        _check_cluster_cpus(num_env_runners)
        return True, None
    context: Any = ray.init(
        # "local": a new instance even when `ray start` left a cluster on this machine
        # (plain ray.init() would join that one, where num_cpus is not allowed).
        address="local",
        # Each runner reserves one CPU; the learner runs in this process. Two logical
        # CPUs at least (Ray's own tasks), more only when more runners must be placed.
        num_cpus=max(2, num_env_runners),
        include_dashboard=False,
        log_to_driver=False,
        configure_logging=False,
    )
    return True, Path(context.address_info["session_dir"]) / "logs"


def _check_cluster_cpus(num_env_runners: int) -> None:
    """Refuse more runners than the joined cluster has CPUs (disconnecting first)."""
    import ray

    cpus = int(ray.cluster_resources().get("CPU", 0))
    if num_env_runners > cpus:
        ray.shutdown()
        raise ClusterTooSmallError(
            f"{num_env_runners} runners, but the cluster has {cpus} CPUs (one runner per CPU)"
        )


def _shutdown(started: bool, logs: Path | None, run_dir: Path) -> None:
    """Copy the local Ray session's logs into ``run_dir/ray_logs``, then shut Ray down."""
    import ray

    if logs is not None and logs.is_dir():
        # Ray's session folder stays under /tmp: its unix sockets need a short path.
        shutil.copytree(logs, run_dir / "ray_logs", dirs_exist_ok=True)
    if started:
        ray.shutdown()


def _number(section: object, key: str) -> float:
    """A number of one of RLlib's result sections (NaN when it has none yet)."""
    value = section.get(key) if isinstance(section, Mapping) else None
    return float(value) if isinstance(value, (int, float)) else math.nan


@dataclass(frozen=True)
class IterationRow:
    """One row of ``progress.csv``: what one RLlib iteration reports.

    ``sample_s`` and ``learn_s`` are RLlib's own timers, smoothed across iterations (so
    not summable into a wall time): sampling on the runners, the update in the learner.
    """

    iteration: int
    timesteps: int
    wall_s: float
    episode_return_mean: float
    episode_len_mean: float
    num_episodes: int
    sample_s: float
    learn_s: float

    @classmethod
    def from_result(
        cls, result: Mapping[str, object], iteration: int, wall_s: float
    ) -> IterationRow:
        """The row of RLlib's result of ``algorithm.train()``."""
        runners = result.get("env_runners")
        timers = result.get("timers")
        lifetime = "num_env_steps_sampled_lifetime"
        steps = _number(result, lifetime)
        steps = _number(runners, lifetime) if math.isnan(steps) else steps
        episodes = _number(runners, "num_episodes_lifetime")
        return cls(
            iteration=iteration,
            timesteps=0 if math.isnan(steps) else int(steps),
            wall_s=round(wall_s, 2),
            episode_return_mean=_number(runners, "episode_return_mean"),
            episode_len_mean=_number(runners, "episode_len_mean"),
            num_episodes=0 if math.isnan(episodes) else int(episodes),
            sample_s=_number(timers, "env_runner_sampling_timer"),
            learn_s=_number(timers, "learner_update_timer"),
        )


@dataclass(frozen=True)
class RLlibRun:
    """What :func:`train_rllib` did.

    Attributes:
        record: The run's record (``config.json``, the policy export's card).
        timesteps: Environment steps sampled.
        env_steps_per_s: Their rate over the training's wall time.
    """

    record: dict[str, object]
    timesteps: int
    env_steps_per_s: float


def train_rllib(
    config: TrainConfig,
    run_dir: Path,
    *,
    num_env_runners: int = 1,
    address: str | None = None,
    verbose: int = 1,
) -> RLlibRun:
    """Train ``config.algo`` (a record of :data:`RLLIB_ALGOS`) on Ray RLlib until
    ``config.budget`` env steps.

    Args:
        config: What to train (backend "rllib"); ``config.n_envs`` convoys in all,
            split evenly across the runners' native batches.
        run_dir: Run folder.
        num_env_runners: Remote env runners (0: the driver samples itself).
        address: A running Ray cluster (``ray start --head`` prints it; "auto" finds a
            local one); None starts a local Ray and shuts it down at the end.

    Training stops after the first iteration that reaches the budget.

    Raises:
        ValueError: For an algorithm without a record or a negative runner count.
        ConnectionError: If ``address`` cannot be reached.
    """
    if config.algo not in RLLIB_ALGOS:
        raise ValueError(f"the rllib backend trains {list(RLLIB_ALGOS)}, not {config.algo!r}")
    trained = RLLIB_ALGOS[config.algo]
    if num_env_runners < 0:
        raise ValueError(f"num_env_runners must be >= 0, got {num_env_runners}")
    per_runner = max(config.n_envs // max(num_env_runners, 1), 1)
    if address is None and num_env_runners > local_cpus():
        raise ClusterTooSmallError(
            f"{num_env_runners} runners, but this machine has {local_cpus()} CPUs"
        )
    started_ray, ray_logs = _ray_init(address, num_env_runners)
    run_dir.mkdir(parents=True, exist_ok=True)
    previous_handler = _raise_on_sigterm()
    try:
        rllib_config = trained.build_config(
            config.env_id,
            config.env_kwargs,
            config.hyperparams,
            config.seed,
            num_env_runners,
            per_runner,
        )
        algorithm: Any = rllib_config.build_algo()  # RLlib types its parts as optional
        runner_envs = (
            algorithm.env_runner_group.foreach_env_runner(_runner_env, local_env_runner=False)
            if num_env_runners > 0
            else [_runner_env(algorithm.env_runner)]
        )
        record: dict[str, object] = {
            **config.document(),
            "n_envs": per_runner * max(num_env_runners, 1),
            "num_env_runners": num_env_runners,
            "envs_per_runner": per_runner,
            "address": address,
            # What each runner steps and where: (class name, is a native ConvoyVectorEnv
            # batch, Ray node id).
            "runner_envs": runner_envs,
            "hyperparams": trained.settings(rllib_config),
            # The driver's machine (the runners may be elsewhere: runner_envs names them).
            "host": measure_host_speed(config.seed).to_json(),
        }
        write_config(run_dir, card_of(record, f"for {run_dir}"))
        rows, wall = _iterate(algorithm, config.budget, verbose)
        return _finish(algorithm, run_dir, record, rows, wall, trained.module)
    finally:
        if previous_handler is not None:
            signal.signal(signal.SIGTERM, previous_handler)
        _shutdown(started_ray, ray_logs, run_dir)


def _iterate(algorithm: Any, budget: int, verbose: int) -> tuple[list[IterationRow], float]:
    """Train until ``budget`` env steps are sampled: the iterations' rows and the wall time."""
    rows: list[IterationRow] = []
    started = time.perf_counter()
    steps = 0
    while steps < budget:
        result = algorithm.train()
        row = IterationRow.from_result(result, len(rows) + 1, time.perf_counter() - started)
        rows.append(row)
        steps = row.timesteps
        if verbose:
            print(
                f"[rllib] {steps:>9d} steps  return {row.episode_return_mean:8.1f}  "
                f"({row.wall_s:.0f} s)",
                flush=True,
            )
    return rows, time.perf_counter() - started


def _finish(
    algorithm: Any,
    run_dir: Path,
    record: dict[str, object],
    rows: list[IterationRow],
    wall: float,
    module_path: str,
) -> RLlibRun:
    """Write the curve, the checkpoint, the policy export and the completed record."""
    write_curve(run_dir / PROGRESS_FILE, [dataclasses.asdict(row) for row in rows], FIELDS)
    checkpoint = run_dir / RLLIB_CHECKPOINT
    algorithm.save_to_path(str(checkpoint.resolve()))
    steps = rows[-1].timesteps
    rate = round(steps / wall, 1)
    record.update(
        {
            "timesteps": steps,
            "wall_time_s": round(wall, 1),
            "env_steps_per_s": rate,
            "episode_return_mean": rows[-1].episode_return_mean,
        }
    )
    export_policy(algorithm, checkpoint, record, module_path)
    write_config(run_dir, card_of(record, f"for {run_dir}"))
    algorithm.stop()
    return RLlibRun(record, steps, rate)


#: The columns of ``progress.csv``.
FIELDS = [field.name for field in dataclasses.fields(IterationRow)]


def learner_policy_state(algorithm: Any) -> dict[str, torch.Tensor]:
    """The trained policy's weights (inference part, as tensors) from the learner.

    Read from the learner group, whose module is the one being optimised (the env
    runners hold copies synchronised after each iteration).
    """
    import torch
    from ray.rllib.core import COMPONENT_LEARNER, COMPONENT_RL_MODULE, DEFAULT_MODULE_ID

    path = f"{COMPONENT_LEARNER}/{COMPONENT_RL_MODULE}/{DEFAULT_MODULE_ID}"
    state = algorithm.learner_group.get_state(components=path, inference_only=True)
    weights = state[COMPONENT_LEARNER][COMPONENT_RL_MODULE][DEFAULT_MODULE_ID]
    return {key: torch.as_tensor(np.asarray(value)) for key, value in weights.items()}


def export_policy(
    algorithm: Any,
    checkpoint: Path,
    card: Mapping[str, object],
    module_path: str = PPO_MODULE,
) -> None:
    """Write the pickle-free policy export (weights + card) into ``checkpoint``; the card
    names the RLModule (``module_path``, ``"module:Class"``) the policy is rebuilt with."""
    import torch

    checkpoint.mkdir(parents=True, exist_ok=True)
    weights = io.BytesIO()
    torch.save(learner_policy_state(algorithm), weights)
    atomic_write_bytes(checkpoint / POLICY_WEIGHTS, weights.getvalue())
    module = algorithm.get_module()
    spaces = {
        "observation_shape": list(module.observation_space.shape),
        "action_shape": list(module.action_space.shape),
        "action_low": np.asarray(module.action_space.low, dtype=float).tolist(),
        "action_high": np.asarray(module.action_space.high, dtype=float).tolist(),
    }
    document = {
        **card,
        "module": module_path.rpartition(":")[2],
        "module_path": module_path,
        "inference_only": True,
        "spaces": spaces,
    }
    write_json(checkpoint / POLICY_CARD, document)
