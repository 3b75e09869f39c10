"""What a training run starts from, checked once (:mod:`agents.commands.train`): the model
(``--resume``'s checkpoint, ``--init-from``'s model) and the run a resume goes on with.

Both must be a file saved by the run's algorithm, load in the run's environment without
an unsafe unpickling, and carry the observation statistics the run reads through. They
differ in what else they may hold: a checkpoint may keep pickled statistics and a replay
buffer (loaded only with ``--trust-pickle``); a fine-tuning start must not have been
imitated with the mirror (it acts through it, so its bare network is another policy) and
needs its statistics as JSON (they are frozen and read as they are).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from agents.algorithms.options import TRAINING_OPTIONS
from agents.artifacts.cards import card_of, read_model_card
from agents.artifacts.paths import pickled_stats_path, replay_buffer_path, stats_path
from agents.artifacts.run_folder import (
    CONFIG_FILE,
    checkpoint_folder,
    export_problem,
    holds_run,
    read_run_record,
    record_differences,
    resume_problem,
    run_dir_of_checkpoint,
    symlink_problem,
)
from agents.artifacts.sb3_zip import UnsafeFileError
from agents.artifacts.stats import read_stats
from agents.policies.sb3 import detect_algo, load_model
from agents.training.config import TrainConfig


@dataclass(frozen=True)
class SourceModel:
    """A model file a run starts from.

    Attributes:
        flag: The option that names it (refusals name it).
        path: The file.
        resumed: True for a checkpoint the run goes on from (``--resume``), False for a
            fine-tuning start (``--init-from``).
    """

    flag: str
    path: Path
    resumed: bool

    @property
    def kind(self) -> str:
        """The file in words."""
        return "checkpoint" if self.resumed else "model"

    def file_problem(self, algo: str) -> str | None:
        """What is wrong with the file before anything is loaded: missing, saved by
        another algorithm than ``algo``, or (a fine-tuning start) imitated with the mirror;
        None when nothing is."""
        if not self.path.is_file():
            return f"no {self.kind} file {self.path}"
        try:
            saved_algo = detect_algo(self.path)
            if saved_algo != algo:
                return f"{self.path} was saved by {saved_algo}, not {algo}"
            if not self.resumed and read_model_card(self.path).mirrored:
                # It acts as the mean of its network and the network's mirror image;
                # training the bare network would start from other decisions than the model's.
                return f"{self.path} was trained with the mirror (imitation.mirror)"
        except (ValueError, FileNotFoundError) as error:
            return str(error)
        return None

    def statistics_problem(self, normalizes_observations: bool) -> str | None:
        """What is missing from its observation statistics for a run that does (or does
        not) normalise observations; None when nothing is."""
        saved = stats_path(self.path)
        pickled = self.resumed and pickled_stats_path(self.path) is not None
        if normalizes_observations and not saved.is_file() and not pickled:
            return (
                f"{self.path} has no observation statistics ({saved.name}), but the "
                "hyperparameters normalise observations"
            )
        return None

    def load_problem(
        self, algo: str, env_id: str, env_kwargs: dict[str, object], trust_pickle: bool
    ) -> tuple[str | None, int]:
        """Load it as the run would (``env_kwargs``: the file's, with the command's n and
        physics): what is wrong (damaged, unsafe to load, made for other observations) or
        None, and its step count."""
        try:
            model = load_model(
                self.path, algo, env_id=env_id, env_kwargs=env_kwargs, trust_pickle=trust_pickle
            )
            saved = stats_path(self.path)
            pickled = pickled_stats_path(self.path)
            if saved.is_file():
                read_stats(saved)
            elif self.resumed and pickled is not None and not trust_pickle:
                raise UnsafeFileError(
                    f"its statistics {pickled} are a pickle; pass --trust-pickle to load them"
                )
            buffer = replay_buffer_path(self.path) if self.resumed else None
            if buffer is not None and not trust_pickle:
                raise UnsafeFileError(
                    f"its replay buffer {buffer} is a pickle; pass --trust-pickle to load it "
                    "(only if you trust the file)"
                )
        except (ValueError, FileNotFoundError) as error:
            return str(error), 0
        return None, int(model.num_timesteps)


#: Keys of a training run's record that its continuation may change: the command, the
#: total budget (which only grows), the totals of the run so far and the host's speed.
RESUMABLE_KEYS = (
    "command",
    "budget",
    "timesteps",
    "wall_time_s",
    "stopped_on_plateau_at",
    "host",
)
#: The option that sets a key of the record (the hyperparameter file sets the others;
#: the training options name their own flags).
_FLAGS = {
    "algo": "--algo",
    "env_id": "--env",
    "seed": "--seed",
    "n_envs": "--n-envs",
    "env_kwargs.n_trailers": "--n-trailers",
    "env_kwargs.randomize": "--randomize",
}


def _shown(value: object) -> str:
    """A record's value in a refusal message."""
    if value is None:
        return "none"
    return value if isinstance(value, str) else json.dumps(value, sort_keys=True)


def resumed_run_problem(checkpoint: Path, config: TrainConfig) -> tuple[str, str] | None:
    """Whether resuming ``checkpoint`` continues its run as the run recorded it: the flag
    to name and what is wrong, or None.

    Every setting that shapes the run (scene, algorithm, n, physics, seed, batch, shaping,
    the hyperparameter file's entry) must be the run's, and so must every training option
    (its schedule, its buffer's rules, its frozen statistics go on); the message names the
    option, with the run's value and the one given. A run folder whose record is damaged,
    or that holds another trainer's run, is refused likewise. A checkpoint in no run
    folder has nothing to hold to.
    """
    own_run = run_dir_of_checkpoint(checkpoint)
    if own_run is None:
        folder = checkpoint_folder(checkpoint)
        if holds_run(folder):  # its learning curve without its record: a damaged run
            return "--resume", f"{folder / CONFIG_FILE} is missing"
        return None
    problem = symlink_problem(own_run)  # the folder the run goes on in, first
    if problem is not None:
        return "--run-dir", problem
    try:
        saved = read_run_record(own_run)
        recipe = saved.recipe
        if recipe is not None:  # e.g. an imitation run: another trainer's record
            raise ValueError(
                f"{own_run} holds a {recipe} run, not one of agents.train; "
                "fine-tune its model with --init-from"
            )
        for kind in TRAINING_OPTIONS:
            old, new = saved.option(kind), config.option(kind)
            if (old is None) != (new is None) or (old and new and not new.same_run(old)):
                text = kind.absent_text() if old is None else old.flags_text()
                raise ValueError(f"{own_run} was trained with {text}; resume it with the same")
    except ValueError as error:
        return "--resume", str(error)
    free = (*RESUMABLE_KEYS, *(key for kind in TRAINING_OPTIONS for key in kind.KEYS))
    wanted = card_of(config.document(), f"for {own_run / CONFIG_FILE}")
    for key, old_value, new_value in record_differences(saved, wanted, free):
        flag = _FLAGS.get(key) or _FLAGS.get(key.partition(".")[0]) or "--hyperparams"
        return flag, (
            f"{own_run} was trained with {key} = {_shown(old_value)}, not "
            f"{_shown(new_value)}; resume it with the same"
        )
    return None


def target_problem(
    target: Path, resume: Path | None, init_from: Path | None, export: Path | None, overwrite: bool
) -> tuple[str, str] | None:
    """Whether a run can go into the folder ``target``: the flag to name and what is
    wrong, or None. The folder a resume goes on in must have readable run files, a
    fine-tuning start must not lie in it, and ``export`` must be writable."""
    own_run = None if resume is None else run_dir_of_checkpoint(resume)
    if resume is not None and (target.resolve() == own_run or not holds_run(target)):
        # The files of the folder the run goes on in (a folder holding another run is
        # refused, or cleared with --overwrite): checked before anything is written.
        problem = resume_problem(target)
        if problem is not None:
            return "--resume", f"cannot resume into {target}: {problem}"
    if init_from is not None and init_from.resolve().is_relative_to(target.resolve()):
        # --overwrite would clear it, and the run's own models would replace it.
        return "--init-from", (
            f"{init_from} lies in the run folder {target}; copy it out or choose another --run-dir"
        )
    if export is not None:
        problem = export_problem(export, overwrite)
        if problem is not None:
            return "--export", problem
    return None
