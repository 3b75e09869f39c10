"""Plane reconstruction: poses of every body and the no-slip constraints."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import ConvoyParams, body_poses, rhs, simulate


def test_straight_convoy_lies_on_a_line() -> None:
    xs, ys, thetas = body_poses(2.0, 1.0, 1.0, np.pi / 2, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(xs, [1.0, 1.0, 1.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(ys, [1.0, -1.0, -3.0, -5.0], atol=1e-15)
    np.testing.assert_allclose(thetas, np.pi / 2)


def test_rods_have_length_l_and_headings_subtract_hitch_angles(rng: np.random.Generator) -> None:
    alpha = rng.uniform(-np.pi, np.pi, (7, 4))
    theta = rng.uniform(-np.pi, np.pi, 7)
    xs, ys, thetas = body_poses(0.7, rng.normal(size=7), rng.normal(size=7), theta, alpha)
    np.testing.assert_allclose(np.hypot(np.diff(xs), np.diff(ys)), 0.7, rtol=1e-14)
    np.testing.assert_allclose(thetas[:, 0] - thetas[:, -1], alpha.sum(axis=1), atol=1e-13)
    # Each rod points along its trailer's heading, from the trailer to the body ahead.
    np.testing.assert_allclose(-np.diff(xs), 0.7 * np.cos(thetas[:, 1:]), atol=1e-14)


@pytest.mark.parametrize("n", [0, 1, 3, 5])
def test_every_body_rolls_without_slipping_along_a_trajectory(
    rng: np.random.Generator, n: int
) -> None:
    params = ConvoyParams(n_trailers=n, mu=0.3, a=0.4)
    z0 = np.zeros(n + 5)
    z0[:2] = [-1.2, 0.4]
    z0[2 : n + 2] = rng.uniform(-0.6, 0.6, n)
    run = simulate(params, z0, 0.05, 100, substeps=2, s0=0.1, s_dot0=0.0, s_ddot=-0.05)
    z = run.z
    z_dot = rhs(params, z, run.s, run.s_dot, -0.05)
    alpha, alpha_dot = z[:, 2 : n + 2], z_dot[:, 2 : n + 2]
    _, _, thetas = body_poses(params.l, z[:, n + 2], z[:, n + 3], z[:, n + 4], alpha)
    # Velocities by the chain rule through the poses (exact, no finite differences).
    theta_dots = z[:, 1:2] - np.concatenate(
        [np.zeros((len(z), 1)), np.cumsum(alpha_dot, axis=1)], axis=1
    )
    x_dots = z_dot[:, n + 2 : n + 3] + params.l * np.concatenate(
        [np.zeros((len(z), 1)), np.cumsum(np.sin(thetas[:, 1:]) * theta_dots[:, 1:], axis=1)],
        axis=1,
    )
    y_dots = z_dot[:, n + 3 : n + 4] - params.l * np.concatenate(
        [np.zeros((len(z), 1)), np.cumsum(np.cos(thetas[:, 1:]) * theta_dots[:, 1:], axis=1)],
        axis=1,
    )
    slip = x_dots * np.sin(thetas) - y_dots * np.cos(thetas)
    assert np.max(np.abs(slip)) < 1e-13
    # And the bodies really move: the constraint is not trivially satisfied.
    assert np.median(np.hypot(x_dots, y_dots)) > 0.3


def test_body_poses_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="l must be"):
        body_poses(0.0, 0.0, 0.0, 0.0, [0.0])
    with pytest.raises(ValueError, match="alpha contains non-finite"):
        body_poses(1.0, 0.0, 0.0, 0.0, [np.nan])
    with pytest.raises(ValueError, match="broadcast"):
        body_poses(1.0, np.zeros(3), 0.0, 0.0, np.zeros((2, 1)))
