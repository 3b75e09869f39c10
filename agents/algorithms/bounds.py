"""The valid values of the algorithms' numeric arguments: one table for every reader.

A hyperparameter file's entry (:func:`agents.training.config.load_hyperparams`), a
search space of ``agents.tune`` (every choice and both ends of every range,
:func:`agents.training.tune.read_space`) and the constructor of
:class:`~agents.algorithms.ppo_lagrangian.PPOLagrangian` check a value against the
same bound here, so a value the algorithm would
refuse (or train on without meaning: a discount of 1.5) is refused before any run
folder or study is written.

Only numbers are checked here: a schedule string (``lin_3e-4``), SAC's ``ent_coef:
auto`` or None (``target_kl``) are the readers' to check; the upper bounds on counts
(``n_steps``, ``buffer_size`` ...) are :mod:`agents.artifacts.limits`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ARGUMENT_BOUNDS", "Bound", "argument_problem", "bound_of"]


@dataclass(frozen=True)
class Bound:
    """An interval of valid values: ``low`` .. ``high``, each end included unless open;
    ``integer`` when only integers are valid."""

    low: float
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    integer: bool = False

    def contains(self, value: float) -> bool:
        """Whether the finite number ``value`` lies in the interval."""
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def text(self) -> str:
        """The interval in words, e.g. ``"in [0, 1]"``, ``"> 0"``, ``"an integer >= 1"``."""
        kind = "an integer " if self.integer else ""
        if math.isinf(self.high):
            return f"{kind}{'>' if self.low_open else '>='} {self.low:g}"
        left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
        return f"{kind}in {left}{self.low:g}, {self.high:g}{right}"


_RATE = Bound(0.0, 1.0)
_POSITIVE = Bound(0.0, low_open=True)
_NON_NEGATIVE = Bound(0.0)
_COUNT = Bound(1, integer=True)

#: Argument -> its valid values, for every algorithm that takes it.
ARGUMENT_BOUNDS: dict[str, Bound] = {
    "learning_rate": _POSITIVE,
    "gamma": _RATE,
    "gae_lambda": _RATE,
    "clip_range": _POSITIVE,
    "clip_range_vf": _POSITIVE,
    "ent_coef": _NON_NEGATIVE,
    "vf_coef": _NON_NEGATIVE,
    "max_grad_norm": _POSITIVE,
    "target_kl": _POSITIVE,
    "tau": Bound(0.0, 1.0, low_open=True),
    "target_policy_noise": _NON_NEGATIVE,
    "target_noise_clip": _NON_NEGATIVE,
    "noise_std": _NON_NEGATIVE,
    "log_std_init": Bound(-math.inf),
    "n_steps": _COUNT,
    "batch_size": _COUNT,
    "n_epochs": _COUNT,
    "buffer_size": _COUNT,
    "learning_starts": Bound(0, integer=True),
    "policy_delay": _COUNT,
    "target_update_interval": _COUNT,
    "stats_window_size": _COUNT,
    # PPO-Lagrangian: the constraint's bound, the multiplier's step and its start.
    "cost_limit": _NON_NEGATIVE,
    "lambda_lr": _POSITIVE,
    "lambda_init": _NON_NEGATIVE,
}
#: Bounds particular to an algorithm: PPO normalises each minibatch's advantages, which
#: needs two samples (stable-baselines3 asserts ``batch_size > 1``).
_ALGORITHM_BOUNDS: dict[str, dict[str, Bound]] = {
    "ppo": {"batch_size": Bound(2, integer=True)},
    "ppo_lag": {"batch_size": Bound(2, integer=True)},
}


def bound_of(algo: str, key: str) -> Bound | None:
    """The bound of ``algo``'s argument ``key`` (None: no numeric bound is known)."""
    return _ALGORITHM_BOUNDS.get(algo, {}).get(key, ARGUMENT_BOUNDS.get(key))


def argument_problem(algo: str, key: str, value: object) -> str | None:
    """Why ``value`` is not a valid ``key`` of ``algo`` (None when it is, or when it is
    not a number: a string, None, a list are left to the caller), e.g.
    ``"gamma must be a finite number in [0, 1], got 1.5"``."""
    bound = bound_of(algo, key)
    if bound is None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    if not math.isfinite(value):
        return f"{key} must be a finite number, got {value!r}"
    if (bound.integer and value != int(value)) or not bound.contains(float(value)):
        kind = "" if bound.integer else "a finite number "
        return f"{key} must be {kind}{bound.text()}, got {value!r}"
    return None
