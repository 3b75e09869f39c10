"""Periodic safety evaluation during training: a CSV learning curve and the best model.

Every ``eval_freq`` environment steps :class:`SafetyEvalCallback` plays
``episodes`` seeded episodes of the deterministic policy in one native batch
(:func:`agents.evaluation.metrics.rollout`), appends a row to ``<run>/evaluations.csv``, logs
the numbers (``eval/...``, TensorBoard when installed) and keeps the best model so
far in ``<run>/best_model.zip``. Validation seeds are disjoint from the test seeds
used by :mod:`agents.commands.evaluate` (see :data:`VALIDATION_SEED`), so choosing the best
model does not peek at the reported numbers.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.type_aliases import TrainFreq

from agents.artifacts import files
from agents.artifacts.cards import ModelCard, read_model_card, write_card
from agents.artifacts.curves import CURVE_COLUMNS, append_rows, keep_rows, write_curve
from agents.artifacts.paths import card_path, stats_path
from agents.artifacts.run_folder import BEST_MODEL, CURVE_FILE
from agents.artifacts.sb3_zip import save_model
from agents.artifacts.stats import save_stats
from agents.envs import headline_metric
from agents.evaluation.learning_curves import is_flat, trend
from agents.evaluation.metrics import Summary, rollout, summarize
from agents.policies.sb3 import ModelPolicy
from agents.progress import Progress
from agents.seeds import VALIDATION_SEED

#: Called after each evaluation with (steps, summary); returns True to stop the run. The
#: summary is the evaluation's, with ``wall_s``: the run's training seconds so far.
EvaluationHook = Callable[[int, Mapping[str, object]], bool]


class PlateauStop:
    """An :data:`EvaluationHook` that stops a run once its headline rate is flat: the last
    ``window`` evaluations within ``eps`` of their mean (the rule of
    :mod:`agents.evaluation.learning_curves`), the evaluations before a resume included.

    A window whose mean is within ``eps`` of the run's first evaluation is not a plateau:
    a run that has not left its starting level (PPO on Reverse sits at 0 for its first
    1.5-4M steps) has not started learning, and stops only at its budget. Nor is a window
    whose curve still rises by :func:`~agents.evaluation.learning_curves.trend` (the line
    through the last third of the steps climbs by more than its error times Student's t):
    five noisy evaluations within 0.05 of each other at 0.9 can sit on a climb, and a run
    stopped there would be flagged "rising" by the tables that report it.

    Args:
        metric: The rate (a key of the summaries), e.g. "safe_rate".
        window, eps: The rule.
        previous: The (steps, rate) of the evaluations before the resume (a resumed run).
    """

    def __init__(
        self,
        metric: str,
        window: int,
        eps: float,
        previous: Sequence[tuple[float, float]] = (),
    ) -> None:
        self.metric, self.window, self.eps = metric, window, eps
        self.steps = [int(steps) for steps, _ in previous]
        self.values = [float(value) for _, value in previous]
        #: The step at which the plateau was detected, once it was.
        self.stopped_at: int | None = None

    def __call__(self, steps: int, summary: Mapping[str, object]) -> bool:
        value = summary[self.metric]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"the summary's {self.metric} is no number: {value!r:.40}")
        self.steps.append(int(steps))
        self.values.append(float(value))
        if self.stopped_at is None and self._settled():
            self.stopped_at = steps
        return self.stopped_at is not None

    def _settled(self) -> bool:
        if not is_flat(self.values, self.window, self.eps):
            return False
        level = sum(self.values[-self.window :]) / self.window
        if abs(level - self.values[0]) <= self.eps:
            return False
        end = trend(self.steps, self.values)
        return end is None or not end.rising


#: The columns of a learning curve's steps and training seconds.
STEPS, WALL = CURVE_COLUMNS[:2]

#: The rates an evaluation is ranked by, in order (:func:`score`).
SCORED = ("safe_rate", "success_rate", "mean_return")


def score(summary: Mapping[str, float] | Summary) -> tuple[float, float, float]:
    """Ranking of an evaluation (a summary, or a row of a learning curve): safe rate,
    then success rate, then mean return."""
    if isinstance(summary, Summary):
        return summary.safe_rate, summary.success_rate, summary.mean_return
    safe, success, mean = (summary[key] for key in SCORED)
    return safe, success, mean


class StatsCheckpointCallback(CheckpointCallback):
    """SB3's ``CheckpointCallback`` with the observation statistics saved as JSON.

    SB3 pickles them (``save_vecnormalize``); this writes
    ``<prefix>_vecnormalize_<k>_steps.json`` beside each ``<prefix>_<k>_steps.zip``
    instead (:func:`agents.artifacts.stats.save_stats`). The replay buffer of SAC/TD3
    (``save_replay_buffer``) stays SB3's pickle: resuming from it needs ``--trust-pickle``.

    Each file is written atomically, the zip last: a checkpoint zip that can be seen
    has its statistics (and buffer) beside it.
    """

    def __init__(
        self, save_freq: int, save_path: str, name_prefix: str, save_replay_buffer: bool
    ) -> None:
        super().__init__(
            save_freq=save_freq,
            save_path=save_path,
            name_prefix=name_prefix,
            save_replay_buffer=save_replay_buffer,
            save_vecnormalize=False,
        )

    def _on_step(self) -> bool:
        if self.n_calls % self.save_freq != 0:
            return True
        model_path = Path(self._checkpoint_path(extension="zip"))
        stats = self.model.get_vec_normalize_env()
        if stats is not None:
            save_stats(stats, stats_path(model_path))
        buffer = getattr(self.model, "replay_buffer", None)
        if self.save_replay_buffer and buffer is not None:
            data = io.BytesIO()
            self.model.save_replay_buffer(data)  # type: ignore[attr-defined]
            files.atomic_write_bytes(
                Path(self._checkpoint_path("replay_buffer_", extension="pkl")), data.getvalue()
            )
        save_model(self.model, model_path)
        return True


class SafetyEvalCallback(BaseCallback):
    """Evaluate the policy every ``eval_freq`` steps on seeded episodes; keep the best model.

    Args:
        env_id: Environment of the evaluation.
        env_kwargs: Its keyword arguments (``n_trailers`` ...).
        run_dir: Where ``evaluations.csv`` and ``best_model.zip`` go.
        eval_freq: Environment steps between evaluations (>= 1).
        episodes: Episodes per evaluation.
        seed: Episode ``i`` is seeded ``seed + i``.
        resume_from: The step count of the checkpoint a resumed run starts from: rows of
            ``evaluations.csv`` after it belong to the abandoned continuation and are
            dropped, and so is a best model selected after it.
        verbose: 1 prints one line per evaluation.
        hooks: Called after each evaluation (:data:`EvaluationHook`); the run stops at
            its next step once one returns True (a plateau, a pruned trial).
        record: The run's record (:meth:`agents.training.config.TrainConfig.document`),
            the base of the best model's card from its first save, so that the model loads
            and evaluates (its env, n, algorithm) while the run is still going.
    """

    def __init__(
        self,
        env_id: str,
        env_kwargs: Mapping[str, object],
        run_dir: Path,
        eval_freq: int,
        episodes: int = 50,
        seed: int = VALIDATION_SEED,
        resume_from: int | None = None,
        verbose: int = 1,
        hooks: Sequence[EvaluationHook] = (),
        record: Mapping[str, object] | None = None,
    ) -> None:
        super().__init__(verbose)
        self.hooks = list(hooks)
        self.record = dict(record or {})
        #: Set once a hook asked the run to stop.
        self.stop_requested = False
        self.env_id = env_id
        self.env_kwargs = env_kwargs
        self.run_dir = run_dir
        self.eval_freq = max(1, int(eval_freq))
        self.episodes = episodes
        self.seed = seed
        self.curve_path = run_dir / CURVE_FILE
        self.best_path = run_dir / BEST_MODEL
        previous: list[dict[str, float]] = []
        if resume_from is not None:
            # The kept rows stay as they were written; the later ones go.
            previous = keep_rows(
                self.curve_path, lambda row: row[STEPS] <= resume_from, CURVE_COLUMNS
            )
            selected = read_model_card(self.best_path).selected_at_timesteps
            if selected is None or selected > resume_from:
                for path in (self.best_path, card_path(self.best_path), stats_path(self.best_path)):
                    path.unlink(missing_ok=True)
        self.wall_offset = previous[-1][WALL] if previous else 0.0
        self.best: tuple[float, float, float] | None = None
        if previous and self.best_path.is_file():
            self.best = max(score(row) for row in previous)
        self._evaluated_at = {int(row[STEPS]) for row in previous}
        self._next_eval = 0
        self._start = time.perf_counter()
        #: The rows evaluated before the resume (a resumed run), as kept.
        self.previous_rows = previous

    @property
    def metric(self) -> str:
        """The scene's headline rate."""
        return headline_metric(self.env_id)

    def _on_training_start(self) -> None:
        self._start = time.perf_counter()
        steps = self.num_timesteps
        self._next_eval = (steps // self.eval_freq + 1) * self.eval_freq
        if steps not in self._evaluated_at:
            self.evaluate()

    def _on_rollout_start(self) -> None:
        # The policy changes only between rollouts (after each PPO update, after each
        # SAC step), so evaluations happen here and never twice for the same weights.
        if self.num_timesteps >= self._next_eval:
            self._next_eval = (self.num_timesteps // self.eval_freq + 1) * self.eval_freq
            self.evaluate()

    def _on_step(self) -> bool:
        return not self.stop_requested

    def _on_training_end(self) -> None:
        # A stopped run's policy is the one evaluated last: no second row for it.
        if self.num_timesteps not in self._evaluated_at and not self.stop_requested:
            self.evaluate()

    def _write_rows(self, rows: list[dict[str, float]], append: bool = False) -> None:
        """Write (atomically) or append rows of evaluations.csv (header when it starts)."""
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if append:
            append_rows(self.curve_path, rows, CURVE_COLUMNS)
        else:
            write_curve(self.curve_path, rows, CURVE_COLUMNS)

    @property
    def wall_seconds(self) -> float:
        """Training wall time of the run so far, the time before a resume included."""
        return self.wall_offset + time.perf_counter() - self._start

    def evaluate(self) -> dict[str, object]:
        """Run one evaluation now; returns its summary."""
        stats = self.model.get_vec_normalize_env()
        results = rollout(
            ModelPolicy(self.model, stats), self.env_id, self.episodes, self.seed, self.env_kwargs
        )
        summary = summarize(results)
        typed = Summary.from_json(summary, "of the evaluation")
        steps = int(self.num_timesteps)
        row: dict[str, float] = {"timesteps": steps, "wall_s": round(self.wall_seconds, 2)}
        row.update({key: summary[key] for key in CURVE_COLUMNS[2:]})
        self._write_rows([row], append=True)
        self._evaluated_at.add(steps)
        for key in CURVE_COLUMNS[2:]:
            self.logger.record(f"eval/{key}", row[key])
        self.logger.dump(steps)
        if self.best is None or score(typed) > self.best:
            self.best = score(typed)
            if stats is not None:
                save_stats(stats, stats_path(self.best_path))
            save_model(self.model, self.best_path)
            selected = {**self.record, "selected_at_timesteps": steps, "validation": row}
            write_card(self.best_path, ModelCard.from_json(selected, str(self.best_path)))
        if self.verbose:
            print(
                f"[eval] {steps:>9d} steps  return {typed.mean_return:8.1f}  "
                f"safe {typed.safe_rate:.2f}  success {typed.success_rate:.2f}  "
                f"jackknife {typed.jackknife_rate:.2f}  "
                f"band {typed.band_time_fraction:.3f}  ({row['wall_s']:.0f} s)",
                flush=True,
            )
        seen = {**summary, WALL: row[WALL]}
        for hook in self.hooks:
            self.stop_requested = hook(steps, seen) or self.stop_requested
        return summary


class ProgressCallback(BaseCallback):
    """Training progress (:class:`agents.progress.Progress`) that ends at the real total.

    SB3 runs whole rollouts: PPO collects ``n_steps * n_envs`` steps at a time, so a
    budget that is not a multiple ends above it (SB3's own bar then reads, say,
    114,688/100,000). The total here is the count the run will actually reach.
    """

    def __init__(self, label: str) -> None:
        super().__init__()
        self.label = label
        self.bar: Progress | None = None

    def _on_training_start(self) -> None:
        model = self.model
        start = int(model.num_timesteps)
        remaining = int(self.locals["total_timesteps"]) - start
        n_envs = int(model.n_envs)
        if isinstance(model, OnPolicyAlgorithm):  # whole rollouts
            chunk = int(model.n_steps) * n_envs
        else:  # off-policy: train_freq steps of every env per collection
            assert isinstance(model, OffPolicyAlgorithm)
            frequency = model.train_freq
            assert isinstance(frequency, TrainFreq)
            steps = frequency.frequency if str(frequency.unit).endswith("STEP") else 1
            chunk = int(steps) * n_envs
        total = -(-max(remaining, 0) // chunk) * chunk
        self.bar = Progress(total, self.label).__enter__()

    def _on_step(self) -> bool:
        assert self.bar is not None
        self.bar.advance(f"{self.model.num_timesteps:,} steps", int(self.model.n_envs))
        return True

    def _on_training_end(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
