"""What a DAgger run trains (:class:`ImitationConfig`), checked whole before a run starts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from agents.artifacts import limits
from agents.envs import check_env_id, settings_by_count
from agents.policies.convoy_order import CONVOY_DIRECTIONS, check_direction
from agents.policies.experts import EXPERTS, ExpertConfig, PolicyExpertConfig, default_expert
from agents.policies.sb3 import ModelPolicy, TrailersPolicy
from agents.seeds import SELECTION_SEED, TRAINING_SEED, VALIDATION_SEED
from dynamics.params import bounded_integer
from trailer_env.mixed import is_trailer_range, trailer_range
from trailer_env.observation import checked_observation, trailers_observation
from trailer_env.randomize import PRESETS, Randomization
from trailer_env.settings import MAX_HISTORY

#: Validation episodes take seeds from VALIDATION_SEED up to the selection seeds.
MAX_VALIDATION_EPISODES = SELECTION_SEED - VALIDATION_SEED

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.vec_env import VecNormalize

    from trailer_env.settings import EnvSettings


@dataclass(frozen=True)
class ImitationConfig:
    """What :func:`imitate` trains.

    Attributes:
        env_id: The scene (one that an expert of
            :data:`agents.policies.experts.EXPERTS` fits).
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
        validation_episodes: Episodes of each validation (seeds from VALIDATION_SEED, at
            most MAX_VALIDATION_EPISODES so that they stay clear of the selection seeds);
            the iteration kept ranks first on them (safe rate, then success rate, then
            mean return).
        expert: The expert's name in :data:`agents.policies.experts.EXPERTS`; None: the
            scene's default (:func:`agents.policies.experts.default_expert`: ``mpc`` on
            Reverse, ``ilqr`` on Dock and Coast).
        planner: The expert's settings, of its ``config_class`` (``PlannerConfig`` for
            ``mpc``, whose seed is replaced by ``seed``; ``ILQRConfig`` for ``ilqr``;
            :class:`~agents.policies.experts.PolicyExpertConfig` for ``specialists``);
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
        history: Past frames (observation, applied action) the student reads beside the
            current observation (the env's ``history=``, :mod:`trailer_env.history`): a
            memory from which it can tell the convoy's parameters under ``randomize``;
            0 (default) none. Needs ``observation="flat"``.
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
    planner: ExpertConfig | None = None
    randomize: str | dict[str, object] | None = None
    expert: str | None = None
    observation: str = "flat"
    max_trailers: int | None = None
    mirror: bool = False
    convoy_direction: str = "cart_first"
    history: int = 0

    def __post_init__(self) -> None:
        check_env_id(self.env_id)
        history = bounded_integer("history", self.history, 0, MAX_HISTORY)
        if history and self.observation != "flat":
            raise ValueError(f"history = {history} needs observation='flat' (the flat student)")
        object.__setattr__(self, "history", history)
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
        if self.validation_episodes > MAX_VALIDATION_EPISODES:
            raise ValueError(
                f"validation_episodes must be <= {MAX_VALIDATION_EPISODES} (the validation "
                f"seeds end where the selection seeds begin), got {self.validation_episodes}"
            )
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
        elif self.expert not in EXPERTS:
            raise ValueError(f"expert: unknown {self.expert!r}; experts: {sorted(EXPERTS)}")
        expert = EXPERTS[str(self.expert)]
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
        if isinstance(self.planner, PolicyExpertConfig):  # the policies load, before a run
            problem = self.planner.problem(self.env_id, sorted(self.settings_by_count()))
            if problem is not None:
                raise ValueError(problem)

    @property
    def expert_config(self) -> ExpertConfig:
        """The expert's settings (resolved: never None after construction)."""
        if self.planner is None:  # pragma: no cover - __post_init__ sets it
            raise RuntimeError("ImitationConfig was not validated")
        return self.planner

    @property
    def env_kwargs(self) -> dict[str, object]:
        """The labelling and validation envs' keywords: the counts, the physics and the
        student's memory."""
        kwargs: dict[str, object] = {"n_trailers": self.n_trailers}
        if self.randomize is not None:
            kwargs["randomize"] = self.randomize
        if self.history:
            kwargs["history"] = self.history
        return kwargs

    @property
    def top_trailers(self) -> int:
        """The largest n of the episodes (the padded layout's with a range)."""
        return self.n_trailers[1] if isinstance(self.n_trailers, tuple) else self.n_trailers

    @property
    def student_kwargs(self) -> dict[str, object]:
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

    def settings_by_count(self) -> dict[int, EnvSettings]:
        """The env settings of each count (one entry for one n)."""
        return settings_by_count(self.env_kwargs)
