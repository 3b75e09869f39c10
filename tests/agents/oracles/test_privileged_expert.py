"""The privileged expert of the generalist: the planner with per-row true parameters, one
planner per n of a mixed core, and its refusals."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from agents.envs import env_settings
from agents.oracles.labellers import PrivilegedExpert
from agents.oracles.planner import PlannerConfig, SamplingPlanner
from trailer_env.mixed import MixedCore, mixed_settings, pad_observations
from trailer_env.randomize import PARAMETERS
from trailer_env.scenes.reverse_v1 import ReverseV1Core

#: Labels of the planner of main (commit be25ddb, before per-row parameters), default
#: PlannerConfig with seed 4, 6 rows started from generators seeded 50..55, three
#: planned steps each, n = 1 then n = 3 (rows of the three steps in order). Recorded on
#: one CPU: another CPU's kernels differ in the last bits (docs/reliability.md, "What
#: reproduces where"), so they are compared to LABEL_RTOL; within one process the
#: comparisons stay exact.
OLD_LABELS = [
    0.14163990804285975, 0.19492624724119342, -0.1308665401776027, 0.21271531698267407,
    0.21216224011582288, 0.07918508508769712, 0.3594773434327049, 0.14672548451635728,
    -0.2843290336341872, 0.3943674236275926, 0.2758565888436744, 0.17345176740881194,
    0.3705221945175638, 0.3793947452329257, -0.2623212737114458, 0.29612714089180836,
    0.43113710122444676, 0.016580632920278768, 0.551383897209395, -0.20825918022440731,
    0.22239048655756657, -0.0015278713285512779, -0.27541580362901447, -0.21516343021059922,
    0.6692369930984107, -0.2463988159519833, 0.2509807488710446, 0.004975282724946022,
    -0.16902773398279744, -0.18715156835974261, -0.04668610231621573, -0.2706932775417408,
    0.27024877645270695, 0.023073146536230847, -0.19963118591547763, -0.2876663269117614,
]  # fmt: skip

#: Relative tolerance of labels recorded on another CPU (AVX-512 and a generic x86-64
#: differ from the recording by at most 2.4e-14 relative).
LABEL_RTOL = 1e-9

SMALL = PlannerConfig(samples=8, elites=2, horizon=5, tail=10, seed=3)


def _started(settings, rows: int, seed: int) -> ReverseV1Core:  # type: ignore[no-untyped-def]
    core = ReverseV1Core(settings, rows)
    core.reset_rows(np.arange(rows), [np.random.default_rng(seed + k) for k in range(rows)])
    return core


def _direct(settings, values: np.ndarray, config: PlannerConfig) -> SamplingPlanner:  # type: ignore[no-untyped-def]
    """A planner built for one parameter vector (no randomisation)."""
    params = settings.params.replace(**dict(zip(PARAMETERS, values.tolist(), strict=True)))
    return SamplingPlanner(
        ReverseV1Core, dataclasses.replace(settings, params=params, randomize=None), 1, config
    )


def test_labels_without_randomisation_are_the_old_planners() -> None:
    labels = []
    for n in (1, 3):
        settings = env_settings({"n_trailers": n})
        core = _started(settings, 6, 50)
        planner = SamplingPlanner(ReverseV1Core, settings, 6, PlannerConfig(seed=4))
        assert not planner.per_row
        expert = PrivilegedExpert(ReverseV1Core, {n: settings}, 6, PlannerConfig(seed=4))
        for _ in range(3):
            action = planner.plan(core.z, core.act)
            np.testing.assert_array_equal(expert.label(core), action)
            labels.append(action)
            core.step(action)
    np.testing.assert_allclose(np.concatenate(labels)[:, 0], OLD_LABELS, rtol=LABEL_RTOL, atol=0)


def test_a_rows_label_is_that_of_a_planner_built_for_its_parameters() -> None:
    settings = env_settings({"n_trailers": 2, "randomize": "mismatch20"})
    core = _started(settings, 4, 0)
    values = core.param_values.copy()
    assert len({tuple(row) for row in values.tolist()}) == 4  # four distinct draws
    extended = SamplingPlanner(ReverseV1Core, settings, 4, SMALL)
    assert extended.per_row
    # The rollout costs of the same offsets, row by row (all rows in one batch).
    offsets = np.random.default_rng(3).normal(0.0, 0.2, (4, SMALL.samples, SMALL.horizon))
    state = np.zeros((4, extended.core.z.shape[1]))
    state[:, :4] = core.z[:, :4]
    extended._set_row_params(values)
    costs, first = extended._evaluate(state, core.act, offsets)
    extended._row_tables = None
    for row in range(4):
        direct = _direct(settings, values[row], SMALL)
        expected = direct._evaluate(
            state[row : row + 1], core.act[row : row + 1], offsets[row : row + 1]
        )
        np.testing.assert_array_equal(costs[row], expected[0][0])
        np.testing.assert_array_equal(first[row], expected[1][0])
        # And the labels of plan() (one-row planners, the same seed).
        alone = SamplingPlanner(ReverseV1Core, settings, 1, SMALL)
        label = alone.plan(core.z[row : row + 1], core.act[row : row + 1], values[row : row + 1])
        np.testing.assert_array_equal(
            label, direct.plan(core.z[row : row + 1], core.act[row : row + 1])
        )
    # The true parameters matter: nominal ones give other costs.
    nominal = SamplingPlanner(ReverseV1Core, env_settings({"n_trailers": 2}), 4, SMALL)
    assert not np.array_equal(nominal._evaluate(state, core.act, offsets)[0], costs)


def test_the_mixed_expert_plans_each_row_with_its_counts_planner() -> None:
    kwargs = {"n_trailers": (1, 3), "randomize": "mismatch20"}
    by_count = mixed_settings(kwargs)
    core = MixedCore(ReverseV1Core, by_count, 3)
    for seed in range(0, 300, 3):  # starts with one convoy of each n
        core.reset_rows(np.arange(3), [np.random.default_rng(seed + k) for k in range(3)])
        if sorted(core.trailers.tolist()) == [1, 2, 3]:
            break
    else:  # pragma: no cover - the draws are fixed
        pytest.fail("no seed gave one convoy of each n")
    expert = PrivilegedExpert(ReverseV1Core, by_count, 3, SMALL)
    labels = expert.label(core)
    assert labels.shape == (3, 1)
    for row, n in enumerate(core.trailers.tolist()):
        sub = core.cores[n]
        direct = _direct(by_count[n], sub.param_values[row], dataclasses.replace(SMALL, seed=3 + n))
        np.testing.assert_array_equal(
            labels[row], direct.plan(sub.z[row : row + 1], sub.act[row : row + 1])[0]
        )
    assert expert.simulated_steps == 3 * SMALL.steps_per_decision


def test_padded_observations_are_the_mixed_cores() -> None:
    kwargs = {"n_trailers": (1, 3)}
    core = MixedCore(ReverseV1Core, mixed_settings(kwargs), 12)
    core.reset_rows(np.arange(12), [np.random.default_rng(k) for k in range(12)])
    for n in (1, 2, 3):
        rows = np.flatnonzero(core.trailers == n)
        assert rows.size
        np.testing.assert_array_equal(
            pad_observations(core.cores[n].obs[rows], n, 3), core.obs[rows]
        )
    with pytest.raises(ValueError, match="does not fit a layout of 3"):
        pad_observations(np.zeros((1, 12), dtype=np.float32), 4, 3)


def test_bad_plan_inputs_are_refused() -> None:
    random = env_settings({"n_trailers": 1, "randomize": "mismatch20"})
    core = _started(random, 2, 0)
    planner = SamplingPlanner(ReverseV1Core, random, 2, SMALL)
    with pytest.raises(ValueError, match="needs each row's params"):
        planner.plan(core.z, core.act)
    with pytest.raises(ValueError, match=r"params must be \(2, 7\)"):
        planner.plan(core.z, core.act, np.ones((2, 6)))
    with pytest.raises(ValueError, match="finite and > 0"):
        planner.plan(core.z, core.act, -core.param_values)
    with pytest.raises(ValueError, match="rows must be distinct"):
        planner.plan(core.z, core.act, core.param_values, np.array([0, 0]))
    with pytest.raises(ValueError, match=r"rows must be in 0\.\.1"):
        planner.plan(core.z[:1], core.act[:1], core.param_values[:1], np.array([2]))
    nominal = env_settings({"n_trailers": 1})
    fixed = SamplingPlanner(ReverseV1Core, nominal, 2, SMALL)
    with pytest.raises(ValueError, match="do not randomise the physics"):
        fixed.plan(core.z, core.act, core.param_values)
    with pytest.raises(ValueError, match="needs per-row parameters"):
        fixed.core.set_row_params(np.arange(2), core.param_values)
    with pytest.raises(ValueError, match="counts differ"):
        PrivilegedExpert(ReverseV1Core, mixed_settings({"n_trailers": (1, 2)}), 2, SMALL).label(
            MixedCore(ReverseV1Core, mixed_settings({"n_trailers": (1, 3)}), 2)
        )


def test_a_subset_of_rows_is_planned_as_a_batch_of_those_rows() -> None:
    settings = env_settings({"n_trailers": 2, "randomize": "mismatch20"})
    core = _started(settings, 5, 9)
    rows = np.array([1, 3])
    subset = SamplingPlanner(ReverseV1Core, settings, 5, SMALL)
    alone = SamplingPlanner(ReverseV1Core, settings, 2, SMALL)
    for _ in range(2):  # the warm starts of the planned rows carry over
        picked = subset.plan(core.z[rows], core.act[rows], core.param_values[rows], rows)
        whole = alone.plan(core.z[rows], core.act[rows], core.param_values[rows])
        np.testing.assert_array_equal(picked, whole)
    assert not subset.mean[[0, 2, 4]].any()
