"""The examples run as written (short budgets) and end with a protocol score."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def example(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cleanrl_ppo_trains_on_the_native_batch_and_scores() -> None:
    summary = example("cleanrl_ppo").main(["--total-steps", "16384", "--episodes", "20"])
    assert summary["episodes"] == 20 and 0.0 <= summary["safe_rate"] <= 1.0
    assert summary["mean_length"] > 0


def test_torchrl_rolls_out_and_scores() -> None:
    pytest.importorskip("torchrl")
    summary = example("torchrl_rollout").main(["--steps", "50", "--episodes", "10"])
    assert summary["episodes"] == 10
    assert summary["safe_rate"] == 0.0  # an untrained network folds every reversing convoy


def test_sb3_her_trains_on_the_goal_view_and_scores() -> None:
    summary = example("sb3_her").main(["--steps", "350", "--episodes", "8"])
    assert summary["episodes"] == 8 and summary["jackknife_rate"] == 0.0


@pytest.mark.slow
def test_plain_rllib_runs_remote_runners_on_a_registered_id() -> None:
    pytest.importorskip("ray")
    summary = example("rllib_ppo").main(["--iterations", "1", "--episodes", "10"])
    assert summary["episodes"] == 10
