"""``--start-curriculum FROM,STEPS``: grow the training starts to the scene's own."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from stable_baselines3.common.callbacks import BaseCallback

from agents.algorithms.options.base import (
    Flag,
    OptionError,
    StartScalable,
    TrainingOption,
    recorded_int,
    recorded_number,
    recorded_part,
)


@dataclass(frozen=True)
class StartCurriculum(TrainingOption):
    """A start curriculum: the training starts' perturbation grows linearly from ``low``
    times the scene's size to its own over the first ``steps`` steps (sb3; scenes whose
    core is ``start_scalable``); the evaluations keep the scene's starts.

    Attributes:
        low: The first starts' scale, in (0, 1).
        steps: The steps over which the scale reaches 1 (>= 1).
    """

    KEYS: ClassVar[tuple[str, ...]] = ("start_curriculum",)
    FLAGS: ClassVar[tuple[Flag, ...]] = (
        Flag(
            "--start-curriculum",
            "schedule",
            "FROM,STEPS",
            "grow the training starts' perturbation linearly from FROM (in (0, 1)) times "
            "the scene's size to its own over the first STEPS steps (Reverse-v1; sb3 only); "
            "evaluations use the scene's starts",
        ),
    )

    low: float
    steps: int

    def __post_init__(self) -> None:
        if not 0.0 < self.low < 1.0 or self.steps < 1:
            raise OptionError(
                self.flag(),
                "start_curriculum must be (low, steps) with 0 < low < 1 and steps >= 1; "
                f"got {(self.low, self.steps)}",
            )

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> StartCurriculum | None:
        if args.start_curriculum is None:
            return None
        low, steps = args.start_curriculum
        return cls(low, steps)

    @classmethod
    def from_record(cls, record: Mapping[str, object]) -> StartCurriculum | None:
        value = recorded_part(record, "start_curriculum", ("from", "steps"))
        if value is None:
            return None
        return cls(
            recorded_number(value.get("from"), "start_curriculum.from"),
            recorded_int(value.get("steps"), "start_curriculum.steps"),
        )

    def check_command(self, env_id: str, algo: str, backend: str) -> None:
        from trailer_env.registry import core_class_of

        super().check_command(env_id, algo, backend)
        if not core_class_of(env_id).start_scalable:
            raise OptionError(
                self.flag(),
                f"{env_id}'s starts have no perturbation size to scale (Reverse-v1's have)",
            )

    def record(self) -> dict[str, object]:
        return {"start_curriculum": {"from": self.low, "steps": self.steps}}

    def tag(self) -> str:
        return " + start curriculum"

    def flags_text(self) -> str:
        return f"--start-curriculum {self.low},{self.steps}"

    def prepare(self, venv: StartScalable, *, seed: int, start_steps: int) -> None:
        venv.unwrapped.set_start_scale(self.scale_at(start_steps))  # type: ignore[attr-defined]

    def callbacks(self) -> list[BaseCallback]:
        return [CurriculumSchedule(self)]

    def scale_at(self, timesteps: int) -> float:
        """The perturbation's scale after ``timesteps`` steps."""
        return self.low + (1.0 - self.low) * min(1.0, timesteps / self.steps)


class CurriculumSchedule(BaseCallback):
    """Before each rollout, set the training environment's starting perturbation to
    :meth:`StartCurriculum.scale_at` the run's step count (``set_start_scale`` of
    :class:`trailer_env.sb3.ConvoySB3VecEnv`), so a resumed run picks up the schedule
    where it was. Episodes running when the scale changes keep their start; the
    evaluation environment is not touched, so the learning curve scores the scene's own
    starts throughout (the first rollout's scale is set by :meth:`StartCurriculum.prepare`:
    SB3 resets the environment before any callback runs).
    """

    def __init__(self, curriculum: StartCurriculum) -> None:
        super().__init__(0)
        self.curriculum = curriculum
        #: The scale the training starts were last drawn at (None before training).
        self.scale: float | None = None

    def _on_rollout_start(self) -> None:
        scale = self.curriculum.scale_at(self.num_timesteps)
        if scale != self.scale:
            self.model.get_env().unwrapped.set_start_scale(scale)  # type: ignore[union-attr]
            self.scale = scale

    def _on_step(self) -> bool:
        return True
