"""``median(A,B,...)``: the middle action of several policies, as a policy spec and as
the expert of an imitation run."""

from __future__ import annotations

import numpy as np
import pytest

from agents.envs import env_settings
from agents.evaluation.metrics import rollout, summarize
from agents.evaluation.results import spec_kind
from agents.policies.baselines import Policy
from agents.policies.ensemble import (
    MedianPolicy,
    ensemble_label,
    ensemble_members,
    split_members,
)
from agents.policies.experts import PolicyExpert, PolicyExpertConfig
from agents.policies.registry import (
    is_model_spec,
    load_policy,
    model_card,
    policy_label,
    window_kwargs,
)
from trailer_env.scenes.reverse_v1 import ReverseV1Core
from trailer_env.vector import ConvoyVectorEnv

V1 = "trailer_env/Reverse-v1"
TEACHER = "agents/models/teachers/ppo_privileged_reverse_v1_n{n}_s{seed}.zip"
TEACHERS = "median(" + ",".join(TEACHER.format(n="{n}", seed=s) for s in range(3)) + ")"
PRIVILEGED = {"n_trailers": 2, "observe_params": True, "randomize": "mismatch20"}


def _constant(value: float) -> Policy:
    return lambda obs: np.full((len(obs), 1), value, dtype=np.float32)


def test_the_median_is_the_middle_action_per_row() -> None:
    obs = np.arange(8, dtype=np.float32).reshape(4, 2)
    members = [_constant(0.5), lambda o: o[:, :1] / 10, _constant(-0.2)]
    # The middle member acts 0.0, 0.2, 0.4, 0.6 row by row, between -0.2 and 0.5 but the last.
    np.testing.assert_allclose(
        MedianPolicy(members)(obs)[:, 0], [0.0, 0.2, 0.4, 0.5], rtol=0, atol=1e-7
    )
    # Two members: their mean.
    two = MedianPolicy([_constant(0.5), _constant(-0.1)])(obs)
    np.testing.assert_allclose(two[:, 0], 0.2, atol=1e-7)
    assert two.dtype == np.float32 and two.shape == (4, 1)


def test_the_spec_splits_at_its_own_commas_only() -> None:
    assert split_members("a, median(b,c) ,d") == ["a", "median(b,c)", "d"]
    assert ensemble_members("median(lqr,median(lqr,zero),zero)") == (
        "lqr",
        "median(lqr,zero)",
        "zero",
    )
    for bad, match in [
        ("median(lqr)", "at least 2 members, got 1"),
        ("median(lqr,)", "an empty member"),
        ("median(lqr,zero", "unbalanced"),
        ("median(lqr,zero))", "unbalanced"),
    ]:
        with pytest.raises(ValueError, match=match):
            ensemble_members(bad)


def test_every_spec_helper_reads_a_median() -> None:
    spec = TEACHERS.format(n=2)
    assert not is_model_spec(spec) and not is_model_spec(spec + "+mirror")
    assert spec_kind(spec) == "ensemble" and spec_kind(spec + "+mirror") == "ensemble"
    assert policy_label(spec) == "median(ppo_privileged_reverse_v1_n2_s{0,1,2})"
    assert policy_label("median(lqr,zero)+mirror") == "median(lqr, zero)+mirror"
    assert ensemble_label(["run/best_model", "run2/best_model"]) == (
        "median(run/best_model, run2/best_model)"
    )
    assert model_card(spec).empty
    window = window_kwargs("median(dagger_reverse_v1_adapt_n2,dagger_reverse_v1_adapt_n2_s0)", {})
    assert window == {"history": 16}
    with pytest.raises(ValueError, match="different windows of past frames"):
        window_kwargs("median(dagger_reverse_v1_adapt_n2,dagger_reverse_v1_n2)", {})


def test_a_median_of_one_policy_three_times_is_that_policy() -> None:
    kwargs = {"n_trailers": 2}
    alone = summarize(rollout(load_policy("lqr", V1, kwargs), V1, 10, 1000, kwargs))
    thrice = load_policy("median(lqr,lqr,lqr)", V1, kwargs)
    assert isinstance(thrice, MedianPolicy)
    together = summarize(rollout(thrice, V1, 10, 1000, kwargs))
    assert together["safe_rate"] == alone["safe_rate"]
    assert together["mean_return"] == pytest.approx(alone["mean_return"], rel=1e-5)


def test_the_teachers_median_acts_between_them() -> None:
    envs = ConvoyVectorEnv(
        ReverseV1Core,
        16,
        autoreset_mode="same_step",
        n_trailers=2,
        observe_params=True,
        randomize="mismatch20",
    )
    seen, _ = envs.reset(seed=60000)  # the task's features, then the parameters'
    assert isinstance(seen, np.ndarray)
    members = [load_policy(TEACHER.format(n=2, seed=s), V1, PRIVILEGED) for s in range(3)]
    actions = np.hstack([member(seen) for member in members])
    median = load_policy(TEACHERS.format(n=2), V1, PRIVILEGED)(seen)
    np.testing.assert_array_equal(median[:, 0], np.median(actions, axis=1).astype(np.float32))
    assert np.all(actions.min(axis=1) <= median[:, 0]) and np.all(median[:, 0] <= actions.max(1))


def test_a_median_of_privileged_teachers_labels_from_the_parameters() -> None:
    settings = {n: env_settings({"n_trailers": n, "randomize": "mismatch20"}) for n in (1, 2)}
    expert = PolicyExpert(ReverseV1Core, settings, 8, PolicyExpertConfig(TEACHERS))
    assert expert.privileged == {1, 2}
    assert all(isinstance(policy, MedianPolicy) for policy in expert.policies.values())
    mixed = "median(" + TEACHER.format(n="{n}", seed=0) + ",dagger_reverse_v1_n{n})"
    with pytest.raises(ValueError, match="only some members read the parameters"):
        PolicyExpert(ReverseV1Core, settings, 8, PolicyExpertConfig(mixed))


def test_members_that_read_the_core_are_refused() -> None:
    with pytest.raises(ValueError, match="reads the environment's core"):
        load_policy("median(lqr,lqr-adaptive)", V1, {"n_trailers": 2})
    with pytest.raises(ValueError, match="at least 2 policies"):
        MedianPolicy([_constant(0.0)])
