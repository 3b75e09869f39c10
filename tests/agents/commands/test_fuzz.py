"""Property tests (issue 21): random arguments and random files never end in a traceback.

* Commands: random argv for evaluate, certify, train, imitate and report either reach
  the work (stubbed here) or exit with status 2; never another exception.
* Loaders: random JSON and bytes for model cards, statistics, certificates, curves,
  policy cards, SB3 zips and hyperparameter files: each loader returns or raises
  ValueError / TypeError (UnsafeFileError is a ValueError); never another exception.

The default suite runs a short version; ``-m slow`` runs the file fuzz with many more
examples.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from agents.artifacts.cards import read_model_card
from agents.artifacts.certificates import CERTIFICATES_DIR, read_certificate
from agents.artifacts.curves import read_curve
from agents.artifacts.rllib_files import read_rllib_card
from agents.artifacts.sb3_zip import read_sb3_data
from agents.artifacts.shipped import MODELS_DIR
from agents.artifacts.stats import read_stats
from agents.commands import certify, evaluate, imitate, report, train
from agents.training.config import load_hyperparams

QUICK = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
LONG = settings(
    max_examples=1500,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


class ReachedError(Exception):
    """The command got past its checks to the work (stubbed)."""


def _reached(*args: Any, **kwargs: Any) -> Any:
    raise ReachedError


TRICKY = ["", "0", "1", "-1", "-5", "2", "1e7", "1e8", "1.5", "nan", "inf", "-inf",
          str(2**32 - 1), str(2**64), "1e999", "abc", "1000-1099999999", "1,1", "9-3",
          "0x10", " 3", "zero", "lqr", "x.zip", "out", "out/sub", ".", "garbage",
          "trailer_env/Reverse-v1", "ppo", "sac", "rllib", "\x00", "auto"]  # fmt: skip


def _argv(command: Any) -> st.SearchStrategy[list[str]]:
    parser = command.build_parser()
    flags = [
        flag
        for action in parser._actions
        for flag in action.option_strings
        if flag not in ("-h", "--help")
    ]
    value = st.one_of(st.sampled_from(TRICKY), st.text(max_size=8))
    pair = st.tuples(st.sampled_from(flags), value).map(list)
    token = st.one_of(
        pair, st.sampled_from(flags).map(lambda flag: [flag]), value.map(lambda text: [text])
    )
    required = {
        train: ["--env", "trailer_env/Reverse-v0", "--algo", "ppo"],
        certify: ["--out", "cert"],
        report: [],
    }.get(command, ["--env", "trailer_env/Reverse-v1"])
    tokens = st.lists(pair, max_size=3) | st.lists(token, max_size=5)
    return tokens.map(lambda chosen: required + [word for words in chosen for word in words])


@pytest.fixture
def stubbed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The work of every command replaced by :class:`ReachedError`, in an empty folder."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(certify, "certify", _reached)
    monkeypatch.setattr(evaluate, "evaluate_policies", _reached)
    monkeypatch.setattr(report, "evaluate_policies", _reached)
    monkeypatch.setattr(train, "train", _reached)
    monkeypatch.setattr(imitate, "imitate", _reached)
    monkeypatch.setattr("agents.training.rllib.train_rllib", _reached)
    monkeypatch.setattr(train, "limit_torch_threads", lambda threads=1: None)
    return tmp_path


def _run(command: Any, argv: list[str]) -> None:
    try:
        command.main(argv)
    except SystemExit as error:
        assert error.code in (0, 2), (argv, error.code)
    except ReachedError:
        pass


COMMANDS = [evaluate, certify, train, imitate, report]


def _check_command(command: Any, budget: Any) -> None:
    @budget
    @given(argv=_argv(command))
    def check(argv: list[str]) -> None:
        _run(command, argv)

    check()


@pytest.mark.parametrize("command", COMMANDS)
def test_random_arguments_parse_or_exit_2(command: Any, stubbed: Path) -> None:
    _check_command(command, QUICK)


@pytest.mark.slow
@pytest.mark.parametrize("command", COMMANDS)
def test_random_arguments_parse_or_exit_2_long(command: Any, stubbed: Path) -> None:
    _check_command(command, settings(LONG, max_examples=400))


# ---------------------------------------------------------------- random files

JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70) | st.floats() | st.text(max_size=6),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=12,
)


def _mutated(base: dict[str, Any]) -> st.SearchStrategy[dict[str, Any]]:
    """``base`` with one key (top level or one below) replaced by a random JSON value,
    or removed."""

    @st.composite
    def build(draw: Any) -> dict[str, Any]:
        document = json.loads(json.dumps(base))
        key = draw(st.sampled_from(sorted(document)))
        target = document
        if isinstance(document[key], dict) and document[key] and draw(st.booleans()):
            target, key = document[key], draw(st.sampled_from(sorted(document[key])))
        if draw(st.integers(0, 4)) == 0:
            del target[key]
        else:
            target[key] = draw(JSON)
        return document

    return build()


def _json_bytes(document: Any) -> bytes:
    return json.dumps(document, allow_nan=True).encode()


CARD = json.loads((MODELS_DIR / "ppo_reverse_n2.json").read_text())
STATS = json.loads((MODELS_DIR / "ppo_reverse_n2_vecnormalize.json").read_text())
CERTIFICATE = json.loads(sorted(CERTIFICATES_DIR.glob("reverse*.json"))[0].read_text())
CERTIFICATE["starts"] = CERTIFICATE["starts"][:3]
CERTIFICATE.update(episodes=3, feasible=3, open=0, not_recoverable=0, ceiling=1.0)

FILE_BYTES = st.one_of(
    st.binary(max_size=64),
    JSON.map(_json_bytes),
    _mutated(CARD).map(_json_bytes),
    _mutated(STATS).map(_json_bytes),
    _mutated(CERTIFICATE).map(_json_bytes),
)


def _zip_with_data(data: bytes) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("data", data)
    return buffer.getvalue()


def _yaml_text(document: Any) -> bytes:
    return json.dumps({"trailer_env/Reverse-v0": document}, allow_nan=True).encode()


HYPERPARAMS = {
    "n_envs": 2,
    "n_timesteps": 64,
    "policy": "MlpPolicy",
    "n_steps": 16,
    "batch_size": 16,
    "normalize": "dict(norm_obs=True)",
    "policy_kwargs": "dict(net_arch=[8])",
}


def _loaders(folder: Path) -> dict[str, tuple[Callable[[bytes], Any], st.SearchStrategy[bytes]]]:
    def at(name: str, content: bytes) -> Path:
        path = folder / name
        path.write_bytes(content)
        return path

    def rllib(content: bytes) -> Any:
        (folder / "checkpoint").mkdir(exist_ok=True)
        at("checkpoint/policy_card.json", content)
        return read_rllib_card(folder / "checkpoint")

    return {
        "card": (
            lambda content: read_model_card(at("m.json", content).with_suffix(".zip")),
            FILE_BYTES,
        ),
        "stats": (lambda content: read_stats(at("s.json", content)), FILE_BYTES),
        "certificate": (lambda content: read_certificate(at("c.json", content)), FILE_BYTES),
        "curve": (
            lambda content: read_curve(at("e.csv", content)),
            st.binary(max_size=64) | st.text(max_size=64).map(str.encode),
        ),
        "policy card": (rllib, FILE_BYTES),
        "sb3 zip": (
            lambda content: read_sb3_data(at("z.zip", content)),
            st.binary(max_size=64) | FILE_BYTES.map(_zip_with_data),
        ),
        "hyperparameters": (
            lambda content: load_hyperparams(
                "ppo", "trailer_env/Reverse-v0", at("ppo.yml", content).parent
            ),
            st.binary(max_size=64) | JSON.map(_yaml_text) | _mutated(HYPERPARAMS).map(_yaml_text),
        ),
    }


LOADERS = ["card", "stats", "certificate", "curve", "policy card", "sb3 zip", "hyperparameters"]


def _check_loader(name: str, folder: Path, budget: Any) -> None:
    load, contents = _loaders(folder)[name]

    @budget
    @given(content=contents)
    def check(content: bytes) -> None:
        try:
            result = load(content)
        except (ValueError, TypeError):
            return
        if name == "stats":  # accepted statistics are finite and well formed
            assert isinstance(result.obs_rms.mean, tuple)
            assert all(math.isfinite(x) for x in result.obs_rms.mean)

    check()


@pytest.mark.parametrize("name", LOADERS)
def test_loaders_return_or_raise_value_errors(name: str, tmp_path: Path) -> None:
    _check_loader(name, tmp_path, QUICK)


@pytest.mark.slow
@pytest.mark.parametrize("name", LOADERS)
def test_loaders_return_or_raise_value_errors_long(name: str, tmp_path: Path) -> None:
    _check_loader(name, tmp_path, LONG)
