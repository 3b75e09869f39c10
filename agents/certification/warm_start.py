"""Warm starts: the iLQR planner handed a policy's trajectory part of the way.

A goal scene's start that every witness (:mod:`agents.certification.witnesses`) leaves
open may still be reached when a policy drives the first part of the episode and the
planner the rest: :func:`warm_start` tries every (open start, policy, split) row in one
batch and keeps a record that replays to success, as any witness's must.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence

import numpy as np

from agents.artifacts.certificates import (
    Certified,
    WarmStartAttempt,
    WarmStartPass,
    WitnessesPart,
)
from agents.certification.replays import is_goal
from agents.certification.search import drive, reset_core, restart_config
from agents.certification.witnesses import WITNESS_SUCCESS, Upgrade, witness_run
from agents.envs import env_settings
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.ilqr_costs import scene_horizon
from agents.policies.baselines import Policy
from agents.policies.registry import policy_label
from agents.progress import Progress
from trailer_env.core import ConvoyCore
from trailer_env.registry import core_class_of

#: Where a warm start hands over: these fractions of the policy's own episode.
WARM_START_SPLITS = (0.25, 0.5, 0.75)


def _prefix_states(
    core: ConvoyCore, prefixes: list[np.ndarray], policy: Policy | None = None
) -> None:
    """Step the rows of ``core`` through their prefixes: the recorded actions, or (with
    ``policy``) the policy's own actions for as many steps, closed loop."""
    longest = max(len(prefix) for prefix in prefixes)
    lengths = np.array([len(prefix) for prefix in prefixes])
    action = np.zeros((core.batch_size, core.settings.action_dim))
    for t in range(longest):
        rows = np.flatnonzero(lengths > t)
        if policy is not None:
            action[:] = np.clip(np.asarray(policy(core.obs.copy()), dtype=np.float64), -1, 1)
        else:
            for row in rows.tolist():
                action[row] = prefixes[row][t]
        core.step(action, rows)


def repeated_labels(specs: Sequence[str]) -> list[str]:
    """The policy labels (:func:`policy_label`) that more than one of ``specs`` has: a
    warm start keys its policies and sources by label, so they must differ."""
    labels = [policy_label(spec) for spec in specs]
    return sorted({label for label in labels if labels.count(label) > 1})


#: A warm start's row: (seed, the policy's label, the policy's prefix of actions).
_Row = tuple[int, str, np.ndarray]


def warm_start(
    certified: Certified,
    specs: Sequence[str],
    *,
    splits: Sequence[float] = WARM_START_SPLITS,
    config: ILQRConfig | None = None,
    restarts: int = 1,
    closed_loop: bool = True,
    trust_pickle: bool = False,
) -> Certified:
    """Goal scenes: the iLQR planner warm-started on the policies' trajectories, on the
    starts ``certified`` still leaves open; returns a new certificate and records.

    For every open start and spec, the policy plays from ``reset(seed=seed)`` (it failed
    there, or the start would not be open); at each fraction of ``splits`` of its
    episode the iLQR planner (:func:`agents.certification.search.drive`) takes over
    from the state the policy reached, for the steps left in the episode. All (start,
    spec, split) rows run in one batch; the starts none of them brings to the goal are
    tried again with a longer horizon (:func:`restart_config`, up to ``restarts`` times).
    A record (the policy's steps, then the planner's) that replays to success
    (:func:`replays_to_success`) makes the start feasible with ``source``
    ``"ilqr+<label>"`` and ``warm_start_steps`` the policy's steps. The pass is
    appended to the ``witnesses`` block's ``warm_starts``.

    Raises:
        ValueError: For a scene that is not a goal scene, a split outside (0, 1), a bad
            ``restarts``, two specs of one label or a spec that does not load.
    """
    env_id = certified.certificate.env_id
    _check_warm_start(env_id, specs, splits, restarts)
    upgrade = Upgrade(certified)
    policies = {policy_label(spec): (spec, upgrade.load(spec, trust_pickle)) for spec in specs}
    config = config or ILQRConfig()
    open_seeds = upgrade.open_seeds()
    started = time.perf_counter()
    rows = _warm_rows(upgrade, policies, open_seeds, splits)
    attempts, solved = _plan_warm_rows(upgrade, rows, config, restarts)
    if closed_loop and solved:
        _warm_closed_loop(upgrade, config, policies, solved)
    this_pass = WarmStartPass(
        specs=tuple(policies),
        splits=tuple(splits),
        open_before=len(open_seeds),
        attempts=tuple(attempts),
        wall_time_s=round(time.perf_counter() - started, 1),
    )
    earlier = upgrade.certificate.witnesses
    block = earlier or WitnessesPart(runs=(), success=WITNESS_SUCCESS, wall_time_s=0.0)
    earlier_passes = () if earlier is None else earlier.warm_start_passes()
    block = block.replace(warm_starts=(*earlier_passes, this_pass), warm_start=None)
    if closed_loop:
        block = block.replace(closed_loop=upgrade.closed_loop_summary())
    return upgrade.settled(block)


def _check_warm_start(
    env_id: str, specs: Sequence[str], splits: Sequence[float], restarts: int
) -> None:
    if not is_goal(env_id):
        raise ValueError(f"warm starts plan with iLQR: goal scenes only, not {env_id}")
    if not splits or not all(isinstance(split, float) and 0.0 < split < 1.0 for split in splits):
        raise ValueError(f"splits must be floats in (0, 1), at least one, got {splits!r}")
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    repeated = repeated_labels(specs)
    if repeated:
        raise ValueError(f"warm-start specs must name different policies; repeated: {repeated}")


def _warm_rows(
    upgrade: Upgrade,
    policies: Mapping[str, tuple[str, Policy]],
    open_seeds: list[int],
    splits: Sequence[float],
) -> list[_Row]:
    """Each policy plays every open start; its prefixes at the split fractions of its
    episode (each at least one step and one short of the episode) are the rows."""
    rows: list[_Row] = []
    for label, (spec, policy) in policies.items():
        if not open_seeds:
            break
        run = witness_run(policy, upgrade.env_id, upgrade.played(spec), open_seeds)
        for i, seed in enumerate(open_seeds):
            length = int(run.lengths[i])
            for k in sorted({max(1, min(length - 1, round(split * length))) for split in splits}):
                rows.append((seed, label, run.actions[i, :k].copy()))
    return rows


def _plan_warm_rows(
    upgrade: Upgrade, rows: list[_Row], config: ILQRConfig, restarts: int
) -> tuple[list[WarmStartAttempt], dict[int, tuple[str, int]]]:
    """Plan from every row's state, then again with longer horizons for the starts none
    solved; returns the attempts and the solved starts (seed -> (label, prefix steps))."""
    core_class = core_class_of(upgrade.env_id)
    attempts: list[WarmStartAttempt] = []
    solved: dict[int, tuple[str, int]] = {}
    for restart in range(restarts + 1):
        pending = [row for row in rows if row[0] not in solved]
        if not pending:
            break
        retry = config if restart == 0 else restart_config(config, core_class, restart)
        found = _plan_pass(upgrade, pending, retry, restart, solved)
        attempts.append(
            WarmStartAttempt(
                restart=restart,
                horizon=retry.horizon or scene_horizon(core_class),
                iterations=retry.iterations,
                rows=len(pending),
                solved=found,
            )
        )
    return attempts, solved


def _plan_pass(
    upgrade: Upgrade,
    pending: list[_Row],
    config: ILQRConfig,
    restart: int,
    solved: dict[int, tuple[str, int]],
) -> int:
    """One iLQR pass over ``pending`` from their prefixes' states; a record that replays to
    success solves its start (added to ``solved``). Returns how many it solved."""
    core_class = core_class_of(upgrade.env_id)
    settings = env_settings(dict(upgrade.env_kwargs))
    steps = core_class.max_episode_steps
    core = reset_core(core_class, settings, [row[0] for row in pending])
    _prefix_states(core, [row[2] for row in pending])
    shortest = min(len(row[2]) for row in pending)
    label = f"warm start {restart}: iLQR on {len(pending)} (start, policy, split) rows"
    with Progress(steps - shortest, label) as bar:
        episodes, _ = drive(core, settings, config, bar, steps=steps - shortest)
    found = 0
    for i, (seed, name, prefix) in enumerate(pending):
        if seed in solved or not episodes.success[i]:
            continue
        record = np.concatenate([prefix, episodes.actions[i, : episodes.lengths[i], None]])
        if len(record) > steps or not upgrade.solves(seed, record):
            continue
        solved[seed] = (name, len(prefix))
        found += 1
        upgrade.solve(
            seed,
            record,
            f"ilqr+{name}",
            warm_start_steps=len(prefix),
            witness_length=len(record),
        )
    return found


def _warm_closed_loop(
    upgrade: Upgrade,
    config: ILQRConfig,
    policies: Mapping[str, tuple[str, Policy]],
    solved: dict[int, tuple[str, int]],
) -> None:
    """Re-run each solved warm start closed loop on the dopri5 plant: the policy for its
    steps (a fresh copy of it, acting on the plant's observations), then the planner
    (its model on the default fidelity, the first pass's settings) for the rest."""
    core_class = core_class_of(upgrade.env_id)
    settings = env_settings(dict(upgrade.env_kwargs))
    plant_settings = env_settings(upgrade.plant())
    steps = core_class.max_episode_steps
    for label, (spec, _) in policies.items():
        seeds = [seed for seed, (name, _) in solved.items() if name == label]
        if not seeds:
            continue
        policy = upgrade.load(spec)
        plant = reset_core(core_class, plant_settings, seeds)
        lengths = [solved[seed][1] for seed in seeds]
        _prefix_states(plant, [np.zeros(k) for k in lengths], policy)
        episodes, _ = drive(plant, settings, config, steps=steps - min(lengths))
        reached = [
            episodes.success[i] and lengths[i] + episodes.lengths[i] <= steps
            for i in range(len(seeds))
        ]
        upgrade.mark_closed_loop(seeds, reached)


__all__ = ["WARM_START_SPLITS", "repeated_labels", "warm_start"]
