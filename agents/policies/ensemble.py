"""The middle action of several policies: ``median(<spec>,<spec>,...)``.

Policies trained alike from different seeds err on different starts. Where one of three
errs, the other two outvote it: the median of their actions keeps more starts than any
one of them (the privileged teachers of Reverse-v1 with three trailers under mismatch20:
``agents.evaluate --policy "median(A,B,C)" A B C``, docs/guide/analyses.md). As the
expert of an imitation run (``agents.imitate --expert specialists --expert-policy
"median(...)"``) it labels each state with that middle action. The median, not the mean:
a mean follows the one that errs part of the way; the median of an action per entry
ignores it.

Members are any policy specs (:func:`agents.policies.registry.load_policy`), each called
on the same observations, so they must read the same observation (the same window,
parameter features or not).
"""

from __future__ import annotations

import numpy as np

from agents.policies.baselines import Policy

#: A spec ``median(A,B,...)`` asks for :class:`MedianPolicy` of A, B, ...
ENSEMBLE_PREFIX = "median("
#: The fewest members: with one there is nothing to vote.
MIN_MEMBERS = 2


def split_members(text: str) -> list[str]:
    """``text`` split at its commas outside parentheses, each part stripped (a member may
    itself be a ``median(...)``; ``A,median(B,C)`` is two parts)."""
    parts, depth, start = [], 0, 0
    for index, char in enumerate(text):
        if char == "(":
            depth += 1
        elif char == ")":
            depth -= 1
        elif char == "," and depth == 0:
            parts.append(text[start:index].strip())
            start = index + 1
    parts.append(text[start:].strip())
    return parts


def is_ensemble_spec(spec: str) -> bool:
    """Whether ``spec`` asks for the median of several policies."""
    return spec.startswith(ENSEMBLE_PREFIX)


def ensemble_members(spec: str) -> tuple[str, ...]:
    """The member specs of ``median(A,B,...)``.

    Raises:
        ValueError: A spec that does not close its parenthesis at its end, unbalanced
            parentheses, an empty member, or fewer than :data:`MIN_MEMBERS` members.
    """
    if not is_ensemble_spec(spec):
        raise ValueError(f"policy {spec!r} is not {ENSEMBLE_PREFIX}...)")
    inner = spec[len(ENSEMBLE_PREFIX) : -1]
    if not spec.endswith(")") or not _balanced(inner):
        raise ValueError(f"policy {spec!r}: unbalanced parentheses in {ENSEMBLE_PREFIX}...)")
    members = split_members(inner)
    if any(not member for member in members):
        raise ValueError(f"policy {spec!r}: an empty member")
    if len(members) < MIN_MEMBERS:
        raise ValueError(
            f"policy {spec!r}: {ENSEMBLE_PREFIX}...) needs at least {MIN_MEMBERS} members, "
            f"got {len(members)}"
        )
    return tuple(members)


def ensemble_label(labels: list[str]) -> str:
    """A table's name for the median of policies named ``labels``: what they share
    written once, ``median(ppo_teacher_s{0,1,2})``, or, where they share no stem, every
    name, ``median(lqr, ppo_reverse_v1_n2)``."""
    prefix = _common_start(labels)
    suffix = _common_start([label[len(prefix) :][::-1] for label in labels])[::-1]
    middles = [label[len(prefix) : len(label) - len(suffix)] for label in labels]
    if prefix and all(middles):
        return f"{ENSEMBLE_PREFIX}{prefix}{{{','.join(middles)}}}{suffix})"
    return f"{ENSEMBLE_PREFIX}{', '.join(labels)})"


def _common_start(texts: list[str]) -> str:
    """The longest start every one of ``texts`` shares, character by character."""
    shortest = min(texts, key=len)
    for index, char in enumerate(shortest):
        if any(text[index] != char for text in texts):
            return shortest[:index]
    return shortest


def _balanced(text: str) -> bool:
    depth = 0
    for char in text:
        depth += (char == "(") - (char == ")")
        if depth < 0:
            return False
    return depth == 0


class MedianPolicy:
    """The median of ``members``' actions, entry by entry (for two members, their mean).

    Args:
        members: Batched policies of the same observation (stateless or each keeping
            its own state: every member is called once per step, on every row).

    Raises:
        ValueError: Fewer than :data:`MIN_MEMBERS` members, or a member that reads the
            environment's core (an ``observe`` method, e.g. ``lqr-adaptive``): the median
            hands its members the observations only.
    """

    def __init__(self, members: list[Policy]) -> None:
        if len(members) < MIN_MEMBERS:
            raise ValueError(f"a median needs at least {MIN_MEMBERS} policies, got {len(members)}")
        for member in members:
            if callable(getattr(member, "observe", None)):
                raise ValueError(
                    f"a median's member {type(member).__name__} reads the environment's "
                    "core (observe), not the observations alone"
                )
        self.members = list(members)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        actions = [np.asarray(member(obs), dtype=np.float32) for member in self.members]
        return np.median(np.stack(actions), axis=0).astype(np.float32)
