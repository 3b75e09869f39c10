"""Witnesses of a certificate: any policy's action record that replays to the scene's success.

A start of a certificate (:mod:`agents.oracles.certify`, :mod:`agents.oracles.certify_goals`)
is feasible when *some* float64 action record, replayed open-loop in a fresh env
(``gym.make(env_id, **env_kwargs)``, ``reset(seed=seed)``: a randomised certificate's
``env_kwargs`` hold its ``randomize``, so the start's parameters are drawn again), reaches
the scene's success: Reverse, a safe episode
of the full length; Dock and Coast, the goal. The planner is one source of such records;
a *witness* is another: a policy spec that :func:`agents.policies.load_policy` loads (a
baseline such as ``lqr``, a committed model such as ``ppo_dock_n2``, a model path).

:func:`witness_run` plays a policy on the given starts in one native batched env and
records each step's action as the env applies it (cast to float64 and clipped to
[-1, 1], which is what the kernel does to any action; clipping is idempotent, so the
record replays exactly the step the policy took). :func:`add_witnesses` tries the
witnesses in order on the starts a certificate leaves open (or not recoverable): a
start whose record replays to success becomes feasible, with ``source`` the witness's
label and the record kept. The planner's starts keep their records and get ``source``
the planner's name (``mpc`` or ``ilqr``; a certificate written before sources existed
reads as its planner's, :func:`start_source`).

Closed loop: for each witnessed start the witness policy is also re-run closed-loop on
a plant built with the adaptive Dormand-Prince integrator at ``rtol = atol =``
:data:`agents.oracles.certify_goals.CLOSED_LOOP_TOLERANCE`, and the start records
whether it still succeeds (``witness_closed_loop_success``): the counterpart of the
planner's closed-loop re-planning. Under randomised physics (``randomize`` in the
certificate's ``env_kwargs``) the plant is RK4 with auto substeps at that tolerance
instead (:data:`RANDOMIZED_CLOSED_LOOP`; the Dormand-Prince core integrates one
parameter vector per batch), with the same drawn parameters.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from agents.artifacts.cards import is_count_range, read_card
from agents.artifacts.certificates import (
    FEASIBLE,
    NOT_RECOVERABLE,
    OPEN,
    source_counts,
    start_source,
)
from agents.artifacts.shipped import MODELS_DIR, SEEDS_DIR
from agents.envs import check_env_id, env_settings, make_vector_env, scene_baselines
from agents.oracles.certify import replay
from agents.oracles.certify_goals import (
    CLOSED_LOOP_TOLERANCE,
    drive,
    is_goal_scene,
    replay_goal,
    reset_core,
    restart_config,
)
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.ilqr_costs import scene_horizon
from agents.policies.baselines import Policy
from agents.policies.registry import PaddedPolicy, load_policy, policy_label
from agents.policies.sb3 import ModelPolicy, SampledPolicy
from agents.progress import Progress
from trailer_env.benchmark import privileged_view
from trailer_env.core import ConvoyCore
from trailer_env.json_types import JSONObject
from trailer_env.observation import flat_observation
from trailer_env.registry import core_class_of

#: The integrator of the witnesses' closed-loop plant.
WITNESS_CLOSED_LOOP = "dopri5"
#: Its integrator under randomised physics (dopri5 integrates one parameter vector for
#: the whole batch; RK4 takes each row's drawn parameters), with auto substeps at the
#: same tolerance.
RANDOMIZED_CLOSED_LOOP = "rk4"


def committed_witnesses(env_id: str, n_trailers: int, directory: Path = MODELS_DIR) -> list[Path]:
    """Committed models (``directory`` and its ``seeds/`` folder, the other training seeds)
    whose card names ``env_id`` and ``n_trailers``, or a range of counts holding it (a
    generalist); sorted by file name within each folder."""
    found = []
    for folder in (directory, directory / SEEDS_DIR.name):
        for path in sorted(folder.glob("*.zip")):
            card = read_card(path)
            trained = card.get("env_kwargs", {}).get("n_trailers")
            fits = trained == n_trailers or (
                is_count_range(trained) and trained[0] <= n_trailers <= trained[1]
            )
            if card.get("env_id") == env_id and fits:
                found.append(path)
    return found


def default_witnesses(
    env_id: str, n_trailers: int, directory: Path = MODELS_DIR, *, randomized: bool = False
) -> list[str]:
    """The scene's default baselines (:func:`agents.envs.scene_baselines`), with
    ``randomized`` physics ``lqr-adaptive`` after them (the regulator designed for each
    start's drawn parameters; at nominal physics it is ``lqr``), then every committed model
    of that env and n (:func:`committed_witnesses`), as policy specs."""
    models = [str(path) for path in committed_witnesses(env_id, n_trailers, directory)]
    baselines = list(scene_baselines(check_env_id(env_id)))
    if randomized and "lqr" in baselines:
        baselines.append("lqr-adaptive")
    return [*baselines, *models]


@dataclass(frozen=True)
class WitnessRun:
    """What :func:`witness_run` recorded: actions (E, steps, action_dim) float64 as applied
    (zero after the end), lengths (E,) steps played, success (E,) reached the scene's
    success (goal scenes: ended at the goal; Reverse: all steps played, never in the
    singular band, never failed)."""

    actions: np.ndarray
    lengths: np.ndarray
    success: np.ndarray


def witness_run(
    policy: Policy, env_id: str, env_kwargs: JSONObject, seeds: Sequence[int]
) -> WitnessRun:
    """Play ``policy`` from ``reset(seed=seed)`` of every seed at once (one native vector
    env, one row per seed) and record the applied actions.

    Raises:
        ValueError: On an empty list of seeds (and whatever the env refuses).
    """
    if len(seeds) == 0:
        raise ValueError("witness_run needs at least one seed")
    envs = make_vector_env(env_id, len(seeds), env_kwargs)
    reset_obs, _ = envs.reset(seed=[int(seed) for seed in seeds])
    obs = flat_observation(reset_obs, "witness_run")
    count, steps = len(seeds), envs.max_episode_steps
    dim = envs.settings.action_dim
    goal = is_goal_scene(env_id)
    actions = np.zeros((count, steps, dim))
    lengths = np.zeros(count, dtype=np.int64)
    success = np.zeros(count, dtype=bool)
    unsafe = np.zeros(count, dtype=bool)
    running = np.ones(count, dtype=bool)
    observe = privileged_view(policy)
    for t in range(steps):
        seen = obs if observe is None else observe(envs.core, obs)
        raw = np.asarray(policy(seen), dtype=np.float64).reshape(count, dim)
        applied = np.clip(raw, -1.0, 1.0)  # the kernel's own clip: the record is the step
        actions[running, t] = applied[running]
        stepped, _, terminated, truncated, info = envs.step(applied)
        obs = flat_observation(stepped, "witness_run")
        lengths[running] += 1
        ended = running & (terminated | truncated)
        if goal:
            success |= ended & terminated & info["is_success"]
        else:
            unsafe |= running & (
                (info["cost"] > 0.0) | (terminated & ~np.asarray(info["is_success"]))
            )
            success |= ended & ~unsafe & (lengths == steps)
        running &= ~(terminated | truncated)
        if not running.any():
            break
    envs.close()
    return WitnessRun(actions, lengths, success)


def replays_to_success(env_id: str, env_kwargs: JSONObject, seed: int, record: np.ndarray) -> bool:
    """Whether ``record`` replayed open-loop in a fresh env from ``reset(seed=seed)``
    reaches the scene's success exactly at its last step (goal scenes) or keeps the start
    safe for the full episode (Reverse): the test the planners' records pass."""
    if is_goal_scene(env_id):
        return replay_goal(env_id, env_kwargs, seed, record) == (True, len(record))
    outcome = replay(env_id, env_kwargs, seed, record)
    return outcome.safe and outcome.length == core_class_of(env_id).max_episode_steps


def check_records(certificate: Mapping[str, Any], where: str) -> None:
    """Replay a certificate's own action records (``actions``) on its own scene, n and
    physics (its ``env_id`` and ``env_kwargs``) before they are passed on.

    Every feasible start must have a record that replays to success
    (:func:`replays_to_success`); no start that is not feasible may have one; a start
    that states its drawn parameters (``params``, randomised physics) must draw exactly
    those again at ``reset(seed=seed)``. A record swapped for another, or a certificate
    relabelled with another scene, n or physics, fails here.

    Raises:
        ValueError: Naming ``where`` and the first start whose record or parameters do
            not match what the certificate states.
    """
    env_id = check_env_id(certificate["env_id"])
    env_kwargs = dict(certificate["env_kwargs"])
    actions = certificate["actions"]
    feasible = [start["seed"] for start in certificate["starts"] if start["status"] == FEASIBLE]
    missing = [seed for seed in feasible if seed not in actions]
    if missing:
        raise ValueError(f"{where}: no action record of the feasible starts {missing[:8]}")
    extra = sorted(set(actions) - set(feasible))
    if extra:
        raise ValueError(f"{where}: action records of starts that are not feasible {extra[:8]}")
    stated = [start for start in certificate["starts"] if "params" in start]
    if stated:
        env = gym.make(env_id, **env_kwargs)
        try:
            for start in stated:
                _, info = env.reset(seed=start["seed"])
                if start["params"] != info.get("params"):
                    raise ValueError(
                        f"{where}: start {start['seed']} states parameters that "
                        f"{env_id} with {_kwargs_text(env_kwargs)} does not draw"
                    )
        finally:
            env.close()
    outcome = "the goal" if is_goal_scene(env_id) else "a safe episode of the full length"
    for seed in feasible:
        if not replays_to_success(env_id, env_kwargs, seed, np.asarray(actions[seed])):
            raise ValueError(
                f"{where}: the record of start {seed} does not replay to its stated outcome "
                f"(feasible: {outcome} on {env_id} with {_kwargs_text(env_kwargs)})"
            )


def _kwargs_text(env_kwargs: Mapping[str, Any]) -> str:
    return ", ".join(f"{key}={value!r}" for key, value in env_kwargs.items())


#: Most sampled episodes per (start, model) of :func:`add_witnesses`.
MAX_WITNESS_SAMPLES = 1024


def add_witnesses(
    certificate: JSONObject,
    specs: Sequence[str],
    *,
    closed_loop: bool = True,
    trust_pickle: bool = False,
    samples: int = 0,
    sample_seed: int = 0,
) -> JSONObject:
    """``certificate`` (with its ``actions``) with the starts it leaves open (or not
    recoverable) tried by each witness in ``specs``, in order; returns a new certificate.

    A start whose witness record replays to success (:func:`replays_to_success`) becomes
    feasible: ``source`` the witness's label (:func:`agents.policies.registry.policy_label`),
    ``witness_length`` its steps, the record added to ``actions``. Counts, ``ceiling``,
    ``sources`` (label -> feasible starts) and ``witnesses`` (what each spec was tried on
    and solved, the closed-loop check) are brought up to date; nothing else changes.

    ``samples`` > 0: then each model witness (an SB3 model on the flat observation, a
    padded generalist's included: :func:`sampled`), in order, plays each start still
    open ``samples`` times with its actions sampled from its distribution
    (:class:`agents.policies.sb3.SampledPolicy`, draws seeded by ``sample_seed``, all
    (start, draw) rows in one batch). The first draw whose record
    replays to success makes the start feasible, ``source`` ``"<label> (sampled)"`` and
    ``witness_draw`` its draw; the closed-loop check re-runs the same draws on the plant.

    Raises:
        ValueError: If a spec does not load for the certificate's env and n, a feasible
            start of ``certificate`` has no record, or ``samples`` is not an integer in
            0 .. :data:`MAX_WITNESS_SAMPLES`.
    """
    if isinstance(samples, bool) or not isinstance(samples, int):
        raise ValueError(f"samples must be an integer, got {samples!r}")
    if not 0 <= samples <= MAX_WITNESS_SAMPLES:
        raise ValueError(f"samples must be in 0 .. {MAX_WITNESS_SAMPLES}, got {samples}")
    env_id = certificate["env_id"]
    env_kwargs = dict(certificate["env_kwargs"])
    actions = {int(seed): np.asarray(record) for seed, record in certificate["actions"].items()}
    starts = [dict(start) for start in certificate["starts"]]
    missing = [s["seed"] for s in starts if s["status"] == FEASIBLE and s["seed"] not in actions]
    if missing:
        raise ValueError(f"feasible starts without an action record: {missing[:8]}")
    # Load every witness first: a bad spec is refused before any start is played (and
    # none is loaded when no start is left to try).
    anything_open = any(start["status"] != FEASIBLE for start in starts)
    policies = [
        (spec, policy_label(spec), load_policy(spec, env_id, env_kwargs, trust_pickle=trust_pickle))
        for spec in (specs if anything_open else [])
    ]
    for start in starts:
        if start["status"] == FEASIBLE:
            start["source"] = start_source(certificate, start)
    by_seed = {start["seed"]: start for start in starts}
    started = time.perf_counter()
    runs = []
    for spec, label, policy in policies:
        pending = [start["seed"] for start in starts if start["status"] != FEASIBLE]
        if not pending:
            runs.append({"source": label, "tried": 0, "solved": 0})
            continue
        run = witness_run(policy, env_id, env_kwargs, pending)
        solved = []
        for row, seed in enumerate(pending):
            if not run.success[row]:
                continue
            record = run.actions[row, : run.lengths[row]].copy()
            if not replays_to_success(env_id, env_kwargs, seed, record):
                continue
            actions[seed] = record
            start = by_seed[seed]
            start.update(status=FEASIBLE, source=label, witness_length=int(run.lengths[row]))
            start["replay_success" if is_goal_scene(env_id) else "replay_safe"] = True
            solved.append(seed)
        if solved and closed_loop:
            # A fresh copy of the policy: a stateful one (random) starts as it did above.
            again = load_policy(spec, env_id, env_kwargs, trust_pickle=trust_pickle)
            plant = {**env_kwargs, "fidelity": _closed_loop_fidelity(env_kwargs)}
            checked = witness_run(again, env_id, plant, solved)
            for seed, reached in zip(solved, checked.success, strict=True):
                by_seed[seed]["witness_closed_loop_success"] = bool(reached)
        runs.append({"source": label, "tried": len(pending), "solved": len(solved)})
    # Sampled draws only after every witness's own (deterministic) decisions were tried.
    for spec, label, policy in policies if samples else []:
        still = [start["seed"] for start in starts if start["status"] != FEASIBLE]
        if still and sampled(policy, sample_seed) is not None:
            witness = SampledWitness(spec, label, policy, samples, sample_seed)
            runs.append(
                _sampled_witness(
                    witness,
                    env_id,
                    env_kwargs,
                    still,
                    by_seed,
                    actions,
                    closed_loop=closed_loop,
                    trust_pickle=trust_pickle,
                )
            )
    block = {
        "runs": _merged_runs(certificate.get("witnesses"), runs),
        "success": "the record replayed open-loop in a fresh env (gym.make, "
        "reset(seed=seed)) reaches the scene's success, as a planner's record must",
        "closed_loop": _closed_loop_summary(starts, env_kwargs) if closed_loop else None,
        "wall_time_s": round(time.perf_counter() - started, 1),
    }
    passes = warm_start_passes(certificate.get("witnesses"))
    if passes:
        block["warm_starts"] = passes
    return _settled(certificate, starts, actions, block)


def sampled(policy: Policy, seed: int) -> Policy | None:
    """``policy`` with its actions sampled (:class:`SampledPolicy`, seeded by ``seed``): an
    SB3 model on the flat observation, alone or padded for a generalist's n; None for
    anything else (a baseline, a mirrored or sequence policy)."""
    if type(policy) is ModelPolicy:
        return SampledPolicy(policy, seed)
    if type(policy) is PaddedPolicy and type(policy.policy) is ModelPolicy:
        return PaddedPolicy(SampledPolicy(policy.policy, seed), policy.n, policy.top)
    return None


@dataclass(frozen=True)
class SampledWitness:
    """A model witness played with sampled actions: ``samples`` draws per start, seeded."""

    spec: str
    label: str
    policy: Policy
    samples: int
    seed: int

    def draws(self, policy: Policy | None = None) -> Policy:
        """The sampling policy (of ``policy``, a fresh load of the spec, if given)."""
        drawing = sampled(self.policy if policy is None else policy, self.seed)
        if drawing is None:  # pragma: no cover - checked before a SampledWitness is made
            raise TypeError(f"{self.spec} cannot be sampled")
        return drawing


def _sampled_witness(
    witness: SampledWitness,
    env_id: str,
    env_kwargs: JSONObject,
    pending: list[int],
    by_seed: dict[int, JSONObject],
    actions: dict[int, np.ndarray],
    *,
    closed_loop: bool,
    trust_pickle: bool,
) -> JSONObject:
    """Play ``witness`` ``samples`` times on each pending start (one batch, rows start-major);
    a draw whose record replays to success makes its start feasible. Returns the run's
    entry of the ``witnesses`` block."""
    source = f"{witness.label} (sampled)"
    rows = [seed for seed in pending for _ in range(witness.samples)]
    run = witness_run(witness.draws(), env_id, env_kwargs, rows)
    solved: dict[int, int] = {}
    for row, seed in enumerate(rows):
        if seed in solved or not run.success[row]:
            continue
        record = run.actions[row, : run.lengths[row]].copy()
        if not replays_to_success(env_id, env_kwargs, seed, record):
            continue
        solved[seed] = row
        actions[seed] = record
        by_seed[seed].update(
            status=FEASIBLE,
            source=source,
            witness_length=int(run.lengths[row]),
            witness_draw=row % witness.samples,
        )
        by_seed[seed]["replay_success" if is_goal_scene(env_id) else "replay_safe"] = True
    if solved and closed_loop:
        # The same draws: the same seed on the same batch of rows, on the plant.
        fresh = load_policy(witness.spec, env_id, env_kwargs, trust_pickle=trust_pickle)
        plant = {**env_kwargs, "fidelity": _closed_loop_fidelity(env_kwargs)}
        checked = witness_run(witness.draws(fresh), env_id, plant, rows)
        for seed, row in solved.items():
            by_seed[seed]["witness_closed_loop_success"] = bool(checked.success[row])
    return {
        "source": source,
        "tried": len(pending),
        "solved": len(solved),
        "draws": witness.samples,
        "sample_seed": witness.seed,
    }


def warm_start_passes(witnesses: object) -> list[JSONObject]:
    """The warm-start passes a certificate's ``witnesses`` block records, oldest first.

    Each pass of :func:`warm_start` is appended to ``warm_starts``; a certificate written
    before that kept only the last pass, as the dict ``warm_start``, which comes first.
    """
    if not isinstance(witnesses, dict):
        return []
    legacy = witnesses.get("warm_start")
    passes = [legacy] if isinstance(legacy, dict) else []
    later = witnesses.get("warm_starts")
    return passes + [p for p in (later if isinstance(later, list) else []) if isinstance(p, dict)]


def _closed_loop_summary(starts: list[JSONObject], env_kwargs: JSONObject) -> JSONObject:
    witnessed = [start for start in starts if "witness_closed_loop_success" in start]
    return {
        "integrator": _closed_loop_fidelity(env_kwargs)["integrator"],
        "tolerance": CLOSED_LOOP_TOLERANCE,
        "meaning": "the witness policy (warm starts: the policy's steps, then the iLQR "
        "planner re-planning on its default model) re-run closed-loop on a plant with this "
        "integrator; per start witness_closed_loop_success",
        "success": sum(bool(start["witness_closed_loop_success"]) for start in witnessed),
        "of": len(witnessed),
    }


def _settled(
    certificate: Mapping[str, object],
    starts: list[JSONObject],
    actions: dict[int, np.ndarray],
    witnesses: Mapping[str, object],
) -> JSONObject:
    """``certificate`` with ``starts``, ``actions`` and ``witnesses``, its counts recounted."""
    count = len(starts)
    feasible = sum(start["status"] == FEASIBLE for start in starts)
    upgraded = {
        **certificate,
        "starts": starts,
        "actions": actions,
        "feasible": feasible,
        "not_recoverable": sum(start["status"] == NOT_RECOVERABLE for start in starts),
        "open": sum(start["status"] == OPEN for start in starts),
        "ceiling": feasible / count,
        "witnesses": witnesses,
    }
    upgraded["sources"] = source_counts(upgraded)
    return upgraded


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


def warm_start(
    certificate: JSONObject,
    specs: Sequence[str],
    *,
    splits: Sequence[float] = WARM_START_SPLITS,
    config: ILQRConfig | None = None,
    restarts: int = 1,
    closed_loop: bool = True,
    trust_pickle: bool = False,
) -> JSONObject:
    """Goal scenes: the iLQR planner warm-started on the policies' trajectories, on the
    starts ``certificate`` still leaves open; returns a new certificate.

    For every open start and spec, the policy plays from ``reset(seed=seed)`` (it failed
    there, or the start would not be open); at each fraction of ``splits`` of its
    episode the iLQR planner (:func:`agents.oracles.certify_goals.drive`) takes over
    from the state the policy reached, for the steps left in the episode. All (start,
    spec, split) rows run in one batch; the starts none of them brings to the goal are
    tried again with a longer horizon (:func:`restart_config`, up to ``restarts`` times).
    A record (the policy's steps, then the planner's) that replays to success
    (:func:`replays_to_success`) makes the start feasible with ``source``
    ``"ilqr+<label>"`` and ``warm_start_steps`` the policy's steps. The pass is
    appended to the ``witnesses`` block's ``warm_starts`` (:func:`warm_start_passes`).

    Raises:
        ValueError: For a scene that is not a goal scene, a split outside (0, 1), a bad
            ``restarts``, two specs of one label or a spec that does not load.
    """
    env_id = certificate["env_id"]
    if not is_goal_scene(env_id):
        raise ValueError(f"warm starts plan with iLQR: goal scenes only, not {env_id}")
    if not splits or not all(isinstance(split, float) and 0.0 < split < 1.0 for split in splits):
        raise ValueError(f"splits must be floats in (0, 1), at least one, got {splits!r}")
    if isinstance(restarts, bool) or not isinstance(restarts, int) or restarts < 0:
        raise ValueError(f"restarts must be an integer >= 0, got {restarts!r}")
    env_kwargs = dict(certificate["env_kwargs"])
    settings = env_settings(env_kwargs)
    core_class = core_class_of(env_id)
    steps = core_class.max_episode_steps
    config = config or ILQRConfig()
    labels = [policy_label(spec) for spec in specs]
    repeated = repeated_labels(specs)
    if repeated:
        raise ValueError(f"warm-start specs must name different policies; repeated: {repeated}")
    policies = {
        label: (spec, load_policy(spec, env_id, env_kwargs, trust_pickle=trust_pickle))
        for label, spec in zip(labels, specs, strict=True)
    }
    actions = {int(seed): np.asarray(record) for seed, record in certificate["actions"].items()}
    starts = [dict(start) for start in certificate["starts"]]
    for start in starts:
        if start["status"] == FEASIBLE:
            start["source"] = start_source(certificate, start)
    by_seed = {start["seed"]: start for start in starts}
    open_seeds = [start["seed"] for start in starts if start["status"] != FEASIBLE]
    started = time.perf_counter()
    # Rows: (seed, label, the policy's prefix).
    rows: list[tuple[int, str, np.ndarray]] = []
    for label, (_, policy) in policies.items():
        if not open_seeds:
            break
        run = witness_run(policy, env_id, env_kwargs, open_seeds)
        for i, seed in enumerate(open_seeds):
            length = int(run.lengths[i])
            for k in sorted({max(1, min(length - 1, round(split * length))) for split in splits}):
                rows.append((seed, label, run.actions[i, :k].copy()))
    attempts: list[JSONObject] = []
    solved: dict[int, tuple[str, int]] = {}
    for restart in range(restarts + 1):
        pending = [row for row in rows if row[0] not in solved]
        if not pending:
            break
        retry = config if restart == 0 else restart_config(config, core_class, restart)
        core = reset_core(core_class, settings, [row[0] for row in pending])
        _prefix_states(core, [row[2] for row in pending])
        shortest = min(len(row[2]) for row in pending)
        label = f"warm start {restart}: iLQR on {len(pending)} (start, policy, split) rows"
        with Progress(steps - shortest, label) as bar:
            episodes, _ = drive(core, settings, retry, bar, steps=steps - shortest)
        found = 0
        for i, (seed, name, prefix) in enumerate(pending):
            if seed in solved or not episodes.success[i]:
                continue
            record = np.concatenate([prefix, episodes.actions[i, : episodes.lengths[i], None]])
            if len(record) > steps or not replays_to_success(env_id, env_kwargs, seed, record):
                continue
            actions[seed] = record
            solved[seed] = (name, len(prefix))
            found += 1
            by_seed[seed].update(
                status=FEASIBLE,
                source=f"ilqr+{name}",
                warm_start_steps=len(prefix),
                witness_length=len(record),
                replay_success=True,
            )
        attempts.append(
            {
                "restart": restart,
                "horizon": retry.horizon or scene_horizon(core_class),
                "iterations": retry.iterations,
                "rows": len(pending),
                "solved": found,
            }
        )
    if closed_loop and solved:
        _warm_closed_loop(env_id, env_kwargs, config, policies, solved, by_seed)
    earlier = certificate.get("witnesses")
    block = dict(earlier) if isinstance(earlier, dict) else {"runs": []}
    this_pass: JSONObject = {
        "specs": list(policies),
        "splits": list(splits),
        "open_before": len(open_seeds),
        "attempts": attempts,
        "wall_time_s": round(time.perf_counter() - started, 1),
    }
    block.pop("warm_start", None)
    block["warm_starts"] = [*warm_start_passes(earlier), this_pass]
    if closed_loop:
        block["closed_loop"] = _closed_loop_summary(starts, env_kwargs)
    return _settled(certificate, starts, actions, block)


def _warm_closed_loop(
    env_id: str,
    env_kwargs: JSONObject,
    config: ILQRConfig,
    policies: dict[str, tuple[str, Policy]],
    solved: dict[int, tuple[str, int]],
    by_seed: dict[int, JSONObject],
) -> None:
    """Re-run each solved warm start closed loop on the dopri5 plant: the policy for its
    steps (a fresh copy of it, acting on the plant's observations), then the planner
    (its model on the default fidelity, the first pass's settings) for the rest."""
    core_class = core_class_of(env_id)
    settings = env_settings(env_kwargs)
    plant_settings = env_settings({**env_kwargs, "fidelity": _closed_loop_fidelity(env_kwargs)})
    steps = core_class.max_episode_steps
    for label, (spec, _) in policies.items():
        seeds = [seed for seed, (name, _) in solved.items() if name == label]
        if not seeds:
            continue
        policy = load_policy(spec, env_id, env_kwargs)
        plant = reset_core(core_class, plant_settings, seeds)
        lengths = [solved[seed][1] for seed in seeds]
        _prefix_states(plant, [np.zeros(k) for k in lengths], policy)
        episodes, _ = drive(plant, settings, config, steps=steps - min(lengths))
        for i, seed in enumerate(seeds):
            reached = episodes.success[i] and lengths[i] + episodes.lengths[i] <= steps
            by_seed[seed]["witness_closed_loop_success"] = bool(reached)


def _closed_loop_fidelity(env_kwargs: JSONObject) -> JSONObject:
    randomized = env_kwargs.get("randomize") is not None
    integrator = RANDOMIZED_CLOSED_LOOP if randomized else WITNESS_CLOSED_LOOP
    return {"integrator": integrator, "tolerance": CLOSED_LOOP_TOLERANCE}


def _merged_runs(earlier: object, runs: list[JSONObject]) -> list[JSONObject]:
    """An earlier witness pass's runs followed by this one's (a certificate upgraded twice
    keeps both)."""
    if isinstance(earlier, dict) and isinstance(earlier.get("runs"), list):
        return [*earlier["runs"], *runs]
    return runs


__all__ = [
    "MAX_WITNESS_SAMPLES",
    "RANDOMIZED_CLOSED_LOOP",
    "WITNESS_CLOSED_LOOP",
    "SampledWitness",
    "WitnessRun",
    "add_witnesses",
    "check_records",
    "committed_witnesses",
    "default_witnesses",
    "repeated_labels",
    "replays_to_success",
    "sampled",
    "warm_start",
    "warm_start_passes",
    "witness_run",
]
