"""Seeded batched rollouts and the safety metrics of an evaluation.

:func:`rollout` plays K episodes in one native vector env (episode ``i`` seeded
``seed + i``), each to its end (jackknife, success or time limit), and collects
per-episode results from ``info`` and termination:

* ``returns``: sum of the rewards;
* ``jackknifed``: the episode ended by folding (the env's ``jackknifed`` flag on the
  terminating step);
* ``success``: the env's ``is_success`` on the last step (Reverse-v0: neither folded
  nor stopped reversing);
* ``failed``: the episode was terminated without success: a fold, or a scene's other
  failure (Reverse-v0 ends an episode as a failure when the cart's speed u >= 0);
* ``band_steps``: steps spent in the singular band (``cost`` > 0, i.e.
  ``singular_margin < singular_band``);
* ``min_margin``: the smallest ``singular_margin`` seen, the starting state included;
* ``actuator_work``: the actuator's work over the episode (J).

An episode is *safe* when it never enters the singular band and is not terminated
as a failure (it never folds, and on Reverse-v0 it never stops reversing: braking
the convoy would otherwise count as safe while escaping the task). With one trailer
the margin is identically 1 (no consecutive trailer pair to align), so safety
reduces to not failing.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from agents.envs import make_vector_env
from agents.policies.baselines import Policy


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


def rollout(
    policy: Policy,
    env_id: str,
    episodes: int,
    seed: int,
    env_kwargs: dict[str, Any] | None = None,
) -> EpisodeResults:
    """Play ``episodes`` seeded episodes of ``policy`` at once on the native vector env.

    Args:
        policy: Batched policy (observations (K, obs_dim) -> actions (K, action_dim)).
        env_id: A trailer_env id.
        episodes: Number of episodes K >= 1 (one environment each).
        seed: Episode ``i`` starts from the state drawn with seed ``seed + i``.
        env_kwargs: Keyword arguments of ``gym.make`` (``n_trailers`` ...).

    Returns:
        The per-episode results; deterministic for a deterministic policy and seed.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    envs = make_vector_env(env_id, episodes, env_kwargs)
    obs, info = envs.reset(seed=seed)
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
    for _ in range(envs.max_episode_steps):
        obs, reward, terminated, truncated, info = envs.step(policy(obs))
        rows = running.copy()  # the environments whose episode this step belongs to
        returns[rows] += reward[rows]
        lengths[rows] += 1
        margin = info["singular_margin"]
        min_margin[rows] = np.minimum(min_margin[rows], margin[rows])
        band_steps[rows] += info["cost"][rows] > 0.0
        success[rows] = info["is_success"][rows]
        work[rows] = info["actuator_work"][rows]
        jackknifed[rows] = terminated[rows] & info["jackknifed"][rows]
        failed[rows] = terminated[rows] & ~info["is_success"][rows]
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


def summarize(results: EpisodeResults) -> dict[str, Any]:
    """Aggregate metrics (plain Python numbers, rounded so JSON files diff cleanly).

    Keys: ``episodes``, ``mean_return``, ``std_return``, ``mean_length``,
    ``jackknife_rate``, ``failure_rate`` (terminated without success: folded, or on
    Reverse-v0 stopped reversing), ``safe_rate`` (never in the band, no failure) with its 95 %
    Wilson interval ``safe_rate_ci``, ``band_time_fraction`` (mean over episodes),
    ``min_margin_mean``, ``min_margin_worst``, ``success_rate``,
    ``mean_abs_actuator_work``.
    """
    count = int(results.returns.size)
    safe = int(results.safe.sum())
    low, high = wilson_interval(safe, count)

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
        "safe_rate_ci": [rounded(low), rounded(high)],
        "band_time_fraction": rounded(results.band_fraction.mean()),
        "min_margin_mean": rounded(results.min_margin.mean()),
        "min_margin_worst": rounded(results.min_margin.min()),
        "success_rate": rounded(results.success.mean()),
        "mean_abs_actuator_work": rounded(np.abs(results.actuator_work).mean()),
    }
