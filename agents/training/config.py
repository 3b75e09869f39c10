"""Hyperparameters in the rl-zoo3 YAML format (``agents/hyperparams/<algo>.yml``).

The files follow rl-baselines3-zoo's conventions so that
``python -m rl_zoo3.train --gym-packages trailer_env --env trailer_env/Reverse-v0
--algo ppo --conf-file agents/hyperparams/ppo.yml`` reads them too: one entry per
environment id (plus a ``default:`` entry the others merge with ``<<: *default``), with
``n_envs``, ``n_timesteps``, ``policy``, ``env_kwargs``, ``normalize``, ``policy_kwargs``
as a Python expression string (``"dict(net_arch=[64, 64])"``), learning-rate schedules as
``lin_<initial value>``, ``train_freq`` as a list, and the algorithm's own keyword
arguments.

An id without an entry of its own reads the file's ``default:`` entry (MuJoCo Playground's
rule: the defaults, then the overrides an id's entry names), so a new scene trains before
it has entries; rl-zoo3 itself has no such fallback and still needs the id's entry.

:func:`load_hyperparams` turns an entry into what :mod:`agents.commands.train` needs. It does
not ``eval`` anything: ``policy_kwargs`` is parsed by :func:`parse_policy_kwargs`,
which accepts literals, ``dict(...)``, the activations ``nn.ReLU`` / ``nn.Tanh`` and the
shipped features extractors by name (``ConvoyEncoder``,
:data:`agents.policies.extractors.FEATURE_EXTRACTORS`).

An entry is checked before anything is built: ``policy`` must be ``MlpPolicy`` (or
``MultiInputPolicy``, for the Dict observation of ``observation="trailers"``); every
other key must be one of rl-zoo3's (``n_envs``, ``normalize`` ...) or an argument of
the algorithm's constructor (an unknown key is refused, naming it); counts
(``batch_size``, ``n_steps`` ...) must be integers and rates numbers; and the sizes are
bounded (:mod:`agents.artifacts.limits`):

==========================  =====================================================
key                         bound
==========================  =====================================================
``n_envs``                  1 .. 65,536 (:data:`~agents.artifacts.limits.MAX_N_ENVS`)
``n_timesteps``             1 .. 2**31
``policy_kwargs.net_arch``  10,000,000 parameters, 64 layers
``buffer_size``             1 .. 10,000,000 transitions (:data:`MAX_BUFFER_SIZE`)
``n_steps`` x ``n_envs``    10,000,000 steps per rollout (:data:`MAX_ROLLOUT_STEPS`)
the file                    1 MiB (:data:`MAX_HYPERPARAMS_BYTES`)
==========================  =====================================================
"""

from __future__ import annotations

import ast
import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from agents.algorithms import algo_class
from agents.algorithms.bounds import argument_problem
from agents.algorithms.options.base import OptionT, TrainingOption
from agents.algorithms.options.shaping import Shaping
from agents.artifacts import files, limits
from agents.policies.extractors import FEATURE_EXTRACTORS, feature_extractor

HYPERPARAMS_DIR = Path(__file__).resolve().parent.parent / "hyperparams"

#: Keyword arguments (of an env, a wrapper) as the files give them.
Keywords = dict[str, object]
#: Keyword arguments handed on to a stable-baselines3 constructor, which checks their
#: types itself (the entry's values are checked against the bounds here).
AlgoKwargs = dict[str, Any]

#: The largest hyperparameter file read.
MAX_HYPERPARAMS_BYTES = 2**20
#: The largest replay buffer (SAC/TD3), in transitions.
MAX_BUFFER_SIZE = 10_000_000
#: The largest rollout (PPO's n_steps times the batch's environments).
MAX_ROLLOUT_STEPS = 10_000_000
#: rl-zoo3's keys of an entry that are not the algorithm's arguments.
_ZOO_KEYS = (
    "n_envs",
    "n_timesteps",
    "policy",
    "env_kwargs",
    "normalize",
    "noise_type",
    "noise_std",
    "shaping",
)
#: Algorithm arguments that must be integers, and those that must be numbers.
_INT_KEYS = (
    "n_steps",
    "batch_size",
    "n_epochs",
    "buffer_size",
    "learning_starts",
    "gradient_steps",
    "policy_delay",
    "target_update_interval",
    "sde_sample_freq",
    "stats_window_size",
)
_NUMBER_KEYS = (
    "gamma",
    "gae_lambda",
    "vf_coef",
    "max_grad_norm",
    "tau",
    "target_policy_noise",
    "target_noise_clip",
    "target_kl",
    "cost_limit",
    "lambda_lr",
    "lambda_init",
)
#: Arguments the trainer sets itself (an entry may not).
_RESERVED = (
    "self",
    "policy",
    "env",
    "verbose",
    "seed",
    "device",
    "_init_setup_model",
    "tensorboard_log",
    "action_noise",
)
#: Keyword arguments of VecNormalize an entry's ``normalize`` may set.
_NORMALIZE_KEYS = ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon")

#: Activation functions allowed in policy_kwargs strings.
_ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "SiLU", "GELU")
#: The SB3 policies an entry may name: flat observations, and Dict ones
#: (``observation="trailers"``).
POLICIES = ("MlpPolicy", "MultiInputPolicy")


@dataclass
class Hyperparams:
    """One environment's entry of an rl-zoo3 hyperparameter file, preprocessed.

    Attributes:
        n_envs: Number of environments in the training batch.
        n_timesteps: Default training budget (environment steps).
        policy: Policy name, e.g. "MlpPolicy".
        env_kwargs: Keyword arguments of the environment.
        normalize: Keyword arguments of ``VecNormalize`` (observation normalisation), or
            None. rl-zoo3's ``normalize: true`` means both observations and rewards;
            a string is parsed like ``policy_kwargs``.
        action_noise_std: Gaussian exploration noise (rl-zoo3's ``noise_type: normal``,
            ``noise_std``) for TD3, or None.
        shaping: Potential-based reward shaping (this project's key, not rl-zoo3's), or
            None: the training option :class:`~agents.algorithms.options.shaping.Shaping`
            a run without ``--shaping`` takes (:meth:`TrainConfig.resolve`). The file's
            ``shaping: lqr`` names a potential; a ``dict(...)`` string sets its keywords.
        algo_kwargs: Everything else, ready for the algorithm's constructor.
    """

    n_envs: int = 1
    n_timesteps: int = 100_000
    policy: str = "MlpPolicy"
    env_kwargs: Keywords = field(default_factory=dict)
    normalize: AlgoKwargs | None = None
    action_noise_std: float | None = None
    shaping: Shaping | None = None
    algo_kwargs: AlgoKwargs = field(default_factory=dict)

    @property
    def gamma(self) -> float:
        """The discount (the algorithm's ``gamma``, SB3's default 0.99 when not set)."""
        gamma = self.algo_kwargs.get("gamma", 0.99)
        return float(gamma) if isinstance(gamma, (int, float)) else 0.99

    @property
    def n_steps(self) -> int:
        """An on-policy rollout's steps per environment (0 when not set)."""
        steps = self.algo_kwargs.get("n_steps", 0)
        return steps if isinstance(steps, int) else 0

    def number(self, key: str, default: float) -> float:
        """The algorithm's setting ``key`` as a number (a schedule: its starting value),
        ``default`` when the entry does not set it.

        Raises:
            ValueError: If the entry sets it to something else than a number.
        """
        value = self.algo_kwargs.get(key, default)
        if callable(value):
            value = value(1.0)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{key} must be a number, got {value!r:.60}")
        return float(value)

    @property
    def policy_kwargs(self) -> Keywords:
        """The policy's keyword arguments (a copy; empty when not set)."""
        kwargs = self.algo_kwargs.get("policy_kwargs")
        return dict(kwargs) if isinstance(kwargs, dict) else {}


def _literal(node: ast.expr) -> object:
    """Evaluate a policy_kwargs expression node: literals, dict(...), nn.<activation>, and
    a shipped features extractor's name."""
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict":
        if node.args:
            raise ValueError("dict(...) in policy_kwargs takes keyword arguments only")
        return {str(keyword.arg): _literal(keyword.value) for keyword in node.keywords}
    if (
        isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Name)
        and node.value.id == "nn"
        and node.attr in _ACTIVATIONS
    ):
        import torch.nn

        return getattr(torch.nn, node.attr)
    if isinstance(node, ast.Name) and node.id in FEATURE_EXTRACTORS:
        return feature_extractor(node.id)
    if isinstance(node, ast.Dict):
        pairs = zip(node.keys, node.values, strict=True)
        return {_literal(key): _literal(value) for key, value in pairs if key is not None}
    if isinstance(node, (ast.List, ast.Tuple)):
        items = [_literal(item) for item in node.elts]
        return items if isinstance(node, ast.List) else tuple(items)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        operand = _literal(node.operand)
        if not isinstance(operand, (int, float)):
            raise ValueError(f"unsupported expression in policy_kwargs: {ast.unparse(node)!r}")
        return -operand
    if isinstance(node, ast.Constant):
        return node.value
    raise ValueError(f"unsupported expression in policy_kwargs: {ast.unparse(node)!r}")


def parse_policy_kwargs(text: object) -> Keywords:
    """Parse an rl-zoo3 ``policy_kwargs`` string such as ``"dict(net_arch=[64, 64])"`` or
    ``"dict(features_extractor_class=ConvoyEncoder, features_extractor_kwargs=dict(hidden=32))"``.

    Raises:
        ValueError: If the string is not a dict of literals, allowed activations and
            shipped features extractors (any other name included).
    """
    if isinstance(text, dict):
        return text
    if not isinstance(text, str):
        raise ValueError(f"policy_kwargs must be a dict or its text, got {text!r:.60}")
    try:
        tree = ast.parse(text.strip(), mode="eval")
        value = _literal(tree.body)
    except (SyntaxError, RecursionError, MemoryError) as error:
        raise ValueError(f"policy_kwargs is not a Python expression: {text!r:.80}") from error
    if not isinstance(value, dict):
        raise ValueError(f"policy_kwargs must be a dict, got {text!r}")
    return value


def linear_schedule(initial: float) -> Callable[[float], float]:
    """rl-zoo3's ``lin_<x>``: decay linearly from ``initial`` to 0 over the training."""

    def schedule(progress_remaining: float) -> float:
        return progress_remaining * initial

    return schedule


def _schedule(key: str, value: object) -> object:
    if isinstance(value, str):
        kind, _, initial = value.partition("_")
        if kind != "lin":
            raise ValueError(f"{key}: unknown schedule {value!r} (only lin_<value> is supported)")
        try:
            return linear_schedule(float(initial))
        except ValueError:
            raise ValueError(f"{key}: bad schedule {value!r}") from None
    return value


def _train_freq(key: str, value: object) -> object:
    """rl-zoo3's ``train_freq: [1, episode]`` as the tuple SB3 takes."""
    del key
    return tuple(value) if isinstance(value, list) else value


#: The entry's values that are read into what the algorithm takes, by key.
_PARSED: dict[str, Callable[[str, object], object]] = {
    "policy_kwargs": lambda key, value: parse_policy_kwargs(value),
    "learning_rate": _schedule,
    "clip_range": _schedule,
    "train_freq": _train_freq,
}


def hyperparams_file(algo: str, directory: Path = HYPERPARAMS_DIR) -> Path:
    """The YAML file of ``algo``.

    Raises:
        FileNotFoundError: If there is none.
    """
    path = directory / f"{algo}.yml"
    if not path.is_file():
        raise FileNotFoundError(f"no hyperparameter file {path}")
    return path


#: The entry an id without one of its own reads.
DEFAULT_ENTRY = "default"


def raw_entry(algo: str, env_id: str, directory: Path = HYPERPARAMS_DIR) -> Keywords:
    """``env_id``'s entry of ``<directory>/<algo>.yml`` as the YAML holds it (anchors
    merged, nothing checked but the file's size and shape), or the file's ``default:``
    entry when ``env_id`` has none.

    Raises:
        FileNotFoundError: If the algorithm has no file.
        ValueError: If the file has neither an entry for ``env_id`` nor a ``default:`` one,
            or if the file is too large, not YAML, or not a mapping of mappings.
    """
    path = hyperparams_file(algo, directory)
    return _entry(path, env_id)[1]


def _entry(path: Path, env_id: str) -> tuple[str, Keywords]:
    """The name of the entry ``env_id`` reads in ``path`` and that entry (see :func:`raw_entry`)."""
    size = path.stat().st_size
    if size > MAX_HYPERPARAMS_BYTES:
        raise ValueError(f"{path} is {size} bytes, over the limit of {MAX_HYPERPARAMS_BYTES}")
    try:
        entries = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError, RecursionError) as error:
        raise ValueError(f"{path} is not valid YAML: {str(error)[:200]}") from None
    if not isinstance(entries, dict):
        raise ValueError(f"{path} must map environment ids to entries")
    name = env_id if env_id in entries else DEFAULT_ENTRY
    if name not in entries:
        raise ValueError(
            f"{path} has no entry for {env_id} and no {DEFAULT_ENTRY!r} entry; entries: "
            f"{sorted(map(str, entries))}"
        )
    if not isinstance(entries[name], dict):
        raise ValueError(f"{path}: the entry for {name} must be a mapping")
    return name, {str(key): value for key, value in entries[name].items()}


def load_hyperparams(algo: str, env_id: str, directory: Path = HYPERPARAMS_DIR) -> Hyperparams:
    """Read and preprocess ``env_id``'s entry of ``<directory>/<algo>.yml`` (its
    ``default:`` entry when ``env_id`` has none).

    Raises:
        FileNotFoundError: If the algorithm has no file.
        ValueError: If the file has neither an entry for ``env_id`` nor a ``default:`` one,
            or on a value the trainer cannot use.
    """
    path = hyperparams_file(algo, directory)
    name, raw = _entry(path, env_id)
    where = f"{path}, entry {name}"
    _check_keys(algo, raw, where)
    env_kwargs = raw.pop("env_kwargs", None) or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"{where}: env_kwargs must be a mapping, got {env_kwargs!r:.60}")
    result = Hyperparams(
        n_envs=_count(raw.pop("n_envs", 1), "n_envs", limits.MAX_N_ENVS, where),
        n_timesteps=_count(
            raw.pop("n_timesteps", 100_000), "n_timesteps", limits.MAX_TIMESTEPS, where
        ),
        policy=str(raw.pop("policy", "MlpPolicy")),
        env_kwargs=dict(env_kwargs),
    )
    if result.policy not in POLICIES:
        raise ValueError(f"{where}: policy must be one of {POLICIES}, got {result.policy!r:.60}")
    normalize = raw.pop("normalize", False)
    if isinstance(normalize, str):
        result.normalize = parse_policy_kwargs(normalize)
    elif isinstance(normalize, dict):
        result.normalize = {str(key): value for key, value in normalize.items()}
    elif normalize:
        result.normalize = {}
    for key in result.normalize or {}:
        if key not in _NORMALIZE_KEYS:
            raise ValueError(f"{where}: normalize has no setting {key!r}; {list(_NORMALIZE_KEYS)}")
    try:
        result.shaping = Shaping.from_setting(raw.pop("shaping", None))
    except ValueError as error:
        raise ValueError(f"{where}: {error}") from None
    for key in _INT_KEYS:
        if key in raw:
            bound = MAX_BUFFER_SIZE if key == "buffer_size" else limits.MAX_TIMESTEPS
            raw[key] = _count(raw[key], key, bound, where, minimum=0)
    for key in _NUMBER_KEYS:
        if key in raw and not files.is_number(raw[key]):
            raise ValueError(f"{where}: {key} must be a finite number, got {raw[key]!r:.60}")
    for key, value in raw.items():  # the bounds the algorithm (and agents.tune) holds to
        problem = argument_problem(algo, key, value)
        if problem is not None:
            raise ValueError(f"{where}: {problem}")
    result.algo_kwargs = raw
    rollout = result.n_steps * result.n_envs
    if rollout > MAX_ROLLOUT_STEPS:
        raise ValueError(
            f"{where}: n_steps x n_envs = {rollout} steps per rollout, over the limit of "
            f"{MAX_ROLLOUT_STEPS}"
        )
    for key, parse in _PARSED.items():
        if key in raw:
            raw[key] = parse(key, raw[key])
    problem = limits.network_problem(result.policy_kwargs.get("net_arch", [64, 64]))
    if problem is not None:
        raise ValueError(f"{where}: policy_kwargs: {problem}")
    if "noise_type" in raw:
        if str(raw.pop("noise_type")).strip() != "normal":
            raise ValueError(f"{path}: only noise_type 'normal' is supported")
        noise = raw.pop("noise_std", None)
        if isinstance(noise, bool) or not isinstance(noise, (int, float, str)):
            raise ValueError(f"{where}: noise_type normal needs a number noise_std")
        try:
            result.action_noise_std = float(noise)
        except ValueError:
            raise ValueError(f"{where}: noise_type normal needs a number noise_std") from None
    for unsupported in ("env_wrapper", "vec_env_wrapper", "frame_stack", "callback"):
        if unsupported in raw:
            raise ValueError(f"{path}: {unsupported!r} is not supported by agents.train")
    return result


def _count(value: object, key: str, maximum: int, where: str, minimum: int = 1) -> int:
    """An integer count of an entry (``2e6`` allowed as a float of integral value)."""
    count: int | None = None
    if isinstance(value, int) and not isinstance(value, bool):
        count = value
    elif isinstance(value, float) and math.isfinite(value) and value == int(value):
        count = int(value)
    if count is None or not minimum <= count <= maximum:
        raise ValueError(
            f"{where}: {key} must be an integer in {minimum}..{maximum}, got {value!r:.60}"
        )
    return count


def init_arguments(cls: type) -> set[str]:
    """The named arguments of ``cls``'s constructor, those its ``**kwargs`` passes on to
    the base classes' included (PPO-Lagrangian adds three to PPO's)."""
    names: set[str] = set()
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        parameters = inspect.signature(klass.__init__).parameters.values()  # type: ignore[misc]
        names |= {p.name for p in parameters if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
        if all(p.kind != p.VAR_KEYWORD for p in parameters):
            break
    return names


def _check_keys(algo: str, raw: Mapping[str, object], where: str) -> None:
    """Refuse an entry key that is neither rl-zoo3's nor an argument of the algorithm."""
    accepted = init_arguments(algo_class(algo)) - set(_RESERVED)
    for key in raw:
        if (
            key not in accepted
            and key not in _ZOO_KEYS
            and key not in ("env_wrapper", "vec_env_wrapper", "frame_stack", "callback")
        ):
            raise ValueError(
                f"{where}: unknown key {key!r:.60} (neither rl-zoo3's nor an argument of {algo})"
            )


def jsonable(value: object) -> object:
    """Hyperparameter values as JSON (schedules and classes by name)."""
    if isinstance(value, dict):
        return {str(key): jsonable(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(item) for item in value]
    if isinstance(value, (bool, int, float, str)) or value is None:
        return value
    return getattr(value, "__name__", repr(value))


@dataclass(frozen=True)
class TrainConfig:
    """What one training run was asked to do: behind the CLI, ``config.json`` and the cards.

    Build it with :meth:`resolve` (the command's values over the hyperparameter file's);
    :meth:`document` is the record written to ``config.json`` and into every model card.

    Attributes:
        env_id: A trailer_env id.
        algo: A name of :data:`agents.algorithms.ALGOS` ("ppo", "ppo_lag", "sac", "td3").
        n_trailers: Number of trailers, or a range ``(low, high)`` (a generalist: every
            episode draws its n, :mod:`trailer_env.mixed`), over the file's ``env_kwargs``.
        seed: Seed of the model and of the training environments (env i gets seed + i).
        budget: Total training budget in environment steps.
        n_envs: Environments in the training batch (RLlib: all runners together).
        hyperparams: The hyperparameter file's entry.
        backend: "sb3" or "rllib".
        command: The command line that started the run.
        randomize: A preset of :data:`trailer_env.randomize.PRESETS` over the file's
            ``env_kwargs`` (None: the file's).
        options: The training options (:data:`agents.algorithms.options.TRAINING_OPTIONS`:
            a start curriculum, a start replay, a fine-tuning start ...), at most one of
            each kind; each checks itself against the run.
    """

    env_id: str
    algo: str
    n_trailers: int | tuple[int, int]
    seed: int
    budget: int
    n_envs: int
    hyperparams: Hyperparams
    backend: str = "sb3"
    command: tuple[str, ...] = ()
    randomize: str | None = None
    options: tuple[TrainingOption, ...] = ()

    def __post_init__(self) -> None:
        if self.backend not in ("sb3", "rllib"):
            raise ValueError(f"backend must be 'sb3' or 'rllib', got {self.backend!r}")
        if self.budget < 1 or self.n_envs < 1:
            raise ValueError(f"budget and n_envs must be >= 1, got {self.budget}, {self.n_envs}")
        kinds = [type(option) for option in self.options]
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"one option of each kind, got {[kind.__name__ for kind in kinds]}")
        for option in self.options:
            option.check(self)
        if self.budget > limits.MAX_TIMESTEPS:
            raise ValueError(f"timesteps must be <= {limits.MAX_TIMESTEPS}, got {self.budget}")
        if self.n_envs > limits.MAX_N_ENVS:
            raise ValueError(f"n_envs must be <= {limits.MAX_N_ENVS}, got {self.n_envs}")
        rollout = self.hyperparams.n_steps * self.n_envs
        if self.backend == "sb3" and rollout > MAX_ROLLOUT_STEPS:
            raise ValueError(
                f"n_steps x n_envs = {rollout} steps per rollout, over the limit of "
                f"{MAX_ROLLOUT_STEPS}"
            )
        # Env i is seeded seed + i; a resumed run reseeds at seed + its step count.
        problem = limits.seed_problem(self.seed, self.budget + self.n_envs + 1, "seed")
        if problem is not None:
            raise ValueError(problem)

    @classmethod
    def resolve(
        cls,
        env_id: str,
        algo: str,
        n_trailers: int | tuple[int, int],
        seed: int,
        hyperparams: Hyperparams,
        *,
        timesteps: int | None = None,
        n_envs: int | None = None,
        backend: str = "sb3",
        command: tuple[str, ...] | list[str] = (),
        randomize: str | None = None,
        options: tuple[TrainingOption, ...] = (),
    ) -> TrainConfig:
        """The run's configuration: ``timesteps`` and ``n_envs`` default to the file's, and
        an SB3 run without a :class:`Shaping` option takes the file's ``shaping``.

        Raises:
            ValueError: On a setting out of bounds; an :class:`OptionError` names the
                option's flag.
        """
        return cls(
            env_id=env_id,
            algo=algo,
            n_trailers=n_trailers,
            seed=seed,
            budget=int(timesteps if timesteps is not None else hyperparams.n_timesteps),
            n_envs=int(n_envs if n_envs is not None else hyperparams.n_envs),
            hyperparams=hyperparams,
            backend=backend,
            command=tuple(command),
            randomize=randomize,
            options=_with_file_options(options, hyperparams, backend),
        )

    def option(self, kind: type[OptionT]) -> OptionT | None:
        """The run's option of ``kind``, or None."""
        for option in self.options:
            if isinstance(option, kind):
                return option
        return None

    @property
    def env_kwargs(self) -> Keywords:
        """The environment's keyword arguments: the file's, with this run's ``n_trailers``
        (a range as a JSON list) and ``randomize``."""
        counts = self.n_trailers
        physics = {} if self.randomize is None else {"randomize": self.randomize}
        return {
            **self.hyperparams.env_kwargs,
            "n_trailers": list(counts) if isinstance(counts, tuple) else counts,
            **physics,
        }

    def document(self) -> Keywords:
        """The run's record (JSON-ready) for ``config.json`` and the model cards.

        An SB3 run records the file's policy, algorithm arguments and normalisation and
        each option's part; an RLlib run records ``backend`` (its trainer adds the RLlib
        settings it resolved).
        """
        record: Keywords = {
            "algo": self.algo,
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
            "seed": self.seed,
            "budget": self.budget,
            "n_envs": self.n_envs,
            "command": list(self.command),
        }
        if self.backend != "sb3":
            return {**record, "backend": self.backend}
        record.update(
            {
                "policy": self.hyperparams.policy,
                "hyperparams": jsonable(self.hyperparams.algo_kwargs),
                "normalize": self.hyperparams.normalize,
            }
        )
        for option in self.options:
            record.update(option.record())
        return record


def _with_file_options(
    options: tuple[TrainingOption, ...], hyperparams: Hyperparams, backend: str
) -> tuple[TrainingOption, ...]:
    """``options`` and the hyperparameter entry's shaping when they have none (an SB3
    entry's setting: an RLlib run leaves it)."""
    shaping = hyperparams.shaping
    if shaping is None or backend != "sb3" or any(isinstance(o, Shaping) for o in options):
        return tuple(options)
    return (shaping, *options)
