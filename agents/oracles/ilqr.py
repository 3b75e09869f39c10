"""The ``ilqr`` baseline: a deterministic receding-horizon trajectory optimiser (an oracle).

Every control step, for every environment of the batch, :class:`ILQRPlanner` runs a fixed
number of iterations of control-limited iLQR (box-constrained DDP with a Gauss-Newton
cost Hessian, :func:`agents.oracles.ilqr_kernels.backward_pass`) over ``horizon`` steps
and applies the first action of the result. It draws no random numbers and stops after
a fixed count, so the same state (and warm start) gives the same action, bit for bit.

The model is the scene's own batched core (:class:`trailer_env.core.ConvoyCore`), never a
second copy of the equations:

* rollouts (the warm starts and the line search) step a core with the environment's own
  settings, so a plan's cost is what the environment would do: its integrator, servo,
  rail guard, fold test and the scene's termination (a fold, a stop, a missed dock);
* the Jacobians come from finite differences of one ``core.step`` per iteration on a
  second core holding, for every step of the horizon, the perturbed copies of the
  nominal state and control: forward differences by default (``d + 2`` copies: the
  nominal, ``x + h e_j``, ``v + h``; ``d`` = the core's ``z`` row plus the mass's ``s``
  and ``s_dot``), central ones with ``central=True`` (``2 (d + 1)``; on validation
  seeds 50040-50079 of Reverse-v1, n = 2, forward kept 40 starts safe to central's
  39, in 0.78 of the time); their ``refresh()`` also differentiates the cost's residuals
  (:mod:`agents.oracles.ilqr_costs`), which read the scene's task arrays. That core
  integrates with fixed RK4 substeps set per row to the count the nominal step used, so
  the auto rule switching counts between two copies never shows up as a derivative;
* or, with ``jacobians="exact"``, the step's Jacobians come from the differentiable
  twin by autograd (:mod:`agents.oracles.ilqr_tangent`, the same substep counts), exact
  where the differences read a kink's jump over their step; the residuals keep their
  differences (``agents.certify``'s default; benchmarks/results/ilqr_jacobians.md).

The control. The planner's variable is the rail acceleration as a fraction ``v`` of
``rail_accel_max``, boxed in [-1, 1] (the acceleration bound); the action sent is the
actuator's own inverse (``settings.actuator.command_for_accel``, what the LQR sends)
clipped to [-1, 1], so no action ever leaves the box. The stroke and the speed limits
are the core's guard: a plan that runs into them pays for it in its rollout. Planning
the servo's target directly failed: the servo saturates at 8 % of the action's range
(``rail_accel_max / (4 w^2 s_max)``), where the action's derivative is zero.

Warm start (each control step): the LQR's closed-loop rollout and (``reuse``) the
previous step's solution shifted by one step with its feedback gains; the cheaper one is
the first nominal. Each iteration's line search tries every step size of ``alphas`` in
one batched rollout and keeps the cheapest if it lowers the cost; otherwise the row's
regularisation grows tenfold. Without ``reuse`` the action is a function of the state
alone (what imitation labels need); with it, of the state and the previous call.

It reads the exact state (or an observation, in float32, through
:class:`agents.oracles.ilqr_policy.ILQRPolicy`). Cost per decision and environment:
``(iterations + 1) * L * horizon`` rollout steps plus ``iterations * (horizon + 1)``
times the copies per step (:attr:`ILQRPlanner.steps_per_decision`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from agents.oracles.ilqr_costs import CostWeights, SceneCost, scene_horizon
from agents.oracles.ilqr_kernels import backward_pass, feedback
from agents.oracles.rail import require_rail
from dynamics.columns import ACT_WIDTH, ALPHA, ETA, ETA_DOT, OMEGA, U
from trailer_env.controllers import LQRController
from trailer_env.core import ConvoyCore
from trailer_env.fidelity import Fidelity
from trailer_env.settings import EnvSettings

if TYPE_CHECKING:
    from agents.oracles.ilqr_tangent import StepTangent


def _positive_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


#: Where the step's Jacobians come from (:attr:`ILQRConfig.jacobians`).
JACOBIANS = ("differences", "exact")


@dataclass(frozen=True)
class ILQRConfig:
    """Settings of :class:`ILQRPlanner`.

    Attributes:
        horizon: Steps planned (>= 1); None: the scene's (:func:`ilqr_costs.scene_horizon`).
        iterations: iLQR iterations per control step (>= 0; 0 plays the better warm start).
        alphas: Line-search step sizes, each in (0, 1], tried in one batch (>= 1 of them).
        reuse: Warm-start from the previous call's shifted solution as well as the LQR.
        jacobians: "differences" (the step's Jacobians by differences of the kernel's
            step) or "exact" (forward-mode autograd through the differentiable twin,
            :mod:`agents.oracles.ilqr_tangent`; needs torch).
        central: Central differences (2 (d + 1) copies per step), else forward (d + 2);
            with "exact", of the cost's residuals only.
        state_step, control_step: Central-difference steps (state units; fraction of
            the acceleration bound), > 0.
        regularization: Initial ``Q_vv`` damping of each plan (>= 0).
        weights: Cost weights; None: the scene's defaults (:func:`ilqr_costs.scene_weights`).
    """

    horizon: int | None = None
    iterations: int = 3
    alphas: tuple[float, ...] = (1.0, 0.5, 0.2, 0.05)
    reuse: bool = True
    jacobians: str = "differences"
    central: bool = False
    state_step: float = 1e-5
    control_step: float = 1e-5
    regularization: float = 1e-3
    weights: CostWeights | None = None

    def __post_init__(self) -> None:
        if self.horizon is not None:
            _positive_int("horizon", self.horizon, 1)
        _positive_int("iterations", self.iterations, 0)
        alphas = tuple(self.alphas)
        if not alphas or not all(
            isinstance(a, (int, float)) and not isinstance(a, bool) and 0.0 < a <= 1.0
            for a in alphas
        ):
            raise ValueError(f"alphas must be numbers in (0, 1], at least one, got {alphas!r}")
        if not isinstance(self.jacobians, str):
            raise TypeError(f"jacobians must be a str, got {type(self.jacobians).__name__}")
        if self.jacobians not in JACOBIANS:
            raise ValueError(f"jacobians must be one of {list(JACOBIANS)}, got {self.jacobians!r}")
        for name in ("reuse", "central"):
            if not isinstance(getattr(self, name), bool):
                raise TypeError(f"{name} must be a bool, got {type(getattr(self, name)).__name__}")
        for name in ("state_step", "control_step", "regularization"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"{name} must be a real number, got {value!r}")
            if not np.isfinite(value) or value < 0.0 or (value == 0.0 and name != "regularization"):
                raise ValueError(
                    f"{name} must be finite and > 0 (regularization >= 0), got {value}"
                )
        if self.weights is not None and not isinstance(self.weights, CostWeights):
            raise TypeError(f"weights must be CostWeights, got {type(self.weights).__name__}")

    @property
    def candidates(self) -> int:
        """Rollouts per environment and batch: the step sizes (at least the 2 warm starts)."""
        return max(2, len(self.alphas))


@dataclass
class Trajectory:
    """Rollouts (R rows): states ``x`` (R, H+1, d) with their core rows ``z``, ``act``;
    controls ``v`` and actions sent (R, H); substeps (R, H); stage residuals (R, H+1, m);
    the terminal design-speed index (R,); ``alive`` (R, H+1); total ``cost`` (R,)."""

    x: np.ndarray
    z: np.ndarray
    act: np.ndarray
    v: np.ndarray
    actions: np.ndarray
    substeps: np.ndarray
    residual: np.ndarray
    terminal: np.ndarray
    speed_index: np.ndarray
    alive: np.ndarray
    cost: np.ndarray

    def take(self, rows: np.ndarray) -> Trajectory:
        """The rollouts ``rows`` (int array), copied."""
        values = {f.name: getattr(self, f.name)[rows].copy() for f in dataclasses.fields(self)}
        return Trajectory(**values)

    def update(self, rows: np.ndarray, other: Trajectory) -> None:
        """Replace the rollouts where ``rows`` (bool (R,)) by ``other``'s."""
        for f in dataclasses.fields(self):
            getattr(self, f.name)[rows] = getattr(other, f.name)[rows]


def _derivative_settings(settings: EnvSettings) -> EnvSettings:
    """The settings with fixed RK4 substeps (the count is then set per row)."""
    for substeps in (1, 2, 4, 8, 16, 32, 64):
        try:
            fidelity = Fidelity(integrator="rk4", substeps=substeps)
            return dataclasses.replace(settings, fidelity=fidelity)
        except ValueError:
            continue
    raise ValueError("no fixed RK4 substep count up to 64 integrates these settings")


class ILQRPlanner:
    """Control-limited iLQR on the scene's batched core (see the module).

    Args:
        core_class: The scene's batch core (e.g. ``DockCore``).
        settings: The environment's settings (rail actuator: "servo" or "accel").
        batch_size: Environments planned for at once (E).
        config: Planner settings.

    After :meth:`plan`: ``last`` is the final nominal :class:`Trajectory` (E rows),
    ``warm_costs`` (E, 2) the costs of the LQR's and the shifted warm start, and
    ``simulated_steps`` counts every simulated row-step so far.

    Raises:
        ValueError: In planar mode, for a batch size below 1.
        TypeError: For a batch size or config of the wrong type.
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        batch_size: int,
        config: ILQRConfig | None = None,
    ) -> None:
        require_rail(settings)
        if config is not None and not isinstance(config, ILQRConfig):
            raise TypeError(f"config must be ILQRConfig, got {type(config).__name__}")
        self.batch_size = _positive_int("batch_size", batch_size, 1)
        self.config = config or ILQRConfig()
        self.settings = settings
        self.core_class = core_class
        self.n = settings.n_trailers
        self.cost = SceneCost(core_class, settings, self.config.weights)
        chosen = self.config.horizon
        self.horizon = horizon = scene_horizon(core_class) if chosen is None else int(chosen)
        count = self.batch_size
        self.model = core_class(settings, count * self.config.candidates)
        self.width = self.model.z.shape[1]
        self.d = self.width + 2
        d = self.d
        central = self.config.central
        # Copies per step of the horizon: state +-h e_j and control +-h (central), or the
        # nominal, state + h e_j and control + h (forward). plus/minus: their rows.
        self.perturbed = 2 * (d + 1) if central else d + 2
        if central:
            self._plus, self._minus = 2 * np.arange(d), 2 * np.arange(d) + 1
            self._control_rows = (2 * d, 2 * d + 1)
        else:
            self._plus, self._minus = 1 + np.arange(d), np.zeros(d, dtype=np.int64)
            self._control_rows = (d + 1, 0)
        self.jac = core_class(
            _derivative_settings(settings), count * (horizon + 1) * self.perturbed
        )
        self.tangent: StepTangent | None = None
        if self.config.jacobians == "exact":
            from agents.oracles.ilqr_tangent import StepTangent

            self.tangent = StepTangent(
                core_class, _derivative_settings(settings), self.model.with_pose
            )
        self.lqr = LQRController(settings)
        step = self.config.state_step
        self._delta = np.zeros((self.perturbed, d))
        self._delta[self._plus, np.arange(d)] = step
        if central:
            self._delta[self._minus, np.arange(d)] = -step
        self._divisor = (2.0 if central else 1.0) * step
        self.previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.valid = np.zeros(count, dtype=bool)
        self.simulated_steps = 0

    @property
    def steps_per_decision(self) -> int:
        """Simulated steps per environment and control step: the rollouts, and the
        perturbed copies or (exact Jacobians) the twin's steps."""
        config = self.config
        rollouts = (config.iterations + 1) * config.candidates * self.horizon
        if self.tangent is not None:  # one twin step (with its tangents) per state
            return rollouts + config.iterations * self.horizon
        return rollouts + config.iterations * (self.horizon + 1) * self.perturbed

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Forget the warm start of ``rows`` (default all), e.g. after their episodes ended."""
        if rows is None:
            self.valid[:] = False
        else:
            self.valid[rows] = False

    # ----------------------------------------------------------------- model
    def _state(self, core: ConvoyCore) -> np.ndarray:
        return np.column_stack([core.z, core.act[:, ETA], core.act[:, ETA_DOT]])

    def _command(self, fraction: np.ndarray, core: ConvoyCore) -> np.ndarray:
        """The action (clipped to [-1, 1]) asking the actuator for ``fraction`` of the bound.

        A non-finite fraction becomes 0 in place, before the rollout records it: near a
        fold the backward pass can return non-finite gains (Dock-v0, n = 2), and a NaN
        command would make the core refuse the whole batch's step.
        """
        fraction[~np.isfinite(fraction)] = 0.0
        settings = self.settings
        accel_max = settings.rail_accel_max
        command = settings.actuator.command_for_accel(
            fraction * accel_max,
            core.act[:, ETA],
            core.act[:, ETA_DOT],
            settings.params.s_max,
            accel_max,
            settings.servo_frequency,
        )
        return np.clip(command, -1.0, 1.0)

    def _lqr_fraction(self, core: ConvoyCore) -> np.ndarray:
        """The LQR's acceleration for every row of ``core``, as a clipped fraction."""
        n = self.n
        z = core.z
        state = np.column_stack(
            [z[:, OMEGA], z[:, ALPHA : ALPHA + n], core.act[:, ETA], core.act[:, ETA_DOT]]
        )
        accel = -np.sum(self.lqr.gains(z[:, U]) * state, axis=1)
        return np.clip(accel / self.settings.rail_accel_max, -1.0, 1.0)

    def _set_task(self, core: ConvoyCore, task: dict[str, np.ndarray], repeat: int) -> None:
        for key, value in task.items():
            getattr(core, key)[:] = np.repeat(value, repeat, axis=0)

    def _rollout(
        self,
        z0: np.ndarray,
        act0: np.ndarray,
        feedforward: np.ndarray,
        gains: np.ndarray,
        reference: np.ndarray,
        lqr_rows: np.ndarray,
    ) -> Trajectory:
        """Roll the model core out from the E states, L candidates each (rows e * L + l):
        ``v_t = clip(feedforward + gains . (x_t - reference_t))``, or the LQR's where
        ``lqr_rows``."""
        core = self.model
        cost_model = self.cost
        w = cost_model.weights
        horizon = self.horizon
        rows = core.batch_size
        repeat = rows // z0.shape[0]
        core.z[:] = np.repeat(z0, repeat, axis=0)
        core.act[:] = np.repeat(act0, repeat, axis=0)
        core.refresh()
        m = cost_model.size
        x = np.empty((rows, horizon + 1, self.d))
        out = Trajectory(
            x=x,
            z=np.empty((rows, horizon + 1, self.width)),
            act=np.empty((rows, horizon + 1, ACT_WIDTH)),
            v=np.zeros((rows, horizon)),
            actions=np.zeros((rows, horizon)),
            substeps=np.ones((rows, horizon), dtype=np.int64),
            residual=np.zeros((rows, horizon + 1, m)),
            terminal=np.zeros((rows, cost_model.terminal_size)),
            speed_index=np.zeros(rows, dtype=np.int64),
            alive=np.zeros((rows, horizon + 1), dtype=bool),
            cost=np.zeros(rows),
        )
        alive = np.ones(rows, dtype=bool)
        fraction = np.empty(rows)
        action = np.zeros((rows, 1))
        any_lqr = bool(lqr_rows.any())
        out.residual[:, 0] = cost_model.stage_residuals(core)
        for t in range(horizon + 1):
            x[:, t] = self._state(core)
            out.z[:, t] = core.z
            out.act[:, t] = core.act
            out.alive[:, t] = alive
            if t == horizon:
                break
            feedback(feedforward[:, t], gains[:, t], x[:, t], reference[:, t], fraction)
            if any_lqr:
                fraction[lqr_rows] = self._lqr_fraction(core)[lqr_rows]
            fraction[~alive] = 0.0
            action[:, 0] = self._command(fraction, core)
            out.v[:, t] = fraction
            out.actions[:, t] = action[:, 0]
            core.step(action)
            self.simulated_steps += rows
            out.substeps[:, t] = core.substeps
            ended = alive & core.terminated
            failed = ended & ~core.success
            out.cost += np.where(alive, w.control * fraction**2, 0.0)
            alive = alive & ~core.terminated
            # Residuals of the state reached (those of ended rows are never read).
            residual = out.residual[:, t + 1]
            residual[:] = cost_model.stage_residuals(core)
            out.cost += np.where(alive, np.sum(residual**2, axis=1), 0.0)
            out.cost += np.where(failed, w.failure + w.failure_per_step * (horizon - t), 0.0)
            if ended.any():
                # Park ended rows straight: their cost is settled, and a folded convoy
                # stepped on could approach the model's singularity.
                parked = np.flatnonzero(ended)
                core.z[parked] = 0.0
                core.z[parked, 0] = -1.0
                core.act[parked] = 0.0
                core.act[parked, 0] = core.params.b
                core.refresh(parked)
        out.speed_index[:] = cost_model.speed_index(core.z[:, U])
        out.terminal[:] = cost_model.terminal_residuals(core.z, core.act, out.speed_index)
        out.cost += np.where(alive, np.sum(out.terminal**2, axis=1), 0.0)
        return out

    def _derivatives(self, nominal: Trajectory) -> tuple[np.ndarray, ...]:
        """Jacobians of the step (A, B) and of the residuals along ``nominal`` (E rows):
        the residuals' from the perturbed copies, the step's from one step of them or,
        with exact Jacobians, from the twin's tangent."""
        jac = self.jac
        count = nominal.x.shape[0]
        horizon = self.horizon
        d, width, p = self.d, self.width, self.perturbed
        delta = self._delta
        z = nominal.z[:, :, None, :] + delta[None, None, :, :width]
        act = np.repeat(nominal.act[:, :, None, :], p, axis=2)
        act[..., ETA] += delta[:, width]
        act[..., ETA_DOT] += delta[:, width + 1]
        jac.z[:] = z.reshape(-1, width)
        jac.act[:] = act.reshape(-1, ACT_WIDTH)
        jac.refresh()
        plus, minus, divisor = self._plus, self._minus, self._divisor
        residual = self.cost.stage_residuals(jac).reshape(count, horizon + 1, p, -1)
        jacobian = (residual[:, :, plus] - residual[:, :, minus]) / divisor
        # The terminal residuals of the last step's copies only (rows e, H, :).
        last = (np.arange(count)[:, None] * (horizon + 1) + horizon) * p + np.arange(p)
        index = np.repeat(nominal.speed_index, p)
        terminal = self.cost.terminal_residuals(jac.z[last.ravel()], jac.act[last.ravel()], index)
        terminal = terminal.reshape(count, p, -1)
        terminal_jacobian = (terminal[:, plus] - terminal[:, minus]) / divisor
        jacobian = np.ascontiguousarray(np.swapaxes(jacobian, 2, 3))
        terminal_jacobian = np.ascontiguousarray(np.swapaxes(terminal_jacobian, 1, 2))
        if self.tangent is not None:
            # Live steps only: the backward pass reads no Jacobian after an episode ends.
            live = nominal.alive[:, :horizon].reshape(-1)
            a_matrix = np.zeros((count * horizon, d, d))
            b_vector = np.zeros((count * horizon, d))
            if live.any():
                _, a_matrix[live], b_vector[live] = self.tangent.jacobians(
                    nominal.z[:, :horizon].reshape(-1, width)[live],
                    nominal.act[:, :horizon].reshape(-1, ACT_WIDTH)[live],
                    nominal.v.reshape(-1)[live],
                    nominal.substeps.reshape(-1)[live],
                )
            self.simulated_steps += int(live.sum())
            return (
                a_matrix.reshape(count, horizon, d, d),
                b_vector.reshape(count, horizon, d),
                jacobian,
                terminal_jacobian,
            )
        # Controls: the nominal's, and on the control rows +-h around it (central, kept
        # inside the box) or the nominal and v + h (forward; v - h at the upper bound).
        h = self.config.control_step
        v = np.zeros((count, horizon + 1))
        v[:, :horizon] = nominal.v
        controls = np.repeat(v[:, :, None], p, axis=2)
        up, down = self._control_rows
        if self.config.central:
            centre = np.clip(v, -1.0 + h, 1.0 - h)
            controls[:, :, up] = centre + h
            controls[:, :, down] = centre - h
        else:
            controls[:, :, up] = np.where(v + h <= 1.0, v + h, v - h)
        spread = (controls[:, :horizon, up] - controls[:, :horizon, down])[:, :, None]
        substeps = np.ones((count, horizon + 1), dtype=np.int64)
        substeps[:, :horizon] = nominal.substeps
        jac.substeps[:] = np.repeat(substeps, p)
        jac.step(self._command(controls.reshape(-1), jac)[:, None])
        self.simulated_steps += jac.batch_size
        after = self._state(jac).reshape(count, horizon + 1, p, d)[:, :horizon]
        a_matrix = (after[:, :, plus] - after[:, :, minus]) / divisor
        b_vector = (after[:, :, up] - after[:, :, down]) / spread
        # after[..., j, i] = x_i after perturbing x_j: A[i, j] wants the transpose.
        a_matrix = np.ascontiguousarray(np.swapaxes(a_matrix, 2, 3))
        return a_matrix, b_vector, jacobian, terminal_jacobian

    # ------------------------------------------------------------------ plan
    def _check(
        self, z: np.ndarray, act: np.ndarray, task: Mapping[str, object] | None
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        count, width = self.batch_size, self.width
        z = np.asarray(z, dtype=np.float64)
        act = np.asarray(act, dtype=np.float64)
        if z.ndim != 2 or z.shape[0] != count or act.shape != (count, ACT_WIDTH):
            raise ValueError(f"expected {count} states, got z {z.shape} and act {act.shape}")
        if z.shape[1] < width and (self.model.with_pose or z.shape[1] < self.n + 2):
            raise ValueError(
                f"z needs {width} columns for {self.core_class.__name__}, got {z.shape}"
            )
        if not (np.all(np.isfinite(z[:, :width])) and np.all(np.isfinite(act))):
            raise ValueError("z and act must be finite")
        state = np.zeros((count, width))
        state[:, : min(width, z.shape[1])] = z[:, :width]
        task = dict(task or {})
        keys = self.core_class.task_keys
        if sorted(task) != sorted(keys):
            raise ValueError(f"task must give {list(keys)} for {self.core_class.__name__}")
        values: dict[str, np.ndarray] = {}
        for key in keys:
            target = getattr(self.model, key, None)
            if not isinstance(target, np.ndarray):
                raise ValueError(f"the planner cannot set task value {key!r} of this scene")
            value = np.asarray(task[key], dtype=np.float64).reshape((count, *target.shape[1:]))
            if not np.all(np.isfinite(value)):
                raise ValueError(f"task value {key!r} must be finite")
            values[key] = value
        return state, act, values

    def plan(
        self, z: np.ndarray, act: np.ndarray, task: Mapping[str, object] | None = None
    ) -> np.ndarray:
        """Actions (E, 1), float64 in [-1, 1], for the environments' exact states.

        Args:
            z: (E, width) core states (E, n+2 suffices for scenes without a pose).
            act: (E, 6) mass states as in :attr:`ConvoyCore.act`.
            task: The scene's task arrays by :attr:`ConvoyCore.task_keys` (Dock:
                ``{"target": (E, 3)}``); required exactly when the scene has task keys.

        Raises:
            ValueError: On shapes that do not fit, non-finite values, missing task values.
        """
        config = self.config
        state, act, task_values = self._check(z, act, task)
        count, horizon, d = self.batch_size, self.horizon, self.d
        candidates = config.candidates
        self._set_task(self.model, task_values, candidates)
        self._set_task(self.jac, task_values, (horizon + 1) * self.perturbed)
        shape = (count, candidates)
        feedforward = np.zeros((*shape, horizon))
        gains = np.zeros((*shape, horizon, d))
        reference = np.zeros((*shape, horizon + 1, d))
        lqr_rows = np.ones(shape, dtype=bool)
        if config.reuse and self.previous is not None and self.valid.any():
            v, gain, x = self.previous
            feedforward[:, 1, :-1], feedforward[:, 1, -1] = v[:, 1:], v[:, -1]
            gains[:, 1, :-1], gains[:, 1, -1] = gain[:, 1:], gain[:, -1]
            reference[:, 1, :-1], reference[:, 1, -1] = x[:, 1:], x[:, -1]
            lqr_rows[:, 1] = ~self.valid
        flat = (count * candidates,)
        trial = self._rollout(
            state,
            act,
            feedforward.reshape(*flat, horizon),
            gains.reshape(*flat, horizon, d),
            reference.reshape(*flat, horizon + 1, d),
            lqr_rows.reshape(flat),
        )
        offsets = np.arange(count) * candidates
        self.warm_costs = trial.cost.reshape(shape)[:, :2].copy()
        nominal = trial.take(offsets + trial.cost.reshape(shape).argmin(axis=1))
        regularization = np.full(count, config.regularization)
        alphas = np.array(
            list(config.alphas) + [config.alphas[-1]] * (candidates - len(config.alphas))
        )
        step = np.zeros((count, horizon))
        gain = np.zeros((count, horizon, d))
        decrease = np.zeros(count)
        no_lqr = np.zeros(count * candidates, dtype=bool)
        for _ in range(config.iterations):
            a_matrix, b_vector, jacobian, terminal_jacobian = self._derivatives(nominal)
            backward_pass(
                a_matrix,
                b_vector,
                jacobian,
                nominal.residual,
                terminal_jacobian,
                nominal.terminal,
                nominal.alive,
                nominal.v,
                self.cost.weights.control,
                regularization,
                step,
                gain,
                decrease,
            )
            trial_ff = nominal.v[:, None, :] + alphas[None, :, None] * step[:, None, :]
            trial = self._rollout(
                state,
                act,
                trial_ff.reshape(*flat, horizon),
                np.repeat(gain, candidates, axis=0),
                np.repeat(nominal.x, candidates, axis=0),
                no_lqr,
            )
            best = trial.take(offsets + trial.cost.reshape(shape).argmin(axis=1))
            better = best.cost < nominal.cost
            nominal.update(better, best)
            regularization = np.where(better, regularization * 0.1, regularization * 10.0)
            regularization = np.clip(regularization, 1e-8, 1e8)
        self.previous = (nominal.v.copy(), gain.copy(), nominal.x.copy())
        self.valid[:] = True
        self.last = nominal
        return nominal.actions[:, :1].copy()


__all__ = ["JACOBIANS", "ILQRConfig", "ILQRPlanner", "Trajectory"]
