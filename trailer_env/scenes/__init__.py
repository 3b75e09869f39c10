"""The scenes: one module each, holding its batch core (task logic) and its Gymnasium env.

Adding a scene: write its module (a :class:`~trailer_env.core.ConvoyCore` subclass that
declares ``scene``, ``version``, ``objective``, ``max_episode_steps``, ``headline_metric``,
``failure_words`` and ``baselines``, and a :class:`~trailer_env.env.ConvoyEnv` subclass
naming it), then add the env class to :data:`SCENE_ENVS` (CONTRIBUTING.md, "Adding a
scene"). Registration,
the vector env, the SB3 adapter and the agents' command lines all read that table.
"""

from trailer_env.env import ConvoyEnv
from trailer_env.scenes.coast import CoastCore, CoastEnv
from trailer_env.scenes.dock import DockCore, DockEnv
from trailer_env.scenes.heading import HeadingCore, HeadingEnv
from trailer_env.scenes.reverse import ReverseCore, ReverseEnv
from trailer_env.scenes.reverse_v1 import ReverseV1Core, ReverseV1Env

#: The one table of scenes, in registration order.
SCENE_ENVS: tuple[type[ConvoyEnv], ...] = (ReverseEnv, ReverseV1Env, CoastEnv, HeadingEnv, DockEnv)

__all__ = [
    "SCENE_ENVS",
    "CoastCore",
    "CoastEnv",
    "DockCore",
    "DockEnv",
    "HeadingCore",
    "HeadingEnv",
    "ReverseCore",
    "ReverseEnv",
    "ReverseV1Core",
    "ReverseV1Env",
]
