"""Model cards (JSON beside a model) and run records (a run's ``config.json``).

Both are one document, :class:`ModelCard`: what a training run was asked for (the
algorithm, the scene and its ``gym.make`` keywords, the seed, the options) and, once a
model is kept, what it reached (``validation``, ``timesteps``, ``wall_time_s``, when it
was selected). A card is read with :func:`read_model_card` (bounded by
:data:`~agents.artifacts.files.MAX_JSON_BYTES` and the JSON depth limit) and refused
whole, with a :class:`~agents.artifacts.records.DocumentError` (a ``ValueError``) naming
the field, when a field is unknown or of the wrong type.

Every field may be absent (a run record is written before the run has results, an
imitated model has no ``n_envs``); an absent field reads as its default. :meth:`to_json`
leaves out an optional field at its default, so a card read and written back is the
document it was (with ``schema_version`` added); the run record's own keys
(:data:`RECORD_KEYS`) and ``normalize`` (null: no normalisation) are always written.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import ClassVar, cast

from agents.algorithms.options import TRAINING_OPTIONS, TrainingOption, recorded_options
from agents.algorithms.options.base import OptionT
from agents.artifacts import files
from agents.artifacts.paths import card_path
from agents.artifacts.records import (
    NOT_IN_JSON,
    DocumentError,
    RecordT,
    SparsePart,
    SparseRecord,
)

#: The keys every run record (``config.json``) holds.
RECORD_KEYS = ("algo", "env_id", "env_kwargs", "seed")
#: The flags of a command that name where its run's files go, not what it trains: a
#: committed card's recipe leaves them out (its reproduction sets them).
RUN_FOLDER_FLAGS = ("--run-dir", "--export")


def recipe_command(command: Sequence[str]) -> tuple[str, ...]:
    """``command`` without its run-folder flags (:data:`RUN_FOLDER_FLAGS`, each with its
    value) and ``--overwrite``: the same training, wherever its files go."""
    kept: list[str] = []
    skip = False
    for item in command:
        if skip:
            skip = False
        elif item in RUN_FOLDER_FLAGS:
            skip = True
        elif item != "--overwrite":
            kept.append(item)
    return tuple(kept)


#: RLlib's keyword (in an RLlib run's ``hyperparams``) for its network's hidden layers.
RLLIB_HIDDENS = "fcnet_hiddens"


def is_count_range(value: object) -> bool:
    """Whether ``n_trailers`` is a range ``[low, high]`` (a generalist's)."""
    return (
        isinstance(value, (list, tuple))
        and len(value) == 2
        and all(files.is_integer(bound, 0) for bound in value)
        and value[0] < value[1]
    )


@dataclasses.dataclass(frozen=True)
class EnvKwargs(SparsePart):
    """The ``gym.make`` keywords of the run: those the agents read are fields; any other
    keyword (``dt``, ``fidelity``, a parameter override such as ``mu``) is kept in
    :attr:`other` as written, for ``gym.make`` to check."""

    #: One count, or a range ``(low, high)`` with ``low < high`` (a generalist).
    n_trailers: int | tuple[int, int] | None = None
    observation: str | None = None
    max_trailers: int | None = None
    randomize: str | Mapping[str, object] | None = None
    trailer_draw: str | None = None
    #: Past frames in the observation (``gym.make``'s ``history``; None: none).
    history: int | None = None
    #: The other keywords, as written.
    other: Mapping[str, object] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        count = self.n_trailers
        if isinstance(count, tuple) and not is_count_range(count):
            raise DocumentError(
                "'n_trailers' must be an integer or a pair [low, high] of integers with "
                f"low < high (a generalist), got {list(count)}"
            )
        if isinstance(count, int) and count < 0:
            raise DocumentError(f"'n_trailers' must be >= 0, got {count}")
        named = {field.name for field in dataclasses.fields(self)} - {"other"}
        clash = sorted(set(self.other) & named)
        if clash:
            raise DocumentError(f"'other' repeats the keyword {clash[0]!r}")

    @classmethod
    def _read(cls: type[RecordT], data: object, label: str, *, versioned: bool) -> RecordT:
        if isinstance(data, dict):
            named = {field.name for field in dataclasses.fields(cls)} - {"other"}
            other = {key: value for key, value in data.items() if key not in named}
            data = {key: value for key, value in data.items() if key in named}
            data["other"] = other
        return super()._read(data, label, versioned=versioned)

    def to_json(self) -> dict[str, object]:
        """The keywords as written (the other keywords beside the named ones)."""
        document = super().to_json()
        other = document.pop("other", {})
        assert isinstance(other, dict)
        return {**document, **other}

    def as_kwargs(self) -> dict[str, object]:
        """The keywords for ``gym.make`` (a range of counts as a list)."""
        return self.to_json()

    @property
    def is_range(self) -> bool:
        """Whether the run trained on a range of counts (a generalist)."""
        return isinstance(self.n_trailers, tuple)


@dataclasses.dataclass(frozen=True)
class Validation(SparsePart):
    """The model's validation metrics when it was kept: a learning-curve row (SB3 runs:
    ``timesteps``, ``wall_s`` and the curve's rates) or the whole metrics summary
    (imitation: :func:`trailer_env.benchmark.summarize`)."""

    timesteps: int | None = None
    wall_s: float | None = None
    episodes: int | None = None
    mean_return: float | None = None
    std_return: float | None = None
    mean_length: float | None = None
    jackknife_rate: float | None = None
    failure_rate: float | None = None
    safe_rate: float | None = None
    safe_rate_ci: tuple[float, float] | None = None
    band_time_fraction: float | None = None
    min_margin_mean: float | None = None
    min_margin_worst: float | None = None
    success_rate: float | None = None
    mean_abs_actuator_work: float | None = None
    iteration: int | None = None
    loss: float | None = None

    def rate(self, metric: str) -> float | None:
        """The rate ``metric`` (``safe_rate`` or ``success_rate``), None when not recorded."""
        if metric not in ("safe_rate", "success_rate"):
            raise ValueError(f"no rate {metric!r} (safe_rate, success_rate)")
        value = getattr(self, metric)
        return value if isinstance(value, float) else None


@dataclasses.dataclass(frozen=True)
class Imitation(SparsePart):
    """How an imitated model was fitted (``agents.imitate``'s settings)."""

    iterations: int
    episodes: int
    epochs: int
    batch_size: int
    learning_rate: float
    validation_episodes: int
    #: The student's hidden layers; None: the algorithm's default network.
    net_arch: tuple[int, ...] | None = None
    #: Fitted on each state and its mirror image: the model acts as the mean of its
    #: network and the network's mirror image.
    mirror: bool = False
    convoy_direction: str = "cart_first"

    ALWAYS: ClassVar[tuple[str, ...]] = ("net_arch",)


@dataclasses.dataclass(frozen=True)
class Planner(SparsePart):
    """The expert's settings (the fields of its config record: a sampling planner's,
    an iLQR's, or the expert policies' ``policy``); the ones an expert does not have are
    absent."""

    samples: int | None = None
    horizon: int | None = None
    tail: int | None = None
    iterations: int | None = None
    elites: int | None = None
    noise: float | None = None
    min_noise: float | None = None
    seed: int | None = None
    alphas: tuple[float, ...] | None = None
    reuse: bool | None = None
    jacobians: str | None = None
    central: bool | None = None
    state_step: float | None = None
    control_step: float | None = None
    regularization: float | None = None
    weights: Mapping[str, object] | None = None
    policy: str | None = None


@dataclasses.dataclass(frozen=True)
class Normalize(SparsePart):
    """Observation (and reward) normalisation of an SB3 model (``VecNormalize``)."""

    norm_obs: bool
    norm_reward: bool


@dataclasses.dataclass(frozen=True)
class Selection(SparsePart):
    """How the shipped model was chosen among its training seeds: the best headline rate
    on the selection episodes ``seeds`` (first, last)."""

    chosen_seed: int
    seeds: tuple[int, int]
    safe_rate_per_training_seed: Mapping[str, float] | None = None
    success_rate_per_training_seed: Mapping[str, float] | None = None

    @property
    def rates(self) -> Mapping[str, float]:
        """The headline rate of each training seed (its seed as a string)."""
        return self.safe_rate_per_training_seed or self.success_rate_per_training_seed or {}


@dataclasses.dataclass(frozen=True)
class Spaces(SparsePart):
    """The spaces an exported RLlib policy was trained with."""

    observation_shape: tuple[int, ...]
    action_shape: tuple[int, ...]
    action_low: tuple[float, ...]
    action_high: tuple[float, ...]


@dataclasses.dataclass(frozen=True)
class HostSpeed(SparsePart):
    """The speed of the machine a run trained on, measured by a short fixed benchmark
    (:mod:`agents.training.host_speed`) when the run (or its last resume) started: wall
    times of two runs compare only beside these."""

    #: The benchmark's name: two records compare only when it is the same.
    benchmark: str
    #: Environment steps per second of the benchmark's batch.
    env_steps_per_s: float
    #: Seconds of the benchmark's one PPO update.
    ppo_update_s: float
    cpus: int
    torch_threads: int
    #: The 1-minute load average when it ran (what ``uptime`` shows).
    load_average: float

    def __post_init__(self) -> None:
        for name in ("env_steps_per_s", "ppo_update_s"):
            value = getattr(self, name)
            if not files.is_number(value) or value <= 0:
                raise DocumentError(f"'{name}' must be a positive number, got {value}")
        if self.cpus < 1 or self.torch_threads < 1:
            raise DocumentError("'cpus' and 'torch_threads' must be at least 1")
        if not files.is_number(self.load_average) or self.load_average < 0:
            raise DocumentError(f"'load_average' must be >= 0, got {self.load_average}")

    def cell(self) -> str:
        """A table's cell: ``232k steps/s, update 0.81 s, load 1.6``."""
        return (
            f"{self.env_steps_per_s / 1000:.0f}k steps/s, update {self.ppo_update_s:.2f} s, "
            f"load {self.load_average:.1f}"
        )

    def summary(self) -> str:
        """One line: ``12,345 steps/s, PPO update 0.21 s (2 CPUs, load 1.5)``."""
        return (
            f"{self.env_steps_per_s:,.0f} steps/s, PPO update {self.ppo_update_s:.2f} s "
            f"({self.cpus} CPUs, load {self.load_average:.1f})"
        )


@dataclasses.dataclass(frozen=True)
class ModelCard(SparseRecord):
    """A model card or run record (see the module docstring)."""

    DOCUMENT: ClassVar[str] = "model card"
    ALWAYS: ClassVar[tuple[str, ...]] = (*RECORD_KEYS, "normalize")

    # What was trained, on what.
    algo: str | None = None
    env_id: str | None = None
    env_kwargs: EnvKwargs = dataclasses.field(default_factory=EnvKwargs)
    seed: int | None = None
    #: How the algorithm was set up: ``dagger`` (imitation), ``rl_from_reward`` ...
    recipe: str | None = None
    #: The expert an imitated model learnt from.
    expert: str | None = None
    policy: str | None = None
    #: The algorithm's own keywords (SB3's or RLlib's), as it was given them.
    hyperparams: Mapping[str, object] = dataclasses.field(default_factory=dict)
    normalize: Normalize | None = None
    command: tuple[str, ...] = ()
    budget: int | None = None
    n_envs: int | None = None
    backend: str | None = None
    # Training options.
    #: The training options the run was given (``TRAINING_OPTIONS``), each read from and
    #: written to its own keys by its record.
    options: tuple[TrainingOption, ...] = dataclasses.field(default=(), metadata=NOT_IN_JSON)
    forward_penalty: float | None = None
    imitation: Imitation | None = None
    planner: Planner | None = None
    training_seed: int | None = None
    # What the run reached.
    timesteps: int | None = None
    wall_time_s: float | None = None
    #: The machine's speed when the run (or its last resume) started.
    host: HostSpeed | None = None
    simulated_steps: int | None = None
    validation: Validation | None = None
    selected_at_timesteps: int | None = None
    selected_at_iteration: int | None = None
    stopped_on_plateau_at: int | None = None
    #: The iterations done before each resume of an imitation.
    resumed_at: tuple[int, ...] | None = None
    selection: Selection | None = None
    # An RLlib run's record and exported policy.
    num_env_runners: int | None = None
    envs_per_runner: int | None = None
    address: str | None = None
    #: What each runner stepped: (class name, native batch, Ray node id).
    runner_envs: tuple[object, ...] | None = None
    env_steps_per_s: float | None = None
    episode_return_mean: float | None = None
    module: str | None = None
    module_path: str | None = None
    inference_only: bool | None = None
    spaces: Spaces | None = None

    def __post_init__(self) -> None:
        if self.wall_time_s is not None and not files.is_number(self.wall_time_s):
            raise DocumentError(f"'wall_time_s' must be a finite number, got {self.wall_time_s}")

    @classmethod
    def _read(cls: type[RecordT], data: object, label: str, *, versioned: bool) -> RecordT:
        # The options' keys are read by their records, the rest field by field.
        if not isinstance(data, dict):
            return super()._read(data, label, versioned=versioned)
        keys = {key for option in TRAINING_OPTIONS for key in option.KEYS}
        try:
            options = recorded_options({key: data[key] for key in keys if key in data})
        except ValueError as error:
            raise DocumentError(f"{label}: {error}") from None
        rest = {key: value for key, value in data.items() if key not in keys}
        card = super()._read(rest, label, versioned=versioned)
        if not options:
            return card
        return cast(RecordT, dataclasses.replace(cast(ModelCard, card), options=options))

    def to_json(self) -> dict[str, object]:
        """The card as written: its fields, then each option's keys."""
        document = super().to_json()
        for option in self.options:
            document.update(option.record())
        return document

    def option(self, kind: type[OptionT]) -> OptionT | None:
        """The run's option of record ``kind`` (None: the run had none)."""
        found = [option for option in self.options if isinstance(option, kind)]
        return found[0] if found else None

    @property
    def empty(self) -> bool:
        """Whether this is the card of a model without one (every field at its default)."""
        return self == ModelCard()

    @property
    def mirrored(self) -> bool:
        """Whether the model was imitated with the mirror image (``imitate --mirror``): it
        acts as the mean of its network and the network's mirror image."""
        return self.imitation is not None and self.imitation.mirror

    @property
    def n_trailers(self) -> int | tuple[int, int] | None:
        """The count (or range of counts) the model was trained on."""
        return self.env_kwargs.n_trailers

    @property
    def rllib_hiddens(self) -> object:
        """An RLlib run's hidden layers (its ``hyperparams``' :data:`RLLIB_HIDDENS`, as
        written: checked by whoever builds the network), None when not recorded."""
        return self.hyperparams.get(RLLIB_HIDDENS)


def read_model_card(model_path: Path) -> ModelCard:
    """The model card of ``model_path``; an empty card (:attr:`ModelCard.empty`, every
    field at its default) when the model has none.

    Raises:
        ValueError: If the card is too large or deep, not a JSON object, or a field is
            unknown or of the wrong type (naming it).
    """
    path = card_path(model_path)
    if not path.is_file():
        return ModelCard()
    return ModelCard.from_json(files.read_json(path, "model card", allow_nan=True), str(path))


def card_of(document: Mapping[str, object], where: str) -> ModelCard:
    """The card that ``document`` (a card or run record being built: tuples as JSON
    lists) holds.

    Raises:
        DocumentError: Naming ``where`` and the first field that is wrong.
    """
    return ModelCard.from_json(json.loads(json.dumps(dict(document))), where)


def write_card(model_path: Path, card: ModelCard) -> Path:
    """Write the model card (JSON beside the model) that :func:`read_model_card` reads.

    Raises:
        TypeError: If ``card`` is not a :class:`ModelCard`.
    """
    if not isinstance(card, ModelCard):
        raise TypeError(f"write_card takes a ModelCard, got {type(card).__name__}")
    return files.write_json(card_path(model_path), card.to_json())
