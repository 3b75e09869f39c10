"""Gymnasium environments of a cart pulling n trailers, steered only by a moving mass.

Importing the package registers the scenes (namespace ``trailer_env``):

==========================  ==================  =====================================
id                          max_episode_steps   task
==========================  ==================  =====================================
``trailer_env/Reverse-v0``  400 (20 s)          back up without folding (kept, unchanged)
``trailer_env/Reverse-v1``  400 (20 s)          the headline: every start recoverable
``trailer_env/Coast-v0``    300 (15 s)          straighten from a random coasting state
``trailer_env/Heading-v0``  300 (15 s)          reach and hold a target heading
``trailer_env/Dock-v0``     400 (20 s)          reverse the last axle onto a dock
==========================  ==================  =====================================

Each id has an ``entry_point`` (the single env, :mod:`trailer_env.scenes`) and a
``vector_entry_point`` (the native batched env, :mod:`trailer_env.vector`)::

    import gymnasium as gym
    import trailer_env

    env = gym.make("trailer_env/Reverse-v1", n_trailers=3, mu=0.4)
    envs = gym.make_vec(
        "trailer_env/Reverse-v1", num_envs=1024, vectorization_mode="vector_entry_point"
    )

Keyword arguments: :data:`trailer_env.settings.MAKE_KEYWORDS` (with their meanings in
docs/generated/keywords.md) and any :class:`dynamics.ConvoyParams` field. The
stable-baselines3 adapter lives in :mod:`trailer_env.sb3` (imported on demand), the
benchmark protocol and its ``score`` in :mod:`trailer_env.benchmark`, and views in
other libraries' conventions (safety-gymnasium's step, goal-conditioned ``Dict``
observations for HER) in :mod:`trailer_env.wrappers`.
``python -m trailer_env`` lists the ids; ``python -m trailer_env --play ID`` drives one
from the keyboard (needs a display and pygame).
"""

from __future__ import annotations

__version__ = "0.17.0"

from trailer_env.fidelity import Fidelity
from trailer_env.registry import ENVIRONMENTS, register_scenes
from trailer_env.scenes import CoastEnv, DockEnv, HeadingEnv, ReverseEnv, ReverseV1Env
from trailer_env.settings import EnvSettings
from trailer_env.substeps import AccuracyWarning

register_scenes()

__all__ = [
    "ENVIRONMENTS",
    "AccuracyWarning",
    "CoastEnv",
    "DockEnv",
    "EnvSettings",
    "Fidelity",
    "HeadingEnv",
    "ReverseEnv",
    "ReverseV1Env",
    "__version__",
]
