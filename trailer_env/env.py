"""The single Gymnasium environment: a scene's batch core with B = 1.

:class:`ConvoyEnv` holds no physics and no task logic: it validates the action,
calls :meth:`ConvoyCore.step` and returns row 0. Each scene subclasses it only
to name its core class and carry its documentation.
"""

from __future__ import annotations

import numbers
import sys
from collections.abc import Mapping, Sequence
from types import FrameType
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.wrappers import TimeLimit

from dynamics.columns import ETA, theta_column, x_column
from dynamics.params import one_of, real_number
from trailer_env.core import ConvoyCore
from trailer_env.mixed import build_core, observation_view
from trailer_env.observation import Observation
from trailer_env.rendering import (
    RENDER_MODES,
    ConvoyRenderer,
    PathTrace,
    core_frame,
    make_renderer,
)
from trailer_env.settings import EnvSettings

#: Past cart positions kept for the rendered path.
PATH_LENGTH = 2000
#: ``reset(options=...)`` keys of every scene; each scene adds its ``task_keys``.
STATE_OPTIONS = ("state", "s", "s_dot")


def options_dict(options: object, valid: Sequence[str]) -> dict[str, object]:
    """``reset(options=...)`` as a dict (None -> {}), its keys among ``valid``.

    Raises:
        TypeError: If ``options`` is not a dict or None.
        ValueError: Naming the unknown keys and the valid ones.
    """
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
    unknown = sorted(set(options) - set(valid), key=str)
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown}; valid: {list(valid)}")
    return options


def check_reset_options(options: object, task_keys: tuple[str, ...]) -> dict[str, object]:
    """``options`` as a dict (None -> {}), its keys checked against the scene's.

    Raises:
        TypeError: If ``options`` is not a dict or None.
        ValueError: Naming unknown keys, or ``s``/``s_dot`` given without ``state``.
    """
    options = options_dict(options, (*STATE_OPTIONS, *task_keys))
    if "state" not in options and ("s" in options or "s_dot" in options):
        raise ValueError("reset options 's' and 's_dot' need 'state' (the convoy's state)")
    return options


def checked_seed(seed: object) -> int | None:
    """A ``reset(seed=...)`` value as a Python int (or None), never truncated.

    Raises:
        TypeError: If it is not None or an integer (a bool, a float such as 1.5, a string).
        ValueError: If it is negative.
    """
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TypeError(
            f"seed must be None or a non-negative integer, got {type(seed).__name__} {seed!r}"
        )
    if seed < 0:
        raise ValueError(f"seed must be None or a non-negative integer, got {seed!r}")
    return int(seed)


def refuse_masked(value: object, name: str) -> object:
    """``value`` itself, or its data if it is a numpy masked array with nothing masked.

    Raises:
        ValueError: If it is a masked array with a masked entry (its hidden data would be
            used otherwise).
    """
    if isinstance(value, np.ma.MaskedArray):
        if np.ma.getmaskarray(value).any():
            raise ValueError(
                f"{name} is a masked array with masked entries ({np.ma.count_masked(value)} of "
                f"{value.size}); pass plain values"
            )
        return np.ma.getdata(value)
    return value


def check_render_mode(render_mode: object) -> None:
    """Refuse a render mode other than None, "human" or "rgb_array".

    Raises:
        TypeError: If it is neither None nor a str.
        ValueError: If it is a str naming another mode.
    """
    one_of("render_mode", render_mode, RENDER_MODES, none=True)


class RenderModes(list[str]):
    """The ``render_modes`` metadata list, checking the type of what it is asked about.

    ``gymnasium.make`` tests ``render_mode in metadata["render_modes"]`` before it
    calls the environment's constructor, and on a miss calls ``render_mode.endswith``,
    which for ``render_mode=1`` fails with AttributeError inside gymnasium. Answering
    the membership test with our own TypeError names the argument instead.
    """

    def __contains__(self, item: object) -> bool:
        if item is not None and not isinstance(item, str):
            check_render_mode(item)
        return super().__contains__(item)


def real_array(name: str, value: object, expected: str) -> np.ndarray:
    """``value`` as a numpy array of real numbers (any shape, not copied where possible).

    The one type check of what users hand in as numbers (actions, states, task values):
    ``expected`` describes what ``name`` must be, e.g. ``"3 real numbers (x, y, heading)"``,
    and every message names both. The caller checks the shape and the values.

    Raises:
        TypeError: For None, bools, strings or bytes, or an array of anything but
            integers and floats (bools, strings, complex numbers, objects).
        ValueError: For a ragged sequence, or a numpy masked array with masked entries.
    """
    if isinstance(value, np.ndarray):
        array = np.asarray(refuse_masked(value, name))
    elif value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{name} must be {expected}, got {type(value).__name__} {value!r}")
    else:
        try:
            array = np.asarray(value)
        except (ValueError, TypeError) as error:
            raise ValueError(f"{name} must be {expected}, got {value!r}") from error
    if array.dtype.kind not in "iuf":
        raise TypeError(
            f"{name} must be {expected} (not bools, strings or complex numbers), "
            f"got dtype {array.dtype}"
        )
    return array


def as_action_array(
    action: object,
    shape: tuple[int, ...],
    name: str = "action",
    *,
    alternative: tuple[int, ...] = (),
) -> np.ndarray:
    """``action`` as a numeric array of exactly ``shape`` (or ``alternative``), or a clear error.

    Accepted: arrays and (nested) sequences of real numbers (ints or floats) of exactly
    that shape. Nothing is broadcast. Finiteness is checked by the core.

    Raises:
        TypeError: For None, bools, strings, complex numbers or other non-numbers.
        ValueError: For a wrong shape (a ragged sequence included), or a numpy masked
            array with masked entries.
    """
    array = real_array(name, action, f"an array of real numbers of shape {shape}")
    if array.shape != shape and not (alternative and array.shape == alternative):
        shown = f"{shape} or {alternative}" if alternative else f"{shape}"
        raise ValueError(f"{name} must have shape {shown}, got {array.shape}")
    return array


#: Largest magnitude of a hand-built state's components (set_state, reset options): the
#: energy (~ M u^2, I0 omega^2) and the float32 observations (up to 3.4e38) stay finite.
MAX_STATE_MAGNITUDE = 1e30


def checked_state(z: object, s: object, s_dot: object) -> tuple[np.ndarray, float, float]:
    """A hand-built state as a float64 vector and the mass's position and velocity as floats.

    The shape and the rail are checked by :meth:`ConvoyCore.set_row_state`.

    Raises:
        TypeError: If ``z``, ``s`` or ``s_dot`` is not made of real numbers (bools,
            strings, complex numbers, None).
        ValueError: If a value is not finite or beyond 1e30 in magnitude
            (:data:`MAX_STATE_MAGNITUDE`), ``z`` is ragged, or a masked array with masked
            entries.
    """
    state = real_array("z", z, "a flat sequence of real numbers").astype(np.float64)
    if not np.all(np.isfinite(state)):
        raise ValueError("z must be finite")
    if state.size and np.max(np.abs(state)) > MAX_STATE_MAGNITUDE:
        raise ValueError(
            f"z is too large: every component must be within +-{MAX_STATE_MAGNITUDE:g} (the "
            f"energy and the float32 observation would overflow), got {np.max(np.abs(state)):g}"
        )
    return state, real_number("s", s), real_number("s_dot", s_dot)


class ConvoyEnv(gym.Env[Observation, np.ndarray]):
    """Base of the scenes' single environments (see each scene's docstring).

    Args:
        render_mode: None, "human" or "rgb_array".
        **kwargs: Settings: the keywords of :data:`trailer_env.settings.MAKE_KEYWORDS`
            and any :class:`dynamics.ConvoyParams` field
            (see :func:`trailer_env.settings.settings_from_kwargs`). ``n_trailers`` may
            be a range ``(low, high)``: each episode draws its n (:mod:`trailer_env.mixed`).

    Raises:
        TypeError: On an unknown keyword or a value of the wrong type (bools, strings
            for numbers, ...), naming it; ``render_mode=1`` included, which is caught
            before ``gymnasium.make`` looks at it (:class:`RenderModes`).
        ValueError: On a value out of its documented range, naming it.

    Instances pickle (``pickle.dumps(env)``), after rendering too: the renderer is left
    out and recreated by the next :meth:`render`.
    """

    metadata = {"render_modes": RenderModes(RENDER_MODES), "render_fps": 20}  # noqa: RUF012
    core_class: ClassVar[type[ConvoyCore]]

    def __init__(self, render_mode: str | None = None, **kwargs: object) -> None:
        check_render_mode(render_mode)
        self.settings: EnvSettings
        self.settings, self.core = build_core(self.core_class, kwargs, 1, render_mode is not None)
        self.render_mode = render_mode
        # Frames at the control rate: RecordVideo and the human window play in real time.
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.settings.dt))}
        self._view = observation_view(self.core)
        self.observation_space = self._view.space
        self.action_space = spaces.Box(-1.0, 1.0, (self.settings.action_dim,), dtype=np.float32)
        self._rows = np.zeros(1, dtype=np.int64)
        self._action = np.zeros((1, self.settings.action_dim))
        self._action_shape: tuple[int, ...] = (self.settings.action_dim,)
        self._path = PathTrace(1, PATH_LENGTH)
        self._renderer: ConvoyRenderer | None = None
        self._has_reset = False
        # set_state began an episode that the TimeLimit wrappers above have not seen yet
        self._restart_time_limits = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, object] | None = None
    ) -> tuple[Observation, dict[str, object]]:
        """Start an episode; ``seed`` seeds the generator that draws the starting state.

        Args:
            seed: Seeds the generator (None keeps drawing from the current one).
            options: None, or a dict with any of ``state`` (the start, as for
                :meth:`set_state`: (u, omega, alpha_1..alpha_n) optionally followed by the
                pose), ``s`` and ``s_dot`` (the mass; need ``state``) and the scene's task
                values (``target_heading`` in Heading, ``target`` in Dock). The random start
                is drawn first either way, so the generator's stream does not depend on the
                options; given values then replace it.

        Every argument is checked before anything changes: a refused reset leaves the
        state, the observation and the generator as they were.

        Raises:
            TypeError: If ``options`` is not a dict, ``seed`` is not an integer (1.5, True),
                or a value is not made of real numbers (a string or bool for a number).
            ValueError: On an unknown option or an invalid value (naming it): a negative
                seed, a state of the wrong length, a mass off the rail, a task value out
                of range.
        """
        seed = checked_seed(seed)
        options = check_reset_options(options, self.core.task_keys)
        # A bad start state or task value is refused before anything changes (generator
        # included).
        given = None
        if "state" in options:
            given = checked_state(
                options["state"], options.get("s", 0.0), options.get("s_dot", 0.0)
            )
            self.core.check_row_state(*given)
        self.core.check_task(
            {key: value for key, value in options.items() if key not in STATE_OPTIONS}
        )
        super().reset(seed=seed)
        self.core.reset_rows(self._rows, [self.np_random])
        self._has_reset = True
        self._restart_time_limits = False
        if options:
            task = {key: value for key, value in options.items() if key not in STATE_OPTIONS}
            drawn = self.core.row_core(0).z[0].copy()
            state, s, s_dot = given if given is not None else (drawn, 0.0, 0.0)
            self.core.set_row_state(0, state, s=s, s_dot=s_dot, **task)
        self._path.clear()
        self._record_path()
        if self.render_mode == "human":
            self.render()
        return self._view.row(self.core.obs, 0), self.core.info_row(0)

    def step(self, action: object) -> tuple[Observation, float, bool, bool, dict[str, object]]:
        """Advance by ``dt``. Out-of-range actions are clipped to [-1, 1].

        ``action`` must have exactly the action space's shape, (1,) or (2,) in planar
        mode (an array or a sequence of ints or floats); with a 1-D action space a
        plain real number is accepted too. Nothing else is broadcast.

        Raises:
            TypeError: If the action is None, a bool, a string, complex or not numeric.
            ValueError: If the action is NaN, infinite, of the wrong shape, or a masked
                array with masked entries.
            FloatingPointError: If the step diverged (a non-finite result or one beyond
                1e12, see :mod:`trailer_env.core`) or would exceed the work budget of 2e8
                body-substeps; the state, observation and generator are left as they were.
        """
        if not self._has_reset:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._restart_time_limits:
            self._restart_wrapper_counts()
        if (
            type(action) is np.ndarray
            and action.shape == self._action_shape
            and action.dtype.kind == "f"
        ):
            self._action[0] = action  # the common case, checked at no cost
        elif (
            self._action.shape[1] == 1
            and isinstance(action, numbers.Real)
            and not isinstance(action, (bool, np.bool_))
        ):
            self._action[0, 0] = real_number("action", action)
        else:
            self._action[0] = as_action_array(action, self._action_shape)
        core = self.core
        core.step(self._action)
        if self.render_mode is not None:
            self._record_path()
            if self.render_mode == "human":
                self.render()
        return (
            self._view.row(core.obs, 0),
            float(core.reward[0]),
            bool(core.terminated[0]),
            False,
            core.info_row(0),
        )

    def set_state(
        self,
        z: object,
        *,
        s: float = 0.0,
        s_dot: float = 0.0,
        **task: object,
    ) -> Observation:
        """Put the environment in a hand-built state and start a new episode there; returns
        the observation.

        The new episode is one for the wrappers too: the step count of every
        ``gymnasium.wrappers.TimeLimit`` around this env (``gym.make``'s included) starts
        again at the next step, as after ``reset``, so the episode runs its full time limit.

        Args:
            z: (u, omega, alpha_1..alpha_n), optionally followed by the cart's pose (x, y, theta)
                when the environment tracks it (otherwise the pose is the origin, heading x).
                Or the dict :meth:`get_state` returns (then no other argument).
                With ``n_trailers=(low, high)`` its length picks the episode's n, and it
                must be whole, as :meth:`get_state` returns it (pose included where the
                env tracks it): a state without its pose would read as another count's.
            s, s_dot: The mass on the rail (rail modes; in planar mode the lateral axis).
            **task: Scene-specific task values (e.g. ``target_heading``), see the scene.

        Raises:
            TypeError: If ``z``, ``s`` or ``s_dot`` is not made of real numbers, or ``z`` is
                a dict given with other arguments.
            ValueError: If the shape is wrong, a value is not finite or overflows, the
                mass is off the rail, or a key or task value is unknown.
        """
        if isinstance(z, Mapping):
            if task or s != 0.0 or s_dot != 0.0:
                raise TypeError(
                    "set_state takes get_state()'s dict alone, or z with keywords; not both"
                )
            if "z" not in z or not all(isinstance(key, str) for key in z):
                raise ValueError(
                    "a state dict needs the key 'z' and string keys, as get_state() returns"
                )
            return self.set_state(**z)
        state, s, s_dot = checked_state(z, s, s_dot)
        self.core.check_row_state(state, s, s_dot)  # refused before anything changes
        self.core.check_task(task)
        if not self._has_reset:
            self.reset()
        self.core.set_row_state(0, state, s=s, s_dot=s_dot, **task)
        self._restart_time_limits = True
        self._path.clear()
        self._record_path()
        return self._view.row(self.core.obs, 0)

    def _restart_wrapper_counts(self) -> None:
        """Start again the step count of every TimeLimit wrapper whose ``step`` calls this one.

        :meth:`set_state` is called on ``env.unwrapped`` and cannot reach the wrappers
        that ``gym.make`` put around it, but the first step after it comes through them:
        each wrapper's ``step`` is on the call stack, so the ``TimeLimit`` frames there
        are this env's. Their count is set to 0 and this step makes it 1, as after a
        ``reset(options={"state": ...})`` through the wrappers.
        """
        self._restart_time_limits = False
        code = TimeLimit.step.__code__
        frame: FrameType | None = sys._getframe(2)  # the caller of step
        while frame is not None:
            if frame.f_code is code:
                wrapper = frame.f_locals.get("self")
                if isinstance(wrapper, TimeLimit) and wrapper.unwrapped is self:
                    wrapper.__dict__["_elapsed_steps"] = 0
            frame = frame.f_back

    def get_state(self) -> dict[str, object]:
        """The current state, as :meth:`set_state` takes it: ``env.set_state(**env.get_state())``
        puts this env, or another one made with the same keywords, in the same state.

        Returns:
            A dict of copies: ``z`` (float64: u, omega, alpha_1..alpha_n, then the cart's
            pose x, y, theta when the env tracks it, as :attr:`state`), ``s`` and ``s_dot``
            (the mass on the rail, floats; in planar mode its lateral axis) and the
            scene's task values (Heading: ``target_heading``; Dock: ``target``).
            With ``n_trailers=(low, high)``: the running episode's, ``z`` of length 2 + n
            for its n. ``env.set_state(env.get_state())`` takes the dict as it is.

        :meth:`set_state` starts a new episode at that state: what counts steps
        (the time limit, Heading's 1 s hold) and the energy reference start again, and
        randomised physics (``randomize=``) are the env's, not part of the state. The round
        trip is exact in the rail modes (``servo``, ``accel``); in ``planar`` mode
        :meth:`set_state` puts the mass's longitudinal axis at rest at its centre.

        Raises:
            gymnasium.error.ResetNeeded: Before the first :meth:`reset`.
        """
        if not self._has_reset:
            raise gym.error.ResetNeeded("call reset() before get_state()")
        core = self.core.row_core(0)
        return {
            "z": core.z[0].copy(),
            "s": float(core.act[0, ETA]),
            "s_dot": float(core.act[0, 3]),
            **core.task_values(0),
        }

    @property
    def state(self) -> np.ndarray:
        """The convoy's state z (a float64 copy), the Gymnasium-usual attribute: (u, omega,
        alpha_1..alpha_n), then the cart's pose (x, y, theta) when the env tracks it
        (:meth:`get_state` adds the mass and the task; zeros before the first reset).
        With ``n_trailers=(low, high)``: the running episode's, of length 2 + n."""
        return self.core.row_core(0).z[0].copy()

    def _record_path(self) -> None:
        if self.core.with_pose:  # one count: row 0's core is the batch's
            core = self.core.row_core(0)
            self._path.record(core.z[:1, x_column(core.n) : theta_column(core.n)])

    def render(self) -> np.ndarray | None:  # type: ignore[override]
        """Draw the convoy (top-down) in a window ("human") or return an RGB array ("rgb_array")."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode to gym.make")
            return None
        if not self._has_reset:
            raise gym.error.ResetNeeded("call reset() before render()")
        if self._renderer is None:
            self._renderer = make_renderer(
                self.core.row_core(0), self.render_mode, self.metadata["render_fps"]
            )
        return self._renderer.draw(core_frame(self.core.row_core(0), 0, self._path.path(0)))

    def get_keys_to_action(self) -> dict[tuple[str, ...], np.ndarray]:
        """Keyboard map for :func:`gymnasium.utils.play.play` (no key: the action 0).

        Servo and accel modes: ``a`` pushes the mass to the left end of its rail (+1), ``d``
        to the right (-1). Planar mode adds ``w`` (forward, +1) and ``s`` (back, -1) on the
        first axis, with ``a``/``d`` on the second; pairs combine.
        """
        if self.settings.action_dim == 1:
            return {("a",): np.array([1.0], np.float32), ("d",): np.array([-1.0], np.float32)}
        keys: dict[tuple[str, ...], np.ndarray] = {}
        for forward, first in (("", 0.0), ("w", 1.0), ("s", -1.0)):
            for side, second in (("", 0.0), ("a", 1.0), ("d", -1.0)):
                combination = tuple(sorted(key for key in (forward, side) if key))
                if combination:
                    keys[combination] = np.array([first, second], np.float32)
        return keys

    def __getstate__(self) -> dict[str, object]:
        """Pickle everything but the renderer (it holds pygame objects); it is recreated by
        the next :meth:`render`."""
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state

    def close(self) -> None:
        """Close the window, if any."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
