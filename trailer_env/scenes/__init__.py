"""The scenes: one module each, holding its batch core (task logic) and its Gymnasium env."""

from trailer_env.scenes.coast import CoastCore, CoastEnv
from trailer_env.scenes.dock import DockCore, DockEnv
from trailer_env.scenes.heading import HeadingCore, HeadingEnv
from trailer_env.scenes.reverse import ReverseCore, ReverseEnv

__all__ = [
    "CoastCore",
    "CoastEnv",
    "DockCore",
    "DockEnv",
    "HeadingCore",
    "HeadingEnv",
    "ReverseCore",
    "ReverseEnv",
]
