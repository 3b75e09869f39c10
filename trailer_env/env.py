"""The single Gymnasium environment: a scene's batch core with B = 1.

:class:`ConvoyEnv` holds no physics and no task logic: it validates the action,
calls :meth:`ConvoyCore.step` and returns row 0. Each scene subclasses it only
to name its core class and carry its documentation.
"""

from __future__ import annotations

import numbers
from collections import deque
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dynamics import body_poses
from dynamics.params import real_number
from trailer_env.core import ConvoyCore, NonFiniteStateError
from trailer_env.settings import EnvSettings, settings_from_kwargs

RENDER_MODES = ("human", "rgb_array")
#: Past cart positions kept for the rendered path.
PATH_LENGTH = 2000


def check_render_mode(render_mode: object) -> None:
    """Refuse a render mode other than None, "human" or "rgb_array".

    Raises:
        TypeError: If it is neither None nor a str.
        ValueError: If it is a str naming another mode.
    """
    if render_mode is None:
        return
    if not isinstance(render_mode, str):
        raise TypeError(
            f"render_mode must be None or one of {RENDER_MODES}, "
            f"got {type(render_mode).__name__} {render_mode!r}"
        )
    if render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {render_mode!r}")


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


def as_action_array(
    action: Any, shape: tuple[int, ...], name: str = "action", *, alternative: tuple[int, ...] = ()
) -> np.ndarray:
    """``action`` as a numeric array of exactly ``shape`` (or ``alternative``), or a clear error.

    Accepted: arrays and (nested) sequences of real numbers (ints or floats) of exactly
    that shape. Nothing is broadcast. Finiteness is checked by the core.

    Raises:
        TypeError: For None, bools, strings, complex numbers or other non-numbers.
        ValueError: For a wrong shape (a ragged sequence included).
    """
    if isinstance(action, np.ndarray):
        array = action
    elif action is None or isinstance(action, (str, bytes, bool, np.bool_)):
        raise TypeError(
            f"{name} must be an array of real numbers of shape {shape}, "
            f"got {type(action).__name__} {action!r}"
        )
    else:
        try:
            array = np.asarray(action)
        except (ValueError, TypeError) as error:
            raise ValueError(
                f"{name} must be an array of real numbers of shape {shape}, got {action!r}"
            ) from error
    if array.dtype.kind not in "iuf":
        raise TypeError(
            f"{name} must be an array of real numbers of shape {shape}, got dtype {array.dtype}"
        )
    if array.shape != shape and not (alternative and array.shape == alternative):
        shown = f"{shape} or {alternative}" if alternative else f"{shape}"
        raise ValueError(f"{name} must have shape {shown}, got {array.shape}")
    return array


class ConvoyEnv(gym.Env[np.ndarray, np.ndarray]):
    """Base of the scenes' single environments (see each scene's docstring).

    Args:
        render_mode: None, "human" or "rgb_array".
        **kwargs: Settings: ``n_trailers``, ``params``, ``dt``, ``fidelity``,
            ``action_mode``, ``rail_accel_max``, ``servo_bandwidth``, ``singular_band``,
            ``fold_angle`` and any :class:`dynamics.ConvoyParams` field
            (see :func:`trailer_env.settings.settings_from_kwargs`).

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

    def __init__(self, render_mode: str | None = None, **kwargs: Any) -> None:
        check_render_mode(render_mode)
        self.settings: EnvSettings = settings_from_kwargs(**kwargs)
        self.render_mode = render_mode
        # Frames at the control rate: RecordVideo and the human window play in real time.
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.settings.dt))}
        self.core = self.core_class(self.settings, 1, track_pose=render_mode is not None)
        low, high = self.core.observation_bounds()
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.settings.action_dim,), dtype=np.float32)
        self._rows = np.zeros(1, dtype=np.int64)
        self._action = np.zeros((1, self.settings.action_dim))
        self._action_shape: tuple[int, ...] = (self.settings.action_dim,)
        self._path: deque[tuple[float, float]] = deque(maxlen=PATH_LENGTH)
        self._renderer: Any = None
        self._has_reset = False

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode; ``seed`` seeds the generator that draws the starting state."""
        super().reset(seed=seed)
        self.core.reset_rows(self._rows, [self.np_random])
        self._has_reset = True
        self._path.clear()
        self._record_path()
        if self.render_mode == "human":
            self.render()
        return self.core.obs[0].copy(), self.core.info_row(0)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Advance by ``dt``. Out-of-range actions are clipped to [-1, 1].

        ``action`` must have exactly the action space's shape, (1,) or (2,) in planar
        mode (an array or a sequence of ints or floats); with a 1-D action space a
        plain real number is accepted too. Nothing else is broadcast.

        Raises:
            TypeError: If the action is None, a bool, a string, complex or not numeric.
            ValueError: If the action is NaN, infinite or of the wrong shape.
        """
        if not self._has_reset:
            raise gym.error.ResetNeeded("call reset() before step()")
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
            core.obs[0].copy(),
            float(core.reward[0]),
            bool(core.terminated[0]),
            False,
            core.info_row(0),
        )

    def set_state(
        self,
        z: Any,
        *,
        s: float = 0.0,
        s_dot: float = 0.0,
        **task: Any,
    ) -> np.ndarray:
        """Put the environment in a hand-built state (tests, demos); returns the observation.

        Args:
            z: (u, omega, alpha_1..alpha_n), optionally followed by the cart's pose (x, y, theta)
                when the environment tracks it (otherwise the pose is the origin, heading x).
            s, s_dot: The mass on the rail (rail modes; in planar mode the lateral axis).
            **task: Scene-specific task values (e.g. ``target_heading``), see the scene.

        Raises:
            TypeError: If ``z``, ``s`` or ``s_dot`` is not made of real numbers.
            ValueError: If the shape is wrong, a value is not finite or overflows, or the
                mass is off the rail.
        """
        if not self._has_reset:
            self.reset()
        core = self.core
        if isinstance(z, np.ndarray):
            given = z
        elif z is None or isinstance(z, (str, bytes, bool, np.bool_)):
            raise TypeError(f"z must be a sequence of real numbers, got {type(z).__name__}")
        else:
            try:
                given = np.asarray(z)
            except (ValueError, TypeError) as error:
                raise ValueError(f"z must be a flat sequence of real numbers, got {z!r}") from error
        if given.dtype.kind not in "iuf":
            raise TypeError(f"z must hold real numbers, got dtype {given.dtype}")
        state = given.astype(np.float64)
        if state.ndim != 1 or state.shape[0] not in (core.n + 2, core.z.shape[1]):
            raise ValueError(
                f"z must have length {core.n + 2} or {core.z.shape[1]}, got shape {state.shape}"
            )
        if not np.all(np.isfinite(state)):
            raise ValueError("z must be finite")
        s = real_number("s", s)
        s_dot = real_number("s_dot", s_dot)
        s_max = self.settings.params.s_max
        accel = self.settings.rail_accel_max
        if (
            abs(s) > s_max
            or s + max(s_dot, 0.0) ** 2 / (2 * accel) > s_max
            or (s - max(-s_dot, 0.0) ** 2 / (2 * accel) < -s_max)
        ):
            raise ValueError("the mass must be on the rail and able to stop before its ends")
        previous_z, previous_act = core.z[0].copy(), core.act[0].copy()
        core.z[0] = 0.0  # a pose not given starts at the origin, heading along x
        core.z[0, : state.shape[0]] = state
        core.act[0] = 0.0
        core.act[0, 0] = self.settings.params.b
        core.act[0, 1] = s
        core.act[0, 3] = s_dot
        try:
            core.refresh()
            overflow = not (np.isfinite(core.energy[0]) and np.all(np.isfinite(core.obs[0])))
        except NonFiniteStateError:
            overflow = True
        if overflow:
            core.z[0], core.act[0] = previous_z, previous_act
            core.refresh()
            raise ValueError(
                "z is too large: its energy or its float32 observation overflows "
                "(the state was left unchanged)"
            )
        core.set_task(0, **task)
        core.refresh()
        core.energy0[0] = core.energy[0]
        core._after_reset(self._rows)
        self._path.clear()
        self._record_path()
        return core.obs[0].copy()

    def _record_path(self) -> None:
        if self.core.with_pose:
            n = self.core.n
            self._path.append((float(self.core.z[0, n + 2]), float(self.core.z[0, n + 3])))

    def render(self) -> np.ndarray | None:
        """Draw the convoy (top-down) in a window ("human") or return an RGB array ("rgb_array")."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode to gym.make")
            return None
        if not self._has_reset:
            raise gym.error.ResetNeeded("call reset() before render()")
        from trailer_env.rendering import ConvoyRenderer, RenderFrame  # pygame only when rendering

        if self._renderer is None:
            self._renderer = ConvoyRenderer(
                self.settings.params,
                render_mode=self.render_mode,
                singular_band=self.settings.singular_band,
                fps=self.metadata["render_fps"],
                view_size=self.core.render_view_size(),
            )
        core = self.core
        n = core.n
        x, y, theta = core.z[0, n + 2 : n + 5]
        xs, ys, thetas = body_poses(self.settings.params.l, x, y, theta, core.z[0, 2 : 2 + n])
        frame = RenderFrame(
            xs=xs,
            ys=ys,
            thetas=thetas,
            mass_xy_body=(float(core.act[0, 0]), float(core.act[0, 1])),
            singular_margin=float(core.singular_margin[0]),
            path=np.asarray(self._path, dtype=np.float64).reshape(-1, 2),
            text=f"u = {core.z[0, 0]:+.2f} m/s   margin = {core.singular_margin[0]:.2f}",
            **core.render_extras(0),
        )
        return self._renderer.draw(frame)

    def __getstate__(self) -> dict[str, Any]:
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
