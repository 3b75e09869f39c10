"""The table of algorithms: what a record derives from its class rather than states."""

from __future__ import annotations

from agents.algorithms import ALGOS, Algorithm, algo_class


def test_the_replay_buffer_follows_the_class() -> None:
    assert {name: record.off_policy for name, record in ALGOS.items()} == {
        "ppo": False,
        "ppo_lag": False,
        "sac": True,
        "td3": True,
    }
    assert algo_class("sac").__name__ == "SAC"


def test_a_new_algorithm_is_one_record() -> None:
    """A record of a class the table does not hold says its kind without being told."""
    ddpg = Algorithm("ddpg", "stable_baselines3", "DDPG", "stable_baselines3.td3.policies", "DDPG")
    a2c = Algorithm("a2c", "stable_baselines3", "A2C", "stable_baselines3.common.policies", "A2C")
    assert ddpg.off_policy is True and a2c.off_policy is False
    assert ddpg.load_class().__name__ == "DDPG"
