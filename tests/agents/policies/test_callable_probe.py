"""A ``module:name`` that is no policy is refused where it is named: one line, exit 2,
nothing written (``--policy`` of evaluate, ``--expert-policy`` of imitate)."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from agents.commands import evaluate, imitate
from agents.policies.registry import load_policy

MODULE = """
import sys

import numpy as np

def exits(obs):
    sys.exit(3)

def wrong_width(obs):
    return np.zeros((len(obs), 2))

def act(obs):
    return np.zeros((len(obs), 1))
"""
REVERSE = "trailer_env/Reverse-v1"


@pytest.fixture
def user_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    (tmp_path / "not_a_policy_module.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "not_a_policy_module"
    sys.modules.pop("not_a_policy_module", None)


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("os:system", "calling it on a batch of observations raised TypeError"),
        ("{module}:exits", "raised SystemExit: 3"),
        ("{module}:wrong_width", "does not return one action per observation"),
    ],
)
def test_a_callable_that_is_no_policy_is_refused(user_module: str, name: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        load_policy(name.format(module=user_module), REVERSE, {"n_trailers": 2})
    policy = load_policy(f"{user_module}:act", REVERSE, {"n_trailers": 2})
    assert policy(__import__("numpy").zeros((4, 8))).shape == (4, 1)


def test_evaluate_and_imitate_refuse_it_and_write_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as refused:
        evaluate.main(["--policy", "os:system", "--episodes", "2", "--out", "eval", "--no-plots"])
    assert refused.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "argument --policy: policy 'os:system': calling it" in error
    argv = ["--env", REVERSE, "--n-trailers", "2", "--expert", "specialists"]
    with pytest.raises(SystemExit) as refused:
        imitate.main([*argv, "--expert-policy", "os:system", "--run-dir", "run"])
    assert refused.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "expert policy of n = 2: policy 'os:system': calling it" in error
    assert sorted(path.name for path in tmp_path.iterdir()) == []
