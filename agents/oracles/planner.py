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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from agents.progress import Progress
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
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        batch_size: int,
        config: PlannerConfig | None = None,
    ) -> None:
        if settings.action_mode == "planar":
            raise ValueError("the planner drives the rail actuator, not action_mode='planar'")
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
        core.z[:] = np.repeat(z, samples, axis=0)
        core.act[:] = np.repeat(act, samples, axis=0)
        core.refresh()
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
            action[:, 0] = command
            core.step(action)
            self.simulated_steps += count * samples
            alpha = core.z[:, 2 : 2 + n]
            stage = (
                ANGLE_COST * np.sum(alpha**2, axis=1)
                + OMEGA_COST * core.z[:, 1] ** 2
                + RAIL_COST * (core.act[:, 1] / s_max) ** 2
                + BAND_COST * core.cost
            )
            failed = alive & core.terminated & ~core.success
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
                core.act[rows, 0] = settings.params.b
                core.refresh(rows)
        # Terminal cost x^T P x with the Riccati matrix at the nearest design speed.
        nearest = np.abs(core.z[:, :1] - self.speeds[None, :]).argmin(axis=1)
        state = np.column_stack(
            [core.z[:, 1], core.z[:, 2 : 2 + n], core.act[:, 1], core.act[:, 3]]
        )
        terminal = np.einsum("bi,bij,bj->b", state, self.riccati[nearest], state)
        cost += np.where(alive, terminal, 0.0)
        return cost.reshape(count, samples), first.reshape(count, samples)

    def _feedback(self) -> np.ndarray:
        """The LQR's command for every row of the planning core, from its exact state."""
        core = self.core
        n = self.n
        settings = self.settings
        speed = core.z[:, 0]
        gains = self.lqr.gains(speed)
        state = np.column_stack(
            [core.z[:, 1], core.z[:, 2 : 2 + n], core.act[:, 1], core.act[:, 3]]
        )
        accel = -np.sum(gains * state, axis=1)
        return settings.actuator.command_for_accel(
            accel,
            core.act[:, 1],
            core.act[:, 3],
            settings.params.s_max,
            settings.rail_accel_max,
            settings.servo_frequency,
        )

    def plan(self, z: np.ndarray, act: np.ndarray) -> np.ndarray:
        """Actions (E, 1), float64 in [-1, 1], for the environments' exact states.

        Args:
            z: (E, >= n+2) states (u, omega, alpha_1..alpha_n, ...); the pose is ignored.
            act: (E, 6) mass states as in :attr:`ConvoyCore.act`.
        """
        config = self.config
        count = self.batch_size
        n = self.n
        z = np.asarray(z, dtype=np.float64)
        act = np.asarray(act, dtype=np.float64)
        if z.shape[0] != count or act.shape != (count, 6) or z.shape[1] < n + 2:
            raise ValueError(f"expected {count} states, got z {z.shape} and act {act.shape}")
        width = self.core.z.shape[1]
        state = np.zeros((count, width))
        state[:, : n + 2] = z[:, : n + 2]
        mean = self.mean.copy()
        spread = np.full_like(mean, config.noise)
        best_cost = np.full(count, np.inf)
        best_offsets = np.zeros_like(mean)
        best_first = np.zeros(count)
        for _ in range(config.iterations):
            noise = self.rng.standard_normal((count, config.samples, config.horizon))
            offsets = mean[:, None, :] + spread[:, None, :] * noise
            offsets[:, 0] = mean  # the current mean (the shifted previous plan)
            offsets[:, 1] = 0.0  # the LQR's own sequence
            costs, first = self._evaluate(state, act, offsets)
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
        self.mean[:, :-1] = best_offsets[:, 1:]
        self.mean[:, -1] = 0.0
        return best_first[:, None]


def state_from_observation(obs: np.ndarray, settings: EnvSettings) -> tuple[np.ndarray, np.ndarray]:
    """The state (z, act) an observation of a rail-mode scene holds (float32 rounding).

    Raises:
        ValueError: In planar mode (the observation's layout differs).
    """
    if settings.action_mode == "planar":
        raise ValueError("the planner drives the rail actuator, not action_mode='planar'")
    n = settings.n_trailers
    batch = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    z = np.column_stack(
        [batch[:, :2], np.arctan2(batch[:, 2 : 2 + n], batch[:, 2 + n : 2 + 2 * n])]
    )
    act = np.zeros((batch.shape[0], 6))
    act[:, 0] = settings.params.b
    act[:, 1] = batch[:, 2 + 2 * n] * settings.params.s_max
    act[:, 3] = batch[:, 3 + 2 * n] * settings.rail_speed_max
    return z, act


class MPCPolicy:
    """The planner behind the batched policy interface (observations -> actions).

    The batch size is fixed by the first call. Between calls the planner keeps each
    row's warm start; rows whose observation says a new episode began are not detected
    (the LQR's sequence is a candidate at every step, so a stale warm start costs
    little). It reads the state from the observation (float32: about 1e-7 relative).
    """

    def __init__(
        self,
        core_class: type[ConvoyCore],
        settings: EnvSettings,
        config: PlannerConfig | None = None,
    ) -> None:
        self.core_class = core_class
        self.settings = settings
        self.config = config
        self.planner: SamplingPlanner | None = None

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        z, act = state_from_observation(obs, self.settings)
        if self.planner is None or self.planner.batch_size != z.shape[0]:
            self.planner = SamplingPlanner(self.core_class, self.settings, z.shape[0], self.config)
        return self.planner.plan(z, act).astype(np.float32)


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

    ``progress`` (counting steps) advances once per planned step.

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
        planned = planner.plan(core.z, core.act)[:, 0]
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
            core.act[rows, 0] = core.params.b
            core.refresh(rows)
    return PlannedEpisodes(actions, lengths, failed, band_steps)


__all__ = [
    "MPCPolicy",
    "PlannedEpisodes",
    "PlannerConfig",
    "SamplingPlanner",
    "plan_episodes",
    "riccati_matrices",
    "state_from_observation",
]
