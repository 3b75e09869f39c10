"""What a scene asks of the convoy: to survive its episode, or to reach a goal.

Every scene's core declares it once (``ConvoyCore.objective``); termination, the
agents' certification, witnesses and tables read it from there.
"""

from __future__ import annotations

import enum


class Objective(enum.Enum):
    """A scene's objective.

    * ``SURVIVAL``: the episode is a success when it runs to its time limit without a
      jackknife or the scene's failure (Reverse); success means "not failed so far", so
      the episode ends only on a failure or at truncation.
    * ``GOAL``: the episode is a success when the scene's goal is reached (Dock, Coast,
      Heading); it ends there, or on a failure.
    """

    SURVIVAL = "survival"
    GOAL = "goal"


__all__ = ["Objective"]
