"""Every command the README and the docs show runs as written.

The commands are collected from the Markdown: every line of a ``bash`` block (``\\``
continuations joined, ``for`` loops expanded with their first value) and every inline
``python -m ...`` in backticks. Each is checked by what it is:

- ``python -m agents.<command>``: its own argparse parser accepts the arguments; the
  evaluations also run for real with a budget of one episode (``--episodes 1``, output
  in a temporary folder, a video cut to a few frames). Training, imitation,
  certification and the report take minutes: parsed only.
- ``bash scripts/<name>.sh``: the script exists and parses (``bash -n``).
- any other ``python -m <module>``: the module exists.
- the set-up lines (``pip install``, ``cp``, ``export``, ``ray start``, ``mkdocs``,
  ``pytest``): their files, folders and extras exist.

A line none of these covers fails the test, so a new kind of command in the docs
comes with its check.
"""

from __future__ import annotations

import importlib
import importlib.util
import re
import shlex
import subprocess
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = sorted(
    {
        ROOT / "README.md",
        ROOT / "CONTRIBUTING.md",
        ROOT / "benchmarks" / "README.md",
        *(ROOT / "docs").rglob("*.md"),
    }
)
#: The agents' commands: module of ``python -m agents.<name>`` -> its command module (every
#: ``agents/<name>.py`` beside an ``agents/commands/<name>.py``).
AGENT_COMMANDS = {
    f"agents.{path.stem}": f"agents.commands.{path.stem}"
    for path in sorted((ROOT / "agents").glob("*.py"))
    if path.stem != "__init__" and (ROOT / "agents" / "commands" / path.name).is_file()
}
#: The example module that protocol.md's ``--policy my_module:act`` imports.
MY_MODULE = "import numpy as np\n\n\ndef act(obs):\n    return np.zeros((len(obs), 1))\n"


@dataclass(frozen=True)
class Command:
    """One documented command: where it is shown and its words (as the shell splits them)."""

    where: str
    words: tuple[str, ...]
    #: Named in the text (`python -m agents.certify --closed-loop dopri5`): a mention,
    #: often of a few options only, whose options must exist; a block's line runs.
    inline: bool = False

    @property
    def text(self) -> str:
        return shlex.join(self.words)


def _expand_loops(lines: list[str]) -> Iterator[str]:
    """The lines of a block with ``for VAR in A B ...; do`` ... ``done`` removed and
    ``$VAR`` / ``${VAR}`` replaced by the loop's first value; a line ``VAR=VALUE`` sets
    ``VAR`` for the lines after it."""
    values: dict[str, str] = {}
    for line in lines:
        rest = line
        if assignment := re.fullmatch(r"(\w+)=(\S+)", rest.strip()):
            values[assignment.group(1)] = assignment.group(2)
            continue
        while match := re.match(r"for (\w+) in (\S+)[^;]*; do\s*", rest):
            values[match.group(1)] = match.group(2)
            rest = rest[match.end() :]
        if re.fullmatch(r"(done;?\s*)+", rest.strip()):
            continue
        rest = re.sub(r"(;\s*)?(done;?\s*)+$", "", rest).strip()
        for name, value in values.items():
            rest = rest.replace("${" + name + "}", value).replace("$" + name, value)
        if rest:
            yield rest


def documented_commands() -> list[Command]:
    """Every command of the documents' ``bash`` blocks and inline ``python -m`` spans."""
    commands = []
    for document in DOCUMENTS:
        text = document.read_text()
        where = str(document.relative_to(ROOT))
        for block in re.findall(r"```(?:bash|sh|shell)\n(.*?)```", text, flags=re.S):
            lines = [line for line in block.replace("\\\n", " ").splitlines() if line.strip()]
            for line in _expand_loops(lines):
                words = shlex.split(line, comments=True)
                if words:
                    commands.append(Command(where, tuple(words)))
        for span in re.findall(r"`(python -m [^`]+)`", text):
            # Placeholders (python -m benchmarks.<name>, a|b) are patterns, not commands.
            # The README's are copied as shown by a reader's first hour: they run whole.
            if not re.search(r"[<|]", span):
                inline = document.name != "README.md" or document.parent != ROOT
                commands.append(Command(where, tuple(shlex.split(span)), inline=inline))
    return commands


COMMANDS = documented_commands()


def _python_module(command: Command) -> str | None:
    """``X`` of ``python -m X ...`` (or ``.venv/bin/python -m X``), else None."""
    words = command.words
    if len(words) >= 3 and Path(words[0]).name == "python" and words[1] == "-m":
        return words[2]
    return None


def _agent(command: Command) -> tuple[str, list[str]] | None:
    module = _python_module(command)
    if module in AGENT_COMMANDS:
        return AGENT_COMMANDS[module], list(command.words[3:])
    return None


def _check_setup_line(command: Command) -> None:
    """The set-up lines: what they name exists (they are not run)."""
    words = command.words
    head = words[0]
    if head == "bash":
        script = ROOT / words[1]
        assert script.is_file(), f"{command.where}: {command.text}: no {script}"
        subprocess.run(["bash", "-n", str(script)], check=True)
    elif Path(head).name == "pip" or words[1:3] == ("-m", "pip"):
        tomllib = pytest.importorskip("tomllib")  # Python 3.11+
        extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
            "optional-dependencies"
        ]
        for word in words:
            if word.startswith("trailer-env["):
                wanted = word[len("trailer-env[") : -1].split(",")
                assert set(wanted) <= set(extras), f"{command.text}: unknown extra"
            if word.endswith(".txt"):
                assert (ROOT / word).is_file(), f"{command.text}: no {word}"
    elif head == "cp":
        assert (ROOT / words[-1]).parent.is_dir(), f"{command.text}: no destination folder"
    elif head == "export" or words[:2] == ("ray", "start"):
        assert "RAY_AUTH_TOKEN" in command.text or "--head" in words or "--address" in words
    elif Path(head).name == "mkdocs":
        assert importlib.util.find_spec("mkdocs") is not None
        assert (ROOT / "mkdocs.yml").is_file()
    elif _python_module(command) == "pytest":
        for word in words[3:]:
            if not word.startswith("-"):
                assert (ROOT / word).exists(), f"{command.text}: no {word}"
    elif _python_module(command) == "rl_zoo3.train":
        # rl-zoo3 is optional (the docs say how to install it): its files must exist.
        configuration = words[words.index("--conf-file") + 1]
        assert (ROOT / configuration).is_file()
    else:
        module = _python_module(command)
        assert module is not None, f"{command.where}: no check for {command.text!r}"
        assert importlib.util.find_spec(module) is not None, f"{command.text}: no {module}"


def test_the_docs_show_commands() -> None:
    assert {"agents.main", "agents.across_n", "agents.time_to_ceiling"} <= set(AGENT_COMMANDS)
    agents = [command for command in COMMANDS if _agent(command) is not None]
    assert len(COMMANDS) > 60
    assert len(agents) > 40
    assert any("--video" in command.words for command in agents)


@pytest.mark.parametrize(
    "command",
    [command for command in COMMANDS if _agent(command) is None],
    ids=lambda command: command.text[:60],
)
def test_setup_and_other_commands(command: Command) -> None:
    _check_setup_line(command)


@pytest.mark.parametrize(
    "command",
    [command for command in COMMANDS if _agent(command) is not None],
    ids=lambda command: command.text[:70],
)
def test_agents_commands_parse(command: Command) -> None:
    found = _agent(command)
    assert found is not None
    module, argv = found
    parser = importlib.import_module(module).build_parser()
    if command.inline:
        known = {option for action in parser._actions for option in action.option_strings}
        named = {word.split("=")[0] for word in argv if word.startswith("--")}
        assert named <= known, f"{command.where}: {command.text}: no {sorted(named - known)}"
        return
    try:
        parser.parse_args(argv)
    except SystemExit as error:  # argparse's refusal (--help exits 0)
        if error.code != 0:
            pytest.fail(f"{command.where}: {command.text} is refused (exit {error.code})")


def _tiny(argv: list[str], out: Path) -> list[str]:
    """``argv`` of an evaluation with one episode, its output and video under ``out``."""
    tiny: list[str] = []
    words = iter(argv)
    for word in words:
        if word in ("--episodes", "--out", "--video"):
            value = next(words)
            if word == "--video":
                tiny += ["--video", str(out / Path(value).name), "--video-steps", "3"]
            continue
        tiny.append(word)
    return [*tiny, "--episodes", "1", "--out", str(out / "eval"), "--no-plots"]


EVALUATIONS = [
    command
    for command in COMMANDS
    if _python_module(command) == "agents.evaluate"
    and not command.inline
    and not any(word.startswith("runs/") for word in command.words)  # a run of your own
]


@pytest.mark.parametrize("command", EVALUATIONS, ids=lambda command: command.text[:70])
def test_evaluations_run_with_one_episode(
    command: Command,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from agents.commands import evaluate

    (tmp_path / "my_module.py").write_text(MY_MODULE)
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    argv = _tiny(list(command.words[3:]), tmp_path)
    try:
        assert evaluate.main(argv) == 0
    except SystemExit as error:
        message = capsys.readouterr().err.strip().splitlines()[-1:]
        pytest.fail(f"{command.where}: {command.text} fails: {message} (exit {error.code})")
    assert (tmp_path / "eval" / "results.json").is_file()
    if "--video" in command.words:
        (video,) = (path for path in tmp_path.iterdir() if path.suffix in (".mp4", ".gif"))
        assert video.stat().st_size > 0
