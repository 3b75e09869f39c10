"""A policy of your own, named ``module:name``, is scored like any other."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from agents.commands import evaluate
from agents.policies.registry import is_callable_spec, is_model_spec, load_policy, policy_label

MODULE = """
import numpy as np

def act(obs):
    return np.zeros((len(obs), 1))

not_callable = 3
"""


@pytest.fixture
def user_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    (tmp_path / "my_policy_module.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "my_policy_module"
    sys.modules.pop("my_policy_module", None)


def test_module_name_specs_are_callables_not_models(user_module: str) -> None:
    assert is_callable_spec(f"{user_module}:act") and is_callable_spec("pkg.sub:act_fn")
    assert not is_callable_spec("ppo_reverse_n2") and not is_callable_spec("a/b.zip")
    assert not is_model_spec(f"{user_module}:act")
    assert policy_label(f"{user_module}:act") == f"{user_module}:act"
    policy = load_policy(f"{user_module}:act", "trailer_env/Reverse-v1", {"n_trailers": 2})
    assert policy(__import__("numpy").ones((3, 8))).shape == (3, 1)
    with pytest.raises(ValueError, match="has no callable 'not_callable'"):
        load_policy(f"{user_module}:not_callable", "trailer_env/Reverse-v1")
    with pytest.raises(ValueError, match="cannot import 'no_such_module_here'"):
        load_policy("no_such_module_here:act", "trailer_env/Reverse-v1")


def test_evaluate_scores_a_callable(
    user_module: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "eval"
    argv = ["--policy", f"{user_module}:act", "--episodes", "5", "--out", str(out), "--no-plots"]
    assert evaluate.main(argv) == 0
    document = json.loads((out / "results.json").read_text())
    assert document["env_id"] == "trailer_env/Reverse-v1"  # the headline scene by default
    (row,) = document["policies"]
    assert row["name"] == f"{user_module}:act" and row["kind"] == "callable"
    assert row["episodes"] == 5 and row["safe_rate"] == 0.0
    with pytest.raises(SystemExit) as raised:
        evaluate.main(["--policy", "no_such_module_here:act", "--out", str(tmp_path / "x")])
    assert raised.value.code == 2
    assert "cannot import 'no_such_module_here'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
