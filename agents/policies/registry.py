"""The policy registry: a baseline by name, a saved model by path or shipped stem, or a
callable of your own as ``module:name``.

``load_policy("lqr", ...)`` and ``load_policy("agents/models/sac_reverse_n2.zip", ...)``
both return a batched :data:`agents.policies.baselines.Policy`. A saved model may carry a
*model card*, a JSON file beside it (same stem; names in :mod:`agents.artifacts`), that
records the algorithm, environment, seed, budget and wall time of its training.
Models load without unpickling anything unless the caller trusts the file
(:mod:`agents.artifacts`); RLlib checkpoints come from :mod:`agents.training.rllib`.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Mapping
from pathlib import Path
from typing import cast

import numpy as np

from agents.artifacts.cards import ModelCard, read_model_card
from agents.artifacts.curves import CURVE_COLUMNS, read_curve
from agents.artifacts.paths import curve_path, stats_path
from agents.artifacts.run_folder import CONFIG_FILE, RLLIB_CHECKPOINT
from agents.artifacts.shipped import resolve_model, shipped_models
from agents.envs import (
    check_env_id,
    env_settings,
    make_vector_env,
)
from agents.policies.baselines import BASELINES, Policy, make_baseline
from agents.policies.ensemble import (
    MedianPolicy,
    ensemble_label,
    ensemble_members,
    is_ensemble_spec,
)
from agents.policies.mirror import MIRROR_SUFFIX, MirroredPolicy, mirror_signs_of, split_mirror
from agents.policies.sb3 import ModelPolicy, TrailersPolicy, load_model, load_stats
from dynamics.params import MAX_TRAILERS, bounded_integer
from trailer_env.mixed import (
    is_trailer_range,
    pad_observations,
    pad_window_observations,
    trailer_range,
)
from trailer_env.vector import as_action_batch

#: The ``gym.make`` keywords the registry reads from an env's keywords.
N_TRAILERS = "n_trailers"
OBSERVATION = "observation"
#: The observation of the sequence models (a Dict of per-trailer rows).
TRAILERS_OBSERVATION = "trailers"

#: ``package.module:attribute`` (the form of console-script entry points).
_CALLABLE_SPEC = re.compile(r"[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*")


def is_callable_spec(spec: str) -> bool:
    """Whether ``spec`` names a Python callable as ``module:name`` (e.g. ``my_policy:act``)."""
    return _CALLABLE_SPEC.fullmatch(spec) is not None and not Path(spec).exists()


def load_callable(spec: str) -> Policy:
    """The batched policy ``module:name`` names (the module imported from ``sys.path``,
    which holds the working folder under ``python -m``): a callable mapping observations
    (K, obs_dim) to actions (see :func:`trailer_env.benchmark.per_observation`).

    Importing runs the module's code: name only modules you trust, as for any import.

    Raises:
        ValueError: If the module cannot be imported (not found, or its code raised,
            ``sys.exit()`` included: the exception is named) or has no such callable.
    """
    module_name, _, attribute = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ValueError(f"policy {spec!r}: cannot import {module_name!r}: {error}") from None
    except (Exception, SystemExit) as error:  # its own code failed; KeyboardInterrupt passes
        raise ValueError(
            f"policy {spec!r}: importing {module_name!r} raised {type(error).__name__}: {error}"
        ) from None
    policy = getattr(module, attribute, None)
    if not callable(policy):
        raise ValueError(f"policy {spec!r}: {module_name} has no callable {attribute!r}")
    return policy


def check_callable(
    policy: Policy, spec: str, env_id: str, env_kwargs: Mapping[str, object]
) -> None:
    """Call the policy ``spec`` names once on a start of the environment (seed 0) and
    check that it returns one action per observation, so that a callable that is no
    policy (``os:system``) is refused where it is named, not in the middle of a run.

    Raises:
        ValueError: If the call raises (``sys.exit()`` included: the exception is named)
            or returns anything but actions of the env's shape.
    """
    probe = make_vector_env(env_id, 1, env_kwargs)
    observation, _ = probe.reset(seed=0)
    action_dim = probe.settings.action_dim
    probe.close()
    try:
        # A Dict observation (observation="trailers") is passed on as the env gives it.
        actions = policy(cast("np.ndarray", observation))
    except (Exception, SystemExit) as error:  # its own code failed; KeyboardInterrupt passes
        raise ValueError(
            f"policy {spec!r}: calling it on a batch of observations raised "
            f"{type(error).__name__}: {str(error)[:200]}"
        ) from None
    try:
        as_action_batch(actions, 1, action_dim)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"policy {spec!r} does not return one action per observation: {error}"
        ) from None


def is_model_spec(spec: str) -> bool:
    """Whether ``spec`` names a model (file, shipped stem or RLlib folder), not a baseline
    (``<spec>+mirror``: whether ``<spec>`` does)."""
    spec, _ = split_mirror(spec)
    if spec in BASELINES or is_callable_spec(spec) or is_ensemble_spec(spec):
        return False
    return (
        spec.endswith(".zip")
        or "/" in spec
        or Path(spec).suffix != ""
        or (resolve_model(spec) != spec or Path(spec).is_dir())
    )


def policy_label(spec: str) -> str:
    """Short name of a policy spec for tables: the baseline name or the model's file stem,
    ``<run>/<stem>`` for a model in a run folder (``best_model`` and ``final_model`` of
    two runs stay apart), then ``+mirror`` if it asks for the mirror."""
    base, mirrored = split_mirror(spec)
    if mirrored:
        return policy_label(base) + MIRROR_SUFFIX
    if is_ensemble_spec(spec):
        return ensemble_label([policy_label(member) for member in ensemble_members(spec)])
    if not is_model_spec(spec):
        return spec
    path = Path(resolve_model(spec))
    if path.is_dir() and path.name == RLLIB_CHECKPOINT:
        return path.resolve().parent.name  # an RLlib run's checkpoint: the run's name
    if (path.parent / CONFIG_FILE).is_file():
        return f"{path.resolve().parent.name}/{path.stem}"
    return path.stem


def check_trained_on(
    card: ModelCard, spec: str, env_id: str, env_kwargs: Mapping[str, object]
) -> None:
    """Refuse a model whose card names another environment id or number of trailers.

    Raises:
        ValueError: On a mismatch (observations of equal length do not make two scenes
            alike: a Reverse-v0 model and Dock-v0 both see 8 numbers with n = 2).
    """
    if card.empty:
        return
    trained_id = card.env_id
    trained_n: object = card.n_trailers
    wanted_n: object = _wanted_trailers(env_kwargs)
    if isinstance(card.n_trailers, tuple):
        low, high = card.n_trailers
        if isinstance(wanted_n, int) and wanted_n > high:
            raise ValueError(
                f"model {spec} is a generalist over n_trailers = {low}..{high}: its padded "
                f"observation holds at most {high} trailers, so it cannot act with "
                f"n_trailers = {wanted_n}"
            )
        if isinstance(wanted_n, int) and low <= wanted_n <= high:
            trained_n = wanted_n  # a generalist, run on one of its counts (padded)
        else:
            trained_n = [low, high]
            wanted_n = list(wanted_n) if isinstance(wanted_n, tuple) else wanted_n
    if (trained_id is not None and trained_id != env_id) or (
        trained_n is not None and trained_n != wanted_n
    ):
        raise ValueError(
            f"model {spec} was trained on {trained_id} with n_trailers = {trained_n}, not "
            f"{env_id} with n_trailers = {wanted_n}; pass --force to evaluate it anyway"
        )


def _wanted_trailers(env_kwargs: Mapping[str, object]) -> int | tuple[int, int]:
    """The env's ``n_trailers``: one count, or the range ``(low, high)``."""
    value = env_kwargs.get(N_TRAILERS)
    if is_trailer_range(value):
        return trailer_range(value)
    return env_settings(dict(env_kwargs)).n_trailers


class PaddedPolicy:
    """A generalist (trained on ``n_trailers=(low, top)``) acting in a scene of one n:
    each observation is laid out as the mixed env would observe the same state
    (:func:`trailer_env.mixed.pad_observations`: zeros beyond n, the mask's n ones; with
    a window of ``history`` past frames, each frame so, :func:`pad_window_observations`)."""

    def __init__(
        self, policy: Policy, n: int, top: int, history: int = 0, action_dim: int = 1
    ) -> None:
        self.policy = policy
        self.n = n
        self.top = top
        self.history = history
        self.action_dim = action_dim

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        if self.history:
            padded = pad_window_observations(obs, self.n, self.top, self.history, self.action_dim)
            return np.asarray(self.policy(padded))
        return np.asarray(self.policy(pad_observations(obs, self.n, self.top)))


class CurrentObservationPolicy:
    """A policy trained without a memory acting in an env with ``history=k``: it reads
    the current observation, the window's first ``width`` entries
    (:mod:`trailer_env.history`)."""

    def __init__(self, policy: Policy, width: int) -> None:
        self.policy = policy
        self.width = width

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self.policy(np.atleast_2d(obs)[:, : self.width]))


def window_kwargs(spec: str, env_kwargs: Mapping[str, object]) -> dict[str, object]:
    """The env ``spec`` plays in: ``env_kwargs``, with a model's memory window (``history``
    on its card, :mod:`trailer_env.history`) where they name none. The window changes
    what the policy reads, not the dynamics or the episodes, so policies played with and
    without one are compared on the same starts."""
    played = dict(env_kwargs)
    base, _ = split_mirror(spec)
    if is_ensemble_spec(base):
        played_by = [window_kwargs(member, env_kwargs) for member in ensemble_members(base)]
        windows = {repr(member_kwargs.get("history")) for member_kwargs in played_by}
        if len(windows) > 1:
            raise ValueError(
                f"policy {spec!r}: its members read different windows of past frames "
                f"(history {', '.join(sorted(windows))}); a median calls them on one observation"
            )
        return played_by[0]
    if "history" not in played and is_model_spec(spec):
        history = model_card(spec).env_kwargs.history
        if history:
            played["history"] = history
    return played


def _history_of(spec: str, card: ModelCard, kwargs: Mapping[str, object]) -> tuple[int, int]:
    """``(the model's history, the env's)``: a model with a memory runs only in an env
    with the same window (ValueError naming both)."""
    trained = card.env_kwargs.history or 0
    given = kwargs.get("history", 0)
    wanted = given if isinstance(given, int) and not isinstance(given, bool) else 0
    if trained and trained != wanted:
        raise ValueError(
            f"model {spec} reads a window of history = {trained} past frames (its card), "
            f"the environment has history = {wanted}: evaluate it with history={trained} "
            f"(--set history={trained})"
        )
    return trained, wanted


def _trailers_model(
    path: Path,
    card: ModelCard,
    env_id: str,
    kwargs: Mapping[str, object],
    trust_pickle: bool,
    force: bool,
) -> Policy:
    """A model trained on ``observation="trailers"`` (its card says so), acting in the env
    of ``env_id`` and ``kwargs`` with any n up to its ``max_trailers``: on the flat
    observation, rearranged (:class:`~agents.policies.sb3.TrailersPolicy`), unless the
    env gives the Dict itself.

    Raises:
        ValueError: If the card names another env id (unless ``force``), its
            ``max_trailers`` is not an integer in 1 .. 256, or the env has more trailers.
    """
    trained_id = card.env_id
    if not force and trained_id is not None and trained_id != env_id:
        raise ValueError(
            f"model {path} was trained on {trained_id}, not {env_id}; pass --force to "
            "evaluate it anyway"
        )
    try:
        slots = bounded_integer("max_trailers", card.env_kwargs.max_trailers, 1, MAX_TRAILERS)
    except TypeError as error:
        raise ValueError(f"{path}: its card's env_kwargs: {error}") from None
    wanted = _wanted_trailers(kwargs)
    top = wanted[1] if isinstance(wanted, tuple) else wanted
    if top > slots:
        raise ValueError(
            f"model {path} reads at most {slots} trailers (max_trailers = {slots}), so it "
            f"cannot act with n_trailers = {wanted}"
        )
    space_kwargs = {**kwargs, "observation": "trailers", "max_trailers": slots}
    model = load_model(path, env_id=env_id, env_kwargs=space_kwargs, trust_pickle=trust_pickle)
    if kwargs.get(OBSERVATION) == TRAILERS_OBSERVATION:
        return ModelPolicy(model)
    return TrailersPolicy(ModelPolicy(model), top, slots, isinstance(wanted, tuple))


def model_card(spec: str) -> ModelCard:
    """The card of a model spec (SB3 zip or RLlib checkpoint); the empty card
    (:attr:`~agents.artifacts.cards.ModelCard.empty`) for a baseline or a model without one."""
    spec, _ = split_mirror(spec)
    if not is_model_spec(spec):
        return ModelCard()
    path = Path(resolve_model(spec))
    if path.is_dir():
        from agents.artifacts.rllib_files import read_rllib_card

        return read_rllib_card(path)
    return read_model_card(path)


def load_policy(
    spec: str,
    env_id: str,
    env_kwargs: Mapping[str, object] | None = None,
    seed: int | None = 0,
    *,
    trust_pickle: bool = False,
    force: bool = False,
) -> Policy:
    """A batched policy from a baseline name, a model path, a shipped model's stem or an
    RLlib checkpoint folder.

    Args:
        spec: A baseline name (:data:`agents.policies.baselines.BASELINES`), a ``.zip`` model
            path, the stem of a shipped model (:func:`resolve_model`), an RLlib
            checkpoint folder (:mod:`agents.training.rllib`), or ``module:name``, a
            batched callable of your own (:func:`load_callable`), or
            ``median(A,B,...)``, the middle action of those specs
            (:mod:`agents.policies.ensemble`); any of them followed by ``+mirror``, made
            odd under the convoy's mirror image (:mod:`agents.policies.mirror`).
        env_id: The environment it will act in.
        env_kwargs: The environment's keyword arguments (``n_trailers`` ...).
        seed: Seed of the random baseline.
        trust_pickle: Allow unpickling the file's pickled parts (see :mod:`agents.artifacts`).
        force: Evaluate a model whose card names another env id or n.

    Raises:
        ValueError: Unknown name, unknown environment, a model whose card or
            observation space does not fit the environment, a damaged file, or one
            that needs unpickling without ``trust_pickle``.
        FileNotFoundError: A model path that does not exist.
    """
    check_env_id(env_id)
    kwargs = dict(env_kwargs or {})
    base, mirrored = split_mirror(spec)
    if mirrored:
        signs = mirror_signs_of(env_id, kwargs)
        inner = load_policy(base, env_id, kwargs, seed, trust_pickle=trust_pickle, force=force)
        return MirroredPolicy(inner, *signs)
    if is_callable_spec(spec):
        policy = load_callable(spec)
        check_callable(policy, spec, env_id, kwargs)
        return policy
    if is_ensemble_spec(spec):
        return MedianPolicy(
            [
                load_policy(member, env_id, kwargs, seed, trust_pickle=trust_pickle, force=force)
                for member in ensemble_members(spec)
            ]
        )
    spec = resolve_model(spec)
    if not is_model_spec(spec):
        if spec not in BASELINES:
            raise ValueError(
                f"unknown policy {spec!r}: give a baseline ({', '.join(BASELINES)}), "
                f"a shipped model ({', '.join(shipped_models())}) "
                "or the path of a saved model (.zip) or RLlib checkpoint"
            )
        return make_baseline(spec, env_settings(kwargs), env_id, seed)
    path = Path(spec)
    probe = make_vector_env(env_id, 1, kwargs)
    if path.is_dir():
        from agents.artifacts.rllib_files import is_rllib_checkpoint, read_rllib_card
        from agents.policies.rllib import load_rllib_policy

        if not is_rllib_checkpoint(path):
            raise ValueError(f"{path} is a folder but not an RLlib checkpoint")
        if not force:
            check_trained_on(read_rllib_card(path), spec, env_id, kwargs)
        return load_rllib_policy(
            path, probe.single_observation_space, probe.single_action_space, trust_pickle
        )
    card = read_model_card(path)
    if card.mirrored:  # trained odd: acts so
        return MirroredPolicy(
            _card_policy(path, card, spec, env_id, kwargs, trust_pickle, force),
            *mirror_signs_of(env_id, kwargs),
        )
    return _card_policy(path, card, spec, env_id, kwargs, trust_pickle, force)


def _card_policy(
    path: Path,
    card: ModelCard,
    spec: str,
    env_id: str,
    kwargs: dict[str, object],
    trust_pickle: bool,
    force: bool,
) -> Policy:
    """The SB3 model at ``path`` (card read) as a policy of the env (:func:`load_policy`)."""
    if card.env_kwargs.observation == TRAILERS_OBSERVATION:
        read_curve(curve_path(path), CURVE_COLUMNS)
        return _trailers_model(path, card, env_id, kwargs, trust_pickle, force)
    if not force:
        check_trained_on(card, spec, env_id, kwargs)
    read_curve(curve_path(path), CURVE_COLUMNS)  # a damaged curve fails now, not at the end
    trained_n = card.n_trailers
    padded: tuple[int, int] | None = None
    history, env_history = _history_of(spec, card, kwargs)
    space_kwargs = {key: value for key, value in kwargs.items() if key != "history"}
    if history:
        space_kwargs["history"] = history
    wanted_n = _wanted_trailers(kwargs)
    if isinstance(trained_n, tuple) and isinstance(wanted_n, int):
        top = trained_n[1]
        if wanted_n > top:
            raise ValueError(
                f"model {spec} is a generalist over n_trailers = {trained_n[0]}..{top}: its "
                f"padded observation holds at most {top} trailers, so it cannot act with "
                f"n_trailers = {wanted_n}"
            )
        padded = (wanted_n, top)
        space_kwargs = {**space_kwargs, N_TRAILERS: list(trained_n)}
    model = load_model(path, env_id=env_id, env_kwargs=space_kwargs, trust_pickle=trust_pickle)
    stats = load_stats(path, model.observation_space, trust_pickle)
    if stats is None and card.normalize is not None and card.normalize.norm_obs:
        raise ValueError(
            f"model {path} was trained on normalised observations (its card), but its "
            f"statistics {stats_path(path).name} are missing"
        )
    policy: Policy = ModelPolicy(model, stats)
    if padded is not None:
        action_dim = int(np.prod(model.action_space.shape or (1,)))
        policy = PaddedPolicy(policy, *padded, history, action_dim)
    if env_history and not history:
        width = int(np.prod(model.observation_space.shape or (0,)))
        if padded is not None:  # an n-trailer frame is 3 top - 2 n narrower than a padded one
            n, top = padded
            width -= 3 * top - 2 * n
        policy = CurrentObservationPolicy(policy, width)
    return policy
