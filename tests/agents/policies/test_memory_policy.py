"""The committed policy with a memory (``dagger_reverse_v1_memory``: a DAgger student reading
``history=16`` past frames): its actions depend on its history, it reloads to the same
actions, and it plays through agents.evaluate, score() and the SB3 adapter."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.artifacts.cards import read_model_card
from agents.artifacts.shipped import resolve_model
from agents.commands import evaluate
from agents.policies.registry import load_policy
from agents.policies.sb3 import load_model
from trailer_env.benchmark import rollout, score, summarize
from trailer_env.sb3 import ConvoySB3VecEnv

REVERSE = "trailer_env/Reverse-v1"
MEMORY = "dagger_reverse_v1_memory"
HISTORY = 16
KWARGS: dict[str, object] = {"n_trailers": 2, "randomize": "mismatch20", "history": HISTORY}


def windows_after(policy: object, seed: int, steps: int) -> np.ndarray:
    """The window the policy sees after driving ``steps`` steps of the episode ``seed``."""
    env = gym.make(REVERSE, **KWARGS)
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        obs, *_ = env.step(policy(obs[None])[0])  # type: ignore[operator]
    return obs


def test_the_card_names_the_memory() -> None:
    card = read_model_card(Path(resolve_model(MEMORY)))
    assert card.env_kwargs.history == HISTORY
    assert card.env_kwargs.randomize == "mismatch20"
    assert card.n_trailers == (1, 3)


def test_the_actions_depend_on_the_history() -> None:
    policy = load_policy(MEMORY, REVERSE, KWARGS)
    window = windows_after(policy, 1000, 30)
    d = (window.size - HISTORY) // (HISTORY + 1)
    other = windows_after(policy, 1001, 30)
    swapped = np.concatenate([window[:d], other[d:]])  # same present, another past
    at_rest = np.concatenate([window[:d], np.tile(np.append(window[:d], 0.0), HISTORY)])
    actions = policy(np.stack([window, swapped, at_rest]).astype(np.float32))
    assert abs(actions[0, 0] - actions[1, 0]) > 1e-3
    assert abs(actions[0, 0] - actions[2, 0]) > 1e-3


def test_a_saved_memory_policy_reloads_to_the_same_actions(tmp_path: Path) -> None:
    source = Path(resolve_model(MEMORY))
    for path in source.parent.glob(f"{MEMORY}*"):
        shutil.copy(path, tmp_path / path.name)
    copy = tmp_path / f"{MEMORY}.zip"
    model = load_model(copy, env_id=REVERSE, env_kwargs={**KWARGS, "n_trailers": [1, 3]})
    assert model.observation_space.shape == (13 + HISTORY * 14,)
    window = windows_after(load_policy(MEMORY, REVERSE, KWARGS), 1002, 20)
    batch = np.stack([window, window * 0.5]).astype(np.float32)
    np.testing.assert_array_equal(
        load_policy(str(copy), REVERSE, KWARGS)(batch), load_policy(MEMORY, REVERSE, KWARGS)(batch)
    )


def test_a_window_of_another_length_is_refused() -> None:
    for history in (0, 8):
        with pytest.raises(ValueError, match="history = 16 past frames"):
            load_policy(MEMORY, REVERSE, {**KWARGS, "history": history})


def test_score_and_the_sb3_adapter_play_it() -> None:
    policy = load_policy(MEMORY, REVERSE, KWARGS)
    scored = score(policy, REVERSE, 2, episodes=6, history=HISTORY)
    played = summarize(rollout(policy, REVERSE, 6, 1000, {"n_trailers": 2, "history": HISTORY}))
    assert scored.document["history"] == HISTORY
    assert scored.summary == played
    venv = ConvoySB3VecEnv(REVERSE, num_envs=3, **KWARGS)
    venv.seed(4)
    obs = venv.reset()
    np.testing.assert_array_equal(policy(obs), policy(obs.copy()))
    assert policy(obs).shape == (3, 1)


def test_evaluate_takes_the_window_from_the_card(tmp_path: Path) -> None:
    out = tmp_path / "eval"
    argv = ["--policy", MEMORY, "lqr", "--n-trailers", "2", "--episodes", "4"]
    argv += ["--set", "randomize=mismatch20", "--out", str(out), "--no-plots"]
    assert evaluate.main(argv) == 0
    document = json.loads((out / "results.json").read_text())
    assert document["env_kwargs"]["history"] == HISTORY
    rates = {row["name"]: row["safe_rate"] for row in document["policies"]}
    policy = load_policy(MEMORY, REVERSE, KWARGS)
    assert rates[MEMORY] == summarize(rollout(policy, REVERSE, 4, 1000, KWARGS))["safe_rate"]
    plain = {"n_trailers": 2, "randomize": "mismatch20"}
    lqr = load_policy("lqr", REVERSE, plain)
    assert rates["lqr"] == summarize(rollout(lqr, REVERSE, 4, 1000, plain))["safe_rate"]


def test_a_policy_without_memory_reads_the_current_frame_of_a_window() -> None:
    plain = {"n_trailers": 2, "randomize": "mismatch20"}
    for spec in ("ppo_reverse_v1_n2", "dagger_reverse_v1_general", "lqr", "lqr-adaptive"):
        alone = rollout(load_policy(spec, REVERSE, plain), REVERSE, 8, 1000, plain)
        windowed = {**plain, "history": 3}
        beside = rollout(load_policy(spec, REVERSE, windowed), REVERSE, 8, 1000, windowed)
        np.testing.assert_array_equal(alone.returns, beside.returns)
