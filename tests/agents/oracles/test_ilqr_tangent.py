"""iLQR's exact Jacobians (the twin's tangent) against central differences of the kernel."""

from __future__ import annotations

import numpy as np
import pytest

from agents.oracles.ilqr import ILQRConfig, ILQRPlanner, Trajectory
from agents.oracles.ilqr_tangent import BOUND_INSET
from trailer_env.registry import core_class_of
from trailer_env.settings import settings_from_kwargs
from trailer_env.vector import seed_generators

HORIZON = 20
SCENES = [
    ("trailer_env/Reverse-v1", 2),
    ("trailer_env/Reverse-v1", 5),
    ("trailer_env/Dock-v0", 2),  # the pose in the state
    ("trailer_env/Coast-v0", 1),
]


def planners(env_id: str, n: int) -> tuple[ILQRPlanner, ILQRPlanner, Trajectory]:
    """A central-difference and an exact planner, and the central one's plan of two
    validation starts."""
    core_class = core_class_of(env_id)
    settings = settings_from_kwargs(n_trailers=n)
    core = core_class(settings, 2)
    core.reset_rows(np.arange(2), seed_generators([50005, 50006], 2, None))
    task = {key: getattr(core, key).copy() for key in core_class.task_keys}
    central = ILQRPlanner(core_class, settings, 2, ILQRConfig(central=True, horizon=HORIZON))
    exact = ILQRPlanner(
        core_class, settings, 2, ILQRConfig(jacobians="exact", central=True, horizon=HORIZON)
    )
    exact.plan(core.z, core.act, task)  # sets the task of its residuals' copies
    central.plan(core.z, core.act, task)
    return central, exact, central.last


@pytest.mark.parametrize(("env_id", "n"), SCENES)
def test_exact_jacobians_match_central_differences(env_id: str, n: int) -> None:
    central, exact, nominal = planners(env_id, n)
    differences = central._derivatives(nominal)
    tangents = exact._derivatives(nominal)
    alive = nominal.alive[:, :HORIZON]
    assert alive.sum() >= 10  # the comparison reads live steps
    # Measured: A within 5e-11 of its scale, B within 6e-7 (the central differences'
    # own error, h^2 times the third derivative, and the control's inset at the bound).
    for name, one, other, tolerance in (("A", 0, 0, 1e-9), ("B", 1, 1, 1e-5)):
        scale = np.abs(tangents[one][alive]).max()
        gap = np.abs(tangents[one] - differences[other])[alive].max()
        assert scale > 0.1 and gap < tolerance * scale, (name, gap, scale)
    # The residuals' Jacobians are the same differences in both planners.
    for index in (2, 3):
        np.testing.assert_array_equal(tangents[index], differences[index])
    # The tangent's primal is the kernel's next state (to the control's inset).
    width = central.width
    after, _, _ = exact.tangent.jacobians(  # type: ignore[union-attr]
        nominal.z[:, :HORIZON].reshape(-1, width),
        nominal.act[:, :HORIZON].reshape(-1, 6),
        nominal.v.reshape(-1),
        nominal.substeps.reshape(-1),
    )
    reached = nominal.x[:, 1:]
    live = nominal.alive[:, 1:]
    assert np.abs(after.reshape(reached.shape) - reached)[live].max() < 1e-9


def test_rows_with_different_substep_counts() -> None:
    central, exact, nominal = planners("trailer_env/Reverse-v1", 3)
    nominal.substeps[0, ::2] = 2
    nominal.substeps[1, ::3] = 4
    differences = central._derivatives(nominal)
    tangents = exact._derivatives(nominal)
    alive = nominal.alive[:, :HORIZON]
    scale = np.abs(tangents[0][alive]).max()
    assert np.abs(tangents[0] - differences[0])[alive].max() < 1e-9 * scale
    # A row's Jacobian depends on its own count: one substep and two differ.
    single = ILQRPlanner(
        central.core_class,
        central.settings,
        2,
        ILQRConfig(jacobians="exact", horizon=HORIZON),
    )
    nominal.substeps[:] = 1
    assert np.abs(single._derivatives(nominal)[0] - tangents[0]).max() > 1e-9


def test_a_control_on_the_bound_keeps_its_authority() -> None:
    _, exact, nominal = planners("trailer_env/Dock-v0", 1)
    width = exact.width
    z = np.repeat(nominal.z[:1, 0], 3, axis=0)
    act = np.repeat(nominal.act[:1, 0], 3, axis=0)
    tangent = exact.tangent
    assert tangent is not None
    _, _, at_bound = tangent.jacobians(z, act, np.array([-1.0, 1.0, 0.0]), np.ones(3, np.int64))
    _, _, inside = tangent.jacobians(
        z, act, np.array([-1.0 + BOUND_INSET, 1.0 - BOUND_INSET, 0.0]), np.ones(3, np.int64)
    )
    np.testing.assert_array_equal(at_bound, inside)
    speed = width + 1  # the mass's speed moves by dt * A per unit of v
    dt_accel = exact.settings.dt * exact.settings.rail_accel_max
    np.testing.assert_allclose(at_bound[:, speed], dt_accel, rtol=1e-6)


def test_exact_planner_is_deterministic_and_reaches_the_goal() -> None:
    core_class = core_class_of("trailer_env/Coast-v0")
    settings = settings_from_kwargs(n_trailers=2)
    seeds = [50000, 50002, 50006]  # validation starts both planners straighten
    core = core_class(settings, 3)
    core.reset_rows(np.arange(3), seed_generators(seeds, 3, None))
    config = ILQRConfig(jacobians="exact", reuse=False)
    planner = ILQRPlanner(core_class, settings, 3, config)
    alone = ILQRPlanner(core_class, settings, 1, config)
    first = planner.plan(core.z, core.act)
    assert first.tobytes() == planner.plan(core.z, core.act).tobytes()
    # The same start planned in another batch: the same bits.
    assert first[1:2].tobytes() == alone.plan(core.z[1:2], core.act[1:2]).tobytes()
    lengths = np.zeros(3, dtype=np.int64)
    success = np.zeros(3, dtype=bool)
    for step in range(1, core_class.max_episode_steps + 1):
        running = lengths == 0
        core.step(np.where(running[:, None], planner.plan(core.z, core.act), 0.0))
        ended = running & core.terminated
        lengths[ended] = step
        success |= ended & core.success
        if lengths.all():
            break
    assert success.all(), lengths
    assert lengths.max() < 200, lengths  # measured: 178, 60 and 41 steps


def test_bad_jacobians_setting_raises() -> None:
    with pytest.raises(ValueError, match="jacobians"):
        ILQRConfig(jacobians="analytic")
    with pytest.raises(TypeError, match="jacobians"):
        ILQRConfig(jacobians=True)  # type: ignore[arg-type]
