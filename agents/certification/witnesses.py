"""Witnesses of a certificate: any policy's action record that replays to the scene's success.

A start of a certificate (:mod:`agents.certification.certify`)
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
reads as its planner's, :meth:`~agents.artifacts.certificates.Certificate.source_of`).

Closed loop: for each witnessed start the witness policy is also re-run closed-loop on
a plant built with the adaptive Dormand-Prince integrator at ``rtol = atol =``
:data:`agents.certification.search.CLOSED_LOOP_TOLERANCE`, and the start records
whether it still succeeds (``witness_closed_loop_success``): the counterpart of the
planner's closed-loop re-planning. Under randomised physics (``randomize`` in the
certificate's ``env_kwargs``) the plant is RK4 with auto substeps at that tolerance
instead (:data:`RANDOMIZED_CLOSED_LOOP`; the Dormand-Prince core integrates one
parameter vector per batch), with the same drawn parameters.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from agents.artifacts.cards import read_model_card
from agents.artifacts.certificates import (
    FEASIBLE,
    Certified,
    WitnessClosedLoop,
    WitnessesPart,
    WitnessTally,
)
from agents.artifacts.shipped import MODELS_DIR, SEEDS_DIR
from agents.certification.replays import is_goal, replays_to_success
from agents.certification.search import CLOSED_LOOP_TOLERANCE
from agents.envs import MakeKwargs, check_env_id, make_vector_env, scene_baselines
from agents.policies.baselines import Policy
from agents.policies.registry import PaddedPolicy, load_policy, policy_label, window_kwargs
from agents.policies.sb3 import ModelPolicy, SampledPolicy
from trailer_env.benchmark import privileged_view
from trailer_env.observation import flat_observation

#: The integrator of the witnesses' closed-loop plant.
WITNESS_CLOSED_LOOP = "dopri5"
#: Its integrator under randomised physics (dopri5 integrates one parameter vector for
#: the whole batch; RK4 takes each row's drawn parameters), with auto substeps at the
#: same tolerance.
RANDOMIZED_CLOSED_LOOP = "rk4"
#: What a witness's record must do (the ``witnesses`` block's ``success``).
WITNESS_SUCCESS = (
    "the record replayed open-loop in a fresh env (gym.make, reset(seed=seed)) reaches "
    "the scene's success, as a planner's record must"
)
#: What the witnesses' closed-loop check is (its ``meaning``).
WITNESS_CLOSED_LOOP_MEANING = (
    "the witness policy (warm starts: the policy's steps, then the iLQR planner "
    "re-planning on its default model) re-run closed-loop on a plant with this "
    "integrator; per start witness_closed_loop_success"
)


def committed_witnesses(env_id: str, n_trailers: int, directory: Path = MODELS_DIR) -> list[Path]:
    """Committed models (``directory`` and its ``seeds/`` folder, the other training seeds)
    whose card names ``env_id`` and ``n_trailers``, or a range of counts holding it (a
    generalist); sorted by file name within each folder."""
    found = []
    for folder in (directory, directory / SEEDS_DIR.name):
        for path in sorted(folder.glob("*.zip")):
            card = read_model_card(path)
            trained = card.env_kwargs.n_trailers
            fits = trained == n_trailers or (
                isinstance(trained, tuple) and trained[0] <= n_trailers <= trained[1]
            )
            if card.env_id == env_id and fits:
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


@dataclasses.dataclass(frozen=True)
class WitnessRun:
    """What :func:`witness_run` recorded: actions (E, steps, action_dim) float64 as applied
    (zero after the end), lengths (E,) steps played, success (E,) reached the scene's
    success (goal scenes: ended at the goal; Reverse: all steps played, never in the
    singular band, never failed)."""

    actions: np.ndarray
    lengths: np.ndarray
    success: np.ndarray

    def record(self, row: int) -> np.ndarray:
        """Row ``row``'s actions, as many as it played."""
        return self.actions[row, : self.lengths[row]].copy()


def witness_run(
    policy: Policy, env_id: str, env_kwargs: MakeKwargs, seeds: Sequence[int]
) -> WitnessRun:
    """Play ``policy`` from ``reset(seed=seed)`` of every seed at once (one native vector
    env, one row per seed) and record the applied actions.

    Raises:
        ValueError: On an empty list of seeds (and whatever the env refuses).
    """
    if len(seeds) == 0:
        raise ValueError("witness_run needs at least one seed")
    envs = make_vector_env(env_id, len(seeds), dict(env_kwargs))
    reset_obs, _ = envs.reset(seed=[int(seed) for seed in seeds])
    obs = flat_observation(reset_obs, "witness_run")
    count, steps = len(seeds), envs.max_episode_steps
    dim = envs.settings.action_dim
    goal = is_goal(env_id)
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
        reached = np.asarray(info["is_success"])
        if goal:
            success |= ended & terminated & reached
        else:
            unsafe |= running & ((np.asarray(info["cost"]) > 0.0) | (terminated & ~reached))
            success |= ended & ~unsafe & (lengths == steps)
        running &= ~(terminated | truncated)
        if not running.any():
            break
    envs.close()
    return WitnessRun(actions, lengths, success)


class Upgrade:
    """A certificate while witnesses solve its open starts: its starts by seed (each
    feasible one naming its source) and its records, both replaced as starts are solved."""

    def __init__(self, certified: Certified) -> None:
        certificate = certified.certificate
        self.certificate = certificate
        self.env_id = certificate.env_id
        self.env_kwargs = certificate.env_kwargs.kwargs()
        self.goal = is_goal(self.env_id)
        self.actions = {int(seed): np.asarray(record) for seed, record in certified.actions.items()}
        missing = [s.seed for s in certificate.starts if s.feasible and s.seed not in self.actions]
        if missing:
            raise ValueError(f"feasible starts without an action record: {missing[:8]}")
        self.starts = {
            start.seed: start.replace(source=certificate.source_of(start))
            for start in certificate.starts
        }

    def played(self, spec: str, kwargs: MakeKwargs | None = None) -> dict[str, object]:
        """The env the witness ``spec`` plays in: the certificate's, or ``kwargs``, with a
        model's memory window (:func:`agents.policies.registry.window_kwargs`); its records
        replay in the certificate's env, whose dynamics the window does not change."""
        return window_kwargs(spec, self.env_kwargs if kwargs is None else kwargs)

    def load(self, spec: str, trust_pickle: bool = False) -> Policy:
        """The policy ``spec`` loaded for the certificate's env and n (and its window)."""
        return load_policy(spec, self.env_id, self.played(spec), trust_pickle=trust_pickle)

    def open_seeds(self) -> list[int]:
        """The starts not feasible yet, in the certificate's order."""
        return [seed for seed, start in self.starts.items() if not start.feasible]

    def solves(self, seed: int, record: np.ndarray) -> bool:
        """Whether ``record`` replays to success from ``seed`` (:func:`replays_to_success`)."""
        return replays_to_success(self.env_id, self.env_kwargs, seed, record)

    def solve(self, seed: int, record: np.ndarray, source: str, **found: int) -> None:
        """Make ``seed`` feasible with ``record``, found by ``source`` (``found``: the
        start's witness fields, ``witness_length`` and the like)."""
        replay = {"replay_success": True} if self.goal else {"replay_safe": True}
        start = self.starts[seed]
        self.starts[seed] = start.replace(status=FEASIBLE, source=source, **found, **replay)
        self.actions[seed] = record

    def mark_closed_loop(self, seeds: Iterable[int], reached: Iterable[bool]) -> None:
        """Record whether each witnessed start still succeeded on the closed-loop plant."""
        for seed, success in zip(seeds, reached, strict=True):
            start = self.starts[seed]
            self.starts[seed] = start.replace(witness_closed_loop_success=bool(success))

    @property
    def integrator(self) -> str:
        """The closed-loop plant's integrator (:func:`closed_loop_integrator`)."""
        return closed_loop_integrator(self.certificate.env_kwargs.randomize is not None)

    def plant(self) -> dict[str, object]:
        """The env keywords of the closed-loop plant: the certificate's, with the
        plant's integrator at :data:`CLOSED_LOOP_TOLERANCE`."""
        fidelity = {"integrator": self.integrator, "tolerance": CLOSED_LOOP_TOLERANCE}
        return {**self.env_kwargs, "fidelity": fidelity}

    def closed_loop_summary(self) -> WitnessClosedLoop:
        """How many witnessed starts still succeeded on the closed-loop plant."""
        checked = [
            start.witness_closed_loop_success
            for start in self.starts.values()
            if start.witness_closed_loop_success is not None
        ]
        return WitnessClosedLoop(
            integrator=self.integrator,
            tolerance=CLOSED_LOOP_TOLERANCE,
            meaning=WITNESS_CLOSED_LOOP_MEANING,
            success=sum(checked),
            of=len(checked),
        )

    def settled(self, witnesses: WitnessesPart) -> Certified:
        """The certificate with these starts (counts and sources recounted), records and
        ``witnesses`` block."""
        certificate = self.certificate.with_starts(
            tuple(self.starts.values()), sources=True, witnesses=witnesses
        )
        return Certified(certificate, dict(self.actions))


#: Most sampled episodes per (start, model) of :func:`add_witnesses`.
MAX_WITNESS_SAMPLES = 1024


def add_witnesses(
    certified: Certified,
    specs: Sequence[str],
    *,
    closed_loop: bool = True,
    trust_pickle: bool = False,
    samples: int = 0,
    sample_seed: int = 0,
) -> Certified:
    """``certified`` with the starts it leaves open (or not recoverable) tried by each
    witness in ``specs``, in order; returns a new certificate and records.

    A start whose witness record replays to success (:func:`replays_to_success`) becomes
    feasible: ``source`` the witness's label (:func:`agents.policies.registry.policy_label`),
    ``witness_length`` its steps, the record added to the records. Counts, ``ceiling``,
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
            start has no record, or ``samples`` is not an integer in
            0 .. :data:`MAX_WITNESS_SAMPLES`.
    """
    if isinstance(samples, bool) or not isinstance(samples, int):
        raise ValueError(f"samples must be an integer, got {samples!r}")
    if not 0 <= samples <= MAX_WITNESS_SAMPLES:
        raise ValueError(f"samples must be in 0 .. {MAX_WITNESS_SAMPLES}, got {samples}")
    upgrade = Upgrade(certified)
    # Load every witness first: a bad spec is refused before any start is played (and
    # none is loaded when no start is left to try).
    policies = [
        (spec, policy_label(spec), upgrade.load(spec, trust_pickle))
        for spec in (specs if upgrade.open_seeds() else [])
    ]
    started = time.perf_counter()
    runs = [
        _witness_tally(upgrade, spec, label, policy, closed_loop=closed_loop, trust=trust_pickle)
        for spec, label, policy in policies
    ]
    # Sampled draws only after every witness's own (deterministic) decisions were tried.
    for spec, label, policy in policies if samples else []:
        still = upgrade.open_seeds()
        if still and sampled(policy, sample_seed) is not None:
            witness = SampledWitness(spec, label, policy, samples, sample_seed)
            runs.append(
                _sampled_witness(
                    witness, upgrade, still, closed_loop=closed_loop, trust_pickle=trust_pickle
                )
            )
    wall_time = round(time.perf_counter() - started, 1)
    return upgrade.settled(_witnesses_block(upgrade, runs, closed_loop, wall_time))


def _witnesses_block(
    upgrade: Upgrade, runs: list[WitnessTally], closed_loop: bool, wall_time_s: float
) -> WitnessesPart:
    """The ``witnesses`` block after this pass: an earlier pass's runs, then this one's;
    earlier warm-start passes kept."""
    earlier = upgrade.certificate.witnesses
    return WitnessesPart(
        runs=(*(() if earlier is None else earlier.runs), *runs),
        success=WITNESS_SUCCESS,
        closed_loop=upgrade.closed_loop_summary() if closed_loop else None,
        wall_time_s=wall_time_s,
        warm_starts=(None if earlier is None else earlier.warm_start_passes()) or None,
    )


def _witness_tally(
    upgrade: Upgrade, spec: str, label: str, policy: Policy, *, closed_loop: bool, trust: bool
) -> WitnessTally:
    """Play one witness on the starts still open; each start whose record replays to
    success is solved (then re-run on the closed-loop plant)."""
    pending = upgrade.open_seeds()
    if not pending:
        return WitnessTally(source=label, tried=0, solved=0)
    run = witness_run(policy, upgrade.env_id, upgrade.played(spec), pending)
    solved = []
    for row, seed in enumerate(pending):
        if run.success[row] and upgrade.solves(seed, record := run.record(row)):
            upgrade.solve(seed, record, label, witness_length=int(run.lengths[row]))
            solved.append(seed)
    if solved and closed_loop:
        # A fresh copy of the policy: a stateful one (random) starts as it did above.
        again = upgrade.load(spec, trust)
        checked = witness_run(again, upgrade.env_id, upgrade.played(spec, upgrade.plant()), solved)
        upgrade.mark_closed_loop(solved, checked.success)
    return WitnessTally(source=label, tried=len(pending), solved=len(solved))


def sampled(policy: Policy, seed: int) -> Policy | None:
    """``policy`` with its actions sampled (:class:`SampledPolicy`, seeded by ``seed``): an
    SB3 model on the flat observation, alone or padded for a generalist's n; None for
    anything else (a baseline, a mirrored or sequence policy)."""
    if type(policy) is ModelPolicy:
        return SampledPolicy(policy, seed)
    if type(policy) is PaddedPolicy and type(policy.policy) is ModelPolicy:
        drawing = SampledPolicy(policy.policy, seed)
        return PaddedPolicy(drawing, policy.n, policy.top, policy.history, policy.action_dim)
    return None


@dataclasses.dataclass(frozen=True)
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
    upgrade: Upgrade,
    pending: list[int],
    *,
    closed_loop: bool,
    trust_pickle: bool,
) -> WitnessTally:
    """Play ``witness`` ``samples`` times on each pending start (one batch, rows start-major);
    a draw whose record replays to success makes its start feasible. Returns the run's
    entry of the ``witnesses`` block."""
    source = f"{witness.label} (sampled)"
    rows = [seed for seed in pending for _ in range(witness.samples)]
    run = witness_run(witness.draws(), upgrade.env_id, upgrade.played(witness.spec), rows)
    solved: dict[int, int] = {}
    for row, seed in enumerate(rows):
        if seed in solved or not run.success[row]:
            continue
        record = run.record(row)
        if not upgrade.solves(seed, record):
            continue
        solved[seed] = row
        draw = row % witness.samples
        upgrade.solve(seed, record, source, witness_length=int(run.lengths[row]), witness_draw=draw)
    if solved and closed_loop:
        # The same draws: the same seed on the same batch of rows, on the plant.
        fresh = upgrade.load(witness.spec, trust_pickle)
        plant = upgrade.played(witness.spec, upgrade.plant())
        checked = witness_run(witness.draws(fresh), upgrade.env_id, plant, rows)
        upgrade.mark_closed_loop(solved, (checked.success[row] for row in solved.values()))
    return WitnessTally(
        source=source,
        tried=len(pending),
        solved=len(solved),
        draws=witness.samples,
        sample_seed=witness.seed,
    )


def closed_loop_integrator(randomized: bool) -> str:
    """The integrator of the witnesses' closed-loop plant: dopri5, or RK4 under
    ``randomized`` physics (both at :data:`CLOSED_LOOP_TOLERANCE`)."""
    return RANDOMIZED_CLOSED_LOOP if randomized else WITNESS_CLOSED_LOOP


__all__ = [
    "MAX_WITNESS_SAMPLES",
    "RANDOMIZED_CLOSED_LOOP",
    "WITNESS_CLOSED_LOOP",
    "WITNESS_SUCCESS",
    "SampledWitness",
    "Upgrade",
    "WitnessRun",
    "add_witnesses",
    "closed_loop_integrator",
    "committed_witnesses",
    "default_witnesses",
    "sampled",
    "witness_run",
]
