"""Trained specialists as DAgger experts: policy distillation, ``--expert specialists``.

A planner labels a state with thousands of simulated steps and, for the sampling one, a
noisy action: two default ``mpc`` planners label the same states with a mean squared
difference of about 0.02 (:mod:`agents.training.imitate`). A trained specialist, one
policy per count of trailers, labels a state with one network call and the same action
every time. :class:`TeacherExpert` is such a labeller: for a range of counts
(:class:`trailer_env.mixed.MixedCore`) each row is labelled by the specialist of its own
n, reading the row's observation in that count's own layout, so a student over n = 1-6
learns from six teachers at once (policy distillation; Rusu et al., 2016, with DAgger's
states, as in Ross et al., 2011). The student learns what its teachers do, their faults
included: it is no more robust than they are to physics they were not trained on.

A teacher trained with ``observe_params=True`` (its card says so) is privileged: under
randomised physics (``agents.imitate --randomize``) it labels each row from the row's
observation with the row's parameter features appended
(:meth:`trailer_env.core.ConvoyCore.parameter_features`), what it saw in training, while
the student reads the observation alone: teacher-student distillation of a policy that
knows each episode's parameters into one that must act without them (Chen et al., 2019,
"Learning by cheating"; Lee et al., 2020).

:data:`DAGGER_EXPERTS` is the table ``agents.imitate --expert`` reads: the planners of
:data:`agents.oracles.experts.EXPERTS`, then ``specialists``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.artifacts.cards import read_card
from agents.artifacts.shipped import resolve_model
from agents.oracles.experts import EXPERTS, Expert, ExpertConfig, Labeller
from agents.policies.baselines import Policy
from agents.policies.registry import is_model_spec, load_policy
from dynamics.params import MAX_TRAILERS
from trailer_env.core import ConvoyCore
from trailer_env.json_types import JSONObject
from trailer_env.mixed import MixedCore
from trailer_env.registry import ENVIRONMENTS
from trailer_env.settings import EnvSettings

#: The count's place in a teacher spec (``dagger_reverse_v1_n{n}``).
COUNT_FIELD = "{n}"


@dataclass(frozen=True)
class TeacherConfig:
    """The specialists: a policy spec (:func:`load_policy`) with ``{n}`` where the count
    of trailers goes, e.g. the default ``dagger_reverse_v1_n{n}`` (a spec without ``{n}``
    names one policy for every count), or several, comma-separated, each but one after
    the counts it serves: ``1-3=ppo_reverse_v1_n{n},dagger_reverse_v1_n{n}`` takes the
    PPO specialists for n = 1-3 and the DAgger ones for the other counts."""

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
        for item in self.policy.split(","):
            counts_text, sep, spec = item.partition("=")
            counts = _counts(counts_text.strip(), self.policy) if sep else None
            spec = (spec if sep else item).strip()
            if not spec:
                raise ValueError(f"teacher {self.policy!r}: an item names no policy")
            try:
                spec.format(n=1)
            except (IndexError, KeyError, ValueError) as error:
                raise ValueError(
                    f"teacher {spec!r}: the only field a teacher spec may hold is "
                    f"{COUNT_FIELD} ({type(error).__name__}: {error})"
                ) from None
            items.append((counts, spec))
        if sum(counts is None for counts, _ in items) > 1:
            raise ValueError(f"teacher {self.policy!r}: more than one item without counts")
        return tuple(items)

    def spec(self, n: int) -> str:
        """The specialist of ``n`` trailers.

        Raises:
            ValueError: When no item serves ``n``.
        """
        for counts, spec in self.specs():
            if counts is None or counts[0] <= n <= counts[1]:
                return spec.format(n=n)
        raise ValueError(f"teacher {self.policy!r} names no policy for n = {n}")

    def problem(self, env_id: str, counts: list[int]) -> str | None:
        """Why these specialists cannot label the scene ``env_id`` with ``counts``
        trailers (None when they can): one policy for several counts, a count no item
        serves, or a specialist that does not load for its count (unknown, another
        scene's or n's card). Each is loaded once here, before any run writes."""
        if len(counts) > 1 and self.is_one_policy():
            return (
                f"teacher {self.policy!r} names one policy for counts {counts}: put "
                f"{COUNT_FIELD} where the count goes"
            )
        for n in counts:
            try:
                load_teacher(self.spec(n), env_id, n)
            except (ValueError, FileNotFoundError) as error:
                return f"teacher of n = {n}: {error}"
        return None

    def is_one_policy(self) -> bool:
        """Whether every count gets the same policy (one item, no ``{n}``)."""
        items = self.specs()
        return len(items) == 1 and COUNT_FIELD not in items[0][1]


def load_teacher(spec: str, env_id: str, n: int) -> tuple[Policy, bool]:
    """The specialist ``spec`` of ``n`` trailers and whether it reads the episode's
    parameter features (a model whose card's ``env_kwargs`` hold ``observe_params=True``).

    Raises:
        ValueError, FileNotFoundError: As :func:`load_policy`.
    """
    card = read_card(Path(resolve_model(spec))) if is_model_spec(spec) else {}
    privileged = bool(card.get("env_kwargs", {}).get("observe_params", False))
    kwargs: JSONObject = {"n_trailers": n, **({"observe_params": True} if privileged else {})}
    return load_policy(spec, env_id, kwargs), privileged


def _counts(text: str, policy: str) -> tuple[int, int]:
    """``N`` or ``LOW-HIGH`` as ``(low, high)`` in 1..MAX_TRAILERS."""
    low, _, high = text.partition("-")
    try:
        counts = (int(low), int(high or low))
    except ValueError:
        counts = (0, 0)
    if not 1 <= counts[0] <= counts[1] <= MAX_TRAILERS:
        raise ValueError(
            f"teacher {policy!r}: counts {text!r} are not N or LOW-HIGH in 1..{MAX_TRAILERS}"
        )
    return counts


def _env_id_of(core_class: type[ConvoyCore]) -> str:
    """The registered scene whose core is ``core_class``."""
    for env_id, env_class in ENVIRONMENTS.items():
        if env_class.core_class is core_class:
            return env_id
    raise ValueError(f"{core_class.__name__} is no registered scene's core")


class TeacherExpert:
    """Trained specialists as a labeller of a batch core's rows (one per count n).

    Args:
        core_class: The scene's core.
        settings: The settings of each count (``{n: settings}``).
        batch_size: Rows of the core labelled (E).
        config: Which specialists (:class:`TeacherConfig`).

    Raises:
        ValueError: A spec without ``{n}`` for a range of counts, or a specialist that
            does not load for its count (unknown, another scene's or n's card).
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: dict[int, EnvSettings],
        batch_size: int,
        config: TeacherConfig | None = None,
    ) -> None:
        self.config = config or TeacherConfig()
        env_id = _env_id_of(core_class)
        problem = self.config.problem(env_id, sorted(settings))
        if problem is not None:
            raise ValueError(problem)
        loaded = {n: load_teacher(self.config.spec(n), env_id, n) for n in sorted(settings)}
        self.teachers: dict[int, Policy] = {n: policy for n, (policy, _) in loaded.items()}
        #: The counts whose teacher reads the row's parameter features.
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

    def label(self, core: ConvoyCore | MixedCore) -> np.ndarray:
        """Actions (E, 1): each row's specialist at the row's own observation.

        Raises:
            ValueError: For a core of another batch size or other counts.
        """
        if core.batch_size != self.batch_size:
            raise ValueError(
                f"core has {core.batch_size} rows, the expert labels {self.batch_size}"
            )
        if not isinstance(core, MixedCore):
            ((n, teacher),) = self.teachers.items()
            seen = self._seen(n, core, slice(None))
            return np.asarray(teacher(seen), dtype=np.float64).reshape(-1, 1)
        cores = core.cores
        if sorted(cores) != sorted(self.teachers):
            raise ValueError("the teachers' counts differ from the core's")
        labels = np.zeros((self.batch_size, 1))
        for n, teacher in self.teachers.items():
            rows = np.flatnonzero(core.trailers == n)
            if rows.size:
                seen = self._seen(n, cores[n], rows)
                labels[rows] = np.asarray(teacher(seen), dtype=np.float64)
        return labels

    def _seen(self, n: int, core: ConvoyCore, rows: np.ndarray | slice) -> np.ndarray:
        """What the teacher of ``n`` reads of ``rows``: the observations, then (a
        privileged teacher) their parameter features, in the observation's precision."""
        obs = core.obs[rows]
        if n not in self.privileged:
            return obs
        return np.hstack([obs, core.parameter_features(rows).astype(obs.dtype)])


def _build_teachers(
    core_class: type[ConvoyCore],
    settings: dict[int, EnvSettings],
    batch_size: int,
    config: ExpertConfig | TeacherConfig,
    seed: int,
) -> Labeller:
    del seed  # the teachers draw no random numbers
    if not isinstance(config, TeacherConfig):
        raise TypeError(f"the specialists expert takes TeacherConfig, got {type(config).__name__}")
    return TeacherExpert(core_class, settings, batch_size, config)


#: ``--expert specialists``: the trained specialists, one per count.
SPECIALISTS = Expert(
    name="specialists",
    summary="trained policies, one per n (--teacher SPEC, default dagger_reverse_v1_n{n}): "
    "policy distillation, a network call per label (every scene; ranges of n; randomised "
    "physics, a teacher trained with observe_params reading each row's parameters)",
    config_class=TeacherConfig,
    default_config=TeacherConfig,
    build=_build_teachers,
    counts_range=True,
    # A policy acts on what it reads, so it labels any physics (a privileged one reads
    # each row's parameters).
    per_row_parameters=True,
    options=("policy",),
    any_scene=True,
)

#: Every DAgger expert by name: the planners, then the specialists.
DAGGER_EXPERTS: dict[str, Expert] = {**EXPERTS, SPECIALISTS.name: SPECIALISTS}


__all__ = ["DAGGER_EXPERTS", "SPECIALISTS", "TeacherConfig", "TeacherExpert", "load_teacher"]
