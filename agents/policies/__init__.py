"""Batched policies: the baselines, saved models (SB3 zips, RLlib exports) and the registry
that turns a name or a path into one (:func:`load_policy`)."""

from agents.policies.baselines import BASELINES, Policy, make_baseline
from agents.policies.registry import load_policy, policy_label

__all__ = ["BASELINES", "Policy", "load_policy", "make_baseline", "policy_label"]
