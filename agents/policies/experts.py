"""The experts DAgger imitates (``agents.imitate --expert NAME``): one table, :data:`EXPERTS`.

Each :class:`Expert` record says which scenes it fits, what it can label (a range of
trailer counts, randomised physics), its default settings and how to build its labeller
(:class:`agents.oracles.labellers.Labeller`) for a batch core. A scene's default expert
is the first of the table that fits it (:func:`default_expert`): ``mpc`` on the Reverse
scenes, ``ilqr`` on Dock and Coast, where the sampling planner has no cost for the goal.

* ``mpc``: the sampling planner (:class:`~agents.oracles.labellers.PrivilegedExpert`):
  one planner per count of trailers, each row planned with its true parameters under
  randomised physics. Its decisions depend on its random stream (seeded with the run's
  seed) and its warm start: two planners label the same states differently (a mean
  squared difference of about 0.02 for the default planner).
* ``ilqr``: the deterministic iLQR planner (:class:`~agents.oracles.labellers.ILQRExpert`),
  with ``reuse=False`` by default, so that a label is a function of the state alone. It
  plans one count of trailers with the nominal parameters: a range of counts and
  randomised physical parameters are refused (:meth:`Expert.problem`).
* ``specialists``: trained policies, one per count of trailers (:class:`PolicyExpert`,
  ``--expert-policy SPEC``): a label is one network call and the same action every time. For a
  range of counts (:class:`trailer_env.mixed.MixedCore`) each row is labelled by the
  policy of its own n, reading the row's observation in that count's own layout, so a
  student over n = 1-6 learns from six policies at once (policy distillation; Rusu et
  al., 2016, with DAgger's states, as in Ross et al., 2011). The student learns what
  they do, their faults included. A policy trained with ``observe_params=True`` (its card
  says so) is privileged: under randomised physics it labels each row from the row's
  observation with the row's parameter features appended
  (:meth:`trailer_env.core.ConvoyCore.parameter_features`), what it saw in training, while
  the student reads the observation alone (Chen et al., 2019, "Learning by cheating";
  Lee et al., 2020).

A planner fits a scene when its name is among the scene record's ``planners``
(:data:`agents.oracles.scenes.SCENE_ORACLES` says which planners have a cost for it);
the trained policies fit every scene.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.artifacts.cards import ModelCard, read_model_card
from agents.artifacts.shipped import resolve_model
from agents.oracles.ilqr import ILQRConfig
from agents.oracles.labellers import (
    ILQRExpert,
    Labeller,
    PrivilegedExpert,
    randomised_parameters,
)
from agents.oracles.planner import PlannerConfig
from agents.oracles.scenes import scene_oracle
from agents.policies.baselines import Policy
from agents.policies.ensemble import ensemble_members, is_ensemble_spec, split_members
from agents.policies.mirror import split_mirror
from agents.policies.registry import is_model_spec, load_policy
from dynamics.params import MAX_TRAILERS
from trailer_env.core import ConvoyCore
from trailer_env.core_protocol import BatchCore
from trailer_env.registry import ENVIRONMENTS
from trailer_env.settings import EnvSettings

#: The count's place in an expert policy's spec (``dagger_reverse_v1_n{n}``).
COUNT_FIELD = "{n}"


@dataclass(frozen=True)
class PolicyExpertConfig:
    """The trained policies of the ``specialists`` expert: a policy spec
    (:func:`load_policy`) with ``{n}`` where the count of trailers goes, e.g. the default
    ``dagger_reverse_v1_n{n}`` (a spec without ``{n}`` names one policy for every count),
    or several, comma-separated, each but one after the counts it serves:
    ``1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}`` takes the PPO policies for n = 1-3
    and the DAgger ones for the other counts. A spec may be ``median(A,B,...)``
    (:mod:`agents.policies.ensemble`): its commas stay inside it, and each label is the
    middle of its members' actions."""

    policy: str = "dagger_reverse_v1_n{n}"

    def __post_init__(self) -> None:
        if not isinstance(self.policy, str):
            raise TypeError(f"policy must be a str, got {type(self.policy).__name__}")
        self.specs()  # a malformed list fails here, named

    def specs(self) -> tuple[tuple[tuple[int, int] | None, str], ...]:
        """``((counts or None for the default, spec), ...)`` in the given order.

        Raises:
            ValueError: An empty item, counts that are not ``N`` or ``LOW-HIGH`` in
                1..MAX_TRAILERS, two defaults, or a field other than ``{n}``.
        """
        items: list[tuple[tuple[int, int] | None, str]] = []
        for item in split_members(self.policy):
            counts_text, sep, spec = item.partition("=")
            counts = _counts(counts_text.strip(), self.policy) if sep else None
            spec = (spec if sep else item).strip()
            if not spec:
                raise ValueError(f"expert policies {self.policy!r}: an item names no policy")
            try:
                spec.format(n=1)
            except (IndexError, KeyError, ValueError) as error:
                raise ValueError(
                    f"expert policy {spec!r}: the only field a policy spec may hold is "
                    f"{COUNT_FIELD} ({type(error).__name__}: {error})"
                ) from None
            items.append((counts, spec))
        if sum(counts is None for counts, _ in items) > 1:
            raise ValueError(f"expert policies {self.policy!r}: more than one item without counts")
        return tuple(items)

    def spec(self, n: int) -> str:
        """The policy of ``n`` trailers.

        Raises:
            ValueError: When no item serves ``n``.
        """
        for counts, spec in self.specs():
            if counts is None or counts[0] <= n <= counts[1]:
                return spec.format(n=n)
        raise ValueError(f"expert policies {self.policy!r} name no policy for n = {n}")

    def problem(self, env_id: str, counts: list[int]) -> str | None:
        """Why these policies cannot label the scene ``env_id`` with ``counts``
        trailers (None when they can): one policy for several counts, a count no item
        serves, or a policy that does not load for its count (unknown, another
        scene's or n's card). Each is loaded once here, before any run writes."""
        if len(counts) > 1 and self.is_one_policy():
            return (
                f"expert policies {self.policy!r} name one policy for counts {counts}: put "
                f"{COUNT_FIELD} where the count goes"
            )
        for n in counts:
            try:
                load_expert_policy(self.spec(n), env_id, n)
            except (ValueError, FileNotFoundError) as error:
                return f"expert policy of n = {n}: {error}"
        return None

    def is_one_policy(self) -> bool:
        """Whether every count gets the same policy (one item, no ``{n}``)."""
        items = self.specs()
        return len(items) == 1 and COUNT_FIELD not in items[0][1]


def load_expert_policy(spec: str, env_id: str, n: int) -> tuple[Policy, bool]:
    """The expert policy ``spec`` of ``n`` trailers and whether it reads the episode's
    parameter features (a model whose card's ``env_kwargs`` hold ``observe_params=True``).

    Raises:
        ValueError, FileNotFoundError: As :func:`load_policy`.
    """
    privileged = _reads_parameters(spec)
    kwargs: dict[str, object] = {"n_trailers": n}
    if privileged:
        kwargs.update(observe_params=True)
    return load_policy(spec, env_id, kwargs), privileged


def _reads_parameters(spec: str) -> bool:
    """Whether the policy ``spec`` reads the parameter features (its card's ``env_kwargs``
    hold ``observe_params=True``; a median's members all do).

    Raises:
        ValueError: A median whose members differ in this.
    """
    base, _ = split_mirror(spec)
    if is_ensemble_spec(base):
        members = {member: _reads_parameters(member) for member in ensemble_members(base)}
        if len(set(members.values())) > 1:
            readers = ", ".join(member for member, reads in members.items() if reads)
            raise ValueError(
                f"expert policy {spec!r}: only some members read the parameters ({readers})"
            )
        return next(iter(members.values()))
    card = read_model_card(Path(resolve_model(base))) if is_model_spec(base) else ModelCard()
    return card.env_kwargs.other.get("observe_params") is True


def _counts(text: str, policy: str) -> tuple[int, int]:
    """``N`` or ``LOW-HIGH`` as ``(low, high)`` in 1..MAX_TRAILERS."""
    low, _, high = text.partition("-")
    try:
        counts = (int(low), int(high or low))
    except ValueError:
        counts = (0, 0)
    if not 1 <= counts[0] <= counts[1] <= MAX_TRAILERS:
        raise ValueError(
            f"expert policies {policy!r}: counts {text!r} are not N or LOW-HIGH in "
            f"1..{MAX_TRAILERS}"
        )
    return counts


def _env_id_of(core_class: type[ConvoyCore]) -> str:
    """The registered scene whose core is ``core_class``."""
    for env_id, env_class in ENVIRONMENTS.items():
        if env_class.core_class is core_class:
            return env_id
    raise ValueError(f"{core_class.__name__} is no registered scene's core")


class PolicyExpert:
    """Trained policies as a labeller of a batch core's rows (one per count n).

    Args:
        core_class: The scene's core.
        settings: The settings of each count (``{n: settings}``).
        batch_size: Rows of the core labelled (E).
        config: Which policies (:class:`PolicyExpertConfig`).

    Raises:
        ValueError: A spec without ``{n}`` for a range of counts, or a policy that
            does not load for its count (unknown, another scene's or n's card).
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: dict[int, EnvSettings],
        batch_size: int,
        config: PolicyExpertConfig | None = None,
    ) -> None:
        self.config = config or PolicyExpertConfig()
        env_id = _env_id_of(core_class)
        problem = self.config.problem(env_id, sorted(settings))
        if problem is not None:
            raise ValueError(problem)
        loaded = {n: load_expert_policy(self.config.spec(n), env_id, n) for n in sorted(settings)}
        self.policies: dict[int, Policy] = {n: policy for n, (policy, _) in loaded.items()}
        #: The counts whose policy reads the row's parameter features.
        self.privileged = {n for n, (_, privileged) in loaded.items() if privileged}
        self.batch_size = batch_size

    @property
    def simulated_steps(self) -> int:
        return 0  # a label is a network call, not a simulation

    @property
    def steps_per_label(self) -> int:
        return 0

    def reset(self, rows: np.ndarray | None = None) -> None:
        del rows  # a policy of the observation keeps no warm start

    def random_streams(self) -> list[np.random.Generator]:
        return []  # deterministic: a label is a function of the observation

    def label(self, core: BatchCore) -> np.ndarray:
        """Actions (E, 1): each row's policy at the row's own observation.

        Raises:
            ValueError: For a core of another batch size or other counts.
        """
        if core.batch_size != self.batch_size:
            raise ValueError(
                f"core has {core.batch_size} rows, the expert labels {self.batch_size}"
            )
        if len(core.counts) == 1:
            ((n, policy),) = self.policies.items()
            seen = self._seen(n, core.row_core(0), slice(None))
            return np.asarray(policy(seen), dtype=np.float64).reshape(-1, 1)
        cores = core.count_cores()
        if sorted(cores) != sorted(self.policies):
            raise ValueError("the expert policies' counts differ from the core's")
        labels = np.zeros((self.batch_size, 1))
        for n, policy in self.policies.items():
            rows = np.flatnonzero(core.trailers == n)
            if rows.size:
                seen = self._seen(n, cores[n], rows)
                labels[rows] = np.asarray(policy(seen), dtype=np.float64)
        return labels

    def _seen(self, n: int, core: ConvoyCore, rows: np.ndarray | slice) -> np.ndarray:
        """What the policy of ``n`` reads of ``rows``: the observations, then (a
        privileged policy) their parameter features, in the observation's precision."""
        obs = core.obs[rows]
        if n not in self.privileged:
            return obs
        return np.hstack([obs, core.parameter_features(rows).astype(obs.dtype)])


#: The settings of an expert: a planner's, or the trained policies' specs.
ExpertConfig = PlannerConfig | ILQRConfig | PolicyExpertConfig


@dataclass(frozen=True)
class Expert:
    """One expert of :data:`EXPERTS`.

    Attributes:
        name: The ``--expert`` name (also the scene record's ``planners`` entry).
        summary: One line for the help.
        config_class: The type of its settings.
        default_config: Its settings when none are given.
        build: ``build(core_class, settings_by_count, batch_size, config, seed)``: the
            labeller (``seed``: the run's, for experts that draw random numbers).
        counts_range: Whether it labels a range of trailer counts (a generalist).
        per_row_parameters: Whether it plans each row with its own physical parameters.
        options: The ``--planner-*`` options of ``agents.imitate`` it takes (the
            :class:`ExpertConfig` fields they set).
        complete: The fields the given options imply (mpc: the elites follow the samples).
        any_scene: Whether it fits every scene (trained policies,
            :class:`PolicyExpert`), not only those with a cost for it.
    """

    name: str
    summary: str
    config_class: type[ExpertConfig]
    default_config: Callable[[], ExpertConfig]
    build: Callable[[type[ConvoyCore], dict[int, EnvSettings], int, ExpertConfig, int], Labeller]
    counts_range: bool
    per_row_parameters: bool
    options: tuple[str, ...]
    complete: Callable[[dict[str, int | str]], dict[str, int | str]] = dict
    any_scene: bool = False

    def fits(self, env_id: str) -> bool:
        """Whether the scene of ``env_id`` has a cost for this planner (an expert that is
        not a planner, ``any_scene``, fits every scene)."""
        return self.any_scene or self.name in scene_oracle(env_id).planners

    def problem(
        self,
        env_id: str,
        n_trailers: int | tuple[int, int],
        randomize: str | dict[str, object] | None,
    ) -> str | None:
        """Why this expert cannot label the env (None when it can); ``randomize`` must
        already be valid (:meth:`Randomization.coerce`)."""
        if not self.fits(env_id):
            fitting = [name for name, expert in _planners() if expert.fits(env_id)]
            choice = f"use {' or '.join(fitting)}" if fitting else "no expert fits it"
            return f"the {self.name} expert has no cost for {env_id}; {choice}"
        if isinstance(n_trailers, tuple) and not self.counts_range:
            return (
                f"the {self.name} expert labels one count of trailers, not a range "
                f"({n_trailers[0]}-{n_trailers[1]}); use one n or --expert mpc"
            )
        if randomised_parameters(randomize) and not self.per_row_parameters:
            return (
                f"the {self.name} expert plans with the nominal parameters: it cannot "
                "label randomised physical parameters; use --expert mpc"
            )
        return None

    def configure(self, **options: int | str | None) -> ExpertConfig:
        """The default settings with the given ``--planner-*`` options (None: not given).

        Raises:
            TypeError: For an option this expert does not take (named).
            ValueError: For a value its settings refuse.
        """
        given = {key: value for key, value in options.items() if value is not None}
        unknown = sorted(set(given) - set(self.options))
        if unknown:
            raise TypeError(
                f"the {self.name} expert takes no planner option {unknown[0]!r} "
                f"(it takes {', '.join(self.options)})"
            )
        # dataclasses.replace checks the fields (TypeError naming an unknown one).
        changes = self.complete(given)  # the fields of this expert's own settings
        return dataclasses.replace(self.default_config(), **changes)  # type: ignore[arg-type]


def _mpc_fields(given: dict[str, int | str]) -> dict[str, int | str]:
    """A quarter of the candidates are the elites, as in the default (4 of 16)."""
    samples = given.get("samples")
    if not isinstance(samples, int):
        return dict(given)
    return {**given, "elites": max(1, samples // 4)}


def _build_mpc(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig,
    seed: int,
) -> Labeller:
    if not isinstance(config, PlannerConfig):
        raise TypeError(f"the mpc expert takes PlannerConfig, got {type(config).__name__}")
    return PrivilegedExpert(
        core_class, settings, batch_size, dataclasses.replace(config, seed=seed)
    )


def _build_ilqr(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig,
    seed: int,
) -> Labeller:
    del seed  # the planner draws no random numbers
    if not isinstance(config, ILQRConfig):
        raise TypeError(f"the ilqr expert takes ILQRConfig, got {type(config).__name__}")
    return ILQRExpert(core_class, settings, batch_size, config)


def _build_policies(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig | PolicyExpertConfig,
    seed: int,
) -> Labeller:
    del seed  # the policies draw no random numbers
    if not isinstance(config, PolicyExpertConfig):
        raise TypeError(
            f"the specialists expert takes PolicyExpertConfig, got {type(config).__name__}"
        )
    return PolicyExpert(core_class, settings, batch_size, config)


#: The experts by name, in the order a scene's default is chosen (:func:`default_expert`):
#: the planners, then the trained policies.
EXPERTS: dict[str, Expert] = {
    "mpc": Expert(
        name="mpc",
        summary="the sampling planner (Reverse scenes; per-row parameters, ranges of n)",
        config_class=PlannerConfig,
        default_config=PlannerConfig,
        build=_build_mpc,
        counts_range=True,
        per_row_parameters=True,
        options=("samples", "iterations"),
        complete=_mpc_fields,
    ),
    "ilqr": Expert(
        name="ilqr",
        summary="the deterministic iLQR planner, a label per state (Reverse, Dock, Coast; one n)",
        config_class=ILQRConfig,
        default_config=lambda: ILQRConfig(reuse=False),
        build=_build_ilqr,
        counts_range=False,
        per_row_parameters=False,
        options=("iterations", "horizon"),
    ),
    "specialists": Expert(
        name="specialists",
        summary="trained policies, one per n (--expert-policy SPEC, default "
        "dagger_reverse_v1_n{n}): "
        "policy distillation, a network call per label (every scene; ranges of n; "
        "randomised physics, a policy trained with observe_params reading each row's "
        "parameters)",
        config_class=PolicyExpertConfig,
        default_config=PolicyExpertConfig,
        build=_build_policies,
        counts_range=True,
        # A policy acts on what it reads, so it labels any physics (a privileged one
        # reads each row's parameters).
        per_row_parameters=True,
        options=("policy",),
        any_scene=True,
    ),
}


def _planners() -> list[tuple[str, Expert]]:
    """The experts that plan (those with a cost for some scenes only), in table order."""
    return [(name, expert) for name, expert in EXPERTS.items() if not expert.any_scene]


def default_expert(env_id: str) -> str:
    """The first planner of :data:`EXPERTS` that fits the scene of ``env_id`` (trained
    policies are an expert only when asked for).

    Raises:
        ValueError: When none fits (naming the scene).
    """
    for name, expert in _planners():
        if expert.fits(env_id):
            return name
    planners = sorted(name for name, _ in _planners())
    raise ValueError(f"{env_id} has no planner to imitate (no expert of {planners} fits it)")


__all__ = [
    "EXPERTS",
    "Expert",
    "ExpertConfig",
    "PolicyExpert",
    "PolicyExpertConfig",
    "default_expert",
    "load_expert_policy",
]
