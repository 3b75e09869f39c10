"""Dock-v0's plane poses along an episode obey the rods and the no-slip constraints."""

from __future__ import annotations

import numpy as np

from dynamics import body_poses
from tests.trailer_env.helpers import make


def test_poses_along_an_episode_satisfy_the_no_slip_constraints() -> None:
    dt = 0.01
    env = make("Dock", n_trailers=3, dt=dt, rail_accel_max=4.0)
    env.reset(seed=6)
    core = env.unwrapped.core
    n, l = 3, core.params.l
    poses = []
    for k in range(250):
        z = core.z[0]
        poses.append(body_poses(l, z[n + 2], z[n + 3], z[n + 4], z[2 : 2 + n]))
        _, _, terminated, _, _ = env.step(np.array([np.sin(0.07 * k)], dtype=np.float32))
        if terminated:  # folded: the poses up to here still count
            break
    assert len(poses) > 100
    xs, ys, thetas = (np.array(p) for p in zip(*poses, strict=True))
    # Rods: consecutive axle midpoints stay l apart.
    np.testing.assert_allclose(np.hypot(np.diff(xs, axis=1), np.diff(ys, axis=1)), l, rtol=1e-12)
    # No slip: each axle midpoint moves along its body's heading (central differences).
    vx = (xs[2:] - xs[:-2]) / (2 * dt)
    vy = (ys[2:] - ys[:-2]) / (2 * dt)
    heading = thetas[1:-1]
    sideways = vx * np.sin(heading) - vy * np.cos(heading)
    speed = np.hypot(vx, vy)
    assert np.max(np.abs(sideways)) < 1e-4 * max(1.0, float(np.max(speed)))
    assert np.min(np.max(speed, axis=1)) > 0.5  # it really moves
    # The cart's own speed is u: the reconstruction x_dot = u cos(theta), y_dot = u sin(theta).
    forward = vx[:, 0] * np.cos(heading[:, 0]) + vy[:, 0] * np.sin(heading[:, 0])
    assert forward.max() < 0.0  # reversing


def test_dock_features_follow_the_last_axle() -> None:
    env = make("Dock", n_trailers=2)
    env.reset(seed=1)
    core = env.unwrapped.core
    for _ in range(20):
        obs, *_ = env.step(np.array([0.2], dtype=np.float32))
    z = core.z[0]
    xs, ys, thetas = body_poses(core.params.l, z[4], z[5], z[6], z[2:4])
    x, y, heading = core.target[0]
    dx, dy = xs[-1] - x, ys[-1] - y
    along = np.cos(heading) * dx + np.sin(heading) * dy
    across = -np.sin(heading) * dx + np.cos(heading) * dy
    np.testing.assert_allclose(obs[-4:-2], [along / 5.0, across / 5.0], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(
        obs[-2:], [np.sin(thetas[-1] - heading), np.cos(thetas[-1] - heading)], atol=1e-6
    )
