"""``lqr-estimated``: the regulator designed for parameters estimated online from the motion.

Under randomised physics (``randomize="mismatch20"`` draws M, J0, a, l and mu per
episode) :class:`ParameterEstimator` identifies each row's parameters from what a policy
sees: its observations and its own past actions. :class:`EstimatingLQRPolicy` feeds the
estimate to the LQR of ``lqr-adaptive`` (the same design path,
:meth:`agents.policies.baselines.AdaptiveLQRPolicy.controller`), re-designed only when the
estimate has moved by more than ``redesign_tolerance``.

Method: a windowed Gauss-Newton (Levenberg-Marquardt) least-squares fit. Each row keeps
``window`` transitions ``(x_t, action_t) -> x_(t+1)``; every control step a Gauss-Newton
step fits the factors (parameter / nominal, one per randomised parameter) to them,
predicting each transition with the exact model (the differentiable twin's control step,
:func:`trailer_env.twin.physics_step`, float64) and its Jacobian by forward differences
of that step (all rows, transitions and perturbations in one batched call; finite
differences rather than autograd because one batched forward pass per parameter is
cheaper here than a backward pass per residual). Why this and not a filter: the model is
exact and the only noise is the observation's float32 rounding, so a short window of
transitions determines the parameters and least squares on them has no noise covariances
to tune; the window keeps the cost per step bounded. It holds the most informative
transitions seen (the largest Jacobian norms), not the latest, so when the motion stops
exciting a parameter (a convoy held straight) its estimate stays where the transients
put it instead of drifting on rounding noise. A step is kept only where it lowers the
window's sum of squared misses; a refused one is retried with more damping
(Levenberg-Marquardt). The fit's coordinates for M, J0 and a are M, M a and J0 + M a^2,
in which the mass matrix and the forces of the equations of motion are linear (with mu;
:meth:`ParameterEstimator.coordinates`): in the raw factors the valleys of the sum of
squares bend, and full Gauss-Newton steps overshoot them. Estimates start at the nominal
values; the fit's iterate is kept within the randomisation's bounds widened by their
width, what it reports and designs for within the bounds themselves.

Measured on Reverse-v1 under mismatch20 (n = 1..3): within about 1 % of every drawn
parameter after 4-8 steps, about 1e-4 after 20-50 steps, and it holds there.

What it reads. The regulator's state comes from the observation as ``lqr`` and
``lqr-adaptive`` read it (:meth:`trailer_env.controllers.LQRController.regulator_state`):
u, omega, the hitch angles from their sines and cosines, the mass's position and
velocity on the rail. The twin's step needs the mass state ``act`` too: its position
and velocity come from the observation (float32, scaled by ``s_max`` and
``rail_speed_max``); on the rail (servo and accel modes) the mass's forward coordinate is
fixed at ``b`` with no speed, and the accelerations the step applies are the actuator's
response to the action (recomputed by the twin), so nothing else is needed. A transition
whose observed mass speed sits at the observation's clip (+-1) is not used.

New episodes. The policy is not told when an environment resets; it sees it: the
mass's motion does not depend on the parameters, so its prediction matches the observed
one to the observation's rounding, and a row whose mass prediction misses by more than
``reset_tolerance`` (or whose convoy prediction misses by more than any parameter
mismatch could explain) starts afresh: window emptied, estimate back to nominal. A batch
of another size restarts every row.

Not restated by the twin, so not estimated: per-row auto substep counts (the nominal
rule's counts are used; an integrator-order difference) and the kernel's divergence
retry (a transition the twin predicts as non-finite is dropped).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import torch

from dynamics.columns import ETA, ETA_DOT, XI, XI_DOT
from trailer_env.core import ConvoyCore
from trailer_env.randomize import NAMES, PARAMETERS
from trailer_env.settings import EnvSettings
from trailer_env.twin import TwinParams, physics_step

#: The parameters the estimator may fit, those the presets randomise (``m`` and ``J``
#: change nothing measurable: trailer_env.randomize).
ESTIMABLE: tuple[str, ...] = ("M", "J0", "a", "l", "mu")

_M, _J0, _A = (PARAMETERS.index(name) for name in ("M", "J0", "a"))

#: ``values (7,) -> controller``: the regulator designed for a parameter vector (columns
#: :data:`trailer_env.randomize.PARAMETERS`), e.g. ``AdaptiveLQRPolicy(settings).controller``.
Design = Callable[[np.ndarray], Callable[[np.ndarray], np.ndarray]]


class Linearised(NamedTuple):
    """Transitions linearised in the factors (leading axis N, the transitions)."""

    #: Observed minus predicted convoy state (N, n+2), hitch angles wrapped; 0 where not finite.
    miss: np.ndarray
    #: d miss / d factor (P, N, n+2); 0 where not finite.
    jacobian: np.ndarray
    #: The predicted mass state (N, 6).
    act: np.ndarray
    #: Whether the prediction and its Jacobian are finite (N,).
    finite: np.ndarray


class ParameterEstimator:
    """Per-row online least-squares estimates of the randomised physical parameters.

    Call :meth:`observe` with each batch of observations and then :meth:`record` with
    the actions applied to it; :attr:`factors` (B, P) holds the current estimates as
    factors of the nominal values of :attr:`names`, :attr:`values` (B, 7) the full
    parameter vectors.

    Args:
        settings: The environment's settings (``env.unwrapped.settings``).
        core_class: The scene's core (``trailer_env.registry.core_class_of(env_id)``).
        window: Transitions per row the fit uses: the most informative seen this
            episode (the largest Jacobian norms when they came).
        damping: The floor of the Levenberg-Marquardt damping (relative to the normal
            matrix's diagonal): 0, a plain Gauss-Newton step while steps lower the misses.
        reset_tolerance: Largest miss (m, m/s) of the mass's predicted motion that still
            counts as the same episode.

    Raises:
        TypeError: For a window that is not an int.
        ValueError: For a window below 1, a negative damping or a non-positive tolerance.
    """

    #: Relative step of the forward differences (float64 model: ~1e-10 relative error).
    STEP = 1e-6
    #: Prior weight on staying put: a factor that the window's motion does not excite
    #: (normal-matrix entries below this) keeps its estimate.
    PRIOR = 1e-13
    #: Largest change of a factor in one Gauss-Newton step (the step is scaled down whole).
    MAX_STEP = 0.5
    #: Largest convoy miss (u, omega, hitch angles) one step of any parameter in the
    #: bounds could explain; above it the row has restarted.
    CONVOY_JUMP = 0.05
    #: A Gauss-Newton step below this (in every factor) leaves the row settled.
    SETTLED = 1e-7
    #: The damping a refused step is retried with first, and the most it grows to (then
    #: the row settles until its window changes).
    MIN_RETRY = 1e-3
    MAX_DAMPING = 1e4
    #: Transitions a row needs before it is fitted.
    MIN_TRANSITIONS = 3
    #: Tries per control step (the damping grows tenfold after each refused one).
    TRIES = 4

    def __init__(
        self,
        settings: EnvSettings,
        core_class: type[ConvoyCore],
        *,
        window: int = 40,
        damping: float = 0.0,
        reset_tolerance: float = 1e-4,
    ) -> None:
        if isinstance(window, bool) or not isinstance(window, int):
            raise TypeError(f"window must be an int, got {type(window).__name__} {window!r}")
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window!r}")
        if not damping >= 0.0:
            raise ValueError(f"damping must be >= 0, got {damping!r}")
        if not reset_tolerance > 0.0:
            raise ValueError(f"reset_tolerance must be > 0, got {reset_tolerance!r}")
        self.settings = settings
        self.window = window
        self.damping = float(damping)
        self.reset_tolerance = float(reset_tolerance)
        self.n = settings.n_trailers
        self.planar = settings.actuator.planar
        randomize = settings.randomize
        drawn = () if randomize is None else randomize.names
        #: The estimated parameters: those of :data:`ESTIMABLE` the settings randomise.
        self.names = tuple(name for name in ESTIMABLE if name in drawn)
        self.columns = np.array([PARAMETERS.index(name) for name in self.names], dtype=np.int64)
        low, high = randomize.bounds() if randomize is not None else (np.ones(len(NAMES)),) * 2
        self.low, self.high = low[self.columns], high[self.columns]
        # The fit's box: the bounds widened by their width on each side (a Gauss-Newton
        # step clipped at the bounds themselves leaves the valley it follows).
        width = self.high - self.low
        self.inner_low = np.maximum(self.low - width, 0.5 * self.low)
        self.inner_high = self.high + width
        self.nominal = np.array([getattr(settings.params, name) for name in PARAMETERS])
        # The columns of M, J0 and a when all three are estimated (see coordinates()), and
        # the nominal J0 + M a^2 and M a^2.
        self._mass: tuple[int, int, int] | None = None
        if {"M", "J0", "a"} <= set(self.names):
            self._mass = (self.names.index("M"), self.names.index("J0"), self.names.index("a"))
        arm = self.nominal[_M] * self.nominal[_A] ** 2
        self._mass_nominal = (self.nominal[_J0] + arm, arm)
        physics = dataclasses.replace(settings, randomize=None)
        self.twin = TwinParams.from_settings(physics, core_class).replace(with_pose=False)
        self.batch = 0
        self._restart_all(0)

    # --- state ---------------------------------------------------------------------------

    def _restart_all(self, batch: int) -> None:
        width, count = self.n + 2, len(self.names)
        self.batch = batch
        self.iterate = np.ones((batch, count))
        self.z0 = np.zeros((batch, self.window, width))
        self.act0 = np.zeros((batch, self.window, 6))
        self.actions = np.zeros((batch, self.window, self.settings.action_dim))
        self.z1 = np.zeros((batch, self.window, width))
        self.valid = np.zeros((batch, self.window), dtype=bool)
        self.score = np.zeros((batch, self.window))
        # Rows whose last fit left nothing to do (a negligible or refused step) and whose
        # window has not changed since: fitting them again would repeat it, so it is skipped.
        self.settled = np.zeros(batch, dtype=bool)
        #: Each row's Levenberg-Marquardt damping (relative to the normal matrix's diagonal).
        self.lam = np.full(batch, self.damping)
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._last_action: np.ndarray | None = None
        #: Rows restarted by the latest :meth:`observe` (a new episode seen).
        self.restarted = np.ones(batch, dtype=bool)

    def _restart(self, rows: np.ndarray) -> None:
        self.iterate[rows] = 1.0
        self.valid[rows] = False
        self.settled[rows] = False
        self.lam[rows] = self.damping

    def coordinates(self, factors: np.ndarray) -> np.ndarray:
        """The fit's coordinates of factors (N, P): the factors themselves, except that
        with M, J0 and a all estimated, those three are replaced by the factors of the
        quantities the mass matrix and forces of the equations of motion are linear in:
        M, M a and the inertia I0 = J0 + M a^2 (in the columns of M, a and J0; see
        :func:`trailer_env.twin.field`). The misses are much
        closer to linear in these (a product M a^2 bends the valleys of the sum of
        squares that a Gauss-Newton step follows)."""
        if self._mass is None:
            return factors
        m, j, a = self._mass
        inertia, arm = self._mass_nominal
        out = factors.copy()
        out[:, a] = factors[:, m] * factors[:, a]
        out[:, j] = (
            self.nominal[_J0] * factors[:, j] + arm * factors[:, m] * factors[:, a] ** 2
        ) / inertia
        return out

    def from_coordinates(self, coordinates: np.ndarray) -> np.ndarray:
        """The factors (N, P) of the fit's coordinates (the inverse of :meth:`coordinates`)."""
        if self._mass is None:
            return coordinates
        m, j, a = self._mass
        inertia, arm = self._mass_nominal
        out = coordinates.copy()
        out[:, a] = coordinates[:, a] / coordinates[:, m]
        out[:, j] = (
            inertia * coordinates[:, j] - arm * coordinates[:, m] * out[:, a] ** 2
        ) / self.nominal[_J0]
        return out

    @property
    def factors(self) -> np.ndarray:
        """The current estimates (B, P), factors of the nominal values of :attr:`names`,
        within the randomisation's bounds (the fit's iterate may stray past them, within
        twice their width, while it converges)."""
        return np.clip(self.iterate, self.low, self.high)

    @property
    def values(self) -> np.ndarray:
        """The current estimates as parameter vectors (B, 7), columns ``PARAMETERS``."""
        values = np.tile(self.nominal, (self.batch, 1))
        values[:, self.columns] *= self.iterate
        return values

    def states(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The convoy state ``(u, omega, alpha)`` (B, n+2), the mass state (B, 6) and
        whether the observed mass speed is at its clip (B,), from observations."""
        n, settings = self.n, self.settings
        batch = np.asarray(obs, dtype=np.float64)
        alpha = np.arctan2(batch[:, 2 : 2 + n], batch[:, 2 + n : 2 + 2 * n])
        z = np.column_stack([batch[:, :2], alpha])
        s_max, speed = settings.params.s_max, settings.rail_speed_max
        act = np.zeros((batch.shape[0], 6))
        base = 2 + 2 * n
        if self.planar:
            act[:, XI] = batch[:, base] * s_max + settings.params.b
            act[:, ETA] = batch[:, base + 1] * s_max
            act[:, XI_DOT] = batch[:, base + 2] * speed
            act[:, ETA_DOT] = batch[:, base + 3] * speed
            speeds = batch[:, base + 2 : base + 4]
        else:
            act[:, XI] = settings.params.b
            act[:, ETA] = batch[:, base] * s_max
            act[:, ETA_DOT] = batch[:, base + 1] * speed
            speeds = batch[:, base + 1 : base + 2]
        return z, act, np.any(np.abs(speeds) >= 1.0 - 1e-6, axis=1)

    # --- the model -----------------------------------------------------------------------

    def predict(
        self, z: np.ndarray, act: np.ndarray, action: np.ndarray, factors: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One control step of the exact model per row: (next convoy state (N, n+2), next
        mass state (N, 6)) for factors (N, P) of the estimated parameters."""
        params = self.twin
        if self.names:
            changes = {
                name: torch.from_numpy(self.nominal[column] * factors[:, k])
                for k, (name, column) in enumerate(zip(self.names, self.columns, strict=True))
            }
            params = params.replace(**changes)
        with torch.no_grad():
            result = physics_step(
                torch.from_numpy(z), torch.from_numpy(act), torch.from_numpy(action), params
            )
        return result.z.numpy(), result.act.numpy()

    def _miss(self, predicted: np.ndarray, observed: np.ndarray) -> np.ndarray:
        """Observed minus predicted convoy state, hitch angles wrapped (N, n+2)."""
        miss = observed - predicted
        miss[:, 2:] = np.arctan2(np.sin(miss[:, 2:]), np.cos(miss[:, 2:]))
        return miss

    # --- the interface -------------------------------------------------------------------

    def observe(self, obs: np.ndarray) -> np.ndarray:
        """Take the batch's new observations (B, obs_dim): the transition from the last
        ones under the recorded actions joins each row's window (or restarts the row),
        then one Gauss-Newton step per row. Returns :attr:`factors` (B, P)."""
        batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
        if batch.shape[0] != self.batch:
            self._restart_all(batch.shape[0])
        z, act, clipped = self.states(batch)
        self.restarted = np.zeros(self.batch, dtype=bool)
        if self._last is None or self._last_action is None:
            self.restarted[:] = True
        else:
            z_prev, act_prev = self._last
            action = self._last_action
            linear = self._linearised(z_prev, act_prev, action, z, self.iterate)
            act_pred = linear.act
            mass = [ETA, ETA_DOT, XI, XI_DOT] if self.planar else [ETA, ETA_DOT]
            mass_miss = np.max(np.abs(act_pred[:, mass] - act[:, mass]), axis=1)
            convoy_miss = np.max(np.abs(linear.miss), axis=1, initial=0.0)
            new = ~(mass_miss <= self.reset_tolerance) | ~(convoy_miss <= self.CONVOY_JUMP)
            clean = ~new & ~clipped & linear.finite
            self.restarted = new
            self._restart(np.flatnonzero(new))
            score = np.einsum("pnc,pnc->n", linear.jacobian, linear.jacobian)
            self._keep(np.flatnonzero(clean), score, z_prev, act_prev, action, z)
            self._fit()
        self._last = (z, act)
        self._last_action = None
        return self.factors

    def _keep(
        self,
        rows: np.ndarray,
        score: np.ndarray,
        z_prev: np.ndarray,
        act_prev: np.ndarray,
        action: np.ndarray,
        z: np.ndarray,
    ) -> None:
        """The new transitions of ``rows`` join their windows: into a free slot, or in
        place of the least informative one kept if the new one is more informative
        (``score``, (B,): the squared norm of its Jacobian with respect to the factors at
        the estimate when it came)."""
        if rows.size == 0:
            return
        score = score[rows]
        held = np.where(self.valid[rows], self.score[rows], -np.inf)
        slots = np.argmin(held, axis=1)
        better = score > held[np.arange(rows.size), slots]
        rows, slots = rows[better], slots[better]
        self.z0[rows, slots] = z_prev[rows]
        self.act0[rows, slots] = act_prev[rows]
        self.actions[rows, slots] = action[rows]
        self.z1[rows, slots] = z[rows]
        self.score[rows, slots] = score[better]
        self.valid[rows, slots] = True
        self.settled[rows] = False

    def record(self, actions: np.ndarray) -> None:
        """The actions (B, action_dim) applied to the latest observations."""
        self._last_action = np.asarray(actions, dtype=np.float64).reshape(self.batch, -1)

    def _linearised(
        self,
        z: np.ndarray,
        act: np.ndarray,
        action: np.ndarray,
        observed: np.ndarray,
        factors: np.ndarray,
    ) -> Linearised:
        """The transitions' misses at ``factors`` (N, P) and their Jacobian with respect
        to the fit's coordinates (:meth:`coordinates`), by forward differences, all in one
        batched step."""
        count, rows = len(self.names), z.shape[0]
        coordinates = self.coordinates(factors)
        perturbed = np.repeat(coordinates[None], count + 1, axis=0)
        step = self.STEP * np.maximum(np.abs(coordinates), 1.0)
        for k in range(count):
            perturbed[k + 1, :, k] += step[:, k]
        tile = count + 1
        z_pred, act_pred = self.predict(
            np.tile(z, (tile, 1)),
            np.tile(act, (tile, 1)),
            np.tile(action, (tile, 1)),
            self.from_coordinates(perturbed.reshape(tile * rows, count)),
        )
        z_pred = z_pred.reshape(tile, rows, -1)
        miss = self._miss(z_pred[0], observed)
        # d(observed - predicted) / d factor
        jacobian = -(z_pred[1:] - z_pred[0]) / step.T[:, :, None]
        finite = np.all(np.isfinite(miss), axis=1) & np.all(np.isfinite(jacobian), axis=(0, 2))
        miss[~finite] = 0.0
        jacobian[:, ~finite] = 0.0
        return Linearised(miss, jacobian, act_pred[:rows], finite)

    def _row_cost(self, rows: np.ndarray, slots: np.ndarray, factors: np.ndarray) -> np.ndarray:
        """Sum of squared misses of each row's window (B,) at per-entry factors (N, P)."""
        z_pred, _ = self.predict(
            self.z0[rows, slots], self.act0[rows, slots], self.actions[rows, slots], factors
        )
        miss = self._miss(z_pred, self.z1[rows, slots])
        squares = np.where(np.isfinite(miss), miss * miss, np.inf).sum(axis=1)
        cost = np.zeros(self.batch)
        np.add.at(cost, rows, squares)
        return cost

    def _fit(self) -> None:
        """A Gauss-Newton step of every row with enough transitions, kept only where it
        lowers the row's sum of squared misses; a refused step is retried at once with ten
        times the damping (up to :attr:`TRIES` times)."""
        count = len(self.names)
        if count == 0:
            return
        ready = (self.valid.sum(axis=1) >= self.MIN_TRANSITIONS) & ~self.settled
        rows, slots = np.nonzero(self.valid & ready[:, None])
        if rows.size == 0:
            return
        miss, jacobian, _, _ = self._linearised(
            self.z0[rows, slots],
            self.act0[rows, slots],
            self.actions[rows, slots],
            self.z1[rows, slots],
            self.iterate[rows],
        )
        normal = np.zeros((self.batch, count, count))
        gradient = np.zeros((self.batch, count))
        before = np.zeros(self.batch)
        np.add.at(normal, rows, np.einsum("inc,jnc->nij", jacobian, jacobian))
        np.add.at(gradient, rows, np.einsum("inc,nc->ni", jacobian, miss))
        np.add.at(before, rows, (miss * miss).sum(axis=1))
        fitted = np.flatnonzero(ready)
        coordinates = self.coordinates(self.iterate[fitted])
        lam = self.lam[fitted]
        accepted = np.zeros(fitted.size, dtype=bool)
        moved = np.zeros(fitted.size, dtype=bool)
        pending = np.arange(fitted.size)
        for _ in range(self.TRIES):
            batch_rows = fitted[pending]
            diagonal = np.einsum("bii->bi", normal[batch_rows])
            damping = lam[pending, None] * diagonal + self.PRIOR
            lhs = normal[batch_rows] + damping[:, :, None] * np.eye(count)
            # miss(c + d) ~ miss + J d: the least-squares d solves (J^T J) d = -J^T miss.
            delta = -np.linalg.solve(lhs, gradient[batch_rows][:, :, None])[:, :, 0]
            # Shortened as a whole, not clipped per factor: the parameters are strongly
            # correlated (the valleys are narrow) and a clipped component leaves them.
            largest = np.max(np.abs(delta), axis=1, keepdims=True)
            delta = delta * np.minimum(1.0, self.MAX_STEP / np.maximum(largest, 1e-300))
            # A step past a zero mass coordinate gives non-finite factors; its prediction
            # is then not finite, its cost infinite, and the step is refused below.
            with np.errstate(divide="ignore", invalid="ignore"):
                factors = self.from_coordinates(coordinates[pending] + delta)
            candidate = np.clip(factors, self.inner_low, self.inner_high)
            trial = np.zeros((self.batch, count))
            trial[batch_rows] = candidate
            entries = np.isin(rows, batch_rows)
            after = self._row_cost(rows[entries], slots[entries], trial[rows[entries]])
            ok = after[batch_rows] <= before[batch_rows]
            good = pending[ok]
            self.iterate[fitted[good]] = candidate[ok]
            accepted[good] = True
            moved[good] = np.max(np.abs(delta[ok]), axis=1) > self.SETTLED
            lam[good] = lam[good] / 10.0
            lam[pending[~ok]] = np.minimum(
                np.maximum(10.0 * lam[pending[~ok]], self.MIN_RETRY), self.MAX_DAMPING
            )
            pending = pending[~ok]
            if pending.size == 0:
                break
        self.lam[fitted] = np.where(lam < self.MIN_RETRY, self.damping, lam)
        given_up = ~accepted & (lam >= self.MAX_DAMPING)
        self.settled[fitted] = (accepted & ~moved) | given_up


class EstimatingLQRPolicy:
    """The LQR designed for each row's online parameter estimate (``lqr-estimated``).

    A batched policy (observations (B, obs_dim) -> actions (B, action_dim)) with state:
    it remembers its last observations and actions to estimate from the next ones
    (:class:`ParameterEstimator`). A row's regulator is re-designed (through ``design``,
    cached per parameter vector) only when its estimate has moved by more than
    ``redesign_tolerance`` in some factor since the design it uses; the design's factors
    are rounded to 1e-3 so that nearby estimates share one.

    Args:
        settings: The environment's settings.
        core_class: The scene's core.
        design: ``values (7,) -> controller`` (``AdaptiveLQRPolicy(settings).controller``).
        redesign_tolerance: Largest change of a factor that keeps the current design.
        **estimator: Keywords of :class:`ParameterEstimator`.
    """

    def __init__(
        self,
        settings: EnvSettings,
        core_class: type[ConvoyCore],
        design: Design,
        *,
        redesign_tolerance: float = 0.02,
        **estimator: float | int,
    ) -> None:
        if not redesign_tolerance >= 0.0:
            raise ValueError(f"redesign_tolerance must be >= 0, got {redesign_tolerance!r}")
        self.settings = settings
        self.estimator = ParameterEstimator(settings, core_class, **estimator)  # type: ignore[arg-type]
        self.design = design
        self.redesign_tolerance = float(redesign_tolerance)
        self.designed = np.ones((0, len(self.estimator.names)))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        batch = np.atleast_2d(np.asarray(obs))
        estimator = self.estimator
        factors = estimator.observe(batch)
        if self.designed.shape[0] != batch.shape[0]:
            self.designed = np.ones_like(factors)
        moved = estimator.restarted | np.any(
            np.abs(factors - self.designed) > self.redesign_tolerance, axis=1
        )
        self.designed[moved] = np.round(factors[moved], 3)
        values = np.tile(estimator.nominal, (batch.shape[0], 1))
        values[:, estimator.columns] *= self.designed
        actions = np.empty((batch.shape[0], self.settings.action_dim), dtype=np.float32)
        distinct, inverse = np.unique(values, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        for k, vector in enumerate(distinct):  # one call per distinct design, not per row
            rows = np.flatnonzero(inverse == k)
            actions[rows] = np.atleast_2d(self.design(vector)(batch[rows]))
        estimator.record(actions)
        return actions
