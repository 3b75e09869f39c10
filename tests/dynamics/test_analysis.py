"""Numerical checks of dynamics.analysis against physics.md sections 6-8.

Every stated result is checked against something computed independently of
the formula being tested: the chain rule through ``rhs``, numerical Jacobians,
simulations (``simulate``) and closed forms written out here.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
import pytest

from dynamics import ConvoyParams, energy, inertia_R, rhs, simulate, step_rk4
from dynamics import analysis as an

SEED = 20240612
NS = range(5)


def _make_params(**fields: float | int) -> ConvoyParams:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return ConvoyParams(**fields)  # type: ignore[arg-type]


def _draw_params(rng: np.random.Generator, n: int, a: float | None = None) -> ConvoyParams:
    """Random physical parameters (J < m l^2); the moving mass is left on to check it is ignored."""
    rod = rng.uniform(0.4, 1.6)
    m = rng.uniform(0.2, 2.0)
    return _make_params(
        n_trailers=n,
        M=rng.uniform(0.3, 3.0),
        J0=rng.uniform(0.05, 1.5),
        a=rng.uniform(0.05, 1.2) if a is None else a,
        m=m,
        J=rng.uniform(0.0, 0.95) * m * rod**2,
        l=rod,
        mu=0.3,
        b=0.5,
    )


def _draw_state(rng: np.random.Generator, n: int, size: int) -> np.ndarray:
    return np.concatenate(
        [rng.uniform(-2.0, 2.0, (size, 2)), rng.uniform(-np.pi, np.pi, (size, n))], axis=1
    )


def _wrap(angle: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * np.asarray(angle)))


# ----------------------------------------------------------------------------
# Section 6: energy tori
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("n", NS)
def test_torus_round_trip(n: int) -> None:
    rng = np.random.default_rng([SEED, 1, n])
    p = _draw_params(rng, n)
    free = p.replace(mu=0.0)
    z = _draw_state(rng, n, 50)
    E, beta, alpha = an.to_torus(p, z)
    assert np.max(np.abs(E - energy(free, z)) / E) < 1e-14
    back = an.from_torus(p, E, beta, alpha)
    assert np.max(np.abs(back - z)) < 1e-13
    # The other way round, with beta anywhere on the circle.
    E2 = rng.uniform(0.1, 5.0, 50)
    beta2 = rng.uniform(-3 * np.pi, 3 * np.pi, 50)
    alpha2 = rng.uniform(-np.pi, np.pi, (50, n))
    E3, beta3, alpha3 = an.to_torus(p, an.from_torus(p, E2, beta2, alpha2))
    assert np.max(np.abs(E3 - E2) / E2) < 1e-14
    assert np.max(np.abs(_wrap(beta3 - beta2))) < 1e-13
    assert np.array_equal(alpha3, alpha2)


def _torus_field_oracle(
    p: ConvoyParams, E: np.ndarray, beta: np.ndarray, alpha: np.ndarray
) -> np.ndarray:
    """alpha_dot on the torus written out from physics.md section 6 (independent of rhs)."""
    R = inertia_R(p, alpha)
    speed, spin = np.sqrt(2 * E / R), np.sqrt(2 * E / p.I0)
    n = alpha.shape[-1]
    out = np.empty_like(alpha)
    if n == 0:
        return out
    out[..., 0] = spin * np.sin(beta) - speed * np.sin(alpha[..., 0]) * np.cos(beta) / p.l
    for k in range(1, n):  # A_k for k = 2..n, 0-based index k
        prefix = np.prod(np.cos(alpha[..., : k - 1]), axis=-1)
        A_k = (
            prefix
            * (np.sin(alpha[..., k - 1]) - np.cos(alpha[..., k - 1]) * np.sin(alpha[..., k]))
            / p.l
        )
        out[..., k] = speed * np.cos(beta) * A_k
    return out


def _torus_rate(
    p: ConvoyParams, z: np.ndarray, direction: np.ndarray, h: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Central difference of to_torus along ``direction``: d/dt (E, beta, alpha)."""
    Ep, bp, ap = an.to_torus(p, z + h * direction)
    Em, bm, am = an.to_torus(p, z - h * direction)
    return (Ep - Em) / (2 * h), _wrap(bp - bm) / (2 * h), (ap - am) / (2 * h)


@pytest.mark.parametrize("n", NS)
def test_torus_field_is_the_chain_rule_through_rhs(n: int) -> None:
    """d/dt to_torus(z(t)) along rhs equals torus_field (Richardson central differences)."""
    rng = np.random.default_rng([SEED, 2, n])
    worst = {"E": 0.0, "beta": 0.0, "alpha": 0.0, "oracle": 0.0}
    for sign_a in (1.0, -1.0):
        p = _draw_params(rng, n, a=sign_a * rng.uniform(0.05, 1.2))
        free = p.replace(mu=0.0)
        z = _draw_state(rng, n, 40)
        direction = rhs(free, z)

        coarse = _torus_rate(p, z, direction, 1e-3)
        fine = _torus_rate(p, z, direction, 5e-4)
        E_dot, beta_dot_fd, alpha_dot_fd = (
            (4 * f - c) / 3 for c, f in zip(coarse, fine, strict=True)
        )
        E, beta, alpha = an.to_torus(p, z)
        beta_dot, alpha_dot = an.torus_field(p, E, beta, alpha)
        scale = np.sqrt(E)  # rates scale like sqrt(E) (homogeneity)
        worst["E"] = max(worst["E"], float(np.max(np.abs(E_dot) / E)))
        worst["beta"] = max(worst["beta"], float(np.max(np.abs(beta_dot - beta_dot_fd) / scale)))
        worst["alpha"] = max(
            worst["alpha"],
            float(np.max(np.abs(alpha_dot - alpha_dot_fd) / scale[:, None], initial=0)),
        )
        oracle = _torus_field_oracle(free, E, beta, alpha)
        worst["oracle"] = max(
            worst["oracle"], float(np.max(np.abs(alpha_dot - oracle) / scale[:, None], initial=0))
        )
    assert worst["E"] < 1e-8, worst
    assert worst["beta"] < 1e-8, worst
    assert worst["alpha"] < 1e-8, worst
    assert worst["oracle"] < 1e-13, worst


def test_energy_conserved_by_simulate_with_mu_zero() -> None:
    rng = np.random.default_rng([SEED, 3])
    for a in (0.4, -0.4):  # a < 0: every equilibrium is a saddle, the motion keeps wandering
        p = _draw_params(rng, 3, a=a).replace(mu=0.0)
        z0 = _draw_state(rng, 3, 4)
        E0 = energy(p, z0)
        plain = simulate(p, z0, 0.2, 1000, substeps=20)  # t = 200, RK4 step 0.01
        kept = simulate(p, z0, 0.2, 1000, substeps=20, preserve_energy=True)
        drift_plain = float(np.max(np.abs(energy(p, plain.z) - E0) / E0))
        drift_kept = float(np.max(np.abs(energy(p, kept.z) - E0) / E0))
        assert drift_plain < 2e-6, drift_plain
        assert drift_kept < 5e-14, drift_kept


def test_homogeneity_of_the_flow() -> None:
    """(c u(ct), c omega(ct), alpha(ct)) is a solution: compare two simulations."""
    rng = np.random.default_rng([SEED, 4])
    for c in (2.5, 0.4):
        p = _draw_params(rng, 3, a=rng.uniform(-1.0, 1.0))
        z0 = _draw_state(rng, 3, 1)[0]
        base = simulate(p.replace(mu=0.0), z0, 0.05, 200, substeps=16)
        scaled_z0 = z0 * np.array([c, c, 1, 1, 1])
        scaled = simulate(p.replace(mu=0.0), scaled_z0, 0.05 / c, 200, substeps=12)
        want = base.z * np.array([c, c, 1, 1, 1])
        err = np.max(np.abs(scaled.z - want) / np.array([c, c, 1, 1, 1]))
        assert err < 1e-8, (c, err)


# ----------------------------------------------------------------------------
# Section 7: equilibria
# ----------------------------------------------------------------------------


def _torus_jacobian(
    p: ConvoyParams, E: float, beta: float, alpha: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """Jacobian of torus_field in (beta, alpha_1..alpha_n) by central differences."""
    point = np.concatenate([[beta], alpha])
    width = point.size
    shifted = np.concatenate([point + h * np.eye(width), point - h * np.eye(width)])
    beta_dot, alpha_dot = an.torus_field(p, E, shifted[:, 0], shifted[:, 1:])
    values = np.concatenate([beta_dot[:, None], alpha_dot], axis=1)
    return ((values[:width] - values[width:]) / (2 * h)).T


@pytest.mark.parametrize("n", range(5))
def test_equilibria_and_their_eigenvalues(n: int) -> None:
    rng = np.random.default_rng([SEED, 5, n])
    worst = {
        "rhs": 0.0,
        "energy": 0.0,
        "transverse": 0.0,
        "upper": 0.0,
        "diag": 0.0,
        "torus_upper": 0.0,
        "torus_diag": 0.0,
        "charpoly": 0.0,
        "eig": 0.0,
    }
    for draw in range(3):
        p = _draw_params(rng, n, a=(1 if draw % 2 == 0 else -1) * rng.uniform(0.05, 1.2))
        free = p.replace(mu=0.0)
        E = float(rng.uniform(0.2, 4.0))
        found = an.equilibria(p, E)
        assert len(found) == 2 ** (n + 1)
        assert len({eq.sigma for eq in found}) == 2 ** (n + 1)
        for eq in found:
            speed = math.sqrt(2 * E / (free.M + n * free.m))
            worst["rhs"] = max(worst["rhs"], float(np.max(np.abs(rhs(free, eq.z)))) / speed**2)
            worst["energy"] = max(worst["energy"], abs(float(energy(free, eq.z)) - E) / E)
            assert eq.z[0] == pytest.approx(eq.sigma[0] * speed, rel=1e-14)
            assert np.allclose(np.cos(eq.z[2:]), eq.sigma[1:], atol=0, rtol=1e-15)
            lam = eq.eigenvalues
            scale = float(np.max(np.abs(lam)))
            # Full (n+2) Jacobian: the u row and column vanish (the zero eigenvalue
            # transverse to the torus); the rest is lower triangular.
            jac = an.jacobian(p, eq.z)
            worst["transverse"] = max(
                worst["transverse"], max(np.max(np.abs(jac[0])), np.max(np.abs(jac[:, 0]))) / scale
            )
            block = jac[1:, 1:]
            worst["upper"] = max(worst["upper"], float(np.max(np.abs(np.triu(block, 1)))) / scale)
            worst["diag"] = max(worst["diag"], float(np.max(np.abs(np.diag(block) - lam))) / scale)
            # The characteristic polynomial is well conditioned even where eigenvalues
            # repeat (lambda_1..lambda_n are all +-c: Jordan blocks).
            charpoly_err = np.abs(np.poly(jac) - np.poly(np.concatenate([[0.0], lam])))
            worst["charpoly"] = max(
                worst["charpoly"],
                float(np.max(charpoly_err / scale ** np.arange(n + 3))),
            )
            # The same on the torus itself, through torus_field.
            beta = 0.0 if eq.sigma[0] > 0 else math.pi
            tj = _torus_jacobian(p, E, beta, eq.z[2:])
            worst["torus_upper"] = max(
                worst["torus_upper"], float(np.max(np.abs(np.triu(tj, 1)))) / scale
            )
            worst["torus_diag"] = max(
                worst["torus_diag"], float(np.max(np.abs(np.diag(tj) - lam))) / scale
            )
            # The spectra restricted to the torus (the u row and column, i.e. the
            # transverse zero eigenvalue, dropped; or through torus_field). Not on
            # the full Jacobian: lambda_1..lambda_n repeat in Jordan blocks, and the
            # 1e-16 noise in the u row moves them by up to ~1e-5 for n = 4.
            for restricted in (block, tj):
                eigs = np.sort(np.linalg.eigvals(restricted).real)
                worst["eig"] = max(worst["eig"], float(np.max(np.abs(eigs - np.sort(lam)))) / scale)
            # Kinds from the stated rules (a > 0). Turning the cart round maps
            # (a, u, alpha_1) to (-a, -u, alpha_1 + pi), so for a < 0 the rules apply
            # with sigma_0 and sigma_1 flipped.
            signs = list(eq.sigma)
            if free.a < 0:
                signs[: min(2, n + 1)] = [-s for s in signs[: min(2, n + 1)]]
            straight = all(s == 1 for s in signs[1:])
            want = ("stable node" if signs[0] > 0 else "unstable node") if straight else "saddle"
            assert eq.kind == want, (eq.sigma, free.a, eq.kind)
            assert eq.stable == (eq.kind == "stable node")
            if eq.kind == "stable node":
                assert np.all(np.diag(tj) < 0)
    assert worst["rhs"] < 1e-12, worst
    assert worst["energy"] < 1e-14, worst
    assert worst["transverse"] < 1e-9, worst
    assert worst["upper"] < 1e-9, worst
    assert worst["diag"] < 1e-6, worst
    assert worst["torus_upper"] < 1e-9, worst
    assert worst["torus_diag"] < 1e-6, worst
    assert worst["charpoly"] < 1e-6, worst
    assert worst["eig"] < 1e-6, worst


def test_equilibria_mu_is_ignored_and_fields_frozen() -> None:
    p = _make_params(n_trailers=2, mu=0.7)
    with_mass = an.equilibria(p, 1.0)
    without = an.equilibria(p.replace(mu=0.0), 1.0)
    for one, other in zip(with_mass, without, strict=True):
        assert np.array_equal(one.z, other.z)
        assert np.array_equal(one.eigenvalues, other.eigenvalues)
    with pytest.raises(ValueError):
        with_mass[0].eigenvalues[0] = 1.0
    with pytest.raises(AttributeError):
        with_mass[0].kind = "saddle"  # type: ignore[misc]


# ----------------------------------------------------------------------------
# Section 8: a = 0
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("n", NS)
def test_a_zero_omega_is_constant(n: int) -> None:
    rng = np.random.default_rng([SEED, 6, n])
    p = _draw_params(rng, n, a=0.0).replace(mu=0.0)
    z0 = _draw_state(rng, n, 5)
    trajectory = simulate(p, z0, 0.02, 1000, substeps=2)
    assert np.max(np.abs(trajectory.z[..., 1] - z0[:, 1])) == 0.0


@pytest.mark.parametrize("n", NS)
def test_relative_equilibria(n: int) -> None:
    rng = np.random.default_rng([SEED, 7, n])
    p = _draw_params(rng, n, a=0.0)
    free = p.replace(mu=0.0)
    omega0 = float(rng.uniform(0.3, 1.0)) * rng.choice([-1.0, 1.0])
    u0 = math.sqrt(n + 0.5) * free.l * abs(omega0) * rng.uniform(1.0, 2.0) * rng.choice([-1.0, 1.0])
    found = an.relative_equilibria(p, u0, omega0)
    assert len(found) == 2**n
    assert len({rel.sigma for rel in found}) == 2**n
    assert found[0].sigma == (1,) * n
    ratio2 = (free.l * omega0) ** 2
    for rel in found:
        assert float(np.max(np.abs(rhs(free, rel.z)))) < 1e-12 * u0**2
        assert rel.radius == pytest.approx(abs(u0 / omega0), rel=1e-15)
        assert rel.radius >= math.sqrt(n) * free.l
        k = np.arange(1, n + 1)
        sin2 = ratio2 / (u0**2 - (k - 1) * ratio2)
        cos2 = (u0**2 - k * ratio2) / (u0**2 - (k - 1) * ratio2)
        assert np.allclose(np.sin(rel.z[2:]) ** 2, sin2, rtol=1e-13, atol=0)
        assert np.allclose(np.cos(rel.z[2:]) ** 2, cos2, rtol=1e-12, atol=1e-15)
        assert tuple(np.sign(np.cos(rel.z[2:])).astype(int)) == rel.sigma
    # Past the bound n l^2 omega0^2 <= u0^2 there are none (n >= 1).
    too_slow = math.sqrt(max(n, 1) - 0.01) * free.l * abs(omega0)
    assert (an.relative_equilibria(p, too_slow, omega0) == []) == (n >= 1)
    # Just inside the bound the last trailer is nearly perpendicular.
    if n >= 1:
        border = an.relative_equilibria(
            p, math.sqrt(n) * free.l * abs(omega0) * (1 + 1e-12), omega0
        )
        assert len(border) == 2**n
        assert abs(abs(border[0].z[-1]) - math.pi / 2) < 1e-5
        assert border[0].radius == pytest.approx(math.sqrt(n) * free.l, rel=1e-11)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_relative_equilibrium_runs_on_a_circle(n: int) -> None:
    rng = np.random.default_rng([SEED, 8, n])
    p = _draw_params(rng, n, a=0.0).replace(mu=0.0)
    omega0 = 0.7
    u0 = math.sqrt(n + 1.0) * p.l * omega0 * 1.3
    principal = an.relative_equilibria(p, u0, omega0)[0]
    x0, y0, theta0 = 0.3, -0.2, 0.4
    z0 = np.concatenate([principal.z, [x0, y0, theta0]])
    turn_time = 2 * math.pi / omega0
    trajectory = simulate(p, z0, turn_time / 200, 600, substeps=2)  # three turns
    centre = np.array([x0, y0]) + (u0 / omega0) * np.array([-math.sin(theta0), math.cos(theta0)])
    distance = np.hypot(trajectory.z[:, -3] - centre[0], trajectory.z[:, -2] - centre[1])
    assert float(np.max(np.abs(distance - principal.radius))) < 1e-9 * principal.radius
    assert float(np.max(np.abs(trajectory.z[:, : n + 2] - principal.z))) < 1e-12


# ----------------------------------------------------------------------------
# Section 8: one trailer, a = 0
# ----------------------------------------------------------------------------

ONE = _make_params(n_trailers=1, M=1.3, J0=0.25, a=0.0, m=0.9, J=0.15, l=0.8, mu=0.3)
OMEGA0 = 0.9


def _circle_state(p: ConvoyParams, E: float, omega0: float, alpha: float) -> np.ndarray:
    u = math.sqrt((2 * E - p.J0 * omega0**2) / float(inertia_R(p, [alpha])))
    return np.array([u, omega0, alpha])


def _time_to_reach(
    p: ConvoyParams, z0: np.ndarray, target: float, dt: float, n_steps: int
) -> float:
    """First time alpha = target (alpha increasing), refined by secant steps of step_rk4."""
    trajectory = simulate(p, z0, dt, n_steps, substeps=4)
    k = int(np.argmax(trajectory.z[:, 2] >= target)) - 1
    assert k >= 0 and trajectory.z[k + 1, 2] >= target
    start = trajectory.z[k]

    def miss(tau: float) -> float:
        if tau == 0.0:
            return float(start[2]) - target
        return float(step_rk4(p, start, tau, substeps=4)[0][2]) - target

    lo, hi = 0.0, dt
    f_lo, f_hi = miss(lo), miss(hi)
    for _ in range(30):
        tau = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        lo, f_lo, hi, f_hi = hi, f_hi, tau, miss(tau)
        if abs(f_hi) < 1e-15:
            break
    return float(trajectory.t[k] + hi)


def test_period_below_critical_energy_matches_simulation() -> None:
    free = ONE.replace(mu=0.0)
    E_min, E_c = 0.5 * ONE.J0 * OMEGA0**2, an.critical_energy(ONE, OMEGA0)
    assert an.period(ONE, E_min, OMEGA0) == pytest.approx(2 * math.pi / OMEGA0, rel=1e-14)
    worst = 0.0
    for fraction in (0.0, 0.4, 0.9):
        E = E_min + fraction * (E_c - E_min)
        T = an.period(ONE, E, OMEGA0)
        z0 = _circle_state(free, E, OMEGA0, 0.0)
        rates = an.one_trailer_hitch_rate(ONE, E, OMEGA0, np.linspace(0, 2 * np.pi, 721))
        assert np.all(rates > 0)  # alpha turns all the way round
        measured = _time_to_reach(free, z0, 2 * math.pi, T / 1000, 1100)
        worst = max(worst, abs(measured - T) / T)
    assert worst < 1e-6, worst


def test_period_diverges_like_inverse_sqrt_at_critical_energy() -> None:
    """Saddle-node on the invariant circle: T (E_c - E)^(1/2) tends to a constant."""
    E_c = an.critical_energy(ONE, OMEGA0)
    scaled = [an.period(ONE, E_c * (1 - d), OMEGA0) * math.sqrt(d) for d in (1e-6, 1e-8, 1e-10)]
    assert abs(scaled[1] / scaled[0] - 1) < 1e-3 and abs(scaled[2] / scaled[1] - 1) < 1e-4, scaled


def test_critical_energy() -> None:
    free = ONE.replace(mu=0.0)
    E_c = an.critical_energy(ONE, OMEGA0)
    at_peak = np.array([free.l * OMEGA0, OMEGA0, math.pi / 2])
    assert float(energy(free, at_peak)) == pytest.approx(E_c, rel=1e-14)
    assert float(np.max(np.abs(rhs(free, at_peak)))) < 1e-15
    rates = an.one_trailer_hitch_rate(ONE, E_c, OMEGA0, np.linspace(0, 2 * np.pi, 7201))
    assert float(rates.min()) > -1e-15 and abs(float(rates[1800])) < 1e-15  # index 1800: pi/2
    # Just above E_c the two equilibria are born at pi/2.
    a1, a2 = an.one_trailer_equilibria(ONE, E_c * (1 + 1e-8), OMEGA0)
    assert a1 < math.pi / 2 < a2 and max(abs(a1 - math.pi / 2), abs(a2 - math.pi / 2)) < 1e-3


def test_equilibria_above_critical_energy() -> None:
    free = ONE.replace(mu=0.0)
    E_c = an.critical_energy(ONE, OMEGA0)
    for E in (1.05 * E_c, 2.0 * E_c, 10.0 * E_c):
        a1, a2 = an.one_trailer_equilibria(ONE, E, OMEGA0)
        assert 0 < a1 < math.pi / 2 < a2 < math.pi
        budget = 2 * E - free.J0 * OMEGA0**2
        level = (free.l * OMEGA0) ** 2 / budget
        # Closed form of sin^2 / (M + m cos^2 + (J/l^2) sin^2) = level.
        sin2 = level * (free.M + free.m) / (1 - level * (free.J / free.l**2 - free.m))
        assert math.sin(a1) ** 2 == pytest.approx(sin2, rel=1e-14)
        assert a1 + a2 == pytest.approx(math.pi, rel=1e-14)
        for alpha, sign in ((a1, 1), (a2, -1)):
            z = _circle_state(free, E, OMEGA0, alpha)
            assert float(np.max(np.abs(rhs(free, z)))) < 1e-14
            assert z[0] == pytest.approx(free.l * OMEGA0 / math.sin(alpha), rel=1e-14)
            # They are the relative equilibria of section 8 with this speed.
            rel = next(r for r in an.relative_equilibria(ONE, z[0], OMEGA0) if r.sigma == (sign,))
            assert rel.z[2] == pytest.approx(alpha, rel=1e-14)
            # 1-D linearisation along the invariant circle; closed form
            # d alpha_dot / d alpha = -sqrt(K) (M + m) cos(alpha) / (l R^(3/2)).
            h = 1e-5
            slope = float(
                an.one_trailer_hitch_rate(ONE, E, OMEGA0, alpha + h)
                - an.one_trailer_hitch_rate(ONE, E, OMEGA0, alpha - h)
            ) / (2 * h)
            want = (
                -math.sqrt(budget)
                * (free.M + free.m)
                * math.cos(alpha)
                / (free.l * float(inertia_R(free, [alpha])) ** 1.5)
            )
            assert slope == pytest.approx(want, rel=1e-8)
            assert (slope < 0) == (sign == 1)  # alpha_1 stable, alpha_2 unstable
        assert an.limiting_radius(ONE, E, OMEGA0) == pytest.approx(free.l / math.sin(a1), rel=1e-15)


def _circle_fit_radius(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares (Kasa) circle through points: x^2 + y^2 + D x + E y + F = 0."""
    design = np.stack([x, y, np.ones_like(x)], axis=1)
    coeffs, *_ = np.linalg.lstsq(design, -(x**2 + y**2), rcond=None)
    d, e, f = coeffs
    return math.sqrt(d * d / 4 + e * e / 4 - f)


def test_simulation_converges_to_the_limiting_circle() -> None:
    free = ONE.replace(mu=0.0)
    E = 2.0 * an.critical_energy(ONE, OMEGA0)
    a1, a2 = an.one_trailer_equilibria(ONE, E, OMEGA0)
    turn_time = 2 * math.pi / OMEGA0
    worst_alpha, worst_radius = 0.0, 0.0
    for alpha0 in (0.0, 2.0, a2 + 0.05, -1.0):  # a2 + 0.05: runs round through 2 pi
        z0 = np.concatenate([_circle_state(free, E, OMEGA0, alpha0), [0.0, 0.0, 0.0]])
        trajectory = simulate(free, z0, turn_time / 200, 200 * 8, substeps=2)  # 8 turns
        last = trajectory.z[-201:]
        gap = _wrap(last[:, 2] - a1)
        worst_alpha = max(worst_alpha, float(np.max(np.abs(gap))))
        radius = _circle_fit_radius(last[:, 3], last[:, 4])
        worst_radius = max(worst_radius, abs(radius / an.limiting_radius(ONE, E, OMEGA0) - 1))
    assert worst_alpha < 1e-5, worst_alpha
    assert worst_radius < 1e-4, worst_radius


# ----------------------------------------------------------------------------
# Bad input
# ----------------------------------------------------------------------------


def test_bad_input_raises_value_error_naming_the_problem() -> None:
    p2 = _make_params(n_trailers=2)
    a0 = p2.replace(a=0.0)
    cases = [
        (lambda: an.to_torus(p2, np.zeros(3)), "length n\\+2"),
        (lambda: an.to_torus(p2, [1.0, np.nan, 0.0, 0.0]), "non-finite"),
        (lambda: an.from_torus(p2, -1.0, 0.0, [0.0, 0.0]), "E must be >= 0"),
        (lambda: an.from_torus(p2, 1.0, 0.0, [0.0]), "alpha must have last axis"),
        (lambda: an.from_torus(p2, np.ones(3), np.ones(2), [0.0, 0.0]), "broadcast"),
        (lambda: an.torus_field(p2, 1.0, np.inf, [0.0, 0.0]), "beta contains non-finite"),
        (lambda: an.equilibria(p2, 0.0), "E must be > 0"),
        (lambda: an.equilibria(a0, 1.0), "a != 0"),
        (lambda: an.equilibrium_eigenvalues(p2, 1.0, (1, 1)), "sigma must be n\\+1"),
        (lambda: an.jacobian(p2, np.zeros((2, 4))), "one state"),
        (lambda: an.jacobian(p2, np.zeros(4), eps=0.0), "eps must be > 0"),
        (lambda: an.relative_equilibria(p2, 1.0, 0.1), "needs a = 0"),
        (lambda: an.relative_equilibria(a0, 0.0, 0.0), "u0 = omega0 = 0"),
        (lambda: an.critical_energy(a0, 1.0), "n_trailers = 1"),
        (lambda: an.critical_energy(ONE.replace(a=0.3), 1.0), "needs a = 0"),
        (lambda: an.critical_energy(ONE, 0.0), "omega0 must be > 0"),
        (lambda: an.period(ONE, 0.1 * ONE.J0 * OMEGA0**2, OMEGA0), "below the rotational energy"),
        (lambda: an.period(ONE, an.critical_energy(ONE, OMEGA0), OMEGA0), "E_c"),
        (lambda: an.one_trailer_equilibria(ONE, an.critical_energy(ONE, OMEGA0), OMEGA0), "<= E_c"),
        (lambda: an.limiting_radius(ONE, 0.5 * an.critical_energy(ONE, OMEGA0), OMEGA0), "<= E_c"),
        (lambda: an.one_trailer_hitch_rate(ONE, 1.0, OMEGA0, np.nan), "non-finite"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError, match=message):
            call()


def test_sign_patterns_cover_all_equilibria() -> None:
    """The sigma of the returned equilibria are exactly {+1, -1}^(n+1)."""
    p = _make_params(n_trailers=3)
    sigmas = {eq.sigma for eq in an.equilibria(p, 2.0)}
    assert sigmas == set(itertools.product((1, -1), repeat=4))
