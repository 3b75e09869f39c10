"""The committed student that adapts (``dagger_reverse_v1_adapt_n1``: DAgger from a
privileged PPO teacher that reads the episode's parameters, through a 16-frame memory):
its card and its teachers, its actions read the past, its rate under mismatch20."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.artifacts.cards import read_model_card
from agents.artifacts.shipped import MODELS_DIR, SEEDS_DIR, resolve_model
from agents.commands.reproduce import Recipe
from agents.evaluation.metrics import rollout, summarize
from agents.policies.registry import load_policy
from agents.seeds import TEST_SEED

REVERSE = "trailer_env/Reverse-v1"
STUDENT = "dagger_reverse_v1_adapt_n1"
HISTORY = 16
KWARGS: dict[str, object] = {"n_trailers": 1, "randomize": "mismatch20", "history": HISTORY}
TEACHERS = MODELS_DIR / "teachers"


def window_after(policy: object, seed: int, steps: int) -> np.ndarray:
    """The window the policy sees after driving ``steps`` steps of the episode ``seed``."""
    env = gym.make(REVERSE, **KWARGS)
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        obs, *_ = env.step(policy(obs[None])[0])  # type: ignore[operator]
    return obs


def test_each_seed_learned_from_its_own_committed_teacher() -> None:
    card = read_model_card(Path(resolve_model(STUDENT)))
    assert card.env_kwargs.history == HISTORY and card.env_kwargs.randomize == "mismatch20"
    assert card.n_trailers == 1 and card.expert == "specialists"
    assert card.selection is not None
    assert sorted(card.selection.safe_rate_per_training_seed or {}) == ["0", "1", "2"]
    for seed in (0, 1, 2):
        sibling = read_model_card(SEEDS_DIR / f"{STUDENT}_s{seed}.zip")
        teacher = f"agents/models/teachers/ppo_privileged_reverse_v1_n1_s{seed}.zip"
        assert sibling.seed == seed and sibling.planner is not None
        assert sibling.planner.policy == teacher
        teacher_card = read_model_card(TEACHERS / Path(teacher).name)
        # The teacher reads the parameters the student must infer.
        assert teacher_card.env_kwargs.other.get("observe_params") is True
        assert teacher_card.env_kwargs.randomize == "mismatch20"


def test_the_recipe_rebuilds_from_committed_files() -> None:
    recipe = Recipe.from_card(MODELS_DIR / f"{STUDENT}.json")
    assert recipe.kind == "distill" and recipe.problem is None


def test_the_actions_read_the_past() -> None:
    policy = load_policy(STUDENT, REVERSE, KWARGS)
    window = window_after(policy, 1000, 30)
    other = window_after(policy, 1001, 30)
    d = (window.size - HISTORY) // (HISTORY + 1)
    swapped = np.concatenate([window[:d], other[d:]])  # the same present, another past
    actions = policy(np.stack([window, swapped]).astype(np.float32))
    assert abs(actions[0, 0] - actions[1, 0]) > 1e-3


@pytest.mark.slow
def test_it_keeps_its_measured_share_of_the_test_starts_under_mismatch20() -> None:
    # 95 % on this machine (docs/generated/adapt_n1); within a few starts elsewhere.
    policy = load_policy(STUDENT, REVERSE, KWARGS, seed=TEST_SEED)
    rate = summarize(rollout(policy, REVERSE, 100, TEST_SEED, KWARGS))["safe_rate"]
    assert rate >= 0.92
