"""Imitate the planner (DAgger) into a stable-baselines3 PPO policy.

Usage::

    python -m agents.imitate --env trailer_env/Reverse-v1 --n-trailers 2 --seed 0 \
        [--expert {mpc,ilqr,specialists}] [--iterations 6] [--episodes 256] [--run-dir DIR] \
        [--export PATH] [--overwrite]

The expert is a record of :data:`agents.policies.experts.EXPERTS`: ``mpc``, the
sampling planner (the Reverse scenes' default), ``ilqr``, the deterministic iLQR planner
(Reverse, and the default on Dock and Coast; one n, nominal physics), which labels a
state with the same action whatever was labelled before, or ``specialists``, trained
policies, one per n, each labelling the rows of its own count (policy distillation).

A generalist: ``--n-trailers 1-3 --randomize mismatch20`` (the env draws each
episode's n and physics; the expert, :class:`agents.oracles.labellers.PrivilegedExpert`,
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
:data:`agents.training.dagger.OBS_VAR_FLOOR`) and saved as JSON, so the
model loads, evaluates and fine-tunes (``agents.train --resume``) like any PPO model.
The run folder gets ``config.json``, ``evaluations.csv`` (one row per iteration;
``timesteps`` counts labelled steps), ``best_model.zip`` and ``final_model.zip`` with
their cards and statistics. After every iteration it also gets a checkpoint
(``checkpoint.json``, the aggregated ``dataset.npz`` and the final model so far):
``--resume`` continues a run cut short, or one asked for more ``--iterations``, with the
same data, weights and random streams, so that it ends as an uninterrupted run would.
A resume first reads back and checks every file it needs
(:func:`agents.training.imitation_checkpoint.read_saved_run`): a damaged one, or a run
configured otherwise, is refused
(:class:`~agents.training.imitation_checkpoint.CheckpointError`, naming
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

import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, is_dataclass
from pathlib import Path

import numpy as np

from agents.artifacts.cards import ModelCard, card_of, read_model_card, write_card
from agents.artifacts.curves import append_rows, write_curve
from agents.artifacts.paths import stats_path
from agents.artifacts.run_folder import BEST_MODEL, CURVE_FILE, FINAL_MODEL, write_config
from agents.artifacts.sb3_zip import save_model
from agents.artifacts.stats import save_stats
from agents.evaluation.metrics import Summary, rollout, summarize
from agents.policies.experts import EXPERTS
from agents.policies.mirror import MirroredPolicy
from agents.progress import Progress
from agents.seeds import TRAINING_SEED, VALIDATION_SEED
from agents.training.callbacks import score
from agents.training.dagger import Driver, build_student, collect, fit, freeze_statistics
from agents.training.host_speed import measure_host_speed
from agents.training.imitation_checkpoint import (
    CURVE_FIELDS,
    RunState,
    restore,
    write_checkpoint,
)
from agents.training.imitation_config import ImitationConfig
from trailer_env.registry import core_class_of
from trailer_env.vector import ConvoyVectorEnv

#: The settings of the run that its record keeps apart from ``imitation`` (or not at all).
_OWN_KEYS = (
    "env_id",
    "n_trailers",
    "seed",
    "planner",
    "randomize",
    "expert",
    "observation",
    "max_trailers",
    "history",
)


def _settings(config: object) -> dict[str, object]:
    """An expert's settings as the record keeps them (its dataclass's fields)."""
    if not is_dataclass(config) or isinstance(config, type):
        raise TypeError(f"an expert's settings are a dataclass, got {type(config).__name__}")
    return asdict(config)


def _card(document: dict[str, object]) -> ModelCard:
    """A card of the run (``document`` as JSON holds it: tuples as lists)."""
    return card_of(document, "of the imitation run")


def imitate(
    config: ImitationConfig,
    run_dir: Path,
    verbose: int = 1,
    resume: bool = False,
    command: Sequence[str] | None = None,
) -> dict[str, object]:
    """Run DAgger (see the module); returns the run's record (also its ``config.json``).

    ``command`` is what the record says started the run (default: this process's
    ``python -m agents.imitate`` arguments).

    After every iteration the run folder gets a checkpoint
    (:data:`~agents.training.imitation_checkpoint.CHECKPOINT_FILE`, the data set, the final
    model and its statistics). With ``resume`` the run in ``run_dir`` goes on from its
    checkpoint to ``config.iterations``: the same data, weights and random streams (the
    planner's and the fit's), so the result is the one an uninterrupted run would give,
    bit for bit on one machine.

    Raises:
        CheckpointError: With ``resume``, before anything is written, if the run cannot be
            resumed (see :func:`agents.training.imitation_checkpoint.restore`).
    """
    run = _Dagger(config, run_dir, verbose, command)
    if resume:
        run.resume()
    for iteration in range(run.done.iterations, config.iterations):
        run.iterate(iteration)
    return run.finish()


class _Dagger:
    """One DAgger run: its student, labelling envs, expert, record and progress."""

    def __init__(
        self, config: ImitationConfig, run_dir: Path, verbose: int, command: Sequence[str] | None
    ) -> None:
        self.started = time.perf_counter()
        self.config, self.run_dir, self.verbose = config, run_dir, verbose
        core_class = core_class_of(config.env_id)
        run_dir.mkdir(parents=True, exist_ok=True)
        student = build_student(config)
        self.model, self.stats = student.model, student.stats
        self.envs = ConvoyVectorEnv(
            core_class,
            config.episodes,
            max_episode_steps=None,
            render_mode=None,
            autoreset_mode="same_step",
            **config.env_kwargs,
        )
        self.signs = self.envs.core.mirror_signs() if config.mirror else None
        if config.mirror and self.signs is None:
            raise ValueError(f"mirror: {config.env_id} declares no mirror symmetry")
        self.expert = EXPERTS[str(config.expert)]
        self.planner = self.expert.build(
            core_class,
            config.settings_by_count(),
            config.episodes,
            config.expert_config,
            config.seed,
        )
        self.rng = np.random.default_rng(config.seed)
        self.record = self._record(student.settings, student.policy_kwargs, command)
        self.done = RunState(data_obs=[], data_labels=[], curve=[])
        self.first_iteration = 0
        self.previous_steps = 0
        self.summary: dict[str, object] = {}

    def _record(
        self,
        settings: dict[str, object],
        policy_kwargs: dict[str, object],
        command: Sequence[str] | None,
    ) -> dict[str, object]:
        """The run's record (``config.json``, the base of its cards): the policy's keywords
        that are plain values (not the extractor's class or keywords)."""
        config = self.config
        plain = (int, float, str, list, tuple)
        kept_kwargs = {
            key: value for key, value in policy_kwargs.items() if isinstance(value, plain)
        }
        return {
            "algo": "ppo",
            "recipe": "dagger",
            "expert": self.expert.name,
            "command": list(command or ["python", "-m", "agents.imitate", *sys.argv[1:]]),
            "env_id": config.env_id,
            "env_kwargs": config.student_kwargs,
            "seed": config.seed,
            "imitation": {
                key: (list(value) if isinstance(value, tuple) else value)
                for key, value in asdict(config).items()
                if key not in _OWN_KEYS
            },
            "planner": _settings(self.planner.config),
            "hyperparams": {**settings, "policy_kwargs": kept_kwargs},
            "normalize": None if self.stats is None else {"norm_obs": True, "norm_reward": False},
            "policy": "MlpPolicy" if self.stats is not None else "MultiInputPolicy",
            "training_seed": TRAINING_SEED,
            "budget": config.iterations * config.episodes * self.envs.max_episode_steps,
            "host": measure_host_speed(config.seed).to_json(),
        }

    def resume(self) -> None:
        """Go on from the run folder's checkpoint (nothing is written here)."""
        width = int((self.envs.single_observation_space.shape or (0,))[-1])
        self.done, saved = restore(
            self.run_dir,
            self.config,
            _card(self.record),
            self.model,
            self.stats,
            self.planner,
            self.rng,
            width,
        )
        earlier = saved.resumed_at or ()
        self.record.update(resumed_at=[*earlier, self.done.iterations])
        self.started -= self.done.wall_s
        self.first_iteration = self.done.iterations
        self.previous_steps = self.done.simulated_steps

    def student(self) -> Driver:
        """The student as it drives and is validated (made odd under the mirror)."""
        policy = self.config.student(self.model, self.stats)
        return policy if self.signs is None else MirroredPolicy(policy, *self.signs)

    def labelled_states(self) -> int:
        """Rows of the data set that the expert labelled (a mirrored copy is not one)."""
        rows = sum(len(chunk) for chunk in self.done.data_obs or [])
        return rows // (2 if self.config.mirror else 1)

    def _label(self, iteration: int) -> tuple[np.ndarray, np.ndarray]:
        """One iteration's labelled states (with their mirror images under the mirror)."""
        config, planner = self.config, self.planner
        seed = TRAINING_SEED + config.seed * 10_000 + iteration * config.episodes
        driver = None if iteration == 0 else self.student()
        cost = (
            f"{planner.steps_per_label:,} simulated steps each"
            if planner.steps_per_label
            else "a network call each"
        )
        label = (
            f"imitate: iteration {iteration + 1}/{config.iterations}, {config.episodes} convoys, "
            f"{self.expert.name} labels ({cost})"
        )
        with Progress(self.envs.max_episode_steps, label, quiet=not self.verbose) as bar:
            obs, labels = collect(self.envs, planner, driver, seed, bar)
        if self.signs is not None:  # each state also mirrored, with its mirrored label
            obs = np.concatenate([obs, obs * self.signs[0].astype(np.float32)])
            labels = np.concatenate([labels, labels * self.signs[1]])
        return obs, labels

    def iterate(self, iteration: int) -> None:
        """Label, fit, validate, and write the iteration's row, best model and checkpoint."""
        config, stats, done = self.config, self.stats, self.done
        obs, labels = self._label(iteration)
        if iteration == 0 and stats is not None:
            freeze_statistics(stats, obs)
        data_obs, data_labels = done.data_obs or [], done.data_labels or []
        seen = obs if stats is None else np.asarray(stats.normalize_obs(obs))
        data_obs.append(seen.astype(np.float32))
        data_labels.append(labels)
        done.data_obs, done.data_labels = data_obs, data_labels
        inputs = config.inputs(np.concatenate(data_obs))
        loss = fit(self.model, inputs, np.concatenate(data_labels), config, self.rng)
        env_kwargs = config.env_kwargs
        results = rollout(
            self.student(), config.env_id, config.validation_episodes, VALIDATION_SEED, env_kwargs
        )
        self.summary = summary = summarize(results)
        samples = self._write_row(iteration, loss, Summary.from_json(summary))
        if done.best is None or score(summary) > done.best:
            done.best = score(summary)
            card = _card(
                {
                    **self.record,
                    "validation": summary,
                    "selected_at_iteration": iteration,
                    "selected_at_timesteps": samples,
                    "timesteps": samples,
                }
            )
            if stats is not None:
                save_stats(stats, stats_path(self.run_dir / BEST_MODEL))
            write_card(self.run_dir / BEST_MODEL, card)
            save_model(self.model, self.run_dir / BEST_MODEL)
        done.iterations = iteration + 1
        done.wall_s = round(time.perf_counter() - self.started, 1)
        done.simulated_steps = self.previous_steps + self.planner.simulated_steps
        write_checkpoint(self.run_dir, done, self.model, stats, self.planner, self.rng)

    def _write_row(self, iteration: int, loss: float, summary: Summary) -> int:
        """Write the iteration's row of the learning curve (with the record first, on the
        run's first new iteration: a run that fails before leaves the folder as it was);
        returns the labelled states so far."""
        samples = self.labelled_states()
        row: dict[str, float] = {
            "timesteps": samples,
            "wall_s": round(time.perf_counter() - self.started, 1),
            **{column: float(getattr(summary, column)) for column in CURVE_FIELDS[2:-2]},
            "iteration": iteration,
            "loss": round(loss, 6),
        }
        (self.done.curve or []).append(row)
        if iteration == self.first_iteration:
            write_config(self.run_dir, _card(self.record))
        if iteration == 0:
            write_curve(self.run_dir / CURVE_FILE, [row], CURVE_FIELDS)
        else:  # the earlier rows stay as they were written
            append_rows(self.run_dir / CURVE_FILE, [row], CURVE_FIELDS)
        if self.verbose:
            print(
                f"iteration {iteration}: {samples} labels, loss {loss:.4f}, validation safe "
                f"{summary.safe_rate:.2f}, folds {summary.jackknife_rate:.2f} "
                f"({row['wall_s']:.0f} s)",
                flush=True,
            )
        return samples

    def finish(self) -> dict[str, object]:
        """Write the final model's card, the best model's totals and the record."""
        record = self.record
        totals = {
            "timesteps": self.labelled_states(),
            "wall_time_s": round(time.perf_counter() - self.started, 1),
            "simulated_steps": self.previous_steps + self.planner.simulated_steps,
        }
        record.update(totals)
        write_card(self.run_dir / FINAL_MODEL, _card({**record, "validation": self.summary}))
        # The best model's card keeps when it was selected, and gets the run's totals.
        best = self.run_dir / BEST_MODEL
        write_card(best, read_model_card(best).replace(**totals))
        write_config(self.run_dir, _card(record))
        self.envs.close()
        return record
