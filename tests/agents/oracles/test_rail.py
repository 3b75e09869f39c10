"""The planners, the policies on them, their observation decoding and the screen model
the rail's one actuator: each refuses the planar one with the same message."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from agents.oracles.ilqr import ILQRPlanner
from agents.oracles.ilqr_policy import ILQRPolicy
from agents.oracles.mpc_policy import state_from_observation
from agents.oracles.planner import SamplingPlanner
from agents.oracles.rail import require_rail
from agents.oracles.screen import screen_start
from trailer_env.scenes import ReverseV1Core
from trailer_env.settings import EnvSettings, settings_from_kwargs

PLANAR = settings_from_kwargs(action_mode="planar")
REFUSAL = "the planner drives the rail actuator, not action_mode='planar'"

USES: list[tuple[str, Callable[[EnvSettings], object]]] = [
    ("sampling planner", lambda settings: SamplingPlanner(ReverseV1Core, settings, 1)),
    ("ilqr planner", lambda settings: ILQRPlanner(ReverseV1Core, settings, 1)),
    ("ilqr policy", lambda settings: ILQRPolicy(ReverseV1Core, settings)),
    ("observation", lambda settings: state_from_observation(np.zeros((1, 10)), settings)),
]


@pytest.mark.parametrize(("name", "use"), USES, ids=[name for name, _ in USES])
def test_each_planner_refuses_the_planar_actuator_once_worded(
    name: str, use: Callable[[EnvSettings], object]
) -> None:
    with pytest.raises(ValueError) as raised:
        use(PLANAR)
    assert str(raised.value) == REFUSAL


def test_the_screen_says_what_it_models() -> None:
    with pytest.raises(ValueError) as raised:
        screen_start(PLANAR, np.zeros(4))
    assert str(raised.value) == "the screen models the rail actuator, not action_mode='planar'"
    assert require_rail(settings_from_kwargs()) is None
