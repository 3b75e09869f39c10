"""The numbers behind the thesis pictures that ``docs/figures/`` draws.

Each picture is checked against something it does not itself compute: the equilibria
drawn are zeros of ``rhs``, their kinds follow from a finite-difference linearisation, the
period and the limiting radius read off simulated paths match ``dynamics.analysis``'s
closed forms, the decay rate read off the path matches the stable node's eigenvalue
written out here from the parameters, and the singular set drawn is where the computed
degree of nonholonomy exceeds n + 2.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from docs.figures import command
from docs.figures._common import (
    OMEGA0,
    TORUS_WINDOW,
    break_at_jumps,
    crossing_times,
    fit_circle,
    fit_decay_rate,
    wrap_into,
)
from docs.figures._common import ONE_TRAILER as ONE
from docs.figures._common import ONE_TRAILER_A0 as ONE_A0
from docs.figures.cart_paths import energy_for_rotation, limiting_circle_data, periodic_orbit_data
from docs.figures.invariant_circles import invariant_circles_data
from docs.figures.level_function import energy_level, level_function, level_function_data
from docs.figures.singular_set import singular_slice_data
from docs.figures.straight_line import straight_line_data
from docs.figures.torus_portrait import torus_equilibria, torus_linearisation, torus_portrait_data
from dynamics import ConvoyParams, analysis, energy, rhs

DOCS = Path(__file__).resolve().parents[2] / "docs"


def _stable_node_rates(params: ConvoyParams, E: float) -> tuple[float, float]:
    """lambda_0 and lambda_1 at the forward straight convoy, from the parameters alone."""
    speed = math.sqrt(2.0 * E / (params.M + params.n_trailers * params.m))
    return -(params.M * params.a / params.I0) * speed, -speed / params.l


# ---------------------------------------------------------------------------------------
# Helpers shared by the pictures
# ---------------------------------------------------------------------------------------


def test_crossing_times_are_fourth_order_accurate() -> None:
    t = np.linspace(0.0, 10.0, 201)
    values = t + 0.4 * np.sin(t)
    rates = 1.0 + 0.4 * np.cos(t)
    levels = np.array([1.0, 4.0, 9.0])
    found = crossing_times(t, values, rates, levels)
    assert np.allclose(found + 0.4 * np.sin(found), levels, atol=1e-8, rtol=0)
    assert math.isnan(crossing_times(t, values, rates, np.array([50.0]))[0])


def test_fit_circle_and_decay_rate_recover_exact_data() -> None:
    angle = np.linspace(0.3, 2.0, 30)
    centre_x, centre_y, radius = fit_circle(1.5 + 2.5 * np.cos(angle), -0.7 + 2.5 * np.sin(angle))
    assert (centre_x, centre_y, radius) == pytest.approx((1.5, -0.7, 2.5), rel=1e-12)
    t = np.linspace(0.0, 5.0, 50)
    assert fit_decay_rate(t, -3.0 * np.exp(-0.8 * t)) == pytest.approx(-0.8, rel=1e-12)


def test_wrapping_keeps_angles_in_the_window_and_breaks_lines() -> None:
    wrapped = wrap_into(np.array([-2.0, 5.0, 0.0, 10.0]))
    low, high = TORUS_WINDOW
    assert np.all((wrapped >= low) & (wrapped < high))
    assert np.allclose(np.cos(wrapped), np.cos([-2.0, 5.0, 0.0, 10.0]))
    x, y = break_at_jumps(np.array([0.0, 0.1, 6.0]), np.array([0.0, 0.1, 0.2]))
    assert np.isnan(x[2]) and np.isnan(y[2]) and x.size == 4


# ---------------------------------------------------------------------------------------
# 1. The energy torus (n = 1, a > 0)
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2])
def test_plotted_equilibria_are_equilibria_of_the_kinds_shown(n: int) -> None:
    params = ONE.replace(n_trailers=n)
    E = 0.5
    points = torus_equilibria(params, E)
    assert len(points) == 2 ** (n + 1)
    for point in points:
        assert np.max(np.abs(rhs(params, point.z))) < 1e-12
        beta_dot, alpha_dot = analysis.torus_field(params, E, point.beta, point.z[2:])
        assert abs(float(beta_dot)) < 1e-12 and np.max(np.abs(alpha_dot)) < 1e-12
        # The kind drawn follows from a finite-difference Jacobian of the torus field.
        jac = torus_linearisation(params, E, point.beta, point.z[2:])
        numeric = np.sort(np.linalg.eigvals(jac).real)
        assert np.allclose(numeric, np.sort(point.eigenvalues), rtol=1e-6, atol=1e-8)
        signs = {bool(v < 0) for v in numeric}
        expected = {"stable node": {True}, "unstable node": {False}, "saddle": {True, False}}
        assert signs == expected[point.kind]
    kinds = sorted(point.kind for point in points)
    assert kinds.count("stable node") == 1 and kinds.count("unstable node") == 1


def test_one_trailer_portrait_places_the_four_equilibria_as_the_thesis() -> None:
    where = {
        (round(p.alpha / math.pi, 12), round(p.beta / math.pi, 12)): p.kind
        for p in torus_equilibria(ONE, 0.5)
    }
    # Thesis figure 3.2(a): stable node (0, 0), unstable (0, pi), saddles (pi, 0), (pi, pi).
    assert where == {
        (0.0, 0.0): "stable node",
        (0.0, 1.0): "unstable node",
        (1.0, 0.0): "saddle",
        (1.0, 1.0): "saddle",
    }


def test_drawn_orbits_follow_the_drawn_field_and_end_at_the_stable_node() -> None:
    dt = 0.02
    data = torus_portrait_data(grid_size=9, t_end=25.0, dt=dt)
    assert data.alpha_dot.shape == data.beta_dot.shape == (9, 9)
    for (alpha, beta), energy_along in zip(data.paths, data.path_energy, strict=True):
        assert np.max(np.abs(energy_along / data.E - 1.0)) < 1e-6
        alpha_u, beta_u = np.unwrap(alpha), np.unwrap(beta)
        beta_dot, alpha_dot = analysis.torus_field(ONE, data.E, beta_u, alpha_u[:, None])
        # Central differences of the orbit against the field's arrows (error O(dt^2)).
        slope_alpha = (alpha_u[2:] - alpha_u[:-2]) / (2 * dt)
        slope_beta = (beta_u[2:] - beta_u[:-2]) / (2 * dt)
        assert np.max(np.abs(slope_alpha - alpha_dot[1:-1, 0])) < 2e-3
        assert np.max(np.abs(slope_beta - beta_dot[1:-1])) < 2e-3
        assert math.hypot(alpha[-1], beta[-1]) < 1e-3


# ---------------------------------------------------------------------------------------
# 2. The path straightens out (a > 0)
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", [1, 2])
def test_curvature_decays_at_the_stable_node_rate(n: int) -> None:
    params = ONE.replace(n_trailers=n)
    data = straight_line_data(params=params, dt=0.02)
    lambda_0, lambda_1 = _stable_node_rates(params, data.E)
    assert data.lambda_0 == pytest.approx(lambda_0, rel=1e-14)
    assert data.curvature_rate == pytest.approx(lambda_0, rel=1e-8)
    # The heading stops changing: the cart runs on a straight line.
    theta = data.z[:, n + 4]
    late = data.t >= data.t[-1] - 10.0
    assert np.ptp(theta[late]) < 1e-8
    if n == 1:
        # The hitch angle decays at the slower lambda_1 (approached slowly: lambda_0 is close).
        assert data.hitch_rate == pytest.approx(lambda_1, rel=0.02)


# ---------------------------------------------------------------------------------------
# 3. f(alpha) and the energy levels (n = 1, a = 0)
# ---------------------------------------------------------------------------------------


def test_level_function_peaks_at_the_critical_level_and_its_roots_are_circles() -> None:
    data = level_function_data()
    params, omega0 = data.params, data.omega0
    assert data.f_max == pytest.approx(float(np.max(data.f)), rel=1e-12)
    assert data.alpha[int(np.argmax(data.f))] == pytest.approx(math.pi / 2, rel=1e-12)
    E_c = analysis.critical_energy(params, omega0)
    assert energy_level(params, E_c, omega0) == pytest.approx(data.f_max, rel=1e-12)
    below, _, above = data.levels
    assert below > data.f_max and above < data.f_max
    assert data.roots[0] is None and data.roots[1] is None
    assert data.roots[2] is not None
    for root in data.roots[2]:
        assert float(level_function(params, np.array(root))) == pytest.approx(above, rel=1e-12)


@pytest.mark.parametrize("omega0", [1.0, 2.0])
def test_roots_of_the_squared_level_are_relative_equilibria_of_energy_e(omega0: float) -> None:
    params = ONE_A0
    E = 1.5 * analysis.critical_energy(params, omega0)
    for root in analysis.one_trailer_equilibria(params, E, omega0):
        z = np.array([params.l * omega0 / math.sin(root), omega0, root])
        assert np.max(np.abs(rhs(params, z))) < 1e-12
        assert float(energy(params, z)) == pytest.approx(E, rel=1e-12)


def test_the_thesis_level_without_the_square_gives_the_wrong_energy() -> None:
    """(3.41) writes l^2 omega0 / (2E - J0 omega0^2): at omega0 != 1 its root is off."""
    params, omega0 = ONE_A0, 2.0
    E = 1.5 * analysis.critical_energy(params, omega0)
    unsquared = params.l**2 * omega0 / (2.0 * E - params.J0 * omega0**2)
    alpha = np.linspace(1e-3, math.pi / 2, 200001)
    root = float(alpha[np.argmin(np.abs(level_function(params, alpha) - unsquared))])
    z = np.array([params.l * omega0 / math.sin(root), omega0, root])
    assert float(energy(params, z)) > 1.2 * E


# ---------------------------------------------------------------------------------------
# 4. Invariant circles and the cylinder omega = omega0
# ---------------------------------------------------------------------------------------


def test_invariant_circles_have_the_equilibria_drawn() -> None:
    data = invariant_circles_data(grid_size=21)
    params, omega0 = data.params, data.omega0
    alpha = np.linspace(0.0, 2.0 * math.pi, data.circle_u.shape[1])
    for E, u_curve, rate, on_circle in zip(
        data.energies, data.circle_u, data.circle_rate, data.equilibria, strict=True
    ):
        states = np.stack([u_curve, np.full_like(u_curve, omega0), alpha], axis=-1)
        assert np.allclose(energy(params, states), E, rtol=1e-12)
        assert np.allclose(rate, rhs(params, states)[:, 2], rtol=0, atol=1e-12)
        for point in on_circle:
            z = np.array([point.u, omega0, point.alpha])
            assert np.max(np.abs(rhs(params, z))) < 1e-12
            assert float(energy(params, z)) == pytest.approx(E, rel=1e-12)
            # Stability along the circle: d(alpha_dot)/d(alpha) < 0 at a stable point.
            step = 1e-6
            slope = np.diff(
                analysis.one_trailer_hitch_rate(
                    params, float(E), omega0, [point.alpha - step, point.alpha + step]
                )
            )[0]
            if point.stable is True:
                assert slope < 0
            elif point.stable is False:
                assert slope > 0
    below, at, above = data.circle_rate
    assert below.min() > 0.0  # E < E_c: alpha turns round, no equilibrium
    assert at.min() > -1e-12 and len(data.equilibria[1]) == 1  # E = E_c: touches 0 at pi/2
    assert data.equilibria[1][0].alpha == math.pi / 2
    assert data.equilibria[1][0].u == pytest.approx(params.l * omega0, rel=1e-15)
    # E > E_c: alpha_dot changes sign exactly twice, at the two equilibria drawn.
    sign_changes = alpha[:-1][np.diff(np.sign(above)) != 0]
    roots = [p.alpha for p in data.equilibria[2]]
    assert len(sign_changes) == 2
    spacing = alpha[1] - alpha[0]
    assert np.all(np.abs(np.array(roots) - sign_changes - 0.5 * spacing) <= spacing)


def test_the_black_curve_of_the_cylinder_is_made_of_equilibria() -> None:
    data = invariant_circles_data(grid_size=11)
    curve_alpha, curve_u = data.equilibrium_curve
    z = np.stack([curve_u, np.full_like(curve_u, data.omega0), curve_alpha], axis=-1)
    assert np.max(np.abs(rhs(data.params, z))) < 1e-12
    assert data.E_c == pytest.approx(
        0.5 * (ONE_A0.J0 + ONE_A0.J + ONE_A0.M * ONE_A0.l**2) * data.omega0**2, rel=1e-15
    )


# ---------------------------------------------------------------------------------------
# 5. The cart's paths (n = 1, a = 0)
# ---------------------------------------------------------------------------------------


def test_period_read_off_the_path_matches_t_of_e() -> None:
    run = periodic_orbit_data(E=0.45, n_periods=3, dt=0.02)
    assert run.period_read == pytest.approx(analysis.period(ONE_A0, 0.45, OMEGA0), rel=1e-8)


def test_quasi_periodic_path_turns_about_a_fixed_centre_each_period() -> None:
    run = periodic_orbit_data(E=0.45, n_periods=6, dt=0.02)
    x, y, theta = run.period_poses.T
    centre_x, centre_y, radius = fit_circle(x, y)
    assert np.max(np.abs(np.hypot(x - centre_x, y - centre_y) - radius)) < 1e-8
    # ... turned by omega0 T each time, the same angle as the heading.
    turn = np.diff(np.arctan2(y - centre_y, x - centre_x))
    heading_turn = np.diff(theta)
    assert np.max(np.abs(np.angle(np.exp(1j * (turn - heading_turn))))) < 1e-8
    assert heading_turn == pytest.approx(run.omega0 * run.period_theory, rel=1e-8)


def test_rational_rotation_gives_a_closed_path() -> None:
    p, q = 5, 3
    E = energy_for_rotation(ONE_A0, p / q)
    assert OMEGA0 * analysis.period(ONE_A0, E, OMEGA0) / (2 * math.pi) == (
        pytest.approx(p / q, rel=1e-12)
    )
    run = periodic_orbit_data(E=E, n_periods=q, dt=0.02)
    start, end = run.period_poses[0], run.period_poses[-1]
    assert math.hypot(end[0] - start[0], end[1] - start[1]) < 1e-7
    assert end[2] - start[2] == pytest.approx(2 * math.pi * p, rel=1e-9)
    # ... and not before: after one period the cart is elsewhere.
    assert math.hypot(*(run.period_poses[1, :2] - start[:2])) > 0.1


def test_limiting_circle_radius_read_off_the_path() -> None:
    run = limiting_circle_data(dt=0.02)
    assert run.radius_read == pytest.approx(
        analysis.limiting_radius(ONE_A0, run.E, run.omega0), rel=1e-8
    )
    alpha_1, _ = analysis.one_trailer_equilibria(ONE_A0, run.E, run.omega0)
    assert run.radius_read == pytest.approx(ONE_A0.l / math.sin(alpha_1), rel=1e-8)
    assert run.z[-1, 2] % (2 * math.pi) == pytest.approx(alpha_1, rel=1e-8)


# ---------------------------------------------------------------------------------------
# 6. The singular set
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(("n", "fixed"), [(2, ()), (3, (0.0,)), (3, (math.pi / 2,))])
def test_singular_set_drawn_is_where_the_degree_exceeds_n_plus_2(
    n: int, fixed: tuple[float, ...]
) -> None:
    data = singular_slice_data(n, 8, fixed)
    singular = data.margin < 1e-9
    assert singular.any() and not singular.all()
    assert np.array_equal(data.degree > n + 2, singular)
    assert np.all(data.degree[~singular] == n + 2)
    cos_1 = np.abs(np.cos(data.grid))[None, :] < 1e-9  # columns are alpha_1
    cos_2 = np.abs(np.cos(data.grid))[:, None] < 1e-9  # rows are alpha_2
    expected = cos_1 | cos_2 if n == 3 else np.broadcast_to(cos_1, singular.shape)
    assert np.array_equal(singular, expected)
    if n == 2:
        assert set(np.unique(data.degree)) == {4, 5}  # thesis appendix A


def test_the_last_hitch_angle_never_changes_the_degree() -> None:
    at_zero = singular_slice_data(3, 4, (0.0,))
    at_right_angle = singular_slice_data(3, 4, (math.pi / 2,))
    assert np.array_equal(at_zero.degree, at_right_angle.degree)


# ---------------------------------------------------------------------------------------
# The command
# ---------------------------------------------------------------------------------------


@pytest.mark.slow
def test_quick_command_writes_every_picture(tmp_path: Path) -> None:
    written = command.main(["--quick", "--out", str(tmp_path)])
    names = sorted(path.name for path in written)
    assert names == sorted(name for name, _, _ in command.figure_jobs(quick=True))
    for path in written:
        assert path.name.startswith("thesis_")
        assert 10_000 < path.stat().st_size < 250_000


def test_committed_pictures_are_modest() -> None:
    pictures = sorted((DOCS / "img").glob("thesis_*.png"))
    if not pictures:
        pytest.skip("run `python -m docs.figures` to write the pictures")
    for picture in pictures:
        assert picture.stat().st_size < 250_000, picture.name


def test_the_command_runs_from_the_root() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "docs.figures", "--help"],
        cwd=DOCS.parent,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("usage: python -m docs.figures [-h] [--out OUT] [--quick]")
