"""The differentiable twin (trailer_env.twin) held to the compiled kernel.

Every scene at n = 1..8: from ``env.reset(seed=1000 + k)`` starts, 400 steps of random
actions (a fixed seed) through the kernel; the twin, stepped from the kernel's own state
before every step, gives the same next state, mass state, reward, cost, termination and
substep count; stepped alone from the start, the same trajectory. Its Jacobians agree
with central differences of the kernel's step.

Errors are measured as ``|twin - kernel| / max(1, |kernel|)`` per entry (relative for
values above 1, absolute below: hitch angles and rates cross zero). Measured: per step at
most 2.2e-16, over 400 steps from the start at most 8.3e-14 (states) and 1.8e-14 (rewards)
with random actions (they fold a reversing convoy within about 50 steps, after which the
state no longer grows); a trajectory that
keeps reversing (the LQR's actions replayed open loop) amplifies a last-bit difference by
its unstable modes, up to 2e-9 after 400 steps at n = 7.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import trailer_env  # noqa: F401  (registers the scenes)

torch = pytest.importorskip("torch")

from trailer_env.twin import TwinParams, TwinState, TwinStep, observe, step  # noqa: E402
from trailer_env.twin.scenes import step_outcome  # noqa: E402

SCENES = [
    "trailer_env/Reverse-v1",
    "trailer_env/Reverse-v0",
    "trailer_env/Coast-v0",
    "trailer_env/Heading-v0",
    "trailer_env/Dock-v0",
]
COUNTS = range(1, 9)
ROWS = 4
STEPS = 400
#: Per step from the kernel's state, and over a whole trajectory from the start.
STEP_TOLERANCE = 1e-12
TRAJECTORY_TOLERANCE = 1e-9


def batch_core(env_id: str, n: int, rows: int = ROWS, **kwargs: Any) -> Any:
    """A batch core whose row k starts where ``env.reset(seed=1000 + k)`` does."""
    records = []
    for k in range(rows):
        env = gym.make(env_id, n_trailers=n, **kwargs)
        env.reset(seed=1000 + k)
        single = env.unwrapped.core  # type: ignore[attr-defined]
        records.append(single.start_records(np.array([0])))
    core = type(single)(single.settings, rows, track_pose=single.with_pose)
    for row, record in enumerate(records):
        core.restart(np.array([row]), record)
    return core


def kernel_run(env_id: str, n: int, steps: int = STEPS, **kwargs: Any) -> dict[str, Any]:
    """The kernel's run: the states before every step and what every step gave."""
    core = batch_core(env_id, n, **kwargs)
    actions = np.random.default_rng(n).uniform(-1.0, 1.0, (steps, ROWS, core.settings.action_dim))
    start = TwinState.from_core(core)
    before, after = [], []
    outcome: dict[str, list[np.ndarray]] = {
        key: [] for key in ("reward", "cost", "terminated", "substeps", "act")
    }
    for t in range(steps):
        before.append(TwinState.from_core(core))
        core.step(actions[t])
        after.append(core.z.copy())
        outcome["reward"].append(core.reward.copy())
        outcome["cost"].append(core.cost.copy())
        outcome["terminated"].append(core.terminated.copy())
        outcome["substeps"].append(core.substeps.copy())
        outcome["act"].append(core.act.copy())
    stacked = TwinState(*(torch.cat(parts) for parts in zip(*before, strict=True)))
    return {
        "core": core,
        "params": TwinParams.from_core(core),
        "start": start,
        "before": stacked,
        "actions": actions,
        "z": np.stack(after),
        **{key: np.stack(value) for key, value in outcome.items()},
    }


def relative_error(twin: np.ndarray, kernel: np.ndarray) -> float:
    return float(np.max(np.abs(twin - kernel) / np.maximum(1.0, np.abs(kernel)), initial=0.0))


def _runs() -> list[tuple[str, int]]:
    return [(env_id, n) for env_id in SCENES for n in COUNTS]


@pytest.mark.parametrize(("env_id", "n"), _runs())
def test_step_from_kernel_states(env_id: str, n: int) -> None:
    """Every one of 400 steps, from the kernel's state before it, in one batched call."""
    run = kernel_run(env_id, n)
    actions = torch.tensor(run["actions"].reshape(STEPS * ROWS, -1))
    outcome = step_outcome(run["before"], actions, run["params"])
    shape = (STEPS, ROWS)
    z = outcome.state.z.numpy().reshape(*shape, -1)
    act = outcome.state.act.numpy().reshape(*shape, -1)
    assert relative_error(z, run["z"]) < STEP_TOLERANCE
    assert relative_error(act, run["act"]) < STEP_TOLERANCE
    assert relative_error(outcome.reward.numpy().reshape(shape), run["reward"]) < STEP_TOLERANCE
    np.testing.assert_array_equal(outcome.cost.numpy().reshape(shape), run["cost"])
    np.testing.assert_array_equal(outcome.terminated.numpy().reshape(shape), run["terminated"])
    np.testing.assert_array_equal(outcome.substeps.numpy().reshape(shape), run["substeps"])
    assert run["terminated"].any() or env_id.endswith("Heading-v0")  # the flags were exercised


def twin_trajectory(run: dict[str, Any], steps: int) -> dict[str, np.ndarray]:
    state, params = run["start"], run["params"]
    rewards, terminated, zs = [], [], []
    for t in range(steps):
        state, reward, _, done = step(state, torch.tensor(run["actions"][t]), params)
        zs.append(state.z.numpy())
        rewards.append(reward.numpy())
        terminated.append(done.numpy())
    return {"z": np.stack(zs), "reward": np.stack(rewards), "terminated": np.stack(terminated)}


def check_trajectory(env_id: str, n: int, steps: int) -> None:
    run = kernel_run(env_id, n, steps)
    twin = twin_trajectory(run, steps)
    assert relative_error(twin["z"], run["z"]) < TRAJECTORY_TOLERANCE
    assert relative_error(twin["reward"], run["reward"]) < TRAJECTORY_TOLERANCE
    np.testing.assert_array_equal(twin["terminated"], run["terminated"])


@pytest.mark.parametrize("n", [1, 3])
def test_trajectory_reverse_v1_short(n: int) -> None:
    check_trajectory("trailer_env/Reverse-v1", n, 120)


@pytest.mark.slow
@pytest.mark.parametrize(("env_id", "n"), _runs())
def test_trajectory(env_id: str, n: int) -> None:
    """400 steps from the start, the twin alone."""
    check_trajectory(env_id, n, STEPS)


@pytest.mark.slow
@pytest.mark.parametrize("n", [1, 2, 3, 5, 7])
def test_trajectory_that_keeps_reversing(n: int) -> None:
    """The LQR's actions through the kernel, replayed open loop through the twin: the
    unstable modes amplify last-bit differences, still within 1e-7 after 400 steps."""
    from trailer_env.controllers import LQRController

    core = batch_core("trailer_env/Reverse-v1", n)
    lqr = LQRController(core.settings)
    params = TwinParams.from_core(core)
    state = TwinState.from_core(core)
    worst = 0.0
    for _ in range(STEPS):
        action = np.asarray(lqr(core.obs.astype(np.float64)), dtype=np.float64).reshape(ROWS, 1)
        core.step(action)
        state, *_ = step(state, torch.tensor(action), params)
        worst = max(worst, relative_error(state.z.numpy(), core.z))
    assert worst < 1e-7


@pytest.mark.parametrize("env_id", SCENES)
def test_observation(env_id: str) -> None:
    core = batch_core(env_id, 3)
    core.step(np.full((ROWS, 1), 0.4))
    twin = observe(TwinState.from_core(core), TwinParams.from_core(core)).numpy()
    np.testing.assert_allclose(twin.astype(np.float32), core.obs, rtol=1e-6, atol=1e-7)


def kernel_jacobian(core: Any, x: np.ndarray, n: int, eps: float) -> np.ndarray:
    """Central differences of the kernel's next (z, eta, eta_dot) in x = (z, eta, eta_dot, a)."""
    width = core.z.shape[1]
    size = x.size
    points = np.repeat(x[None], 2 * size, axis=0)
    for j in range(size):
        points[2 * j, j] += eps
        points[2 * j + 1, j] -= eps
    core.z[:] = points[:, :width]
    core.act[:, 1] = points[:, width]
    core.act[:, 3] = points[:, width + 1]
    core.step(points[:, width + 2 :])
    out = np.concatenate([core.z, core.act[:, [1, 3]]], axis=1)
    return ((out[0::2] - out[1::2]) / (2.0 * eps)).T


@pytest.mark.parametrize(
    ("env_id", "n"),
    [
        ("trailer_env/Reverse-v1", 1),
        ("trailer_env/Reverse-v1", 3),
        ("trailer_env/Reverse-v1", 6),
        ("trailer_env/Dock-v0", 2),
    ],
)
def test_jacobian_against_central_differences(env_id: str, n: int) -> None:
    """d next state / d (state, action) by autograd against the kernel's differences."""
    run_core = batch_core(env_id, n, rows=1)
    for action in (0.5, -0.3, 0.8):  # a few steps: the mass moving, the convoy bent
        run_core.step(np.array([[action]]))
    state = TwinState.from_core(run_core)
    params = TwinParams.from_core(run_core)
    # An action whose servo acceleration is inside its bounds (the clip passes no gradient).
    frequency = run_core.settings.servo_frequency
    s, s_dot = run_core.act[0, 1], run_core.act[0, 3]
    target = s + (s_dot + 0.05) / frequency
    x0 = np.concatenate([run_core.z[0], [s, s_dot], [target / run_core.params.s_max]])
    width = run_core.z.shape[1]

    def next_state(x: Any) -> Any:
        act = state.act[0].clone()
        act = torch.cat(
            [act[:1], x[width : width + 1], act[2:3], x[width + 1 : width + 2], act[4:]]
        )
        moved = TwinState(x[None, :width], act[None], state.task, state.hold)
        after, *_ = step(moved, x[None, width + 2 :], params)
        return torch.cat([after.z[0], after.act[0, [1, 3]]])

    jacobian = torch.autograd.functional.jacobian(next_state, torch.tensor(x0)).numpy()
    core = type(run_core)(run_core.settings, 2 * x0.size, track_pose=run_core.with_pose)
    core.act[:] = run_core.act[0]
    if env_id.endswith("Dock-v0"):
        core.target[:] = run_core.target[0]
    differences = kernel_jacobian(core, x0, n, 1e-6)
    scale = max(1.0, float(np.abs(differences).max()))
    assert np.abs(jacobian - differences).max() / scale < 1e-9  # measured 2e-11 to 4e-11
    assert np.abs(jacobian[:, -1]).max() > 1e-3  # the action moves the state


def test_batches_parameters_and_device_follow_the_tensors() -> None:
    """Per-row parameters as tensors give gradients in them; TwinStep binds the parameters."""
    core = batch_core("trailer_env/Reverse-v1", 2, rows=2)
    state = TwinState.from_core(core)
    mu = torch.tensor(core.params.mu, dtype=torch.float64, requires_grad=True)
    params = TwinParams.from_core(core).replace(mu=mu)
    action = torch.full((2, 1), 0.7, dtype=torch.float64)
    after, reward, cost, done = TwinStep(params)(state, action)
    after.z[:, 1].sum().backward()
    assert mu.grad is not None and abs(float(mu.grad)) > 0.0
    plain, *_ = step(state, action, TwinParams.from_core(core))
    torch.testing.assert_close(after.z, plain.z, rtol=0.0, atol=0.0)
    assert reward.dtype == torch.float64 and cost.shape == (2,) and done.dtype == torch.bool


def test_refuses_what_it_does_not_restate() -> None:
    with pytest.raises(ValueError, match="rk4"):
        TwinParams.make("trailer_env/Reverse-v1", n_trailers=2, fidelity="dopri5")
    with pytest.raises(ValueError, match="randomize"):
        TwinParams.make("trailer_env/Reverse-v1", n_trailers=2, randomize="mismatch10")
    with pytest.raises(TypeError, match="ConvoyCore"):
        TwinParams.from_core(object())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="TwinParams"):
        TwinStep("Reverse")  # type: ignore[arg-type]


def test_without_trailers_matches_the_kernel() -> None:
    """n = 0 (the cart alone): the recurrences run empty, the step still agrees."""
    run = kernel_run("trailer_env/Reverse-v1", 0, steps=60)
    actions = torch.tensor(run["actions"].reshape(60 * ROWS, -1))
    outcome = step_outcome(run["before"], actions, run["params"])
    z = outcome.state.z.numpy().reshape(60, ROWS, -1)
    assert relative_error(z, run["z"]) < STEP_TOLERANCE
    reward = outcome.reward.numpy().reshape(60, ROWS)
    assert relative_error(reward, run["reward"]) < STEP_TOLERANCE


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
def test_cuda_step_matches_cpu() -> None:
    run = kernel_run("trailer_env/Dock-v0", 3, steps=50)
    actions = torch.tensor(run["actions"].reshape(50 * ROWS, -1))
    on_cpu = step_outcome(run["before"], actions, run["params"])
    moved = TwinState(*(part.cuda() for part in run["before"]))
    on_gpu = step_outcome(moved, actions.cuda(), run["params"])
    assert on_gpu.state.z.is_cuda
    torch.testing.assert_close(on_gpu.state.z.cpu(), on_cpu.state.z, rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(on_gpu.reward.cpu(), on_cpu.reward, rtol=1e-12, atol=1e-12)
    assert torch.equal(on_gpu.terminated.cpu(), on_cpu.terminated)


def test_per_row_parameters_with_different_substep_counts_match_the_kernel() -> None:
    """Rows whose states need different substep counts are integrated in groups: each
    group with its own rows' parameters (as the kernel's blocks)."""
    from trailer_env.randomize import PARAMETERS
    from trailer_env.twin.physics import substep_counts

    envs = gym.make_vec(
        "trailer_env/Reverse-v1",
        num_envs=64,
        vectorization_mode="vector_entry_point",
        n_trailers=2,
        randomize="mismatch40",
    )
    speeds = np.linspace(-0.5, -6.0, 64)
    starts = np.column_stack([speeds, np.zeros(64), np.full(64, 0.1), np.full(64, -0.05)])
    envs.reset(seed=3, options={"state": starts})
    core = envs.unwrapped.core
    values = torch.from_numpy(core.param_values.copy())
    params = TwinParams.make("trailer_env/Reverse-v1", n_trailers=2).replace(
        **{name: values[:, k] for k, name in enumerate(PARAMETERS)}
    )
    state = TwinState.from_core(core)
    action = torch.linspace(-1.0, 1.0, 64, dtype=torch.float64)[:, None]
    counts = substep_counts(state.z, state.act, params)
    assert counts.unique().numel() > 1
    after, *_ = step(state, action, params)
    envs.step(action.numpy())
    kernel = torch.from_numpy(core.z.copy())
    torch.testing.assert_close(after.z, kernel, rtol=1e-12, atol=1e-12)


def test_straight_through_keeps_the_values_and_passes_the_saturated_gradient() -> None:
    envs = gym.make_vec(
        "trailer_env/Reverse-v1", num_envs=4, vectorization_mode="vector_entry_point", n_trailers=2
    )
    envs.reset(seed=50000)
    core = envs.unwrapped.core
    exact = TwinParams.from_core(core)
    surrogate = exact.replace(straight_through=True)
    state = TwinState.from_core(core)
    # Targets far from the mass (the servo saturates) and beyond the box (the action clips).
    action = torch.tensor([[0.9], [-0.9], [1.5], [0.0]], dtype=torch.float64)
    grads = []
    for params in (exact, surrogate):
        pushed = action.clone().requires_grad_(True)
        after = step(state, pushed, params)[0]
        (after.z[:, 1].sum()).backward()  # the turning rate after the step
        assert pushed.grad is not None
        grads.append((after.z.detach(), pushed.grad[:, 0].numpy().copy()))
    (values, exact_grad), (same_values, surrogate_grad) = grads
    assert torch.equal(values, same_values)  # the forward step is untouched
    # Saturated rows: no gradient exactly, the surrogate's through the clip.
    np.testing.assert_array_equal(exact_grad[:3], 0.0)
    assert np.all(np.abs(surrogate_grad[:3]) > 1e-6)
    envs.close()
