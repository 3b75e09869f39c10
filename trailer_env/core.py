"""The batched core: B environments of one scene held as arrays and stepped together.

Every environment, single or vectorised, is a :class:`ConvoyCore` subclass (a
scene) with a batch size: the Gymnasium env uses B = 1, the vector env B = N.
One control step is a fixed pipeline over the whole batch, in ONE compiled call with the
default integrators ("rk4", "rk4-energy"; :func:`trailer_env.kernels.step_serial`):

1. action -> guarded mass acceleration (:mod:`trailer_env.actuator`), the fidelity's
   substep counts, a backup of the state;
2. RK4 on blocks of rows, with the fold test after every substep (a fold between two
   control instants is not missed);
3. the rail guard; observations, singular margin, cost, jackknife flags and energy;
4. where the scene provides :attr:`ConvoyCore.scene_kernel` (a jitted function that
   calls the step kernel, then its reward and termination formulas), those too.

Then, in Python: the scene's ``_update_task`` and, for scenes without a scene kernel, the
hooks ``_advance``, ``_is_success``, ``_is_failed``, ``_is_terminated``, ``_reward``.
When the step was not fused (``"dopri5"``), a scene with a scene kernel has its
:attr:`ConvoyCore.scene_outcome` called instead: the same compiled formulas, written
once. ``"dopri5"`` takes three calls: the actuator and auto
rule, the integrator, the observations; its fold test sees the state at control instants
only (DOPRI5's own steps are not visible from here).

Accuracy: with ``fidelity.substeps="auto"`` the rule's estimate of each step's error
stays below the tolerance unless a cap binds (``max_substeps`` on the accuracy rule,
only at speeds far beyond the scenes', e.g. ``|u| = 1000`` m/s). Such a step is never
silent: :attr:`ConvoyCore.accuracy_exceeded` flags its rows and an
:class:`~trailer_env.substeps.AccuracyWarning` is issued (once per core).

Divergence: a step whose result is not finite, or holds a value beyond
:data:`~trailer_env.kernels.DIVERGENCE_BOUND` (1e12) in magnitude (u = 1.2 -> 2e96 m/s in
one step has been seen with in-range parameters), is redone with 8 times the substeps on
the rows concerned; if it still diverges, :meth:`ConvoyCore.step` raises
FloatingPointError naming the rows and the cause, with every row back at its state
before the step. With ``fidelity.substeps="auto"``, a step whose substeps a cap kept
inaccurate (an AccuracyWarning step) and whose speed scale ``max(|u|, l |omega|)`` grew
more than :data:`~trailer_env.substeps.GROWTH_LIMIT` (1000) times over its start's (plus
the mass's speed scale) has diverged too (u = 1.3 -> 5.9e6 m/s in one step was seen).
Slower growth below the bound is not detected.

Cost: one step's work, substeps x (n + 1) bodies summed over the rows stepped, is
bounded by :data:`~trailer_env.substeps.MAX_STEP_WORK` (2e8 body-substeps; its time:
benchmarks/README.md): fixed substeps beyond it (or ``(n + 1) B`` beyond it with
"auto") are refused at construction (ValueError), and an auto step whose chosen substeps
exceed it raises FloatingPointError before anything is integrated.

Scenes override the hooks (``_reset_row``, ``_update_task``, ``_advance``,
``_is_success``, ``_is_terminated``, ``_reward``, ``_after_reset``,
``_task_feature_bounds``); they never step the physics themselves. Per-row work
is done in numba kernels or numpy over the batch, never in a Python loop over
environments. Resets too: each environment draws its start from its own generator
(which is what makes the vector env replay single environments), and the scene's
:attr:`~ConvoyCore.start_kernel` draws every resetting row's in one compiled call.

Observation layout (rail actuator; ``n`` trailers), float32:

====================  =========================================================
index                 value
====================  =========================================================
0                     u, forward speed of the cart's axle midpoint (m/s)
1                     omega, the cart's turning rate (rad/s)
2 .. n+1              sin(alpha_k), k = 1..n
n+2 .. 2n+1           cos(alpha_k), k = 1..n
2n+2                  s / s_max, the mass's position on the rail, in [-1, 1]
2n+3                  s_dot / v_max, its velocity, v_max = 2 sqrt(rail_accel_max s_max)
2n+4 ..               the scene's task features
====================  =========================================================

With the planar actuator, indices 2n+2 .. 2n+5 hold (xi - b) / s_max,
eta / s_max, xi_dot / v_max, eta_dot / v_max, and task features start at 2n+6.
With ``observe_params=True``, 7 values follow the task features
(:attr:`ConvoyCore.param_offset` + k): ``log(value / nominal)`` of M, J0, a, m, J, l, mu,
the episode's parameters (:mod:`trailer_env.randomize`; 0 where not randomised, and 0
where the nominal value is 0: a factor leaves such a parameter 0).

Randomised physics (``randomize=``): each row's parameters are ``param_values`` (B, 7);
the kernels then take them per row, and the auto substep rule's settings are computed
per row from them at each reset (exact per row, not conservative).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar, NamedTuple

import numpy as np

from dynamics.columns import ETA, ETA_DOT, XI
from dynamics.params import bounded_real
from trailer_env.core_base import SceneFunction
from trailer_env.core_infos import InfoMixin
from trailer_env.core_physics import PhysicsMixin
from trailer_env.core_retry import RetryMixin
from trailer_env.fidelity import AccuracyWarning
from trailer_env.generators import GeneratorBank, typed_generators
from trailer_env.kernels import OVER_BUDGET
from trailer_env.objective import Objective
from trailer_env.randomize import MAX_FACTOR
from trailer_env.settings import EnvSettings
from trailer_env.shaping import penalty_vector, shaped_rewards

#: Largest magnitude of a task value set by hand (``reset(options=...)``, ``set_state``):
#: target positions in metres, headings in radians. Beyond it the observation's
#: distances lose their meaning (1e308 gave a -inf observation).
MAX_TASK_MAGNITUDE = 1e6


class StartRecord(NamedTuple):
    """Starts of some rows (:meth:`ConvoyCore.start_records`): their state rows ``z``,
    mass rows ``act``, task values (key of :attr:`ConvoyCore.task_keys` -> rows) and, in a
    batch that draws its physics, the episodes' drawn ``factors`` (rows of
    :attr:`ConvoyCore.factors`; None otherwise)."""

    z: np.ndarray
    act: np.ndarray
    task: dict[str, np.ndarray]
    factors: np.ndarray | None = None


class ConvoyCore(PhysicsMixin, InfoMixin, RetryMixin):
    """B environments of one scene (subclass it to make a scene).

    Args:
        settings: Shared settings (parameters, dt, actuator, fidelity).
        batch_size: Number of environments B >= 1.
        track_pose: Integrate the cart's pose (x, y, theta) even if the scene does
            not need it (rendering). The reduced state's trajectory is identical
            either way: the pose is appended to the state, it does not feed back.

    Attributes: :class:`trailer_env.core_base.CoreBase`'s (the batch's arrays).
    """

    #: The scene's name and version: it is registered as ``trailer_env/{scene}-v{version}``.
    scene: ClassVar[str] = ""
    version: ClassVar[int] = 0
    #: What the scene asks (to survive the episode or reach a goal): read by the
    #: termination and by the agents' certification, witnesses and tables.
    objective: ClassVar[Objective] = Objective.GOAL
    #: Truncation length registered for the scene (steps).
    max_episode_steps: ClassVar[int] = 400
    #: The rate the agents report first for this scene (a key of
    #: :func:`trailer_env.benchmark.summarize`'s summary).
    headline_metric: ClassVar[str] = "success_rate"
    #: The scene's failure other than a jackknife (what :meth:`_is_failed` tests), in
    #: words for the results tables ("the convoy stopped reversing"); "" if it has none.
    failure_words: ClassVar[str] = ""
    #: Names of the ``agents`` baselines that apply to this scene (evaluated by default):
    #: the controllers of :mod:`trailer_env.controllers` and the trivial policies. The
    #: planners that apply too are the agents' business (``agents.oracles.scenes``).
    baselines: ClassVar[tuple[str, ...]] = ("zero", "random", "lqr")
    #: Signs of the task features in the convoy's mirror image (:meth:`mirror_signs`);
    #: None: the scene declares no mirror symmetry.
    mirror_task_signs: ClassVar[tuple[float, ...] | None] = ()
    #: Reward on the step that ends in a jackknife (added to the scene's reward).
    fold_penalty: ClassVar[float] = 10.0
    #: Reward per step spent in the singular band (subtracted).
    band_penalty: ClassVar[float] = 0.5
    #: Task values :meth:`set_task` accepts (``reset(options=...)`` keys beyond the state).
    task_keys: ClassVar[tuple[str, ...]] = ()
    #: A jitted ``start(generators, picks, rows, z, task)`` that draws the starting state
    #: of every row ``rows[j]`` from ``generators[picks[j]]`` (a ``numba.typed.List``,
    #: :mod:`trailer_env.generators`) into ``z`` (zeroed) and the scene's task arrays
    #: (:meth:`_start_arguments`, passed as a plain tuple): the resets of a whole batch in
    #: one call. None: :meth:`_reset_row` draws each row in Python. Either way a row draws
    #: the same numbers in the same order from its generator, so single and vector
    #: environments replay each other.
    start_kernel: ClassVar[SceneFunction | None] = None
    #: Whether the scene's start is a perturbation of a size that :meth:`set_start_scale`
    #: can shrink or widen (a start curriculum); False: the method refuses.
    start_scalable: ClassVar[bool] = False

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        super().__init__(settings, batch_size, track_pose=track_pose)
        self._warned_accuracy = False
        self._saved: tuple[np.ndarray, ...] | None = None  # save_step's copies
        self._start: tuple[object, ...] | None = None  # built on the first reset
        #: Factor on the size of the starting perturbation (:meth:`set_start_scale`).
        self.start_scale = 1.0

    def _start_arguments(self) -> tuple:
        """The start kernel's last argument (the task arrays and constants it writes and
        reads), built once; passed as a plain tuple."""
        return ()

    def set_start_scale(self, scale: float) -> None:
        """Draw the next starts with the perturbation's size times ``scale`` (a start
        curriculum; 1, the default, is the scene's own distribution).

        Only the size changes: every row draws the same numbers from its generator as at
        scale 1, so a start at scale ``s`` is the scale-1 start with its perturbation
        multiplied by ``s``. Starts at a scale other than 1 are not the scene's and carry
        no certificate.

        Raises:
            TypeError: If ``scale`` is not a real number.
            ValueError: If it is not in (0, 2], or the scene's starts have no size to scale
                (:attr:`start_scalable`); nothing changes.
        """
        if not self.start_scalable:
            raise ValueError(
                f"{self.scene}-v{self.version}'s starts have no perturbation size to scale "
                "(set_start_scale applies to Reverse-v1)"
            )
        self.start_scale = bounded_real("start_scale", scale, 0.0, 2.0, low_open=True)
        self._start = None

    def _start_tuple(self) -> tuple:
        if self._start is None:
            self._start = tuple(self._start_arguments())
        return self._start

    # ----------------------------------------------------------------- hooks
    def _reset_row(self, i: int, rng: np.random.Generator) -> None:
        """Sample row ``i``'s starting state into ``z[i]`` and the scene's task arrays
        (scenes without a :attr:`start_kernel`).

        ``z[i]`` and ``act[i]`` arrive zeroed (the mass at rest at the rail's centre).
        """
        raise NotImplementedError

    def _is_success(self) -> np.ndarray:
        """Boolean (B,): the task is achieved. Default: never."""
        return np.zeros(self.batch_size, dtype=bool)

    def _starting_success(self, rows: np.ndarray) -> np.ndarray:
        """Boolean (len(rows),): the success flag of rows just reset. Default:
        :meth:`_is_success` of the batch at ``rows``; scenes whose test is per row
        override it so a reset costs its rows, not the batch."""
        return self._is_success()[rows]

    def _is_failed(self) -> np.ndarray:
        """Boolean (B,): the episode ends in a failure other than a jackknife. Default: never.

        Evaluated after :meth:`_is_success` (it may read ``success``); the result is kept
        in ``failed`` for :meth:`_is_terminated` and :meth:`_reward`.
        """
        return np.zeros(self.batch_size, dtype=bool)

    def _is_terminated(self) -> np.ndarray:
        """Boolean (B,): the episode ends. Default, from :attr:`objective`: a jackknife or
        a failure in a survival scene (its success means "not failed so far"; the time
        limit truncates its episodes), a jackknife, the goal or a failure in a goal scene.
        """
        if self.objective is Objective.SURVIVAL:
            return self.jackknifed | self.failed
        return self.jackknifed | self.success | self.failed

    def _reward(self) -> np.ndarray:
        """Float (B,) reward of the step just taken."""
        raise NotImplementedError

    def _advance(self) -> None:
        """Per-step bookkeeping after the state advanced (counters); may update ``obs`` features.

        Called once per step, after :meth:`refresh` and before the success, termination
        and reward hooks (never on a reset).
        """

    def _after_reset(self, rows: np.ndarray) -> None:
        """Initialise per-episode bookkeeping (potentials, counters) of ``rows`` after a reset."""

    def mirror_signs(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The convoy's mirror image as signs: ``(observation signs (obs_dim,), action
        signs (action_dim,))``, or None where the scene declares no mirror symmetry.

        Reflecting the plane about the cart's axis at the start (y -> -y) changes the
        sign of the turning rate, the hitch angles, the mass's lateral position and
        velocity and the lateral parts of the task (a dock's lateral offset, a heading
        error), and keeps the rest (speed, cosines, the mass's position along the cart,
        the parameters). The equations, the rail and every scene's starts, reward and
        termination are symmetric under it, so ``obs * signs`` is the observation of the
        mirrored state, ``action * action_signs`` the mirrored action, and a mirrored
        episode earns the same rewards (tests/trailer_env/test_mirror.py). A policy
        that is odd under it (``agents.policies.mirror``) acts on a straight convoy
        with no bias.
        """
        if self.mirror_task_signs is None:
            return None
        n = self.n
        if self.settings.actuator.planar:  # (xi - b, eta, xi_dot, eta_dot), (xi_ddot, eta_ddot)
            mass, action = [1.0, -1.0, 1.0, -1.0], [1.0, -1.0]
        else:  # (s, s_dot), s_ddot
            mass, action = [-1.0, -1.0], [-1.0]
        signs = [1.0, -1.0, *([-1.0] * n), *([1.0] * n), *mass, *self.mirror_task_signs]
        signs += [1.0] * self.n_param_features
        return np.array(signs), np.array(action)

    def _task_feature_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the task features (default unbounded)."""
        return np.full(self.n_task_features, -np.inf), np.full(self.n_task_features, np.inf)

    @property
    def counts(self) -> tuple[int, ...]:
        """The trailer counts of the batch's episodes: this core's one."""
        return (self.n,)

    @property
    def trailers(self) -> np.ndarray:
        """Each row's number of trailers (B,): this core's n."""
        return np.full(self.batch_size, self.n, dtype=np.int64)

    def count_cores(self) -> dict[int, ConvoyCore]:
        """The core of each count: this one."""
        return {self.n: self}

    def row_core(self, i: int) -> ConvoyCore:
        """The core holding row ``i``'s episode: this one (a mix of trailer counts holds
        one core per count, :meth:`trailer_env.mixed.MixedCore.row_core`)."""
        del i
        return self

    def check_task(self, task: Mapping[str, object]) -> dict[str, object]:
        """The task values :meth:`set_task` would set, validated, changing nothing.

        Keys outside :attr:`task_keys` are refused; each given value is checked by
        :meth:`check_task_value`, which a scene with task values overrides.

        Raises:
            TypeError: If a value is not of the right type (a string or bool for a number).
            ValueError: If a value is unknown, not finite or out of its documented range.
        """
        unknown = sorted(set(task) - set(self.task_keys), key=str)
        if unknown:
            raise ValueError(
                f"unknown task value(s) {unknown} for {type(self).__name__}; "
                f"valid: {list(self.task_keys)}"
            )
        return {key: self.check_task_value(key, task[key]) for key in self.task_keys if key in task}

    def check_task_value(self, key: str, value: object) -> object:
        """Task value ``key`` as :meth:`set_task` stores it, checked (a scene with
        :attr:`task_keys` overrides it)."""
        raise NotImplementedError(f"{type(self).__name__} does not check task value {key!r}")

    def set_task(self, i: int, **task: object) -> None:
        """Set row ``i``'s task values by hand (e.g. a target; :meth:`check_task`): each
        key of :attr:`task_keys` is an array attribute with one entry per row."""
        for key, value in self.check_task(task).items():
            getattr(self, key)[i] = value

    def task_values(self, i: int) -> dict[str, float | np.ndarray]:
        """Row ``i``'s task values as :meth:`set_task` takes them (copies): each key of
        :attr:`task_keys` is an array attribute of the scene's core, one entry per row."""
        values: dict[str, float | np.ndarray] = {}
        for key in self.task_keys:
            value = np.array(getattr(self, key)[i], dtype=np.float64)
            values[key] = float(value) if value.ndim == 0 else value
        return values

    def check_row_state(self, z: object, s: float = 0.0, s_dot: float = 0.0) -> np.ndarray:
        """The state :meth:`set_row_state` would set, as float64, checked; changes nothing.

        Raises:
            ValueError: If the shape is wrong, a value is not finite, or the mass is off
                the rail or could not stop before its ends.
        """
        state = np.asarray(z, dtype=np.float64)
        if state.ndim != 1 or state.shape[0] not in (self.n + 2, self.z.shape[1]):
            lengths = sorted({self.n + 2, self.z.shape[1]})
            shown = " or ".join(str(length) for length in lengths)
            raise ValueError(f"z must have length {shown}, got shape {state.shape}")
        if not np.all(np.isfinite(state)) or not (np.isfinite(s) and np.isfinite(s_dot)):
            raise ValueError("z, s and s_dot must be finite")
        s_max = self.params.s_max
        accel = self.settings.rail_accel_max
        if (
            abs(s) > s_max
            or s + max(s_dot, 0.0) ** 2 / (2 * accel) > s_max
            or (s - max(-s_dot, 0.0) ** 2 / (2 * accel) < -s_max)
        ):
            raise ValueError("the mass must be on the rail and able to stop before its ends")
        return state

    def set_row_state(
        self, i: int, z: object, *, s: float = 0.0, s_dot: float = 0.0, **task: object
    ) -> None:
        """Put row ``i`` in a hand-built state and start a new episode there.

        Args:
            i: The row.
            z: (u, omega, alpha_1..alpha_n), optionally followed by the cart's pose
                (x, y, theta) when the core tracks it (otherwise the pose is the origin,
                heading along x).
            s, s_dot: The mass on the rail (rail modes; in planar mode the lateral axis).
            **task: The scene's task values (:attr:`task_keys`, e.g. ``target_heading``).

        Raises:
            ValueError: If the shape is wrong, a value is not finite, the mass is off the
                rail or could not stop before its ends, or a task value is unknown.
        """
        state = self.check_row_state(z, s, s_dot)
        rows = np.array([i], dtype=np.int64)
        self.set_task(i, **task)  # validates the task values before anything else changes
        self.z[i] = 0.0
        self.z[i, : state.shape[0]] = state
        self.act[i] = 0.0
        self.act[i, XI] = self.params.b
        self.act[i, ETA] = s
        self.act[i, ETA_DOT] = s_dot
        self._begin_episodes(rows)

    def start_records(self, rows: np.ndarray) -> StartRecord:
        """Copies of ``rows``' state, mass and task values, and of their drawn physics where
        the batch draws it (``randomize``), taken just after their reset: starts that
        :meth:`restart` puts back (:mod:`trailer_env.start_replay`)."""
        task = {key: np.array(getattr(self, key)[rows], dtype=np.float64) for key in self.task_keys}
        factors = None if self.randomization is None else self.factors[rows].copy()
        return StartRecord(self.z[rows].copy(), self.act[rows].copy(), task, factors)

    def restart(self, rows: np.ndarray, record: StartRecord) -> None:
        """Start new episodes in ``rows`` from ``record`` (one entry per row, as
        :meth:`start_records` returns them): each replays the recorded start, its drawn
        physics included, to the bit.

        Raises:
            ValueError: If the record's shapes do not fit ``rows`` or this batch, or it
                carries drawn physics where the batch draws none or the reverse.
        """
        size = len(rows)
        task_shapes = {key: (size, *getattr(self, key).shape[1:]) for key in self.task_keys}
        factor_shape = None if self.randomization is None else (size, self.factors.shape[1])
        if (
            record.z.shape != (size, self.z.shape[1])
            or record.act.shape != (size, self.act.shape[1])
            or {key: value.shape for key, value in record.task.items()} != task_shapes
            or (None if record.factors is None else record.factors.shape) != factor_shape
        ):
            raise ValueError(f"the start record does not fit {size} rows of this batch")
        self.z[rows] = record.z
        self.act[rows] = record.act
        for key, values in record.task.items():
            getattr(self, key)[rows] = values
        if record.factors is not None:
            self._restore_physics(np.asarray(rows, dtype=np.int64), record.factors)
        self._begin_episodes(rows)

    def render_markers(self, i: int) -> tuple[Any, ...]:
        """Row ``i``'s targets to draw (:class:`~trailer_env.rendering.Marker`); default none."""
        return ()

    def render_view_size(self) -> float | None:
        """Metres across the rendered picture; None lets the renderer fit the convoy."""
        return None

    # ------------------------------------------------------------------ core
    @property
    def actuator_work(self) -> np.ndarray:
        """Work done by the actuator since the reset, E - E(reset) (J).

        The energy's rate of change is the actuator's power (physics.md section 9),
        so the energy change is the integral of that power; the difference is the
        integrator's error, bounded per step by the fidelity's tolerance (default 1e-4,
        typically ~100 times smaller; see :mod:`trailer_env.substeps`).
        """
        return self.energy - self.energy0

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of one observation, float32."""
        n = self.n
        low = np.full(self.n_common, -np.inf)
        high = np.full(self.n_common, np.inf)
        low[2 : 2 + 2 * n] = -1.0
        high[2 : 2 + 2 * n] = 1.0
        low[2 + 2 * n :] = -1.0
        high[2 + 2 * n :] = 1.0
        task_low, task_high = self._task_feature_bounds()
        # The same bounds whatever the ranges, so that a policy trained under one
        # randomisation sees the same observation space under another.
        param_high = np.full(self.n_param_features, np.log(MAX_FACTOR))
        param_low = -param_high
        return (
            np.concatenate([low, task_low, param_low]).astype(np.float32),
            np.concatenate([high, task_high, param_high]).astype(np.float32),
        )

    def reset_rows(self, rows: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        """Start new episodes in ``rows`` (int array), row ``rows[j]`` drawing from ``rngs[j]``."""
        if self.start_kernel is None:
            self._start_episodes(rows, rngs, None)
        else:
            picks = np.arange(len(rows), dtype=np.int64)
            self._start_episodes(rows, typed_generators(rngs), picks)

    def reset_rows_from(self, rows: np.ndarray, bank: GeneratorBank) -> None:
        """Start new episodes in ``rows``, row ``i`` drawing from ``bank[i]`` (one generator
        per row of the batch): the vector env's and the SB3 adapter's resets, drawn in one
        compiled call where the scene has a :attr:`start_kernel`."""
        if self.start_kernel is None:
            self._start_episodes(rows, [bank[i] for i in rows.tolist()], None)
        else:
            self._start_episodes(rows, bank.typed, rows)

    def _start_episodes(
        self, rows: np.ndarray, rngs: Sequence[np.random.Generator], picks: np.ndarray | None
    ) -> None:
        """Draw the starts of ``rows`` (``rngs[picks[j]]`` for ``rows[j]``; without picks,
        ``rngs`` is aligned with ``rows`` and the Python hook draws), then derive the rest."""
        self.z[rows] = 0.0
        self.act[rows] = 0.0
        self.act[rows, XI] = self.params.b
        if picks is None:
            for i, rng in zip(rows.tolist(), rngs, strict=True):
                self._reset_row(i, rng)
        else:
            start = self.start_kernel
            assert start is not None  # picks come only with a start kernel (reset_rows)
            start(rngs, picks, rows, self.z, self._start_tuple())
        if self._draws is not None:
            self._draw_physics(rows, rngs, picks)
        self._begin_episodes(rows)

    def _begin_episodes(self, rows: np.ndarray) -> None:
        """Start episodes in ``rows`` from the states already in ``z`` and ``act``: derive
        the observation, the energy (the actuator work's zero), clear the step's outcome,
        and run the scene's :meth:`_after_reset` and :meth:`_starting_success` (every
        start, drawn or hand-built, goes through here)."""
        self.refresh(rows)
        self.energy0[rows] = self.energy[rows]
        self.reward[rows] = 0.0
        self.terminated[rows] = False
        self.failed[rows] = False
        self._after_reset(rows)
        self.success[rows] = self._starting_success(rows)

    def step(self, action: np.ndarray, rows: np.ndarray | None = None) -> None:
        """Advance every environment (or ``rows``, an int array) by ``dt`` under ``action``
        (B, action_dim), float64; rows not stepped keep their state (their results of
        this step are meaningless: the vector env resets them).

        Raises:
            ValueError: If an action of a stepped row is NaN or infinite (nothing is stepped).
            FloatingPointError: If a step diverged (a non-finite result, or a value beyond
                :data:`~trailer_env.kernels.DIVERGENCE_BOUND` in magnitude) even with 8
                times the substeps, or the auto rule's substeps would exceed the work
                budget :data:`~trailer_env.substeps.MAX_STEP_WORK` (nothing is integrated).
                Every row is left at its state before the step, and the results of the
                last step (``reward``, ``terminated``, ``success``, ``failed``) as they were;
                ``substeps`` and ``accuracy_exceeded`` describe the refused step.
        """
        stepped = self._all_rows if rows is None else rows
        bad, nonfinite, over = self._physics_step(action, stepped, True)
        if bad >= 0:
            raise ValueError(
                f"action contains non-finite values (NaN or inf), environment {bad}: {action[bad]}"
            )
        if bad == OVER_BUDGET:
            self._refuse_over_budget(stepped)
        if nonfinite:
            self._retry_finer(action, stepped)
        if over and not self._warned_accuracy:
            self._warned_accuracy = True
            warnings.warn(
                f"{over} environment(s) took a step whose estimated error exceeds the "
                f"fidelity's tolerance: fidelity.max_substeps = "
                f"{self.settings.fidelity.max_substeps} caps the substeps (see "
                "core.accuracy_exceeded; raise max_substeps, or use fidelity='dopri5'). "
                "Warned once per environment batch.",
                AccuracyWarning,
                stacklevel=3,
            )
        self._update_task(slice(None))
        if self.scene_outcome is not None:
            # The same compiled formulas the fused step runs; it skipped them when a row
            # was redone (_retry_finer), so that a refused step leaves the results alone.
            if not self.settings.fidelity.fused or nonfinite:
                self.scene_outcome(stepped, self.kernel_args.outputs_tuple, self._scene_tuple())
        else:
            self._advance()
            self.success[:] = self._is_success()
            self.failed[:] = self._is_failed()
            self.terminated[:] = self._is_terminated()
            self.reward[:] = self._reward()

    def _step_records(self) -> tuple[np.ndarray, ...]:
        """The per-row arrays a completed step writes that the state alone does not give
        back (:meth:`save_step`): the step's results and flags. Scenes with per-step
        bookkeeping (counters) add theirs."""
        return (
            self.reward,
            self.terminated,
            self.success,
            self.failed,
            self.jackknifed,
            self.accuracy_exceeded,
        )

    def save_step(self) -> None:
        """Keep a copy of :meth:`_step_records` so that :meth:`undo_step` can take back the
        next step (a :class:`~trailer_env.mixed.MixedCore` step whose later count was
        refused). A few array copies: the plain step does not call it."""
        records = self._step_records()
        if self._saved is None:
            self._saved = tuple(np.empty_like(array) for array in records)
        for array, saved in zip(records, self._saved, strict=True):
            np.copyto(saved, array)

    def undo_step(self, rows: np.ndarray) -> None:
        """Put ``rows`` back where they were before the last step, completed or refused,
        with everything a step changes (state, observation, results, flags, bookkeeping)
        as it was, but for what only that step reads (the mass's commanded accelerations,
        ``act[:, XI_DDOT:]``, and ``substeps``); :meth:`save_step` must have been called before
        that step.

        Raises:
            RuntimeError: If :meth:`save_step` was never called.
        """
        if self._saved is None:
            raise RuntimeError("undo_step needs save_step before the step")
        indices = np.asarray(rows, dtype=np.int64)
        # The step kernel's copies of the rows it stepped.
        self.z[indices] = self.step_state.z_backup[indices]
        self.act[indices] = self.step_state.act_backup[indices]
        records = tuple(zip(self._step_records(), self._saved, strict=True))
        for array, saved in records:  # the bookkeeping first: the task features read it
            array[indices] = saved[indices]
        self.refresh(indices)
        self._after_restore(indices)
        for array, saved in records:  # a fold seen between control instants is not in z
            array[indices] = saved[indices]


class ShapedCore(ConvoyCore):
    """A scene whose reward is potential-based shaping plus fixed bonuses and penalties.

    Reward of a step: ``potential(after) - potential(before) - time_penalty
    - band_penalty * cost + success_bonus * success - fold_penalty * jackknifed
    - failure_penalty * failed``. The potential differences telescope, so over an
    episode they add up to a bounded amount, and the per-step penalties over a full
    episode stay below ``fold_penalty``: folding on purpose never pays.
    """

    time_penalty: ClassVar[float] = 0.01
    band_penalty: ClassVar[float] = 0.05
    success_bonus: ClassVar[float] = 10.0
    fold_penalty: ClassVar[float] = 20.0
    failure_penalty: ClassVar[float] = 10.0

    def __init__(self, settings: EnvSettings, batch_size: int, *, track_pose: bool = False) -> None:
        super().__init__(settings, batch_size, track_pose=track_pose)
        self.previous_potential = np.zeros(self.batch_size)
        #: The constants of :func:`trailer_env.shaping.shaped_reward`, at its named indices.
        self.shaping_penalties = penalty_vector(
            self.time_penalty,
            self.band_penalty,
            self.success_bonus,
            self.fold_penalty,
            self.failure_penalty,
        )

    def _potential(self) -> np.ndarray:
        """Potential of every row's current state (higher is closer to the goal)."""
        raise NotImplementedError

    def _after_reset(self, rows: np.ndarray) -> None:
        self.previous_potential[rows] = self._potential()[rows]

    def _after_restore(self, rows: np.ndarray) -> None:
        # The potential of every row's state is its previous potential between steps.
        self.previous_potential[rows] = self._potential()[rows]

    def _step_records(self) -> tuple[np.ndarray, ...]:
        return (*super()._step_records(), self.previous_potential)

    def _reward(self) -> np.ndarray:
        potential = self._potential()
        reward = np.empty(self.batch_size)
        shaped_rewards(
            potential,
            self.previous_potential,
            self.cost,
            self.success,
            self.jackknifed,
            self.failed,
            self.shaping_penalties,
            reward,
        )
        self.previous_potential[:] = potential
        return reward
