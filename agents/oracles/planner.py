"""The ``mpc`` baseline: a saturation-aware receding-horizon sampling planner (an oracle).

Every control step, for every environment of the batch, :class:`SamplingPlanner` runs a
cross-entropy search (CEM) over action sequences on the real nonlinear model and applies
the first action of the best one found. Its candidates are closed-loop: the action at
each step of a rollout is the LQR's action for that step's state plus a sampled offset,
``a_t = clip(LQR(x_t) + delta_t, -1, 1)``, so ``delta = 0`` is the LQR's own action
sequence (always a candidate: the planner is warm-started from the LQR and never
does worse than it over its horizon, by its cost) and the search only has to find the
offsets that steer around saturation (the rail's ends, the acceleration bound), which
the LQR's design ignores. The previous step's best offsets, shifted by one step, are the
search's starting mean.

The candidates are simulated by the scene's own batched core
(:class:`trailer_env.core.ConvoyCore`, one row per candidate and environment, the same
integrator, servo and guard as the env): their states are copied from the real state
each control step (``core.z[:] = ...; core.act[:] = ...; core.refresh()``). A candidate's
offsets act over ``horizon`` steps; the rollout then continues for ``tail`` steps under
the LQR alone, which is what makes the search saturation-aware: a candidate is judged
by whether the regulator can still recover from where it leaves the convoy (a short
horizon alone picked myopic sequences that drove the mass to the rail's end, and did
worse than the LQR). A rollout's cost sums, per step, ``sum_k alpha_k^2 + 0.1 omega^2 +
0.05 (s / s_max)^2`` plus 20 per step in the singular band; a failure (a fold, or the
scene's other termination without success: the convoy stopped reversing) costs 1000
plus 100 per remaining step, and the final state costs ``x^T P x`` with ``P`` the LQR's
Riccati matrix at the nearest design speed.

It is an oracle: it knows the model exactly and reads the exact state (from the
environment's core, or from an observation, which holds the state in float32). Its
cost per control step is ``iterations * (horizon + tail) * samples`` simulated steps
per environment: with the defaults (2 iterations, 10 + 50 steps, 16 samples) 1920, so
768 000 per 400-step episode. The wall time of 100 episodes planned in one batch is
written by ``python -m agents.certify`` and quoted in docs/physics.md section 14.

This module holds the search (:class:`SamplingPlanner`) and its episode runner
(:func:`plan_episodes`); :class:`agents.oracles.mpc_policy.MPCPolicy` puts it behind the
policy interface and :class:`agents.oracles.labellers.PrivilegedExpert` makes it a DAgger
labeller.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from agents.oracles.rail import require_rail
from agents.progress import Progress
from dynamics.columns import XI
from trailer_env.controllers import (
    ACCEL_WEIGHT,
    ANGLE_WEIGHT,
    DESIGN_SPEEDS,
    OMEGA_WEIGHT,
    RAIL_SPEED_WEIGHT,
    RAIL_WEIGHT,
    LQRController,
    linearise,
)
from trailer_env.core import ConvoyCore
from trailer_env.randomize import PARAMETERS
from trailer_env.settings import EnvSettings

#: Stage-cost weights (per step) and penalties of a rollout.
ANGLE_COST = 1.0
OMEGA_COST = 0.1
RAIL_COST = 0.05
BAND_COST = 20.0
FAILURE_COST = 1000.0
FAILURE_COST_PER_STEP = 100.0


@dataclass(frozen=True)
class PlannerConfig:
    """Search settings of :class:`SamplingPlanner`.

    Attributes:
        samples: Candidate sequences per environment and iteration (>= 2).
        horizon: Steps over which a candidate's offsets act (>= 1).
        tail: Further steps simulated under the LQR alone (>= 0): whether the LQR can
            recover from where the offsets leave the convoy.
        iterations: CEM iterations per control step (>= 1).
        elites: Candidates the CEM refits its mean and spread to (< samples).
        noise: Initial spread of the offsets, in action units.
        min_noise: Floor of the refitted spread.
        seed: Seed of the sampling generator (the planner is deterministic given it).
    """

    samples: int = 16
    horizon: int = 10
    tail: int = 50
    iterations: int = 2
    elites: int = 4
    noise: float = 0.2
    min_noise: float = 0.05
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("samples", "horizon", "iterations", "elites"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if self.samples < 2 or self.elites >= self.samples:
            raise ValueError(
                f"need samples >= 2 and elites < samples, got {self.samples}, {self.elites}"
            )
        if (
            isinstance(self.tail, bool)
            or not isinstance(self.tail, (int, np.integer))
            or self.tail < 0
        ):
            raise ValueError(f"tail must be an integer >= 0, got {self.tail!r}")
        if not (self.noise > 0.0 and self.min_noise >= 0.0):
            raise ValueError("noise must be > 0 and min_noise >= 0")

    @property
    def steps_per_decision(self) -> int:
        """Simulated steps per environment and control step."""
        return self.iterations * (self.horizon + self.tail) * self.samples


def riccati_matrices(settings: EnvSettings, speeds: np.ndarray) -> np.ndarray:
    """The LQR's Riccati matrices P (len(speeds), n+3, n+3) at forward ``speeds``."""
    n = settings.n_trailers
    q = np.diag([OMEGA_WEIGHT] + [ANGLE_WEIGHT] * n + [RAIL_WEIGHT, RAIL_SPEED_WEIGHT])
    r = np.array([[ACCEL_WEIGHT]])
    out = np.zeros((len(speeds), n + 3, n + 3))
    for i, speed in enumerate(speeds):
        a_matrix, b_matrix = linearise(settings, float(speed))
        try:
            out[i] = scipy.linalg.solve_continuous_are(a_matrix, b_matrix, q, r)
        except (np.linalg.LinAlgError, ValueError):
            out[i] = np.diag(np.diag(q))
    return out


class SamplingPlanner:
    """CEM over closed-loop action offsets on the scene's batched core (see the module).

    Args:
        core_class: The scene's batch core (e.g. ``ReverseCore``).
        settings: The environment's settings (rail actuator: "servo" or "accel").
        batch_size: Environments planned for at once (E).
        config: Search settings.

    :meth:`plan` takes the exact states of the E environments and returns their actions.

    Per-row parameters (a privileged expert for randomised physics): when ``settings``
    randomise a physical parameter (``randomize=``), :meth:`plan` takes each row's TRUE
    parameters ``params`` (E, 7), columns :data:`trailer_env.randomize.PARAMETERS`
    (``core.param_values``). Each row's vector is repeated over its candidate copies in
    the planning core (the kernels take per-row parameters), and the LQR feedback and the
    terminal Riccati matrices of a row are those designed for its parameters (a design is
    cached per distinct vector, as ``lqr-adaptive`` does). A row's label is then what a
    planner built for that row's parameters alone (``randomize=None``,
    ``params=ConvoyParams(...)``) would give for the same sampled offsets.
    :meth:`plan` may also plan for a subset ``rows`` of the E environments (the others'
    warm starts are kept): the planning core then steps only those rows' candidates.
    """

    #: Most cached LQR designs (a design per distinct parameter vector); cleared when full.
    MAX_DESIGNS = 8192

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        batch_size: int,
        config: PlannerConfig | None = None,
    ) -> None:
        require_rail(settings)
        if isinstance(batch_size, bool) or not isinstance(batch_size, (int, np.integer)):
            raise TypeError(f"batch_size must be an int, got {type(batch_size).__name__}")
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        self.config = config or PlannerConfig()
        self.settings = settings
        self.n = settings.n_trailers
        self.batch_size = int(batch_size)
        samples = self.config.samples
        self.core = core_class(settings, self.batch_size * samples)
        self.lqr = LQRController(settings)
        self.speeds = -DESIGN_SPEEDS
        self.riccati = riccati_matrices(settings, self.speeds)
        self.rng = np.random.default_rng(self.config.seed)
        self.mean = np.zeros((self.batch_size, self.config.horizon))
        self.simulated_steps = 0
        randomize = settings.randomize
        #: Whether the planning core takes per-row parameters (``plan(..., params=...)``).
        self.per_row = randomize is not None and any(name in PARAMETERS for name in randomize.names)
        self._designs: dict[tuple[float, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # Per candidate row while a per-row plan is evaluated: gains tables (forward,
        # reverse: (m, S, n+3)) and Riccati matrices (m, S, n+3, n+3).
        self._row_tables: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._rows_stepped: np.ndarray | None = None

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Forget the warm start of ``rows`` (default all), e.g. after their episodes ended."""
        if rows is None:
            self.mean[:] = 0.0
        else:
            self.mean[rows] = 0.0

    def _evaluate(
        self, z: np.ndarray, act: np.ndarray, offsets: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Costs (E, K) of the offset sequences (E, K, H) and their first actions (E, K)."""
        core = self.core
        settings = self.settings
        n = self.n
        count, samples, horizon = offsets.shape
        flat = offsets.reshape(count * samples, horizon)
        used = count * samples
        whole = used == core.batch_size
        stepped = None if whole else np.arange(used, dtype=np.int64)
        self._rows_stepped = stepped
        core.z[:used] = np.repeat(z, samples, axis=0)
        core.act[:used] = np.repeat(act, samples, axis=0)
        core.refresh(stepped)
        cost = np.zeros(count * samples)
        alive = np.ones(count * samples, dtype=bool)
        first = np.zeros(count * samples)
        action = np.zeros((count * samples, 1))
        s_max = settings.params.s_max
        total = horizon + self.config.tail
        for t in range(total):
            command = self._feedback()
            if t < horizon:
                command += flat[:, t]
            np.clip(command, -1.0, 1.0, out=command)
            if t == 0:
                first[:] = command
            if whole:
                action[:, 0] = command
                core.step(action)
            else:
                full = np.zeros((core.batch_size, 1))
                full[:used, 0] = command
                core.step(full, stepped)
            self.simulated_steps += count * samples
            alpha = core.z[:used, 2 : 2 + n]
            stage = (
                ANGLE_COST * np.sum(alpha**2, axis=1)
                + OMEGA_COST * core.z[:used, 1] ** 2
                + RAIL_COST * (core.act[:used, 1] / s_max) ** 2
                + BAND_COST * core.cost[:used]
            )
            failed = alive & core.terminated[:used] & ~core.success[:used]
            cost += np.where(alive, stage, 0.0)
            cost += np.where(failed, FAILURE_COST + FAILURE_COST_PER_STEP * (total - t), 0.0)
            alive &= ~failed
            if failed.any():
                # Park the failed rows in a harmless state: their cost is settled, and a
                # folded convoy stepped on could approach the model's singularity.
                rows = np.flatnonzero(failed)
                core.z[rows] = 0.0
                core.z[rows, 0] = -1.0
                core.act[rows] = 0.0
                core.act[rows, XI] = settings.params.b
                core.refresh(rows)
        # Terminal cost x^T P x with the Riccati matrix at the nearest design speed.
        nearest = np.abs(core.z[:used, :1] - self.speeds[None, :]).argmin(axis=1)
        state = np.column_stack(
            [core.z[:used, 1], core.z[:used, 2 : 2 + n], core.act[:used, 1], core.act[:used, 3]]
        )
        if self._row_tables is None:
            riccati = self.riccati[nearest]
        else:
            riccati = self._row_tables[2][np.arange(used), nearest]
        terminal = np.einsum("bi,bij,bj->b", state, riccati, state)
        cost += np.where(alive, terminal, 0.0)
        return cost.reshape(count, samples), first.reshape(count, samples)

    def _feedback(self) -> np.ndarray:
        """The LQR's command for every row of the planning core, from its exact state."""
        core = self.core
        n = self.n
        settings = self.settings
        used = core.batch_size if self._rows_stepped is None else self._rows_stepped.size
        speed = core.z[:used, 0]
        if self._row_tables is None:
            gains = self.lqr.gains(speed)
        else:
            gains = _row_gains(speed, self._row_tables[0], self._row_tables[1])
        state = np.column_stack(
            [core.z[:used, 1], core.z[:used, 2 : 2 + n], core.act[:used, 1], core.act[:used, 3]]
        )
        accel = -np.sum(gains * state, axis=1)
        return settings.actuator.command_for_accel(
            accel,
            core.act[:used, 1],
            core.act[:used, 3],
            settings.params.s_max,
            settings.rail_accel_max,
            settings.servo_frequency,
        )

    def _design(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Forward and reverse gain tables and Riccati matrices for one parameter vector."""
        key = tuple(float(value) for value in values)
        design = self._designs.get(key)
        if design is None:
            if len(self._designs) >= self.MAX_DESIGNS:
                self._designs.clear()
            params = self.settings.params.replace(**dict(zip(PARAMETERS, key, strict=True)))
            settings = dataclasses.replace(self.settings, params=params, randomize=None)
            lqr = LQRController(settings)
            design = (lqr.forward_gains, lqr.reverse_gains, riccati_matrices(settings, self.speeds))
            self._designs[key] = design
        return design

    def _set_row_params(self, params: np.ndarray) -> None:
        """Each planned row's parameters over its candidate copies, and its designs."""
        samples = self.config.samples
        count = params.shape[0]
        designs = [self._design(values) for values in params]
        forward = np.repeat(np.stack([d[0] for d in designs]), samples, axis=0)
        reverse = np.repeat(np.stack([d[1] for d in designs]), samples, axis=0)
        riccati = np.repeat(np.stack([d[2] for d in designs]), samples, axis=0)
        self._row_tables = (forward, reverse, riccati)
        used = np.arange(count * samples, dtype=np.int64)
        self.core.set_row_params(used, np.repeat(params, samples, axis=0))

    def label(self, core: ConvoyCore) -> np.ndarray:
        """:meth:`plan` for every row of a scene core of this planner's settings, from its
        exact states (and its rows' parameters when :attr:`per_row`)."""
        if self.per_row:
            return self.plan(core.z, core.act, core.param_values)
        return self.plan(core.z, core.act)

    def plan(
        self,
        z: np.ndarray,
        act: np.ndarray,
        params: np.ndarray | None = None,
        rows: np.ndarray | None = None,
    ) -> np.ndarray:
        """Actions (E, 1) (or (len(rows), 1)), float64 in [-1, 1], for exact states.

        Args:
            z: (E, >= n+2) states (u, omega, alpha_1..alpha_n, ...); the pose is ignored.
            act: (E, 6) mass states as in :attr:`ConvoyCore.act`.
            params: (E, 7) each row's true parameters (columns
                :data:`trailer_env.randomize.PARAMETERS`), required when the settings
                randomise the physics (:attr:`per_row`) and refused otherwise.
            rows: Which of the E environments ``z``, ``act`` and ``params`` are (distinct
                indices, int); default all, in order.

        Raises:
            ValueError: On shapes that do not match, ``params`` given to (or missing
                from) a planner without (with) per-row parameters, non-finite or
                non-positive parameters, or bad ``rows``.
        """
        config = self.config
        n = self.n
        if rows is None:
            count = self.batch_size
            picked: Any = slice(None)
        else:
            picked = np.asarray(rows)
            if picked.ndim != 1 or not np.issubdtype(picked.dtype, np.integer):
                raise ValueError(f"rows must be a 1-d integer array, got {picked!r}")
            if picked.size and (picked.min() < 0 or picked.max() >= self.batch_size):
                raise ValueError(f"rows must be in 0..{self.batch_size - 1}")
            if np.unique(picked).size != picked.size:
                raise ValueError("rows must be distinct")
            count = picked.size
            if count == 0:
                return np.zeros((0, 1))
        z = np.asarray(z, dtype=np.float64)
        act = np.asarray(act, dtype=np.float64)
        if z.shape[0] != count or act.shape != (count, 6) or z.shape[1] < n + 2:
            raise ValueError(f"expected {count} states, got z {z.shape} and act {act.shape}")
        if self.per_row:
            if params is None:
                raise ValueError(
                    "the settings randomise the physics: plan() needs each row's params (E, 7)"
                )
            values = np.asarray(params, dtype=np.float64)
            if values.shape != (count, len(PARAMETERS)):
                raise ValueError(
                    f"params must be ({count}, {len(PARAMETERS)}) (columns {PARAMETERS}), "
                    f"got {values.shape}"
                )
            if not (np.all(np.isfinite(values)) and np.all(values > 0.0)):
                raise ValueError("params must be finite and > 0")
            self._set_row_params(values)
        elif params is not None:
            raise ValueError(
                "params given, but the planner's settings do not randomise the physics "
                "(build it with the env's randomize= settings)"
            )
        width = self.core.z.shape[1]
        state = np.zeros((count, width))
        state[:, : n + 2] = z[:, : n + 2]
        mean = self.mean[picked].copy()
        spread = np.full_like(mean, config.noise)
        best_cost = np.full(count, np.inf)
        best_offsets = np.zeros_like(mean)
        best_first = np.zeros(count)
        for _ in range(config.iterations):
            noise = self.rng.standard_normal((count, config.samples, config.horizon))
            offsets = mean[:, None, :] + spread[:, None, :] * noise
            offsets[:, 0] = mean  # the current mean (the shifted previous plan)
            offsets[:, 1] = 0.0  # the LQR's own sequence
            try:
                costs, first = self._evaluate(state, act, offsets)
            finally:
                self._rows_stepped = None
            order = np.argsort(costs, axis=1)
            rows = np.arange(count)
            top = order[:, 0]
            better = costs[rows, top] < best_cost
            best_cost = np.where(better, costs[rows, top], best_cost)
            best_offsets[better] = offsets[rows, top][better]
            best_first = np.where(better, first[rows, top], best_first)
            elites = np.take_along_axis(offsets, order[:, : config.elites, None], axis=1)
            mean = elites.mean(axis=1)
            spread = np.maximum(elites.std(axis=1), config.min_noise)
        self._row_tables = None
        if rows is None:
            self.mean[:, :-1] = best_offsets[:, 1:]
            self.mean[:, -1] = 0.0
        else:
            shifted = np.zeros_like(best_offsets)
            shifted[:, :-1] = best_offsets[:, 1:]
            self.mean[picked] = shifted
        return best_first[:, None]


def _interp_rows(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp(x[i], xp, fp[i, :, c])`` for every row i and column c at once (the
    same arithmetic, so the same bits): x (m,) within [xp[0], xp[-1]], xp (S,)
    increasing, fp (m, S, C); returns (m, C)."""
    rows = np.arange(x.size)
    last = xp.size - 1
    j = np.clip(np.searchsorted(xp, x, side="right") - 1, 0, last - 1)
    low, high = fp[rows, j], fp[rows, j + 1]
    slope = (high - low) / (xp[j + 1] - xp[j])[:, None]
    out = slope * (x - xp[j])[:, None] + low
    out = np.where((x == xp[j])[:, None], low, out)
    out = np.where((x >= xp[last])[:, None], fp[rows, last], out)
    return np.where((x <= xp[0])[:, None], fp[rows, 0], out)


def _row_gains(speed: np.ndarray, forward: np.ndarray, reverse: np.ndarray) -> np.ndarray:
    """:meth:`LQRController.gains` with each row's own gain tables (m, S, n+3)."""
    magnitude = np.clip(np.abs(speed), DESIGN_SPEEDS[0], DESIGN_SPEEDS[-1])
    forwards = speed >= 0.0
    # Every row of a Reverse batch backs up: interpolate only the table the rows use
    # (row by row the same arithmetic, so the same bits), half the planner's feedback cost.
    if not forwards.any():
        return _interp_rows(magnitude, DESIGN_SPEEDS, reverse)
    if forwards.all():
        return _interp_rows(magnitude, DESIGN_SPEEDS, forward)
    ahead = _interp_rows(magnitude, DESIGN_SPEEDS, forward)
    back = _interp_rows(magnitude, DESIGN_SPEEDS, reverse)
    return np.where(forwards[:, None], ahead, back)


@dataclass(frozen=True)
class PlannedEpisodes:
    """What :func:`plan_episodes` did: the applied actions and how each episode went.

    Attributes:
        actions: (E, steps) float64, the actions applied (zero after an episode ended).
        lengths: (E,) steps before each episode ended (``steps`` if it did not).
        failed: (E,) the episode was terminated without success (folded, stopped reversing).
        band_steps: (E,) steps spent in the singular band.
    """

    actions: np.ndarray
    lengths: np.ndarray
    failed: np.ndarray
    band_steps: np.ndarray

    @property
    def safe(self) -> np.ndarray:
        """Never failed and never in the band (the metric of :mod:`agents.evaluation.metrics`)."""
        return ~self.failed & (self.band_steps == 0)


def plan_episodes(
    core: ConvoyCore, planner: SamplingPlanner, steps: int, progress: Progress | None = None
) -> PlannedEpisodes:
    """Run the planner on a reset core (one row per episode, exact states) for ``steps`` steps.

    ``progress`` (counting steps) advances once per planned step. Under randomised
    physics (:attr:`SamplingPlanner.per_row`) every row is planned with its episode's
    drawn parameters (``core.param_values``).

    Rows whose episode ended are parked straight (their result is settled) so that a
    folded convoy is not integrated further.
    """
    count = planner.batch_size
    if core.batch_size != count:
        raise ValueError(f"core has {core.batch_size} rows, the planner plans for {count}")
    actions = np.zeros((count, steps))
    lengths = np.full(count, steps, dtype=np.int64)
    failed = np.zeros(count, dtype=bool)
    band_steps = np.zeros(count, dtype=np.int64)
    running = np.ones(count, dtype=bool)
    step_action = np.zeros((count, 1))
    for t in range(steps):
        planned = planner.label(core)[:, 0]
        step_action[:, 0] = np.where(running, planned, 0.0)
        actions[running, t] = step_action[running, 0]
        core.step(step_action)
        if progress is not None:
            progress.advance(f"step {t + 1}, {int(running.sum())} convoys running")
        band_steps += running & (core.cost > 0.0)
        ended = running & core.terminated
        lengths[ended] = t + 1
        failed |= ended & ~core.success
        running &= ~ended
        if not running.any():
            break
        if ended.any():
            rows = np.flatnonzero(ended)
            core.z[rows, 1:] = 0.0
            core.z[rows, 0] = -1.0
            core.act[rows] = 0.0
            core.act[rows, XI] = core.params.b
            core.refresh(rows)
    return PlannedEpisodes(actions, lengths, failed, band_steps)


__all__ = [
    "PlannedEpisodes",
    "PlannerConfig",
    "SamplingPlanner",
    "plan_episodes",
    "riccati_matrices",
]
