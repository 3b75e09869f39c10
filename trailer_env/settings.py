"""Settings shared by every scene: physical parameters, control period, actuator, fidelity.

:class:`EnvSettings` is frozen and validated once; the environments, their batch
core and the controllers all read it. :func:`settings_from_kwargs` turns the
keyword arguments of ``gym.make`` (``n_trailers``, ``dt``, ConvoyParams field
overrides such as ``mu=0.4`` ...) into settings.

Default parameters are :class:`dynamics.ConvoyParams`' own. Its actuator (``mu =
0.5``, half the cart's mass, on a rail ``b = 1.0`` m ahead of the axle with
``s_max = 0.5`` m) was sized for these tasks: a full stroke of the mass turns
the cart by about ``mu b 2 s_max / (I0 + mu b^2)``, 0.53 rad. With a weaker one
(``mu = 0.25, b = 0.5, s_max = 0.3``: 0.15 rad) the linear controller of
:mod:`trailer_env.controllers` keeps a reversing two-trailer convoy (Reverse-v0)
from folding in 8 % of 50 episodes, against 64 % with the defaults, while the
zero action folds every episode within about 3 s either way: hard, but feasible.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from dynamics import ConvoyParams
from trailer_env.fidelity import Fidelity

ACTION_MODES = ("servo", "accel", "planar")

_PARAM_FIELDS = frozenset(f.name for f in dataclasses.fields(ConvoyParams))


def _positive(name: str, value: Any) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(number) and number > 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return number


@dataclass(frozen=True)
class EnvSettings:
    """Everything but the task: physics, control period, actuator and safety thresholds.

    Attributes:
        params: Physical parameters (``params.n_trailers`` trailers).
        dt: Control period in seconds (the action is held over it), > 0.
        fidelity: Integrator and substep control (:class:`Fidelity`).
        action_mode: "servo" (default: the action is a target position on the rail),
            "accel" (the action is the rail acceleration) or "planar" (2-D target).
        rail_accel_max: Bound on the mass's acceleration along each axis, m/s^2;
            ``rail_accel_max * dt**2 <= s_max`` so the end-of-rail guard can always act.
        servo_bandwidth: Natural frequency of the position servo, rad/s, capped at
            ``0.25 / dt`` for the sampled loop to stay well damped.
        singular_band: The convoy is in the singular band when
            ``singular_margin < singular_band``, in [0, 1).
        fold_angle: Jackknife when any ``|alpha_k| >= fold_angle`` (radians, in (0, pi]).
    """

    params: ConvoyParams = field(default_factory=ConvoyParams)
    dt: float = 0.05
    fidelity: Fidelity = field(default_factory=Fidelity)
    action_mode: str = "servo"
    rail_accel_max: float = 4.0
    servo_bandwidth: float = 5.0
    singular_band: float = 0.3
    fold_angle: float = math.pi / 2

    def __post_init__(self) -> None:
        if not isinstance(self.params, ConvoyParams):
            raise ValueError(f"params must be a ConvoyParams, got {type(self.params).__name__}")
        object.__setattr__(self, "fidelity", Fidelity.coerce(self.fidelity))
        for name in ("dt", "rail_accel_max", "servo_bandwidth"):
            object.__setattr__(self, name, _positive(name, getattr(self, name)))
        if self.action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {self.action_mode!r}")
        if self.rail_accel_max * self.dt**2 > self.params.s_max:
            raise ValueError(
                f"rail_accel_max * dt**2 = {self.rail_accel_max * self.dt**2:.4g} exceeds s_max = "
                f"{self.params.s_max}: the end-of-rail guard could not always stop the mass; "
                "lower rail_accel_max or dt"
            )
        try:
            band = float(self.singular_band)
            fold = float(self.fold_angle)
        except (TypeError, ValueError):
            raise ValueError("singular_band and fold_angle must be numbers") from None
        if not (0.0 <= band < 1.0):
            raise ValueError(f"singular_band must be in [0, 1), got {self.singular_band!r}")
        if not (0.0 < fold <= math.pi):
            raise ValueError(f"fold_angle must be in (0, pi], got {self.fold_angle!r}")
        object.__setattr__(self, "singular_band", band)
        object.__setattr__(self, "fold_angle", fold)
        # Fail now rather than at the first step (e.g. "rk4-energy" with mu > 0).
        self.fidelity.make_integrator(self.params, False)

    @property
    def n_trailers(self) -> int:
        """Number of trailers."""
        return self.params.n_trailers

    @property
    def servo_frequency(self) -> float:
        """The servo's natural frequency actually used, min(servo_bandwidth, 0.25 / dt)."""
        return min(self.servo_bandwidth, 0.25 / self.dt)

    @property
    def rail_speed_max(self) -> float:
        """Largest speed the guard lets the mass reach, 2 sqrt(rail_accel_max s_max).

        The mass must be able to stop within the rail, so v^2 / (2 A) <= 2 s_max.
        Observations divide the mass's velocity by this.
        """
        return 2.0 * math.sqrt(self.rail_accel_max * self.params.s_max)

    @property
    def action_dim(self) -> int:
        """1, or 2 in planar mode."""
        return 2 if self.action_mode == "planar" else 1


def settings_from_kwargs(
    n_trailers: int | None = None,
    params: ConvoyParams | None = None,
    dt: float = 0.05,
    fidelity: Fidelity | dict[str, Any] | str | int | None = None,
    action_mode: str = "servo",
    rail_accel_max: float = 4.0,
    servo_bandwidth: float = 5.0,
    singular_band: float = 0.3,
    fold_angle: float = math.pi / 2,
    **param_overrides: float,
) -> EnvSettings:
    """Build settings from ``gym.make``-style keyword arguments.

    Args:
        n_trailers: Number of trailers, default 2 (must agree with ``params`` when both are given).
        params: Full parameters; by default ConvoyParams' own.
        dt, fidelity, action_mode, rail_accel_max, servo_bandwidth, singular_band, fold_angle:
            See :class:`EnvSettings`.
        **param_overrides: Any ConvoyParams field, e.g. ``mu=0.4``.

    Raises:
        ValueError: On an unknown keyword or an invalid value, naming it.
    """
    unknown = sorted(set(param_overrides) - _PARAM_FIELDS)
    if unknown:
        raise ValueError(
            f"unknown argument(s) {unknown}; valid ConvoyParams fields: {sorted(_PARAM_FIELDS)}"
        )
    if n_trailers is not None and (
        isinstance(n_trailers, bool)
        or not isinstance(n_trailers, (int, np.integer))
        or n_trailers < 0
    ):
        raise ValueError(f"n_trailers must be an integer >= 0, got {n_trailers!r}")
    if params is None:
        count = 2 if n_trailers is None else int(n_trailers)
        base = {"n_trailers": count, **param_overrides}
        params = ConvoyParams(**base)  # type: ignore[arg-type]
    elif not isinstance(params, ConvoyParams):
        raise ValueError(f"params must be a ConvoyParams, got {type(params).__name__}")
    else:
        if n_trailers is not None and n_trailers != params.n_trailers:
            raise ValueError(
                f"n_trailers = {n_trailers} disagrees with params.n_trailers = {params.n_trailers}"
            )
        if param_overrides:
            params = params.replace(**param_overrides)
    return EnvSettings(
        params=params,
        dt=dt,
        fidelity=Fidelity.coerce(fidelity),
        action_mode=action_mode,
        rail_accel_max=rail_accel_max,
        servo_bandwidth=servo_bandwidth,
        singular_band=singular_band,
        fold_angle=fold_angle,
    )
