"""The benchmark protocol, and one call that scores any policy on it.

A policy from any stack (a Python callable, an SB3 model, a TorchRL module, an RLlib
policy) is scored on exactly the episodes the project's own tables use::

    from trailer_env.benchmark import score

    result = score(my_policy, "trailer_env/Reverse-v1", n_trailers=2, out="out/score")
    print(result.markdown)          # the standard table row
    result.summary["safe_rate"]     # the headline metric, with its 95 % interval

``my_policy`` maps a batch of observations, shape (K, obs_dim), to a batch of actions,
(K, action_dim) (or (K,) for a 1-D action); wrap a function of one observation with
:func:`per_observation`. All K episodes run in one native vector env, episode ``i``
seeded ``seed + i``, each to its end; a deterministic policy gives the same JSON on
every run.

Protocol ``trailer_env-benchmark/1`` (:data:`PROTOCOL`):

===============================  =================================================
what                             value
===============================  =================================================
tasks (:data:`TASKS`)            Reverse-v1 n = 1, 2, 3; Dock-v0 n = 1, 2;
                                 Coast-v0 n = 1, 2; Heading-v0 n = 2
episodes, seeds                  100 episodes, seeds 1000..1099 (the test seeds)
environment                      default keywords except ``n_trailers``
headline metric                  the scene's ``headline_metric``: ``safe_rate`` on
                                 Reverse, ``success_rate`` on the others
interval                         Wilson score interval, 95 %
===============================  =================================================

Per episode (:class:`EpisodeResults`), from ``info`` and termination:

* ``returns``: sum of the rewards;
* ``jackknifed``: the episode ended by folding (the ``jackknifed`` flag on the
  terminating step);
* ``success``: the env's ``is_success`` on the last step;
* ``failed``: terminated without success: a fold, or a scene's other failure (Reverse
  ends an episode as a failure when the convoy stops reversing);
* ``band_steps``: steps in the singular band (``cost`` > 0, i.e.
  ``singular_margin < singular_band``);
* ``min_margin``: the smallest ``singular_margin`` seen, the starting state included;
* ``actuator_work``: the actuator's work over the episode (J).

An episode is *safe* when it never enters the singular band and is not terminated as a
failure. The singular margin is min over k < n of abs(cos alpha_k): it looks at the
hitches between consecutive trailers and never at the last hitch, so with one trailer
the margin is identically 1 and "safe" reduces to "not folded, not stopped".
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from trailer_env.json_types import JSONObject
from trailer_env.observation import flat_observation
from trailer_env.settings import MAX_HISTORY

PROTOCOL = "trailer_env-benchmark/1"
#: First seed of the test episodes.
TEST_SEED = 1000
#: Episodes per task.
EPISODES = 100
#: (environment id, number of trailers) of the protocol's tasks.
TASKS: tuple[tuple[str, int], ...] = (
    ("trailer_env/Reverse-v1", 1),
    ("trailer_env/Reverse-v1", 2),
    ("trailer_env/Reverse-v1", 3),
    ("trailer_env/Dock-v0", 1),
    ("trailer_env/Dock-v0", 2),
    ("trailer_env/Coast-v0", 1),
    ("trailer_env/Coast-v0", 2),
    ("trailer_env/Heading-v0", 2),
)
#: Episodes one call may run (one environment each, all in memory at once).
MAX_EPISODES = 100_000

#: A batched policy: observations (K, obs_dim) -> actions (K, action_dim) or (K,).
Policy = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class EpisodeResults:
    """Per-episode results of a batch of seeded episodes (arrays of length K)."""

    seeds: np.ndarray
    returns: np.ndarray
    lengths: np.ndarray
    jackknifed: np.ndarray
    success: np.ndarray
    failed: np.ndarray
    band_steps: np.ndarray
    min_margin: np.ndarray
    actuator_work: np.ndarray
    #: Every step's singular margin, all episodes concatenated (for histograms).
    margins: np.ndarray

    @property
    def safe(self) -> np.ndarray:
        """Episodes that never entered the singular band and were not failures."""
        return (self.band_steps == 0) & ~self.jackknifed & ~self.failed

    @property
    def band_fraction(self) -> np.ndarray:
        """Fraction of each episode's steps spent in the singular band."""
        return self.band_steps / np.maximum(self.lengths, 1)


def privileged_view(policy: object) -> Callable[[Any, np.ndarray], Any] | None:
    """The policy's ``observe(core, obs)`` method, or None.

    A privileged policy (``lqr-adaptive``, which re-designs its regulator for each
    episode's drawn parameters) reads more than the observations: the rollouts hand it
    ``policy.observe(core, obs)`` of the environment's batch core instead of ``obs``.
    """
    observe = getattr(policy, "observe", None)
    return observe if callable(observe) else None


def per_observation(act: Callable[[np.ndarray], Any]) -> Policy:
    """A batched policy from a function of one observation (called once per row)."""

    def batched(obs: np.ndarray) -> np.ndarray:
        return np.stack([np.asarray(act(row), dtype=np.float64) for row in obs])

    return batched


def _integer(name: str, value: object) -> int:
    """``value`` as a Python int (NumPy integers accepted; bools and floats refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    return int(value)


def _flag(name: str, value: object) -> bool:
    """``value`` as a Python bool (a NumPy bool accepted; 0, 1 or "no" refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {type(value).__name__} {value!r}")
    return bool(value)


def _check_episodes_and_seed(episodes: object, seed: object) -> tuple[int, int]:
    """``(episodes, seed)`` as Python ints, checked.

    Raises:
        TypeError: If either is not an integer (a bool or a float).
        ValueError: If they are out of range.
    """
    episodes, seed = _integer("episodes", episodes), _integer("seed", seed)
    if not 1 <= episodes <= MAX_EPISODES:
        raise ValueError(f"episodes must be in 1..{MAX_EPISODES}, got {episodes}")
    if not 0 <= seed <= 2**32 - 1 - episodes:
        raise ValueError(f"seed must be in 0..2**32 - 1 - episodes, got {seed}")
    return episodes, seed


def _trailer_count(value: object) -> int | tuple[int, int]:
    """``n_trailers`` with Python ints: one count, or a (low, high) range
    (:mod:`trailer_env.mixed`); the values are checked by ``gym.make``."""
    if isinstance(value, (tuple, list)):
        if len(value) != 2:
            raise TypeError(f"n_trailers must be an integer or a pair (low, high), got {value!r}")
        return (_integer("n_trailers[0]", value[0]), _integer("n_trailers[1]", value[1]))
    return _integer("n_trailers", value)


def rollout(
    policy: Policy,
    env_id: str,
    episodes: int,
    seed: int,
    env_kwargs: Mapping[str, object] | None = None,
    observe: Callable[[Any, np.ndarray], Any] | None = None,
) -> EpisodeResults:
    """Play ``episodes`` seeded episodes of ``policy`` at once on the native vector env.

    Args:
        policy: Batched policy (observations (K, obs_dim) -> actions).
        env_id: A trailer_env id.
        episodes: Number of episodes K, 1 .. :data:`MAX_EPISODES` (one environment each).
        seed: Episode ``i`` starts from the state drawn with seed ``seed + i``.
        env_kwargs: Keyword arguments of ``gym.make`` (``n_trailers`` ...).
        observe: What the policy sees instead of the observations: ``observe(core,
            obs)`` of the batch's core (e.g. :func:`trailer_env.wrappers.goal_observation`).
            Default: the policy's own :func:`privileged_view`, if it has one.

    Returns:
        The per-episode results; deterministic for a deterministic policy and seed.

    Raises:
        TypeError, ValueError: On a bad count, seed, id or keyword (before any env exists);
            ``observation="trailers"`` is refused (ValueError): policies are scored on the
            flat observation (a policy may rearrange it,
            :func:`trailer_env.observation.trailers_observation`).
    """
    import gymnasium as gym

    from trailer_env.vector import ConvoyVectorEnv

    episodes, seed = _check_episodes_and_seed(episodes, seed)
    if (env_kwargs or {}).get("observation", "flat") != "flat":
        raise ValueError(
            "rollout scores policies on the flat observation; got observation="
            f"{(env_kwargs or {})['observation']!r} (a policy may rearrange the flat one with "
            "trailer_env.observation.trailers_observation)"
        )
    made = gym.make_vec(
        env_id,
        num_envs=episodes,
        vectorization_mode="vector_entry_point",
        **(env_kwargs or {}),  # type: ignore[arg-type]  # the scene's keywords, checked there
    )
    envs = made.unwrapped
    if not isinstance(envs, ConvoyVectorEnv):  # pragma: no cover - registration guarantees it
        raise TypeError(f"{env_id} did not build a ConvoyVectorEnv")
    reset_obs, info = envs.reset(seed=seed)
    obs = flat_observation(reset_obs, "rollout")
    running = np.ones(episodes, dtype=bool)
    returns = np.zeros(episodes)
    lengths = np.zeros(episodes, dtype=np.int64)
    jackknifed = np.zeros(episodes, dtype=bool)
    success = np.asarray(info["is_success"], dtype=bool).copy()
    failed = np.zeros(episodes, dtype=bool)
    band_steps = np.zeros(episodes, dtype=np.int64)
    min_margin = np.asarray(info["singular_margin"], dtype=np.float64).copy()
    work = np.zeros(episodes)
    margins: list[np.ndarray] = []
    if observe is None:
        observe = privileged_view(policy)
    for _ in range(envs.max_episode_steps):
        seen = obs if observe is None else observe(envs.core, obs)
        stepped, reward, terminated, truncated, info = envs.step(policy(seen))
        obs = flat_observation(stepped, "rollout")
        rows = running.copy()  # the environments whose episode this step belongs to
        returns[rows] += reward[rows]
        lengths[rows] += 1
        margin = np.asarray(info["singular_margin"])
        min_margin[rows] = np.minimum(min_margin[rows], margin[rows])
        band_steps[rows] += np.asarray(info["cost"])[rows] > 0.0
        success[rows] = np.asarray(info["is_success"])[rows]
        work[rows] = np.asarray(info["actuator_work"])[rows]
        jackknifed[rows] = terminated[rows] & np.asarray(info["jackknifed"])[rows]
        failed[rows] = terminated[rows] & ~np.asarray(info["is_success"])[rows]
        margins.append(margin[rows])
        running &= ~(terminated | truncated)
        if not running.any():
            break
    envs.close()
    return EpisodeResults(
        seeds=seed + np.arange(episodes),
        returns=returns,
        lengths=lengths,
        jackknifed=jackknifed,
        success=success,
        failed=failed,
        band_steps=band_steps,
        min_margin=min_margin,
        actuator_work=work,
        margins=np.concatenate(margins) if margins else np.ones(0),
    )


def wilson_interval(successes: int, trials: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval (95 % by default) of a binomial proportion."""
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    denominator = 1.0 + z**2 / trials
    centre = (p + z**2 / (2 * trials)) / denominator
    half = z * np.sqrt(p * (1 - p) / trials + z**2 / (4 * trials**2)) / denominator
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


def summarize(results: EpisodeResults) -> JSONObject:
    """Aggregate metrics (plain Python numbers, rounded so JSON files diff cleanly).

    Keys: ``episodes``, ``mean_return``, ``std_return``, ``mean_length``,
    ``jackknife_rate``, ``failure_rate`` (terminated without success), ``safe_rate``
    (never in the band, no failure) with its 95 % Wilson interval ``safe_rate_ci``,
    ``band_time_fraction`` (mean over episodes), ``min_margin_mean``,
    ``min_margin_worst``, ``success_rate``, ``mean_abs_actuator_work``.
    """
    count = int(results.returns.size)
    safe = int(results.safe.sum())

    def rounded(value: float) -> float:
        return round(float(value), 6)

    return {
        "episodes": count,
        "mean_return": rounded(results.returns.mean()),
        "std_return": rounded(results.returns.std()),
        "mean_length": rounded(results.lengths.mean()),
        "jackknife_rate": rounded(results.jackknifed.mean()),
        "failure_rate": rounded(results.failed.mean()),
        "safe_rate": rounded(safe / count),
        "safe_rate_ci": [rounded(bound) for bound in wilson_interval(safe, count)],
        "band_time_fraction": rounded(results.band_fraction.mean()),
        "min_margin_mean": rounded(results.min_margin.mean()),
        "min_margin_worst": rounded(results.min_margin.min()),
        "success_rate": rounded(results.success.mean()),
        "mean_abs_actuator_work": rounded(np.abs(results.actuator_work).mean()),
    }


@dataclass(frozen=True)
class Score:
    """A policy's score on one task of the protocol."""

    document: JSONObject
    results: EpisodeResults

    @property
    def summary(self) -> JSONObject:
        """The metrics (:func:`summarize`)."""
        return dict(self.document["metrics"])

    @property
    def markdown(self) -> str:
        """The standard table: header and this policy's row."""
        s = self.summary
        metric = self.document["headline_metric"]
        low, high = self.document["headline_ci"]
        return (
            f"{self.document['env_id']}, n = {self.document['n_trailers']}: "
            f"{s['episodes']} episodes, seeds {self.document['seeds'][0]}.."
            f"{self.document['seeds'][1]} ({PROTOCOL})\n\n"
            f"| policy | {metric.removesuffix('_rate')} [95% CI] | return (mean ± sd) "
            "| fold | time in band | min margin (mean / worst) |\n"
            "|---|---|---|---|---|---|\n"
            f"| {self.document['policy']} | {100 * s[metric]:.0f}% "
            f"[{100 * low:.0f}, {100 * high:.0f}] "
            f"| {s['mean_return']:.1f} ± {s['std_return']:.1f} "
            f"| {100 * s['jackknife_rate']:.0f}% | {100 * s['band_time_fraction']:.1f}% "
            f"| {s['min_margin_mean']:.2f} / {s['min_margin_worst']:.2f} |\n"
        )


def _file_mode() -> int:
    """The mode ``open()`` gives a new file: 0o666 less the umask (read without a window
    where a looser mask applies: the one set meanwhile is the strictest, 0o077)."""
    mask = os.umask(0o077)
    os.umask(mask)
    return 0o666 & ~mask


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename (never half written).

    Raises:
        ValueError: If ``path`` is a symbolic link.
    """
    if path.is_symlink():
        raise ValueError(f"{path} is a symbolic link; refusing to write through it")
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        os.chmod(temporary, _file_mode())  # mkstemp's 0600 would outlive the rename
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def score(
    policy: Policy,
    env_id: str,
    n_trailers: int | tuple[int, int] = 2,
    *,
    name: str = "policy",
    episodes: int = EPISODES,
    seed: int = TEST_SEED,
    out: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    goal_conditioned: bool = False,
    history: int = 0,
) -> Score:
    """Score a batched policy on the protocol's episodes of ``env_id`` with ``n_trailers``.

    Args:
        policy: Observations (K, obs_dim) -> actions; see :func:`per_observation`.
        env_id: A trailer_env id (the protocol's tasks are :data:`TASKS`; any id works).
        n_trailers: Number of trailers (or a range ``(low, high)``, :mod:`trailer_env.mixed`).
        name: The policy's name in the table and the JSON.
        episodes, seed: The protocol's by default (100 episodes from seed 1000); other
            values are recorded in the JSON and mark the score as off-protocol.
        out: A folder to write ``score.json`` and ``score.md`` into (created if absent;
            existing files are refused unless ``overwrite``; files get the mode the
            umask gives, as ``open()``'s would).
        overwrite: Replace an existing ``score.json`` / ``score.md`` (a bool).
        goal_conditioned: The policy reads :class:`trailer_env.wrappers.GoalConditioned`'s
            ``Dict`` observations (batched; Dock-v0 and Heading-v0), e.g. an SB3 HER agent.
        history: The policy reads a window of this many past observations and actions
            (``gym.make``'s ``history``, :mod:`trailer_env.history`; 0 to 64): a policy
            with a memory. The episodes are the same, so the score stays on protocol.

    Integers may be NumPy integers (they are written to the JSON as ints).

    Raises:
        TypeError: On a bool or float where an integer is wanted (``n_trailers``,
            ``episodes``, ``seed``, ``history``), a ``name`` that is not a str, ``overwrite`` or
            ``goal_conditioned`` not a bool, ``out`` not a path.
        ValueError: On a bad id, count or seed, an empty ``out``, or an ``out`` whose
            ``score.json`` or ``score.md`` exists (without ``overwrite``), is a folder or
            a symbolic link, dangling or not. Everything is checked before any episode
            runs; a refusal writes nothing.
    """
    from trailer_env.registry import core_class_of

    core = core_class_of(env_id)
    n_trailers = _trailer_count(n_trailers)
    episodes, seed = _check_episodes_and_seed(episodes, seed)
    if not isinstance(name, str):
        raise TypeError(f"name must be a str, got {type(name).__name__} {name!r}")
    overwrite = _flag("overwrite", overwrite)
    goal_conditioned = _flag("goal_conditioned", goal_conditioned)
    history = _integer("history", history)
    if not 0 <= history <= MAX_HISTORY:
        raise ValueError(f"history must be in 0..{MAX_HISTORY}, got {history}")
    if history and goal_conditioned:
        raise ValueError("history needs the flat observation, not goal_conditioned=True")
    observe = None
    if goal_conditioned:
        from trailer_env.scenes.dock import DockCore
        from trailer_env.scenes.heading import HeadingCore
        from trailer_env.wrappers import goal_observation

        if not issubclass(core, (DockCore, HeadingCore)):
            raise ValueError(f"goal_conditioned=True needs Dock-v0 or Heading-v0, not {env_id}")
        observe = goal_observation
    folder = _out_folder(out, overwrite)
    kwargs: dict[str, object] = {"n_trailers": n_trailers}
    if history:
        kwargs["history"] = history
    results = rollout(policy, env_id, episodes, seed, kwargs, observe)
    document = {
        "protocol": PROTOCOL,
        "on_protocol": (env_id, n_trailers) in TASKS and (episodes, seed) == (EPISODES, TEST_SEED),
        "policy": name,
        "goal_conditioned": goal_conditioned,
        "env_id": env_id,
        "n_trailers": n_trailers,
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "headline_metric": core.headline_metric,
        "metrics": summarize(results),
    }
    if history:
        document["history"] = history
    hits = int((results.safe if core.headline_metric == "safe_rate" else results.success).sum())
    document["headline_ci"] = [round(bound, 6) for bound in wilson_interval(hits, episodes)]
    result = Score(document, results)
    if folder is not None:
        texts = {  # both made before the folder: a failure leaves nothing behind
            "score.json": json.dumps(document, indent=2, sort_keys=True) + "\n",
            "score.md": result.markdown,
        }
        folder.mkdir(parents=True, exist_ok=True)
        for file, text in texts.items():
            write_atomic(folder / file, text)
    return result


#: The files :func:`score` writes into ``out``.
SCORE_FILES = ("score.json", "score.md")


def _out_folder(out: object, overwrite: bool) -> Path | None:
    """``out`` as a folder :func:`score` may write :data:`SCORE_FILES` into, checked for
    every file before anything is written (None: no folder)."""
    if out is None:
        return None
    if not isinstance(out, (str, os.PathLike)):
        raise TypeError(f"out must be a path (str or os.PathLike), got {type(out).__name__}")
    if os.fspath(out) in ("", b""):
        raise ValueError("out='' names no folder; pass '.' for the current folder")
    folder = Path(os.fsdecode(out))
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"out={str(folder)!r} is not a folder")
    for file in SCORE_FILES:
        target = folder / file
        if target.is_symlink():
            raise ValueError(f"{target} is a symbolic link; refusing to write through it")
        if target.is_dir():
            raise ValueError(f"{target} is a folder")
        if target.exists() and not overwrite:
            raise ValueError(f"{target} exists; pass overwrite=True to replace it")
    return folder
