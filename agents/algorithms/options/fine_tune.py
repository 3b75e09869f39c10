"""``--init-from MODEL [--critic-warmup STEPS]``: fine-tune, starting from another model's
policy."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import ClassVar

import torch
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.policies import ActorCriticPolicy

from agents.algorithms import algorithm
from agents.algorithms.options.base import (
    Flag,
    OptionError,
    RunFacts,
    TrainingOption,
    recorded_int,
)

#: The largest warm-up (the largest training budget).
MAX_WARMUP = 2**31


@dataclass(frozen=True)
class FineTune(TrainingOption):
    """A fine-tuning run: its policy starts as ``init_from``'s (its weights and frozen
    observation statistics), under the run's own hyperparameters; on-policy algorithms
    only.

    Attributes:
        init_from: The starting model's path (e.g. an imitation agent).
        critic_warmup: Steps at the start that train the value function alone
            (:class:`CriticWarmup`), under the run's budget.
    """

    KEYS: ClassVar[tuple[str, ...]] = ("init_from", "critic_warmup")
    FLAGS: ClassVar[tuple[Flag, ...]] = (
        Flag(
            "--init-from",
            "path",
            "MODEL",
            "fine-tune: start a new run from this model's policy (e.g. an imitation "
            "agent), its observation statistics frozen; with --resume, the run's own",
        ),
        Flag(
            "--critic-warmup",
            "count",
            "STEPS",
            "with --init-from (ppo, ppo_lag): train the value function alone for this "
            "many steps before the policy moves (default 0)",
            high=MAX_WARMUP,
            default=0,
        ),
    )

    init_from: str
    critic_warmup: int = 0

    def __post_init__(self) -> None:
        if self.critic_warmup < 0:
            raise OptionError(
                "--critic-warmup", f"critic_warmup must be >= 0, got {self.critic_warmup}"
            )

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> FineTune | None:
        if args.init_from is None:
            if args.critic_warmup:
                raise OptionError("--critic-warmup", "only with --init-from")
            return None
        return cls(str(args.init_from), args.critic_warmup)

    @classmethod
    def from_record(cls, record: Mapping[str, object]) -> FineTune | None:
        source = record.get("init_from")
        if source is None:
            return None
        if not isinstance(source, str):
            raise ValueError(f"init_from must be a path, got {source!r:.40}")
        return cls(source, recorded_int(record.get("critic_warmup", 0), "critic_warmup"))

    @property
    def source(self) -> Path:
        """The starting model's file."""
        return Path(self.init_from)

    def check_command(self, env_id: str, algo: str, backend: str) -> None:
        super().check_command(env_id, algo, backend)
        if algorithm(algo).off_policy:
            # Only the policy's weights would carry over: the replay buffer and SAC's
            # entropy coefficient would restart, and learning_starts steps would act at
            # random.
            raise OptionError("--init-from", f"{algo} is off-policy; only on-policy runs fine-tune")

    def check(self, run: RunFacts) -> None:
        super().check(run)
        if self.critic_warmup >= run.budget:
            raise OptionError(
                "--critic-warmup",
                f"critic_warmup ({self.critic_warmup}) must be under the budget ({run.budget})",
            )

    def record(self) -> dict[str, object]:
        return {"init_from": self.init_from, "critic_warmup": self.critic_warmup}

    def tag(self) -> str:
        return f" from {PurePath(self.init_from).stem}"

    def flags_text(self) -> str:
        return f"--init-from {self.init_from} --critic-warmup {self.critic_warmup}"

    def same_run(self, other: TrainingOption) -> bool:
        return (
            isinstance(other, FineTune)
            and self.source.resolve() == other.source.resolve()
            and self.critic_warmup == other.critic_warmup
        )

    def callbacks(self) -> list[BaseCallback]:
        return [CriticWarmup(self.critic_warmup)] if self.critic_warmup else []


class CriticWarmup(BaseCallback):
    """Train the value function alone for the first ``steps`` steps of a fine-tuning run.

    A policy taken from elsewhere (imitation) comes with a value function that knows
    nothing of it; PPO's first updates would follow advantages from that untrained
    critic and can undo the policy. So every parameter the policy's actions depend on
    (its features extractor when shared, its hidden layers, its action head and log
    standard deviation) is frozen until ``steps``, then released. Frozen parameters get
    no gradient, so the optimiser leaves them (and its moments for them) untouched.
    """

    def __init__(self, steps: int) -> None:
        super().__init__(0)
        self.steps = int(steps)
        self.frozen: list[torch.nn.Parameter] = []

    def _on_training_start(self) -> None:
        if self.num_timesteps >= self.steps:
            return
        policy = self.model.policy
        assert isinstance(policy, ActorCriticPolicy)  # on-policy algorithms only
        modules = [policy.mlp_extractor.policy_net, policy.action_net]
        shared = policy.share_features_extractor
        modules.append(policy.features_extractor if shared else policy.pi_features_extractor)
        self.frozen = [p for module in modules for p in module.parameters() if p.requires_grad]
        log_std = getattr(policy, "log_std", None)
        if isinstance(log_std, torch.nn.Parameter) and log_std.requires_grad:
            self.frozen.append(log_std)
        for parameter in self.frozen:
            parameter.requires_grad_(False)

    def _on_rollout_start(self) -> None:
        if self.frozen and self.num_timesteps >= self.steps:
            for parameter in self.frozen:
                parameter.requires_grad_(True)
            self.frozen = []

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        # The saved model is left trainable, whatever step the run stopped at.
        for parameter in self.frozen:
            parameter.requires_grad_(True)
        self.frozen = []
