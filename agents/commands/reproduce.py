"""``python -m agents.reproduce``: rebuild a committed model from its card.

Usage::

    python -m agents.reproduce --list
    python -m agents.reproduce ppo_reverse_v1_n2 --out rebuilt/ppo_reverse_v1_n2
    python -m agents.reproduce dagger_reverse_v1_n2 --out smoke --budget 1 --episodes 4
    python -m agents.reproduce ppo_reverse_v1_n2 --out rebuilt --dry-run

Every committed model (``agents/models/*.zip``, its training seeds'
``agents/models/seeds/*.zip`` and the privileged teachers ``agents/models/teachers/*.zip``
the students that adapt learned from) has a card whose ``command`` is the recipe that trained
it. :class:`Recipe` reads that card into a typed record: its kind (``train``: an SB3
algorithm from the scene's reward, ``agents.train``; ``imitate``: DAgger from a planner,
``agents.imitate``; ``distill``: DAgger from trained specialists), algorithm, scene,
number of trailers, budget (steps for ``train``, iterations for the others), seed, and
what it learns from (the hyperparameter folder, the planner, the expert policies). The command
runs the recipe in-process into the folder ``--out`` names (the run's ``--run-dir``): the
rebuilt model is ``<out>/best_model.zip`` (``final_model.zip`` after ``--export-model final``).

A recipe is rebuilt from committed files only. One that needs anything else (an expert policy,
a checkpoint or a hyperparameter folder that is not in the package) or whose files no
longer give the card's settings (the hyperparameter file now holds other values, the
card's iterations differ from its command's) says so in ``--list`` and is refused.

``--budget N`` shrinks the run for a smoke run: ``--timesteps N`` of a ``train`` recipe,
``--iterations N`` of the others; ``--episodes K`` (``imitate`` and ``distill`` only)
drives K convoys per iteration instead of the recipe's. ``--dry-run`` prints the command
it would run and writes nothing. ``--markdown FILE`` writes the table of every recipe
(:func:`recipes_page`, the reproduce section of the docs).

Refusals exit with status 2 and a one-line message before anything is written: an
unknown model (the close names are listed), ``--out`` an existing non-empty folder
without ``--overwrite`` (or a file), a ``--budget`` that is not a count between 1 and the
recipe's own budget, ``--episodes`` for a ``train`` recipe, a recipe that is not
reproducible from committed files.
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import io
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

from agents.artifacts import files
from agents.artifacts.cards import RUN_FOLDER_FLAGS, ModelCard
from agents.artifacts.run_folder import comparable_hyperparams, kept_model
from agents.artifacts.shipped import MODELS_DIR, SEEDS_DIR, TEACHERS_DIR
from agents.commands import options as cli

#: The recipe kinds, in the order ``--list`` and the docs name them.
KINDS = ("train", "imitate", "distill")

#: The command module of each kind.
MODULES = {"train": "agents.train", "imitate": "agents.imitate", "distill": "agents.imitate"}

#: The folder the card's repository-relative paths (``agents/hyperparams/...``) start in.
PACKAGE_PARENT = MODELS_DIR.parent.parent

#: The page :func:`recipes_page` writes (relative to the repository root).
DOCS_PAGE = Path("docs/generated/reproduce.md")

#: SB3's keywords of the policy's network (in a card's ``hyperparams``).
POLICY_KWARGS = "policy_kwargs"
NET_ARCH = "net_arch"

#: What the card's command may name for the run folder: the reproduction sets it.
_RUN_FLAGS = RUN_FOLDER_FLAGS

#: The keys of a train card that the recipe's files must give again (``agents.train``'s
#: record, :meth:`agents.training.config.TrainConfig.document`).
_TRAIN_KEYS = (
    "algo",
    "env_id",
    "env_kwargs",
    "seed",
    "budget",
    "n_envs",
    "policy",
    "hyperparams",
    "normalize",
    "shaping",
    "init_from",
    "critic_warmup",
    "start_curriculum",
    "start_replay",
)


class RecipeError(ValueError):
    """A card whose recipe cannot be read (the message names the card and the field)."""


@dataclass(frozen=True)
class Recipe:
    """A committed model's recipe, read from its card (:meth:`from_card`).

    Attributes:
        model: The model's name (its file stem), e.g. ``ppo_reverse_v1_n2``.
        card: The card's path.
        kind: One of :data:`KINDS`.
        algorithm: The training algorithm (``ppo``, ``sac`` ...; ``dagger`` for imitation
            and distillation).
        env_id: The scene.
        n_trailers: One count, or a range ``(low, high)`` (a generalist).
        seed: The run's seed.
        budget: Environment steps (``train``) or DAgger iterations (the others).
        arguments: The command's arguments after ``python -m <module>``, without a run
            folder or an export target.
        source: What it learns from: the hyperparameter folder (``train``), the planner
            (``imitate``) or the expert policies' spec (``distill``).
        problem: Why it cannot be rebuilt from committed files; None when it can.
    """

    model: str
    card: Path
    kind: str
    algorithm: str
    env_id: str
    n_trailers: int | tuple[int, int]
    seed: int
    budget: int
    arguments: tuple[str, ...]
    source: str
    problem: str | None = None

    def __post_init__(self) -> None:
        for name in ("model", "kind", "algorithm", "env_id", "source"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise TypeError(f"recipe field {name} must be a non-empty str")
        if self.kind not in KINDS:
            raise ValueError(f"recipe field kind must be one of {KINDS}, got {self.kind!r}")
        for name in ("seed", "budget"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"recipe field {name} must be an int, got {value!r}")
        if self.seed < 0 or self.budget < 1:
            raise ValueError(
                f"recipe fields seed >= 0 and budget >= 1, got {self.seed} and {self.budget}"
            )
        if not all(isinstance(argument, str) for argument in self.arguments):
            raise TypeError("recipe field arguments must be strings")
        for flag in (*_RUN_FLAGS, "--overwrite"):
            if flag in self.arguments:
                raise ValueError(f"recipe field arguments: {flag} is the reproduction's to set")

    @property
    def module(self) -> str:
        """The command that runs the recipe."""
        return MODULES[self.kind]

    @property
    def budget_unit(self) -> str:
        """What :attr:`budget` counts: ``steps`` or ``iterations``."""
        return "steps" if self.kind == "train" else "iterations"

    @property
    def budget_flag(self) -> str:
        """The command's option that sets the budget."""
        return "--timesteps" if self.kind == "train" else "--iterations"

    @property
    def scene(self) -> str:
        """The scene's short name (``Reverse-v1``)."""
        return self.env_id.split("/")[-1]

    @property
    def counts(self) -> str:
        """The number of trailers as text (``2`` or ``1-6``)."""
        if isinstance(self.n_trailers, tuple):
            return f"{self.n_trailers[0]}-{self.n_trailers[1]}"
        return str(self.n_trailers)

    @classmethod
    def from_card(cls, card_path: Path) -> Recipe:
        """The recipe of the card at ``card_path`` (``<model>.json``), validated whole.

        Raises:
            RecipeError: An unreadable card, or a field that is missing or of the wrong
                type or value (the message names the card and the field).
        """
        card = _read(card_path)
        model = card_path.stem
        command = list(card.command)
        if len(command) < 3:
            raise RecipeError(f"model card {card_path}: field command must be a list of strings")
        if command[:2] != ["python", "-m"] or command[2] not in set(MODULES.values()):
            raise RecipeError(
                f"model card {card_path}: field command must start with python -m and one of "
                f"{sorted(set(MODULES.values()))}, got {' '.join(command[:3])!r}"
            )
        arguments = tuple(command[3:])
        for flag in (*_RUN_FLAGS, "--overwrite"):
            if flag in arguments:
                raise RecipeError(
                    f"model card {card_path}: field command names {flag}; the reproduction "
                    "sets the run folder"
                )
        for name, value in (("env_id", card.env_id), ("algo", card.algo)):
            if value is None:
                raise RecipeError(f"model card {card_path}: field {name} must be a str")
        seed = card.seed
        if seed is None or seed < 0:
            raise RecipeError(f"model card {card_path}: field seed must be an int >= 0")
        read = _train_recipe if command[2] == "agents.train" else _imitation_recipe
        try:
            return read(model, card_path, card, arguments)
        except (TypeError, ValueError) as error:
            if isinstance(error, RecipeError):
                raise
            raise RecipeError(f"model card {card_path}: {error}") from None

    def command(
        self,
        out: Path | str,
        *,
        budget: int | None = None,
        episodes: int | None = None,
        overwrite: bool = False,
        package_paths: bool = False,
    ) -> list[str]:
        """The command line that rebuilds the model into ``out``.

        Args:
            out: The run folder.
            budget: A smaller budget (:attr:`budget_unit`) for a smoke run.
            episodes: Convoys per iteration (``imitate`` and ``distill``).
            overwrite: Let the command replace a run in ``out``.
            package_paths: Name the card's repository-relative paths
                (``agents/hyperparams/...``) by where the package is, so that the command
                runs from any folder.

        Raises:
            ValueError: A budget outside 1 .. :attr:`budget`, or ``episodes`` for a
                ``train`` recipe or below 1.
        """
        arguments = list(self.arguments)
        if budget is not None:
            if isinstance(budget, bool) or not isinstance(budget, int):
                raise TypeError(f"budget must be an int, got {type(budget).__name__}")
            if not 1 <= budget <= self.budget:
                raise ValueError(
                    f"budget must be 1 .. {self.budget:,} {self.budget_unit} (the recipe's), "
                    f"got {budget:,}"
                )
            arguments = _with_option(arguments, self.budget_flag, str(budget))
        if episodes is not None:
            if self.kind == "train":
                raise ValueError(
                    f"episodes apply to imitate and distill recipes; {self.model} is a train recipe"
                )
            if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
                raise ValueError(f"episodes must be an int >= 1, got {episodes!r}")
            arguments = _with_option(arguments, "--episodes", str(episodes))
        if package_paths:
            arguments = [_package_path(item) for item in arguments]
        tail = ["--run-dir", str(out)] + (["--overwrite"] if overwrite else [])
        return ["python", "-m", self.module, *arguments, *tail]


def _read(card_path: Path) -> ModelCard:
    """The card at ``card_path`` (:class:`~agents.artifacts.cards.ModelCard`).

    Raises:
        RecipeError: If it cannot be read, is no JSON object, or a field is unknown or
            of the wrong type (naming it).
    """
    try:
        document = files.read_json(card_path, "model card", allow_nan=True)
    except (OSError, ValueError) as error:
        raise RecipeError(f"model card {card_path}: {error}") from None
    if not isinstance(document, dict):
        raise RecipeError(f"model card {card_path}: not a JSON object")
    try:
        return ModelCard.from_json(document, str(card_path))
    except ValueError as error:
        raise RecipeError(str(error)) from None


def _package_path(item: str) -> str:
    """A card's repository-relative path (``agents/...``) as the installed package's file:
    unchanged when the working folder is the package's own checkout (so that a rebuilt
    card records the path as the committed one does), absolute otherwise."""
    if not item.startswith("agents/"):
        return item
    installed = PACKAGE_PARENT / item
    return item if Path(item).resolve() == installed.resolve() else str(installed)


def _with_option(arguments: list[str], flag: str, value: str) -> list[str]:
    """``arguments`` with ``flag``'s value replaced by ``value`` (appended when absent)."""
    if flag in arguments:
        index = arguments.index(flag)
        return [*arguments[: index + 1], value, *arguments[index + 2 :]]
    return [*arguments, flag, value]


def _parse(parser: argparse.ArgumentParser, arguments: Sequence[str]) -> argparse.Namespace:
    """``arguments`` through a command's own parser; its refusal as a ValueError (no exit)."""

    def refuse(message: str) -> NoReturn:
        raise ValueError(f"field command: {message}")

    parser.error = refuse  # type: ignore[method-assign]
    with contextlib.redirect_stderr(io.StringIO()):
        return parser.parse_args(list(arguments))


def _committed_path(text: str) -> Path | None:
    """The package file a card's path names (``agents/...``), None when it names none."""
    if not text.startswith("agents/"):
        return None
    path = PACKAGE_PARENT / text
    return path if path.exists() else None


def _committed_expert(spec: str) -> bool:
    """Whether ``spec`` (each member of a ``median(...)``) is committed."""
    from agents.policies.ensemble import ensemble_members, is_ensemble_spec

    if is_ensemble_spec(spec):
        return all(_committed_expert(member) for member in ensemble_members(spec))
    if "/" not in spec and not Path(spec).suffix:
        return (MODELS_DIR / f"{spec}.zip").is_file()
    return _committed_path(spec) is not None


def _train_recipe(
    model: str, card_path: Path, card: ModelCard, arguments: tuple[str, ...]
) -> Recipe:
    """The recipe of an ``agents.train`` card; the hyperparameter file's settings must be
    the card's."""
    # Imported here: the trainer brings torch, which --help and refusals do not need.
    from agents.commands import train

    parser = train.build_parser()
    args = _parse(parser, arguments)
    problem = None
    folder = "agents/hyperparams" if args.hyperparams is None else str(args.hyperparams)
    for flag, path in (("--resume", args.resume), ("--init-from", args.init_from)):
        if path is not None and _committed_path(str(path)) is None:
            problem = f"{flag} {path} is not committed"
    if problem is None and _committed_path(folder) is None:
        problem = f"hyperparameter folder {folder} is not committed"
    if problem is None:
        resolved = [_package_path(item) for item in arguments]
        parsed = train.build_parser()
        config = train.config_from_args(parsed, _parse(parsed, resolved), ["python"])
        document = config.document()
        written = card.to_json()
        for key in _TRAIN_KEYS:
            given, recorded = (
                comparable_hyperparams(document.get(key)),
                comparable_hyperparams(written.get(key)),
            )
            if given != recorded:
                problem = f"{folder} now gives {key} {given!r:.60}, the card {recorded!r:.60}"
                break
    budget = card.budget
    if budget is None:
        raise RecipeError(f"model card {card_path}: field budget must be an int")
    return Recipe(
        model=model,
        card=card_path,
        kind="train",
        algorithm=str(card.algo),
        env_id=str(args.env),
        n_trailers=args.n_trailers,
        seed=int(args.seed),
        budget=budget,
        arguments=arguments,
        source=folder,
        problem=problem,
    )


def _student_problem(card: ModelCard, env_id: str, net_arch: list[int] | None) -> str | None:
    """Why the student's network and PPO settings (``agents/hyperparams/ppo.yml``'s entry of
    the scene, which ``agents.imitate`` reads) are no longer the card's; None when they are."""
    from agents.training.config import jsonable, load_hyperparams, parse_policy_kwargs

    recorded = card.hyperparams
    policy_kwargs = recorded.get(POLICY_KWARGS)
    if not isinstance(policy_kwargs, dict):
        raise ValueError("field hyperparams must be an object with policy_kwargs")
    hp = load_hyperparams("ppo", env_id)
    given: dict[str, object] = {
        "n_envs": hp.n_envs,
        **{str(k): jsonable(v) for k, v in hp.algo_kwargs.items() if k != POLICY_KWARGS},
    }
    given[NET_ARCH] = net_arch or parse_policy_kwargs(hp.algo_kwargs.get(POLICY_KWARGS, {})).get(
        NET_ARCH
    )
    card_values = {k: v for k, v in recorded.items() if k != POLICY_KWARGS}
    card_values[NET_ARCH] = policy_kwargs.get(NET_ARCH)
    for key in sorted(set(given) | set(card_values)):
        if given.get(key) != card_values.get(key):
            return (
                f"agents/hyperparams/ppo.yml now gives the student's {key} "
                f"{given.get(key)!r:.60}, the card {card_values.get(key)!r:.60}"
            )
    return None


def _imitation_recipe(
    model: str, card_path: Path, card: ModelCard, arguments: tuple[str, ...]
) -> Recipe:
    """The recipe of an ``agents.imitate`` card (DAgger from a planner, or distillation
    from specialists, which must be committed models)."""
    from agents.commands import imitate
    from agents.policies.experts import PolicyExpertConfig, default_expert

    args = _parse(imitate.build_parser(), arguments)
    expert = args.expert or default_expert(args.env)
    imitation = card.imitation
    if imitation is None:
        raise RecipeError(f"model card {card_path}: field imitation must be an object")
    problem = None
    if args.resume:
        problem = "--resume continues a run folder that is not committed"
    given = {
        "seed": args.seed,
        "expert": expert,
        "env_id": args.env,
        "imitation.iterations": args.iterations,
        "imitation.episodes": args.episodes,
        "imitation.epochs": args.epochs,
        "imitation.mirror": args.mirror,
    }
    recorded_values = {
        "seed": card.seed,
        "expert": card.expert,
        "env_id": card.env_id,
        "imitation.iterations": imitation.iterations,
        "imitation.episodes": imitation.episodes,
        "imitation.epochs": imitation.epochs,
        "imitation.mirror": imitation.mirror,
    }
    for key, value in given.items():
        recorded = recorded_values[key]
        if problem is None and recorded != value:
            problem = f"the card's {key} is {recorded!r}, its command's {value!r}"
    if problem is None:
        problem = _student_problem(card, args.env, args.net_arch)
    source = f"planner {expert}"
    if expert == "specialists":
        experts = (
            PolicyExpertConfig(args.expert_policy) if args.expert_policy else PolicyExpertConfig()
        )
        source = f"expert policies {experts.policy}"
        low, high = (
            args.n_trailers if isinstance(args.n_trailers, tuple) else (args.n_trailers,) * 2
        )
        for n in range(low, high + 1):
            spec = experts.spec(n)
            if problem is None and not _committed_expert(spec):
                problem = f"expert policy {spec} not committed"
    return Recipe(
        model=model,
        card=card_path,
        kind="distill" if expert == "specialists" else "imitate",
        algorithm="dagger",
        env_id=str(args.env),
        n_trailers=args.n_trailers,
        seed=int(args.seed),
        budget=int(args.iterations),
        arguments=arguments,
        source=source,
        problem=problem,
    )


def model_cards(
    models_dir: Path = MODELS_DIR, seeds_dir: Path = SEEDS_DIR, teachers_dir: Path = TEACHERS_DIR
) -> dict[str, Path]:
    """Every committed model's card by model name: the models, their seeds', then the
    teachers'."""
    cards: dict[str, Path] = {}
    for folder in (models_dir, seeds_dir, teachers_dir):
        for model in sorted(folder.glob("*.zip")):
            cards.setdefault(model.stem, model.with_suffix(".json"))
    return cards


def recipes(
    models_dir: Path = MODELS_DIR, seeds_dir: Path = SEEDS_DIR, teachers_dir: Path = TEACHERS_DIR
) -> list[Recipe]:
    """The recipe of every committed model (:func:`model_cards`' order).

    Raises:
        RecipeError: A card whose recipe cannot be read.
    """
    cards = model_cards(models_dir, seeds_dir, teachers_dir)
    return [Recipe.from_card(card) for card in cards.values()]


def _budget_text(recipe: Recipe) -> str:
    return f"{recipe.budget:,} {recipe.budget_unit}"


def list_lines(all_recipes: Sequence[Recipe]) -> list[str]:
    """``--list``'s lines: a header, then one line per model with its recipe and, for one
    that committed files cannot rebuild, why not."""
    header = ("model", "kind", "algorithm", "scene", "n", "budget", "seed", "from")
    rows = [
        (
            recipe.model,
            recipe.kind,
            recipe.algorithm,
            recipe.scene,
            recipe.counts,
            _budget_text(recipe),
            str(recipe.seed),
            recipe.source,
        )
        for recipe in all_recipes
    ]
    widths = [max(len(row[column]) for row in [header, *rows]) for column in range(len(header))]
    lines = []
    for row, recipe in zip([header, *rows], [None, *all_recipes], strict=True):
        line = "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True))
        if recipe is not None and recipe.problem is not None:
            line += f"  not reproducible: {recipe.problem}"
        lines.append(line.rstrip())
    return lines


def _markdown_rows(all_recipes: Sequence[Recipe]) -> Iterator[str]:
    for recipe in all_recipes:
        command = cli.shell_line(recipe.command("OUT"))
        rebuilt = "yes" if recipe.problem is None else f"no: {recipe.problem}"
        yield f"| {recipe.model} | {recipe.kind} | `{command}` | {rebuilt} |"


def recipes_page(
    models_dir: Path = MODELS_DIR, seeds_dir: Path = SEEDS_DIR, teachers_dir: Path = TEACHERS_DIR
) -> str:
    """The Markdown page of every committed model's recipe (:data:`DOCS_PAGE`)."""
    all_recipes = recipes(models_dir, seeds_dir, teachers_dir)
    committed, seeds, teachers = (
        [recipe for recipe in all_recipes if recipe.card.parent == folder]
        for folder in (models_dir, seeds_dir, teachers_dir)
    )
    header = (
        "| Model | Kind | Command (OUT: the folder given to --out) | From committed files |\n"
        "|---|---|---|---|\n"
    )
    return (
        "# Rebuilding the committed models\n\n"
        "Written by `python -m agents.reproduce --markdown docs/generated/reproduce.md` "
        "from the model cards. `python -m agents.reproduce MODEL --out OUT` runs the "
        "command of MODEL's row; `--budget N` shrinks it for a smoke run (steps for "
        "`train`, iterations for `imitate` and `distill`).\n\n"
        "## Committed models\n\n"
        + header
        + "\n".join(_markdown_rows(committed))
        + "\n\n## Their training seeds (agents/models/seeds)\n\n"
        + header
        + "\n".join(_markdown_rows(seeds))
        + "\n\n## The teachers of the students that adapt (agents/models/teachers)\n\n"
        + header
        + "\n".join(_markdown_rows(teachers))
        + "\n"
    )


def build_parser() -> argparse.ArgumentParser:
    """The command-line interface."""
    parser = argparse.ArgumentParser(
        prog=cli.program("agents.reproduce"),
        description="Rebuild a committed model from its card's recipe.",
    )
    parser.add_argument("model", nargs="?", help="the model's name (see --list)")
    parser.add_argument("--out", type=Path, default=None, help="the folder the run writes")
    parser.add_argument(
        "--list", action="store_true", help="print every committed model with its recipe"
    )
    parser.add_argument(
        "--budget",
        type=cli.positive_int,
        default=None,
        help="a smaller budget for a smoke run: steps (train) or iterations (imitate, distill)",
    )
    parser.add_argument(
        "--episodes",
        type=cli.positive_int,
        default=None,
        help="convoys per DAgger iteration instead of the recipe's (imitate, distill)",
    )
    parser.add_argument(
        "--dry-run", action="store_true", help="print the command it would run; run nothing"
    )
    parser.add_argument(
        "--markdown",
        type=Path,
        default=None,
        metavar="FILE",
        help=f"write the table of every recipe to FILE (the docs' {DOCS_PAGE})",
    )
    cli.add_overwrite(parser, "run in an --out folder that is not empty (its run is replaced)")
    return parser


def _find(parser: argparse.ArgumentParser, name: str) -> Path:
    """The card of the model ``name``; exit 2 listing close names when there is none."""
    cards = model_cards()
    if name in cards:
        return cards[name]
    stem = Path(name).name.removesuffix(".zip").removesuffix(".json")
    if stem in cards and name != stem:
        return cards[stem]
    close = difflib.get_close_matches(stem, list(cards), n=5, cutoff=0.6)
    hint = f"close names: {', '.join(close)}" if close else "see --list"
    parser.error(f"argument model: no committed model {name!r}; {hint}")


def _check_out(parser: argparse.ArgumentParser, out: Path, overwrite: bool) -> None:
    """Exit 2 when ``out`` cannot be the run folder: a file, a link, not writable, or a
    folder that is not empty without ``--overwrite``."""
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        parser.error(f"argument --out: {out} exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        parser.error(
            f"argument --out: {out} is not empty; pass --overwrite to replace the run there"
        )
    cli.check_out_folder(parser, out)


def _runner(module: str) -> Callable[[list[str]], int]:
    if module == "agents.train":
        from agents.commands.train import main as train_main

        return train_main
    from agents.commands.imitate import main as imitate_main

    return imitate_main


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit status (refusals exit 2 with a one-line message)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.list or args.markdown is not None:
            if args.model is not None:
                parser.error("argument model: not with --list or --markdown")
            if args.markdown is not None:
                cli.check_out_file(parser, args.markdown, "--markdown")
                page = recipes_page()
                files.atomic_write_text(args.markdown, page)
                print(f"wrote {args.markdown}")
            if args.list:
                print("\n".join(list_lines(recipes())))
            return 0
        if args.model is None:
            parser.error("argument model: name a committed model (see --list)")
        card = _find(parser, args.model)
        recipe = Recipe.from_card(card)
    except RecipeError as error:
        parser.error(str(error))
    if args.out is None:
        parser.error("argument --out: the folder to rebuild the model in is required")
    if recipe.problem is not None:
        parser.error(
            f"argument model: {recipe.model} is not reproducible from committed files: "
            f"{recipe.problem}"
        )
    try:
        command = recipe.command(
            args.out,
            budget=args.budget,
            episodes=args.episodes,
            overwrite=args.overwrite,
            package_paths=True,
        )
    except (TypeError, ValueError) as error:
        flag = "--episodes" if str(error).startswith("episodes") else "--budget"  # their names
        parser.error(f"argument {flag}: {error}")
    _check_out(parser, args.out, args.overwrite)
    if args.dry_run:
        print(cli.shell_line(command))
        return 0
    print(cli.shell_line(command), flush=True)
    status = _runner(recipe.module)(command[3:])
    if status == 0:
        print(
            f"rebuilt {recipe.model} in {args.out}: {args.out / kept_model(recipe.arguments)} "
            f"(committed: {recipe.card.with_suffix('.zip')})"
        )
    return status


if __name__ == "__main__":
    sys.exit(main())
