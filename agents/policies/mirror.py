"""Policies made odd under the convoy's mirror image: ``<policy>+mirror``.

Reflecting the plane about the cart's axis maps a state to its mirror image and an
action to its mirrored action, and every scene's equations, starts, reward and
termination are symmetric under it
(:meth:`trailer_env.core.ConvoyCore.mirror_signs`, tests/trailer_env/test_mirror.py). So a
good policy is odd: ``pi(S o) = A pi(o)`` with ``S`` and ``A`` the observation's and the
action's signs. A learned one is odd only as far as its data taught it; its error shows
most at a straight convoy, where it should act with exactly 0 and a bias of a few
hundredths of the action range decides episodes that start within a milliradian of
straight (Reverse-v1 with 5 and 6 trailers). :class:`MirroredPolicy` makes any policy
odd, ``a(o) = (pi(o) + A pi(S o)) / 2``, at the cost of two calls per step; an odd
policy (the LQR) is left as it is, to rounding. ``load_policy("<spec>+mirror", ...)`` and
``agents.evaluate --policy <spec>+mirror`` wrap any policy spec.
"""

from __future__ import annotations

import numpy as np

from agents.envs import make_vector_env
from agents.policies.baselines import Policy
from trailer_env.json_types import JSONObject

#: The policy-spec suffix that wraps a policy in :class:`MirroredPolicy`.
MIRROR_SUFFIX = "+mirror"


def split_mirror(spec: str) -> tuple[str, bool]:
    """``(the wrapped spec, whether it asks for the mirror)``."""
    if spec.endswith(MIRROR_SUFFIX) and len(spec) > len(MIRROR_SUFFIX):
        return spec[: -len(MIRROR_SUFFIX)], True
    return spec, False


class MirroredPolicy:
    """``policy`` made odd under the mirror image: ``(pi(o) + A pi(S o)) / 2``.

    Args:
        policy: A batched policy of the flat observation (stateless: it is called twice
            per step, on the observations and on their images).
        observation_signs: ``S``, one sign per observation entry.
        action_signs: ``A``, one sign per action entry.
    """

    def __init__(
        self, policy: Policy, observation_signs: np.ndarray, action_signs: np.ndarray
    ) -> None:
        self.policy = policy
        self.observation_signs = np.asarray(observation_signs, dtype=np.float32)
        self.action_signs = np.asarray(action_signs, dtype=np.float32)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.asarray(obs, dtype=np.float32)
        direct = np.asarray(self.policy(batch), dtype=np.float32)
        image = np.asarray(self.policy(batch * self.observation_signs), dtype=np.float32)
        return np.float32(0.5) * (direct + image * self.action_signs)


def mirror_signs_of(env_id: str, env_kwargs: JSONObject) -> tuple[np.ndarray, np.ndarray]:
    """The observation and action signs of the env ``gym.make(env_id, **env_kwargs)``.

    A range of trailer counts gives the signs of its padded layout
    (:meth:`trailer_env.mixed.MixedCore.mirror_signs`).

    Raises:
        ValueError: For the Dict observation (a policy here reads the flat one; a
            ``"trailers"`` model is wrapped on the flat side), or a scene that declares
            no mirror symmetry.
    """
    if env_kwargs.get("observation", "flat") != "flat":
        raise ValueError(f"{MIRROR_SUFFIX} acts on the flat observation, not on {env_kwargs}")
    probe = make_vector_env(env_id, 1, env_kwargs)
    try:
        signs = probe.core.mirror_signs()
    finally:
        probe.close()
    if signs is None:
        raise ValueError(f"{env_id} declares no mirror symmetry (mirror_task_signs is None)")
    return signs


__all__ = ["MIRROR_SUFFIX", "MirroredPolicy", "mirror_signs_of", "split_mirror"]
