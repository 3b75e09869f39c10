"""Hyperparameter search with Optuna: every trial a normal training run, resumable.

:func:`tune` samples hyperparameters from a search space (``agents/hyperparams/search.yml``,
one per algorithm, in the spirit of rl-baselines3-zoo's), writes each trial's entry as
an rl-zoo3 file beside its run (``<out>/trials/trial_<k>/<algo>.yml``, checked by
:func:`agents.training.config.load_hyperparams` like any file) and trains it with the
project's trainer (:func:`agents.training.sb3.train`): each trial is a run folder with
its ``evaluations.csv``, models and logs.

The objective is the **area under the validation curve over the budget**: the
headline rate (safe for Reverse, success otherwise) of the periodic validation
evaluations (50 episodes from :data:`agents.seeds.VALIDATION_SEED` by default),
integrated over the steps (trapezoids) and divided by the budget, so it is the rate
averaged over the training: 1 for a run that is perfect from the start, the final rate
times the share of the budget left after the curve reached it otherwise. It rewards a
high rate *and* an early plateau in one number (a second objective, "first step at 0.9
of the best rate", would make the search multi-objective, where Optuna's pruners do not
apply, and is noisy on 50-episode evaluations). The final and best rates are kept with
each trial (``user_attrs``) and in ``best_trials.md``, with the steps and the wall time at
which its curve first reached 90 % of its best rate (its time to the plateau).

With ``wall_budget`` (seconds) the objective is the same area over **wall time**
instead: the rate averaged over the first ``wall_budget`` seconds of training
(evaluations included), each trial stopping at its first evaluation past that time or at
its step budget, whichever comes first; a trial that ends its steps early keeps its last
rate to the end of the window (its model exists from then on). It ranks hyperparameters
by how soon *this machine* gets a good policy: a configuration that learns more per step
but costs more per step wins only if it wins per second. Wall time depends on the
machine's load, so such a search compares trials only when run alone (or at a steady
load), and its winner is a statement about that machine.

Sampler and pruner: TPE (Optuna's ``TPESampler``, seeded with ``--seed``) and the
median pruner on the intermediate values: after each evaluation the trial reports the
area so far (over the whole budget, so trials are compared at the same evaluation
index; over wall time, at the same tenth of the window) and stops once below the median
of the earlier trials there (``n_startup_trials`` complete trials first, no pruning
before the second evaluation or tenth).

The study is an Optuna journal file, ``<out>/study.log``: a search that was killed
resumes by running the same command again (trials left running are marked failed; the
settings in ``<out>/search.json`` must match). A kill during a write leaves the
journal's last record cut (no line end): Optuna reads past it, but would append the
next record to it and so damage the journal for good, so a resumed search first drops
that cut record (:func:`intact_journal_length`; it names it on standard error). All
other damage, such as a complete line that is not a JSON record, is refused before anything
is written, and the journal is left as it is. At the end :func:`write_results` writes
``best_trials.md`` (the best complete trials) and ``best_hyperparams.yml`` (the best
trial's entry, in the format of ``agents/hyperparams/<algo>.yml``, to be committed),
atomically.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import yaml

from agents.algorithms import algo_class
from agents.algorithms.bounds import argument_problem, bound_of
from agents.artifacts import files, limits
from agents.artifacts.curves import CURVE_COLUMNS, read_curve
from agents.artifacts.run_folder import CURVE_FILE
from agents.envs import headline_metric
from agents.progress import duration
from agents.training.config import (
    _RESERVED,
    HYPERPARAMS_DIR,
    MAX_HYPERPARAMS_BYTES,
    TrainConfig,
    init_arguments,
    load_hyperparams,
    parse_policy_kwargs,
    raw_entry,
)

if TYPE_CHECKING:
    from optuna import Study, Trial

#: The columns of a learning curve's steps and training seconds.
STEPS, WALL = CURVE_COLUMNS[:2]

#: A value a search space names (YAML's scalars).
Scalar = bool | int | float | str

#: The search spaces shipped with the package.
SEARCH_SPACES = HYPERPARAMS_DIR / "search.yml"
#: Files of a search's folder.
STUDY_FILE = "study.log"
SETTINGS_FILE = "search.json"
BEST_TRIALS = "best_trials.md"
BEST_HYPERPARAMS = "best_hyperparams.yml"
TRIALS = "trials"
#: Searched keys that are not the algorithm's arguments: the policy's and TD3's noise.
POLICY_KEYS = ("net_arch", "log_std_init")
ZOO_KEYS = ("noise_std",)
KINDS = ("categorical", "uniform", "log_uniform", "int")
#: The install hint of a missing Optuna.
MISSING_OPTUNA = (
    "optuna is not installed: pip install 'trailer-env[tune]' -c constraints.txt (the tune extra)"
)


def require_optuna() -> ModuleType:
    """The optuna module.

    Raises:
        ImportError: With :data:`MISSING_OPTUNA` when it is not installed.
    """
    try:
        import optuna
    except ImportError:
        raise ImportError(MISSING_OPTUNA) from None
    return optuna


@dataclass(frozen=True)
class Distribution:
    """One searched key: ``kind`` (one of :data:`KINDS`) and its choices or bounds."""

    kind: str
    values: tuple[Scalar, ...]


def _distribution(key: str, spec: object, where: str) -> Distribution:
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in KINDS:
        raise ValueError(f"{where}: {key} must be one of {{{', '.join(KINDS)}: ...}}")
    kind, values = next(iter(spec.items()))
    if not isinstance(values, list) or not values:
        raise ValueError(f"{where}: {key}: {kind} needs a non-empty list")
    if kind == "categorical":
        if not all(isinstance(v, (int, float, str)) and not isinstance(v, bool) for v in values):
            raise ValueError(f"{where}: {key}: choices must be numbers or strings")
        if key == "net_arch":
            for choice in values:
                net_arch(choice)
        return Distribution(kind, tuple(values))
    if len(values) != 2 or not all(files.is_number(v) for v in values) or values[0] >= values[1]:
        raise ValueError(f"{where}: {key}: {kind} needs [low, high] with low < high")
    if kind == "log_uniform" and values[0] <= 0:
        raise ValueError(f"{where}: {key}: log_uniform needs low > 0")
    if kind == "int" and not all(files.is_integer(v) for v in values):
        raise ValueError(f"{where}: {key}: int needs integer bounds")
    return Distribution(kind, tuple(values))


def _values_problem(algo: str, key: str, distribution: Distribution) -> str | None:
    """Why a distribution may sample a value ``algo`` refuses (None when it cannot):
    every categorical choice and both ends of a range are checked against the
    argument's bound (:mod:`agents.algorithms.bounds`), a count must be sampled as an
    integer, and every net_arch choice must fit the network limits."""
    if key == "net_arch":
        for choice in distribution.values:
            problem = limits.network_problem(net_arch(choice))
            if problem is not None:
                return f"net_arch choice {choice!r}: {problem}"
        return None
    bound = bound_of(algo, key)
    if bound is None:
        return None
    if bound.integer and distribution.kind in ("uniform", "log_uniform"):
        return f"{key} takes integers: sample it with int or categorical, not {distribution.kind}"
    for value in distribution.values:
        if isinstance(value, str):
            continue  # a schedule or SAC's "auto": the trainer's reading of the file checks it
        problem = argument_problem(algo, key, value)
        if problem is not None:
            return problem
    return None


def net_arch(choice: object) -> list[int]:
    """A net_arch choice ``"64x64"`` as ``[64, 64]``.

    Raises:
        ValueError: If it is not layer widths >= 1 joined by ``x``.
    """
    parts = str(choice).split("x")
    if not all(part.isdigit() and int(part) >= 1 for part in parts):
        raise ValueError(f"net_arch choice {choice!r} is not widths joined by x, e.g. '64x64'")
    return [int(part) for part in parts]


def read_space(algo: str, path: Path = SEARCH_SPACES) -> dict[str, Distribution]:
    """``algo``'s search space from ``path``, checked.

    The space is checked whole, as every trial would use it: a distribution that can
    sample a value the algorithm refuses (``batch_size: [0]``, a discount of 1.5, a
    count sampled as a float) is refused here, before a study is written.

    Raises:
        ValueError: If the file is unreadable, has no space for ``algo``, names a key the
            algorithm does not take (or the trainer sets itself), a distribution is
            malformed, or it can sample a value the algorithm refuses.
    """
    try:
        if path.stat().st_size > MAX_HYPERPARAMS_BYTES:
            raise ValueError(f"{path} is over {MAX_HYPERPARAMS_BYTES} bytes")
        spaces = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as error:
        raise ValueError(f"cannot read the search spaces {path}: {str(error)[:200]}") from None
    if not isinstance(spaces, dict) or not isinstance(spaces.get(algo), dict):
        raise ValueError(f"{path} has no search space for {algo}")
    arguments = init_arguments(algo_class(algo)) - set(_RESERVED)
    accepted = arguments | set(POLICY_KEYS) | set(ZOO_KEYS)
    space = {}
    for key, spec in spaces[algo].items():
        if key not in accepted:
            raise ValueError(
                f"{path}, {algo}: {key!r} is not an argument of {algo} that a search may set"
            )
        distribution = _distribution(str(key), spec, f"{path}, {algo}")
        problem = _values_problem(algo, str(key), distribution)
        if problem is not None:
            raise ValueError(f"{path}, {algo}: {problem}")
        space[str(key)] = distribution
    if not space:
        raise ValueError(f"{path}: the search space of {algo} is empty")
    return space


def sample(trial: Trial, space: Mapping[str, Distribution]) -> dict[str, object]:
    """One point of ``space`` from an Optuna trial (its parameters, as Optuna records them)."""
    params: dict[str, object] = {}
    for key, distribution in space.items():
        low, high = distribution.values[0], distribution.values[-1]
        if distribution.kind == "categorical":
            params[key] = trial.suggest_categorical(key, list(distribution.values))
        elif distribution.kind == "int":
            params[key] = trial.suggest_int(key, int(low), int(high))
        else:
            log = distribution.kind == "log_uniform"
            params[key] = trial.suggest_float(key, float(low), float(high), log=log)
    return params


def _policy_text(kwargs: Mapping[str, object]) -> str:
    """policy_kwargs as rl-zoo3's text (``"dict(net_arch=[64, 64], log_std_init=-1.0)"``)."""

    def text(value: object) -> str:
        if isinstance(value, type):
            return f"nn.{value.__name__}"
        if isinstance(value, dict):
            return "dict(" + ", ".join(f"{k}={text(v)}" for k, v in value.items()) + ")"
        return repr(value)

    return text(dict(kwargs))


def trial_entry(base: Mapping[str, object], params: Mapping[str, object]) -> dict[str, object]:
    """The rl-zoo3 entry of a trial: ``base`` (the algorithm's file) with ``params`` over it.

    ``net_arch`` and ``log_std_init`` go into ``policy_kwargs``; a ``batch_size`` larger
    than a rollout (``n_steps * n_envs``) is cut to it (as rl-zoo3 does).
    """
    entry = {key: value for key, value in base.items()}
    policy = dict(parse_policy_kwargs(entry.get("policy_kwargs", "dict()")))
    for key, value in params.items():
        if key == "net_arch":
            policy.update(net_arch=net_arch(value))
        elif key in POLICY_KEYS:
            policy[key] = value
        else:
            entry[key] = value
    if policy:
        entry.update(policy_kwargs=_policy_text(policy))
    if "n_steps" in entry and "batch_size" in entry:
        rollout = int(_number(entry["n_steps"]) * _number(entry.get("n_envs", 1)))
        entry.update(batch_size=min(int(_number(entry["batch_size"])), rollout))
    return entry


def area_over_budget(
    steps: Sequence[float], rates: Sequence[float], budget: float, *, hold_last: bool = False
) -> float:
    """The area under the curve (trapezoids) up to ``budget``, divided by ``budget``: the
    rate averaged over the budget (the part of the curve past ``budget`` is cut off;
    a curve that ends earlier counts 0 after its end, or its last rate with
    ``hold_last``). ``steps`` may be steps or seconds."""
    x = np.asarray(steps, dtype=float)
    y = np.asarray(rates, dtype=float)
    if x.size == 0:
        return 0.0
    if x[-1] > budget:
        keep = x < budget
        x, y = np.append(x[keep], budget), np.append(y[keep], np.interp(budget, x, y))
    elif hold_last and x[-1] < budget:
        x, y = np.append(x, budget), np.append(y, y[-1])
    return float(np.trapezoid(y, x) / budget) if x.size > 1 else 0.0


def first_reaching(rates: Sequence[float], share: float = 0.9) -> int | None:
    """The index of the first evaluation at ``share`` of the curve's best rate (None for a
    curve that never rises above 0): where its plateau begins, by a stated rule."""
    if not rates or max(rates) <= 0.0:
        return None
    goal = share * max(rates)
    return next(i for i, rate in enumerate(rates) if rate >= goal)


@dataclass(frozen=True)
class TuneSettings:
    """What a search is: its record, ``search.json``, must match when it resumes.

    Attributes:
        env_id, algo, n_trailers: The task and the algorithm.
        budget: Environment steps per trial.
        seed: The training seed of every trial and the sampler's seed.
        n_envs: Environments per trial (None: the file's).
        eval_freq, eval_episodes: The validation schedule of every trial.
        hyperparams: Folder of the base ``<algo>.yml`` (None: the package's).
        space: The search-space file.
        startup_trials: Complete trials before the pruner prunes.
        wall_budget: Seconds of training per trial; when set, the objective is the
            area over wall time (see the module), not over steps.
    """

    env_id: str
    algo: str
    n_trailers: int
    budget: int
    seed: int = 0
    n_envs: int | None = None
    eval_freq: int | None = None
    eval_episodes: int = 50
    hyperparams: Path | None = None
    space: Path = SEARCH_SPACES
    startup_trials: int = 5
    wall_budget: float | None = None
    command: tuple[str, ...] = field(default=(), compare=False)

    @property
    def evaluation_every(self) -> int:
        """Steps between evaluations (default: a tenth of the budget)."""
        return self.eval_freq or max(self.budget // 10, 1)

    @property
    def objective_text(self) -> str:
        """What the objective averages over, in words."""
        if self.wall_budget is None:
            return f"over the {self.budget:,}-step budget"
        return f"over the first {self.wall_budget:g} s of wall time"

    def objective(
        self, steps: Sequence[float], seconds: Sequence[float], rates: Sequence[float]
    ) -> float:
        """The objective of a curve (evaluations at ``steps``, ``seconds`` into training)."""
        if self.wall_budget is None:
            return area_over_budget(steps, rates, self.budget)
        return area_over_budget(seconds, rates, self.wall_budget, hold_last=True)

    def report_index(self, evaluation: int, seconds: float) -> int:
        """Where an intermediate value is compared with the other trials' (the pruner's
        step): the evaluation's index over steps; over wall time, the tenth of the window
        it falls in, since trials evaluate at different times (only the first evaluation in
        each tenth is reported)."""
        if self.wall_budget is None:
            return evaluation
        return int(10 * seconds / self.wall_budget)

    def document(self) -> dict[str, object]:
        """The record of ``search.json`` (without the command, which may differ on resume)."""
        record = asdict(self)
        record.pop("command")
        record.update(
            hyperparams=str(self.hyperparams) if self.hyperparams else None, space=str(self.space)
        )
        return record

    def base_entry(self) -> dict[str, object]:
        """The algorithm file's entry for the environment, raw (the trials' base).

        Raises:
            FileNotFoundError, ValueError: As :func:`raw_entry`.
        """
        directory = self.hyperparams or HYPERPARAMS_DIR
        load_hyperparams(self.algo, self.env_id, directory)  # the base must be valid
        return raw_entry(self.algo, self.env_id, directory)


def intact_journal_length(path: Path) -> int:
    """The bytes of the journal ``path`` that hold whole records: up to its last line end
    (a last line without one is a record cut by a kill during its write).

    Raises:
        ValueError: If it cannot be read, or a complete line is not a JSON object (a
            damaged journal), naming the record.
    """
    try:
        files.refuse_symlink(path)
        data = path.read_bytes()
    except (OSError, files.UnsafeFileError) as error:
        raise ValueError(f"cannot read the study {path}: {error}") from None
    end = data.rfind(b"\n") + 1
    for number, line in enumerate(data[:end].split(b"\n")[:-1], start=1):
        try:
            record = json.loads(line)
        except (UnicodeDecodeError, ValueError):
            record = None
        if not isinstance(record, dict):
            raise ValueError(
                f"the study {path} is damaged: its record {number} is not a JSON object "
                "(restore the file or search in another --out)"
            )
    return end


def search_problem(out: Path, settings: TuneSettings, overwrite: bool) -> str | None:
    """Why a search could not run in ``out`` (None when it can), found without writing.

    A folder holding this search's study resumes it; its results (``best_*``) are
    replaced only with ``overwrite``; a folder holding anything else is refused unless
    ``overwrite``; a study of other settings, or a damaged one
    (:func:`intact_journal_length`), is always refused.
    """
    problem = files.writable_problem(out, folder=True)
    if problem is not None or not out.exists():
        return problem
    settings_path = out / SETTINGS_FILE
    if (out / STUDY_FILE).exists():
        if not settings_path.is_file():
            return f"{out} holds a study without its {SETTINGS_FILE}"
        try:
            saved = files.read_json(settings_path, "search settings")
        except ValueError as error:
            return str(error)
        current = settings.document()
        changed = sorted(key for key in current if saved.get(key) != current[key])
        if changed:
            return (
                f"{out} holds a search with other settings ({', '.join(changed)}); "
                "use another --out"
            )
        try:
            intact_journal_length(out / STUDY_FILE)
        except ValueError as error:
            return str(error)
        for name in (BEST_TRIALS, BEST_HYPERPARAMS):
            if (out / name).exists() and not overwrite:
                return f"{out / name} exists (a finished search); pass --overwrite to go on"
        return None
    if any(out.iterdir()) and not overwrite:
        return f"{out} is not empty and holds no search; pass --overwrite to search there"
    return None


def _print(text: str, verbose: int) -> None:
    if verbose:
        import sys

        print(text, file=sys.stderr, flush=True)


def tune(
    settings: TuneSettings,
    out: Path,
    trials: int,
    *,
    overwrite: bool = False,
    verbose: int = 1,
) -> Study:
    """Run (or resume) the search until the study holds ``trials`` finished trials.

    Returns the Optuna study. Writes the results (:func:`write_results`) at the end.

    Raises:
        ImportError: Without Optuna (:data:`MISSING_OPTUNA`).
        ValueError: On a bad search space or base file, or an ``out`` that
            :func:`search_problem` refuses; nothing is written then.
    """
    optuna = require_optuna()
    from agents.training.sb3 import train

    space = read_space(settings.algo, settings.space)
    base = settings.base_entry()
    problem = search_problem(out, settings, overwrite)
    if problem is not None:
        raise ValueError(problem)
    metric = headline_metric(settings.env_id)
    with files.RunLock(out):
        journal = out / STUDY_FILE
        if journal.exists():
            intact = intact_journal_length(journal)
            cut = journal.stat().st_size - intact
            if cut:
                # Optuna would append the next record to the cut one: it goes first.
                os.truncate(journal, intact)
                _print(f"{journal}: dropped its last record, cut by a kill ({cut} bytes)", 1)
        files.write_json(out / SETTINGS_FILE, settings.document())
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        storage = optuna.storages.JournalStorage(
            optuna.storages.journal.JournalFileBackend(str(out / STUDY_FILE))
        )
        study = optuna.create_study(
            study_name="search",
            storage=storage,
            direction="maximize",
            load_if_exists=True,
            sampler=optuna.samplers.TPESampler(seed=settings.seed),
            pruner=optuna.pruners.MedianPruner(
                n_startup_trials=settings.startup_trials, n_warmup_steps=1
            ),
        )
        for stale in study.get_trials(states=(optuna.trial.TrialState.RUNNING,)):
            study.tell(stale.number, state=optuna.trial.TrialState.FAIL)
            _print(f"trial {stale.number} was left running by a killed search: failed", verbose)
        finished = len(study.get_trials(deepcopy=False))
        started = time.perf_counter()
        done_here = 0
        while finished < trials:
            trial = study.ask()
            params = sample(trial, space)
            run_dir = out / TRIALS / f"trial_{trial.number:04d}"
            run_dir.mkdir(parents=True, exist_ok=True)
            entry = trial_entry(base, params)
            text = yaml.safe_dump({settings.env_id: entry}, sort_keys=False)
            files.atomic_write_text(run_dir / f"{settings.algo}.yml", text)
            state, value = _run_trial(optuna, train, settings, trial, run_dir, metric)
            if state == "complete":
                study.tell(trial, value)
            else:
                study.tell(trial, state=getattr(optuna.trial.TrialState, state.upper()))
            finished += 1
            done_here += 1
            elapsed = time.perf_counter() - started
            eta = elapsed / done_here * (trials - finished)
            best = _best_text(study, optuna)
            shown = f"{value:.3f}" if value is not None else state
            _print(
                f"trial {finished}/{trials} (#{trial.number}): {shown}; best {best}; "
                f"{duration(elapsed)} so far, ETA {duration(eta)}",
                verbose,
            )
        write_results(study, settings, base, out)
    return study


def _best_text(study: Study, optuna: ModuleType) -> str:
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    if not complete:
        return "none yet"
    return f"{study.best_value:.3f} (#{study.best_trial.number})"


def _number(value: object) -> float:
    """A number of an entry or an evaluation's summary (checked where it was written).

    Raises:
        ValueError: If it is not a number.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"expected a number, got {value!r:.40}")
    return float(value)


def _run_trial(
    optuna: ModuleType,
    train: Callable[..., object],
    settings: TuneSettings,
    trial: Trial,
    run_dir: Path,
    metric: str,
) -> tuple[str, float | None]:
    """Train one trial; returns ("complete", value), ("pruned", None) or ("fail", None)."""
    steps: list[float] = []
    seconds: list[float] = []
    rates: list[float] = []
    pruned: list[int] = []
    reported: set[int] = set()

    def report(step: int, summary: Mapping[str, object]) -> bool:
        steps.append(float(step))
        seconds.append(_number(summary[WALL]))
        rates.append(_number(summary[metric]))
        index = settings.report_index(len(steps) - 1, seconds[-1])
        if index not in reported:
            reported.add(index)
            trial.report(settings.objective(steps, seconds, rates), index)
            if not pruned and trial.should_prune():
                pruned.append(step)
        out_of_time = settings.wall_budget is not None and seconds[-1] >= settings.wall_budget
        return bool(pruned) or out_of_time

    try:
        hp = load_hyperparams(settings.algo, settings.env_id, run_dir)
        config = TrainConfig.resolve(
            settings.env_id,
            settings.algo,
            settings.n_trailers,
            settings.seed,
            hp,
            timesteps=settings.budget,
            n_envs=settings.n_envs,
            command=settings.command,
        )
        train(
            config,
            run_dir,
            eval_freq=settings.evaluation_every,
            eval_episodes=settings.eval_episodes,
            checkpoint_freq=settings.budget,
            progress_bar=False,
            verbose=0,
            hooks=[report],
        )
    except (ValueError, FileNotFoundError, RuntimeError) as error:
        # A sampled combination the trainer refuses (or a diverging run) fails the trial,
        # not the search.
        trial.set_user_attr("error", f"{type(error).__name__}: {error}"[:500])
        return "fail", None
    rows = read_curve(run_dir / CURVE_FILE, ("timesteps", "wall_s", metric))
    x = [row[STEPS] for row in rows]
    t = [row[WALL] for row in rows]
    y = [row[metric] for row in rows]
    trial.set_user_attr("final_rate", y[-1] if y else math.nan)
    trial.set_user_attr("best_rate", max(y) if y else math.nan)
    trial.set_user_attr("steps", x[-1] if x else 0)
    trial.set_user_attr("wall_s", t[-1] if t else 0.0)
    reached = first_reaching(y)
    if reached is not None:
        trial.set_user_attr("plateau_steps", x[reached])
        trial.set_user_attr("plateau_wall_s", t[reached])
    if pruned:
        trial.set_user_attr("pruned_at", pruned[0])
        return "pruned", None
    return "complete", settings.objective(x, t, y)


def write_results(
    study: Study, settings: TuneSettings, base: Mapping[str, object], out: Path
) -> None:
    """``best_trials.md`` and ``best_hyperparams.yml`` (atomic), when a trial completed."""
    optuna = require_optuna()
    states = optuna.trial.TrialState
    complete = study.get_trials(deepcopy=False, states=(states.COMPLETE,))
    counts = {
        name: len(study.get_trials(deepcopy=False, states=(getattr(states, name.upper()),)))
        for name in ("complete", "pruned", "fail")
    }
    metric = headline_metric(settings.env_id)
    lines = [
        f"# Search: {settings.algo} on {settings.env_id}, n = {settings.n_trailers}",
        "",
        f"{'at most ' if settings.wall_budget else ''}{settings.budget:,} steps per trial; "
        f"objective: the validation {metric} averaged "
        f"{settings.objective_text} (area under the curve / budget); trials: "
        + ", ".join(f"{count} {name}" for name, count in counts.items()),
        "",
        "Plateau: the first evaluation at 90 % of the trial's best rate (steps, wall "
        "seconds), evaluations included.",
        "",
        "| rank | trial | objective | final rate | best rate | plateau | wall | hyperparameters |",
        "|---|---|---|---|---|---|---|---|",
    ]
    ranked = sorted(complete, key=lambda trial: -(trial.value or 0.0))
    for rank, trial in enumerate(ranked[:10], start=1):
        params = ", ".join(f"{key}={_short(value)}" for key, value in trial.params.items())
        attrs = trial.user_attrs
        plateau = (
            f"{attrs['plateau_steps']:,.0f} / {attrs['plateau_wall_s']:.0f} s"
            if "plateau_steps" in attrs
            else "-"
        )
        lines.append(
            f"| {rank} | {trial.number} | {trial.value:.3f} | "
            f"{attrs.get('final_rate', math.nan):.2f} | "
            f"{attrs.get('best_rate', math.nan):.2f} | {plateau} | "
            f"{attrs.get('wall_s', math.nan):.0f} s | {params} |"
        )
    files.atomic_write_text(out / BEST_TRIALS, "\n".join(lines) + "\n")
    if not ranked:
        return
    best = ranked[0]
    entry = trial_entry(base, best.params)
    header = (
        f"# The best trial (#{best.number}, objective {best.value:.3f}) of the search in {out}:\n"
        f"# {settings.algo} on {settings.env_id}, n = {settings.n_trailers}, "
        f"{settings.budget:,} steps per trial, seed {settings.seed}.\n"
        f"# Copy the entry into agents/hyperparams/{settings.algo}.yml to commit it.\n"
    )
    text = header + yaml.safe_dump({settings.env_id: entry}, sort_keys=False)
    files.atomic_write_text(out / BEST_HYPERPARAMS, text)


def _short(value: object) -> str:
    return f"{value:.3g}" if isinstance(value, float) else str(value)
