"""Check ``dynamics`` against the independent full-coordinate oracle (oracle.py).

The oracle derives the equations of motion from the bodies' kinetic energies and
the no-slip constraints with Lagrange multipliers; it shares nothing with
``dynamics`` or with physics.md sections 3-5 and 9 beyond the geometry.
"""

from __future__ import annotations

import importlib.util
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from dynamics import ConvoyParams, energy, energy_planar, rhs, rhs_planar


def _load_oracle() -> ModuleType:
    """Import oracle.py next to this file, whatever pytest's import mode."""
    name = "_trailer_env_tests_dynamics_oracle"
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name("oracle.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


oracle = _load_oracle()

SEED = 20240611
NS = range(6)
N_SAMPLES = 12
RTOL = 1e-9


def _rel_err(got: np.ndarray, want: np.ndarray) -> float:
    """Largest component error relative to the largest component of ``want``."""
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    assert got.shape == want.shape, (got.shape, want.shape)
    scale = max(float(np.max(np.abs(want), initial=0.0)), 1e-300)
    return float(np.max(np.abs(got - want), initial=0.0)) / scale


def _make_params(**fields: float | int) -> ConvoyParams:
    """Build ConvoyParams, silencing only the J >= m l^2 UserWarning."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return ConvoyParams(**fields)  # type: ignore[arg-type]


def _draw_params(rng: np.random.Generator, n: int, i: int, mu: float | None = None) -> ConvoyParams:
    """Random parameters; ``i`` cycles the sign of ``a`` and the regime of ``J``.

    Args:
        rng: Seeded generator.
        n: Number of trailers.
        i: Sample index: even -> a > 0, odd -> a < 0; (i // 2) even -> J < m l^2,
            odd -> J > m l^2 (unphysical but allowed).
        mu: Moving mass; random in [0, 1] when None.

    Returns:
        The parameters.
    """
    rod = rng.uniform(0.4, 1.6)
    m = rng.uniform(0.2, 2.0)
    a = (1.0 if i % 2 == 0 else -1.0) * rng.uniform(0.05, 1.2)
    j_ratio = rng.uniform(0.0, 0.95) if (i // 2) % 2 == 0 else rng.uniform(1.05, 3.0)
    return _make_params(
        n_trailers=n,
        M=rng.uniform(0.3, 3.0),
        J0=rng.uniform(0.05, 1.5),
        a=a,
        m=m,
        J=j_ratio * m * rod**2,
        l=rod,
        mu=rng.uniform(0.0, 1.0) if mu is None else mu,
        b=rng.uniform(-1.0, 1.0),
        s_max=0.6,
    )


def _draw_state(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random reduced state: u, omega in [-2, 2], hitch angles in [-pi, pi]."""
    return np.concatenate([rng.uniform(-2.0, 2.0, 2), rng.uniform(-np.pi, np.pi, n)])


def _draw_rail(rng: np.random.Generator) -> tuple[float, float, float]:
    """Random rail input (s, s_dot, s_ddot) with abs(s) <= 0.5."""
    return (rng.uniform(-0.5, 0.5), rng.uniform(-2.0, 2.0), rng.uniform(-3.0, 3.0))


def _draw_planar(rng: np.random.Generator) -> tuple[float, ...]:
    """Random planar input (xi, eta, xi_dot, eta_dot, xi_ddot, eta_ddot)."""
    return (
        rng.uniform(-1.0, 1.0),
        rng.uniform(-0.6, 0.6),
        rng.uniform(-2.0, 2.0),
        rng.uniform(-2.0, 2.0),
        rng.uniform(-3.0, 3.0),
        rng.uniform(-3.0, 3.0),
    )


def _pose(rng: np.random.Generator) -> tuple[float, float, float]:
    """Random cart pose used to embed the reduced state (result must not depend on it)."""
    return (rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0), rng.uniform(-np.pi, np.pi))


def _random_cases(
    stream: int, n: int, mu: float | None = None
) -> Iterator[tuple[np.random.Generator, int, ConvoyParams, np.ndarray]]:
    """N_SAMPLES random parameters and states from the generator seeded (SEED, stream, n).

    Yields ``(rng, i, params, z)``: whatever else a test draws from ``rng`` is drawn
    between two cases, so every test keeps its own reproducible stream.
    """
    rng = np.random.default_rng([SEED, stream, n])
    for i in range(N_SAMPLES):
        p = _draw_params(rng, n, i, mu)
        yield rng, i, p, _draw_state(rng, n)


def _planar_energy_of(p: ConvoyParams) -> Callable[[np.ndarray, np.ndarray, np.ndarray], float]:
    """energy_planar as a function of (z, (xi, eta), (xi_dot, eta_dot)), for _fd_energy_rate."""

    def planar_energy(z: np.ndarray, position: np.ndarray, velocity: np.ndarray) -> float:
        return float(energy_planar(p, z, position[0], position[1], velocity[0], velocity[1]))

    return planar_energy


def _rail_energy_of(p: ConvoyParams) -> Callable[[np.ndarray, np.ndarray], float]:
    """energy as a function of (z, (s, s_dot)), for _fd_energy_rate."""

    def rail_energy(z: np.ndarray, rail: np.ndarray) -> float:
        return float(energy(p, z, rail[0], rail[1]))

    return rail_energy


def _special_states(n: int) -> list[np.ndarray]:
    """States where some cos(alpha_k) or sin(alpha_k) vanishes exactly (or nearly).

    These catch implementations that divide by prefix products of cosines.
    """
    angles = [0.0, np.pi / 2, -np.pi / 2, np.pi, 1e-9, np.pi / 2 - 1e-9]
    out = []
    for k, first in enumerate(angles):
        alpha = np.array([angles[(k + j) % len(angles)] for j in range(n)])
        if n:
            alpha[0] = first
        out.append(np.concatenate([[1.3 - 0.4 * k, 0.7 - 0.3 * k], alpha]))
    out.append(np.concatenate([[0.0, 0.0], np.full(n, 0.3)]))  # at rest
    return out


def _fd_energy_rate(
    f: Callable[..., float], direction_args: list[tuple[np.ndarray, np.ndarray]]
) -> float:
    """Richardson-extrapolated central difference of f along a straight line.

    Args:
        f: Callable taking the points of ``direction_args`` moved by ``t * dir``.
        direction_args: Pairs ``(point, direction)``.

    Returns:
        d/dt f(point + t direction) at t = 0, error O(h^4).
    """

    def central(h: float) -> float:
        plus = [p + h * d for p, d in direction_args]
        minus = [p - h * d for p, d in direction_args]
        return (float(f(*plus)) - float(f(*minus))) / (2.0 * h)

    h = 1e-3
    return (4.0 * central(h / 2.0) - central(h)) / 3.0


# ----------------------------------------------------------------------------
# The oracle's own sanity (it must be right before it judges anything).
# ----------------------------------------------------------------------------


def test_oracle_chaplygin_sleigh() -> None:
    """n = 0, mu = 0: M u_dot = M a omega^2 and I0 omega_dot = -M a u omega."""
    rng = np.random.default_rng([SEED, 0])
    for i in range(N_SAMPLES):
        p = oracle.OracleParams(
            0,
            M=rng.uniform(0.3, 3),
            J0=rng.uniform(0.05, 1.5),
            a=rng.uniform(-1, 1),
            m=1.0,
            J=0.1,
            l=1.0,
            mu=0.0,
        )
        u, w = rng.uniform(-2, 2, 2)
        got = oracle.reduced_rhs_rail(p, np.array([u, w]), b=rng.uniform(-1, 1), pose=_pose(rng))
        i0 = p.J0 + p.M * p.a**2
        want = np.array([p.a * w**2, -p.M * p.a * u * w / i0])
        assert _rel_err(got, want) < 1e-12, (i, got, want)


@pytest.mark.parametrize("n", NS)
def test_oracle_invariance_constraints_and_energy(n: int) -> None:
    """Oracle: SE(2) invariance, constraints hold, dT/dt = actuator power (0 if mu = 0)."""
    rng = np.random.default_rng([SEED, 1, n])
    for i in range(N_SAMPLES):
        p = oracle.OracleParams.from_any(_draw_params(rng, n, i, mu=0.0 if i < 4 else None))
        z = _draw_state(rng, n)
        act = _draw_planar(rng)
        base = oracle.reduced_rhs_planar(p, z, *act)
        moved = oracle.reduced_rhs_planar(p, z, *act, pose=_pose(rng))
        assert _rel_err(moved, base) < 1e-11, (n, i)

        q, qd = oracle.full_state(p, z, *_pose(rng))
        qdd, _ = oracle.solve_full(p, q, qd, *act)
        fm = oracle.full_model(n)
        B = np.array(fm.B(*q, p.l), dtype=float)
        bdot = np.array(fm.Bdot_qd(*q, *qd, p.l), dtype=float).ravel()
        speed = abs(z[0]) + abs(z[1]) * p.l + 1e-300
        assert np.max(np.abs(B @ qd)) < 1e-13 * speed, (n, i)
        assert np.max(np.abs(B @ qdd + bdot)) < 1e-11 * max(1.0, np.max(np.abs(qdd))), (n, i)

        rate = oracle.energy_rate_planar(p, z, *act)
        power = oracle.actuator_power_planar(p, z, *act)
        e = oracle.energy_planar(p, z, *act[:4])
        assert abs(rate - power) < 1e-10 * max(abs(power), e), (n, i, rate, power)
        if p.mu == 0.0:
            assert abs(rate) < 1e-12 * max(e, 1e-300), (n, i, rate)


# ----------------------------------------------------------------------------
# dynamics against the oracle.
# ----------------------------------------------------------------------------


@pytest.mark.parametrize("n", NS)
def test_rhs_rail_matches_oracle(n: int) -> None:
    """rhs (lateral rail, xi = b, eta = s) equals the oracle at random states/params."""
    for rng, i, p, z in _random_cases(2, n):
        s, s_dot, s_ddot = _draw_rail(rng)
        got = rhs(p, z, s, s_dot, s_ddot)
        want = oracle.reduced_rhs_rail(p, z, p.b, s, s_dot, s_ddot, pose=_pose(rng))
        assert np.shape(got) == z.shape
        err = _rel_err(got, want)
        assert err < RTOL, f"n={n} i={i} p={p} z={z} s={(s, s_dot, s_ddot)} got={got} want={want}"


@pytest.mark.parametrize("n", NS)
def test_rhs_planar_matches_oracle(n: int) -> None:
    """rhs_planar equals the oracle at random states, params and mass motions."""
    for rng, i, p, z in _random_cases(3, n):
        act = _draw_planar(rng)
        got = rhs_planar(p, z, *act)
        want = oracle.reduced_rhs_planar(p, z, *act, pose=_pose(rng))
        assert np.shape(got) == z.shape
        err = _rel_err(got, want)
        assert err < RTOL, f"n={n} i={i} p={p} z={z} act={act} got={got} want={want}"


@pytest.mark.parametrize("n", NS)
def test_rhs_mu_zero_matches_oracle(n: int) -> None:
    """mu = 0 (no actuator): both entry points equal the oracle without the mass."""
    for rng, i, p, z in _random_cases(4, n, mu=0.0):
        want = oracle.reduced_rhs_rail(p, z, 0.0, pose=_pose(rng))
        s, s_dot, s_ddot = _draw_rail(rng)
        act = _draw_planar(rng)
        for got in (rhs(p, z), rhs(p, z, s, s_dot, s_ddot), rhs_planar(p, z, *act)):
            err = _rel_err(got, want)
            assert err < RTOL, f"n={n} i={i} p={p} z={z} got={got} want={want}"


@pytest.mark.parametrize("n", NS)
def test_rhs_special_configurations(n: int) -> None:
    """Exactly perpendicular / folded / straight hitches, and rest, match the oracle."""
    rng = np.random.default_rng([SEED, 5, n])
    for i, z in enumerate(_special_states(n)):
        p = _draw_params(rng, n, i)
        s, s_dot, s_ddot = _draw_rail(rng)
        got = rhs(p, z, s, s_dot, s_ddot)
        want = oracle.reduced_rhs_rail(p, z, p.b, s, s_dot, s_ddot)
        assert np.all(np.isfinite(got)), (n, z, got)
        err = _rel_err(got, want)
        assert err < RTOL, f"n={n} i={i} p={p} z={z} got={got} want={want}"


@pytest.mark.parametrize("n", NS)
def test_rail_is_planar_with_xi_b(n: int) -> None:
    """rhs(p, z, s, s_dot, s_ddot) == rhs_planar(p, z, b, s, 0, s_dot, 0, s_ddot)."""
    for rng, i, p, z in _random_cases(6, n):
        s, s_dot, s_ddot = _draw_rail(rng)
        got = rhs(p, z, s, s_dot, s_ddot)
        want = rhs_planar(p, z, p.b, s, 0.0, s_dot, 0.0, s_ddot)
        assert _rel_err(got, want) < 1e-12, (n, i, got, want)
        e_rail = energy(p, z, s, s_dot)
        e_planar = energy_planar(p, z, p.b, s, 0.0, s_dot)
        assert abs(float(e_rail) - float(e_planar)) <= 1e-12 * abs(float(e_planar)), (n, i)


@pytest.mark.parametrize("n", NS)
def test_batched_calls_match_single_calls(n: int) -> None:
    """Leading axes (3, 4): batched rhs / energy equal one-at-a-time calls and the oracle."""
    rng = np.random.default_rng([SEED, 7, n])
    p = _draw_params(rng, n, n)
    shape = (3, 4)
    z = np.stack([_draw_state(rng, n) for _ in range(12)]).reshape(*shape, n + 2)
    s = rng.uniform(-0.5, 0.5, shape)
    s_dot = rng.uniform(-2.0, 2.0, shape)
    s_ddot = rng.uniform(-3.0, 3.0, shape)
    act = [rng.uniform(-1.0, 1.0, shape) for _ in range(6)]
    s0, sd0, sdd0 = 0.2, -0.7, 1.1  # scalar inputs broadcast over the batch

    zdot_arr = rhs(p, z, s, s_dot, s_ddot)
    zdot_sc = rhs(p, z, s0, sd0, sdd0)
    zdot_pl = rhs_planar(p, z, *act)
    e_arr = energy(p, z, s, s_dot)
    e_sc = energy(p, z, s0, sd0)
    e_pl = energy_planar(p, z, *act[:4])
    assert np.shape(zdot_arr) == z.shape
    assert np.shape(zdot_sc) == z.shape
    assert np.shape(zdot_pl) == z.shape
    assert np.shape(e_arr) == shape
    assert np.shape(e_sc) == shape
    assert np.shape(e_pl) == shape

    for idx in np.ndindex(*shape):
        zi = z[idx]
        one = rhs(p, zi, s[idx], s_dot[idx], s_ddot[idx])
        assert _rel_err(zdot_arr[idx], one) < 1e-12, idx
        assert _rel_err(zdot_sc[idx], rhs(p, zi, s0, sd0, sdd0)) < 1e-12, idx
        act_i = [float(c[idx]) for c in act]
        assert _rel_err(zdot_pl[idx], rhs_planar(p, zi, *act_i)) < 1e-12, idx
        assert abs(e_arr[idx] - float(energy(p, zi, s[idx], s_dot[idx]))) <= 1e-12 * e_arr[idx]
        assert abs(e_sc[idx] - float(energy(p, zi, s0, sd0))) <= 1e-12 * e_sc[idx]
        assert abs(e_pl[idx] - float(energy_planar(p, zi, *act_i[:4]))) <= 1e-12 * e_pl[idx]
        want = oracle.reduced_rhs_rail(p, zi, p.b, s[idx], s_dot[idx], s_ddot[idx])
        assert _rel_err(zdot_arr[idx], want) < RTOL, idx
        want_pl = oracle.reduced_rhs_planar(p, zi, *act_i)
        assert _rel_err(zdot_pl[idx], want_pl) < RTOL, idx


@pytest.mark.parametrize("n", NS)
def test_energy_matches_oracle(n: int) -> None:
    """energy / energy_planar equal the oracle's total kinetic energy."""
    for rng, i, p, z in _random_cases(8, n):
        s, s_dot, _ = _draw_rail(rng)
        got = energy(p, z, s, s_dot)
        want = oracle.energy_rail(p, z, p.b, s, s_dot)
        assert np.shape(got) == ()
        assert abs(float(got) - want) <= RTOL * want, (n, i, p, z, s, s_dot, got, want)
        act = _draw_planar(rng)
        got = energy_planar(p, z, *act[:4])
        want = oracle.energy_planar(p, z, *act[:4], pose=_pose(rng))
        assert np.shape(got) == ()
        assert abs(float(got) - want) <= RTOL * want, (n, i, p, z, act, got, want)


def _section10_power_planar(
    p: ConvoyParams, z: np.ndarray, zdot: np.ndarray, act: tuple[float, ...]
) -> float:
    """mu (a_x xi_dot + a_y eta_dot) with a_x, a_y of physics.md section 9."""
    xi, eta, xi_d, eta_d, xi_dd, eta_dd = act
    u, w = z[0], z[1]
    u_d, w_d = zdot[0], zdot[1]
    a_x = u_d - eta * w_d - 2 * w * eta_d + xi_dd - w**2 * xi
    a_y = xi * w_d + eta_dd + 2 * w * xi_d + w * u - w**2 * eta
    return float(p.mu * (a_x * xi_d + a_y * eta_d))


@pytest.mark.parametrize("n", NS)
def test_energy_balance_planar(n: int) -> None:
    """d/dt energy_planar along rhs_planar = mu (a_x xi_dot + a_y eta_dot) = oracle's power."""
    for rng, i, p, z in _random_cases(9, n):
        act = _draw_planar(rng)
        zdot = rhs_planar(p, z, *act)
        pos = np.array(act[:2])
        vel = np.array(act[2:4])
        acc = np.array(act[4:])
        rate = _fd_energy_rate(_planar_energy_of(p), [(z, zdot), (pos, vel), (vel, acc)])
        power = _section10_power_planar(p, z, zdot, act)
        power_oracle = oracle.actuator_power_planar(p, z, *act)
        e = float(energy_planar(p, z, *act[:4]))
        tol = 1e-8 * max(abs(power_oracle), e)
        assert abs(rate - power_oracle) < tol, (n, i, p, z, act, rate, power_oracle)
        assert abs(power - power_oracle) < tol, (n, i, p, z, act, power, power_oracle)


@pytest.mark.parametrize("n", NS)
def test_energy_balance_rail(n: int) -> None:
    """d/dt energy along rhs = F_rail s_dot.

    F_rail = mu (b omega_dot + s_ddot + omega u - omega^2 s), physics.md section 9.
    """
    for rng, i, p, z in _random_cases(10, n):
        s, s_dot, s_ddot = _draw_rail(rng)
        zdot = rhs(p, z, s, s_dot, s_ddot)
        rail = (np.array([s, s_dot]), np.array([s_dot, s_ddot]))
        rate = _fd_energy_rate(_rail_energy_of(p), [(z, zdot), rail])
        u, w = z[0], z[1]
        f_rail = p.mu * (p.b * zdot[1] + s_ddot + w * u - w**2 * s)
        power = float(f_rail * s_dot)
        power_oracle = oracle.actuator_power_planar(p, z, p.b, s, 0.0, s_dot, 0.0, s_ddot)
        e = float(energy(p, z, s, s_dot))
        tol = 1e-8 * max(abs(power_oracle), e)
        ctx = (n, i, p, z, (s, s_dot, s_ddot))
        assert abs(rate - power_oracle) < tol, (*ctx, rate, power_oracle)
        assert abs(power - power_oracle) < tol, (*ctx, power, power_oracle)


@pytest.mark.parametrize("n", NS)
def test_energy_conserved_when_mass_fixed_in_cart(n: int) -> None:
    """No relative velocity of the mass (any relative acceleration): dE/dt = 0."""
    for rng, i, p, z in _random_cases(11, n):
        s, _, s_ddot = _draw_rail(rng)
        zdot = rhs(p, z, s, 0.0, s_ddot)
        rail = (np.array([s, 0.0]), np.array([0.0, s_ddot]))
        rate = _fd_energy_rate(_rail_energy_of(p), [(z, zdot), rail])
        e = float(energy(p, z, s, 0.0))
        assert abs(rate) < 1e-8 * e, (n, i, p, z, s, s_ddot, rate)

        xi, eta, _, _, xi_dd, eta_dd = _draw_planar(rng)
        act = (xi, eta, 0.0, 0.0, xi_dd, eta_dd)
        zdot = rhs_planar(p, z, *act)
        rate = _fd_energy_rate(
            _planar_energy_of(p),
            [
                (z, zdot),
                (np.array([xi, eta]), np.zeros(2)),
                (np.zeros(2), np.array([xi_dd, eta_dd])),
            ],
        )
        e = float(energy_planar(p, z, xi, eta))
        assert abs(rate) < 1e-8 * e, (n, i, p, z, act, rate)
        assert abs(oracle.energy_rate_planar(p, z, *act)) < 1e-12 * e


@pytest.mark.parametrize("n", NS)
def test_mu_zero_ignores_rail_and_mass_motion(n: int) -> None:
    """With mu = 0 neither b nor (s, s_dot, s_ddot) nor (xi, eta, ...) change rhs or energy."""
    rng = np.random.default_rng([SEED, 12, n])
    for i in range(N_SAMPLES):
        p = _draw_params(rng, n, i, mu=0.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            p_other_b = p.replace(b=rng.uniform(-3.0, 3.0))
        z = _draw_state(rng, n)
        base = rhs(p, z)
        e_base = float(energy(p, z))
        want = oracle.reduced_rhs_rail(p, z, 0.0)
        assert _rel_err(base, want) < RTOL, (n, i, base, want)
        assert abs(e_base - oracle.energy_rail(p, z, 0.0)) <= RTOL * e_base
        s, s_dot, s_ddot = _draw_rail(rng)
        act = _draw_planar(rng)
        for got in (rhs(p_other_b, z, s, s_dot, s_ddot), rhs_planar(p, z, *act)):
            assert _rel_err(got, base) < 1e-13, (n, i, got, base)
        for e in (energy(p_other_b, z, s, s_dot), energy_planar(p, z, *act[:4])):
            assert abs(float(e) - e_base) <= 1e-13 * e_base, (n, i, e, e_base)
