"""The auto substep rule: per environment and control step, the fewest RK4 substeps
that keep the step stable and its estimated error below the fidelity's ``tolerance``.

It runs inside the jitted step (:func:`auto_substeps_row`), from settings packed once
per batch (:func:`auto_settings`). How its constants were calibrated, and what it
costs, is in benchmarks/README.md ("Auto fidelity").

What ``tolerance`` means. The error of one control step is the difference between
the step taken and the exact flow over ``dt`` from the same state under the same
held mass acceleration, measured as

    e = max(|du| / v, l |d omega| / v, max_k |d alpha_k|),
    v = max(|u|, l |omega|, v_mass),  v_mass = |xi_dot| + |eta_dot| + dt (|xi_ddot| + |eta_ddot|):

velocities relative to the step's speed scale (the convoy's or, when it is nearly at
rest, the mass's on the cart), hitch angles in radians. The auto rule keeps an
upper estimate of e below ``tolerance`` (default 1e-4); the pose (x, y, theta), when
integrated, follows from these.

The auto rule. With ``n`` trailers, at the start of a step (rates in 1/s):

* ``r = max(|u| c_speed, |omega|)``, ``c_speed = max(1 / l, c_cart)``:
  the trailers' eigenvalue ``|u| / l`` and the cart's ``c_cart |u|`` at a straight
  convoy, ``c_cart = |M a + mu xi| / (I0 + mu xi^2)`` with the mass at ``xi = b``
  (its largest value over the mass's square in planar mode; a lateral offset only
  lowers it), see benchmarks/README.md, "Stability";
* ``R = max(g(n) r, r_mass)``: ``g(n) = 0.55 + 0.15 n`` (:data:`CHAIN_GROWTH`)
  because RK4's error constant grows with the length of the chain, fastest for
  reversing or bent chains, and
  ``r_mass = 0.1 (|xi_dot| + |eta_dot|) / s_max + 0.4 sqrt((|xi_ddot| + |eta_ddot|) / s_max)``
  (:data:`MASS_WEIGHTS`), the time scale of the mass's motion on its rail;
* accuracy: RK4's error over one control step of k substeps is estimated as
  ``C k (dt R / k)^5`` with ``C = 8`` (:data:`ERROR_CONSTANT`), so
  ``k_acc = ceil((C (dt R)^5 / tolerance)^(1/4))``, capped at ``max_substeps``;
* stability: ``k_stab = ceil(dt r / x_safe(n))`` with ``x_safe(n)`` =
  :data:`STABILITY_FRACTION` (0.4) times RK4's usable stability limit of the
  dimensionless step for n trailers (:data:`RK4_STABILITY_LIMITS`: 2.785 for n <= 1,
  2.10 for n = 8, 1.59 for n = 32, measured on the linearised straight convoy whose
  trailers form a Jordan block, with benchmarks/stability.py's criterion). The
  fraction is small because a state can change completely within one control step
  (a convoy reversing at ``dt |u| / l = 10`` folds within it);
* ``k = max(min(k_acc, max_substeps), k_stab, 1)``: stability always wins over
  ``max_substeps`` (up to :data:`HARD_MAX_SUBSTEPS`, speeds no scene reaches).

When a cap binds (``k_acc > max_substeps`` and stability does not ask for as many, or
anything above :data:`HARD_MAX_SUBSTEPS`), the step's estimated error exceeds the
tolerance. Such a step is never silent: the environments flag its rows
(``core.accuracy_exceeded``) and issue an :class:`AccuracyWarning` once per batch
(:mod:`trailer_env.core`). Raise ``max_substeps`` to hold the tolerance there, or use
``"dopri5"``.

Work budget. One control step of a batch costs substeps x (n + 1) body-substeps per
environment; their sum over the batch is capped at :data:`MAX_STEP_WORK` (2e8; what
that costs: benchmarks/README.md, "Figures quoted from the code"). A step whose chosen
substeps would exceed it (e.g. n = 256 at |u| = 1e8 m/s: 1e6 substeps, 2.6e8
body-substeps) raises FloatingPointError naming the speed and the budget before
anything is integrated, instead of running for minutes.
"""

from __future__ import annotations

import math

import numpy as np

from dynamics import ConvoyParams
from dynamics._kernel import row_params
from dynamics.columns import ETA_DDOT, ETA_DOT, OMEGA, XI_DDOT, XI_DOT, U
from dynamics.jit import cached_njit

#: RK4's usable stability limit of ``dt r`` by number of trailers (linear interpolation
#: between entries, the last value beyond): the smaller of the default convoy's and a
#: trailer-dominated one's (a = 0.1, mu = 0), linearised at the straight convoy (a
#: perturbation must decay 1e4-fold without growing 100-fold, benchmarks/stability.py).
RK4_STABILITY_LIMITS: tuple[tuple[int, float], ...] = (
    (0, 2.785), (1, 2.785), (2, 2.734), (3, 2.586), (4, 2.458), (5, 2.347), (6, 2.251),
    (8, 2.098), (10, 1.973), (12, 1.880), (16, 1.761), (20, 1.705), (24, 1.692),
    (32, 1.594), (48, 1.538), (64, 1.497), (96, 1.463), (128, 1.446),
)  # fmt: skip
#: Fraction of the stability limit the auto rule may use: non-straight states have
#: eigenvalues up to ~2.4 times the straight convoy's rate ``r``.
STABILITY_FRACTION = 0.4
#: RK4's error constant C of the auto rule (see the module docstring).
ERROR_CONSTANT = 8.0
#: g(n) = CHAIN_GROWTH[0] + CHAIN_GROWTH[1] n.
CHAIN_GROWTH = (0.55, 0.15)
#: Weights of the mass's speed / s_max and sqrt(acceleration / s_max) in r_mass.
MASS_WEIGHTS = (0.1, 0.4)
#: Upper bound on the tolerance: the error model's calibrated range.
MAX_TOLERANCE = 1e-3
#: Lower bound on the tolerance (float64 rounding).
MIN_TOLERANCE = 1e-13
#: Substeps the stability bound may ask for, at most (dt |u| / l ~ 1e6).
HARD_MAX_SUBSTEPS = 1_000_000
#: A step whose substeps a cap kept below what the error estimate asks for, and whose
#: speed scale ``max(|u|, l |omega|)`` grew more than this factor over its start's (plus
#: the mass's speed scale), has diverged (u = 1.3 -> 5.9e6 m/s in one step was seen).
GROWTH_LIMIT = 1e3
#: The work budget of one control step of a batch, in body-substeps: substeps x (n + 1)
#: bodies, summed over the batch's environments. It bounds the time of one step (the
#: measured rate and bound: benchmarks/README.md, "Figures quoted from the code").
#: Fixed substeps beyond it are refused when the
#: environment is built; with "auto", a step whose chosen substeps exceed it raises
#: FloatingPointError before anything is integrated (trailer_env.core).
MAX_STEP_WORK = 200_000_000

# Indices into the packed settings of auto_substeps.
(
    AUTO_SPEED_RATE,
    AUTO_CHAIN,
    AUTO_MASS_SPEED,
    AUTO_MASS_ACCEL,
    AUTO_DT,
    AUTO_X_ONE,
    AUTO_SCALE,
    AUTO_INV_X_SAFE,
    AUTO_MAX_SUBSTEPS,
    AUTO_WORK_SUBSTEPS,
    AUTO_LENGTH,
    AUTO_SPEED_FLOOR,
) = range(12)


class AccuracyWarning(UserWarning):
    """A step's estimated error exceeded the fidelity's tolerance (a substep cap bound)."""


def stability_limit(n_trailers: int) -> float:
    """RK4's usable stability limit of ``dt r`` with ``n_trailers`` (interpolated table)."""
    counts, limits = zip(*RK4_STABILITY_LIMITS, strict=True)
    return float(np.interp(n_trailers, counts, limits))


def chain_growth(n_trailers: int) -> float:
    """g(n), the factor on the convoy's rate in the error estimate."""
    return CHAIN_GROWTH[0] + CHAIN_GROWTH[1] * n_trailers


def cart_rate_coefficient(params: ConvoyParams, planar: bool) -> float:
    """Largest ``|M a + mu xi| / (I0 + mu xi^2)`` over the mass's positions ``xi``.

    The cart's eigenvalue at a straight convoy is this times ``|u|`` (the mass rides
    as part of the cart); rail modes hold ``xi = b``, planar mode lets ``xi`` range
    over ``b +- s_max`` (the extremes or the interior stationary points). Randomised
    environments compute it per row in compiled code (:func:`cart_rate`).
    """
    moment, inertia, mu = params.M * params.a, params.I0, params.mu

    def coefficient(xi: float) -> float:
        return abs(moment + mu * xi) / (inertia + mu * xi * xi)

    if not planar:
        return coefficient(params.b)
    low, high = params.b - params.s_max, params.b + params.s_max
    candidates = [low, high]
    if mu > 0.0:
        root = math.sqrt(moment * moment + mu * inertia)
        candidates += [x for x in ((-moment + root) / mu, (-moment - root) / mu) if low < x < high]
    return max(coefficient(xi) for xi in candidates)


@cached_njit(nogil=True)
def _rate_at(moment: float, inertia: float, mu: float, xi: float) -> float:
    return abs(moment + mu * xi) / (inertia + mu * xi * xi)


@cached_njit(nogil=True)
def cart_rate(
    M: float, J0: float, a: float, mu: float, b: float, s_max: float, planar: bool
) -> float:
    """:func:`cart_rate_coefficient` of the parameters given one by one (compiled code).

    The same formula; ``I0 = J0 + M a a`` may differ from Python's ``J0 + M a**2`` in
    the last bit (Python's ``**`` calls libm's pow), which moves the auto rule's rate
    estimate by 1e-16 relative: a substep count changes only if a state sits exactly on
    a threshold of the rule.
    """
    moment = M * a
    inertia = J0 + M * (a * a)
    if not planar:
        return _rate_at(moment, inertia, mu, b)
    low = b - s_max
    high = b + s_max
    best = max(_rate_at(moment, inertia, mu, low), _rate_at(moment, inertia, mu, high))
    if mu > 0.0:
        root = math.sqrt(moment * moment + mu * inertia)
        for x in ((-moment + root) / mu, (-moment - root) / mu):
            if low < x < high:
                best = max(best, _rate_at(moment, inertia, mu, x))
    return best


def auto_settings(
    params: ConvoyParams,
    dt: float,
    planar: bool,
    tolerance: float,
    max_substeps: int,
    speed_floor: float = 0.0,
) -> np.ndarray:
    """The packed float64 settings :func:`auto_substeps_row` reads (module docstring);
    ``speed_floor`` is the mass's speed scale of :func:`grew_absurdly_row`."""
    n = params.n_trailers
    speed_rate = max(1.0 / params.l, cart_rate_coefficient(params, planar))
    x_safe = STABILITY_FRACTION * stability_limit(n)
    settings = np.empty(12)
    settings[AUTO_SPEED_RATE] = speed_rate
    settings[AUTO_CHAIN] = chain_growth(n)
    settings[AUTO_MASS_SPEED] = MASS_WEIGHTS[0] / params.s_max
    settings[AUTO_MASS_ACCEL] = MASS_WEIGHTS[1] / math.sqrt(params.s_max)
    settings[AUTO_DT] = dt
    # One substep is accurate enough while C (dt R)^5 <= tolerance.
    settings[AUTO_X_ONE] = (tolerance / ERROR_CONSTANT) ** 0.2
    # k_acc = ceil(scale (dt R)^(5/4)).
    settings[AUTO_SCALE] = (ERROR_CONSTANT / tolerance) ** 0.25
    settings[AUTO_INV_X_SAFE] = 1.0 / x_safe
    settings[AUTO_MAX_SUBSTEPS] = max_substeps
    # The batch's substeps may add up to MAX_STEP_WORK / (n + 1) (the work budget).
    settings[AUTO_WORK_SUBSTEPS] = MAX_STEP_WORK / (n + 1)
    settings[AUTO_LENGTH] = params.l
    settings[AUTO_SPEED_FLOOR] = speed_floor
    return settings


@cached_njit(nogil=True)
def auto_substeps_row(z: np.ndarray, act: np.ndarray, settings: np.ndarray, i: int) -> tuple:
    """The auto rule of the module docstring for row ``i``: (substeps, within tolerance).

    The second value is False when a cap (``max_substeps`` on the accuracy rule, or
    :data:`HARD_MAX_SUBSTEPS` on everything) keeps the count below what the error
    estimate asks for: the step's estimated error then exceeds the tolerance.
    """
    speed_rate = settings[AUTO_SPEED_RATE]
    dt = settings[AUTO_DT]
    x_plain = dt * max(abs(z[i, U]) * speed_rate, abs(z[i, OMEGA]))
    mass = settings[AUTO_MASS_SPEED] * (abs(act[i, XI_DOT]) + abs(act[i, ETA_DOT])) + settings[
        AUTO_MASS_ACCEL
    ] * math.sqrt(abs(act[i, XI_DDOT]) + abs(act[i, ETA_DDOT]))
    x = max(settings[AUTO_CHAIN] * x_plain, dt * mass)
    inv_x_safe = settings[AUTO_INV_X_SAFE]
    if x <= settings[AUTO_X_ONE] and x_plain * inv_x_safe <= 1.0:
        return 1, True  # the common case: no powers needed
    if not math.isfinite(x):
        return 1, True  # the environment reports the non-finite state
    wanted = np.ceil(settings[AUTO_SCALE] * x**1.25)
    accurate = min(wanted, settings[AUTO_MAX_SUBSTEPS])
    stable = np.ceil(x_plain * inv_x_safe)
    chosen = min(max(accurate, stable, 1.0), HARD_MAX_SUBSTEPS)
    return int(chosen), chosen >= wanted


@cached_njit(nogil=True)
def grew_absurdly_row(z: np.ndarray, start: np.ndarray, settings: np.ndarray, i: int) -> bool:
    """Whether row ``i``'s speed scale grew more than :data:`GROWTH_LIMIT`-fold from
    ``start[i]`` (the step's start) to ``z[i]``, over the mass's speed scale."""
    length = settings[AUTO_LENGTH]
    before = max(abs(start[i, U]), length * abs(start[i, OMEGA])) + settings[AUTO_SPEED_FLOOR]
    after = max(abs(z[i, U]), length * abs(z[i, OMEGA]))
    return after > GROWTH_LIMIT * before


@cached_njit()
def auto_substeps(z: np.ndarray, act: np.ndarray, settings: np.ndarray, out: np.ndarray) -> None:
    """The auto rule of the module docstring for every row: substep counts into ``out``.

    ``act`` must hold the accelerations of the step about to be taken; ``settings``
    comes from :func:`auto_settings` (shared, (12,)) or holds one row of them per row
    ((B, 12): per-row parameters, as the kernel's draws set them).
    """
    for i in range(z.shape[0]):
        out[i], _ = auto_substeps_row(z, act, row_params(settings, i), i)
