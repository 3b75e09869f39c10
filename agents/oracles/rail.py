"""The actuator the planners model: the cart on its rail.

The planners (:mod:`agents.oracles.planner`, :mod:`agents.oracles.ilqr`), the policies
built on them, the observation decoding they share and the feasibility screen all model
the rail's one actuator; a scene made with the planar actuator
(``action_mode="planar_*"``) is refused once, here, with one message.
"""

from __future__ import annotations

from trailer_env.settings import EnvSettings


def require_rail(settings: EnvSettings, modeller: str = "the planner drives") -> None:
    """Return if ``settings`` use the rail actuator.

    Raises:
        ValueError: For the planar actuator: "<modeller> the rail actuator, not
            action_mode=...".
    """
    if settings.actuator.planar:
        raise ValueError(f"{modeller} the rail actuator, not action_mode={settings.action_mode!r}")


__all__ = ["require_rail"]
