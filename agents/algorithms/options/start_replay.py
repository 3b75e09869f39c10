"""``--start-replay SHARE [--start-replay-max K]``: begin a share of the training episodes
from starts whose episodes failed before (:class:`trailer_env.start_replay.StartReplay`)."""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from stable_baselines3.common.callbacks import BaseCallback

from agents.algorithms.options.base import (
    Flag,
    OptionError,
    RunFacts,
    StartScalable,
    TrainingOption,
    recorded_int,
    recorded_number,
    recorded_part,
)


@dataclass(frozen=True)
class StartReplay(TrainingOption):
    """Start replay: ``fraction`` in (0, 1) of the training episodes begin from starts that
    failed before, with the physics drawn for them under ``--randomize``, seeded with the
    run's seed (sb3, one count of trailers); the evaluations keep the scene's starts. Its
    buffer is not checkpointed: a resumed run starts with an empty one.

    Attributes:
        fraction: The share of episodes begun from the buffer.
        max_replays: The failed replays after which a start leaves the buffer
            (``StartReplay``'s ``max_replays``); None: no limit.
    """

    KEYS: ClassVar[tuple[str, ...]] = ("start_replay",)
    FLAGS: ClassVar[tuple[Flag, ...]] = (
        Flag(
            "--start-replay",
            "share",
            "SHARE",
            "begin this share (in (0, 1)) of the training episodes from starts whose "
            "episodes failed before, with their drawn physics under --randomize "
            "(trailer_env.start_replay; sb3, one count of trailers); evaluations use the "
            "scene's starts",
        ),
        Flag(
            "--start-replay-max",
            "count",
            "K",
            "with --start-replay: a start leaves the buffer once K of its replays failed "
            "(default: it returns after every failure)",
            low=1,
        ),
    )

    fraction: float
    max_replays: int | None = None

    def __post_init__(self) -> None:
        if not 0.0 < self.fraction < 1.0:
            raise OptionError(
                "--start-replay", f"start_replay must be a share in (0, 1), got {self.fraction}"
            )
        if self.max_replays is not None and self.max_replays < 1:
            raise OptionError(
                "--start-replay-max",
                f"start_replay_max must be >= 1 and needs start_replay, got {self.max_replays}",
            )

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> StartReplay | None:
        if args.start_replay is None:
            if args.start_replay_max is not None:
                raise OptionError(
                    "--start-replay-max",
                    f"start_replay_max must be >= 1 and needs start_replay, got "
                    f"{args.start_replay_max}",
                )
            return None
        return cls(args.start_replay, args.start_replay_max)

    @classmethod
    def from_record(cls, record: Mapping[str, object]) -> StartReplay | None:
        value = recorded_part(record, "start_replay", ("fraction", "max_replays"))
        if value is None:
            return None
        limit = value.get("max_replays")
        return cls(
            recorded_number(value.get("fraction"), "start_replay.fraction"),
            None if limit is None else recorded_int(limit, "start_replay.max_replays"),
        )

    def check(self, run: RunFacts) -> None:
        super().check(run)
        if isinstance(run.n_trailers, tuple):
            raise OptionError(
                "--start-replay",
                "start_replay must be a share in (0, 1), on the sb3 backend, with one count "
                f"of trailers; got {self.fraction} on {run.backend}",
            )

    def record(self) -> dict[str, object]:
        limit = {} if self.max_replays is None else {"max_replays": self.max_replays}
        return {"start_replay": {"fraction": self.fraction, **limit}}

    def tag(self) -> str:
        limit = "" if self.max_replays is None else f" (max {self.max_replays})"
        return f" + start replay {self.fraction}{limit}"

    def flags_text(self) -> str:
        limit = "" if self.max_replays is None else f" --start-replay-max {self.max_replays}"
        return f"--start-replay {self.fraction}{limit}"

    def prepare(self, venv: StartScalable, *, seed: int, start_steps: int) -> None:
        from trailer_env.start_replay import StartReplay as Buffer

        replay = Buffer(self.fraction, seed=seed, max_replays=self.max_replays)
        venv.unwrapped.set_start_replay(replay)  # type: ignore[attr-defined]

    def callbacks(self) -> list[BaseCallback]:
        return [StartReplayStats()]


class StartReplayStats(BaseCallback):
    """Log the training environment's start replay after each rollout:
    ``start_replay/buffer`` (failed starts kept), ``start_replay/episodes`` (episodes
    begun from the buffer so far) and ``start_replay/success_rate`` (the share of those
    that succeeded)."""

    def _on_rollout_end(self) -> None:
        replay = self.model.get_env().unwrapped.start_replay  # type: ignore[union-attr]
        self.logger.record("start_replay/buffer", replay.size)
        self.logger.record("start_replay/episodes", replay.replayed)
        if replay.replayed:
            self.logger.record(
                "start_replay/success_rate", replay.replayed_successes / replay.replayed
            )

    def _on_step(self) -> bool:
        return True
