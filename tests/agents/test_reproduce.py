"""``agents.reproduce``: every committed model's recipe read from its card, rebuilt into
the folder the user names, refused before anything is written."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest

from agents.algorithms.options import StartReplay
from agents.artifacts.cards import ModelCard, Planner, read_model_card
from agents.artifacts.run_folder import kept_model
from agents.artifacts.shipped import MODELS_DIR, SEEDS_DIR, TEACHERS_DIR
from agents.commands import options as cli
from agents.commands import reproduce
from agents.commands.reproduce import Recipe, RecipeError, main, recipes, recipes_page
from agents.evaluation.metrics import rollout, summary_of
from agents.policies.registry import load_policy
from tests.agents.helpers import refusal

ROOT = Path(__file__).resolve().parents[2]
CARD_FILES = sorted(
    path
    for folder in (MODELS_DIR, SEEDS_DIR, TEACHERS_DIR)
    for path in folder.glob("*.json")
    if not path.name.endswith("_vecnormalize.json")
)


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """The one-line message of a refusal (exit status 2)."""
    return refusal(main, argv, capsys)


def test_list_names_every_committed_model(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:7] == ["model", "kind", "algorithm", "scene", "n", "budget", "seed"]
    listed = [line.split()[0] for line in lines[1:]]
    models = [path.stem for path in sorted((ROOT / "agents" / "models").glob("*.zip"))]
    seeds = [path.stem for path in sorted((ROOT / "agents" / "models" / "seeds").glob("*.zip"))]
    teachers = [path.stem for path in sorted(TEACHERS_DIR.glob("*.zip"))]
    assert listed == models + seeds + teachers
    assert len(listed) == len(set(listed)) == 34 + 48 + 15
    by_model = {line.split()[0]: line for line in lines[1:]}
    teacher = by_model["ppo_privileged_reverse_v1_n2_s1"].split()[1:]
    assert teacher[:7] == ["train", "ppo", "Reverse-v1", "2", "6,000,000", "steps", "1"]
    assert by_model["ppo_reverse_v1_n2"].split()[1:7] == [
        "train",
        "ppo",
        "Reverse-v1",
        "2",
        "6,000,000",
        "steps",
    ]
    assert by_model["sac_coast_n2"].split()[1:5] == ["train", "sac", "Coast-v0", "2"]
    assert by_model["dagger_reverse_v1_n1"].split()[1:7] == [
        "imitate",
        "dagger",
        "Reverse-v1",
        "1",
        "4",
        "iterations",
    ]
    assert by_model["distill_reverse_v1_sequence16"].split()[1:8] == [
        "distill",
        "dagger",
        "Reverse-v1",
        "1-6",
        "10",
        "iterations",
        "1",
    ]
    # The one model whose recipe resumed a checkpoint that is not in the package.
    not_reproducible = [line.split()[0] for line in lines if "not reproducible:" in line]
    assert not_reproducible == ["ppo_reverse_n2"]
    assert "--resume runs/reverse_n2_ppo_s0/checkpoints" in by_model["ppo_reverse_n2"]


def test_recipes_are_the_cards_typed() -> None:
    by_model = {recipe.model: recipe for recipe in recipes()}
    assert {recipe.kind for recipe in by_model.values()} == {"train", "imitate", "distill"}
    ppo = by_model["ppo_reverse_v1_n2"]
    card = json.loads((MODELS_DIR / "ppo_reverse_v1_n2.json").read_text())
    assert (ppo.kind, ppo.algorithm, ppo.env_id, ppo.n_trailers) == (
        "train",
        "ppo",
        "trailer_env/Reverse-v1",
        2,
    )
    assert (ppo.seed, ppo.budget, ppo.budget_unit) == (card["seed"], card["budget"], "steps")
    assert (ppo.source, ppo.problem) == ("agents/hyperparams/gsde_wide", None)
    distill = by_model["distill_reverse_v1_sequence16"]
    assert (distill.kind, distill.n_trailers, distill.seed, distill.budget) == (
        "distill",
        (1, 6),
        1,
        10,
    )
    assert distill.source == "expert policies 1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}"
    dagger = by_model["dagger_reverse_v1_n2"]
    assert (dagger.kind, dagger.budget, dagger.source) == ("imitate", 6, "planner mpc")
    assert sum(recipe.problem is not None for recipe in by_model.values()) == 1


@pytest.mark.parametrize("card_path", CARD_FILES, ids=lambda path: path.stem)
def test_no_card_names_a_run_folder(card_path: Path) -> None:
    command = json.loads(card_path.read_text())["command"]
    assert command[:2] == ["python", "-m"]
    assert not {"--run-dir", "--export", "--overwrite"} & set(command)
    assert not [item for item in command if item.startswith(("/tmp", "/work", "runs/s"))]


def test_budget_and_episodes_rewrite_the_command() -> None:
    ppo = Recipe.from_card(MODELS_DIR / "ppo_reverse_v1_n2.json")
    command = ppo.command("out", budget=300)
    assert command[:3] == ["python", "-m", "agents.train"]
    assert command[command.index("--timesteps") + 1] == "300"
    assert command.count("--timesteps") == 1
    assert command[-2:] == ["--run-dir", "out"]
    assert command[command.index("--hyperparams") + 1] == "agents/hyperparams/gsde_wide"
    installed = ppo.command("out", package_paths=True, overwrite=True)
    assert Path(installed[installed.index("--hyperparams") + 1]).resolve() == (
        MODELS_DIR.parent / "hyperparams" / "gsde_wide"
    )
    assert installed[-1] == "--overwrite"
    dagger = Recipe.from_card(MODELS_DIR / "dagger_reverse_v1_n2.json")
    command = dagger.command("out", budget=1, episodes=4)
    assert command[command.index("--iterations") + 1] == "1"
    assert command[command.index("--episodes") + 1] == "4"
    with pytest.raises(ValueError, match=r"budget must be 1 \.\. 6 iterations"):
        dagger.command("out", budget=7)
    with pytest.raises(ValueError, match="episodes apply to imitate and distill"):
        ppo.command("out", episodes=4)


def _card_with(tmp_path: Path, source: str, **changes: object) -> Path:
    card = json.loads((MODELS_DIR / source).read_text())
    card.update(changes)
    path = tmp_path / source
    path.write_text(json.dumps(card))
    return path


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"command": "python -m agents.train"}, "'command' must be a list"),
        ({"command": ["python", "-m", "agents.evaluate", "x"]}, "field command must start"),
        ({"seed": -1}, "field seed must be an int >= 0"),
        ({"env_id": None}, "field env_id must be a str"),
        ({"budget": "many"}, "'budget' must be int"),
        (
            {"command": ["python", "-m", "agents.train", "--algo", "ppo", "--run-dir", "x"]},
            "field command names --run-dir",
        ),
        (
            {"command": ["python", "-m", "agents.train", "--algo", "ppo", "--seed", "2"]},
            "field command: the following arguments are required: --env",
        ),
    ],
)
def test_a_bad_card_is_refused_naming_the_field(
    tmp_path: Path, changes: dict[str, object], message: str
) -> None:
    path = _card_with(tmp_path, "ppo_reverse_v1_n2.json", **changes)
    with pytest.raises(RecipeError, match=message) as error:
        Recipe.from_card(path)
    assert str(path) in str(error.value)


def test_a_recipe_record_is_validated() -> None:
    ppo = Recipe.from_card(MODELS_DIR / "ppo_reverse_v1_n2.json")
    fields = {name: getattr(ppo, name) for name in ppo.__dataclass_fields__}
    with pytest.raises(ValueError, match="recipe field kind must be one of"):
        Recipe(**{**fields, "kind": "bake"})
    with pytest.raises(TypeError, match="recipe field budget must be an int"):
        Recipe(**{**fields, "budget": 1.5})
    with pytest.raises(ValueError, match="--run-dir is the reproduction's to set"):
        Recipe(**{**fields, "arguments": ("--run-dir", "x")})


def test_an_expert_policy_that_is_not_committed_is_said(tmp_path: Path) -> None:
    card = json.loads((MODELS_DIR / "distill_reverse_v1_sequence.json").read_text())
    command = list(card["command"])
    command[command.index("--teacher") + 1] = "private_policy_n{n}"
    path = _card_with(tmp_path, "distill_reverse_v1_sequence.json", command=command)
    recipe = Recipe.from_card(path)
    assert recipe.kind == "distill"
    assert recipe.problem == "expert policy private_policy_n1 not committed"


def test_a_hyperparameter_file_that_changed_is_said(tmp_path: Path) -> None:
    card = json.loads((MODELS_DIR / "sac_reverse_n2.json").read_text())
    hyperparams = {**card["hyperparams"], "gamma": 0.99}
    recipe = Recipe.from_card(_card_with(tmp_path, "sac_reverse_n2.json", hyperparams=hyperparams))
    assert recipe.problem is not None
    assert recipe.problem.startswith("agents/hyperparams now gives hyperparams")


def test_the_committed_page_is_what_the_cards_give() -> None:
    page = (ROOT / reproduce.DOCS_PAGE).read_text()
    assert page == recipes_page()
    rows = [line for line in page.splitlines() if line.startswith("| ") and "`" in line]
    assert len(rows) == len(CARD_FILES) == 34 + 48 + 15
    assert sum("| no: " in row for row in rows) == 1


def test_markdown_writes_the_page(tmp_path: Path) -> None:
    target = tmp_path / "reproduce.md"
    assert main(["--markdown", str(target)]) == 0
    assert target.read_text() == recipes_page()


def test_dry_run_prints_the_command_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rebuilt"
    assert main(["sac_reverse_n1", "--out", str(out), "--budget", "200", "--dry-run"]) == 0
    printed = capsys.readouterr().out.split()
    assert printed[:3] == ["python", "-m", "agents.train"]
    assert printed[printed.index("--timesteps") + 1] == "200"
    assert printed[-2:] == ["--run-dir", str(out)]
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["ppo_reverse_v9"],
            "no committed model 'ppo_reverse_v9'; close names: ppo_reverse_n3, ppo_reverse_n2",
        ),
        (["ppo_reverse_v1_n2", "--budget", "0"], "argument --budget: expected a positive integer"),
        (["ppo_reverse_v1_n2", "--budget", "1.5"], "argument --budget: expected a positive"),
        (["ppo_reverse_v1_n2", "--budget", "6000001"], "budget must be 1 .. 6,000,000 steps"),
        (["dagger_reverse_v1_n2", "--budget", "7"], "budget must be 1 .. 6 iterations"),
        (["ppo_reverse_v1_n2", "--episodes", "4"], "argument --episodes: episodes apply to"),
        (["ppo_reverse_n2"], "ppo_reverse_n2 is not reproducible from committed files: --resume"),
    ],
)
def test_refusals_exit_2_and_write_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    out = tmp_path / "rebuilt"
    assert message in _refused([*argv, "--out", str(out)], capsys)
    assert not out.exists()


def test_a_folder_that_is_not_empty_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "rebuilt"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    message = _refused(["sac_reverse_n1", "--out", str(out), "--budget", "100"], capsys)
    assert "is not empty; pass --overwrite" in message
    assert [path.name for path in out.iterdir()] == ["notes.txt"]
    assert (out / "notes.txt").read_text() == "mine"
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    assert "exists and is not a folder" in _refused(
        ["sac_reverse_n1", "--out", str(a_file)], capsys
    )
    assert "--out" in _refused(["sac_reverse_n1"], capsys)


def _rebuilt(model: str, out: Path, options: list[str]) -> tuple[Recipe, ModelCard]:
    """Rebuild ``model`` into ``out``; its recipe and the rebuilt best model's card, checked
    to load and drive through agents.evaluate's loader."""
    assert main([model, "--out", str(out), *options]) == 0
    recipe = Recipe.from_card(MODELS_DIR / f"{model}.json")
    best = out / "best_model.zip"
    card = read_model_card(best)
    assert card.env_id == recipe.env_id and card.seed == recipe.seed
    low = recipe.n_trailers[0] if isinstance(recipe.n_trailers, tuple) else recipe.n_trailers
    kwargs = {"n_trailers": low}
    policy = load_policy(str(best), recipe.env_id, kwargs)
    summary = summary_of(rollout(policy, recipe.env_id, 2, 0, kwargs))
    assert 0.0 <= summary.safe_rate <= 1.0 and summary.mean_length >= 1
    return recipe, card


@pytest.mark.slow
def test_sac_train_recipe_rebuilds_at_a_tiny_budget(tmp_path: Path) -> None:
    recipe, card = _rebuilt("sac_reverse_n1", tmp_path / "sac", ["--budget", "100"])
    assert card.algo == "sac" and card.budget == 100
    assert list(card.command) == recipe.command(tmp_path / "sac", budget=100, package_paths=True)


@pytest.mark.slow
def test_ppo_train_recipe_rebuilds_at_a_tiny_budget(tmp_path: Path) -> None:
    _, card = _rebuilt("ppo_reverse_v1_n2", tmp_path / "ppo", ["--budget", "300"])
    assert card.algo == "ppo" and card.budget == 300
    committed = read_model_card(MODELS_DIR / "ppo_reverse_v1_n2.zip")
    assert card.hyperparams == committed.hyperparams
    assert card.option(StartReplay) == StartReplay(0.5, 3)


@pytest.mark.slow
def test_dagger_recipe_rebuilds_at_one_iteration(tmp_path: Path) -> None:
    options = ["--budget", "1", "--episodes", "1"]
    _, card = _rebuilt("dagger_reverse_v1_n1", tmp_path / "dagger", options)
    assert card.recipe == "dagger" and card.expert == "mpc"
    imitation = card.imitation
    assert imitation is not None
    assert (imitation.iterations, imitation.episodes) == (1, 1)


def test_distillation_recipe_rebuilds_at_one_iteration(tmp_path: Path) -> None:
    options = ["--budget", "1", "--episodes", "2"]
    recipe, card = _rebuilt("distill_reverse_v1_sequence", tmp_path / "distill", options)
    # The rebuilt card records the imitation command that ran, not reproduce's own.
    assert list(card.command) == recipe.command(
        tmp_path / "distill", budget=1, episodes=2, package_paths=True
    )
    assert card.expert == "specialists"
    assert card.planner == Planner(policy="ppo_reverse_v1_n{n}")
    imitation = card.imitation
    assert imitation is not None
    assert (imitation.iterations, imitation.episodes, imitation.mirror) == (1, 2, True)


def test_seed_models_are_listed_from_their_folder() -> None:
    cards = reproduce.model_cards()
    assert cards["ppo_reverse_v1_n2_s0"] == SEEDS_DIR / "ppo_reverse_v1_n2_s0.json"
    assert cards["ppo_reverse_v1_n2"] == MODELS_DIR / "ppo_reverse_v1_n2.json"
    teacher = "ppo_privileged_reverse_v1_n1_s0"
    assert cards[teacher] == TEACHERS_DIR / f"{teacher}.json"


def _check_teacher(teacher: Recipe, n: int, seed: int, source: str) -> None:
    """A privileged teacher's recipe: trained under mismatch20 at ``n`` from committed
    files, with the hyperparameters of ``source``."""
    assert (teacher.kind, teacher.n_trailers, teacher.seed, teacher.problem) == (
        "train",
        n,
        seed,
        None,
    )
    assert teacher.source == source
    assert teacher.arguments[teacher.arguments.index("--randomize") + 1] == "mismatch20"


def test_a_student_that_adapts_and_its_teacher_rebuild_from_committed_files() -> None:
    by_model = {recipe.model: recipe for recipe in recipes()}
    for n in (1, 2, 3):
        for seed in range(3):
            teacher = by_model[f"ppo_privileged_reverse_v1_n{n}_s{seed}"]
            _check_teacher(teacher, n, seed, "agents/hyperparams/privileged")
            student = by_model[f"dagger_reverse_v1_adapt_n{n}_s{seed}"]
            assert (student.kind, student.problem) == ("distill", None)
    teachers = "agents/models/teachers/ppo_privileged_reverse_v1_n{n}"
    source = by_model["dagger_reverse_v1_adapt_n1"].source
    assert source.startswith(f"expert policies median({teachers}_s0.zip,")


@pytest.mark.parametrize(("n", "kept"), [(2, "final"), (3, None)])
def test_the_fine_tuned_teachers_start_from_committed_teachers(n: int, kept: str | None) -> None:
    by_model = {recipe.model: recipe for recipe in recipes()}
    for seed in range(3):
        teacher = by_model[f"ppo_privileged_replay_reverse_v1_n{n}_s{seed}"]
        _check_teacher(teacher, n, seed, "agents/hyperparams/privileged_finetune")
        start = teacher.arguments[teacher.arguments.index("--init-from") + 1]
        assert start == f"agents/models/teachers/ppo_privileged_reverse_v1_n{n}_s{seed}.zip"
        assert teacher.arguments[teacher.arguments.index("--start-replay") + 1] == "0.5"
        # n = 2 keeps the model at the end of its budget (its validation rate stayed flat).
        arguments = list(teacher.arguments)
        assert kept_model(arguments) == ("final_model.zip" if kept else "best_model.zip")
    student = by_model[f"dagger_reverse_v1_adapt_n{n}"]
    teachers = "agents/models/teachers/ppo_privileged_replay_reverse_v1_n{n}"
    assert student.source.startswith(f"expert policies median({teachers}_s0.zip,")


def test_a_median_of_teachers_is_committed_only_when_every_member_is(tmp_path: Path) -> None:
    recipe = Recipe.from_card(MODELS_DIR / "dagger_reverse_v1_adapt_n3.json")
    assert (recipe.kind, recipe.problem) == ("distill", None)
    assert recipe.source.startswith("expert policies median(agents/models/teachers/")
    card = json.loads((MODELS_DIR / "dagger_reverse_v1_adapt_n3.json").read_text())
    command = list(card["command"])
    at = command.index("--teacher" if "--teacher" in command else "--expert-policy") + 1
    command[at] = command[at].replace("_s2.zip", "_s9.zip")
    path = _card_with(tmp_path, "dagger_reverse_v1_adapt_n3.json", command=command)
    assert Recipe.from_card(path).problem == (
        "expert policy " + command[at].replace("{n}", "3") + " not committed"
    )


def test_a_printed_command_splits_back_into_its_words() -> None:
    words = ["python", "--expert-policy", "median(a_n{n}.zip,b.zip)", "--x", "n{n}", "a b"]
    line = cli.shell_line(words)
    assert line == "python --expert-policy 'median(a_n{n}.zip,b.zip)' --x n{n} 'a b'"
    assert shlex.split(line) == words
    for recipe in recipes():
        command = recipe.command("OUT")
        assert shlex.split(cli.shell_line(command)) == command
