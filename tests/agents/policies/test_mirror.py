"""``<policy>+mirror``: any policy made odd under the convoy's mirror image."""

from __future__ import annotations

import numpy as np
import pytest

from agents.evaluation.metrics import rollout, summarize
from agents.policies.mirror import MirroredPolicy, split_mirror
from agents.policies.registry import is_model_spec, load_policy, model_card, policy_label
from trailer_env.mixed import pad_observations

V1 = "trailer_env/Reverse-v1"


def test_a_mirrored_policy_is_odd_and_acts_with_zero_on_a_straight_convoy() -> None:
    signs = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])

    def biased(obs: np.ndarray) -> np.ndarray:
        return np.tanh(obs @ np.arange(1.0, 7.0))[:, None] + 0.05

    policy = MirroredPolicy(biased, signs, np.array([-1.0]))
    obs = np.random.default_rng(0).normal(size=(9, 6)).astype(np.float32)
    np.testing.assert_allclose(policy(obs * signs.astype(np.float32)), -policy(obs), atol=1e-7)
    straight = np.array([[-1.0, 0.0, 0.0, 1.0, 0.0, 0.0]], dtype=np.float32)
    assert policy(straight)[0, 0] == 0.0  # the bias of 0.05 is gone
    assert biased(straight)[0, 0] != 0.0


def test_the_lqr_is_odd_already_and_the_suffix_keeps_its_episodes() -> None:
    kwargs = {"n_trailers": 2}
    plain = summarize(rollout(load_policy("lqr", V1, kwargs), V1, 20, 1000, kwargs))
    mirrored = summarize(rollout(load_policy("lqr+mirror", V1, kwargs), V1, 20, 1000, kwargs))
    assert mirrored["safe_rate"] == plain["safe_rate"]
    assert mirrored["mean_length"] == plain["mean_length"]
    assert mirrored["mean_return"] == pytest.approx(plain["mean_return"], rel=1e-4)


def test_the_suffix_is_read_by_every_spec_helper() -> None:
    assert split_mirror("lqr+mirror") == ("lqr", True)
    assert split_mirror("+mirror") == ("+mirror", False)
    assert policy_label("lqr+mirror") == "lqr+mirror"
    assert policy_label("dagger_reverse_v1_n2+mirror") == "dagger_reverse_v1_n2+mirror"
    assert is_model_spec("dagger_reverse_v1_n2+mirror") and not is_model_spec("lqr+mirror")
    assert model_card("dagger_reverse_v1_n2+mirror") == model_card("dagger_reverse_v1_n2")


def test_the_mirror_is_refused_where_it_has_no_meaning() -> None:
    with pytest.raises(ValueError, match="flat observation"):
        load_policy("lqr+mirror", V1, {"n_trailers": 2, "observation": "trailers"})
    with pytest.raises(ValueError, match="unknown policy"):
        load_policy("nothing+mirror", V1, {"n_trailers": 2})


def test_a_policy_of_a_range_of_counts_is_made_odd_in_the_padded_layout() -> None:
    kwargs = {"n_trailers": [1, 3]}
    policy = load_policy("dagger_reverse_v1_sequence+mirror", V1, kwargs)
    assert isinstance(policy, MirroredPolicy)
    padded = np.array([pad_observations(_straight(n), n, 3)[0] for n in (1, 2, 3)])
    np.testing.assert_array_equal(policy(padded), np.zeros((3, 1), dtype=np.float32))
    rng = np.random.default_rng(4)
    some = np.array(
        [pad_observations(rng.normal(size=(1, 2 + 2 * n + 2)), n, 3)[0] for n in (1, 2, 3)]
    )
    np.testing.assert_allclose(policy(some * policy.observation_signs), -policy(some), atol=1e-6)


def _straight(n: int) -> np.ndarray:
    """A straight convoy reversing at unit speed with the mass centred (one n, flat)."""
    return np.array([[-1.0, 0.0, *([0.0] * n), *([1.0] * n), 0.0, 0.0]], dtype=np.float32)
